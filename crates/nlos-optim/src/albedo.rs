//! Reflectance on the surface: an albedo per vertex, fitted with the shape (`albedo = "vertex"`,
//! [`crate::ReconstructParams::albedo`]; not the default yet: docs/accuracy.md, "Dark strips").
//!
//! Tsai et al. 2019's reflectance is one BRDF for the whole surface. A hidden object whose reflectance varies —
//! the printed bars of a chart, a label — then has only the shape to explain its dark parts, and the fit
//! turns them into dents: faces pushed back and turned grazing, so that their light arrives later and
//! weaker. Peers that recover detail carry reflectance per point (Choi et al. 2023, albedo with total
//! variation; Plack et al. 2023, per-vertex albedo).
//!
//! **Model.** Each vertex v holds a relative albedo `a_v ≥ 0` ([`ALBEDO`], a field of the loop's surface, so
//! that it follows every remeshing, deletion and patch). Triangle t reflects with the factor
//! ```text
//! w_t = (a_i + a_j + a_k) / 3                                   (t = (i, j, k))
//! ```
//! on top of the BRDF, whichever runs (`nlos_render::Renderer::set_face_weights`) — the rule `nlos render`
//! applies to a PLY's vertex albedo, so a fitted mesh renders as it was fitted.
//!
//! **Gradient.** The renderer gives dE/dw_t (`nlos_render::Gradient::faces`, Proposition 1 with the factor
//! as one more BRDF parameter), so `dE/da_v = Σ_{t ∋ v} dE/dw_t / 3` ([`vertex_gradient`]).
//!
//! **Prior** (edge-preserving): total variation over the mesh's edges, smoothed (Charbonnier),
//! ```text
//! R_TV = Σ_e ℓ_e √((a_i − a_j)² + ε²) / Σ_e ℓ_e                 (ε = TV_EPSILON; boundary edges ℓ_e/2)
//! ```
//! the edge-length-weighted mean jump ([`total_variation`]); its weight is
//! [`AlbedoParams::tv`] times the data term above its noise floor at the block's first step (as the normal
//! smoothing's λ is set). A step between two albedos costs its length, not its square: a printed bar stays
//! sharp, noise within a region is smoothed.
//!
//! **Steps.** Every shape step updates the albedos from the same rendering as the vertices (plain Adam,
//! [`crate::adam::scalar_step`], moments in [`ALBEDO_MOMENTS`]): the fit can make a patch darker while it
//! would otherwise bend it. Reflectance blocks, where the BRDF has free parameters, update them too.
//! Albedos are kept in `[0, AlbedoParams::max]`; one that reaches 0 is the data saying "nothing here", and
//! the region test deletes it when the data cannot tell it from nothing ([`crate::regions`]).
//!
//! **Gauge.** With the measurement's scale solved in closed form at every step, a common factor of all
//! albedos changes nothing; after every step they are divided by their area-weighted mean over the surface
//! ([`recentre`]): the mean albedo is the BRDF's own.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::adam::{AdamParams, ScalarMoments, scalar_step};
use crate::error::{OptimError, Result};
use crate::surface::{Surface, VertexField};

/// The relative albedo of each vertex (module docs). Appended patches start at the mean, 1.
pub const ALBEDO: VertexField<f64> = VertexField::new("albedo", 1.0);

/// The Adam moments of [`ALBEDO`].
pub const ALBEDO_MOMENTS: VertexField<ScalarMoments> = VertexField::new("albedo_adam", ScalarMoments::ZERO);

/// Smoothing ε of the total variation (relative albedo): jumps much larger than it cost their length.
pub const TV_EPSILON: f64 = 0.01;

/// Parameters of the per-vertex albedo ([`crate::ReconstructParams::albedo`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AlbedoParams {
    /// Adam learning rate of the relative albedo, per step (default 0.05: an albedo can fall from the mean
    /// to 0 within a shape block of 20 steps).
    pub lr: f64,
    /// Weight of the total variation relative to the data term above its noise floor (default 0.05).
    pub tv: f64,
    /// Largest relative albedo (default 8): a guard, so that a vertex that sees little light cannot run away.
    pub max: f64,
}

impl Default for AlbedoParams {
    fn default() -> Self {
        Self { lr: 0.05, tv: 0.05, max: 8.0 }
    }
}

