//! The surface never intersects itself (El Topo's promise, per operation): two sheets driven into each other
//! step after step are stopped where they meet, and no check of the run after the start finds a pair.
#![allow(clippy::unwrap_used)]

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::intersect::triangle_self_intersections;
use nlos_mesh::{SurfaceMesh, shapes};
use nlos_optim::{
    Evolve, Hooks, IntersectionCheck, OptimError, Outcome, ReconstructParams, RenderSettings, Schedule,
    reconstruct_with,
};
use nlos_render::{RenderParams, Renderer, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// A square of side `side` centred on the z axis at depth `z`, facing the wall, `n` × `n` vertices.
fn sheet(side: f32, n: usize, z: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let m = shapes::height_field(side, side, n, n, |_, _| z).unwrap();
    let (mut p, t) = m.to_triangles();
    for q in &mut p {
        q.x -= 0.5 * side;
        q.y -= 0.5 * side;
    }
    (p, t.iter().map(|f| [f[0], f[2], f[1]]).collect())
}

/// The front sheet, 0.2 m wide at 0.40 m, and a smaller one 3 cm behind it (its rim cannot slip past the
/// front one's), one mesh of two components.
fn two_sheets() -> SurfaceMesh {
    let (mut p, mut t) = sheet(0.2, 6, 0.40);
    let (q, u) = sheet(0.1, 4, 0.43);
    let k = p.len() as u32;
    p.extend(q);
    t.extend(u.iter().map(|f| f.map(|v| v + k)));
    SurfaceMesh::from_triangles(&p, &t).unwrap()
}

/// The front sheet's light, as the measurement.
fn measurement() -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.25, 0.25).unwrap());
    let time = TimeAxis::new(0.6, 0.0024, 300).unwrap();
    let (p, t) = sheet(0.2, 10, 0.40);
    let params = RenderParams { visibility: Visibility::Off, ..RenderParams::default() };
    let r = Renderer::new(&p, &t, &scan, &time, params).unwrap();
    Transient::new(scan, time, r.forward(&Lambertian::new(1.0f32).unwrap())).unwrap()
}

/// Drives every vertex behind 0.405 m 2 cm toward the wall per step, whatever the gradient says: the
/// second sheet reaches the first at the second step and would pass through it.
struct PushThrough;

impl Evolve for PushThrough {
    fn evolve(&mut self, p: &[Vec3], _t: &[[u32; 3]], d: &[Vec3]) -> nlos_optim::Result<Vec<Vec3>> {
        Ok(p.iter().zip(d).map(|(a, b)| if a.z > 0.405 { *a - Vec3::new(0.0, 0.0, 0.02) } else { *a + *b }).collect())
    }
}

fn params() -> ReconstructParams {
    ReconstructParams {
        schedule: Schedule {
            initial_resolution: 16.0,
            max_stages: 2,
            max_blocks_per_stage: 2,
            shape_iterations: 4,
            reflectance_iterations: 0,
            rel_tol: 0.0,
            ..Schedule::default()
        },
        seed: 7,
        render: RenderSettings { visibility: Visibility::Off, ..RenderSettings::default() },
        prune: None,
        residual: None,
        ..ReconstructParams::default()
    }
}

fn pairs_after_start(out: &Outcome) -> usize {
    out.log.intersections.iter().filter(|r| r.check != IntersectionCheck::Start).map(|r| r.pairs).sum()
}

#[test]
fn two_sheets_driven_into_each_other_stop_where_they_meet() {
    let measured = measurement();
    let init = two_sheets();
    let (p, t) = init.to_triangles();
    assert!(triangle_self_intersections(&p, &t).unwrap().is_empty(), "the start is clean");
    let mut push = PushThrough;
    let out = reconstruct_with(&measured, &init, &params(), Hooks { progress: None, evolve: Some(&mut push) }).unwrap();
    assert_eq!(pairs_after_start(&out), 0, "checks after the start: {:?}", out.log.intersections);
    let (p, t) = out.mesh.to_triangles();
    assert!(triangle_self_intersections(&p, &t).unwrap().is_empty(), "the result is clean");
    // The steps that would have crossed were limited, and the run log says so per block.
    assert_eq!(out.log.collisions.len() as u64, out.blocks_done);
    let limited: u32 = out.log.collisions.iter().map(|r| r.steps_limited).sum();
    assert!(limited > 0, "{:?}", out.log.collisions);
    assert!(out.log.collisions.iter().all(|r| r.steps == 4 && !r.input_intersected), "{:?}", out.log.collisions);
    // The second sheet is still behind the first: nothing in front of the first sheet's depth there.
    let centre: Vec<&Vec3> = p.iter().filter(|q| q.x.abs() < 0.04 && q.y.abs() < 0.04).collect();
    assert!(centre.iter().all(|q| q.z > 0.39), "a vertex went through: {centre:?}");
}

#[test]
fn without_collision_handling_the_same_push_goes_through() {
    let measured = measurement();
    let init = two_sheets();
    let mut push = PushThrough;
    let params = ReconstructParams { collision: None, ..params() };
    match reconstruct_with(&measured, &init, &params, Hooks { progress: None, evolve: Some(&mut push) }) {
        // NLOS_REQUIRE_NO_INTERSECTIONS=1 (CI): the first check that finds pairs stops the run.
        Err(OptimError::SelfIntersecting { pairs, .. }) => assert!(pairs > 0),
        Ok(out) => assert!(pairs_after_start(&out) > 0, "{:?}", out.log.intersections),
        Err(e) => panic!("{e}"),
    }
}
