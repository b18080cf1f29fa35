//! Collision resolution in El Topo's order (Brochu & Bridson 2009, §4, after Bridson, Fedkiw & Anderson
//! 2002): proximity repulsion, collision impulses, rigid impact zones, and a fail-safe that shortens the
//! step of the vertices still involved.
//!
//! The step is a map from start positions `x₀` (f32) to end positions `x₁` (f32); the motion is the
//! straight line between them. Displacements play the role of velocities over a unit time step and all
//! masses are equal. Corrections are computed in `f64` and rounded to `f32` once per pass; a vertex no
//! stage touches keeps its `x₁ = x₀ + d` bit for bit (`f32 → f64 → f32` is exact).
//!
//! Every correction acts along a normal `n` on the relative position `r = Σ wᵢ xᵢ` of a pair, with weights
//! `w = (1, −α, −β, −γ)` (vertex, triangle barycentrics) or `(1−s, s, −(1−u), −u)` (edge–edge): the
//! impulse `j = Δ / Σ wᵢ²` moves vertex `i` by `wᵢ·j·n`, which changes `n·r` by exactly `Δ` (Bridson et al.
//! 2002, eq. 4 with equal masses). `n` is oriented so that the pair starts on the positive side.

use glam::{DMat3, DQuat, DVec3, Vec3};
use rayon::prelude::*;

use std::time::Instant;

use super::EvolveTimings;
use super::broad::{Pairs, QUERY_CHUNK, Topo, candidate_pairs};
use super::ccd::{Moving, edge_edge_ccd, point_triangle_distance, segment_segment_distance, vertex_triangle_ccd};

/// A pair's four vertices: `[p, a, b, c]` (vertex–triangle) or `[a, b, c, d]` (edge–edge).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pair {
    pub verts: [u32; 4],
    pub edge_edge: bool,
    /// (vertex, face) or (edge, edge) indices into [`Topo`]: with `edge_edge`, the canonical order.
    pub key: (u32, u32),
}

/// A detected collision: the pair and its earliest contact time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Collision {
    pub pair: Pair,
    pub t: f64,
}

fn pairs_of(topo: &Topo, c: &Pairs) -> Vec<Pair> {
    let mut out = Vec::with_capacity(c.vt.len() + c.ee.len());
    for &(v, f) in &c.vt {
        let [a, b, cc] = topo.faces[f as usize];
        out.push(Pair { verts: [v, a, b, cc], edge_edge: false, key: (v, f) });
    }
    for &(e0, e1) in &c.ee {
        let [a, b] = topo.edges[e0 as usize];
        let [cc, d] = topo.edges[e1 as usize];
        out.push(Pair { verts: [a, b, cc, d], edge_edge: true, key: (e0, e1) });
    }
    out
}

/// `moving[v]`: whether `x₁[v] ≠ x₀[v]` (bitwise).
pub(crate) fn moving_flags(x0: &[Vec3], x1: &[Vec3]) -> Vec<bool> {
    x0.iter().zip(x1).map(|(a, b)| a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits)).collect()
}

/// Which end positions changed since a pass last looked at them. A pair none of whose vertices changed
/// gives the same answer as then (the tests depend on `x₀` and `x₁` only), so later passes re-examine only
/// pairs with a changed vertex: in a step where few vertices need resolution the passes after the first cost
/// little.
#[derive(Debug, Default)]
pub(crate) struct Changes {
    snapshot: Option<Vec<Vec3>>,
}

impl Changes {
    /// `Some(changed)` (bitwise) since the last [`Changes::mark`]; `None` before the first (everything).
    fn since(&self, x1: &[Vec3]) -> Option<Vec<bool>> {
        self.snapshot.as_ref().map(|s| moving_flags(s, x1))
    }
    fn mark(&mut self, x1: &[Vec3]) {
        match &mut self.snapshot {
            Some(s) => s.copy_from_slice(x1),
            None => self.snapshot = Some(x1.to_vec()),
        }
    }
}

