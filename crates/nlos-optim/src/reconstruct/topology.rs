//! The mesh between shape steps: unlit boundary faces, remeshing with the surface's fields carried over,
//! self-intersection repair, faces deleted, and the collision-aware evolution of a block.

use std::time::Instant;

use glam::Vec3;
use nlos_mesh::SurfaceMesh;
use nlos_mesh::evolve::{EvolveParams, evolve};
use nlos_mesh::intersect::triangle_self_intersections;
use nlos_mesh::remeshing::uniform_remeshing;
use nlos_transient::{Scan, TimeAxis, Transient};

use super::record::RunRecord;
use super::{EvolveRecord, IntersectionCheck, IntersectionRecord};
use crate::error::{OptimError, Result};
use crate::params::ReconstructParams;
use crate::surface::{Remap, Surface};

/// Whether a face with corners `p` can receive light in some measurement (one-sided faces, positive wall
/// cosines, path length inside the time window) — tested at the centroid.
pub(super) fn face_lit(p: [Vec3; 3], scan: &Scan, time: &TimeAxis, two_sided: bool) -> bool {
    let c = (p[0] + p[1] + p[2]) / 3.0;
    let n = (p[1] - p[0]).cross(p[2] - p[0]);
    let (t0, t1) = (time.t0 as f32, time.end() as f32);
    (0..scan.measurements()).any(|m| {
        let g = scan.measurement(m);
        let (a, b) = (g.laser - c, g.sensor - c);
        let (dl, ds) = (n.dot(a), n.dot(b));
        let facing = (dl > 0.0 && ds > 0.0) || (two_sided && dl < 0.0 && ds < 0.0);
        let tau = a.length() + b.length();
        facing && -g.laser_normal.dot(a) > 0.0 && -g.sensor_normal.dot(b) > 0.0 && tau >= t0 && tau <= t1
    })
}

/// Step 1 of a block: unlit boundary faces, remeshing, every surface field carried over ([`Remap::closest`]).
/// Returns the boundary flags and the operations the remeshing refused because they would have made the
/// surface intersect itself.
pub(super) fn prepare_topology(
    st: &mut RunRecord,
    target: f32,
    params: &ReconstructParams,
    measured: &Transient,
) -> Result<(Vec<bool>, usize)> {
    let mut mesh = st.surface.mesh()?;
    // Boundary faces no measurement can see carry no signal and no gradient: they go before remeshing.
    let dark: Vec<_> = mesh
        .faces()
        .filter(|&f| {
            mesh.is_boundary_face(f)
                && !face_lit(mesh.face_points(f), measured.scan(), measured.time(), params.render.two_sided)
        })
        .collect();
    // Guard: never delete everything (a mesh entirely out of view keeps its faces and its zero signal).
    if !dark.is_empty() && dark.len() < mesh.n_faces() {
        let mut pruned = mesh.clone();
        for f in dark {
            pruned.delete_face(f);
        }
        pruned.garbage_collect();
        // Deleting faces can pinch a vertex between two boundary loops (a non-manifold "bow tie" that
        // the half-edge builder rejects): keep the faces for this block rather than fail the run.
        if is_manifold(&pruned) {
            mesh = pruned;
        }
    }
    if mesh.n_faces() == 0 {
        return Err(OptimError::EmptyMesh { context: "after removing unlit faces" });
    }
    let mut remeshed = mesh.clone();
    let refused = uniform_remeshing(&mut remeshed, target, &params.remesh)?.refused_intersections;
    // Guard against a remeshing result that is not a valid manifold mesh: keep the unremeshed mesh.
    if is_manifold(&remeshed) {
        mesh = remeshed;
    }
    if mesh.n_faces() == 0 {
        return Err(OptimError::EmptyMesh { context: "after remeshing" });
    }
    // The fields of the surface before both changes, at the new vertices.
    let remap = Remap::closest(&st.surface, &mesh)?;
    st.surface.apply(remap)?;
    untangle(st, IntersectionCheck::Remeshed)?;
    Ok((st.surface.boundary_vertices(), refused))
}

/// Keeps the triangles flagged in `keep` and the vertices they use (renumbered in order), with every field.
pub(super) fn drop_faces(st: &mut RunRecord, keep: &[bool]) -> Result<()> {
    let remap = Remap::keep_faces(&st.surface, keep);
    st.surface.apply(remap)
}

