//! The mesh between shape steps: unlit boundary faces, remeshing with the Adam state carried over,
//! self-intersection repair, faces deleted or appended, and the collision-aware evolution of a block.

use super::*;

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

/// Step 1 of a block: unlit boundary faces, remeshing, Adam transfer. Returns the boundary flags and the
/// operations the remeshing refused because they would have made the surface intersect itself.
pub(super) fn prepare_topology(
    st: &mut State,
    target: f32,
    params: &ReconstructParams,
    measured: &Transient,
) -> Result<(Vec<bool>, usize)> {
    let (old_pos, old_tris) = (st.positions.clone(), st.triangles.clone());
    let mut mesh = SurfaceMesh::from_triangles(&st.positions, &st.triangles)?;
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
    let (pos, tris) = mesh.to_triangles();
    if tris.is_empty() {
        return Err(OptimError::EmptyMesh { context: "after remeshing" });
    }
    let boundary: Vec<bool> = mesh.vertices().map(|v| mesh.is_boundary_vertex(v)).collect();
    let bvh = TriangleBvh::from_triangles(&old_pos, &old_tris)?;
    let weights: Vec<[(u32, f32); 3]> = pos
        .iter()
        .map(|p| {
            let cp = bvh.closest_point(*p);
            let t = old_tris[cp.triangle as usize];
            let b = cp.barycentric;
            [(t[0], b.x.max(0.0)), (t[1], b.y.max(0.0)), (t[2], b.z.max(0.0))]
        })
        .collect();
    st.shape_adam = st.shape_adam.transfer(&weights);
    st.positions = pos;
    st.triangles = tris;
    let faces = st.triangles.len();
    untangle(st, IntersectionCheck::Remeshed)?;
    if st.triangles.len() == faces {
        return Ok((boundary, refused));
    }
    // Faces went: the boundary flags of the mesh as it now is.
    let mesh = mesh_of(st)?;
    Ok((mesh.vertices().map(|v| mesh.is_boundary_vertex(v)).collect(), refused))
}

/// Keeps the triangles flagged in `keep` and the vertices they use (renumbered in order), with their Adam
/// moments.
pub(super) fn drop_faces(st: &mut State, keep: &[bool]) {
    let mut new_index = vec![u32::MAX; st.positions.len()];
    let mut old_of_new: Vec<u32> = Vec::new();
    let mut triangles = Vec::with_capacity(st.triangles.len());
    for (t, _) in st.triangles.iter().zip(keep).filter(|(_, k)| **k) {
        let mut out = [0u32; 3];
        for (o, &v) in out.iter_mut().zip(t) {
            if new_index[v as usize] == u32::MAX {
                new_index[v as usize] = old_of_new.len() as u32;
                old_of_new.push(v);
            }
            *o = new_index[v as usize];
        }
        triangles.push(out);
    }
    let source: Vec<Option<u32>> = old_of_new.iter().map(|&v| Some(v)).collect();
    st.shape_adam = st.shape_adam.select(&source);
    st.positions = old_of_new.iter().map(|&v| st.positions[v as usize]).collect();
    st.triangles = triangles;
}

/// Checks the surface for self-intersections and deletes the faces that cause them ([`IntersectionRecord`]),
/// with their vertices' Adam state; the check is logged. After the start, where collision handling should
/// leave nothing to find, pairs found are an error under `NLOS_REQUIRE_NO_INTERSECTIONS=1`
/// ([`OptimError::SelfIntersecting`]).
pub(super) fn untangle(st: &mut State, check: IntersectionCheck) -> Result<()> {
    let pairs = triangle_self_intersections(&st.positions, &st.triangles)?;
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
        let area = |f: u32| {
            let t = st.triangles[f as usize].map(|v| st.positions[v as usize]);
            (t[1] - t[0]).cross(t[2] - t[0]).length()
        };
        let smaller: Vec<u32> = pairs.iter().map(|&(f, g)| if area(f) <= area(g) { f } else { g }).collect();
        let both: Vec<u32> = pairs.iter().flat_map(|&(f, g)| [f, g]).collect();
        for doomed in [smaller, both] {
            let mut keep = vec![true; st.triangles.len()];
            for f in doomed {
                keep[f as usize] = false;
            }
            let kept: Vec<[u32; 3]> = st.triangles.iter().zip(&keep).filter(|(_, k)| **k).map(|(t, _)| *t).collect();
            // Guard: deleting faces can pinch a vertex into a bow tie, or delete everything.
            if kept.is_empty() || SurfaceMesh::from_triangles(&st.positions, &kept).is_err() {
                continue;
            }
            record.faces_removed = st.triangles.len() - kept.len();
            drop_faces(st, &keep);
            record.pairs_left = triangle_self_intersections(&st.positions, &st.triangles)?.len();
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

pub(super) fn surface_area(p: &[Vec3], t: &[[u32; 3]]) -> f64 {
    t.iter()
        .map(|f| {
            let (a, b, c) = (p[f[0] as usize], p[f[1] as usize], p[f[2] as usize]);
            0.5 * f64::from((b - a).cross(c - a).length())
        })
        .sum()
}

/// Appends new vertices (numbered from the current count on) and faces; old vertices keep their Adam
/// moments, the new ones start at zero.
pub(super) fn append(st: &mut State, positions: &[Vec3], triangles: &[[u32; 3]]) {
    let source: Vec<Option<u32>> =
        (0..st.positions.len() as u32).map(Some).chain(positions.iter().map(|_| None)).collect();
    st.shape_adam = st.shape_adam.select(&source);
    st.positions.extend(positions);
    st.triangles.extend(triangles);
}

pub(super) fn mesh_of(st: &State) -> Result<SurfaceMesh> {
    Ok(SurfaceMesh::from_triangles(&st.positions, &st.triangles)?)
}

/// One shape step: moves the mesh by `displacement` so that the surface does not pass through itself, on the
/// way or at the end (`nlos_mesh::evolve`, after El Topo, Brochu & Bridson 2009: continuous collision
/// detection, proximity impulses, impact zones, fail-safe, then the exact static check of the end state),
/// improvement off (the Adam state needs fixed connectivity). The mesh was checked at the block's start, so
/// the input is not checked again. A vertex no collision touches ends at exactly `x₀ + d`. The step is
/// tallied in `record`.
pub(super) fn collision_step(
    st: &State,
    displacement: &[Vec3],
    target: f32,
    ep: EvolveParams,
    record: &mut EvolveRecord,
) -> Result<Vec<Vec3>> {
    let t0 = Instant::now();
    let mut mesh = SurfaceMesh::from_triangles(&st.positions, &st.triangles)?;
    let ep = EvolveParams { improve: false, check_input: false, edge_length: ep.edge_length.or(Some(target)), ..ep };
    let report = evolve(&mut mesh, displacement, &ep)?;
    let pos = mesh.positions();
    if pos.len() != st.positions.len() || pos.iter().any(|p| !p.is_finite()) {
        return Err(OptimError::EvolveOutput { expected: st.positions.len(), got: pos.len() });
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
