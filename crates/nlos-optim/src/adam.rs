//! Adam (Kingma & Ba, "Adam: A Method for Stochastic Optimization", ICLR 2015, Algorithm 1), in two
//! forms: Tsai et al. 2019's per-vertex isotropic variant for vertex positions and the plain one for the
//! reflectance parameters θ (the unconstrained space of `nlos_brdf::GgxTheta` / `LambertianTheta`).
//!
//! Algorithm 1, with bias correction:
//! ```text
//! m_t = β1 m_{t−1} + (1 − β1) g_t,    v_t = β2 v_{t−1} + (1 − β2) g_t²
//! Δ_t = −η · m̂_t / (√v̂_t + ε),         m̂_t = m_t/(1 − β1ᵗ),  v̂_t = v_t/(1 − β2ᵗ)
//! ```
//! **Isotropic per vertex** (Tsai et al.'s implementation): the second moment of a vertex is the mean of
//! the squared gradient over x, y, z, `v_t = β2 v_{t−1} + (1 − β2) ‖g_t‖²/3`, so each vertex has one step size
//! and its displacement points along its (momentum-averaged) gradient instead of being bent toward the
//! coordinate axes. Interior and boundary vertices have separate learning rates η. All state is f64 (exact
//! in checkpoints).

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

/// Hyper-parameters of Adam (Kingma & Ba's defaults: β1 = 0.9, β2 = 0.999, ε = 1e-8).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AdamParams {
    /// Decay of the first moment, in [0, 1).
    pub beta1: f64,
    /// Decay of the second moment, in [0, 1).
    pub beta2: f64,
    /// Denominator guard ε (> 0), in gradient units.
    pub eps: f64,
}

impl Default for AdamParams {
    fn default() -> Self {
        Self { beta1: 0.9, beta2: 0.999, eps: 1e-8 }
    }
}

impl AdamParams {
    pub(crate) fn valid(&self) -> bool {
        (0.0..1.0).contains(&self.beta1) && (0.0..1.0).contains(&self.beta2) && self.eps > 0.0 && self.eps.is_finite()
    }

    /// Bias corrections `(1 − β1ᵗ, 1 − β2ᵗ)` for step t ≥ 1.
    fn corrections(&self, t: u64) -> (f64, f64) {
        let t = t.min(i32::MAX as u64) as i32;
        (1.0 - self.beta1.powi(t), 1.0 - self.beta2.powi(t))
    }
}

/// One vertex's isotropic Adam moments (module docs): a field of the loop's surface
/// ([`crate::surface::Surface`], [`crate::reconstruct::SHAPE_MOMENTS`]), so that they follow every remeshing.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Moments {
    /// First moment.
    pub m: DVec3,
    /// Isotropic second moment (mean over x, y, z of g²).
    pub v: f64,
}

impl Moments {
    /// Zero moments: a vertex that has taken no step.
    pub const ZERO: Self = Self { m: DVec3::ZERO, v: 0.0 };
}

/// One scalar parameter's Adam moments (a per-vertex albedo's, [`crate::albedo::ALBEDO_MOMENTS`]): a field
/// of the loop's surface, so that they follow every change of topology.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ScalarMoments {
    /// First moment.
    pub m: f64,
    /// Second moment.
    pub v: f64,
}

impl ScalarMoments {
    /// Zero moments: a parameter that has taken no step.
    pub const ZERO: Self = Self { m: 0.0, v: 0.0 };
}

/// Plain Adam (Algorithm 1) over scalar parameters whose moments live elsewhere (a surface field): one step
/// of step `t` (≥ 1) with learning rate `lr`; returns the update to add to each parameter. The caller
/// guarantees `grad.len() == moments.len()`.
pub fn scalar_step(p: &AdamParams, t: u64, moments: &mut [ScalarMoments], grad: &[f64], lr: f64) -> Vec<f64> {
    let (c1, c2) = p.corrections(t.max(1));
    grad.iter()
        .zip(moments.iter_mut())
        .map(|(&g, mo)| {
            mo.m = p.beta1 * mo.m + (1.0 - p.beta1) * g;
            mo.v = p.beta2 * mo.v + (1.0 - p.beta2) * g * g;
            -lr * (mo.m / c1) / ((mo.v / c2).sqrt() + p.eps)
        })
        .collect()
}

