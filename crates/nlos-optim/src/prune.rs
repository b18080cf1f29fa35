//! Loss-driven boundary pruning: delete the boundary faces the measurement says are not there.
//!
//! The shape steps move vertices; they cannot change where the surface ends. An initial surface taken from a
//! blurred volume (LCT) ends too far out where the object's silhouette recedes (the albedo halo, a rim at
//! the wrong depth), and gradient steps only bend such a rim, never remove it. Pruning asks the data term
//! directly: for a boundary face `f` with rendered share `I_f` (`nlos_render::Renderer::forward_triangle`,
//! same samples, kernel and cached visibility as the forward pass, so `Σ_f I_f = I`),
//! ```text
//! ΔE_f = E(I − I_f) − E(I)      (scale s held at the block's value)
//! ```
//! is the exact change of the data term if `f` were deleted. For the L2 term it is
//! `s⟨s I − Ĩ, I_f⟩ · (−1) + ½ s² ‖I_f‖²`: negative exactly when the face adds light where the rendering
//! already exceeds the measurement by more than half the face's own contribution. A face of the true
//! surface has `E[ΔE_f] = +½ s²‖I_f‖² > 0` under zero-mean noise, a face where nothing is has
//! `E[ΔE_f] = −½ s²‖I_f‖²`, so the sign test is unbiased and needs no threshold; faces that receive no light
//! have `ΔE_f = 0`: nothing supports them, and they go too (unobservable faces, usually a rim folded behind
//! the object or turned away from the wall, would otherwise stay wherever the start put them).
//!
//! **Margin.** Deletions interact (faces overlap in time), and with noise the sign is uncertain for faces
//! whose share is small, so a face goes only when `ΔE_f < −κ · ½ c_f`, with `c_f = ΔE_f(+) + ΔE_f(−)` the
//! second difference of the data term along the face's share (`E(I + I_f) + E(I − I_f) − 2E(I)`, which is
//! `s²‖I_f‖²` for L2): with κ = ½, the rendering must exceed the measurement, in the face's bins, by ¾ of the
//! face's own contribution. A face nothing supports has `ΔE_f = −½ c_f` and still goes. Additions
//! ([`crate::residual`]) take `c_f` from the forward difference
//! `E(I + 2I_f) − 2E(I + I_f) + E(I)`, the same `s²‖I_f‖²` for L2.
//!
//! Per round, every face with a boundary edge is tested (in parallel); faces with `ΔE_f < 0` are deleted
//! greedily from the most negative, each re-tested against the rendering left by the deletions before it
//! (their shares overlap in time and measurement). A deletion that would pinch a vertex into two fans (a
//! non-manifold "bow tie") is skipped. Later rounds test the faces the deletions exposed (and those a pinch
//! held back): deletions only lower the rendering, and for a convex data term that only raises a face's
//! test value, so a face that failed would fail again (up to rounding: on the bunny one face in 6,500 went
//! differently in two blocks). At most
//! [`PruneParams::max_fraction`] of the faces go per call.

use std::collections::HashMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::data_term::RowLoss;
use crate::error::{OptimError, Result};
use nlos_render::AnyBrdf;
use nlos_render::{Renderer, RowSpan};

/// Settings of boundary pruning ([`crate::ReconstructParams::prune`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PruneParams {
    /// Rounds per call: each tests the faces on the boundary the previous round left (≥ 1; default 3).
    pub rounds: u32,
    /// Largest share of the faces deleted per call, in (0, 1] (default 0.2): a guard against a data term
    /// that is wrong everywhere (a bad scale) eating the mesh in one block.
    pub max_fraction: f64,
    /// Margin κ ≥ 0 of the test (module docs): a face goes when `ΔE_f < −κ · ½ c_f`, `c_f` the data term's
    /// second difference along the face's share. 0 is the plain sign test; 1 deletes only faces that
    /// nothing in the measurement supports. Default 0.5.
    pub margin: f64,
}

impl Default for PruneParams {
    fn default() -> Self {
        Self { rounds: 3, max_fraction: 0.2, margin: 0.5 }
    }
}

