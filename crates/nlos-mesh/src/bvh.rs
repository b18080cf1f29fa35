//! Closest-point queries on a triangle set through a bounding volume hierarchy.
//!
//! The hierarchy is built by `obvhs` (PLOC, Meister & Bittner 2018; the same crate the renderer uses for
//! rays); the nearest-point traversal is written here: children are visited nearest box first and pruned
//! by the best squared distance so far.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;

use crate::error::MeshError;
use crate::handles::FaceId;
use crate::surface_mesh::SurfaceMesh;

/// Result of a closest-point query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPoint {
    /// The closest point on the triangle set.
    pub point: Vec3,
    /// Squared distance from the query to `point`.
    pub distance_squared: f32,
    /// Index of the triangle it lies on (into the triangle list given at construction; for
    /// [`TriangleBvh::from_mesh`], see [`TriangleBvh::face_id`]).
    pub triangle: u32,
    /// Barycentric coordinates of `point` in that triangle (weights of its corners 0, 1, 2).
    pub barycentric: Vec3,
}

impl ClosestPoint {
    /// Distance from the query to the closest point.
    pub fn distance(&self) -> f32 {
        self.distance_squared.sqrt()
    }
}

/// A static BVH over triangles for closest-point and box-overlap queries.
pub struct TriangleBvh {
    bvh: Bvh2,
    tris: Vec<[Vec3A; 3]>,
    faces: Vec<FaceId>,
}

impl std::fmt::Debug for TriangleBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriangleBvh")
            .field("triangles", &self.tris.len())
            .field("nodes", &self.bvh.nodes.len())
            .finish()
    }
}

impl TriangleBvh {
    /// BVH over the live faces of `mesh`. Errors on a mesh without faces or with non-finite positions.
    pub fn from_mesh(mesh: &SurfaceMesh) -> Result<Self, MeshError> {
        let faces: Vec<FaceId> = mesh.faces().collect();
        let tris: Vec<[Vec3A; 3]> = faces.iter().map(|&f| mesh.face_points(f).map(Vec3A::from)).collect();
        Self::build(tris, faces)
    }

