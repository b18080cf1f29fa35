//! The collision tests of single mesh operations (El Topo's per-operation checks, Brochu & Bridson 2009 §4–5):
//! a uniform grid of face boxes kept current through the operations, and two questions asked of it before an
//! operation is applied.
//!
//! - [`CollisionGuard::new_faces_intersect`]: would the faces an operation creates (a collapse's or a flip's)
//!   meet any other face? Exact static test ([`crate::intersect::faces_intersect`]: orientation predicates
//!   with Shewchuk's adaptive arithmetic). A topological operation replaces faces at once, with no motion in
//!   between, so the end state is all there is to test.
//! - [`CollisionGuard::move_collides`]: would vertex `v`, moved on a straight line to `to`, meet anything on
//!   the way? Continuous test ([`super::ccd`]: the coplanarity cubic, then a proximity test at its roots) of
//!   every vertex–triangle and edge–edge pair that involves `v`.
//!
//! Used by [`super::improve()`] and, with [`crate::remeshing::RemeshParams::avoid_intersections`], by the
//! isotropic remesher: given a surface free of self-intersections, every operation they apply keeps it so.

use std::collections::HashMap;

use glam::Vec3;

use super::ccd::{Moving, edge_edge_ccd, vertex_triangle_ccd};
use crate::handles::{FaceId, VertexId};
use crate::intersect::faces_intersect;
use crate::surface_mesh::SurfaceMesh;

