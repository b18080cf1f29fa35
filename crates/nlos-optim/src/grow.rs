//! Loss-driven boundary growth: add faces beyond the boundary where the measurement asks for more surface.
//!
//! The counterpart of [`crate::prune`]. An initial surface from a thresholded volume stops short where the
//! object is dim (grazing flanks, a receding rim), and neither the shape steps (which move vertices) nor
//! the remeshing (which keeps the boundary where it is) can extend it. For every boundary edge `ab` of a
//! face `abc`, growth proposes a new triangle `b a p` across it: `p` lies one triangle height `h = |ab|·√3/2`
//! from the edge's midpoint, away from `c` in the face's plane, turned by θ ∈ [`GrowParams::angles`] about
//! the edge away from the wall (a silhouette recedes: the surface turns parallel to the line of sight). The
//! proposal with the lowest test value is kept for the edge when
//! ```text
//! ΔE⁺ = E(I + I_new) − E(I) < −κ · ½ c      (c = ΔE⁺ + ΔE⁻, the second difference; crate::prune)
//! ```
//! i.e. when the measurement holds light the rendering lacks, in the new face's bins, by more than
//! `(1 + κ)/2` of the face's own share. Proposals are rendered without occlusion (they lie beyond the
//! mesh's boundary), with the block's samples and kernel. Accepted proposals are added greedily from the
//! lowest test value, each re-tested against the rendering the additions before it have left, and at most
//! one new face per boundary vertex per call (neighbouring proposals would overlap at a concave corner).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use glam::Vec3;
use nlos_render::{RenderParams, Renderer, Visibility};
use nlos_transient::{Scan, TimeAxis};

use crate::error::{OptimError, Result};
use crate::prune::delta;
use crate::reflectance::ConcreteBrdf;

/// Settings of boundary growth ([`crate::ReconstructParams::grow`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GrowParams {
    /// Angles θ (degrees, in [0, 90]) by which a proposal turns away from the wall about its edge (default
    /// 0°, 30°, 60°: flat continuation to a steeply receding rim).
    pub angles: Vec<f64>,
    /// Margin κ ≥ 0 of the test (module docs; default 0.5, as pruning).
    pub margin: f64,
}

impl Default for GrowParams {
    fn default() -> Self {
        Self { angles: vec![0.0, 30.0, 60.0], margin: 0.5 }
    }
}

impl GrowParams {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for no angle, an angle outside [0, 90] or a negative margin.
    pub fn validate(&self) -> Result<()> {
        if self.angles.is_empty() {
            return Err(OptimError::InvalidParameter {
                name: "grow.angles",
                value: 0.0,
                reason: "growth needs at least one proposal angle (0 continues the surface flat)",
            });
        }
        if let Some(a) = self.angles.iter().find(|a| !(**a >= 0.0 && **a <= 90.0)) {
            return Err(OptimError::InvalidParameter {
                name: "grow.angles",
                value: *a,
                reason: "proposal angles lie in [0, 90] degrees (turning away from the wall)",
            });
        }
        if !(self.margin >= 0.0 && self.margin.is_finite()) {
            return Err(OptimError::InvalidParameter {
                name: "grow.margin",
                value: self.margin,
                reason: "the margin κ is finite and ≥ 0 (0: the plain sign test)",
            });
        }
        Ok(())
    }
}

/// What one call of [`grow_boundary`] did (one per block in the run's checkpoint).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GrowRecord {
    /// Stage.
    pub stage: u32,
    /// Block within the stage.
    pub block: u32,
    /// Boundary edges proposed across.
    pub edges: usize,
    /// Faces added.
    pub added: usize,
    /// Change of the normalised data term from the additions (≤ 0).
    pub data_change: f64,
}

/// The result of [`grow_boundary`]: the new vertices (appended after the old ones) and faces.
#[derive(Debug, Clone, PartialEq)]
pub struct Grown {
    /// New vertex positions, numbered from the old vertex count on.
    pub positions: Vec<Vec3>,
    /// New faces (referring to old and new vertices).
    pub triangles: Vec<[u32; 3]>,
    /// Boundary edges proposed across.
    pub edges: usize,
    /// `Σ ΔE⁺` of the additions (unnormalised data term).
    pub data_change: f64,
}