impl PruneParams {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for `rounds = 0` or `max_fraction` outside (0, 1].
    pub fn validate(&self) -> Result<()> {
        if self.rounds == 0 {
            return Err(OptimError::InvalidParameter {
                name: "prune.rounds",
                value: 0.0,
                reason: "pruning needs at least one round (or switch pruning off)",
            });
        }
        if !(self.max_fraction > 0.0 && self.max_fraction <= 1.0) {
            return Err(OptimError::InvalidParameter {
                name: "prune.max_fraction",
                value: self.max_fraction,
                reason: "the share of faces a pruning may delete lies in (0, 1]",
            });
        }
        if !(self.margin >= 0.0 && self.margin.is_finite()) {
            return Err(OptimError::InvalidParameter {
                name: "prune.margin",
                value: self.margin,
                reason: "the margin κ is finite and ≥ 0 (0: the plain sign test)",
            });
        }
        Ok(())
    }
}

/// What one call of [`prune_boundary`] did (one per block in the run's checkpoint).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PruneRecord {
    /// Stage.
    pub stage: u32,
    /// Block within the stage.
    pub block: u32,
    /// Face tests made (a face tested in several rounds counts each time).
    pub tested: usize,
    /// Faces deleted.
    pub removed: usize,
    /// Change of the (unnormalised) data term from the deletions, `Σ ΔE_f` (≤ 0).
    pub data_change: f64,
}

/// The result of [`prune_boundary`].
#[derive(Debug, Clone, PartialEq)]
pub struct Pruned {
    /// Per input triangle: kept (`true`) or deleted.
    pub keep: Vec<bool>,
    /// Face tests made.
    pub tested: usize,
    /// Faces deleted.
    pub removed: usize,
    /// `Σ ΔE_f` of the deletions (unnormalised data term).
    pub data_change: f64,
}