/// A multiplicative hash for grid cells (the default SipHash dominated the grid's cost).
#[derive(Default, Clone, Copy)]
struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_i32(&mut self, x: i32) {
        self.write_u64(x as u32 as u64);
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// A grid entry: a face and its box `[lo, hi]` when it was inserted.
type Entry = (u32, [Vec3; 2]);

type CellMap = HashMap<u64, Vec<Entry>, std::hash::BuildHasherDefault<CellHasher>>;

/// The map key of a cell: 21 bits per axis. Far-apart cells may share a key; their entries are then
/// filtered by the box test like any other.
#[inline]
fn key(c: [i32; 3]) -> u64 {
    let m = (1u64 << 21) - 1;
    (c[0] as u64 & m) | ((c[1] as u64 & m) << 21) | ((c[2] as u64 & m) << 42)
}

/// A uniform grid of face bounding boxes. Every change of a face's geometry inserts it again with its new
/// box; the entries of deleted faces and the outdated boxes of changed ones stay until the next
/// [`FaceGrid::rebuild`] and are filtered at query time (deleted faces; a face is reported once, through
/// an entry whose box overlaps the query, and then tested against its current box).
struct FaceGrid {
    h: f32,
    cells: CellMap,
    stamp: Vec<u32>,
    generation: u32,
}

/// The bounding box `[lo, hi]` of face `f`.
pub(crate) fn face_box(mesh: &SurfaceMesh, f: FaceId) -> [Vec3; 2] {
    let [a, b, c] = mesh.face_points(f);
    [a.min(b).min(c), a.max(b).max(c)]
}

impl FaceGrid {
    fn new(mesh: &SurfaceMesh, h: f32) -> Self {
        let mut g = Self { h, cells: CellMap::default(), stamp: Vec::new(), generation: 0 };
        g.rebuild(mesh);
        g
    }
    fn cell(&self, p: Vec3) -> [i32; 3] {
        // Guard: `as` saturates, so far-away or non-finite coordinates land in boundary cells, never panic.
        (p / self.h).floor().to_array().map(|x| x as i32)
    }
    fn range(&self, lo: Vec3, hi: Vec3) -> ([i32; 3], [i32; 3]) {
        let (a, mut b) = (self.cell(lo), self.cell(hi));
        for k in 0..3 {
            // Bounds the work for huge boxes: at most 65 cells per axis from the box's low corner. A box wider
            // than that (a face, or a ring's swept move, over 64 cells: with the remesher's cells of two mean
            // target edges, over 128 target edges on one axis) is inserted and queried over its first 65
            // cells only, so a face that overlaps it only beyond them is not a candidate. Kept because no
            // guarded operation comes near it: the remesher builds its guard on a mesh whose edges its sizing
            // field describes (a start mesh, or the last stage's remeshed surface, whose longest edge is 4/3 of
            // its target), and its moves stay inside a one-ring. Where a miss happened anyway, the run's
            // exact self-intersection check after each block finds it (the board's collision check reports
            // it; `NLOS_REQUIRE_NO_INTERSECTIONS=1` makes it an error). An exact form (an overflow list for
            // wide faces, every face for a wide query) changes no run that stays under the clamp.
            b[k] = b[k].min(a[k].saturating_add(64));
        }
        (a, b)
    }
    /// Empties the grid and inserts every live face.
    fn rebuild(&mut self, mesh: &SurfaceMesh) {
        self.cells.values_mut().for_each(Vec::clear);
        for f in mesh.faces() {
            self.insert(mesh, f);
        }
    }
    /// Face `f` had box `old` before its geometry changed: replaces its entries.
    fn moved(&mut self, mesh: &SurfaceMesh, f: FaceId, old: [Vec3; 2]) {
        let (lo, hi) = self.range(old[0], old[1]);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    if let Some(v) = self.cells.get_mut(&key([x, y, z])) {
                        v.retain(|e| e.0 != f.0);
                    }
                }
            }
        }
        self.insert(mesh, f);
    }
    fn insert(&mut self, mesh: &SurfaceMesh, f: FaceId) {
        let bx = face_box(mesh, f);
        let (lo, hi) = self.range(bx[0], bx[1]);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    self.cells.entry(key([x, y, z])).or_default().push((f.0, bx));
                }
            }
        }
    }
    /// Live faces whose current box overlaps `[lo, hi]`, each once.
    fn query(&mut self, mesh: &SurfaceMesh, lo: Vec3, hi: Vec3, out: &mut Vec<FaceId>) {
        out.clear();
        if self.stamp.len() < mesh.faces_size() {
            self.stamp.resize(mesh.faces_size(), 0);
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.fill(0);
            self.generation = 1;
        }
        let (a, b) = self.range(lo, hi);
        for x in a[0]..=b[0] {
            for y in a[1]..=b[1] {
                for z in a[2]..=b[2] {
                    let Some(v) = self.cells.get(&key([x, y, z])) else { continue };
                    for &(f, bx) in v {
                        // the entry's box first (cheap); a face is marked only once it is reported, so an
                        // outdated entry that fails here cannot hide the face's current one
                        if !(bx[0].cmple(hi).all() && lo.cmple(bx[1]).all())
                            || self.stamp[f as usize] == self.generation
                        {
                            continue;
                        }
                        let f = FaceId(f);
                        if mesh.is_deleted_face(f) {
                            continue;
                        }
                        let [flo, fhi] = face_box(mesh, f);
                        if flo.cmple(hi).all() && lo.cmple(fhi).all() {
                            self.stamp[f.0 as usize] = self.generation;
                            out.push(f);
                        }
                    }
                }
            }
        }
    }
}

/// A [`FaceGrid`] with the proximity tolerance of its continuous tests: the collision questions an operation
/// asks before it is applied (module docs). The caller keeps the grid current: [`Self::inserted`] after a
/// topological operation (for the faces it created or reshaped), [`Self::moved`] after a vertex moved (for
/// its one-ring, with their boxes from before), [`Self::rebuild`] after a garbage collection renumbered the
/// faces.
pub(crate) struct CollisionGuard {
    grid: FaceGrid,
    /// Distance at a coplanar instant that counts as contact in [`Self::move_collides`] (metres).
    tol: f64,
    cands: Vec<FaceId>,
}

impl CollisionGuard {
    /// A guard over the live faces of `mesh`, grid cells of `cell` metres (about twice the edge length),
    /// contact tolerance `tol` metres.
    pub(crate) fn new(mesh: &SurfaceMesh, cell: f32, tol: f64) -> Self {
        Self { grid: FaceGrid::new(mesh, cell), tol, cands: Vec::new() }
    }

