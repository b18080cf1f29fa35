//! Construction from indexed triangles, export back to indexed triangles, and orientation of triangle
//! soups.

use std::collections::HashMap;

use glam::Vec3;

use crate::error::MeshError;
use crate::handles::{HalfedgeId, VertexId};
use crate::surface_mesh::SurfaceMesh;

/// Options for [`SurfaceMesh::from_triangles_with`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BuildOptions {
    /// Repair non-manifold vertices (whose triangles form several fans, e.g. two cones touching at
    /// their apex) by giving each extra fan its own copy of the vertex. Without it such input is an error.
    /// Non-manifold edges (more than two triangles) are always an error.
    pub split_non_manifold_vertices: bool,
}

impl SurfaceMesh {
    /// Builds a mesh from positions and counter-clockwise triangles; errors on non-manifold input. See
    /// [`Self::from_triangles_with`].
    pub fn from_triangles(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Self, MeshError> {
        Self::from_triangles_with(positions, triangles, BuildOptions::default())
    }

    /// Builds a mesh from positions and triangles. Vertex `i` becomes `VertexId(i)` and triangle `j`
    /// becomes `FaceId(j)` (extra copies made by the repair option are appended after the input vertices).
    ///
    /// Errors: [`MeshError::NonFinitePosition`], [`MeshError::IndexOutOfRange`],
    /// [`MeshError::DegenerateFace`], [`MeshError::NonManifoldEdge`],
    /// [`MeshError::InconsistentOrientation`] (fix with [`orient_triangles`]) and, unless
    /// `options.split_non_manifold_vertices`, [`MeshError::NonManifoldVertex`]. Unreferenced vertices are
    /// kept as isolated vertices.
    pub fn from_triangles_with(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        options: BuildOptions,
    ) -> Result<Self, MeshError> {
        for (i, p) in positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::NonFinitePosition { vertex: i, position: p.to_array() });
            }
        }
        check_triangles(positions.len(), triangles)?;
        if triangles.len() >= (u32::MAX / 4) as usize || positions.len() >= (u32::MAX / 2) as usize {
            return Err(MeshError::InvalidParameter {
                name: "triangles",
                value: triangles.len() as f64,
                reason: "too many elements for 32-bit handles; split the mesh",
            });
        }
        let mut mesh = SurfaceMesh::new();
        for &p in positions {
            mesh.add_vertex(p);
        }
        // Edges keyed by (min, max) vertex; halfedge 2e runs min → max.
        let mut edge_map: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3 / 2 + 8);
        for (fi, t) in triangles.iter().enumerate() {
            let f = mesh.new_face();
            let mut hs = [HalfedgeId::INVALID; 3];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                let e = match edge_map.get(&key) {
                    Some(&e) => e,
                    None => {
                        let h = mesh.new_edge(VertexId(key.0), VertexId(key.1));
                        let e = h.edge().0;
                        edge_map.insert(key, e);
                        e
                    }
                };
                let h = crate::EdgeId(e).halfedge(if a < b { 0 } else { 1 });
                if mesh.face(h).is_valid() {
                    let o = h.opposite();
                    return Err(if mesh.face(o).is_valid() {
                        MeshError::NonManifoldEdge { v0: a, v1: b, face: fi }
                    } else {
                        MeshError::InconsistentOrientation { v0: a, v1: b, face: fi }
                    });
                }
                mesh.hconn[h.idx()].face = f;
                hs[k] = h;
            }
            // Two triangles listing the same edge twice in the same direction were caught above; a third
            // triangle on an edge with both halfedges taken is caught too.
            for k in 0..3 {
                mesh.set_next(hs[k], hs[(k + 1) % 3]);
            }
            // store the halfedge ending at t[0] so that `face_vertices` returns the input order
            mesh.fhalfedge[f.idx()] = hs[2];
        }

        // Outgoing face halfedges per vertex, to find fans.
        let nv0 = positions.len();
        let nh = mesh.hconn.len();
        let mut out_start = vec![0u32; nv0 + 1];
        for h in 0..nh {
            if mesh.hconn[h].face.is_valid() {
                out_start[mesh.from_vertex(HalfedgeId::new(h)).idx() + 1] += 1;
            }
        }
        for i in 0..nv0 {
            out_start[i + 1] += out_start[i];
        }
        let mut fill = out_start.clone();
        let mut outgoing = vec![HalfedgeId::INVALID; out_start[nv0] as usize];
        for h in 0..nh {
            if mesh.hconn[h].face.is_valid() {
                let v = mesh.from_vertex(HalfedgeId::new(h)).idx();
                outgoing[fill[v] as usize] = HalfedgeId::new(h);
                fill[v] += 1;
            }
        }

        // Walk fans: from any unvisited outgoing face halfedge rotate clockwise (through faces) to the fan's
        // start, then counter-clockwise through the whole fan.
        let mut visited = vec![false; nh];
        for v in 0..nv0 {
            let ring = &outgoing[out_start[v] as usize..out_start[v + 1] as usize];
            let mut fans = 0usize;
            let mut fan_members: Vec<HalfedgeId> = Vec::new();
            for &start in ring {
                if visited[start.idx()] {
                    continue;
                }
                fans += 1;
                fan_members.clear();
                // go clockwise (h -> next(opposite(h))) while the opposite side has a face
                let mut h = start;
                loop {
                    let o = h.opposite();
                    if !mesh.face(o).is_valid() {
                        break;
                    }
                    let n = mesh.next(o);
                    if n == start {
                        break;
                    }
                    h = n;
                }
                // now counter-clockwise: h -> opposite(prev(h))
                let first = h;
                loop {
                    visited[h.idx()] = true;
                    fan_members.push(h);
                    let o = mesh.prev(h).opposite();
                    if !mesh.face(o).is_valid() || o == first {
                        break;
                    }
                    h = o;
                }
                if fans > 1 {
                    if !options.split_non_manifold_vertices {
                        let total = count_fans(&mesh, ring);
                        return Err(MeshError::NonManifoldVertex { vertex: v as u32, fans: total });
                    }
                    let nvtx = mesh.add_vertex(positions[v]);
                    for &m in &fan_members {
                        // incoming halfedges to v of this fan: prev(m) ends at v; the opposite of m ends at v.
                        let p = mesh.prev(m);
                        mesh.hconn[p.idx()].vertex = nvtx;
                        mesh.hconn[m.opposite().idx()].vertex = nvtx;
                    }
                }
            }
        }

        // Link boundary halfedges: next(h) = the outgoing boundary halfedge of to(h).
        let nv = mesh.positions.len();
        let mut out_boundary = vec![HalfedgeId::INVALID; nv];
        let mut any_out = vec![HalfedgeId::INVALID; nv];
        for h in 0..nh {
            let h = HalfedgeId::new(h);
            let from = mesh.from_vertex(h).idx();
            if !mesh.face(h).is_valid() {
                out_boundary[from] = h;
            } else if !any_out[from].is_valid() {
                any_out[from] = h;
            }
        }
        for h in 0..nh {
            let h = HalfedgeId::new(h);
            if !mesh.face(h).is_valid() {
                let n = out_boundary[mesh.to_vertex(h).idx()];
                mesh.set_next(h, n);
            }
        }
        for v in 0..nv {
            mesh.vhalfedge[v] = if out_boundary[v].is_valid() { out_boundary[v] } else { any_out[v] };
        }
        Ok(mesh)
    }

    /// The live vertex positions and triangles as compact arrays (vertex `i` of the output is the `i`-th
    /// live vertex). Isolated vertices are kept.
    pub fn to_triangles(&self) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut map = vec![u32::MAX; self.positions.len()];
        let mut pos = Vec::with_capacity(self.n_vertices());
        for v in self.vertices() {
            map[v.idx()] = pos.len() as u32;
            pos.push(self.position(v));
        }
        let tris = self.faces().map(|f| self.face_vertices(f).map(|v| map[v.idx()])).collect();
        (pos, tris)
    }
}

