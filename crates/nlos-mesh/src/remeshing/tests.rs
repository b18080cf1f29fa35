//! The remesher's collision guard ([`RemeshParams::avoid_intersections`]) on the situations it exists for:
//! a collapse that would fold the surface through a part just under it, a relaxation move through it.

use super::*;
use crate::intersect::self_intersections;

/// A 5 × 5 grid of unit spacing at z = 0 with its centre vertex lifted to z = 1 (a tent), and a second
/// component: a small vertical triangle under the tent's apex, inside the tent, touching nothing. Returns
/// the mesh, the apex and a neighbour of it on the plane.
fn tent_over_a_thin_part() -> (SurfaceMesh, VertexId, VertexId) {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for j in 0..5 {
        for i in 0..5 {
            let z = if (i, j) == (2, 2) { 1.0 } else { 0.0 };
            positions.push(Vec3::new(i as f32, j as f32, z));
        }
    }
    for j in 0..4u32 {
        for i in 0..4u32 {
            let (a, b, c, d) = (j * 5 + i, j * 5 + i + 1, (j + 1) * 5 + i, (j + 1) * 5 + i + 1);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    // The tent's surface lies at height 1 − r at horizontal distance r from the apex: a triangle within
    // 0.04 of it horizontally and below z = 0.9 stays inside.
    let k = positions.len() as u32;
    positions.extend([Vec3::new(2.0 - 0.04, 2.0, 0.05), Vec3::new(2.0 + 0.04, 2.0, 0.05), Vec3::new(2.0, 2.0, 0.9)]);
    triangles.push([k, k + 1, k + 2]);
    let mesh = SurfaceMesh::from_triangles(&positions, &triangles).expect("valid");
    assert!(self_intersections(&mesh).expect("checked").is_empty(), "the start touches nothing");
    (mesh, VertexId::new(12), VertexId::new(13))
}

fn remesher(mesh: &mut SurfaceMesh, guard: bool) -> Remesher<'_> {
    let params = RemeshParams { avoid_intersections: guard, ..RemeshParams::pmp() };
    let sizing = vec![2.0; mesh.vertices_size()];
    Remesher::new(mesh, sizing, true, &params).expect("remesher")
}

#[test]
fn a_collapse_that_would_fold_the_surface_through_a_thin_part_is_refused() {
    let (mut mesh, apex, next) = tent_over_a_thin_part();
    let h = mesh.find_halfedge(apex, next);
    let target = (mesh.position(apex) + mesh.position(next)) * 0.5;
    // Without the guard the remesher's own rules allow it, and it would intersect.
    {
        let mut r = remesher(&mut mesh, false);
        assert!(r.collapse_allowed(h, target), "the collapse passes the remeshing rules");
    }
    let mut folded = mesh.clone();
    folded.collapse(h);
    folded.set_position(next, target);
    assert!(!self_intersections(&folded).expect("checked").is_empty(), "the collapsed tent crosses the part");
    let mut r = remesher(&mut mesh, true);
    assert!(!r.collapse_allowed(h, target), "refused with the guard");
    assert_eq!(r.report.refused_intersections, 1);
}

#[test]
fn a_move_through_a_thin_part_is_refused_and_the_vertex_stays() {
    let (mut mesh, apex, _) = tent_over_a_thin_part();
    let from = mesh.position(apex);
    let to = from - Vec3::new(0.0, 0.0, 0.8);
    let mut r = remesher(&mut mesh, true);
    assert!(!r.move_vertex(apex, to), "the apex may not pass through the part");
    assert_eq!(r.mesh.position(apex), from);
    assert_eq!(r.report.refused_intersections, 1);
    // A move that stays clear is made.
    let up = from + Vec3::new(0.0, 0.0, 0.5);
    assert!(r.move_vertex(apex, up));
    assert_eq!(r.mesh.position(apex), up);
    assert!(self_intersections(r.mesh).expect("checked").is_empty());
}

#[test]
fn remeshing_with_the_guard_keeps_the_tent_clear_of_the_part() {
    let (mesh, _, _) = tent_over_a_thin_part();
    let mut unguarded = mesh.clone();
    uniform_remeshing(&mut unguarded, 1.5, &RemeshParams::pmp()).expect("remeshes");
    assert!(!self_intersections(&unguarded).expect("checked").is_empty(), "without the guard the tent folds through");
    for target in [1.5f32, 2.0, 3.0] {
        let mut m = mesh.clone();
        let report =
            uniform_remeshing(&mut m, target, &RemeshParams { avoid_intersections: true, ..RemeshParams::pmp() })
                .expect("remeshes");
        let pairs = self_intersections(&m).expect("checked");
        assert!(pairs.is_empty(), "L = {target}: {} pairs ({report:?})", pairs.len());
    }
}