    /// Forgets every entry and inserts every live face (after a garbage collection, or to drop stale entries).
    pub(crate) fn rebuild(&mut self, mesh: &SurfaceMesh) {
        self.grid.rebuild(mesh);
    }

    /// Face `f` was created or reshaped by a topological operation: adds its current box.
    pub(crate) fn inserted(&mut self, mesh: &SurfaceMesh, f: FaceId) {
        self.grid.insert(mesh, f);
    }

    /// Face `f` had box `old` ([`face_box`]) before one of its vertices moved: replaces its entries.
    pub(crate) fn moved(&mut self, mesh: &SurfaceMesh, f: FaceId, old: [Vec3; 2]) {
        self.grid.moved(mesh, f, old);
    }

    /// The faces of [`MoveScratch::remember_ring`] moved with their vertex: replaces their entries.
    pub(crate) fn moved_ring(&mut self, mesh: &SurfaceMesh, scratch: &MoveScratch) {
        for &(f, b) in &scratch.boxes {
            self.grid.moved(mesh, f, b);
        }
    }

    /// Whether the new faces (vertex ids, positions) intersect any live face except those in `skip`.
    #[inline(never)]
    pub(crate) fn new_faces_intersect(
        &mut self,
        mesh: &SurfaceMesh,
        new: &[([u32; 3], [Vec3; 3])],
        skip: &[FaceId],
    ) -> bool {
        let mut cands = std::mem::take(&mut self.cands);
        for (k, (fv, t)) in new.iter().enumerate() {
            let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            self.grid.query(mesh, lo, hi, &mut cands);
            for &g in &cands {
                if skip.contains(&g) {
                    continue;
                }
                let gv = mesh.face_vertices(g).map(|v| v.0);
                if faces_intersect(*fv, *t, gv, mesh.face_points(g)) {
                    self.cands = cands;
                    return true;
                }
            }
            for (gv, u) in &new[k + 1..] {
                if faces_intersect(*fv, *t, *gv, *u) {
                    return true;
                }
            }
        }
        self.cands = cands;
        false
    }