/// Deletes boundary faces whose removal lowers the data term (module docs).
///
/// `renderer` holds the mesh `triangles` at the current positions, `rendered` its forward pass with `brdf`
/// (measurement-major, `bins` per histogram; updated in place: the deleted faces' shares are subtracted),
/// and `row_loss` the data term of histogram `m` ([`RowLoss`]) at the block's
/// scale (`DataTerm::row_value_in`, `SensorFit::row_value_in`).
///
/// # Errors
/// [`OptimError::InvalidParameter`] for invalid `params`, [`OptimError::LengthMismatch`] when `rendered`
/// is not measurements × `bins` long, and the errors of `row_loss` and of the renderer.
pub fn prune_boundary(
    triangles: &[[u32; 3]],
    renderer: &Renderer,
    brdf: &AnyBrdf,
    rendered: &mut [f32],
    bins: usize,
    row_loss: &RowLoss<'_>,
    params: &PruneParams,
) -> Result<Pruned> {
    params.validate()?;
    let rows = renderer.scan().measurements();
    if bins == 0 || rendered.len() != rows * bins {
        return Err(OptimError::LengthMismatch { what: "rendered", expected: rows * bins, got: rendered.len() });
    }
    let nt = triangles.len();
    let budget = ((nt as f64 * params.max_fraction).floor() as usize).min(nt.saturating_sub(1));
    let mut keep = vec![true; nt];
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(nt * 2);
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let n_vertices = triangles.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
    let mut vertex_faces: Vec<Vec<usize>> = vec![Vec::new(); n_vertices];
    for (f, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            *edges.entry(key(t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            vertex_faces[t[k] as usize].push(f);
        }
    }
    let (mut tested, mut removed, mut change) = (0usize, 0usize, 0.0f64);
    // Faces whose test failed. Deletions only lower the rendering, and for a data term convex in it (L2,
    // the Poisson deviance, with or without the sensor's convolution) a lower rendering raises both ΔE_f
    // and the curvature c_f: a face that failed fails again, and later rounds test only the faces the
    // deletions exposed (or that a pinch held back).
    let mut settled = vec![false; nt];

    for _ in 0..params.rounds {
        let candidates: Vec<usize> = (0..nt)
            .filter(|&f| {
                let t = triangles[f];
                keep[f] && !settled[f] && (0..3).any(|k| edges.get(&key(t[k], t[(k + 1) % 3])) == Some(&1))
            })
            .collect();
        if candidates.is_empty() || removed >= budget {
            break;
        }
        tested += candidates.len();
        let snapshot: &[f32] = rendered;
        let mut scored: Vec<(f64, usize, Vec<RowSpan>)> = candidates
            .par_iter()
            .map(|&f| {
                let spans = renderer.forward_triangle_any(brdf, f)?;
                let (d, _) = delta(&spans, snapshot, bins, row_loss, params.margin, false)?;
                Ok((d, f, spans))
            })
            .collect::<Result<_>>()?;
        // A face no measurement sees (empty share: facing away, occluded, out of the time window) is
        // unsupported whatever the data say: it goes first (it changes no rendering, so no order among them).
        for s in &mut scored {
            if s.2.is_empty() {
                s.0 = f64::NEG_INFINITY;
            }
        }
        for (d, f, _) in &scored {
            settled[*f] = !(*d < 0.0);
        }
        scored.retain(|(d, _, _)| *d < 0.0);
        scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let before = removed;
        for (_, f, spans) in scored {
            if removed >= budget {
                break;
            }
            // Re-test against the rendering the deletions so far have left.
            let (test, d) = delta(&spans, rendered, bins, row_loss, params.margin, false)?;
            if !(test < 0.0 || spans.is_empty()) {
                settled[f] = true;
                continue;
            }
            if pinches(f, triangles, &keep, &vertex_faces) {
                continue;
            }
            apply_spans(&spans, rendered, bins, false);
            row_loss.applied(&spans, false)?;
            keep[f] = false;
            let t = triangles[f];
            for k in 0..3 {
                if let Some(c) = edges.get_mut(&key(t[k], t[(k + 1) % 3])) {
                    *c -= 1;
                }
            }
            removed += 1;
            change += d;
        }
        if removed == before {
            break;
        }
    }
    Ok(Pruned { keep, tested, removed, data_change: change })
}

/// Subtracts (`add` false) or adds a face's share `spans` to `rendered`.
pub(crate) fn apply_spans(spans: &[RowSpan], rendered: &mut [f32], bins: usize, add: bool) {
    for s in spans {
        let row = &mut rendered[s.measurement * bins..(s.measurement + 1) * bins];
        for (x, v) in row[s.first_bin..].iter_mut().zip(&s.values) {
            // Guard: f32 cancellation can leave −ε where a deleted face was the only light.
            *x = if add { *x + v } else { (*x - v).max(0.0) };
        }
    }
}

/// The test value and the change of the data term of deleting (`add` false: `ΔE = E(I − I_f) − E(I)`) or
/// adding (`add` true: `E(I + I_f) − E(I)`) a face with share `spans`, over the histograms it reaches; the
/// test value is `ΔE + κ · ½ c_f` (module docs) and the move is made when it is negative.
///
/// `c_f` is the second difference of the data term along the share, taken on the side where the rendering
/// stays a sum of faces: for a deletion `E(I + I_f) + E(I − I_f) − 2E(I)`, where `I − I_f ≥ 0` because `f`
/// is part of `I`; for an addition `E(I + 2I_f) − 2E(I + I_f) + E(I)`. (Additions once used the central
/// difference too, but `I − I_f` is negative where the new face is the only light; the guard that clamps
/// it to 0 shrank `c_f`, and with it the margin, to as little as a third.) Both are `s²‖I_f‖²` for L2.
pub(crate) fn delta(
    spans: &[RowSpan],
    rendered: &[f32],
    bins: usize,
    row_loss: &RowLoss<'_>,
    margin: f64,
    add: bool,
) -> Result<(f64, f64)> {
    // `once`: ΔE of the move; `other`: the second point of the second difference (E(I + I_f) − E(I) for a
    // deletion, E(I + 2I_f) − E(I) for an addition).
    let ks: &[f32] = match (add, margin > 0.0) {
        (false, false) => &[-1.0],
        (false, true) => &[-1.0, 1.0],
        (true, false) => &[1.0],
        (true, true) => &[1.0, 2.0],
    };
    let (mut once, mut other) = (0.0, 0.0);
    for s in spans {
        let m = s.measurement;
        let changes = row_loss.changes(m, &rendered[m * bins..(m + 1) * bins], s, ks)?;
        // A `RowTerm` written outside this crate may answer with another length: an error, not a panic.
        if changes.len() != ks.len() {
            return Err(OptimError::LengthMismatch {
                what: "RowTerm::changes",
                expected: ks.len(),
                got: changes.len(),
            });
        }
        once += changes[0];
        other += changes.get(1).copied().unwrap_or(0.0);
    }
    // c_f from the three points (0, once, other) of the data term along the share.
    let c = if add { other - 2.0 * once } else { once + other };
    Ok((once + margin * 0.5 * c, once))
}

/// Whether deleting face `f` leaves one of its vertices with two separate fans of faces (a vertex where
/// two boundary loops touch: not a manifold mesh).
pub(crate) fn pinches(f: usize, triangles: &[[u32; 3]], keep: &[bool], vertex_faces: &[Vec<usize>]) -> bool {
    triangles[f].iter().any(|&v| fans(v, triangles, vertex_faces, |g| g != f && keep[g]).len() > 1)
}

/// Clears `keep` for the faces that leave a vertex pinched between two or more fans once the faces already
/// cleared are gone: each pinched vertex keeps its largest fan and loses the others, and the vertices of the
/// faces lost are checked in turn, until no vertex of `seeds` (or of a face lost since) is pinched. Returns
/// the faces it cleared. Deleting faces from a manifold mesh pinches vertices but never an edge, so what is
/// kept afterwards is a manifold mesh again.
pub(crate) fn unpinch(
    seeds: impl IntoIterator<Item = u32>,
    triangles: &[[u32; 3]],
    vertex_faces: &[Vec<usize>],
    keep: &mut [bool],
) -> Vec<usize> {
    let mut check: Vec<u32> = seeds.into_iter().collect();
    let mut lost = Vec::new();
    while let Some(v) = check.pop() {
        let mut fans = fans(v, triangles, vertex_faces, |g| keep[g]);
        if fans.len() < 2 {
            continue;
        }
        fans.sort_by_key(|f| std::cmp::Reverse(f.len()));
        for f in fans.into_iter().skip(1).flatten() {
            keep[f] = false;
            lost.push(f);
            check.extend(triangles[f]);
        }
    }
    lost
}

/// The faces around each vertex (indices into `triangles`), for [`fans`] and [`unpinch`].
pub(crate) fn vertex_faces(n_vertices: usize, triangles: &[[u32; 3]]) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = vec![Vec::new(); n_vertices];
    for (f, t) in triangles.iter().enumerate() {
        for &v in t {
            out[v as usize].push(f);
        }
    }
    out
}