    /// BVH over indexed triangles. Errors on an empty list, out-of-range indices or non-finite positions.
    pub fn from_triangles(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Self, MeshError> {
        let mut tris = Vec::with_capacity(triangles.len());
        for (i, t) in triangles.iter().enumerate() {
            let mut c = [Vec3A::ZERO; 3];
            for k in 0..3 {
                let p = positions.get(t[k] as usize).ok_or(MeshError::IndexOutOfRange {
                    face: i,
                    index: t[k] as u64,
                    vertex_count: positions.len(),
                })?;
                c[k] = Vec3A::from(*p);
            }
            tris.push(c);
        }
        let faces = (0..triangles.len()).map(FaceId::new).collect();
        Self::build(tris, faces)
    }

    fn build(tris: Vec<[Vec3A; 3]>, faces: Vec<FaceId>) -> Result<Self, MeshError> {
        if tris.is_empty() {
            return Err(MeshError::EmptyMesh { what: "a closest-point BVH" });
        }
        for (i, t) in tris.iter().enumerate() {
            if !t.iter().all(|p| p.is_finite()) {
                return Err(MeshError::NonFinitePosition { vertex: i, position: Vec3::from(t[0]).to_array() });
            }
        }
        let aabbs: Vec<Aabb> =
            tris.iter().map(|t| Aabb::new(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))).collect();
        let mut time = std::time::Duration::ZERO;
        let bvh = obvhs::bvh2::builder::build_bvh2(&aabbs, obvhs::BvhBuildParams::fast_build(), &mut time);
        Ok(Self { bvh, tris, faces })
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether there are no triangles (never true for a constructed BVH).
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// The mesh face of triangle `i` (for [`Self::from_mesh`]; the identity for [`Self::from_triangles`]).
    pub fn face_id(&self, triangle: u32) -> FaceId {
        self.faces.get(triangle as usize).copied().unwrap_or(FaceId::INVALID)
    }

    /// Corners of triangle `i`.
    pub fn triangle(&self, i: u32) -> [Vec3; 3] {
        self.tris[i as usize].map(Vec3::from)
    }

    /// The closest point on the triangles to `p`.
    pub fn closest_point(&self, p: Vec3) -> ClosestPoint {
        // The BVH is never empty, so a result always exists.
        self.closest_point_within(p, f32::INFINITY).unwrap_or(ClosestPoint {
            point: p,
            distance_squared: f32::INFINITY,
            triangle: u32::MAX,
            barycentric: Vec3::ZERO,
        })
    }

    /// The closest point if one lies within `max_distance` of `p`. A small `max_distance` (e.g. for points
    /// known to be near the surface) prunes most of the tree.
    pub fn closest_point_within(&self, p: Vec3, max_distance: f32) -> Option<ClosestPoint> {
        self.closest_point_filtered(p, max_distance, |_| true)
    }

    /// The closest point within `max_distance` among the triangles `accept` returns true for (e.g. only
    /// triangles facing a given direction, to avoid snapping onto a nearby sheet of a thin part).
    pub fn closest_point_filtered(
        &self,
        p: Vec3,
        max_distance: f32,
        mut accept: impl FnMut(u32) -> bool,
    ) -> Option<ClosestPoint> {
        let q = Vec3A::from(p);
        let mut best_d2 = if max_distance.is_finite() { max_distance * max_distance } else { f32::INFINITY };
        let mut best: Option<ClosestPoint> = None;
        let nodes = &self.bvh.nodes;
        // Fixed-size stack: each pop pushes at most two children, so depth + 1 entries suffice; obvhs trees
        // are far shallower than 128 levels for any mesh that fits in memory, and a deeper one falls back to
        // the heap below.
        let mut stack = [(0u32, 0f32); 128];
        let mut overflow: Vec<(u32, f32)> = Vec::new();
        let mut len = 1usize;
        stack[0] = (0, box_distance_squared(nodes[0].aabb(), q));
        loop {
            let (ni, d2) = if let Some(x) = overflow.pop() {
                x
            } else if len > 0 {
                len -= 1;
                stack[len]
            } else {
                break;
            };
            if d2 > best_d2 {
                continue;
            }
            let node = &nodes[ni as usize];
            if node.is_leaf() {
                let start = node.first_index as usize;
                for k in start..start + node.prim_count as usize {
                    let ti = self.bvh.primitive_indices[k];
                    let t = &self.tris[ti as usize];
                    let (c, bary) = closest_point_on_triangle(q, t[0], t[1], t[2]);
                    let d = c.distance_squared(q);
                    if d <= best_d2 && accept(ti) {
                        best_d2 = d;
                        best = Some(ClosestPoint {
                            point: Vec3::from(c),
                            distance_squared: d,
                            triangle: ti,
                            barycentric: bary,
                        });
                    }
                }
            } else {
                let l = node.first_index;
                let r = l + 1;
                let dl = box_distance_squared(nodes[l as usize].aabb(), q);
                let dr = box_distance_squared(nodes[r as usize].aabb(), q);
                // push the farther child first so the nearer one is visited first; skip pruned children
                let (near, far) = if dl <= dr { ((l, dl), (r, dr)) } else { ((r, dr), (l, dl)) };
                for item in [far, near] {
                    if item.1 > best_d2 {
                        continue;
                    }
                    if len < stack.len() && overflow.is_empty() {
                        stack[len] = item;
                        len += 1;
                    } else {
                        overflow.push(item);
                    }
                }
            }
        }
        best
    }

    /// Whether some triangle lies within `max_distance` of `p` (inclusive). Stops at the first one found, so
    /// it is much cheaper than [`Self::closest_point_within`] when only the answer matters (tolerance
    /// checks).
    pub fn any_within(&self, p: Vec3, max_distance: f32) -> bool {
        let q = Vec3A::from(p);
        let r2 = max_distance * max_distance;
        let nodes = &self.bvh.nodes;
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        if box_distance_squared(nodes[0].aabb(), q) <= r2 {
            stack.push(0);
        }
        while let Some(ni) = stack.pop() {
            let node = &nodes[ni as usize];
            if node.is_leaf() {
                let start = node.first_index as usize;
                for k in start..start + node.prim_count as usize {
                    let t = &self.tris[self.bvh.primitive_indices[k] as usize];
                    if closest_point_on_triangle(q, t[0], t[1], t[2]).0.distance_squared(q) <= r2 {
                        return true;
                    }
                }
            } else {
                let l = node.first_index;
                let dl = box_distance_squared(nodes[l as usize].aabb(), q);
                let dr = box_distance_squared(nodes[l as usize + 1].aabb(), q);
                // nearer child on top of the stack
                let (near, far) = if dl <= dr { ((l, dl), (l + 1, dr)) } else { ((l + 1, dr), (l, dl)) };
                for (n, d) in [far, near] {
                    if d <= r2 {
                        stack.push(n);
                    }
                }
            }
        }
        false
    }

    /// The closest point to `p`, searching first within `hint` (cheap when `p` is known to be close to the
    /// surface) and then everywhere.
    pub fn closest_point_near(&self, p: Vec3, hint: f32) -> ClosestPoint {
        match self.closest_point_within(p, hint) {
            Some(c) => c,
            None => self.closest_point(p),
        }
    }

    /// The first intersection of the ray `origin + t·direction`, `0 ≤ t ≤ t_max`, with the triangles (both
    /// faces count), found by front-to-back traversal pruned by the nearest hit so far; each triangle is
    /// tested with [`ray_triangle`]. `t` is in units of `|direction|` (metres for a unit direction). `None`
    /// when nothing is hit, or for a non-finite or zero `origin`/`direction` or a NaN `t_max`.
    pub fn ray_first_hit(&self, origin: Vec3, direction: Vec3, t_max: f32) -> Option<RayHit> {
        if !origin.is_finite() || !direction.is_finite() || direction == Vec3::ZERO || t_max.is_nan() {
            return None;
        }
        let nodes = &self.bvh.nodes;
        let mut best_t = t_max;
        let mut best: Option<RayHit> = None;
        let mut stack: Vec<(u32, f32)> = Vec::with_capacity(64);
        if let Some(t) = ray_box_entry(nodes[0].aabb(), origin, direction, best_t) {
            stack.push((0, t));
        }
        while let Some((ni, entry)) = stack.pop() {
            if entry > best_t {
                continue;
            }
            let node = &nodes[ni as usize];
            if node.is_leaf() {
                let start = node.first_index as usize;
                for k in start..start + node.prim_count as usize {
                    let ti = self.bvh.primitive_indices[k];
                    let tri = self.tris[ti as usize].map(Vec3::from);
                    if let Some((t, barycentric)) = ray_triangle(origin, direction, tri, best_t)
                        && (best.is_none() || t < best_t)
                    {
                        best_t = t;
                        best = Some(RayHit { t, point: origin + direction * t, triangle: ti, barycentric });
                    }
                }
            } else {
                let (l, r) = (node.first_index, node.first_index + 1);
                let tl = ray_box_entry(nodes[l as usize].aabb(), origin, direction, best_t);
                let tr = ray_box_entry(nodes[r as usize].aabb(), origin, direction, best_t);
                // push the farther child first so the nearer one is visited first
                match (tl, tr) {
                    (Some(a), Some(b)) if a <= b => stack.extend([(r, b), (l, a)]),
                    (Some(a), Some(b)) => stack.extend([(l, a), (r, b)]),
                    (Some(a), None) => stack.push((l, a)),
                    (None, Some(b)) => stack.push((r, b)),
                    (None, None) => {}
                }
            }
        }
        best
    }

    /// Calls `f(triangle)` for every triangle whose bounding box overlaps the box `[lo, hi]`.
    pub fn for_each_overlapping(&self, lo: Vec3, hi: Vec3, mut f: impl FnMut(u32)) {
        let query = Aabb::new(Vec3A::from(lo), Vec3A::from(hi));
        self.bvh.aabb_traverse(query, |bvh, node_index| {
            let node = &bvh.nodes[node_index as usize];
            let start = node.first_index as usize;
            for k in start..start + node.prim_count as usize {
                let ti = bvh.primitive_indices[k];
                let t = &self.tris[ti as usize];
                let tlo = t[0].min(t[1]).min(t[2]);
                let thi = t[0].max(t[1]).max(t[2]);
                if tlo.cmple(query.max).all() && thi.cmpge(query.min).all() {
                    f(ti);
                }
            }
            true
        });
    }
}

/// Result of a ray query ([`TriangleBvh::ray_first_hit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Ray parameter of the hit: `point = origin + t·direction`.
    pub t: f32,
    /// The hit point.
    pub point: Vec3,
    /// Index of the triangle hit (as in [`ClosestPoint::triangle`]).
    pub triangle: u32,
    /// Barycentric coordinates of `point` in that triangle (weights of its corners 0, 1, 2).
    pub barycentric: Vec3,
}