    /// Whether moving `v` on a straight line to `to` would meet anything: CCD of every vertex–triangle and edge–edge pair that involves `v` (the moving point
    /// against nearby faces, nearby vertices against the moving one-ring faces, the moving one-ring edges
    /// against nearby edges), each pair first filtered by its swept box.
    #[inline(never)]
    pub(crate) fn move_collides(
        &mut self,
        mesh: &SurfaceMesh,
        v: VertexId,
        to: Vec3,
        scratch: &mut MoveScratch,
    ) -> bool {
        let from = mesh.position(v);
        let at = |w: VertexId| if w == v { to } else { mesh.position(w) };
        scratch.ring.clear();
        scratch.ring.extend(mesh.vertex_faces(v));
        let mut lo = to.min(from);
        let mut hi = to.max(from);
        for &f in &scratch.ring {
            for q in mesh.face_points(f) {
                lo = lo.min(q);
                hi = hi.max(q);
            }
        }
        let tol = self.tol;
        let pad = Vec3::splat(tol as f32);
        let m = |w: VertexId| Moving::new(mesh.position(w), at(w));
        let boxed = |ps: &[Vec3]| {
            let (mut a, mut b) = (ps[0], ps[0]);
            for &q in &ps[1..] {
                a = a.min(q);
                b = b.max(q);
            }
            (a - pad, b + pad)
        };
        let overlap = |x: &(Vec3, Vec3), y: &(Vec3, Vec3)| x.0.cmple(y.1).all() && y.0.cmple(x.1).all();
        // swept boxes of the moving primitives: the point, the one-ring faces, the one-ring edges
        let vbox = boxed(&[from, to]);
        scratch.ring_m.clear();
        scratch.ring_m.extend(scratch.ring.iter().map(|&f| {
            let fv = mesh.face_vertices(f);
            let p = mesh.face_points(f);
            (fv, boxed(&[p[0], p[1], p[2], to]))
        }));
        scratch.spokes.clear();
        scratch.spokes.extend(mesh.vertex_vertices(v).map(|u| (u, boxed(&[from, to, mesh.position(u)]))));
        self.grid.query(mesh, lo - pad, hi + pad, &mut scratch.cands);
        scratch.verts.clear();
        scratch.edges.clear();
        for &g in &scratch.cands {
            let gv = mesh.face_vertices(g);
            if gv.contains(&v) {
                continue;
            }
            let gp = mesh.face_points(g);
            let gbox = boxed(&gp);
            if overlap(&vbox, &gbox) {
                let gm = gv.map(m);
                if vertex_triangle_ccd(&m(v), &gm[0], &gm[1], &gm[2], tol).is_some() {
                    return true;
                }
            }
            for k in 0..3 {
                scratch.verts.push(gv[k].0);
                let (c, d) = (gv[k].0, gv[(k + 1) % 3].0);
                scratch.edges.push((c.min(d), c.max(d)));
            }
        }
        scratch.verts.sort_unstable();
        scratch.verts.dedup();
        scratch.edges.sort_unstable();
        scratch.edges.dedup();
        // static vertices near the one-ring against the moving one-ring faces
        for &w in &scratch.verts {
            let w = VertexId(w);
            let q = mesh.position(w);
            let wbox = (q, q);
            for (fv, fbox) in &scratch.ring_m {
                if fv.contains(&w) || !overlap(&wbox, fbox) {
                    continue;
                }
                let fm = fv.map(m);
                if vertex_triangle_ccd(&m(w), &fm[0], &fm[1], &fm[2], tol).is_some() {
                    return true;
                }
            }
        }
        // moving one-ring edges (spokes) against static edges nearby
        for &(c, d) in &scratch.edges {
            let (c, d) = (VertexId(c), VertexId(d));
            let ebox = boxed(&[mesh.position(c), mesh.position(d)]);
            for &(u, sbox) in &scratch.spokes {
                if c == u || d == u || !overlap(&ebox, &sbox) {
                    continue;
                }
                if edge_edge_ccd(&m(v), &m(u), &m(c), &m(d), tol).is_some() {
                    return true;
                }
            }
        }
        false
    }

    /// The two questions of a vertex move, from one grid query: would moving `v` on a straight line to `to`
    /// meet anything on the way ([`Self::move_collides`]), or would one of its one-ring faces, with `v` at
    /// `to`, intersect a face outside the ring or another ring face ([`Self::new_faces_intersect`] of the
    /// moved ring, skipping the ring)? The same answer as asking the two in turn: the continuous test's query
    /// box holds every moved ring face's box, so its candidates hold each static query's, and the static
    /// test keeps those whose current box overlaps the moved face's, as the grid's own query does.
    pub(crate) fn move_intersects(
        &mut self,
        mesh: &SurfaceMesh,
        v: VertexId,
        to: Vec3,
        scratch: &mut MoveScratch,
    ) -> bool {
        if self.move_collides(mesh, v, to, scratch) {
            return true;
        }
        // `move_collides` ran to its end: `scratch.ring` is the one-ring, `scratch.cands` the live faces
        // whose box overlaps the ring's swept box.
        scratch.moved.clear();
        scratch.moved.extend(scratch.ring.iter().map(|&f| {
            let vs = mesh.face_vertices(f);
            (vs.map(|w| w.0), vs.map(|w| if w == v { to } else { mesh.position(w) }))
        }));
        // the candidates outside the ring, with their boxes
        scratch.cand_boxes.clear();
        let outside = scratch.cands.iter().filter(|g| !scratch.ring.contains(g));
        scratch.cand_boxes.extend(outside.map(|&g| (g, face_box(mesh, g))));
        for (k, (fv, t)) in scratch.moved.iter().enumerate() {
            let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            for &(g, [glo, ghi]) in &scratch.cand_boxes {
                if !(glo.cmple(hi).all() && lo.cmple(ghi).all()) {
                    continue;
                }
                let gv = mesh.face_vertices(g).map(|v| v.0);
                if faces_intersect(*fv, *t, gv, mesh.face_points(g)) {
                    return true;
                }
            }
            for (gv, u) in &scratch.moved[k + 1..] {
                if faces_intersect(*fv, *t, *gv, *u) {
                    return true;
                }
            }
        }
        false
    }
}