impl AlbedoParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a learning rate or TV weight that is not finite and ≥ 0, or a
    /// `max` that is not finite and > 1.
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value, reason| Err(OptimError::InvalidParameter { name, value, reason });
        if !(self.lr.is_finite() && self.lr >= 0.0) {
            return bad("albedo.lr", self.lr, "the learning rate must be finite and >= 0");
        }
        if !(self.tv.is_finite() && self.tv >= 0.0) {
            return bad("albedo.tv", self.tv, "the total variation's weight must be finite and >= 0");
        }
        if !(self.max.is_finite() && self.max > 1.0) {
            return bad("albedo.max", self.max, "the largest relative albedo must be finite and > 1 (the mean)");
        }
        Ok(())
    }
}

/// The factor `w_t` of every triangle: the mean of its corners' albedos (module docs).
pub fn face_weights(albedo: &[f64], triangles: &[[u32; 3]]) -> Vec<f32> {
    triangles.iter().map(|t| (t.iter().map(|&v| albedo[v as usize]).sum::<f64>() / 3.0) as f32).collect()
}

/// `dE/da_v = Σ_{t ∋ v} dE/dw_t / 3` for `n` vertices, from the renderer's per-face gradient.
pub fn vertex_gradient(n: usize, triangles: &[[u32; 3]], grad_faces: &[f32]) -> Vec<f64> {
    let mut g = vec![0.0; n];
    for (t, &gf) in triangles.iter().zip(grad_faces) {
        for &v in t {
            g[v as usize] += f64::from(gf) / 3.0;
        }
    }
    g
}

/// The smoothed total variation `R_TV` of the module docs and its gradient with respect to each albedo.
/// Each edge is summed from each face that holds it with half its length: an interior edge counts once, a
/// boundary edge half.
pub fn total_variation(positions: &[Vec3], triangles: &[[u32; 3]], albedo: &[f64]) -> (f64, Vec<f64>) {
    let (mut sum, mut length) = (0.0, 0.0);
    let mut g = vec![0.0; albedo.len()];
    for t in triangles {
        for k in 0..3 {
            let (i, j) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let l = 0.5 * f64::from(positions[i].distance(positions[j]));
            let d = albedo[i] - albedo[j];
            let r = (d * d + TV_EPSILON * TV_EPSILON).sqrt();
            sum += l * r;
            length += l;
            g[i] += l * d / r;
            g[j] -= l * d / r;
        }
    }
    if !(length > 0.0) {
        return (0.0, vec![0.0; albedo.len()]);
    }
    g.iter_mut().for_each(|x| *x /= length);
    (sum / length, g)
}

/// Divides every albedo by the area-weighted mean of the face factors, so that the mean is 1 (module docs,
/// "Gauge"). A surface of zero area or zero mean albedo is left as it is.
pub fn recentre(albedo: &mut [f64], positions: &[Vec3], triangles: &[[u32; 3]]) {
    let (mut num, mut den) = (0.0, 0.0);
    for t in triangles {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let area = 0.5 * f64::from((b - a).cross(c - a).length());
        num += area * t.iter().map(|&v| albedo[v as usize]).sum::<f64>() / 3.0;
        den += area;
    }
    if num > 0.0 && den > 0.0 {
        let k = den / num;
        albedo.iter_mut().for_each(|a| *a *= k);
    }
}

/// The settings of one albedo step ([`step`]).
#[derive(Debug, Clone, Copy)]
pub struct StepSettings<'a> {
    /// Adam's hyper-parameters.
    pub adam: &'a AdamParams,
    /// The albedo's parameters (its largest value).
    pub params: &'a AlbedoParams,
    /// Weight of the total variation's gradient.
    pub tv_weight: f64,
    /// Learning rate of the step.
    pub lr: f64,
    /// Recentre to an area mean of 1 after the step (the scale is solved, module docs "Gauge").
    pub recentre: bool,
}