/// Checks the surface for self-intersections and deletes the faces that cause them ([`IntersectionRecord`]),
/// with their vertices' fields: the smaller face of each pair (else both), and the smaller fans of a vertex
/// the deletions pinch, so the rest stays a manifold mesh; the check is logged. After the start, where collision handling should
/// leave nothing to find, pairs found are an error under `NLOS_REQUIRE_NO_INTERSECTIONS=1`
/// ([`OptimError::SelfIntersecting`]).
pub(super) fn untangle(st: &mut RunRecord, check: IntersectionCheck) -> Result<()> {
    let pairs = triangle_self_intersections(st.surface.positions(), st.surface.triangles())?;
    if check != IntersectionCheck::Start && !pairs.is_empty() && require_no_intersections() {
        let check = match check {
            IntersectionCheck::Remeshed => "remeshed",
            _ => "block_end",
        };
        return Err(OptimError::SelfIntersecting {
            stage: st.stage,
            block: st.block_in_stage,
            check,
            pairs: pairs.len(),
        });
    }
    let mut record = IntersectionRecord {
        stage: st.stage,
        block: st.block_in_stage,
        check,
        pairs: pairs.len(),
        faces_removed: 0,
        pairs_left: pairs.len(),
    };
    if !pairs.is_empty() {
        let (positions, triangles) = (st.surface.positions(), st.surface.triangles());
        let area = |f: u32| {
            let t = triangles[f as usize].map(|v| positions[v as usize]);
            (t[1] - t[0]).cross(t[2] - t[0]).length()
        };
        let smaller: Vec<u32> = pairs.iter().map(|&(f, g)| if area(f) <= area(g) { f } else { g }).collect();
        let both: Vec<u32> = pairs.iter().flat_map(|&(f, g)| [f, g]).collect();
        let vertex_faces = crate::prune::vertex_faces(positions.len(), triangles);
        for doomed in [smaller, both] {
            let mut keep = vec![true; st.surface.n_faces()];
            for &f in &doomed {
                keep[f as usize] = false;
            }
            // A vertex the deletions pinch between two fans keeps its largest fan (a few more faces go).
            let seeds = doomed.iter().flat_map(|&f| triangles[f as usize]);
            crate::prune::unpinch(seeds, triangles, &vertex_faces, &mut keep);
            let remap = Remap::keep_faces(&st.surface, &keep);
            // Guard: never delete everything, nor keep what does not rebuild.
            if remap.triangles.is_empty() || SurfaceMesh::from_triangles(&remap.positions, &remap.triangles).is_err() {
                continue;
            }
            record.faces_removed = st.surface.n_faces() - remap.triangles.len();
            st.surface.apply(remap)?;
            record.pairs_left = triangle_self_intersections(st.surface.positions(), st.surface.triangles())?.len();
            break;
        }
    }
    st.log.intersections.push(record);
    Ok(())
}

/// Whether the environment asks that no check after the start find an intersection
/// (`NLOS_REQUIRE_NO_INTERSECTIONS=1`; CI's strictness, as `NLOS_REQUIRE_DATA`).
fn require_no_intersections() -> bool {
    std::env::var_os("NLOS_REQUIRE_NO_INTERSECTIONS").is_some_and(|v| v == "1")
}

/// Whether the mesh's triangles rebuild into a valid half-edge mesh (no non-manifold vertex or edge).
pub(super) fn is_manifold(mesh: &SurfaceMesh) -> bool {
    let (p, t) = mesh.to_triangles();
    !t.is_empty() && SurfaceMesh::from_triangles(&p, &t).is_ok()
}

/// One shape step: moves the mesh by `displacement` so that the surface does not pass through itself, on the
/// way or at the end (`nlos_mesh::evolve`, after El Topo, Brochu & Bridson 2009: continuous collision
/// detection, proximity impulses, impact zones, fail-safe, then the exact static check of the end state),
/// improvement off (the Adam state needs fixed connectivity). The mesh was checked at the block's start, so
/// the input is not checked again. A vertex no collision touches ends at exactly `x₀ + d`. The step is
/// tallied in `record`.
pub(super) fn collision_step(
    surface: &Surface,
    displacement: &[Vec3],
    target: f32,
    ep: EvolveParams,
    record: &mut EvolveRecord,
) -> Result<Vec<Vec3>> {
    let t0 = Instant::now();
    let mut mesh = surface.mesh()?;
    let ep = EvolveParams { improve: false, check_input: false, edge_length: ep.edge_length.or(Some(target)), ..ep };
    let report = evolve(&mut mesh, displacement, &ep)?;
    let pos = mesh.positions();
    if pos.len() != surface.n_vertices() || pos.iter().any(|p| !p.is_finite()) {
        return Err(OptimError::EvolveOutput { expected: surface.n_vertices(), got: pos.len() });
    }
    record.seconds += t0.elapsed().as_secs_f64();
    record.steps += 1;
    if report.vertices_adjusted > 0 {
        record.steps_limited += 1;
        record.vertices_adjusted += report.vertices_adjusted;
    }
    record.motion_fraction = record.motion_fraction.min(report.motion_fraction);
    Ok(pos.to_vec())
}
