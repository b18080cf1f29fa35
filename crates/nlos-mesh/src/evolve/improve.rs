//! Mesh improvement that never creates an intersection (El Topo's `SurfTrack::improve_mesh`, Brochu &
//! Bridson 2009 §5): split long edges, collapse short edges and edges of sliver triangles, flip edges for
//! the Delaunay criterion, null-space smoothing (Jiao 2007, "Face offsetting", as in El Topo).
//!
//! The topology operations are the mesh's own check/mutate pairs ([`SurfaceMesh::is_collapse_ok`] /
//! [`SurfaceMesh::collapse`], [`SurfaceMesh::split_edge`], [`SurfaceMesh::is_flip_ok`] /
//! [`SurfaceMesh::flip`]); each is additionally rejected when
//! - (collapse, flip) a new face intersects any other face: exact static test
//!   ([`crate::intersect::faces_intersect`]) against the faces near it (a uniform grid of face boxes;
//!   `guard.rs`, shared with the remesher);
//! - (collapse, flip) it changes the enclosed volume by more than `max_volume_change·L³` (El Topo's
//!   `max_volume_change`), flips a face normal, or creates an angle below `min_angle` where the faces it
//!   replaces had none that small;
//! - (collapse) it creates an edge longer than `max_edge_ratio·L` (so splits and collapses do not undo
//!   each other);
//! - (smoothing) the vertex's straight-line move meets anything: continuous test with [`super::ccd`].
//!
//! Splits are at the edge midpoint: the two new triangles cover exactly the old one, so a split cannot
//! create an intersection and needs no test. Collapses keep one endpoint where it is (the one on the
//! boundary if there is one), so the only geometry that changes is the one-ring of the removed vertex,
//! and the static test of the new faces is complete.

use glam::{DMat3, DVec3, Vec3};

use super::EvolveParams;
use super::guard::{CollisionGuard, MoveScratch, face_box};
use crate::MeshError;
use crate::handles::{EdgeId, FaceId, HalfedgeId, VertexId};
use crate::quality::triangle_angles;
use crate::surface_mesh::SurfaceMesh;

/// What [`improve()`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ImproveReport {
    /// Edge splits.
    pub splits: usize,
    /// Edge collapses.
    pub collapses: usize,
    /// Edge flips.
    pub flips: usize,
    /// Vertices moved by null-space smoothing.
    pub smoothed: usize,
    /// Operations refused because they would create an intersection (static or continuous test).
    pub rejected_intersection: usize,
    /// Operations refused by the volume bound.
    pub rejected_volume: usize,
    /// Operations refused for quality (normal flip, angle, edge length, manifoldness).
    pub rejected_quality: usize,
}

/// Improves `mesh` with the targets of `params` (edge length `L` from `params.edge_length` or the mean edge
/// length). Never creates a self-intersection. The mesh is garbage-collected on return when an operation
/// deleted elements, so handles held before are invalid then.
pub fn improve(mesh: &mut SurfaceMesh, params: &EvolveParams) -> Result<ImproveReport, MeshError> {
    params.validate()?;
    mesh.validate()?;
    let l = params.edge_length.unwrap_or_else(|| mesh.mean_edge_length());
    improve_with_length(mesh, params, l)
}

pub(crate) fn improve_with_length(
    mesh: &mut SurfaceMesh,
    params: &EvolveParams,
    l: f32,
) -> Result<ImproveReport, MeshError> {
    let mut report = ImproveReport::default();
    // Guard: a mesh whose mean edge length is 0 or not finite has nothing to improve toward.
    if !(l.is_finite() && l > 0.0) || mesh.n_faces() == 0 {
        return Ok(report);
    }
    let mut imp = Improver {
        grid: CollisionGuard::new(mesh, 2.0 * l, 1e-7 * f64::from(params.max_edge_ratio * l).max(1e-30)),
        min_len: params.min_edge_ratio * l,
        max_len: params.max_edge_ratio * l,
        min_angle: params.min_angle_degrees,
        max_angle: params.max_angle_degrees,
        max_dv: params.max_volume_change as f64 * (l as f64).powi(3),
        report: &mut report,
    };
    for _ in 0..params.improve_sweeps {
        imp.split_long_edges(mesh);
        // drop the stale entries the previous pass left (deleted and reshaped faces)
        imp.grid.rebuild(mesh);
        imp.collapse_short_edges(mesh);
        imp.grid.rebuild(mesh);
        imp.flip_edges(mesh);
        if params.smoothing {
            imp.grid.rebuild(mesh);
            imp.smooth(mesh);
        }
    }
    if mesh.has_garbage() {
        mesh.garbage_collect();
    }
    Ok(report)
}