/// Tolerance of [`ray_triangle`] on the barycentric coordinates: a hit is accepted for `u, v ≥ −ε` and
/// `u + v ≤ 1 + ε`. The test runs in `f64` on `f32` corners, so its rounding (≈ 1e−15 relative) is far below ε:
/// a ray through an edge or vertex shared by two triangles hits at least one of them (no cracks), and an
/// open boundary grows by at most ε of an edge length (1 nm on a 1 m edge).
pub const RAY_BARYCENTRIC_EPSILON: f64 = 1e-9;

/// Rays closer to parallel to a triangle's plane than this (sine of the angle between ray and plane) miss
/// it; zero-area triangles are always missed.
pub const RAY_PARALLEL_EPSILON: f64 = 1e-12;

/// Möller–Trumbore ray–triangle intersection (Möller & Trumbore 1997), both faces, in `f64`: the hit of
/// `origin + t·direction` with triangle `tri`, `0 ≤ t ≤ t_max`, as `(t, barycentric)` with the weights of
/// corners 0, 1, 2. Edge tolerance [`RAY_BARYCENTRIC_EPSILON`]; near-parallel rays and zero-area triangles
/// per [`RAY_PARALLEL_EPSILON`] miss.
pub fn ray_triangle(origin: Vec3, direction: Vec3, tri: [Vec3; 3], t_max: f32) -> Option<(f32, Vec3)> {
    let [a, b, c] = tri.map(|p| p.as_dvec3());
    let (o, d) = (origin.as_dvec3(), direction.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    // |det| = |e1 × e2|·|d|·sin(angle between ray and plane)
    let scale = e1.cross(e2).length() * d.length();
    // also rejects NaN (non-finite corners)
    if det.abs() <= RAY_PARALLEL_EPSILON * scale || det.is_nan() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(-RAY_BARYCENTRIC_EPSILON..=1.0 + RAY_BARYCENTRIC_EPSILON).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < -RAY_BARYCENTRIC_EPSILON || u + v > 1.0 + RAY_BARYCENTRIC_EPSILON {
        return None;
    }
    let t = e2.dot(q) * inv;
    if !(0.0..=t_max as f64).contains(&t) {
        return None;
    }
    Some((t as f32, Vec3::new((1.0 - u - v) as f32, u as f32, v as f32)))
}

/// Entry parameter of the ray into box `b` if it meets the box within `[0, t_max]` (slab test). Axes with a
/// zero direction component test the origin against the slab directly (no infinities), and the exit is
/// widened by a few ulps so that boxes of flat or axis-aligned triangles touched exactly are not missed.
#[inline]
fn ray_box_entry(b: &Aabb, o: Vec3, d: Vec3, t_max: f32) -> Option<f32> {
    let (lo, hi) = (Vec3::from(b.min), Vec3::from(b.max));
    let (mut t0, mut t1) = (0.0f32, t_max);
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
        } else {
            let inv = 1.0 / d[k];
            let (a, c) = ((lo[k] - o[k]) * inv, (hi[k] - o[k]) * inv);
            let (near, far) = if a <= c { (a, c) } else { (c, a) };
            t0 = t0.max(near);
            // 1 + 2γ₃ (Pharr, Jakob & Humphreys, PBRT 3rd ed., §3.9.2) keeps the test conservative
            t1 = t1.min(far * (1.0 + 4.0 * f32::EPSILON) + f32::MIN_POSITIVE);
        }
    }
    (t0 <= t1).then_some(t0)
}

