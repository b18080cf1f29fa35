//! Shadow rays through an obvhs compressed-wide BVH.

use glam::{Vec3, Vec3A};
use obvhs::{BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh_from_tris, ray::Ray, triangle::Triangle};

/// A BVH over the non-degenerate triangles of the mesh, for occlusion queries.
pub(crate) struct Bvh {
    cw: CwBvh,
    tris: Vec<Triangle>,
    /// `ids[i]`: the mesh triangle of BVH primitive `i`.
    ids: Vec<u32>,
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
        for t in 0..v0.len() {
            if valid[t] {
                let a = Vec3A::from(v0[t]);
                tris.push(Triangle { v0: a, v1: a + Vec3A::from(e1[t]), v2: a + Vec3A::from(e2[t]) });
                ids.push(t as u32);
            }
        }
        if tris.is_empty() {
            return None;
        }
        let cw = build_cwbvh_from_tris(&tris, BvhBuildParams::medium_build(), &mut Default::default());
        Some(Self { cw, tris, ids })
    }

    /// Whether the open segment from `x` (a point of mesh triangle `own`) to `p` is free of the mesh.
    /// `own` is skipped so a sample never shadows itself.
    #[inline]
    pub(crate) fn visible(&self, x: Vec3, p: Vec3, own: u32) -> bool {
        let d = p - x;
        let dist = d.length();
        // Guard: a zero-length segment (x on the wall) cannot be blocked and has no direction.
        if !(dist > 0.0) {
            return true;
        }
        // tmax slightly short of the wall point: the wall is not in the BVH, but a mesh vertex lying on the
        // wall must not count as an occluder of its own spot.
        let ray = Ray::new(Vec3A::from(x), Vec3A::from(d / dist), 0.0, dist * (1.0 - 1e-5));
        self.cw.ray_traverse_miss(ray, |ray, id| {
            // Map the BVH's leaf order to our primitive list, then to the mesh triangle.
            let prim = self.cw.primitive_indices[id] as usize;
            if self.ids[prim] == own { f32::INFINITY } else { self.tris[prim].intersect(ray) }
        })
    }
}
