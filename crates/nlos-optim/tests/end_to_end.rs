//! End-to-end: a synthetic scene rendered by nlos-render is the measurement; the optimiser starts from a
//! flat plane and must bring the surface to the truth. Also: resume after an interruption is
//! bit-identical, and a non-finite step is rolled back.
#![allow(clippy::unwrap_used)]

use std::ops::ControlFlow;
use std::path::PathBuf;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::{SurfaceMesh, shapes};
use nlos_optim::{
    Evolve, Hooks, OptimError, Progress, ProgressEvent, ReconstructParams, RenderSettings, SamplingSchedule, Schedule,
    SensorBackground, SensorFit, StopReason, reconstruct_with, resume,
};
use nlos_render::{DeterministicRule, RenderParams, Renderer, Visibility};
use nlos_transient::sensor::BinKernel;
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// Truth: a 0.2 m square at ≈ 0.4 m with a 3 cm Gaussian bump toward the wall and a tilt.
fn truth_z(x: f32, y: f32) -> f32 {
    0.40 - 0.03 * (-(x * x + y * y) / (2.0 * 0.04 * 0.04)).exp() + 0.05 * x
}

/// A height field over [−0.1, 0.1]² facing the wall (triangles reversed so the normals point to −z).
fn facing_wall(n: usize, z: impl Fn(f32, f32) -> f32) -> SurfaceMesh {
    let m = shapes::height_field(0.2, 0.2, n, n, |x, y| z(x - 0.1, y - 0.1)).unwrap();
    let (mut p, t) = m.to_triangles();
    for q in &mut p {
        q.x -= 0.1;
        q.y -= 0.1;
    }
    let t: Vec<[u32; 3]> = t.iter().map(|f| [f[0], f[2], f[1]]).collect();
    SurfaceMesh::from_triangles(&p, &t).unwrap()
}

fn measurement(scan_n: usize) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(scan_n, scan_n, 0.25, 0.25).unwrap());
    let time = TimeAxis::new(0.6, 0.0024, 300).unwrap();
    let truth = facing_wall(40, truth_z);
    let (p, t) = truth.to_triangles();
    let r = Renderer::new(&p, &t, &scan, &time, fast_render()).unwrap();
    let mut data = r.forward(&Lambertian::new(1.0f32).unwrap());
    // An arbitrary radiometric scale: the optimiser must solve it.
    for x in &mut data {
        *x *= 1234.5;
    }
    Transient::new(scan, time, data).unwrap()
}

/// Möller–Trumbore along +z from (x, y, 0): the z of the first hit.
fn ray_z(p: &[Vec3], t: &[[u32; 3]], x: f32, y: f32) -> Option<f32> {
    let (o, d) = (Vec3::new(x, y, 0.0), Vec3::Z);
    let mut best: Option<f32> = None;
    for f in t {
        let (a, b, c) = (p[f[0] as usize], p[f[1] as usize], p[f[2] as usize]);
        let (e1, e2) = (b - a, c - a);
        let q = d.cross(e2);
        let det = e1.dot(q);
        if det.abs() < 1e-12 {
            continue;
        }
        let s = o - a;
        let u = s.dot(q) / det;
        let r = s.cross(e1);
        let v = d.dot(r) / det;
        let tt = e2.dot(r) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt > 0.0 && best.is_none_or(|z| tt < z) {
            best = Some(tt);
        }
    }
    best
}

/// (mean |z_rec − z_gt| over a 24×24 grid on [−0.08, 0.08]², coverage).
fn depth_error(mesh: &SurfaceMesh) -> (f64, f64) {
    let (p, t) = mesh.to_triangles();
    let (mut sum, mut hits, mut n) = (0.0f64, 0usize, 0usize);
    for j in 0..24 {
        for i in 0..24 {
            let (x, y) = (-0.08 + 0.16 * (i as f32 + 0.5) / 24.0, -0.08 + 0.16 * (j as f32 + 0.5) / 24.0);
            n += 1;
            if let Some(z) = ray_z(&p, &t, x, y) {
                sum += f64::from((z - truth_z(x, y)).abs());
                hits += 1;
            }
        }
    }
    (sum / hits.max(1) as f64, hits as f64 / n as f64)
}