/// Reused buffers of [`CollisionGuard::move_collides`] and [`CollisionGuard::move_intersects`].
#[derive(Default)]
pub(crate) struct MoveScratch {
    ring: Vec<FaceId>,
    cands: Vec<FaceId>,
    verts: Vec<u32>,
    edges: Vec<(u32, u32)>,
    /// The one-ring's faces with their swept boxes, and its spokes' far ends with theirs.
    ring_m: Vec<([VertexId; 3], (Vec3, Vec3))>,
    spokes: Vec<(VertexId, (Vec3, Vec3))>,
    /// The one-ring's faces with `v` at its target (vertex ids, positions).
    moved: Vec<([u32; 3], [Vec3; 3])>,
    /// The static test's candidates (outside the one-ring) with their boxes.
    cand_boxes: Vec<(FaceId, [Vec3; 2])>,
    /// The one-ring's faces with their boxes before a move, for the grid's update after it.
    boxes: Vec<(FaceId, [Vec3; 2])>,
}

impl MoveScratch {
    /// The one-ring's faces and their current boxes, kept in [`Self::boxes`] until
    /// [`CollisionGuard::moved_ring`] hands them to the grid.
    pub(crate) fn remember_ring(&mut self, mesh: &SurfaceMesh, v: VertexId) {
        self.boxes.clear();
        self.boxes.extend(mesh.vertex_faces(v).map(|f| (f, face_box(mesh, f))));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `move_intersects` answers as the continuous test followed by the static test of the moved one-ring,
    /// each from its own grid queries, on a flattened sphere whose two sides lie closer than the moves, with
    /// the accepted moves applied (so the grid's updates are tested too).
    #[test]
    fn move_intersects_is_the_continuous_then_the_static_test() {
        let mut mesh = crate::shapes::icosphere(Vec3::ZERO, 1.0, 3);
        for v in mesh.vertices().collect::<Vec<_>>() {
            let p = mesh.position(v);
            mesh.set_position(v, Vec3::new(p.x, p.y, 0.04 * p.z));
        }
        let l = mesh.mean_edge_length();
        let mut guard = CollisionGuard::new(&mesh, 2.0 * l, 1e-7);
        let mut scratch = MoveScratch::default();
        let mut rng = nlos_transient::rng::SplitMix64::new(7);
        let verts: Vec<VertexId> = mesh.vertices().collect();
        let (mut refused, mut moved) = (0, 0);
        for k in 0..4000 {
            let v = verts[rng.below(verts.len())];
            let reach = [0.01, 0.1, 0.5][k % 3] * l;
            let d = Vec3::new(rng.range_f32(-1.0, 1.0), rng.range_f32(-1.0, 1.0), rng.range_f32(-1.0, 1.0));
            let to = mesh.position(v) + reach * d;
            let ring: Vec<FaceId> = mesh.vertex_faces(v).collect();
            let new: Vec<([u32; 3], [Vec3; 3])> = ring
                .iter()
                .map(|&f| {
                    let vs = mesh.face_vertices(f);
                    (vs.map(|w| w.0), vs.map(|w| if w == v { to } else { mesh.position(w) }))
                })
                .collect();
            let want = guard.move_collides(&mesh, v, to, &mut scratch) || guard.new_faces_intersect(&mesh, &new, &ring);
            assert_eq!(guard.move_intersects(&mesh, v, to, &mut scratch), want, "move {k}");
            if want {
                refused += 1;
            } else {
                scratch.remember_ring(&mesh, v);
                mesh.set_position(v, to);
                guard.moved_ring(&mesh, &scratch);
                moved += 1;
            }
        }
        assert!(refused > 100 && moved > 100, "both answers tested: {refused} refused, {moved} moved");
        assert_eq!(crate::intersect::self_intersections(&mesh).expect("faces"), vec![]);
    }
}