/// Per-vertex isotropic Adam (module docs): the step count; the moments are per vertex ([`Moments`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct VertexAdam {
    /// Steps taken.
    pub t: u64,
}

impl VertexAdam {
    /// One step: updates `moments` with `grad` and returns the displacement of every vertex, with
    /// learning rate `lr(i)` for vertex i. The caller guarantees `grad.len() == moments.len()`.
    pub fn step(
        &mut self,
        p: &AdamParams,
        moments: &mut [Moments],
        grad: &[Vec3],
        lr: impl Fn(usize) -> f64,
    ) -> Vec<Vec3> {
        self.t += 1;
        let (c1, c2) = p.corrections(self.t);
        let mut d = Vec::with_capacity(grad.len());
        for (i, (g, mo)) in grad.iter().zip(moments.iter_mut()).enumerate() {
            let g = g.as_dvec3();
            mo.m = p.beta1 * mo.m + (1.0 - p.beta1) * g;
            mo.v = p.beta2 * mo.v + (1.0 - p.beta2) * g.length_squared() / 3.0;
            let step = -lr(i) * (mo.m / c1) / ((mo.v / c2).sqrt() + p.eps);
            d.push(step.as_vec3());
        }
        d
    }
}

/// Plain Adam over a parameter vector (the reflectance θ).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct VectorAdam {
    /// First moments.
    pub m: Vec<f64>,
    /// Second moments.
    pub v: Vec<f64>,
    /// Steps taken.
    pub t: u64,
}

impl VectorAdam {
    /// Zero state for `n` parameters.
    pub fn new(n: usize) -> Self {
        Self { m: vec![0.0; n], v: vec![0.0; n], t: 0 }
    }

    /// One step with learning rate `lr`; returns the update to add to the parameters.
    pub fn step(&mut self, p: &AdamParams, grad: &[f64], lr: f64) -> Vec<f64> {
        self.t += 1;
        let (c1, c2) = p.corrections(self.t);
        grad.iter()
            .enumerate()
            .map(|(i, &g)| {
                self.m[i] = p.beta1 * self.m[i] + (1.0 - p.beta1) * g;
                self.v[i] = p.beta2 * self.v[i] + (1.0 - p.beta2) * g * g;
                -lr * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + p.eps)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_has_length_lr_along_the_gradient() {
        // Bias correction makes |Δ_1| = η for every non-zero gradient (Kingma & Ba, Sec. 2.1), and the
        // isotropic variant keeps the direction of g.
        let mut a = VertexAdam::default();
        let mut moments = [Moments::ZERO; 2];
        let g = [Vec3::new(3.0, -4.0, 0.0), Vec3::new(1e-3, 0.0, 0.0)];
        let d = a.step(&AdamParams::default(), &mut moments, &g, |i| if i == 0 { 0.01 } else { 0.02 });
        // ‖m̂‖/√v̂ = ‖g‖/(‖g‖/√3) = √3.
        assert!((d[0].length() - 0.01 * 3f32.sqrt()).abs() < 1e-6);
        assert!(d[0].normalize().dot(-g[0].normalize()) > 0.99999);
        assert!((d[1].length() - 0.02 * 3f32.sqrt()).abs() < 1e-5);
    }

    #[test]
    fn minimises_a_quadratic() {
        let p = AdamParams::default();
        let mut a = VectorAdam::new(2);
        let mut x = [3.0f64, -2.0];
        for _ in 0..2000 {
            let g = [2.0 * x[0], 20.0 * x[1]];
            let d = a.step(&p, &g, 0.05);
            x[0] += d[0];
            x[1] += d[1];
        }
        assert!(x[0].abs() < 1e-2 && x[1].abs() < 1e-2, "{x:?}");
    }
}