/// Collision detection across passes: keeps the last result and re-tests only pairs with a changed vertex.
#[derive(Debug, Default)]
pub(crate) struct Detector {
    changes: Changes,
    last: Vec<Collision>,
}

impl Detector {
    /// All collisions of the motion `x₀ → x₁` (CCD with distance tolerance `tol`), earliest time per pair,
    /// in the canonical pair order (vertex–triangle by vertex and face, then edge–edge by edges).
    pub(crate) fn detect(
        &mut self,
        topo: &Topo,
        x0: &[Vec3],
        x1: &[Vec3],
        tol: f64,
        time: &mut EvolveTimings,
    ) -> Vec<Collision> {
        let active = self.changes.since(x1);
        if let Some(a) = &active
            && !a.contains(&true)
        {
            return self.last.clone();
        }
        let clock = Instant::now();
        let moving = moving_flags(x0, x1);
        let cands = candidate_pairs(topo, x0, x1, tol as f32, &moving, active.as_deref());
        let pairs = pairs_of(topo, &cands);
        time.broad_phase += clock.elapsed();
        let fresh = detect_among(&pairs, x0, x1, tol, time);
        self.finish(fresh, active.as_deref(), x1)
    }

    /// The first detection from pairs a broad phase over every vertex produced for these very `x₀`, `x₁`
    /// with a padding of at least `tol` (the proximity pass's when it pushed nothing).
    pub(crate) fn detect_first_among(
        &mut self,
        pairs: &[Pair],
        x0: &[Vec3],
        x1: &[Vec3],
        tol: f64,
        time: &mut EvolveTimings,
    ) -> Vec<Collision> {
        debug_assert!(self.changes.snapshot.is_none());
        let fresh = detect_among(pairs, x0, x1, tol, time);
        self.finish(fresh, None, x1)
    }

    fn finish(&mut self, fresh: Vec<Collision>, active: Option<&[bool]>, x1: &[Vec3]) -> Vec<Collision> {
        let mut out = fresh;
        if let Some(a) = active {
            out.extend(self.last.iter().filter(|c| c.pair.verts.iter().all(|&v| !a[v as usize])).copied());
            out.sort_unstable_by_key(|c| (c.pair.edge_edge, c.pair.key));
        }
        self.changes.mark(x1);
        self.last.clone_from(&out);
        out
    }
}

/// The collisions among `pairs` (a broad-phase result for these very `x₀`, `x₁` with a padding of at
/// least `tol`, e.g. the proximity pass's when it moved nothing).
pub(crate) fn detect_among(
    pairs: &[Pair],
    x0: &[Vec3],
    x1: &[Vec3],
    tol: f64,
    time: &mut EvolveTimings,
) -> Vec<Collision> {
    let clock = Instant::now();
    let out = pairs
        .par_iter()
        .with_min_len(QUERY_CHUNK / 4)
        .filter_map(|p| {
            let m = p.verts.map(|v| Moving::new(x0[v as usize], x1[v as usize]));
            let t = if p.edge_edge {
                edge_edge_ccd(&m[0], &m[1], &m[2], &m[3], tol)
            } else {
                vertex_triangle_ccd(&m[0], &m[1], &m[2], &m[3], tol)
            }?;
            Some(Collision { pair: *p, t })
        })
        .collect();
    time.narrow_phase += clock.elapsed();
    out
}

/// Weights and the relative position `r = Σ wᵢ xᵢ` of a pair at positions `x`.
fn weights_at(p: &Pair, x: [DVec3; 4]) -> ([f64; 4], DVec3) {
    let w = if p.edge_edge {
        let (_, s, u) = segment_segment_distance(x[0], x[1], x[2], x[3]);
        [1.0 - s, s, -(1.0 - u), -u]
    } else {
        let (_, b) = point_triangle_distance(x[0], x[1], x[2], x[3]);
        [1.0, -b[0], -b[1], -b[2]]
    };
    let r = (0..4).fold(DVec3::ZERO, |acc, k| acc + w[k] * x[k]);
    (w, r)
}