struct Improver<'a> {
    grid: CollisionGuard,
    min_len: f32,
    max_len: f32,
    min_angle: f32,
    max_angle: f32,
    max_dv: f64,
    report: &'a mut ImproveReport,
}

/// Smallest angle of a triangle (degrees): the one opposite the shortest edge, so one `atan2` instead of the
/// three of [`triangle_angles`] (the same formula, so the same value up to ties).
fn min_angle_of(p: [Vec3; 3]) -> f32 {
    let q = p.map(|x| x.as_dvec3());
    // edge k is opposite corner k
    let len2 = [(q[2] - q[1]).length_squared(), (q[0] - q[2]).length_squared(), (q[1] - q[0]).length_squared()];
    let k = if len2[0] <= len2[1] && len2[0] <= len2[2] {
        0
    } else if len2[1] <= len2[2] {
        1
    } else {
        2
    };
    let (u, v) = (q[(k + 1) % 3] - q[k], q[(k + 2) % 3] - q[k]);
    u.cross(v).length().atan2(u.dot(v)).to_degrees() as f32
}

fn normal(p: [Vec3; 3]) -> DVec3 {
    let [a, b, c] = p.map(|x| x.as_dvec3());
    (b - a).cross(c - a)
}

impl Improver<'_> {
    #[inline(never)]
    fn split_long_edges(&mut self, mesh: &mut SurfaceMesh) {
        let mut long: Vec<(f32, EdgeId)> = mesh
            .edges()
            .map(|e| (mesh.edge_length(e), e))
            .filter(|&(len, _)| len > self.max_len && len.is_finite())
            .collect();
        long.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (_, e) in long {
            if mesh.is_deleted_edge(e) {
                continue;
            }
            let [a, b] = mesh.edge_vertices(e);
            let mid = (mesh.position(a) + mesh.position(b)) * 0.5;
            let v = mesh.split_edge(e, mid);
            let faces: Vec<FaceId> = mesh.vertex_faces(v).collect();
            for f in faces {
                self.grid.inserted(mesh, f);
            }
            self.report.splits += 1;
        }
    }

    #[inline(never)]
    fn collapse_short_edges(&mut self, mesh: &mut SurfaceMesh) {
        let mut cands: Vec<(f32, EdgeId)> = mesh
            .edges()
            .filter_map(|e| {
                let len = mesh.edge_length(e);
                if len < self.min_len {
                    return Some((len, e));
                }
                None
            })
            .collect();
        // the shortest edge of each sliver (min angle below target)
        for f in mesh.faces() {
            let p = mesh.face_points(f);
            if min_angle_of(p) < self.min_angle {
                let hs = mesh.face_halfedges(f);
                let e = hs
                    .iter()
                    .map(|h| h.edge())
                    .min_by(|&x, &y| mesh.edge_length(x).total_cmp(&mesh.edge_length(y)))
                    .unwrap_or(hs[0].edge());
                cands.push((mesh.edge_length(e), e));
            }
        }
        cands.sort_by(|a, b| a.0.total_cmp(&b.0));
        cands.dedup_by_key(|c| c.1);
        for (_, e) in cands {
            if mesh.is_deleted_edge(e) {
                continue;
            }
            // keep a boundary endpoint in place: collapse the other one onto it
            let h0 = e.halfedge(0);
            let (a, b) = (mesh.from_vertex(h0), mesh.to_vertex(h0));
            let order = if mesh.is_boundary_vertex(a) && !mesh.is_boundary_vertex(b) {
                [h0.opposite(), h0]
            } else {
                [h0, h0.opposite()]
            };
            for h in order {
                if self.try_collapse(mesh, h) {
                    break;
                }
            }
        }
    }

    /// Collapses `h` (removes `from(h)`, keeps `to(h)` in place) if every check passes.
    #[inline(never)]
    fn try_collapse(&mut self, mesh: &mut SurfaceMesh, h: HalfedgeId) -> bool {
        let (v0, v1) = (mesh.from_vertex(h), mesh.to_vertex(h));
        let (x0, x1) = (mesh.position(v0), mesh.position(v1));
        // the cheap length test first: with a tight edge band it rejects most candidates
        for w in mesh.vertex_vertices(v0) {
            if w != v1 && (mesh.position(w) - x1).length() > self.max_len {
                self.report.rejected_quality += 1;
                return false;
            }
        }
        if !mesh.is_collapse_ok(h) {
            self.report.rejected_quality += 1;
            return false;
        }
        if mesh.is_boundary_vertex(v0) && !mesh.is_boundary_edge(h.edge()) {
            self.report.rejected_quality += 1;
            return false; // would pull the boundary inward
        }
        let old_faces: Vec<FaceId> = mesh.vertex_faces(v0).collect();
        let worst_old = old_faces
            .iter()
            .chain(mesh.vertex_faces(v1).collect::<Vec<_>>().iter())
            .map(|&f| min_angle_of(mesh.face_points(f)))
            .fold(f32::INFINITY, f32::min);
        let mut new = Vec::new();
        let mut dv = 0.0f64;
        for &f in &old_faces {
            let vs = mesh.face_vertices(f);
            if vs.contains(&v1) {
                continue; // degenerates and disappears
            }
            let old_p = mesh.face_points(f);
            let new_vs = vs.map(|v| if v == v0 { v1 } else { v });
            let new_p = new_vs.map(|v| mesh.position(v));
            let (n_old, n_new) = (normal(old_p), normal(new_p));
            if n_old.dot(n_new) <= 0.0 || n_new.length_squared() == 0.0 {
                self.report.rejected_quality += 1;
                return false;
            }
            if min_angle_of(new_p) < self.min_angle.min(worst_old) {
                self.report.rejected_quality += 1;
                return false;
            }
            // volume swept by moving v0 to v1 over this face: det(b − x0, c − x0, x1 − x0)/6
            let k = vs.iter().position(|&v| v == v0).unwrap_or(0);
            let (b, c) = (old_p[(k + 1) % 3].as_dvec3(), old_p[(k + 2) % 3].as_dvec3());
            let p0 = x0.as_dvec3();
            dv += (b - p0).cross(c - p0).dot(x1.as_dvec3() - p0) / 6.0;
            new.push((new_vs.map(|v| v.0), new_p));
        }
        if dv.abs() > self.max_dv {
            self.report.rejected_volume += 1;
            return false;
        }
        if self.grid.new_faces_intersect(mesh, &new, &old_faces) {
            self.report.rejected_intersection += 1;
            return false;
        }
        mesh.collapse(h);
        let faces: Vec<FaceId> = mesh.vertex_faces(v1).collect();
        for f in faces {
            self.grid.inserted(mesh, f);
        }
        self.report.collapses += 1;
        true
    }

    #[inline(never)]
    fn flip_edges(&mut self, mesh: &mut SurfaceMesh) {
        let edges: Vec<EdgeId> = mesh.edges().collect();
        for e in edges {
            if mesh.is_deleted_edge(e) || !mesh.is_flip_ok(e) {
                continue;
            }
            let (h0, h1) = (e.halfedge(0), e.halfedge(1));
            let (a, b) = (mesh.from_vertex(h0), mesh.to_vertex(h0));
            let c = mesh.to_vertex(mesh.next(h0));
            let d = mesh.to_vertex(mesh.next(h1));
            let [pa, pb, pc, pd] = [a, b, c, d].map(|v| mesh.position(v));
            // Delaunay: the angles opposite the edge sum to more than 180°, or one exceeds max_angle
            let alpha = triangle_angles(pc, pa, pb)[0];
            let beta = triangle_angles(pd, pb, pa)[0];
            if !(alpha + beta > 180.0 + 1e-3 || alpha.max(beta) > self.max_angle) {
                continue;
            }
            // after the flip: faces (c, a, d) and (d, b, c) (orientation of the mesh's flip)
            let t1 = [pc, pa, pd];
            let t2 = [pd, pb, pc];
            let worst_old = min_angle_of([pa, pb, pc]).min(min_angle_of([pb, pa, pd]));
            let worst_new = min_angle_of(t1).min(min_angle_of(t2));
            if worst_new <= worst_old {
                continue; // not an improvement
            }
            let n_old = normal([pa, pb, pc]) + normal([pb, pa, pd]);
            if normal(t1).dot(n_old) <= 0.0 || normal(t2).dot(n_old) <= 0.0 {
                self.report.rejected_quality += 1;
                continue;
            }
            let vol = (pb - pa).as_dvec3().cross((pc - pa).as_dvec3()).dot((pd - pa).as_dvec3()).abs() / 6.0;
            if vol > self.max_dv {
                self.report.rejected_volume += 1;
                continue;
            }
            let old = [mesh.face(h0), mesh.face(h1)];
            let new = [([c.0, a.0, d.0], t1), ([d.0, b.0, c.0], t2)];
            if self.grid.new_faces_intersect(mesh, &new, &old) {
                self.report.rejected_intersection += 1;
                continue;
            }
            mesh.flip(e);
            for f in old {
                self.grid.inserted(mesh, f);
            }
            self.report.flips += 1;
        }
    }

    /// Null-space smoothing: the move toward the area-weighted centroid of the one-ring, projected onto the
    /// null space of the vertex's normal quadric `Σ Aᶠ nᶠnᶠᵀ` (eigenvectors with eigenvalue below 3 % of
    /// the largest, El Topo's threshold): tangential on smooth parts, along the crease on creases, none at
    /// corners. Boundary vertices stay. Each move is checked continuously.
    #[inline(never)]
    fn smooth(&mut self, mesh: &mut SurfaceMesh) {
        let verts: Vec<VertexId> = mesh.vertices().collect();
        let mut scratch = MoveScratch::default();
        for v in verts {
            if mesh.is_boundary_vertex(v) || mesh.is_isolated(v) {
                continue;
            }
            let x = mesh.position(v).as_dvec3();
            let mut q = DMat3::ZERO;
            let mut centroid = DVec3::ZERO;
            let mut area_sum = 0.0;
            for f in mesh.vertex_faces(v) {
                let p = mesh.face_points(f);
                let n2 = normal(p);
                let area = 0.5 * n2.length();
                // Guard: degenerate faces carry no normal information
                if !(area > 0.0) {
                    continue;
                }
                let n = n2 / (2.0 * area);
                q += DMat3::from_cols(n * n.x, n * n.y, n * n.z) * area;
                centroid += (p[0].as_dvec3() + p[1].as_dvec3() + p[2].as_dvec3()) / 3.0 * area;
                area_sum += area;
            }
            if !(area_sum > 0.0) {
                continue;
            }
            let t = centroid / area_sum - x;
            let (vals, vecs) = symmetric_eigen(q);
            let lmax = vals.iter().fold(0.0f64, |m, &x| m.max(x));
            let mut step = DVec3::ZERO;
            for k in 0..3 {
                if vals[k] < 0.03 * lmax {
                    step += vecs[k] * vecs[k].dot(t);
                }
            }
            let to = (x + step).as_vec3();
            if !to.is_finite() || to == mesh.position(v) {
                continue;
            }
            if self.vertex_move_ok(mesh, v, to, &mut scratch) {
                let old: Vec<(FaceId, [Vec3; 2])> = mesh.vertex_faces(v).map(|f| (f, face_box(mesh, f))).collect();
                mesh.set_position(v, to);
                for (f, p) in old {
                    self.grid.moved(mesh, f, p);
                }
                self.report.smoothed += 1;
            }
        }
    }

    /// Whether moving `v` on a straight line to `to` keeps the one-ring's normals and angles acceptable and
    /// meets nothing ([`CollisionGuard::move_collides`]).
    #[inline(never)]
    fn vertex_move_ok(&mut self, mesh: &SurfaceMesh, v: VertexId, to: Vec3, scratch: &mut MoveScratch) -> bool {
        for f in mesh.vertex_faces(v) {
            let pn = mesh.face_vertices(f).map(|w| if w == v { to } else { mesh.position(w) });
            let p = mesh.face_points(f);
            if normal(p).dot(normal(pn)) <= 0.0 || min_angle_of(pn) < self.min_angle.min(min_angle_of(p)) {
                self.report.rejected_quality += 1;
                return false;
            }
        }
        if self.grid.move_collides(mesh, v, to, scratch) {
            self.report.rejected_intersection += 1;
            return false;
        }
        true
    }
}

