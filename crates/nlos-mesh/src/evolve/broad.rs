//! Broad phase: candidate vertex–triangle and edge–edge pairs from swept bounding boxes.
//!
//! Each triangle's swept box (the box of its three corners at `t = 0` and `t = 1`, which contains the
//! triangle at every `t` of the straight-line motion, padded by a distance) goes into a BVH built by
//! `obvhs` (PLOC, the crate's and the renderer's builder). Every triangle queries the BVH with its own
//! box; each overlapping pair of triangles that share no more than they must yields the vertex–triangle
//! pairs (a vertex of one, the other triangle) and edge–edge pairs (an edge of each) that share no
//! vertex, filtered again by their own swept boxes. Pairs whose vertices are all static are dropped:
//! they cannot start colliding. Queries run in parallel (rayon); pairs are sorted and deduplicated.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use rayon::prelude::*;

use crate::surface_mesh::SurfaceMesh;

/// A compact snapshot of the mesh's connectivity: live faces and edges as vertex indices.
#[derive(Debug, Clone, Default)]
pub(crate) struct Topo {
    /// Corners of each live face.
    pub faces: Vec<[u32; 3]>,
    /// Endpoints of each live edge.
    pub edges: Vec<[u32; 2]>,
    /// The three edges (indices into `edges`) of each face.
    pub face_edges: Vec<[u32; 3]>,
}

impl Topo {
    pub(crate) fn new(mesh: &SurfaceMesh) -> Self {
        let mut edge_index = vec![u32::MAX; mesh.edges_size()];
        let mut edges = Vec::with_capacity(mesh.n_edges());
        for e in mesh.edges() {
            edge_index[e.idx()] = edges.len() as u32;
            edges.push(mesh.edge_vertices(e).map(|v| v.0));
        }
        let mut faces = Vec::with_capacity(mesh.n_faces());
        let mut face_edges = Vec::with_capacity(mesh.n_faces());
        for f in mesh.faces() {
            faces.push(mesh.face_vertices(f).map(|v| v.0));
            face_edges.push(mesh.face_halfedges(f).map(|h| edge_index[h.edge().idx()]));
        }
        Self { faces, edges, face_edges }
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

/// All vertex–triangle and edge–edge pairs whose swept boxes, padded by `pad`, overlap and that have at
/// least one vertex with `moving[v]`.
pub(crate) fn candidate_pairs(topo: &Topo, x0: &[Vec3], x1: &[Vec3], pad: f32, moving: &[bool]) -> Pairs {
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
    let fbox: Vec<Box3> = topo.faces.par_iter().map(|f| sweep(f)).collect();
    let fmoving: Vec<bool> = topo.faces.iter().map(|f| f.iter().any(|&v| moving[v as usize])).collect();
    let aabbs: Vec<Aabb> = fbox.iter().map(|b| Aabb::new(b.lo, b.hi)).collect();
    let mut time = std::time::Duration::ZERO;
    let bvh = obvhs::bvh2::builder::build_bvh2(&aabbs, obvhs::BvhBuildParams::fast_build(), &mut time);

    let (vt, ee) = (0..topo.faces.len())
        .into_par_iter()
        .fold(
            || (Vec::new(), Vec::new()),
            |(mut vt, mut ee), i| {
                let fi = topo.faces[i];
                let query = Aabb::new(fbox[i].lo, fbox[i].hi);
                bvh.aabb_traverse(query, |bvh, node_index| {
                    let node = &bvh.nodes[node_index as usize];
                    let start = node.first_index as usize;
                    for k in start..start + node.prim_count as usize {
                        let j = bvh.primitive_indices[k] as usize;
                        if j <= i || !(fmoving[i] || fmoving[j]) || !fbox[i].overlaps(&fbox[j]) {
                            continue;
                        }
                        face_pair(topo, i, j, fi, &fbox, &sweep, moving, &mut vt, &mut ee);
                    }
                    true
                });
                (vt, ee)
            },
        )
        .reduce(
            || (Vec::new(), Vec::new()),
            |(mut a, mut b), (c, d)| {
                a.extend(c);
                b.extend(d);
                (a, b)
            },
        );
    let mut pairs = Pairs { vt, ee };
    pairs.vt.par_sort_unstable();
    pairs.vt.dedup();
    pairs.ee.par_sort_unstable();
    pairs.ee.dedup();
    pairs
}

#[allow(clippy::too_many_arguments)]
fn face_pair(
    topo: &Topo,
    i: usize,
    j: usize,
    fi: [u32; 3],
    fbox: &[Box3],
    sweep: &impl Fn(&[u32]) -> Box3,
    moving: &[bool],
    vt: &mut Vec<(u32, u32)>,
    ee: &mut Vec<(u32, u32)>,
) {
    let fj = topo.faces[j];
    let mv = |v: u32| moving[v as usize];
    for (f_pt, f_tri, tri) in [(fi, fj, j), (fj, fi, i)] {
        let tri_moving = f_tri.iter().any(|&v| mv(v));
        for &v in &f_pt {
            if f_tri.contains(&v) || !(mv(v) || tri_moving) {
                continue;
            }
            if sweep(&[v]).overlaps(&fbox[tri]) {
                vt.push((v, tri as u32));
            }
        }
    }
    for &ea in &topo.face_edges[i] {
        let [a, b] = topo.edges[ea as usize];
        for &eb in &topo.face_edges[j] {
            let [c, d] = topo.edges[eb as usize];
            if ea == eb || a == c || a == d || b == c || b == d || !(mv(a) || mv(b) || mv(c) || mv(d)) {
                continue;
            }
            if sweep(&[a, b]).overlaps(&sweep(&[c, d])) {
                ee.push((ea.min(eb), ea.max(eb)));
            }
        }
    }
}