/// One Adam step of the surface's albedo ([`ALBEDO`], moments [`ALBEDO_MOMENTS`]) from the renderer's
/// per-face gradient `grad_faces` (of the normalised data term) plus `settings.tv_weight` times the total
/// variation's; `steps` is the albedo's step count. The albedos are clamped to `[0, params.max]` and, with
/// `settings.recentre`, recentred ([`recentre`]).
///
/// # Errors
/// [`OptimError::Field`] when the surface has no albedo, [`OptimError::LengthMismatch`] for a gradient
/// that is not one per face.
pub fn step(surface: &mut Surface, steps: &mut u64, grad_faces: &[f32], settings: &StepSettings<'_>) -> Result<()> {
    let StepSettings { adam, params, tv_weight, lr, recentre: recentre_mean } = *settings;
    if grad_faces.len() != surface.n_faces() {
        return Err(OptimError::LengthMismatch {
            what: "albedo face gradient",
            expected: surface.n_faces(),
            got: grad_faces.len(),
        });
    }
    let mut grad = vertex_gradient(surface.n_vertices(), surface.triangles(), grad_faces);
    if tv_weight > 0.0 {
        let (_, g) = total_variation(surface.positions(), surface.triangles(), surface.vertex(ALBEDO)?);
        grad.iter_mut().zip(&g).for_each(|(x, t)| *x += tv_weight * t);
    }
    *steps += 1;
    let delta = scalar_step(adam, *steps, surface.vertex_mut(ALBEDO_MOMENTS)?, &grad, lr);
    let (positions, triangles) = (surface.positions().to_vec(), surface.triangles().to_vec());
    let albedo = surface.vertex_mut(ALBEDO)?;
    for (a, d) in albedo.iter_mut().zip(&delta) {
        *a = (*a + d).clamp(0.0, params.max);
    }
    if recentre_mean {
        recentre(albedo, &positions, &triangles);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        (p, vec![[0, 1, 2], [0, 2, 3]])
    }

    /// The vertex gradient is the chain rule of `face_weights`: checked against a finite difference of a
    /// linear function of the face factors.
    #[test]
    fn vertex_gradient_is_the_chain_rule_of_the_face_weights() {
        let (_, t) = square();
        let gf = [0.7f32, -1.3];
        let e = |a: &[f64]| face_weights(a, &t).iter().zip(&gf).map(|(w, g)| f64::from(*w * *g)).sum::<f64>();
        let a = [1.0, 0.5, 2.0, 0.1];
        let g = vertex_gradient(4, &t, &gf);
        // E is linear in the albedos: a large step is exact up to the factors' f32 rounding.
        for v in 0..4 {
            let mut b = a;
            b[v] += 0.5;
            let fd = (e(&b) - e(&a)) / 0.5;
            assert!((fd - g[v]).abs() < 1e-5, "vertex {v}: {fd} vs {}", g[v]);
        }
    }

    /// Total variation: zero gradient on a uniform albedo, the mean jump for a step, and its gradient checked
    /// by finite differences.
    #[test]
    fn total_variation_is_the_mean_jump_and_its_gradient_is_exact() {
        let (p, t) = square();
        let (r, g) = total_variation(&p, &t, &[1.0; 4]);
        assert!((r - TV_EPSILON).abs() < 1e-12 && g.iter().all(|x| x.abs() < 1e-12));
        let a = [1.0, 0.2, 0.3, 1.1];
        let (r, g) = total_variation(&p, &t, &a);
        for v in 0..4 {
            let mut b = a;
            b[v] += 1e-6;
            let fd = (total_variation(&p, &t, &b).0 - r) / 1e-6;
            assert!((fd - g[v]).abs() < 1e-4, "vertex {v}: {fd} vs {}", g[v]);
        }
        // A step of 1 between {0, 3} and {1, 2}: edges 0–1, 2–3 and 0–2 jump.
        let (r, _) = total_variation(&p, &t, &[1.0, 0.0, 0.0, 1.0]);
        // Boundary edges (length 1) count half, the interior diagonal (√2) whole.
        let jumps = 0.5 + 0.5 + std::f64::consts::SQRT_2;
        let total = 2.0 + std::f64::consts::SQRT_2;
        // The jumps cost √(1 + ε²) each per length, the two flat edges ε.
        let want = (jumps * (1.0 + TV_EPSILON * TV_EPSILON).sqrt() + TV_EPSILON) / total;
        assert!((r - want).abs() < 1e-7, "{r} vs {want}"); // lengths from f32 positions
    }

    #[test]
    fn recentring_makes_the_area_mean_one() {
        let (p, t) = square();
        let mut a = vec![2.0, 4.0, 2.0, 0.0];
        recentre(&mut a, &p, &t);
        let w = face_weights(&a, &t);
        assert!((0.5 * f64::from(w[0] + w[1]) - 1.0).abs() < 1e-6, "{w:?}");
    }

    #[test]
    fn parameters_are_validated() {
        assert!(AlbedoParams::default().validate().is_ok());
        for bad in [
            AlbedoParams { lr: -1.0, ..AlbedoParams::default() },
            AlbedoParams { tv: f64::NAN, ..AlbedoParams::default() },
            AlbedoParams { max: 1.0, ..AlbedoParams::default() },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