/// Eigen-decomposition of a symmetric 3×3 matrix by cyclic Jacobi rotations (Golub & Van Loan §8.5):
/// eigenvalues and unit eigenvectors.
#[allow(clippy::needless_range_loop)] // the rotations read more clearly with explicit indices
fn symmetric_eigen(m: DMat3) -> ([f64; 3], [DVec3; 3]) {
    let mut a = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            a[i][j] = m.col(j)[i];
        }
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0f64]];
    for _ in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        // Guard: converged (or a zero matrix)
        if !(off > 1e-15 * (a[0][0].abs() + a[1][1].abs() + a[2][2].abs())) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let vals = [a[0][0], a[1][1], a[2][2]];
    let vecs = [0, 1, 2].map(|k| DVec3::new(v[0][k], v[1][k], v[2][k]));
    (vals, vecs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobi_eigen() {
        let m = DMat3::from_cols(DVec3::new(2.0, 1.0, 0.0), DVec3::new(1.0, 2.0, 0.0), DVec3::new(0.0, 0.0, 5.0));
        let (vals, vecs) = symmetric_eigen(m);
        let mut s = vals;
        s.sort_by(f64::total_cmp);
        assert!((s[0] - 1.0).abs() < 1e-12 && (s[1] - 3.0).abs() < 1e-12 && (s[2] - 5.0).abs() < 1e-12);
        for k in 0..3 {
            assert!((m * vecs[k] - vecs[k] * vals[k]).length() < 1e-12);
        }
    }
}