#[inline]
fn rel(w: &[f64; 4], x: &[DVec3], verts: &[u32; 4]) -> DVec3 {
    (0..4).fold(DVec3::ZERO, |acc, k| acc + w[k] * x[verts[k] as usize])
}

/// Applies the impulse that makes `n · r ≥ target` (no-op if it already holds). Returns whether it moved.
fn push_apart(x1: &mut [DVec3], verts: &[u32; 4], w: &[f64; 4], n: DVec3, target: f64) -> bool {
    let s1 = n.dot(rel(w, x1, verts));
    let delta = target - s1;
    let w2: f64 = w.iter().map(|x| x * x).sum();
    // Guard: Σw² ≥ 1/2 for any convex weights (the two sides each sum to 1), so the division is safe;
    // a non-finite delta (degenerate n) is skipped.
    if !(delta > 0.0 && delta.is_finite() && w2 > 0.0) {
        return false;
    }
    let j = delta / w2;
    for k in 0..4 {
        x1[verts[k] as usize] += (w[k] * j) * n;
    }
    true
}

/// A proximity job: the pair, its weights, normal and target separation.
type Job = (Pair, [f64; 4], DVec3, f64);

/// Stage 1 across passes: keeps the last pass's jobs so that later passes recompute only those of pairs with
/// a changed vertex (a job depends on `x₀` and `x₁` of its pair only); the sweep itself runs over all jobs.
#[derive(Debug, Default)]
pub(crate) struct Proximity {
    changes: Changes,
    last: Vec<Job>,
}

impl Proximity {
    /// Stage 1, proximity repulsion: every pair that ends closer than `eps` and closer than it started is
    /// pushed apart along the direction between its closest points at the end of the step (or, when they
    /// touch there, at its start) until `n·r ≥ min(eps, start separation)`. One Gauss–Seidel sweep in the
    /// canonical pair order; returns the number of pairs pushed and the broad-phase pairs (padded by `eps`:
    /// on the first pass, when nothing was pushed, they serve [`Detector::detect_first_among`]).
    pub(crate) fn pass(
        &mut self,
        topo: &Topo,
        x0: &[Vec3],
        x1: &mut [Vec3],
        eps: f64,
        time: &mut EvolveTimings,
    ) -> (usize, Vec<Pair>) {
        let active = self.changes.since(x1);
        self.changes.mark(x1);
        let mut jobs: Vec<Job>;
        let mut pairs = Vec::new();
        if active.as_ref().is_some_and(|a| !a.contains(&true)) {
            jobs = self.last.clone();
        } else {
            let clock = Instant::now();
            let moving = moving_flags(x0, x1);
            let cands = candidate_pairs(topo, x0, x1, eps as f32, &moving, active.as_deref());
            pairs = pairs_of(topo, &cands);
            time.broad_phase += clock.elapsed();
            let clock = Instant::now();
            // geometry of each close pair, computed in parallel on the unmodified end positions
            jobs = pairs.par_iter().with_min_len(QUERY_CHUNK).filter_map(|p| proximity_job(p, x0, x1, eps)).collect();
            time.narrow_phase += clock.elapsed();
            if let Some(a) = &active {
                jobs.extend(self.last.iter().filter(|j| j.0.verts.iter().all(|&v| !a[v as usize])).copied());
                jobs.sort_unstable_by_key(|j| (j.0.edge_edge, j.0.key));
            }
        }
        self.last.clone_from(&jobs);
        if jobs.is_empty() {
            return (0, pairs);
        }
        let mut xd: Vec<DVec3> = x1.iter().map(|p| p.as_dvec3()).collect();
        let mut pushed = 0;
        for (p, w, n, target) in &jobs {
            if push_apart(&mut xd, &p.verts, w, *n, *target) {
                pushed += 1;
            }
        }
        write_back(&xd, x1, &jobs.iter().flat_map(|j| j.0.verts).collect::<Vec<_>>());
        (pushed, pairs)
    }
}

