//! Collision-aware evolution: one `evolve` call with improvement, and one without, on a
//! 51 200-face open height field (160 × 160 grid, the optimiser's kind of mesh: open, with a boundary) with
//! random displacements of up to 0.1·L per axis (L the mean edge length).
//!
//! Before the timed runs it prints the time per part from [`EvolveReport::timings`] (broad phase, narrow
//! phase, exact static checks, improvement) as shares of the call, for one call of each kind.
//! Target on the 2-core development machine: the call with improvement well under 3 s.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use glam::Vec3;
use nlos_mesh::evolve::{EvolveParams, EvolveReport, evolve};
use nlos_mesh::{SurfaceMesh, shapes};

fn input() -> (SurfaceMesh, Vec<Vec3>, f32) {
    let m = shapes::height_field(1.0, 1.0, 160, 160, |x, y| 0.05 * (6.0 * x).sin() * (5.0 * y).cos())
        .expect("height field");
    let l = m.mean_edge_length();
    // Deterministic displacements (the workspace's SplitMix64, the same draws as before).
    let mut rng = nlos_transient::rng::SplitMix64::new(0x2545_F491_4F6C_DD1D);
    let mut next = || rng.next_f32() * 2.0 - 1.0;
    let d = (0..m.vertices_size()).map(|_| Vec3::new(next(), next(), next()) * (0.1 * l)).collect();
    (m, d, l)
}

fn shares(what: &str, faces: usize, r: &EvolveReport) {
    let t = r.timings;
    let pct = |x: Duration| 100.0 * x.as_secs_f64() / t.total.as_secs_f64().max(1e-12);
    eprintln!(
        "{what} on {faces} faces: {:.3} s; broad phase {:.1} %, narrow phase {:.1} %, static checks {:.1} %, \
         improvement {:.1} % (splits {}, collapses {}, flips {}, smoothed {}); motion fraction {:.6}",
        t.total.as_secs_f64(),
        pct(t.broad_phase),
        pct(t.narrow_phase),
        pct(t.static_check),
        pct(t.improvement),
        r.improvement.splits,
        r.improvement.collapses,
        r.improvement.flips,
        r.improvement.smoothed,
        r.motion_fraction,
    );
}

fn bench_evolve(c: &mut Criterion) {
    let (mesh, d, l) = input();
    let with = EvolveParams::with_edge_length(l);
    let without = EvolveParams { improve: false, ..with };
    for (name, params) in [("evolve + improve", &with), ("evolve only", &without)] {
        let mut m = mesh.clone();
        let r = evolve(&mut m, &d, params).expect("evolves");
        shares(name, mesh.n_faces(), &r);
    }
    let mut g = c.benchmark_group("evolve");
    g.sample_size(10);
    for (name, params) in [("height_field_51k_improve", with), ("height_field_51k_motion_only", without)] {
        g.bench_function(name, |b| {
            b.iter_batched(
                || mesh.clone(),
                |mut m| {
                    let r = evolve(&mut m, black_box(&d), &params).expect("evolves");
                    (m, r)
                },
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench_evolve);
criterion_main!(benches);
