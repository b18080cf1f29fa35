//! Per-element geometry (normals, areas) and global structure (boundary loops, connected components).

use glam::Vec3;

use crate::handles::{FaceId, HalfedgeId, VertexId};
use crate::surface_mesh::SurfaceMesh;

/// Unnormalised normal of triangle `(a, b, c)`: `(b − a) × (c − a)`, length twice the area.
#[inline]
pub fn triangle_normal_raw(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    (b - a).cross(c - a)
}

impl SurfaceMesh {
    /// Unit normal of `f` (counter-clockwise corners); zero for a degenerate triangle.
    pub fn face_normal(&self, f: FaceId) -> Vec3 {
        let [a, b, c] = self.face_points(f);
        triangle_normal_raw(a, b, c).normalize_or_zero()
    }

    /// Area of `f`.
    pub fn face_area(&self, f: FaceId) -> f32 {
        let [a, b, c] = self.face_points(f);
        0.5 * triangle_normal_raw(a, b, c).length()
    }

    /// Centroid of `f`.
    pub fn face_centroid(&self, f: FaceId) -> Vec3 {
        let [a, b, c] = self.face_points(f);
        (a + b + c) / 3.0
    }

    /// Total area of the live faces (accumulated in `f64`).
    pub fn surface_area(&self) -> f64 {
        self.faces().map(|f| self.face_area(f) as f64).sum()
    }

    /// Angle-weighted unit vertex normal (Thürmer & Wüthrich 1998); zero for isolated vertices or
    /// degenerate rings.
    pub fn vertex_normal(&self, v: VertexId) -> Vec3 {
        let p = self.position(v);
        let mut n = Vec3::ZERO;
        for h in self.vertex_halfedges(v) {
            if self.is_boundary_halfedge(h) {
                continue;
            }
            let p1 = self.position(self.to_vertex(h));
            let p2 = self.position(self.to_vertex(self.next(h)));
            let (d1, d2) = (p1 - p, p2 - p);
            let fn_ = d1.cross(d2);
            // Guard: zero-length edges or degenerate corners contribute nothing.
            let (l1, l2) = (d1.length(), d2.length());
            if l1 <= f32::MIN_POSITIVE || l2 <= f32::MIN_POSITIVE {
                continue;
            }
            let cos = (d1.dot(d2) / (l1 * l2)).clamp(-1.0, 1.0);
            n += fn_.normalize_or_zero() * cos.acos();
        }
        n.normalize_or_zero()
    }

    /// Unit normals of all faces, indexed by `FaceId::idx` (deleted faces get zero).
    pub fn face_normals(&self) -> Vec<Vec3> {
        let mut out = vec![Vec3::ZERO; self.faces_size()];
        for f in self.faces() {
            out[f.idx()] = self.face_normal(f);
        }
        out
    }

    /// Unit vertex normals of all vertices, indexed by `VertexId::idx`.
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut out = vec![Vec3::ZERO; self.vertices_size()];
        for v in self.vertices() {
            out[v.idx()] = self.vertex_normal(v);
        }
        out
    }

    /// Axis-aligned bounds of the live vertices (`None` if there are none).
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.vertices().map(|v| self.position(v));
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Mean length of the live edges (0 without edges).
    pub fn mean_edge_length(&self) -> f32 {
        let (s, n) = self.edges().fold((0.0f64, 0usize), |(s, n), e| (s + self.edge_length(e) as f64, n + 1));
        if n == 0 { 0.0 } else { (s / n as f64) as f32 }
    }

    /// The boundary loops, each as its boundary halfedges in order (a closed mesh has none).
    pub fn boundary_loops(&self) -> Vec<Vec<HalfedgeId>> {
        let mut seen = vec![false; 2 * self.edges_size()];
        let mut loops = Vec::new();
        for h in self.halfedges() {
            if seen[h.idx()] || !self.is_boundary_halfedge(h) {
                continue;
            }
            let mut lp = Vec::new();
            let mut c = h;
            // Guard: a loop cannot be longer than the halfedge count.
            while !seen[c.idx()] && lp.len() <= seen.len() {
                seen[c.idx()] = true;
                lp.push(c);
                c = self.next(c);
            }
            loops.push(lp);
        }
        loops
    }

    /// Connected components: a component id per vertex (indexed by `VertexId::idx`, `u32::MAX` for deleted
    /// vertices) and the number of components. Isolated vertices are components of their own.
    pub fn connected_components(&self) -> (Vec<u32>, usize) {
        let mut comp = vec![u32::MAX; self.vertices_size()];
        let mut n = 0u32;
        let mut stack = Vec::new();
        for v in self.vertices() {
            if comp[v.idx()] != u32::MAX {
                continue;
            }
            comp[v.idx()] = n;
            stack.push(v);
            while let Some(x) = stack.pop() {
                for w in self.vertex_vertices(x) {
                    if comp[w.idx()] == u32::MAX {
                        comp[w.idx()] = n;
                        stack.push(w);
                    }
                }
            }
            n += 1;
        }
        (comp, n as usize)
    }

    /// Deletes every connected component except the one with the most faces (ties: the lowest component
    /// id) and isolated vertices. Returns the number of deleted faces. Call
    /// [`Self::garbage_collect`] afterwards to compact.
    pub fn keep_largest_component(&mut self) -> usize {
        let (comp, n) = self.connected_components();
        if n <= 1 {
            return 0;
        }
        let mut faces_per = vec![0usize; n];
        for f in self.faces() {
            let v = self.face_vertices(f)[0];
            faces_per[comp[v.idx()] as usize] += 1;
        }
        let mut best = 0;
        for (i, &c) in faces_per.iter().enumerate() {
            if c > faces_per[best] {
                best = i;
            }
        }
        let before = self.n_faces();
        let doomed: Vec<VertexId> = self.vertices().filter(|v| comp[v.idx()] != best as u32).collect();
        self.delete_component(&doomed);
        before - self.n_faces()
    }
}
