//! Broad phase: candidate vertex–triangle and edge–edge pairs from swept bounding boxes.
//!
//! Each primitive's swept box (the box of its corners at `t = 0` and `t = 1`, which contains it at every
//! `t` of the straight-line motion, padded by a distance) is computed once. Two BVHs built by `obvhs`
//! (PLOC, the crate's and the renderer's builder) hold the triangles' and the edges' swept boxes; every
//! vertex queries the triangle BVH with its swept segment's box, and every edge queries the edge BVH with
//! its own box (keeping partners of higher index). So each candidate pair is produced exactly once, with no
//! sort or deduplication of the (large) pair lists; each query's hits are sorted so that the order does not
//! depend on the BVH. Pairs sharing a vertex, and pairs whose vertices are all static (they cannot start
//! colliding), are dropped. Queries run in parallel (rayon) and keep the sequential order.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use rayon::prelude::*;

use crate::surface_mesh::SurfaceMesh;

/// Meshes with fewer faces build their BVHs on the calling thread.
pub(crate) const PARALLEL_FACES: usize = 2048;

/// Smallest number of BVH queries (and of narrow-phase tests) per rayon task.
pub(crate) const QUERY_CHUNK: usize = 256;

/// A compact snapshot of the mesh's connectivity: live faces and edges as vertex indices.
#[derive(Debug, Clone, Default)]
pub(crate) struct Topo {
    /// Corners of each live face.
    pub faces: Vec<[u32; 3]>,
    /// Endpoints of each live edge.
    pub edges: Vec<[u32; 2]>,
    /// Every vertex of a live face, once, in increasing order.
    pub verts: Vec<u32>,
}

impl Topo {
    pub(crate) fn new(mesh: &SurfaceMesh) -> Self {
        let edges: Vec<[u32; 2]> = mesh.edges().map(|e| mesh.edge_vertices(e).map(|v| v.0)).collect();
        let faces: Vec<[u32; 3]> = mesh.faces().map(|f| mesh.face_vertices(f).map(|v| v.0)).collect();
        let mut used = vec![false; mesh.vertices_size()];
        for f in &faces {
            for &v in f {
                used[v as usize] = true;
            }
        }
        let verts = (0..used.len() as u32).filter(|&v| used[v as usize]).collect();
        Self { faces, edges, verts }
    }
}

/// Candidate pairs: `vt` as (vertex, face index), `ee` as (edge index, edge index) with the first smaller.
#[derive(Debug, Clone, Default)]
pub(crate) struct Pairs {
    pub vt: Vec<(u32, u32)>,
    pub ee: Vec<(u32, u32)>,
}

#[derive(Clone, Copy)]
struct Box3 {
    lo: Vec3A,
    hi: Vec3A,
}

impl Box3 {
    #[inline]
    fn of(points: &[Vec3], pad: f32) -> Self {
        let mut lo = Vec3A::from(points[0]);
        let mut hi = lo;
        for &p in &points[1..] {
            lo = lo.min(Vec3A::from(p));
            hi = hi.max(Vec3A::from(p));
        }
        Self { lo: lo - Vec3A::splat(pad), hi: hi + Vec3A::splat(pad) }
    }
    #[inline]
    fn overlaps(&self, o: &Box3) -> bool {
        self.lo.cmple(o.hi).all() && o.lo.cmple(self.hi).all()
    }
}