/// Proposes and adds faces across the boundary edges of the mesh `positions`/`triangles` (module docs).
///
/// `rendered` is the mesh's forward pass with `brdf` (measurement-major, `bins` per histogram; updated in
/// place: the added faces' shares are added), `row_loss(m, row)` the data term of histogram `m` at the
/// block's scale, `render` the block's render settings (visibility is switched off for the proposals).
///
/// # Errors
/// [`OptimError::InvalidParameter`] for invalid `params`, [`OptimError::LengthMismatch`] when `rendered`
/// is not measurements × `bins` long, and the errors of `row_loss` and of the renderer.
#[allow(clippy::too_many_arguments)]
pub fn grow_boundary(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    scan: &Scan,
    time: &TimeAxis,
    render: RenderParams,
    brdf: &ConcreteBrdf,
    rendered: &mut [f32],
    bins: usize,
    row_loss: &(dyn Fn(usize, &[f32]) -> Result<f64> + Sync),
    params: &GrowParams,
) -> Result<Grown> {
    params.validate()?;
    let rows = scan.measurements();
    if bins == 0 || rendered.len() != rows * bins {
        return Err(OptimError::LengthMismatch { what: "rendered", expected: rows * bins, got: rendered.len() });
    }
    // Boundary half-edges a → b (of face a b c) are those whose twin b → a belongs to no face.
    let mut directed = std::collections::HashSet::with_capacity(triangles.len() * 3);
    for t in triangles {
        for k in 0..3 {
            directed.insert((t[k], t[(k + 1) % 3]));
        }
    }
    let mut edges: Vec<(u32, u32, Vec3)> = Vec::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            if !directed.contains(&(b, a)) {
                edges.push((a, b, positions[c as usize]));
            }
        }
    }
    // Proposals: one triangle (b, a, p) per edge and angle, each on its own three vertices.
    let mut prop_pos: Vec<Vec3> = Vec::with_capacity(edges.len() * params.angles.len() * 3);
    let mut prop_tri: Vec<[u32; 3]> = Vec::with_capacity(edges.len() * params.angles.len());
    let mut prop_of: Vec<(usize, Vec3)> = Vec::new();
    for (e, &(a, b, c)) in edges.iter().enumerate() {
        let (pa, pb) = (positions[a as usize], positions[b as usize]);
        let edge = pb - pa;
        let len = edge.length();
        let n = edge.cross(c - pa).normalize_or_zero();
        if !(len > 0.0) || n == Vec3::ZERO {
            continue;
        }
        let mid = 0.5 * (pa + pb);
        let mut out = edge.cross(n).normalize_or_zero();
        if out.dot(mid - c) < 0.0 {
            out = -out;
        }
        // Away from the wall: the side the face's normal does not point to (faces face the wall, n·ẑ < 0);
        // for a face seen edge-on, +z.
        let away = if n.z.abs() < 1e-6 {
            Vec3::Z
        } else if n.z < 0.0 {
            -n
        } else {
            n
        };
        let h = len * 3f32.sqrt() / 2.0;
        for &theta in &params.angles {
            let th = (theta as f32).to_radians();
            let p = mid + h * (th.cos() * out + th.sin() * away);
            let base = prop_pos.len() as u32;
            prop_pos.extend([pb, pa, p]);
            prop_tri.push([base, base + 1, base + 2]);
            prop_of.push((e, p));
        }
    }
    if prop_tri.is_empty() {
        return Ok(Grown { positions: Vec::new(), triangles: Vec::new(), edges: edges.len(), data_change: 0.0 });
    }
    let r = Renderer::new(&prop_pos, &prop_tri, scan, time, RenderParams { visibility: Visibility::Off, ..render })?;
    let mut base: Vec<f64> =
        rendered.par_chunks(bins).enumerate().map(|(m, row)| row_loss(m, row)).collect::<Result<_>>()?;
    let snapshot: &[f32] = rendered;
    let scored: Vec<(f64, usize)> = (0..prop_tri.len())
        .into_par_iter()
        .map(|i| {
            let spans = brdf.forward_triangle(&r, i)?;
            if spans.is_empty() {
                return Ok((f64::INFINITY, i));
            }
            Ok((delta(&spans, snapshot, &base, bins, row_loss, params.margin, true)?.0, i))
        })
        .collect::<Result<_>>()?;
    // The best proposal per edge, if it passes.
    let mut best: Vec<Option<(f64, usize)>> = vec![None; edges.len()];
    for &(test, i) in &scored {
        let e = prop_of[i].0;
        if test < 0.0 && best[e].is_none_or(|(t, _)| test < t) {
            best[e] = Some((test, i));
        }
    }
    let mut order: Vec<(f64, usize)> = best.into_iter().flatten().collect();
    order.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let n_old = positions.len() as u32;
    let mut used = std::collections::HashSet::new();
    let (mut new_pos, mut new_tri, mut change) = (Vec::new(), Vec::new(), 0.0);
    for (_, i) in order {
        let (e, p) = prop_of[i];
        let (a, b, _) = edges[e];
        if used.contains(&a) || used.contains(&b) {
            continue;
        }
        let spans = brdf.forward_triangle(&r, i)?;
        let (test, d) = delta(&spans, rendered, &base, bins, row_loss, params.margin, true)?;
        if !(test < 0.0) {
            continue;
        }
        for s in &spans {
            let row = &mut rendered[s.measurement * bins..(s.measurement + 1) * bins];
            for (x, v) in row[s.first_bin..].iter_mut().zip(&s.values) {
                *x += v;
            }
            base[s.measurement] = row_loss(s.measurement, row)?;
        }
        used.insert(a);
        used.insert(b);
        new_tri.push([b, a, n_old + new_pos.len() as u32]);
        new_pos.push(p);
        change += d;
    }
    Ok(Grown { positions: new_pos, triangles: new_tri, edges: edges.len(), data_change: change })
}