/// The scene is a height field seen from below: no occlusion, so visibility rays can be skipped.
fn fast_render() -> RenderParams {
    RenderParams { visibility: Visibility::Off, ..RenderParams::default() }
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("nlos-optim-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn flat_start_converges_to_the_bumpy_truth() {
    let t0 = std::time::Instant::now();
    let measured = measurement(16);
    let init = facing_wall(10, |_, _| 0.40);
    let (e0, c0) = depth_error(&init);
    let dir = out_dir("e2e");
    let params = ReconstructParams {
        schedule: Schedule {
            initial_resolution: 24.0,
            max_stages: 2,
            max_blocks_per_stage: 2,
            shape_iterations: 15,
            reflectance_iterations: 0,
            ..Schedule::default()
        },
        lr_interior: 0.1,
        lr_boundary: 0.05,
        render: RenderSettings { visibility: Visibility::Off, ..RenderSettings::default() },
        sampling: SamplingSchedule::Deterministic(DeterministicRule {
            max_bin_fraction: 1.5,
            min_level: 1,
            max_level: 8,
        }),
        out_dir: Some(dir.clone()),
        ..ReconstructParams::default()
    };
    let out = reconstruct_with(&measured, &init, &params, Hooks::default()).unwrap();
    let (e1, c1) = depth_error(&out.mesh);
    let log = &out.log.iterations;
    let (l0, l1) = (log[0].data, log.last().unwrap().data);
    println!(
        "depth error {:.2} mm -> {:.2} mm (coverage {:.0}% -> {:.0}%), data term {l0:.4} -> {l1:.5}, scale {:.1} \
         (true 1234.5), {} iterations, {} faces, {:.1} s",
        e0 * 1e3,
        e1 * 1e3,
        c0 * 100.0,
        c1 * 100.0,
        out.scale,
        log.len(),
        out.mesh.n_faces(),
        t0.elapsed().as_secs_f64()
    );
    assert!(e1 < 0.2 * e0, "depth error {e0} -> {e1}");
    assert!(c1 > 0.95);
    // Collision-aware evolution ran once per block; a height field moving along z never collides.
    assert_eq!(out.evolve.len() as u64, out.blocks_done);
    assert!(out.evolve.iter().all(|r| !r.input_intersected && r.motion_fraction > 0.99), "{:?}", out.evolve);
    assert!(l1 < 0.2 * l0);
    // The fit-quality record: L2 on an exact rendering, so an empty scene (the best constant level) leaves
    // most of the data term (1 without it, by the normaliser's definition), the final surface almost none.
    let fit = out.log.fit.expect("a finished run records its fit");
    assert!(fit.empty < 1.0 && fit.empty > 0.5 && fit.noise_floor.is_none(), "{fit:?}");
    assert!(fit.data < 0.2 * l0 && fit.explained().is_some_and(|e| e > 0.9), "{fit:?}");
    assert!(fit.describe().starts_with("explains 100 % of the light ("), "{}", fit.describe());
    // Each stage records what its last surface explains; the last stage's is the run's.
    assert!(out.log.stages.len() == 2 && out.log.stages.iter().all(|r| r.fit.is_some()), "{:?}", out.log.stages);
    assert_eq!(out.log.stages.last().and_then(|r| r.fit), Some(fit));
    let written: nlos_optim::RunLog =
        serde_json::from_slice(&std::fs::read(dir.join("run_log.json")).unwrap()).expect("run log");
    assert_eq!(written.fit, Some(fit), "run_log.json holds the record");
    assert!(dir.join("mesh.obj").exists() && dir.join("run_log.json").exists());
    assert!(dir.join("checkpoint.json").exists() && dir.join("stage_00.obj").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

fn small_params(dir: PathBuf) -> ReconstructParams {
    ReconstructParams {
        schedule: Schedule {
            initial_resolution: 16.0,
            max_stages: 2,
            max_blocks_per_stage: 2,
            shape_iterations: 4,
            reflectance_iterations: 2,
            rel_tol: 0.0,
            ..Schedule::default()
        },
        reflectance: nlos_optim::Reflectance::from_brdf(nlos_brdf::AnyBrdf::Ggx(
            nlos_brdf::Ggx::new(0.5f32, 0.5, 0.3, nlos_brdf::Fresnel::One).unwrap(),
        )),
        lr_interior: 0.1,
        seed: 42,
        render: RenderSettings { visibility: Visibility::Off, ..RenderSettings::default() },
        sampling: SamplingSchedule::Deterministic(DeterministicRule {
            max_bin_fraction: 2.0,
            min_level: 1,
            max_level: 4,
        }),
        out_dir: Some(dir),
        ..ReconstructParams::default()
    }
}

#[test]
fn resume_after_interruption_is_bit_identical() {
    check_resume(Some(nlos_optim::AlbedoParams::default()));
}

/// Without the per-vertex albedo (one albedo for the surface) a resumed run is bit-identical too.
#[test]
fn resume_with_one_albedo_is_bit_identical() {
    check_resume(None);
}

fn check_resume(albedo: Option<nlos_optim::AlbedoParams>) {
    let tag = if albedo.is_none() { "-one-albedo" } else { "" };
    let small_params = |dir: PathBuf| ReconstructParams {
        albedo,
        regions: albedo.and(Some(nlos_optim::RegionParams::default())),
        ..small_params(dir)
    };
    // One rayon thread, as a user might run it (the result does not depend on the thread count).
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| {
        let measured = measurement(8);
        let init = facing_wall(6, |_, _| 0.42);
        let full = reconstruct_with(&measured, &init, &small_params(out_dir(&format!("full{tag}"))), Hooks::default())
            .unwrap();
        assert_eq!(full.stop, StopReason::MaxStages);
        assert!(full.blocks_done >= 2, "{} blocks", full.blocks_done);

        let dir = out_dir(&format!("resume{tag}"));
        let params = small_params(dir.clone());
        let mut stop_after_2 = |p: &Progress| {
            if p.event == ProgressEvent::BlockEnd && p.blocks_done == 1 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        };
        let hooks = Hooks { progress: Some(&mut stop_after_2), evolve: None };
        let part = reconstruct_with(&measured, &init, &params, hooks).unwrap();
        assert_eq!(part.stop, StopReason::Interrupted);
        assert_eq!(part.blocks_done, 1);
        let resumed = resume(&measured, &params, Hooks::default()).unwrap();
        assert_eq!(resumed.blocks_done, full.blocks_done);

        let (pa, ta) = full.mesh.to_triangles();
        let (pb, tb) = resumed.mesh.to_triangles();
        assert_eq!(ta, tb);
        assert!(pa.iter().zip(&pb).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
        assert_eq!(full.reflectance, resumed.reflectance);
        assert_eq!(full.albedo, resumed.albedo);
        assert_eq!(full.albedo.is_some(), albedo.is_some());
        assert_eq!(full.scale.to_bits(), resumed.scale.to_bits());
        let strip = |l: &nlos_optim::RunLog| {
            l.iterations.iter().map(|r| nlos_optim::IterationRecord { time_s: 0.0, ..r.clone() }).collect::<Vec<_>>()
        };
        assert_eq!(strip(&full.log), strip(&resumed.log));
        // A foreign measurement is refused.
        let other = measurement(6);
        assert!(matches!(resume(&other, &params, Hooks::default()), Err(OptimError::Checkpoint { .. })));
        // So are other settings (here: no pruning), which would continue a different run.
        let changed = ReconstructParams { prune: None, ..params.clone() };
        match resume(&measured, &changed, Hooks::default()) {
            Err(OptimError::SettingsChanged { path, field, now, .. }) => {
                assert!(path.ends_with("checkpoint.json"), "{path:?}");
                assert_eq!((field.as_str(), now.as_str()), ("prune", "null"));
            }
            other => panic!("resumed with other settings: {other:?}"),
        }
        let _ = std::fs::remove_dir_all(&dir);
    });
}

/// Returns NaN positions on its third call, otherwise applies the displacement.
#[derive(Debug, Default)]
struct FaultyEvolve {
    calls: usize,
}

impl Evolve for FaultyEvolve {
    fn evolve(&mut self, p: &[Vec3], _t: &[[u32; 3]], d: &[Vec3]) -> nlos_optim::Result<Vec<Vec3>> {
        self.calls += 1;
        Ok(p.iter().zip(d).map(|(a, b)| if self.calls == 3 { Vec3::NAN } else { *a + *b }).collect())
    }
}

#[test]
fn non_finite_step_is_rolled_back_with_a_halved_step() {
    let measured = measurement(8);
    let init = facing_wall(6, |_, _| 0.42);
    let mut params = small_params(out_dir("rollback"));
    params.out_dir = None;
    let mut evolve = FaultyEvolve::default();
    let out = reconstruct_with(&measured, &init, &params, Hooks { progress: None, evolve: Some(&mut evolve) }).unwrap();
    assert_eq!(out.log.rollbacks, 1);
    let steps: Vec<f64> = out.log.iterations.iter().map(|r| r.step_size).collect();
    // Records 0–2 at full size (record 2 is the attempt whose positions came back NaN), then the same
    // iteration again from the restored state with half the step.
    assert_eq!(out.log.iterations[2].iteration, out.log.iterations[3].iteration);
    assert!((steps[2] - steps[0]).abs() < 1e-12 * steps[0], "{steps:?}");
    assert!((steps[3] - 0.5 * steps[0]).abs() < 1e-12 * steps[0], "{steps:?}");
    assert!(out.mesh.positions().iter().all(|p| p.is_finite()));
}

/// Records every displacement the optimiser asks for (with the triangles it applies to), then applies it.
#[derive(Debug, Default)]
struct RecordingEvolve {
    steps: Vec<(Vec<[u32; 3]>, Vec<Vec3>)>,
}

impl Evolve for RecordingEvolve {
    fn evolve(&mut self, p: &[Vec3], t: &[[u32; 3]], d: &[Vec3]) -> nlos_optim::Result<Vec<Vec3>> {
        self.steps.push((t.to_vec(), d.to_vec()));
        Ok(p.iter().zip(d).map(|(a, b)| *a + *b).collect())
    }
}

/// Vertices on an edge used by one triangle only.
fn boundary_vertices(n: usize, t: &[[u32; 3]]) -> Vec<bool> {
    let mut count = std::collections::HashMap::new();
    for f in t {
        for k in 0..3 {
            let (a, b) = (f[k].min(f[(k + 1) % 3]), f[k].max(f[(k + 1) % 3]));
            *count.entry((a, b)).or_insert(0) += 1;
        }
    }
    let mut on = vec![false; n];
    for ((a, b), c) in count {
        if c == 1 {
            on[a as usize] = true;
            on[b as usize] = true;
        }
    }
    on
}

/// The boundary moves freely: a start offset sideways from the truth is pulled sideways at its rim as well as
/// in depth.
#[test]
fn the_boundary_moves_sideways_as_well_as_in_depth() {
    let measured = measurement(8);
    let mut init = facing_wall(6, |_, _| 0.42);
    for p in init.positions_mut() {
        p.x += 0.03;
    }
    let mut params = small_params(out_dir("boundary"));
    params.out_dir = None;
    params.schedule.max_stages = 1;
    params.schedule.max_blocks_per_stage = 1;
    let mut evolve = RecordingEvolve::default();
    reconstruct_with(&measured, &init, &params, Hooks { progress: None, evolve: Some(&mut evolve) }).unwrap();
    assert!(!evolve.steps.is_empty());
    let (mut lateral, mut depth) = (0.0f32, 0.0f32);
    for (t, d) in &evolve.steps {
        for (dv, _) in d.iter().zip(boundary_vertices(d.len(), t)).filter(|(_, b)| *b) {
            lateral = lateral.max(dv.x.abs().max(dv.y.abs()));
            depth = depth.max(dv.z.abs());
        }
    }
    assert!(depth > 0.0 && lateral > 0.0, "boundary motion: lateral {lateral}, depth {depth}");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mut measured = measurement(4);
    let init = facing_wall(4, |_, _| 0.42);
    let params = ReconstructParams::default();
    measured.data_mut()[3] = f32::NAN;
    assert!(matches!(
        reconstruct_with(&measured, &init, &params, Hooks::default()),
        Err(OptimError::NonFiniteMeasurement { index: 3, .. })
    ));
    measured.data_mut().fill(0.0);
    assert!(matches!(
        reconstruct_with(&measured, &init, &params, Hooks::default()),
        Err(OptimError::InvalidParameter { .. })
    ));
    let bad = ReconstructParams { lr_interior: f64::NAN, ..ReconstructParams::default() };
    assert!(matches!(
        reconstruct_with(&measured, &init, &bad, Hooks::default()),
        Err(OptimError::InvalidParameter { name: "lr_interior", .. })
    ));
    assert!(resume(&measured, &params, Hooks::default()).is_err());
}

/// The noise-aware fit end to end: the measurement is expected counts `s·J(I) + b` (a 5-bin jitter kernel,
/// background estimated from the pre-return bins); the sensor fit must recover the shape and the scale.
#[test]
fn sensor_fit_recovers_shape_from_jittered_counts_with_background() {
    let clean = measurement(10);
    let bins = clean.bins();
    let kernel = BinKernel::new(-1, vec![0.15, 0.4, 0.25, 0.12, 0.08]).unwrap();
    let jittered = kernel.apply(clean.data(), bins).unwrap();
    // Counts of ~100 per bin at the peak over a background of 0.5 per bin.
    let peak = jittered.iter().copied().fold(0.0f32, f32::max);
    let gain = 100.0 / peak;
    let counts: Vec<f32> = jittered.iter().map(|v| gain * v + 0.5).collect();
    let measured = Transient::new(clean.scan().clone(), *clean.time(), counts).unwrap();
    let init = facing_wall(10, |_, _| 0.40);
    let (e0, _) = depth_error(&init);
    let mut params = small_params(out_dir("sensor"));
    params.out_dir = None;
    params.reflectance = nlos_optim::Reflectance::default();
    params.schedule.shape_iterations = 12;
    params.sensor = Some(SensorFit {
        kernel,
        background: SensorBackground::Estimate(nlos_transient::sensor::BackgroundWindow::BeforeFirstReturn),
    });
    let out = reconstruct_with(&measured, &init, &params, Hooks::default()).unwrap();
    let (e1, c1) = depth_error(&out.mesh);
    let log = &out.log.iterations;
    println!(
        "sensor fit: depth error {:.2} -> {:.2} mm, coverage {c1:.2}, data {:.4} -> {:.4}",
        e0 * 1e3,
        e1 * 1e3,
        log[0].data,
        log.last().unwrap().data
    );
    assert!(e1 < 0.5 * e0, "depth error {e0} -> {e1}");
    assert!(log.last().unwrap().data < 0.5 * log[0].data);
    // Shape steps log the noise floor the regulariser weight is set against; reflectance steps do not.
    for r in log {
        match (r.kind, r.noise_floor) {
            (nlos_optim::StepKind::Shape, Some(f)) => assert!(f > 0.0 && f.is_finite(), "{r:?}"),
            (nlos_optim::StepKind::Reflectance, None) => {}
            _ => panic!("noise floor logged wrongly: {r:?}"),
        }
    }
    assert!(log[0].noise_floor.is_some_and(|f| f < log[0].data), "the misfit of the flat start is above the floor");
    // The fit-quality record under a sensor fit: an empty scene is the background alone, worse than the fit.
    let fit = out.log.fit.expect("a finished run records its fit");
    assert!(fit.noise_floor.is_some() && fit.data < fit.empty, "{fit:?}");
    assert!(fit.explained().is_some_and(|e| e > 0.5), "{fit:?}: {}", fit.describe());
    // Weights are refused with the sensor fit.
    params.data.weights = Some(vec![1.0; measured.data().len()]);
    assert!(matches!(
        reconstruct_with(&measured, &init, &params, Hooks::default()),
        Err(OptimError::InvalidParameter { name: "data.weights", .. })
    ));
}

/// Regression (sensor scenario, 100 photons per histogram): the automatic smoothing weight was set against
/// the whole data term, ~95 % of which is Poisson noise no surface can remove, and over-smoothed the fit
/// (started from the true bunny, the data term rose while the regulariser fell). With counts, λ at a
/// block's first step is `β·(E − E_floor)/R`: the same first evaluation with and without `counts` gives
/// weights in the ratio `(E − E_floor)/E`, and the floor is most of `E` at a low photon budget.
#[test]
fn smoothing_weight_of_photon_counts_discounts_the_noise_floor() {
    use nlos_transient::sensor::{PhotonBudget, SpadModel};
    let clean = measurement(10);
    let counts = SpadModel::ideal(PhotonBudget::PerMeasurement(30.0)).simulate(&clean, 7).unwrap();
    let init = facing_wall(10, |x, y| truth_z(x, y) + 0.002);
    let first = |counts_flag: bool| {
        let mut p = small_params(out_dir("counts"));
        p.out_dir = None;
        p.reflectance = nlos_optim::Reflectance::default();
        p.schedule.max_stages = 1;
        p.schedule.max_blocks_per_stage = 1;
        p.schedule.shape_iterations = 1;
        p.data.counts = counts_flag;
        let out = reconstruct_with(&counts, &init, &p, Hooks::default()).unwrap();
        out.log.iterations[0].clone()
    };
    let (with, without) = (first(true), first(false));
    assert_eq!(with.data, without.data, "same first evaluation");
    assert!(without.noise_floor.is_none());
    let floor = with.noise_floor.expect("floor logged");
    println!("data {:.4}, noise floor {floor:.4}, λ {:.4e} vs {:.4e}", with.data, with.reg_weight, without.reg_weight);
    assert!(floor > 0.5 * with.data && floor < with.data, "a near-true start at 30 photons: E mostly noise");
    let want = (with.data - floor) / with.data;
    let got = with.reg_weight / without.reg_weight;
    assert!((got - want).abs() < 1e-9 * want.max(1.0), "λ ratio {got} vs (E − E_floor)/E = {want}");
}

/// A start that intersects itself (a plate crossing the surface) is repaired before the loop, and the
/// surface is free of self-intersections after every remeshing and at the end of every block (run log).
#[test]
fn a_start_that_collides_is_repaired_and_every_block_ends_intersection_free() {
    let measured = measurement(8);
    let (mut p, mut t) = facing_wall(6, |_, _| 0.42).to_triangles();
    let (q, u) = facing_wall(3, |x, _| 0.42 + 0.4 * x).to_triangles();
    let offset = p.len() as u32;
    p.extend(q.iter().map(|v| Vec3::new(0.5 * v.x, 0.5 * v.y, v.z)));
    t.extend(u.iter().map(|f| f.map(|i| i + offset)));
    let crossing = nlos_mesh::intersect::triangle_self_intersections(&p, &t).unwrap();
    assert!(!crossing.is_empty(), "the start must collide");
    let init = SurfaceMesh::from_triangles(&p, &t).unwrap();
    let mut params = small_params(out_dir("collide"));
    params.out_dir = None;
    let out = reconstruct_with(&measured, &init, &params, Hooks::default()).unwrap();
    let log = &out.log.intersections;
    let start = log.first().expect("a start check");
    assert_eq!(start.check, nlos_optim::IntersectionCheck::Start);
    assert_eq!(start.pairs, crossing.len());
    assert!(start.faces_removed > 0);
    let blocks = log.iter().filter(|r| r.check == nlos_optim::IntersectionCheck::BlockEnd).count();
    assert_eq!(blocks as u64, out.blocks_done);
    assert!(log.iter().all(|r| r.pairs_left == 0), "{log:?}");
    let (p, t) = out.mesh.to_triangles();
    assert!(nlos_mesh::intersect::triangle_self_intersections(&p, &t).unwrap().is_empty());
}

/// A run does not depend on the thread count: the same reconstruction in pools of 1 and 3 threads gives
/// the same mesh, reflectance, scale and log, bit for bit, with the loop's default renderer rule (splat) and
/// with a point rule.
#[test]
fn a_run_does_not_depend_on_the_thread_count() {
    let measured = measurement(8);
    let init = facing_wall(6, |_, _| 0.42);
    for (name, sampling) in [("splat", SamplingSchedule::default()), ("point", small_params(PathBuf::new()).sampling)] {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let params =
                ReconstructParams { sampling, out_dir: None, ..small_params(out_dir(&format!("threads-{name}"))) };
            pool.install(|| reconstruct_with(&measured, &init, &params, Hooks::default()).unwrap())
        };
        let (one, three) = (run(1), run(3));
        let bits = |o: &nlos_optim::Outcome| {
            let (p, t) = o.mesh.to_triangles();
            (p.iter().flat_map(|v| v.to_array().map(f32::to_bits)).collect::<Vec<_>>(), t)
        };
        assert_eq!(bits(&one), bits(&three), "{name}: meshes differ");
        assert_eq!(one.reflectance, three.reflectance, "{name}");
        assert_eq!(one.scale.to_bits(), three.scale.to_bits(), "{name}");
        let strip = |l: &nlos_optim::RunLog| {
            l.iterations.iter().map(|r| nlos_optim::IterationRecord { time_s: 0.0, ..r.clone() }).collect::<Vec<_>>()
        };
        assert_eq!(strip(&one.log), strip(&three.log), "{name}");
    }
}
