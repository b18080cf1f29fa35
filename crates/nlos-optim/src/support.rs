//! How much of each face's light the data confirm: the face's support, from the exact change of the data
//! term were the face deleted.
//!
//! For face f with share `I_f` of the rendering `I` (its light in every measurement it reaches), deleting
//! it changes the data term by `ΔE_f = E(I − I_f) − E(I)`, and `c_f = E(I + I_f) + E(I − I_f) − 2E(I)` is
//! the term's curvature along the share (`s²‖I_f‖²` for L2; [`crate::prune`]'s test uses both). The
//! face's support is
//! ```text
//! σ_f = ΔE_f / (½ c_f),   clamped to [−1, 1]
//! ```
//! For L2 `σ_f = 2⟨s·I_f, m − s·I⟩ / ‖s·I_f‖² + 1`: **+1** where the capture holds all of the face's light
//! beyond what the rest of the mesh makes (deleting it would leave exactly that light unexplained), **0**
//! where it holds half, **−1** where it holds none (deleting the face would remove only misfit; pruning
//! deletes a boundary face when `σ_f < −½`). A face no measurement sees gets 0: the data say nothing of it.
//!
//! The run computes it once, for the final surface ([`SUPPORT`], a face field carried by the checkpoint);
//! `mesh.ply` carries it per vertex ([`vertex_support`]: the area-weighted mean of the faces around), and
//! the report's 3-D view colours by it. It costs one share per face (the pruning test's, for every face).

use glam::Vec3;
use nlos_render::{AnyBrdf, Renderer};
use rayon::prelude::*;

use crate::data_term::RowLoss;
use crate::error::{OptimError, Result};
use crate::prune::delta;
use crate::surface::FaceField;

/// The support of each face of the final surface (module docs); absent until a run finishes.
pub const SUPPORT: FaceField<f64> = FaceField::new("support", 0.0);

/// `σ_f` of each of the `n_faces` faces of `renderer`'s mesh (module docs), against `rendered` (its forward pass with `brdf`,
/// measurement-major, `bins` per histogram) and the data term row by row at the fit's scale (`row_loss`).
///
/// # Errors
/// [`OptimError::LengthMismatch`] when `rendered` is not measurements × `bins` long; the renderer's and
/// `row_loss`'s errors.
pub fn face_support(
    n_faces: usize,
    renderer: &Renderer,
    brdf: &AnyBrdf,
    rendered: &[f32],
    bins: usize,
    row_loss: &RowLoss<'_>,
) -> Result<Vec<f64>> {
    let rows = renderer.scan().measurements();
    if bins == 0 || rendered.len() != rows * bins {
        return Err(OptimError::LengthMismatch { what: "rendered", expected: rows * bins, got: rendered.len() });
    }
    (0..n_faces)
        .into_par_iter()
        .map(|f| {
            let spans = renderer.forward_triangle_any(brdf, f)?;
            if spans.is_empty() {
                return Ok(0.0);
            }
            // With margin 1 the test value is ΔE_f + ½ c_f.
            let (test, change) = delta(&spans, rendered, bins, row_loss, 1.0, false)?;
            let half_c = test - change;
            Ok(if half_c > 0.0 && half_c.is_finite() { (change / half_c).clamp(-1.0, 1.0) } else { 0.0 })
        })
        .collect()
}

/// Per vertex, the area-weighted mean support of the faces around it (0 for a vertex no face uses).
pub fn vertex_support(positions: &[Vec3], triangles: &[[u32; 3]], support: &[f64]) -> Vec<f32> {
    let (mut sum, mut weight) = (vec![0.0f64; positions.len()], vec![0.0f64; positions.len()]);
    for (t, &s) in triangles.iter().zip(support) {
        let p = t.map(|v| positions[v as usize]);
        let area = f64::from((p[1] - p[0]).cross(p[2] - p[0]).length());
        for &v in t {
            sum[v as usize] += area * s;
            weight[v as usize] += area;
        }
    }
    sum.iter().zip(&weight).map(|(s, w)| if *w > 0.0 { (s / w) as f32 } else { 0.0 }).collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use glam::Vec3;
    use nlos_render::{RenderParams, Visibility};
    use nlos_transient::{PointSet, Scan, TimeAxis};

    /// Two squares side by side at 0.4 m (faces 0–1 left, 2–3 right).
    fn two_squares() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = |x: f32, y: f32| Vec3::new(x, y, 0.4);
        let pos = vec![p(-0.2, -0.1), p(0.0, -0.1), p(0.0, 0.1), p(-0.2, 0.1), p(0.2, -0.1), p(0.2, 0.1)];
        (pos, vec![[0, 2, 1], [0, 3, 2], [1, 5, 4], [1, 2, 5]])
    }

    #[test]
    fn a_face_whose_light_the_capture_holds_is_supported_and_one_it_lacks_is_not() {
        let (pos, tris) = two_squares();
        let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.25, 0.25).unwrap());
        let time = TimeAxis::new(0.5, 0.01, 60).unwrap();
        let params = RenderParams { visibility: Visibility::Off, ..RenderParams::default() };
        let r = Renderer::new(&pos, &tris, &scan, &time, params).unwrap();
        let brdf = AnyBrdf::Lambertian(nlos_brdf::Lambertian::new(1.0).unwrap());
        let rendered = r.forward_any(&brdf);
        let left = Renderer::new(&pos, &tris[..2], &scan, &time, params).unwrap().forward_any(&brdf);
        let bins = time.bins;
        let l2 = |capture: &[f32]| {
            let capture = capture.to_vec();
            move |m: usize, row: &[f32], w: std::ops::Range<usize>| -> Result<f64> {
                let c = &capture[m * bins + w.start..m * bins + w.end];
                Ok(row[w.clone()].iter().zip(c).map(|(&a, &b)| 0.5 * f64::from(a - b).powi(2)).sum())
            }
        };
        // The capture holds the whole mesh's light: every face confirmed.
        let s = face_support(4, &r, &brdf, &rendered, bins, &l2(&rendered)).unwrap();
        assert!(s.iter().all(|&x| x > 0.99), "{s:?}");
        // It holds the left square's light alone: the right square's faces have no support. (The left ones
        // have less than full support here: deleting one also takes away light that overlaps the right
        // square's surplus in time.)
        let s = face_support(4, &r, &brdf, &rendered, bins, &l2(&left)).unwrap();
        assert!(s[2..].iter().all(|&x| x < -0.99), "{s:?}");
        let v = vertex_support(&pos, &tris, &s);
        assert!(v[4] < -0.99 && v[5] < -0.99 && v[0] > v[4], "{v:?}");
        let short = face_support(4, &r, &brdf, &rendered[1..], bins, &l2(&left)).unwrap_err();
        assert!(matches!(short, OptimError::LengthMismatch { .. }), "{short}");
    }
}
