//! Exact triangle–triangle intersection and mesh self-intersection detection.
//!
//! The tests use only orientation predicates, evaluated exactly with Shewchuk's adaptive arithmetic
//! (`robust` crate; `f32` inputs convert to `f64` exactly), so touching, coplanar and shared-edge
//! configurations are decided without tolerance. Two non-coplanar triangles intersect iff an edge of one
//! meets the other (the intersection segment's endpoints lie on edges); coplanar ones are tested in the
//! 2D projection that drops the dominant normal axis.

use glam::Vec3;
use robust::{Coord, Coord3D, orient2d, orient3d};

use crate::bvh::TriangleBvh;
use crate::error::MeshError;
use crate::handles::FaceId;
use crate::surface_mesh::SurfaceMesh;

#[inline]
fn c3(p: Vec3) -> Coord3D<f32> {
    Coord3D { x: p.x, y: p.y, z: p.z }
}

/// Sign of `orient3d(a, b, c, d)`: +1, 0 or −1, exact.
#[inline]
fn o3(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> i8 {
    let v = orient3d(c3(a), c3(b), c3(c), c3(d));
    if v > 0.0 {
        1
    } else if v < 0.0 {
        -1
    } else {
        0
    }
}

/// 2D projection dropping axis `drop`.
#[inline]
fn proj(p: Vec3, drop: usize) -> Coord<f32> {
    match drop {
        0 => Coord { x: p.y, y: p.z },
        1 => Coord { x: p.z, y: p.x },
        _ => Coord { x: p.x, y: p.y },
    }
}

#[inline]
fn o2(a: Vec3, b: Vec3, c: Vec3, drop: usize) -> i8 {
    let v = orient2d(proj(a, drop), proj(b, drop), proj(c, drop));
    if v > 0.0 {
        1
    } else if v < 0.0 {
        -1
    } else {
        0
    }
}

/// The axis along which the normal of `(a, b, c)` is largest (so the projection dropping it is
/// non-degenerate for a non-degenerate triangle). Computed in `f64`: only the choice of axis depends on it.
fn dominant_axis(a: Vec3, b: Vec3, c: Vec3) -> usize {
    let n = (b.as_dvec3() - a.as_dvec3()).cross(c.as_dvec3() - a.as_dvec3()).abs();
    if n.x >= n.y && n.x >= n.z {
        0
    } else if n.y >= n.z {
        1
    } else {
        2
    }
}

/// Whether triangle `(a, b, c)` is degenerate (its corners are collinear), exactly.
pub fn is_degenerate_triangle(a: Vec3, b: Vec3, c: Vec3) -> bool {
    (0..3).all(|d| o2(a, b, c, d) == 0)
}

/// 2D closed segment intersection in projection `drop`.
fn segments_intersect_2d(p: Vec3, q: Vec3, r: Vec3, s: Vec3, drop: usize) -> bool {
    let d1 = o2(p, q, r, drop);
    let d2 = o2(p, q, s, drop);
    let d3 = o2(r, s, p, drop);
    let d4 = o2(r, s, q, drop);
    if d1 * d2 < 0 && d3 * d4 < 0 {
        return true;
    }
    let on = |a: Vec3, b: Vec3, x: Vec3| {
        let (pa, pb, px) = (proj(a, drop), proj(b, drop), proj(x, drop));
        px.x >= pa.x.min(pb.x) && px.x <= pa.x.max(pb.x) && px.y >= pa.y.min(pb.y) && px.y <= pa.y.max(pb.y)
    };
    (d1 == 0 && on(p, q, r)) || (d2 == 0 && on(p, q, s)) || (d3 == 0 && on(r, s, p)) || (d4 == 0 && on(r, s, q))
}

/// Whether point `x` lies in the closed 2D triangle `(a, b, c)` in projection `drop`.
fn point_in_triangle_2d(x: Vec3, a: Vec3, b: Vec3, c: Vec3, drop: usize) -> bool {
    let s1 = o2(a, b, x, drop);
    let s2 = o2(b, c, x, drop);
    let s3 = o2(c, a, x, drop);
    (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0)
}

/// Coplanar closed triangles overlap (edges cross or one contains a vertex of the other).
fn coplanar_triangles_intersect(t: [Vec3; 3], u: [Vec3; 3]) -> bool {
    let drop = dominant_axis(t[0], t[1], t[2]);
    for i in 0..3 {
        for j in 0..3 {
            if segments_intersect_2d(t[i], t[(i + 1) % 3], u[j], u[(j + 1) % 3], drop) {
                return true;
            }
        }
    }
    point_in_triangle_2d(t[0], u[0], u[1], u[2], drop) || point_in_triangle_2d(u[0], t[0], t[1], t[2], drop)
}

/// Whether the closed segment `(s, t)` meets the closed triangle `(a, b, c)` (non-degenerate).
pub fn segment_triangle_intersect(s: Vec3, t: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let os = o3(a, b, c, s);
    let ot = o3(a, b, c, t);
    if os * ot > 0 {
        return false;
    }
    if os == 0 && ot == 0 {
        // coplanar segment: intersects iff it crosses an edge or lies inside
        let drop = dominant_axis(a, b, c);
        return segments_intersect_2d(s, t, a, b, drop)
            || segments_intersect_2d(s, t, b, c, drop)
            || segments_intersect_2d(s, t, c, a, drop)
            || point_in_triangle_2d(s, a, b, c, drop);
    }
    // the line through s, t crosses the plane within the segment; it hits the triangle iff the three
    // edge orientations around the line agree (zero = touching an edge or vertex)
    let e1 = o3(s, t, a, b);
    let e2 = o3(s, t, b, c);
    let e3 = o3(s, t, c, a);
    (e1 >= 0 && e2 >= 0 && e3 >= 0) || (e1 <= 0 && e2 <= 0 && e3 <= 0)
}

/// Whether two closed, non-degenerate triangles share at least one point, exactly.
pub fn triangles_intersect(t: [Vec3; 3], u: [Vec3; 3]) -> bool {
    let du = [o3(t[0], t[1], t[2], u[0]), o3(t[0], t[1], t[2], u[1]), o3(t[0], t[1], t[2], u[2])];
    if du.iter().all(|&s| s > 0) || du.iter().all(|&s| s < 0) {
        return false;
    }
    if du.iter().all(|&s| s == 0) {
        return coplanar_triangles_intersect(t, u);
    }
    let dt = [o3(u[0], u[1], u[2], t[0]), o3(u[0], u[1], u[2], t[1]), o3(u[0], u[1], u[2], t[2])];
    if dt.iter().all(|&s| s > 0) || dt.iter().all(|&s| s < 0) {
        return false;
    }
    (0..3).any(|i| segment_triangle_intersect(t[i], t[(i + 1) % 3], u[0], u[1], u[2]))
        || (0..3).any(|i| segment_triangle_intersect(u[i], u[(i + 1) % 3], t[0], t[1], t[2]))
}

/// Whether two mesh faces intersect anywhere other than in the vertices and edge they share.
///
/// - No shared vertex: [`triangles_intersect`].
/// - A shared edge `(p, q)` with apices `x`, `y`: they overlap iff the four points are coplanar and `x`, `y`
///   lie on the same side of line `pq`.
/// - One shared vertex `p`, with opposite edges `ab` and `cd`: they meet elsewhere iff `ab` meets the other
///   triangle, `cd` meets the first one, or an edge from `p` of one runs along an edge from `p` of the other;
///   first, if `a` and `b` lie strictly on one side of the other's plane (or `c` and `d` of the first's), they
///   meet in `p` alone.
///
/// Both faces non-degenerate (as [`triangles_intersect`]): a degenerate face has no plane to decide by.
pub fn faces_intersect(fv: [u32; 3], t: [Vec3; 3], gv: [u32; 3], u: [Vec3; 3]) -> bool {
    // the corners the faces share, as (index in f, index in g): at most three (distinct corners per face)
    let mut shared = [(0usize, 0usize); 3];
    let mut n_shared = 0;
    for (i, a) in fv.iter().enumerate() {
        for (j, b) in gv.iter().enumerate() {
            if a == b && n_shared < 3 {
                shared[n_shared] = (i, j);
                n_shared += 1;
            }
        }
    }
    match n_shared {
        0 => triangles_intersect(t, u),
        1 => {
            let (i, j) = shared[0];
            let (a, b) = (t[(i + 1) % 3], t[(i + 2) % 3]);
            let (c, d) = (u[(j + 1) % 3], u[(j + 2) % 3]);
            let p = t[i];
            // a and b strictly on one side of g's plane: f meets that plane in p alone, so f and g share p
            // alone (and symmetrically). Exact signs; a degenerate face's plane gives 0 and no shortcut.
            let one_side = |x: Vec3, y: Vec3, w: [Vec3; 3]| o3(w[0], w[1], w[2], x) * o3(w[0], w[1], w[2], y) > 0;
            if one_side(a, b, u) || one_side(c, d, t) {
                return false;
            }
            if segment_triangle_intersect(a, b, u[0], u[1], u[2]) || segment_triangle_intersect(c, d, t[0], t[1], t[2])
            {
                return true;
            }
            // collinear, same-direction edges from p overlap in a segment
            let along = |x: Vec3, y: Vec3| {
                (x - p).as_dvec3().dot((y - p).as_dvec3()) > 0.0 && (0..3).all(|k| o2(p, x, y, k) == 0)
            };
            along(a, c) || along(a, d) || along(b, c) || along(b, d)
        }
        2 => {
            let (i0, j0) = shared[0];
            let (i1, _) = shared[1];
            let x = t[3 - i0 - i1];
            let y = u[(0..3).find(|&k| k != j0 && k != shared[1].1).unwrap_or(0)];
            let (p, q) = (t[i0], t[i1]);
            if o3(p, q, x, y) != 0 {
                return false;
            }
            let drop = dominant_axis(p, q, x);
            o2(p, q, x, drop) * o2(p, q, y, drop) > 0
        }
        // three shared vertices: a duplicate face
        _ => true,
    }
}

/// All pairs of faces of `mesh` that intersect other than along their shared vertices/edges, as
/// `(f, g)` with `f < g`, sorted. Degenerate (zero-area) faces are skipped; find them with
/// [`crate::quality::mesh_quality`]. Errors on a mesh without faces.
pub fn self_intersections(mesh: &SurfaceMesh) -> Result<Vec<(FaceId, FaceId)>, MeshError> {
    let bvh = TriangleBvh::from_mesh(mesh)?;
    let corners = |ti: u32| mesh.face_vertices(bvh.face_id(ti)).map(|v| v.0);
    let mut pairs: Vec<(FaceId, FaceId)> = intersecting_pairs(&bvh, corners)
        .into_iter()
        .map(|(ti, ui)| {
            let (f, g) = (bvh.face_id(ti), bvh.face_id(ui));
            if f < g { (f, g) } else { (g, f) }
        })
        .collect();
    pairs.sort_unstable();
    Ok(pairs)
}

/// [`self_intersections`] of an indexed triangle list: the pairs `(i, j)`, `i < j`, of triangles that
/// intersect other than along their shared vertices/edges, sorted. Errors on an empty list, out-of-range
/// indices or non-finite positions.
pub fn triangle_self_intersections(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Vec<(u32, u32)>, MeshError> {
    let bvh = TriangleBvh::from_triangles(positions, triangles)?;
    let mut pairs = intersecting_pairs(&bvh, |ti| triangles[ti as usize]);
    pairs.sort_unstable();
    Ok(pairs)
}

/// The pairs `(t, u)`, `t < u`, of the BVH's triangles that intersect other than along shared corners
/// (`corners(t)`: the vertex indices of triangle `t`); degenerate triangles are skipped.
fn intersecting_pairs(bvh: &TriangleBvh, corners: impl Fn(u32) -> [u32; 3]) -> Vec<(u32, u32)> {
    let mut pairs = Vec::new();
    for ti in 0..bvh.len() as u32 {
        let t = bvh.triangle(ti);
        if is_degenerate_triangle(t[0], t[1], t[2]) {
            continue;
        }
        let fv = corners(ti);
        let lo = t[0].min(t[1]).min(t[2]);
        let hi = t[0].max(t[1]).max(t[2]);
        bvh.for_each_overlapping(lo, hi, |ui| {
            if ui <= ti {
                return;
            }
            let u = bvh.triangle(ui);
            if !is_degenerate_triangle(u[0], u[1], u[2]) && faces_intersect(fv, t, corners(ui), u) {
                pairs.push((ti, ui));
            }
        });
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Faces sharing one corner: the early exit on the planes' sides gives the answer of the edge tests it
    /// skips, on integer corners that make many touching, coplanar and collinear cases.
    #[test]
    fn one_shared_corner_exit_agrees_with_the_edge_tests() {
        let mut rng = nlos_transient::rng::SplitMix64::new(0x5eed);
        let mut corner = || Vec3::new(rng.below(5) as f32 - 2.0, rng.below(5) as f32 - 2.0, rng.below(5) as f32 - 2.0);
        let (mut hits, mut misses) = (0, 0);
        for _ in 0..200_000 {
            let (p, a, b, c, d) = (corner(), corner(), corner(), corner(), corner());
            if [a, b, c, d].contains(&p) || a == b || c == d || [a, b].contains(&c) || [a, b].contains(&d) {
                continue;
            }
            let (t, u) = ([p, a, b], [p, c, d]);
            // the edge tests' precondition: non-degenerate faces
            if is_degenerate_triangle(p, a, b) || is_degenerate_triangle(p, c, d) {
                continue;
            }
            let along = |x: Vec3, y: Vec3| {
                (0..3).all(|k| o2(p, x, y, k) == 0) && (x - p).as_dvec3().dot((y - p).as_dvec3()) > 0.0
            };
            let want = segment_triangle_intersect(a, b, p, c, d)
                || segment_triangle_intersect(c, d, p, a, b)
                || along(a, c)
                || along(a, d)
                || along(b, c)
                || along(b, d);
            assert_eq!(faces_intersect([0, 1, 2], t, [0, 3, 4], u), want, "{t:?} {u:?}");
            if want { hits += 1 } else { misses += 1 }
        }
        assert!(hits > 1000 && misses > 1000, "both answers tested: {hits} hits, {misses} misses");
    }
}