fn count_fans(mesh: &SurfaceMesh, ring: &[HalfedgeId]) -> usize {
    let mut seen = std::collections::HashSet::new();
    let mut fans = 0;
    for &s in ring {
        if seen.contains(&s) {
            continue;
        }
        fans += 1;
        let mut h = s;
        // mark both directions
        loop {
            seen.insert(h);
            let o = h.opposite();
            if !mesh.face(o).is_valid() {
                break;
            }
            h = mesh.next(o);
            if seen.contains(&h) {
                break;
            }
        }
        let mut h = s;
        loop {
            seen.insert(h);
            let o = mesh.prev(h).opposite();
            if !mesh.face(o).is_valid() || seen.contains(&o) {
                break;
            }
            h = o;
        }
    }
    fans
}

fn check_triangles(n_vertices: usize, triangles: &[[u32; 3]]) -> Result<(), MeshError> {
    for (i, t) in triangles.iter().enumerate() {
        for &x in t {
            if x as usize >= n_vertices {
                return Err(MeshError::IndexOutOfRange { face: i, index: x as u64, vertex_count: n_vertices });
            }
        }
        if t[0] == t[1] || t[0] == t[2] {
            return Err(MeshError::DegenerateFace { face: i, vertex: t[0] });
        }
        if t[1] == t[2] {
            return Err(MeshError::DegenerateFace { face: i, vertex: t[1] });
        }
    }
    Ok(())
}

/// Reorients triangles in place so that each edge-connected patch is consistently oriented (a triangle
/// is flipped when it traverses a shared edge in the same direction as an already visited neighbour).
/// Breadth-first from the lowest-numbered triangle of each patch, which keeps its orientation. Returns
/// the number of flipped triangles. Non-orientable patches (Möbius strips) and non-manifold edges are left
/// as found after the first conflict; [`SurfaceMesh::from_triangles`] then reports them.
pub fn orient_triangles(n_vertices: usize, triangles: &mut [[u32; 3]]) -> Result<usize, MeshError> {
    check_triangles(n_vertices, triangles)?;
    let mut edge_faces: HashMap<(u32, u32), Vec<u32>> = HashMap::with_capacity(triangles.len() * 3 / 2);
    for (i, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edge_faces.entry((a.min(b), a.max(b))).or_default().push(i as u32);
        }
    }
    let has_directed = |t: &[u32; 3], a: u32, b: u32| (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b);
    let mut visited = vec![false; triangles.len()];
    let mut flipped = 0;
    let mut queue = std::collections::VecDeque::new();
    for seed in 0..triangles.len() {
        if visited[seed] {
            continue;
        }
        visited[seed] = true;
        queue.push_back(seed);
        while let Some(f) = queue.pop_front() {
            let t = triangles[f];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let Some(nbrs) = edge_faces.get(&(a.min(b), a.max(b))) else { continue };
                if nbrs.len() != 2 {
                    continue;
                }
                for &g in nbrs {
                    let g = g as usize;
                    if g == f || visited[g] {
                        continue;
                    }
                    visited[g] = true;
                    if has_directed(&triangles[g], a, b) {
                        triangles[g].swap(1, 2);
                        flipped += 1;
                    }
                    queue.push_back(g);
                }
            }
        }
    }
    Ok(flipped)
}