/// All vertex–triangle and edge–edge pairs whose swept boxes, padded by `pad`, overlap, that have at least
/// one vertex with `moving[v]` and, when `active` is given, at least one vertex with `active[v]` (the
/// incremental passes: only pairs touching a vertex whose end position changed need a new test). `vt` is
/// sorted by vertex then face, `ee` by first then second edge.
pub(crate) fn candidate_pairs(
    topo: &Topo,
    x0: &[Vec3],
    x1: &[Vec3],
    pad: f32,
    moving: &[bool],
    active: Option<&[bool]>,
) -> Pairs {
    if topo.faces.is_empty() {
        return Pairs::default();
    }
    let sweep = |vs: &[u32]| {
        let mut pts = [Vec3::ZERO; 6];
        for (k, &v) in vs.iter().enumerate() {
            pts[2 * k] = x0[v as usize];
            pts[2 * k + 1] = x1[v as usize];
        }
        Box3::of(&pts[..2 * vs.len()], pad)
    };
    let mv = |v: u32| moving[v as usize];
    let act = |v: u32| active.is_none_or(|a| a[v as usize]);
    let fbox: Vec<Box3> = topo.faces.iter().map(|f| sweep(f)).collect();
    let fmoving: Vec<bool> = topo.faces.iter().map(|f| f.iter().any(|&v| mv(v))).collect();
    let ebox: Vec<Box3> = topo.edges.iter().map(|e| sweep(e)).collect();
    let emoving: Vec<bool> = topo.edges.iter().map(|e| mv(e[0]) || mv(e[1])).collect();
    let eactive: Vec<bool> = topo.edges.iter().map(|e| act(e[0]) || act(e[1])).collect();
    let bvh_of = |boxes: &[Box3]| {
        let aabbs: Vec<Aabb> = boxes.iter().map(|b| Aabb::new(b.lo, b.hi)).collect();
        let mut time = std::time::Duration::ZERO;
        obvhs::bvh2::builder::build_bvh2(&aabbs, obvhs::BvhBuildParams::fast_build(), &mut time)
    };
    // Incremental calls also need the pairs (inactive vertex, face with an active vertex): faces query a
    // BVH of the inactive vertices' boxes.
    let inactive: Vec<u32> = match active {
        Some(a) => topo.verts.iter().copied().filter(|&v| !a[v as usize]).collect(),
        None => Vec::new(),
    };
    let vboxes = || bvh_of(&inactive.iter().map(|&v| sweep(&[v])).collect::<Vec<_>>());
    // small meshes: no threads (their scheduling costs more than the work)
    let ((fbvh, ebvh), vbvh) = if topo.faces.len() < PARALLEL_FACES {
        ((bvh_of(&fbox), bvh_of(&ebox)), (!inactive.is_empty()).then(vboxes))
    } else {
        rayon::join(|| rayon::join(|| bvh_of(&fbox), || bvh_of(&ebox)), || (!inactive.is_empty()).then(vboxes))
    };
    // each (active vertex, face) once
    let mut vt: Vec<(u32, u32)> = topo
        .verts
        .par_iter()
        .with_min_len(QUERY_CHUNK)
        .filter(|&&v| act(v))
        .flat_map_iter(|&v| {
            let vb = sweep(&[v]);
            let mut hits = Vec::new();
            for_leaves(&fbvh, &vb, |f| {
                if (mv(v) || fmoving[f]) && !topo.faces[f].contains(&v) && vb.overlaps(&fbox[f]) {
                    hits.push((v, f as u32));
                }
            });
            hits.sort_unstable();
            hits
        })
        .collect();
    // each (inactive vertex, face with an active vertex) once
    if let Some(vbvh) = &vbvh {
        let more: Vec<(u32, u32)> = (0..topo.faces.len())
            .into_par_iter()
            .with_min_len(QUERY_CHUNK)
            .filter(|&f| topo.faces[f].iter().any(|&v| act(v)))
            .flat_map_iter(|f| {
                let mut hits = Vec::new();
                for_leaves(vbvh, &fbox[f], |k| {
                    let v = inactive[k];
                    if (mv(v) || fmoving[f]) && !topo.faces[f].contains(&v) && sweep(&[v]).overlaps(&fbox[f]) {
                        hits.push((v, f as u32));
                    }
                });
                hits
            })
            .collect();
        vt.extend(more);
        vt.sort_unstable();
    }
    // each edge pair with an active vertex once: from the lower index when both edges are active
    let ee: Vec<(u32, u32)> = (0..topo.edges.len())
        .into_par_iter()
        .with_min_len(QUERY_CHUNK)
        .filter(|&i| eactive[i])
        .flat_map_iter(|i| {
            let [a, b] = topo.edges[i];
            let mut hits = Vec::new();
            for_leaves(&ebvh, &ebox[i], |j| {
                if (eactive[j] && j <= i) || !(emoving[i] || emoving[j]) {
                    return;
                }
                let [c, d] = topo.edges[j];
                if a == c || a == d || b == c || b == d || !ebox[i].overlaps(&ebox[j]) {
                    return;
                }
                hits.push(((i as u32).min(j as u32), (i as u32).max(j as u32)));
            });
            hits.sort_unstable();
            hits
        })
        .collect();
    let mut pairs = Pairs { vt, ee };
    if active.is_some() {
        pairs.ee.sort_unstable();
    }
    pairs
}

/// Calls `hit` with every primitive in a BVH leaf whose box overlaps `query`.
#[inline]
fn for_leaves(bvh: &obvhs::bvh2::Bvh2, query: &Box3, mut hit: impl FnMut(usize)) {
    bvh.aabb_traverse(Aabb::new(query.lo, query.hi), |bvh, node_index| {
        let node = &bvh.nodes[node_index as usize];
        let start = node.first_index as usize;
        for k in start..start + node.prim_count as usize {
            hit(bvh.primitive_indices[k] as usize);
        }
        true
    });
}