#[inline]
fn box_distance_squared(b: &Aabb, p: Vec3A) -> f32 {
    let d = (b.min - p).max(p - b.max).max(Vec3A::ZERO);
    d.length_squared()
}

/// Closest point on triangle `(a, b, c)` to `p` and its barycentric coordinates (Ericson, *Real-Time
/// Collision Detection*, §5.1.5: Voronoi regions of vertices, then edges, then the face).
pub(crate) fn closest_point_on_triangle(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> (Vec3A, Vec3) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Vec3::X);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Vec3::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        // Guard: d1 - d3 = |ab|² > 0 here unless ab is degenerate, in which case a is as good as any.
        let den = d1 - d3;
        let v = if den > 0.0 { d1 / den } else { 0.0 };
        return (a + ab * v, Vec3::new(1.0 - v, v, 0.0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Vec3::Z);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let den = d2 - d6;
        let w = if den > 0.0 { d2 / den } else { 0.0 };
        return (a + ac * w, Vec3::new(1.0 - w, 0.0, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let den = (d4 - d3) + (d5 - d6);
        let w = if den > 0.0 { (d4 - d3) / den } else { 0.0 };
        return (b + (c - b) * w, Vec3::new(0.0, 1.0 - w, w));
    }
    let sum = va + vb + vc;
    // Guard: a degenerate (zero-area) triangle that reached the face region: fall back to vertex a.
    if sum.is_nan() || sum <= 0.0 || sum.is_infinite() {
        return (a, Vec3::X);
    }
    let denom = 1.0 / sum;
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Vec3::new(1.0 - v - w, v, w))
}