/// The fans of the faces around vertex `v` for which `present` holds: groups of faces joined by an edge at
/// `v`. One fan (or none) is a manifold vertex; two or more, a pinch.
pub(crate) fn fans(
    v: u32,
    triangles: &[[u32; 3]],
    vertex_faces: &[Vec<usize>],
    present: impl Fn(usize) -> bool,
) -> Vec<Vec<usize>> {
    let fan: Vec<usize> = vertex_faces[v as usize].iter().copied().filter(|&g| present(g)).collect();
    // Two faces are adjacent when they share an edge at v.
    let others = |g: usize| triangles[g].into_iter().filter(move |&w| w != v);
    let mut component = vec![usize::MAX; fan.len()];
    let mut out: Vec<Vec<usize>> = Vec::new();
    for start in 0..fan.len() {
        if component[start] != usize::MAX {
            continue;
        }
        component[start] = out.len();
        let (mut members, mut stack) = (vec![fan[start]], vec![start]);
        while let Some(i) = stack.pop() {
            for j in 0..fan.len() {
                if component[j] == usize::MAX && others(fan[i]).any(|w| others(fan[j]).any(|u| u == w)) {
                    component[j] = out.len();
                    members.push(fan[j]);
                    stack.push(j);
                }
            }
        }
        out.push(members);
    }
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::data_term::RowTerm;

    /// A fan of 4 triangles around vertex 0 (a closed-off square cut into 4) plus one more.
    fn square() -> Vec<[u32; 3]> {
        // 1---2
        // | \ |     centre 0, corners 1..4
        vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]]
    }

    /// L2 row loss ½ Σ (s·r − m)² against a fixed measured row, scale `s`.
    fn l2(measured: Vec<f32>, s: f64) -> impl Fn(usize, &[f32], std::ops::Range<usize>) -> Result<f64> + Sync {
        move |_, row: &[f32], w: std::ops::Range<usize>| {
            Ok(row[w.clone()]
                .iter()
                .zip(&measured[w])
                .map(|(&r, &m)| 0.5 * (s * f64::from(r) - f64::from(m)).powi(2))
                .sum())
        }
    }

    /// The default `RowTerm::changes` on a share past the row's end changes nothing, and a term answering
    /// with the wrong number of changes is a typed error in `delta`.
    #[test]
    fn out_of_range_shares_and_short_answers_are_not_panics() {
        let row_loss = l2(vec![0.0; 4], 1.0);
        let late = RowSpan { measurement: 0, first_bin: 9, values: vec![0.5, 0.5] };
        assert_eq!(row_loss.changes(0, &[0.1; 4], &late, &[-1.0, 1.0]).unwrap(), [0.0, 0.0]);
        struct Short;
        impl RowTerm for Short {
            fn value(&self, _: usize, _: &[f32], _: std::ops::Range<usize>) -> Result<f64> {
                Ok(0.0)
            }
            fn changes(&self, _: usize, _: &[f32], _: &RowSpan, _: &[f32]) -> Result<Vec<f64>> {
                Ok(Vec::new())
            }
        }
        let spans = [RowSpan { measurement: 0, first_bin: 0, values: vec![0.5] }];
        let err = delta(&spans, &[0.5; 4], 4, &Short, 0.5, false).unwrap_err();
        assert!(matches!(err, OptimError::LengthMismatch { what: "RowTerm::changes", expected: 2, got: 0 }), "{err}");
    }

    #[test]
    fn addition_margin_is_the_full_curvature_where_the_face_is_the_only_light() {
        // Regression: additions took c_f from E(I + I_f) + E(I − I_f) − 2E(I) with I − I_f clamped at 0,
        // which shrinks c_f wherever the new face is the only light. For L2 c_f = s²‖I_f‖² exactly.
        let (bins, s) = (6, 2.0);
        let rendered = vec![0.0, 0.0, 0.5, 0.0, 0.0, 0.0];
        let measured = vec![0.0, 0.3, 1.0, 0.2, 0.0, 0.0];
        let row_loss = l2(measured, s);
        let base = [row_loss(0, &rendered, 0..rendered.len()).unwrap()];
        let spans = [RowSpan { measurement: 0, first_bin: 1, values: vec![0.1, 0.4, 0.2] }];
        let norm2: f64 = spans[0].values.iter().map(|&v| f64::from(v).powi(2)).sum();
        for margin in [0.0, 0.5, 1.0] {
            let (test, change) = delta(&spans, &rendered, bins, &row_loss, margin, true).unwrap();
            let mut added = rendered.clone();
            for (x, v) in added[1..].iter_mut().zip(&spans[0].values) {
                *x += v;
            }
            let exact = row_loss(0, &added, 0..added.len()).unwrap() - base[0];
            assert!((change - exact).abs() < 1e-9, "{change} vs {exact}");
            let want = exact + margin * 0.5 * s * s * norm2;
            assert!((test - want).abs() < 1e-6, "margin {margin}: test {test}, want {want}");
        }
        // A deletion of the same share from a rendering that holds it: the same curvature.
        let mut holding = rendered.clone();
        for (x, v) in holding[1..].iter_mut().zip(&spans[0].values) {
            *x += v;
        }
        let (test, change) = delta(&spans, &holding, bins, &row_loss, 1.0, false).unwrap();
        assert!((test - change - 0.5 * s * s * norm2).abs() < 1e-6);
    }

    #[test]
    fn pinching_is_detected_at_a_vertex_between_two_fans() {
        let t = square();
        let vf: Vec<Vec<usize>> = (0..5).map(|v| (0..4).filter(|&f| t[f].contains(&v)).collect()).collect();
        // Full fan: deleting any face opens it, no pinch.
        assert!(!(0..4).any(|f| pinches(f, &t, &[true; 4], &vf)));
        // With face 0 gone, deleting face 2 (opposite) would leave faces 1 and 3 touching only at 0.
        let keep = [false, true, true, true];
        assert!(pinches(2, &t, &keep, &vf));
        assert!(!pinches(1, &t, &keep, &vf) && !pinches(3, &t, &keep, &vf));
    }

    #[test]
    fn unpinching_keeps_the_largest_fan() {
        // Square fan of four faces around vertex 0, plus a fifth face hanging off face 1's outer edge.
        let mut t = square();
        t.push([t[1][1], t[1][2], 5]);
        let vf = vertex_faces(6, &t);
        assert_eq!(vf[0], vec![0, 1, 2, 3]);
        // Faces 0 and 2 (opposite) gone: 1 and 3 touch only at vertex 0, two fans of one face each there; one
        // is kept, the other lost, and no vertex is pinched after.
        let mut keep = vec![false, true, false, true, true];
        let lost = unpinch(t[0].iter().chain(&t[2]).copied(), &t, &vf, &mut keep);
        assert_eq!(lost.len(), 1);
        assert!((0..6).all(|v| fans(v, &t, &vf, |g| keep[g]).len() < 2), "{keep:?}");
        // Nothing pinched: nothing lost.
        let mut all = vec![true; 5];
        assert!(unpinch(0..6, &t, &vf, &mut all).is_empty() && all.iter().all(|&k| k));
    }

    #[test]
    fn params_are_validated() {
        assert!(PruneParams::default().validate().is_ok());
        assert!(PruneParams { rounds: 0, ..PruneParams::default() }.validate().is_err());
        for f in [0.0, -0.1, 1.5, f64::NAN] {
            assert!(PruneParams { max_fraction: f, ..PruneParams::default() }.validate().is_err());
        }
    }
}