/// The proximity job of pair `p`, if it ends closer than `eps` and closer than it started.
fn proximity_job(p: &Pair, x0: &[Vec3], x1: &[Vec3], eps: f64) -> Option<Job> {
    let e = p.verts.map(|v| x1[v as usize].as_dvec3());
    let s = p.verts.map(|v| x0[v as usize].as_dvec3());
    let (w1, r1) = weights_at(p, e);
    let d1 = r1.length();
    if d1 >= eps {
        return None;
    }
    let (w0, r0) = weights_at(p, s);
    let d0 = r0.length();
    if d1 >= d0 {
        return None; // not approaching: leave pairs that were already this close alone
    }
    // Guard: closest points that (nearly) coincide at the end give no direction: use the start's.
    let (w, n) = if d1 > 1e-3 * eps { (w1, r1 / d1) } else { (w0, r0 / d0.max(f64::MIN_POSITIVE)) };
    let n = if n.dot(rel(&w, &s, &[0, 1, 2, 3])) < 0.0 { -n } else { n };
    let start_sep = n.dot(rel(&w, &s, &[0, 1, 2, 3]));
    Some((*p, w, n, eps.min(start_sep)))
}

/// Rounds the touched vertices back to `f32` (others are not rewritten at all).
fn write_back(xd: &[DVec3], x1: &mut [Vec3], touched: &[u32]) {
    for &v in touched {
        let p = xd[v as usize].as_vec3();
        // Guard: a correction cannot create a non-finite position from finite data, but never store one.
        if p.is_finite() {
            x1[v as usize] = p;
        }
    }
}

/// Stage 2, collision impulses: for each collision, at its contact time, the normal (triangle normal;
/// cross product of the edges; or the direction between closest points if those degenerate) oriented to
/// the side the pair starts on, and an impulse that restores `n·r ≥ min(eps, start separation)` at the end.
/// One Gauss–Seidel sweep over `collisions`; returns the number of impulses applied.
pub(crate) fn collision_pass(collisions: &[Collision], x0: &[Vec3], x1: &mut [Vec3], eps: f64) -> usize {
    let mut xd: Vec<DVec3> = x1.iter().map(|p| p.as_dvec3()).collect();
    let mut applied = 0;
    for c in collisions {
        let v = c.pair.verts;
        let m = v.map(|k| Moving::new(x0[k as usize], xd[k as usize].as_vec3()));
        let xt = m.map(|q| q.at(c.t));
        let (w, r) = weights_at(&c.pair, xt);
        let geo =
            if c.pair.edge_edge { (xt[1] - xt[0]).cross(xt[3] - xt[2]) } else { (xt[2] - xt[1]).cross(xt[3] - xt[1]) };
        let start: Vec<DVec3> = m.iter().map(|q| q.x0).collect();
        let r0 = rel(&w, &start, &[0, 1, 2, 3]);
        // Guard: a degenerate triangle / parallel edges give no plane normal; fall back to the closest-point
        // direction at contact, then at the start, then against the relative motion.
        let dr = m.iter().enumerate().fold(DVec3::ZERO, |acc, (k, q)| acc + w[k] * q.dx);
        let n = [geo, r, r0, -dr].into_iter().find(|x| x.length_squared() > 1e-24).map(|x| x.normalize());
        let Some(mut n) = n else { continue };
        let s0 = n.dot(r0);
        if s0 < 0.0 || (s0 == 0.0 && n.dot(dr) > 0.0) {
            n = -n;
        }
        let target = eps.min(n.dot(r0).max(0.0));
        if push_apart(&mut xd, &v, &w, n, target) {
            applied += 1;
        }
    }
    let touched: Vec<u32> = collisions.iter().flat_map(|c| c.pair.verts).collect();
    write_back(&xd, x1, &touched);
    applied
}

