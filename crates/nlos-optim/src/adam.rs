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

/// Per-vertex isotropic Adam state (module docs).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct VertexAdam {
    /// First moment per vertex.
    pub m: Vec<DVec3>,
    /// Isotropic second moment per vertex (mean over x, y, z of g²).
    pub v: Vec<f64>,
    /// Steps taken.
    pub t: u64,
}

impl VertexAdam {
    /// Zero state for `n` vertices.
    pub fn new(n: usize) -> Self {
        Self { m: vec![DVec3::ZERO; n], v: vec![0.0; n], t: 0 }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.v.len()
    }

    /// Whether there are no vertices.
    pub fn is_empty(&self) -> bool {
        self.v.is_empty()
    }

    /// One step: updates the moments with `grad` and returns the displacement of every vertex, with
    /// learning rate `lr[i]` for vertex i. The caller guarantees `grad.len() == lr.len() == self.len()`.
    pub fn step(&mut self, p: &AdamParams, grad: &[Vec3], lr: impl Fn(usize) -> f64) -> Vec<Vec3> {
        self.t += 1;
        let (c1, c2) = p.corrections(self.t);
        let mut d = Vec::with_capacity(grad.len());
        for (i, g) in grad.iter().enumerate() {
            let g = g.as_dvec3();
            self.m[i] = p.beta1 * self.m[i] + (1.0 - p.beta1) * g;
            self.v[i] = p.beta2 * self.v[i] + (1.0 - p.beta2) * g.length_squared() / 3.0;
            let step = -lr(i) * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + p.eps);
            d.push(step.as_vec3());
        }
        d
    }

    /// The state of a renumbered vertex set: new vertex `i` takes the moments of old vertex `source[i]`,
    /// or zero moments for `None` (a new vertex) or an old index out of range. The step count is kept.
    pub fn select(&self, source: &[Option<u32>]) -> Self {
        let old = |j: Option<u32>| j.and_then(|j| Some((*self.m.get(j as usize)?, *self.v.get(j as usize)?)));
        let (m, v) = source.iter().map(|&j| old(j).unwrap_or((DVec3::ZERO, 0.0))).unzip();
        Self { m, v, t: self.t }
    }

    /// The state carried to a new vertex set: `weights[i]` lists `(old vertex, weight)` pairs whose weighted
    /// sum gives new vertex i's moments (e.g. barycentric interpolation on the closest old face). The step
    /// count is kept, so the bias corrections continue.
    pub fn transfer(&self, weights: &[[(u32, f32); 3]]) -> Self {
        let mut out = Self { m: Vec::with_capacity(weights.len()), v: Vec::with_capacity(weights.len()), t: self.t };
        for w in weights {
            let (mut m, mut v) = (DVec3::ZERO, 0.0f64);
            for &(j, wj) in w {
                if let (Some(mj), Some(vj)) = (self.m.get(j as usize), self.v.get(j as usize)) {
                    m += f64::from(wj) * *mj;
                    v += f64::from(wj) * *vj;
                }
            }
            out.m.push(m);
            // Guard: interpolation weights are ≥ 0, but keep v ≥ 0 against rounding.
            out.v.push(v.max(0.0));
        }
        out
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
    fn select_keeps_renumbered_moments_and_zeroes_new_vertices() {
        let mut a = VertexAdam::new(3);
        let g = [Vec3::X, Vec3::Y * 2.0, Vec3::Z * 3.0];
        a.step(&AdamParams::default(), &g, |_| 0.1);
        let b = a.select(&[Some(2), None, Some(0), Some(9)]);
        assert_eq!((b.len(), b.t), (4, a.t));
        assert_eq!((b.m[0], b.v[0]), (a.m[2], a.v[2]));
        assert_eq!((b.m[2], b.v[2]), (a.m[0], a.v[0]));
        for i in [1, 3] {
            assert_eq!((b.m[i], b.v[i]), (DVec3::ZERO, 0.0), "vertex {i}: new or out of range");
        }
        assert!(a.v[2] > 0.0, "a non-trivial state");
    }

    #[test]
    fn first_step_has_length_lr_along_the_gradient() {
        // Bias correction makes |Δ_1| = η for every non-zero gradient (Kingma & Ba, Sec. 2.1), and the
        // isotropic variant keeps the direction of g.
        let mut a = VertexAdam::new(2);
        let g = [Vec3::new(3.0, -4.0, 0.0), Vec3::new(1e-3, 0.0, 0.0)];
        let d = a.step(&AdamParams::default(), &g, |i| if i == 0 { 0.01 } else { 0.02 });
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

    #[test]
    fn transfer_interpolates_moments() {
        let mut a = VertexAdam::new(3);
        a.m = vec![DVec3::X, DVec3::Y, DVec3::Z];
        a.v = vec![1.0, 2.0, 3.0];
        a.t = 7;
        let b = a.transfer(&[[(0, 0.5), (1, 0.5), (2, 0.0)], [(2, 1.0), (0, 0.0), (0, 0.0)]]);
        assert_eq!(b.t, 7);
        assert!((b.m[0] - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-12 && (b.v[0] - 1.5).abs() < 1e-12);
        assert!((b.v[1] - 3.0).abs() < 1e-12);
    }
}
