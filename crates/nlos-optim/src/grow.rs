//! Loss-driven boundary growth: add faces beyond the boundary where the measurement asks for more surface.
//!
//! The counterpart of [`crate::prune`]. An initial surface from a thresholded volume stops short where the
//! object is dim (grazing flanks, a receding rim), and neither the shape steps (which move vertices) nor
//! the remeshing (which keeps the boundary where it is) can extend it. Growth proposes a strip one triangle
//! height wide around the boundary: every boundary vertex `v` gets a new vertex `p_v` at
//! `v + h (cos θ · o_v + sin θ · a_v)`, with `o_v` the mean outward direction (in the faces' planes,
//! perpendicular to its boundary edges), `a_v` the side of the surface away from the wall, `h = ℓ·√3/2`
//! for the mean boundary edge length `ℓ`, and θ ∈ [`GrowParams::angles`] (a silhouette recedes: the surface
//! turns parallel to the line of sight). Every boundary edge `a → b` proposes the quad `a b p_b p_a` (two
//! triangles, `b a p_a` and `b p_a p_b`, oriented like the mesh) at each angle, and keeps its best one when
//! ```text
//! ΔE⁺ = E(I + I_quad) − E(I) < −κ · ½ c      (c = E(I + 2I_quad) − 2E(I + I_quad) + E(I); crate::prune)
//! ```
//! i.e. when the measurement holds light the rendering lacks, in the quad's bins, by more than `(1 + κ)/2`
//! of the quad's own share. Proposals are rendered without occlusion (they lie beyond the mesh's boundary),
//! with the block's samples and kernel. Accepted quads are added greedily from the lowest test value, each
//! re-tested against the rendering the additions before it have left; neighbouring quads share their new
//! vertex (placed by the first of them), so runs of accepted edges add a strip without gaps or overlaps.

use std::collections::{HashMap, HashSet};

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use nlos_render::{RenderParams, Renderer, RowSpan, Visibility};
use nlos_transient::{Scan, TimeAxis};

use crate::error::{OptimError, Result};
use crate::prune::{RowLoss, apply_spans, delta};
use crate::reflectance::ConcreteBrdf;

/// Settings of boundary growth ([`crate::ReconstructParams::grow`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GrowParams {
    /// Angles θ (degrees, in [0, 90]) by which a proposal turns away from the wall about its edge (default
    /// 0°, 30°, 60°: flat continuation to a steeply receding rim).
    pub angles: Vec<f64>,
    /// Margin κ ≥ 0 of the test (module docs; default 0.5, as pruning).
    pub margin: f64,
    /// Grow only in the first this many coarse-to-fine stages (default `None`: every stage). The coarse
    /// stages' faces are larger, so each proposal's share stands further above the noise.
    pub stages: Option<u32>,
}

impl Default for GrowParams {
    fn default() -> Self {
        Self { angles: vec![0.0, 30.0, 60.0], margin: 0.5, stages: None }
    }
}

