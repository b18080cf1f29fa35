//! Simulate → initialise → reconstruct → evaluate, across the crates, on the built-in scene: the committed
//! fixtures (`fixtures/builtin/`: ground truth, photon-count capture, LCT start), so a fresh clone runs the
//! real pipeline without the shared data.

mod common;
use common::{fixture, scratch};

use nlos_mesh::metrics::{EvalParams, evaluate};
use nlos_optim::builtin::{BuiltinScene, FIXTURE_FILES};
use nlos_optim::pipeline::{Config, Prepared};

/// The schedule of `cargo xtask reconstruct`: two coarse-to-fine stages, two blocks each.
fn demo_config() -> Config {
    let mut config = Config::default();
    config.schedule.max_stages = 2;
    config.schedule.initial_resolution = 20.0;
    config.schedule.max_blocks_per_stage = 2;
    config.schedule.shape_iterations = 15;
    config.seed = 1;
    config
}

#[test]
fn the_fixtures_are_current() {
    // `cargo xtask fixtures` writes them from the same function; every step is seeded and deterministic.
    let dir = scratch("pipeline-fixtures");
    BuiltinScene::default().write_fixtures(&dir).expect("fixtures written");
    let stale = |name: &str| format!("fixtures/builtin/{name} is stale: run `cargo xtask fixtures` and commit it");
    for name in FIXTURE_FILES {
        let (fresh, committed) = (std::fs::read(dir.join(name)).expect("fresh"), std::fs::read(fixture(name)));
        let committed = committed.expect("fixtures/builtin is committed");
        if name == "start.obj" {
            // The LCT's FFTs pick their kernels by CPU features at run time, so the start may differ in the
            // last bits between machines: same faces, positions within a micrometre.
            let (a, b) = (nlos_mesh::io::load(dir.join(name)).expect("fresh"), nlos_mesh::io::load(fixture(name)));
            let (a, b) = (a.to_triangles(), b.expect("committed").to_triangles());
            assert!(a.1 == b.1, "{}", stale(name));
            let far = a.0.iter().zip(&b.0).map(|(p, q)| (*p - *q).abs().max_element()).fold(0.0f32, f32::max);
            assert!(a.0.len() == b.0.len() && far < 1e-6, "{} ({far} m apart)", stale(name));
        } else {
            assert!(fresh == committed, "{}", stale(name));
        }
    }
}

#[test]
fn the_builtin_capture_reconstructs_closer_to_the_truth_than_its_start() {
    let config = demo_config();
    let prepared = Prepared::load(&fixture("capture.hdf5"), &config).expect("the fixture capture loads");
    let start = prepared.initial_surface(&config).expect("LCT start");
    let committed = nlos_mesh::io::load(fixture("start.obj")).expect("the fixture start loads");
    assert_eq!(start.n_faces(), committed.n_faces(), "the pipeline's start is the committed one");
    let dir = scratch("pipeline-run");
    let params = prepared.params(&config, Some(dir.clone())).expect("params");
    let outcome = nlos_optim::reconstruct(&prepared.measured, &start, &params).expect("reconstructs");
    assert!(dir.join("mesh.obj").is_file() && dir.join("run_log.json").is_file());

    let truth = nlos_mesh::io::load(fixture("truth.obj")).expect("truth");
    let eval = EvalParams::default();
    let before = evaluate(&start, &truth, &eval).expect("metrics of the start");
    let after = evaluate(&outcome.mesh, &truth, &eval).expect("metrics of the result");
    let mean = |m: &nlos_mesh::metrics::Metrics| m.depth_error_mean.expect("pixels hit on both");
    eprintln!(
        "start: coverage {:.3}, mean depth error {:.2} mm, Chamfer {:.1} mm; result: {:.3}, {:.2} mm, {:.1} mm",
        before.coverage,
        mean(&before) * 1e3,
        before.chamfer * 1e3,
        after.coverage,
        mean(&after) * 1e3,
        after.chamfer * 1e3
    );
    // The demo's figures: 0.70 → 0.13 mm mean depth error, Chamfer 9.0 → 1.3 mm; coverage 100 → 98 %.
    assert!(mean(&after) < 0.5 * mean(&before), "depth error did not halve");
    assert!(after.chamfer < 0.5 * before.chamfer, "Chamfer did not halve");
    assert!(after.coverage > 0.9, "coverage {}", after.coverage);
}
