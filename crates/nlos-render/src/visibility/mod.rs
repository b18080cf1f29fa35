//! Occlusion between the surface and the wall.
//!
//! Two queries share one set of triangles:
//! - [`Bvh::visible`]: one shadow ray (a segment from a surface point to a wall point) through an obvhs
//!   compressed-wide BVH: what live visibility traces per sample.
//! - [`bundle::Bundle`]: the same answer for one surface point and *every* wall point at once (the visibility
//!   cache's row): the wall points are grouped in a k-d tree ([`wall::WallTree`]), and a group is answered
//!   without a ray when no triangle can reach the cone that holds its segments. Exact: the cull tests are
//!   conservative, and what they do not settle is decided by the same ray–triangle test as [`Bvh::visible`].

pub(crate) mod bundle;
pub(crate) mod wall;

use glam::{Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    bvh2::{Bvh2, builder::build_bvh2_from_tris},
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::Ray,
    triangle::Triangle,
};

/// A BVH over the non-degenerate triangles of the mesh, for occlusion queries.
pub(crate) struct Bvh {
    cw: CwBvh,
    /// A binary BVH over the same triangles, for the cone queries of [`bundle::Bundle`].
    bin: Bvh2,
    tris: Vec<Triangle>,
    /// `ids[i]`: the mesh triangle of BVH primitive `i`.
    ids: Vec<u32>,
    /// Bounding sphere of primitive `i`: centre (the centroid) and radius (its farthest corner).
    spheres: Vec<(Vec3, f32)>,
    /// Bounding sphere of the binary BVH's node `k`: its box's centre and half diagonal.
    node_balls: Vec<(Vec3, f32)>,
}

impl std::fmt::Debug for Bvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh").field("triangles", &self.tris.len()).finish()
    }
}

impl Bvh {
    /// `None` when there is nothing to occlude with.
    pub(crate) fn build(v0: &[Vec3], e1: &[Vec3], e2: &[Vec3], valid: &[bool]) -> Option<Self> {
        let mut tris = Vec::new();
        let mut ids = Vec::new();
        let mut spheres = Vec::new();
        for t in 0..v0.len() {
            if valid[t] {
                let a = Vec3A::from(v0[t]);
                let (b, c) = (a + Vec3A::from(e1[t]), a + Vec3A::from(e2[t]));
                tris.push(Triangle { v0: a, v1: b, v2: c });
                ids.push(t as u32);
                let m = (a + b + c) / 3.0;
                let r = (a - m).length().max((b - m).length()).max((c - m).length());
                spheres.push((Vec3::from(m), r));
            }
        }
        if tris.is_empty() {
            return None;
        }
        let cw = build_cwbvh_from_tris(&tris, BvhBuildParams::medium_build(), &mut Default::default());
        let bin = build_bvh2_from_tris(&tris, BvhBuildParams::medium_build(), &mut Default::default());
        let node_balls = bin
            .nodes
            .iter()
            .map(|node| {
                let (lo, hi) = (Vec3::from(node.aabb().min), Vec3::from(node.aabb().max));
                (0.5 * (lo + hi), 0.5 * (hi - lo).length())
            })
            .collect();
        Some(Self { cw, bin, tris, ids, spheres, node_balls })
    }

    /// Whether the open segment from `x` (a point of mesh triangle `own`) to `p` is free of the mesh.
    /// `own` is skipped so a sample never shadows itself.
    #[inline]
    pub(crate) fn visible(&self, x: Vec3, p: Vec3, own: u32) -> bool {
        let Some(ray) = segment(x, p) else { return true };
        self.cw.ray_traverse_miss(ray, |ray, id| {
            // Map the BVH's leaf order to our primitive list, then to the mesh triangle.
            let prim = self.cw.primitive_indices[id] as usize;
            if self.ids[prim] == own { f32::INFINITY } else { self.tris[prim].intersect(ray) }
        })
    }

    /// Whether BVH primitive `prim` cuts the segment `ray` (from [`segment`]): the test [`Bvh::visible`] makes.
    #[inline(always)]
    pub(crate) fn blocks(&self, prim: u32, ray: &Ray) -> bool {
        self.tris[prim as usize].intersect(ray) < f32::INFINITY
    }
}

/// The ray of the open segment from `x` to `p`, or None for a zero-length one (x on the wall: it cannot be
/// blocked and has no direction). tmax stops slightly short of the wall point: the wall is not in the BVH,
/// but a mesh vertex lying on the wall must not count as an occluder of its own spot.
#[inline(always)]
pub(crate) fn segment(x: Vec3, p: Vec3) -> Option<Ray> {
    let d = p - x;
    let dist = d.length();
    if !(dist > 0.0) {
        return None;
    }
    Some(Ray::new(Vec3A::from(x), Vec3A::from(d / dist), 0.0, dist * (1.0 - 1e-5)))
}