impl GrowParams {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for no angle, an angle outside [0, 90], a negative margin or
    /// `stages = Some(0)`.
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
        if self.stages == Some(0) {
            return Err(OptimError::InvalidParameter {
                name: "grow.stages",
                value: 0.0,
                reason: "growth in no stage: give at least 1, or switch growth off",
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
    /// Faces added (two per accepted edge).
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
/// place: the added faces' shares are added), `row_loss` the data term of histogram `m` ([`RowLoss`]) at the
/// block's scale, `render` the block's render settings (visibility is switched off for the proposals).
///
/// # Errors
/// [`OptimError::InvalidParameter`] for invalid `params`, [`OptimError::LengthMismatch`] when `rendered`
/// is not measurements × `bins` long, [`OptimError::Render`] (`IndexOutOfRange`) for a triangle that names
/// a vertex beyond `positions`, and the errors of `row_loss` and of the renderer.
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
    row_loss: &RowLoss<'_>,
    params: &GrowParams,
) -> Result<Grown> {
    params.validate()?;
    let rows = scan.measurements();
    if bins == 0 || rendered.len() != rows * bins {
        return Err(OptimError::LengthMismatch { what: "rendered", expected: rows * bins, got: rendered.len() });
    }
    if let Some((triangle, &vertex)) = triangles
        .iter()
        .enumerate()
        .find_map(|(i, t)| t.iter().find(|&&v| v as usize >= positions.len()).map(|v| (i, v)))
    {
        return Err(nlos_render::RenderError::IndexOutOfRange { triangle, vertex, vertices: positions.len() }.into());
    }
    // Boundary half-edges a → b (of face a b c) are those whose twin b → a belongs to no face.
    let mut directed = HashSet::with_capacity(triangles.len() * 3);
    for t in triangles {
        for k in 0..3 {
            directed.insert((t[k], t[(k + 1) % 3]));
        }
    }
    // Per boundary edge: its ends, outward direction in the face's plane, the face's unit normal, length.
    struct Edge {
        a: u32,
        b: u32,
        out: Vec3,
        normal: Vec3,
        len: f32,
    }
    let mut edges: Vec<Edge> = Vec::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            if directed.contains(&(b, a)) {
                continue;
            }
            let (pa, pb, pc) = (positions[a as usize], positions[b as usize], positions[c as usize]);
            let edge = pb - pa;
            let normal = edge.cross(pc - pa).normalize_or_zero();
            let mut out = edge.cross(normal).normalize_or_zero();
            if out.dot(0.5 * (pa + pb) - pc) < 0.0 {
                out = -out;
            }
            let len = edge.length();
            if len > 0.0 && normal != Vec3::ZERO && out != Vec3::ZERO {
                edges.push(Edge { a, b, out, normal, len });
            }
        }
    }
    // Per boundary vertex: the mean outward direction, normal and edge length of its boundary edges.
    let mut frame: HashMap<u32, (Vec3, Vec3, f32, u32)> = HashMap::new();
    for e in &edges {
        for v in [e.a, e.b] {
            let f = frame.entry(v).or_insert((Vec3::ZERO, Vec3::ZERO, 0.0, 0));
            f.0 += e.out;
            f.1 += e.normal;
            f.2 += e.len;
            f.3 += 1;
        }
    }
    let offset = |v: u32, theta: f64| -> Vec3 {
        let (o, n, len, k) = frame[&v];
        let (o, n) = (o.normalize_or_zero(), n.normalize_or_zero());
        // Away from the wall: the side the faces' normals do not point to (they face the wall, n·ẑ < 0);
        // +z for a rim seen edge-on.
        let away = if n.z.abs() < 1e-6 {
            Vec3::Z
        } else if n.z < 0.0 {
            -n
        } else {
            n
        };
        let h = len / k as f32 * 3f32.sqrt() / 2.0;
        let th = (theta as f32).to_radians();
        positions[v as usize] + h * (th.cos() * o + th.sin() * away)
    };
    let quad = |e: &Edge, pa: Vec3, pb: Vec3| -> Result<Vec<RowSpan>> {
        let (qa, qb) = (positions[e.a as usize], positions[e.b as usize]);
        // The strip quad a b p_b p_a as (b, a, p_a) and (b, p_a, p_b): b → a is the twin of the boundary a → b.
        let r = Renderer::new(
            &[qb, qa, pa, pb],
            &[[0, 1, 2], [0, 2, 3]],
            scan,
            time,
            RenderParams { visibility: Visibility::Off, ..render },
        )?;
        let mut spans = brdf.forward_triangle(&r, 0)?;
        spans.extend(brdf.forward_triangle(&r, 1)?);
        Ok(merge(spans))
    };
    let snapshot: &[f32] = rendered;
    // The best angle per edge (both ends turned alike), if it passes.
    let scored: Vec<Option<(f64, f64)>> = edges
        .par_iter()
        .map(|e| {
            let mut best: Option<(f64, f64)> = None;
            for &theta in &params.angles {
                let spans = quad(e, offset(e.a, theta), offset(e.b, theta))?;
                if spans.is_empty() {
                    continue;
                }
                let (test, _) = delta(&spans, snapshot, bins, row_loss, params.margin, true)?;
                if test < 0.0 && best.is_none_or(|(t, _)| test < t) {
                    best = Some((test, theta));
                }
            }
            Ok(best)
        })
        .collect::<Result<_>>()?;
    let mut order: Vec<(f64, usize, f64)> =
        scored.iter().enumerate().filter_map(|(i, b)| b.map(|(t, theta)| (t, i, theta))).collect();
    order.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    // New vertex of each boundary vertex, once placed (shared by the quads of its two boundary edges).
    let n_old = positions.len() as u32;
    let mut placed: HashMap<u32, (u32, Vec3)> = HashMap::new();
    let (mut new_pos, mut new_tri, mut change) = (Vec::new(), Vec::new(), 0.0);
    for (_, i, theta) in order {
        let e = &edges[i];
        let pa = placed.get(&e.a).map_or_else(|| offset(e.a, theta), |p| p.1);
        let pb = placed.get(&e.b).map_or_else(|| offset(e.b, theta), |p| p.1);
        // Re-test at the placed positions against the rendering the additions so far have left.
        let spans = quad(e, pa, pb)?;
        let (test, d) = delta(&spans, rendered, bins, row_loss, params.margin, true)?;
        if !(test < 0.0) {
            continue;
        }
        apply_spans(&spans, rendered, bins, true);
        let mut id = |v: u32, p: Vec3| {
            placed
                .entry(v)
                .or_insert_with(|| {
                    new_pos.push(p);
                    (n_old + new_pos.len() as u32 - 1, p)
                })
                .0
        };
        let (ia, ib) = (id(e.a, pa), id(e.b, pb));
        new_tri.push([e.b, e.a, ia]);
        new_tri.push([e.b, ia, ib]);
        change += d;
    }
    Ok(Grown { positions: new_pos, triangles: new_tri, edges: edges.len(), data_change: change })
}

/// Merges spans of the same measurement into one (summing the overlapping bins), in measurement order.
fn merge(mut spans: Vec<RowSpan>) -> Vec<RowSpan> {
    spans.sort_by_key(|s| s.measurement);
    let mut out: Vec<RowSpan> = Vec::with_capacity(spans.len());
    for s in spans {
        match out.last_mut() {
            Some(last) if last.measurement == s.measurement => {
                let first = last.first_bin.min(s.first_bin);
                let end = (last.first_bin + last.values.len()).max(s.first_bin + s.values.len());
                let mut values = vec![0.0f32; end - first];
                for span in [&*last, &s] {
                    for (k, v) in span.values.iter().enumerate() {
                        values[span.first_bin - first + k] += v;
                    }
                }
                *last = RowSpan { measurement: s.measurement, first_bin: first, values };
            }
            _ => out.push(s),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_sums_spans_of_one_measurement() {
        let span = |m, f, v: &[f32]| RowSpan { measurement: m, first_bin: f, values: v.to_vec() };
        let merged = merge(vec![span(3, 5, &[1.0, 2.0]), span(1, 0, &[4.0]), span(3, 4, &[1.0, 1.0, 1.0, 1.0])]);
        assert_eq!(merged, vec![span(1, 0, &[4.0]), span(3, 4, &[1.0, 2.0, 3.0, 1.0])]);
    }
}