/// Union–find over vertices, for impact zones.
pub(crate) type Zones = crate::UnionFind;

/// Stage 3, rigid impact zones (Provot 1997; Bridson et al. 2002 §7.4): merges the vertices of every
/// collision into zones (kept across passes) and replaces the motion of each zone that a collision touches
/// by the rigid motion with the same linear and angular momentum: `x₁ᵢ = x̄₀ + v̄ + R(ω)(x₀ᵢ − x̄₀)`,
/// `ω = I⁻¹L`. Returns the number of zones made rigid.
pub(crate) fn impact_zone_pass(collisions: &[Collision], zones: &mut Zones, x0: &[Vec3], x1: &mut [Vec3]) -> usize {
    for c in collisions {
        let v = c.pair.verts;
        for k in 1..4 {
            zones.union(v[0], v[k]);
        }
    }
    let mut roots: Vec<u32> = collisions.iter().map(|c| zones.find(c.pair.verts[0])).collect();
    roots.sort_unstable();
    roots.dedup();
    let mut members: std::collections::HashMap<u32, Vec<u32>> = roots.iter().map(|&r| (r, Vec::new())).collect();
    for v in 0..x0.len() as u32 {
        let r = zones.find(v);
        if let Some(m) = members.get_mut(&r) {
            m.push(v);
        }
    }
    for verts in members.values() {
        let n = verts.len() as f64;
        let p0: Vec<DVec3> = verts.iter().map(|&v| x0[v as usize].as_dvec3()).collect();
        let dx: Vec<DVec3> = verts.iter().zip(&p0).map(|(&v, p)| x1[v as usize].as_dvec3() - *p).collect();
        let c0 = p0.iter().copied().sum::<DVec3>() / n;
        let vbar = dx.iter().copied().sum::<DVec3>() / n;
        let mut l = DVec3::ZERO;
        let mut inertia = DMat3::ZERO;
        for (p, d) in p0.iter().zip(&dx) {
            let r = *p - c0;
            l += r.cross(*d - vbar);
            inertia += DMat3::from_diagonal(DVec3::splat(r.length_squared())) - outer(r, r);
        }
        // Guard: collinear zones have a singular inertia tensor: then no rotation (translation only).
        let det = inertia.determinant();
        let scale = inertia.x_axis.x + inertia.y_axis.y + inertia.z_axis.z;
        let omega =
            if det.abs() > 1e-9 * scale.powi(3) && det.is_finite() { inertia.inverse() * l } else { DVec3::ZERO };
        let angle = omega.length();
        let rot = if angle > 0.0 && angle.is_finite() {
            DQuat::from_axis_angle(omega / angle, angle)
        } else {
            DQuat::IDENTITY
        };
        for (&v, p) in verts.iter().zip(&p0) {
            let q = (c0 + vbar + rot * (*p - c0)).as_vec3();
            if q.is_finite() {
                x1[v as usize] = q;
            }
        }
    }
    members.len()
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Stage 4, fail-safe: every vertex of a remaining collision that still moves has its step halved the
/// first time and cancelled (`x₁ = x₀`) the second (`halvings[v]` counts). Returns the number of vertices
/// changed. Terminates the outer loop: every collision has a moving vertex (static pairs are never
/// candidates), and each vertex can be changed at most twice.
pub(crate) fn failsafe_pass(collisions: &[Collision], halvings: &mut [u8], x0: &[Vec3], x1: &mut [Vec3]) -> usize {
    let mut changed = 0;
    let mut seen = vec![false; x0.len()];
    for c in collisions {
        for &v in &c.pair.verts {
            let i = v as usize;
            if seen[i] || x1[i] == x0[i] {
                continue;
            }
            seen[i] = true;
            changed += 1;
            if halvings[i] == 0 {
                halvings[i] = 1;
                x1[i] = x0[i] + (x1[i] - x0[i]) * 0.5;
            } else {
                halvings[i] = 2;
                x1[i] = x0[i];
            }
        }
    }
    changed
}
