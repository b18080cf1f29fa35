//! End-to-end tests of `nlos reconstruct`: a small rendered scene through LCT initialisation, the
//! optimiser and the outputs; resuming a finished run; bad arguments.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
use nlos_transient::{Format, PointSet, Scan, TimeAxis};

mod common;
use common::{nlos, text};

/// A one-stage, one-block, two-step schedule on a coarse mesh: a run of seconds.
const FAST: [&str; 8] = [
    "--set",
    "schedule.max_stages=1",
    "--set",
    "schedule.initial_resolution=10",
    "--set",
    "schedule.max_blocks_per_stage=1",
    "--set",
    "schedule.shape_iterations=2",
];

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    common::scratch("reconstruct", name)
}

/// A 0.2 m square facing the wall at 0.35 m, rendered on a 12 × 12 confocal scan, 256 bins of 4 mm.
fn capture(dir: &Path) -> PathBuf {
    let scan = Scan::confocal(PointSet::wall_grid(12, 12, 0.25, 0.25).expect("grid"));
    square_capture(&dir.join("square.hdf5"), scan)
}

/// The square of [`capture`] rendered on `scan` (256 bins of 4 mm), written to `file`.
fn square_capture(file: &Path, scan: Scan) -> PathBuf {
    let (h, d) = (0.1f32, 0.35f32);
    let positions = [Vec3::new(-h, -h, d), Vec3::new(h, -h, d), Vec3::new(h, h, d), Vec3::new(-h, h, d)];
    let triangles = [[0u32, 2, 1], [0, 3, 2]]; // normals −z: toward the wall
    let time = TimeAxis::new(0.0, 0.004, 256).expect("axis");
    let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
    let renderer = Renderer::new(&positions, &triangles, &scan, &time, params).expect("renderer");
    let t = renderer.forward_transient(&Lambertian::new(1.0f32).expect("brdf")).expect("render");
    nlos_transient::write(&t, file, Format::Tal).expect("write");
    file.to_path_buf()
}

#[test]
fn reconstructs_a_rendered_square_and_writes_every_output() {
    let dir = scratch("square");
    let data = capture(&dir);
    let out = dir.join("run");
    let (d, o) = (data.to_string_lossy().into_owned(), out.to_string_lossy().into_owned());
    let common = ["--out", &o, "--set", "schedule.max_stages=1", "--set", "schedule.initial_resolution=10"];
    let common =
        [&common[..], &["--set", "schedule.max_blocks_per_stage=1", "--set", "schedule.shape_iterations=3", "--quiet"]]
            .concat();
    let mut args = vec!["reconstruct", d.as_str()];
    args.extend(common);
    args.push("--glb");
    let run = nlos(&args);
    assert!(run.status.success(), "{}", text(&run));
    for f in [
        "init.obj",
        "mesh.obj",
        "mesh.ply",
        "mesh.glb",
        "run_log.json",
        "checkpoint.json",
        "command.json",
        "settings.toml",
        "report.html",
        "summed.png",
        "loss.png",
        "depth_final.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing; output: {}", text(&run));
    }
    // The GLB holds the same mesh as the OBJ.
    let (obj, glb) = (
        nlos_mesh::io::load(out.join("mesh.obj")).expect("obj"),
        nlos_mesh::io::load(out.join("mesh.glb")).expect("glb"),
    );
    assert_eq!((obj.n_faces(), obj.n_vertices()), (glb.n_faces(), glb.n_vertices()));
    // `nlos report` regenerates the report from the run directory and the capture.
    std::fs::remove_file(out.join("report.html")).expect("rm report");
    std::fs::remove_file(out.join("summed.png")).expect("rm png");
    let rep = nlos(&["report", &o, "--data", &d]);
    assert!(rep.status.success(), "{}", text(&rep));
    let html = std::fs::read_to_string(out.join("report.html")).expect("report regenerated");
    assert!(html.contains("summed.png") && out.join("summed.png").is_file());
    assert!(html.contains("1 stages from resolution 10 (first edge") && html.contains("mm), 1 blocks of 3 steps"));
    let missing = nlos(&["report", &dir.join("nowhere").to_string_lossy(), "--data", &d]);
    assert_eq!(missing.status.code(), Some(2), "{}", text(&missing));
    // The LCT initial surface sits at the square's depth.
    let init = nlos_mesh::io::load(out.join("init.obj")).expect("init mesh");
    let mean_z = init.positions().iter().map(|p| p.z).sum::<f32>() / init.positions().len() as f32;
    assert!((mean_z - 0.35).abs() < 0.02, "initial surface at {mean_z} m, square at 0.35 m");
    let log: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("run_log.json")).expect("log")).expect("json");
    assert!(log["iterations"].as_array().is_some_and(|a| !a.is_empty()), "empty run log");
    // mesh.ply carries how much of their light the data confirm, per vertex; the square's capture holds
    // the light of most of it, and the report's 3-D view offers the colouring.
    let soup = nlos_mesh::io::read_ply(&std::fs::read(out.join("mesh.ply")).expect("ply"), "mesh.ply").expect("ply");
    let support = soup.support.expect("mesh.ply has the support per vertex");
    assert_eq!(support.len(), soup.positions.len());
    let mean = support.iter().sum::<f32>() / support.len() as f32;
    assert!(support.iter().all(|s| (-1.0..=1.0).contains(s)) && mean > 0.5, "mean support {mean}");
    assert!(html.contains("value=\"support\""), "no support colouring in the 3-D view");
    // Resuming a finished run continues from its checkpoint without error.
    args.push("--resume");
    let resumed = nlos(&args);
    assert!(resumed.status.success(), "{}", text(&resumed));
}

/// The per-vertex albedo (`albedo = "vertex"`): the run fits it, keeps it in the checkpoint (so `--resume` and
/// `nlos report` find it), writes it into `mesh.ply` (one value per vertex), and the report renders with it
/// and shows it. Resuming without it is refused, naming the setting; the default (`"off"`) fits one albedo.
#[test]
fn the_albedo_is_fitted_kept_and_shown() {
    let dir = scratch("albedo");
    let data = capture(&dir);
    let out = dir.join("run");
    let (d, o) = (data.to_string_lossy().into_owned(), out.to_string_lossy().into_owned());
    let mut args = vec!["reconstruct", d.as_str(), "--out", &o, "--set", "schedule.max_stages=1"];
    args.extend(["--set", "schedule.initial_resolution=10", "--set", "schedule.max_blocks_per_stage=1"]);
    args.extend(["--set", "schedule.shape_iterations=2", "--quiet", "--set", "albedo=\"vertex\""]);
    let run = nlos(&args);
    assert!(run.status.success(), "{}", text(&run));
    let ply = std::fs::read(out.join("mesh.ply")).expect("mesh.ply");
    let soup = nlos_mesh::io::read_ply(&ply, "mesh.ply").expect("ply");
    let albedo = soup.albedo.expect("mesh.ply has an albedo per vertex");
    assert_eq!(albedo.len(), soup.positions.len());
    assert!(albedo.iter().all(|a| a.is_finite() && *a >= 0.0), "{albedo:?}");
    let ck: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("checkpoint.json")).expect("checkpoint")).expect("json");
    assert!(ck.to_string().contains("\"albedo\""), "the checkpoint keeps the albedo field");
    assert!(out.join("albedo.png").is_file(), "{}", text(&run));
    let html = std::fs::read_to_string(out.join("report.html")).expect("report");
    assert!(html.contains("albedo.png"));
    // Resuming with other settings (one albedo) is refused, naming the setting; with the run's own it continues.
    let refused = nlos(&["reconstruct", &d, "--out", &o, "--quiet", "--resume", "--set", "albedo=\"off\""]);
    assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
    assert!(text(&refused).contains("albedo"), "{}", text(&refused));
    let resumed = nlos(&["reconstruct", &d, "--out", &o, "--quiet", "--resume"]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    // The default, one albedo: mesh.ply without the property, no albedo figure.
    let one = dir.join("one");
    let o1 = one.to_string_lossy().into_owned();
    let mut args = vec!["reconstruct", d.as_str(), "--out", &o1, "--set", "schedule.max_stages=1"];
    args.extend(["--set", "schedule.initial_resolution=10", "--set", "schedule.max_blocks_per_stage=1"]);
    args.extend(["--set", "schedule.shape_iterations=2", "--quiet"]);
    let run = nlos(&args);
    assert!(run.status.success(), "{}", text(&run));
    let soup = nlos_mesh::io::read_ply(&std::fs::read(one.join("mesh.ply")).expect("ply"), "mesh.ply").expect("ply");
    assert!(soup.albedo.is_none());
    assert!(!one.join("albedo.png").exists());
}

#[test]
fn bad_arguments_are_input_errors() {
    let dir = scratch("bad");
    let data = capture(&dir);
    let d = data.to_string_lossy().into_owned();
    let o = dir.join("run").to_string_lossy().into_owned();
    for extra in [
        vec!["--brdf", "phong"],
        vec!["--init", "no-such-mesh.obj"],
        vec!["--init", "voxels"],
        vec!["--rebin", "0"],
        vec!["--subsample", "0"],
        vec!["--gt", "no-such-gt.obj"],
        vec!["--sensor", "no-such-jitter.mat"],
        vec!["--sensor", "direct"],
        vec!["--set", "schedule.initial_resolution=-3"],
        vec!["--set", "reflectance.alpha=7"],
        vec!["--brdf", "ggx", "--set", "reflectance.alpha=0"],
        vec!["--set", "render.visibility=sometimes"],
        vec!["--set", "render.max_level=0"],
        vec!["--set", "render.device=\"tpu\""],
        vec!["--brdf", "ggx", "--set", "render.device=\"gpu\""],
        vec!["--set", "sensor.background=-3", "--sensor", "ideal"],
        vec!["--set", "sensor.background=lots", "--sensor", "ideal"],
        vec!["--set", "sensor.background=0.5"],
        vec!["--set", "sensor.noise=gaussian"],
        vec!["--set", "capture.gate=lots"],
        vec!["--set", "capture.gate=inf"],
        vec!["--set", "capture.max_depth=-1"],
        vec!["--set", "capture.max_depth=0"],
        vec!["--set", "capture.max_depth=deep"],
        vec!["--set", "capture.max_depth=inf"],
        vec!["--set", "optimiser.boundary_smoothing=-1"],
        vec!["--set", "optimiser.boundary_smoothing=nan"],
        vec!["--set", "boundary.prune_rounds=lots"],
        vec!["--set", "boundary.prune_margin=-1"],
        vec!["--set", "boundary.residual_separation=0"],
        vec!["--set", "boundary.residual_margin=-1"],
        vec!["--set", "boundary.residual_tilts=[40, 95]"],
        vec!["--set", "boundary.residual_tilts=steep"],
        vec!["--set", "albedo=fine"],
        vec!["--set", "albedo=0"],
        vec!["--set", "no_such_setting=1"],
        vec!["--set", "schedule.no_such_setting=1"],
        vec!["--set", "schedule"],
        vec!["--config", "no-such-config.toml"],
    ] {
        // Fast settings, so that an argument wrongly accepted fails the test quickly instead of running long.
        let mut args = vec!["reconstruct", d.as_str(), "--out", o.as_str(), "--quiet"];
        args.extend(["--set", "schedule.max_stages=1", "--set", "schedule.max_blocks_per_stage=1"]);
        args.extend(["--set", "schedule.shape_iterations=1"]);
        args.extend(extra.iter().copied());
        let r = nlos(&args);
        assert_eq!(r.status.code(), Some(2), "{extra:?}: {}", text(&r));
        assert!(text(&r).contains("error:"), "{extra:?}: {}", text(&r));
    }
    let missing = nlos(&["reconstruct", "nope.hdf5", "--out", &o]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(text(&missing).contains("nope.hdf5"));
}

/// `--noise`: a rendered (non-integer) capture is not taken for counts by `auto`, so its run log has no
/// noise floor; `--noise counts` logs one per shape step (here meaningless in size: the capture's values are
/// not counts, which is why `auto` does not pick it).
#[test]
fn noise_counts_logs_the_noise_floor_and_auto_detects_non_counts() {
    let dir = scratch("noise");
    let data = capture(&dir);
    let d = data.to_string_lossy().into_owned();
    for (mode, want_floor) in [("auto", false), ("counts", true)] {
        let o = dir.join(mode).to_string_lossy().into_owned();
        let noise = format!("sensor.noise={mode}");
        let args = ["reconstruct", &d, "--out", &o, "--quiet", "--no-report", "--set", "schedule.max_stages=1"];
        let mut args = args.to_vec();
        args.extend(["--set", "schedule.initial_resolution=10", "--set", "schedule.max_blocks_per_stage=1"]);
        args.extend(["--set", "schedule.shape_iterations=2", "--set", &noise]);
        let r = nlos(&args);
        assert!(r.status.success(), "{mode}: {}", text(&r));
        let log: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join(mode).join("run_log.json")).expect("log")).expect("json");
        let its = log["iterations"].as_array().expect("iterations");
        assert!(!its.is_empty());
        for it in its {
            assert_eq!(it.get("noise_floor").is_some(), want_floor, "{mode}: {it}");
            if let Some(f) = it["noise_floor"].as_f64() {
                assert!(f > 0.0 && f.is_finite(), "{mode}: {it}");
            }
        }
    }
}

#[test]
fn space_carving_initialises_and_gt_adds_metrics_to_the_report() {
    let dir = scratch("carve");
    let data = capture(&dir);
    let out = dir.join("run");
    // The ground truth: the rendered square itself.
    let (h, z) = (0.1f32, 0.35f32);
    let positions = [Vec3::new(-h, -h, z), Vec3::new(h, -h, z), Vec3::new(h, h, z), Vec3::new(-h, h, z)];
    let gt = nlos_mesh::SurfaceMesh::from_triangles(&positions, &[[0, 2, 1], [0, 3, 2]]).expect("gt");
    let gt_file = dir.join("gt.obj");
    nlos_mesh::io::save(&gt, &gt_file).expect("save gt");
    let (d, o, g) = (
        data.to_string_lossy().into_owned(),
        out.to_string_lossy().into_owned(),
        gt_file.to_string_lossy().into_owned(),
    );
    let mut args = vec!["reconstruct", &d, "--out", &o, "--init", "carve", "--gt", &g, "--subsample", "2", "--quiet"];
    args.extend(FAST);
    let run = nlos(&args);
    assert!(run.status.success(), "{}", text(&run));
    let init = nlos_mesh::io::load(out.join("init.obj")).expect("init mesh");
    let mean_z = init.positions().iter().map(|p| p.z).sum::<f32>() / init.positions().len() as f32;
    assert!((mean_z - 0.35).abs() < 0.03, "carved surface at {mean_z} m, square at 0.35 m");
    let html = std::fs::read_to_string(out.join("report.html")).expect("report");
    assert!(html.contains("Metrics against the ground truth") && html.contains("coverage"));
    assert!(out.join("depth_gt.png").is_file());
    // Regression (the report's metrics were taken over the subsampled grid's rectangle, [−0.25, 0.159]² m
    // here, so they differed from `nlos eval`'s): the metrics cover the whole capture's scan area.
    assert!(
        html.contains("x ∈ [-0.250, 0.250] m, y ∈ [-0.250, 0.250] m"),
        "the report's ray grid is not the whole scan area [−0.25, 0.25]²"
    );
}

#[test]
fn sensor_fit_reconstructs_photon_counts() {
    let dir = scratch("sensor");
    let data = capture(&dir);
    // Poisson counts of the square (the SPAD model's ideal counter), 500 photons per measurement.
    let positions = [Vec3::new(-0.1, -0.1, 0.35), Vec3::new(0.1, -0.1, 0.35), Vec3::new(0.1, 0.1, 0.35)];
    let tri = nlos_mesh::SurfaceMesh::from_triangles(&positions, &[[0, 2, 1]]).expect("mesh");
    let mesh_file = dir.join("tri.obj");
    nlos_mesh::io::save(&tri, &mesh_file).expect("save");
    let counts = dir.join("counts.npy");
    let (d, c) = (data.to_string_lossy().into_owned(), counts.to_string_lossy().into_owned());
    let r = nlos(&["render", &mesh_file.to_string_lossy(), "--setup", &d, "--out", &c, "--photons", "500"]);
    assert!(r.status.success(), "{}", text(&r));
    let out = dir.join("run");
    let o = out.to_string_lossy().into_owned();
    let mut args = vec!["reconstruct", &c, "--out", &o, "--sensor", "ideal", "--set", "sensor.background=auto"];
    args.extend(FAST);
    args.push("--quiet");
    let run = nlos(&args);
    assert!(run.status.success(), "{}", text(&run));
    let html = std::fs::read_to_string(out.join("report.html")).expect("report");
    assert!(html.contains("sensor fit: Poisson NLL"), "the report does not name the sensor fit");
    let log: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("run_log.json")).expect("log")).expect("json");
    let it = log["iterations"].as_array().expect("iterations");
    assert!(it.iter().all(|r| r["loss"].as_f64().is_some_and(f64::is_finite)), "non-finite loss in {log}");
}

#[test]
fn max_depth_auto_drops_the_late_background_of_a_capture_with_background_only() {
    let dir = scratch("maxdepth");
    // The rendered square as photon counts on a background of 2 counts per bin, its axis doubled (to 1024
    // bins of 4 mm) so that the later half holds background only.
    let clean = nlos_transient::read(capture(&dir)).expect("clean");
    let peak = clean.data().iter().copied().fold(0.0f32, f32::max);
    let mut rng = nlos_transient::rng::Pcg32::new(3, 1);
    let bins = clean.bins();
    let counts: Vec<f32> = clean
        .histograms()
        .flat_map(|h| h.iter().copied().chain(std::iter::repeat_n(0.0, bins)).collect::<Vec<f32>>())
        .map(|v| rng.poisson(2.0 + 200.0 * f64::from(v / peak)) as f32)
        .collect();
    let time = TimeAxis::new(clean.time().t0, clean.time().bin_width, 2 * bins).expect("axis");
    let noisy = nlos_transient::Transient::new(clean.scan().clone(), time, counts).expect("noisy");
    let expected = noisy.signal_end_path(noisy.time().t0);
    assert!(expected < noisy.time().end(), "the test capture must have background-only late bins");
    let file = dir.join("noisy.hdf5");
    nlos_transient::write(&noisy, &file, Format::Tal).expect("write");
    let d = file.to_string_lossy().into_owned();
    let o = dir.join("run").to_string_lossy().into_owned();
    let fast = [&FAST[..], &["--quiet", "--set", "capture.gate=off"]].concat();
    let mut args = vec!["reconstruct", d.as_str(), "--out", o.as_str()];
    args.extend(&fast);
    let run = nlos(&args);
    assert!(run.status.success(), "{}", text(&run));
    let note = format!("max_depth auto: the last return ends at {expected:.4} m of path");
    assert!(text(&run).contains(&note), "expected `{note}` in: {}", text(&run));
    // `off` keeps every bin, and a capture without background (the clean render) has nothing to drop.
    args.extend(["--set", "capture.max_depth=off"]);
    let run = nlos(&args);
    assert!(run.status.success() && !text(&run).contains("max_depth auto"), "{}", text(&run));
    let clean_file = dir.join("square.hdf5").to_string_lossy().into_owned();
    let mut args = vec!["reconstruct", clean_file.as_str(), "--out", o.as_str()];
    args.extend(fast);
    let run = nlos(&args);
    assert!(run.status.success() && !text(&run).contains("max_depth auto"), "{}", text(&run));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--sensor auto` (the default): photon counts with a direct reflection off the wall (a real capture) are
/// fitted through the capture's own response; the same counts without it, and `--sensor off`, by L2.
#[test]
fn sensor_auto_fits_real_captures_through_their_own_response() {
    let dir = scratch("auto");
    let clean = nlos_transient::read(capture(&dir)).expect("clean");
    let peak = clean.data().iter().copied().fold(0.0f32, f32::max);
    let mut rng = nlos_transient::rng::Pcg32::new(5, 1);
    // The direct return: a tail of the sensor's response at path 0 (bins of 4 mm), 100× the object's peak.
    let direct = |k: usize| if k < 12 { 2e4 * (-(k as f64) / 2.0).exp() } else { 0.0 };
    let mut files = Vec::new();
    for (name, with_direct) in [("real", true), ("simulated", false)] {
        let counts: Vec<f32> = clean
            .histograms()
            .flat_map(|h| {
                h.iter()
                    .enumerate()
                    .map(|(k, &v)| {
                        let d = if with_direct { direct(k) } else { 0.0 };
                        rng.poisson(1.0 + d + 200.0 * f64::from(v / peak)) as f32
                    })
                    .collect::<Vec<f32>>()
            })
            .collect();
        let t = nlos_transient::Transient::new(clean.scan().clone(), *clean.time(), counts).expect("counts");
        let file = dir.join(format!("{name}.hdf5"));
        nlos_transient::write(&t, &file, Format::Tal).expect("write");
        files.push(file);
    }
    let run = |file: &Path, extra: &[&str]| {
        let o = dir.join(format!(
            "run-{}-{}",
            file.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default(),
            extra.len()
        ));
        let (f, o) = (file.to_string_lossy().into_owned(), o.to_string_lossy().into_owned());
        let mut args = vec!["reconstruct", &f, "--out", &o, "--no-report"];
        args.extend(FAST);
        args.extend(extra);
        let r = nlos(&args);
        assert!(r.status.success(), "{extra:?}: {}", text(&r));
        text(&r)
    };
    let own = "through the capture's own response";
    assert!(run(&files[0], &[]).contains(own), "a capture with a direct return is fitted through it");
    assert!(!run(&files[0], &["--sensor", "off"]).contains(own), "--sensor off fits by L2");
    assert!(!run(&files[1], &[]).contains(own), "a simulation has no direct return to take");
    // An L2 run resumed with another sensor setting: refused, naming it.
    let (f, o) = (files[0].to_string_lossy().into_owned(), dir.join("run-real-2").to_string_lossy().into_owned());
    let mut args = vec!["reconstruct", &f, "--out", &o, "--no-report", "--resume", "--sensor", "auto"];
    args.extend(FAST);
    let refused = nlos(&args);
    assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
    assert!(text(&refused).contains("started with sensor = null"), "{}", text(&refused));
    // With the run's own settings (`DIR/settings.toml`) it continues.
    let resumed = nlos(&["reconstruct", &f, "--out", &o, "--no-report", "--resume"]);
    assert!(resumed.status.success(), "{}", text(&resumed));
}

/// `--rim-radius` on `nlos init` (and, through the same `SurfaceParams`, on `nlos reconstruct --init lct`):
/// the boundary vertices recede by the radius, the rest stays where it was, nothing moves sideways.
#[test]
fn rim_radius_turns_the_initial_surface_back_at_its_boundary() {
    let dir = scratch("rim");
    let data = capture(&dir);
    let d = data.to_string_lossy().into_owned();
    let (plain, rounded) = (dir.join("plain.obj"), dir.join("rounded.obj"));
    let (p, r) = (plain.to_string_lossy().into_owned(), rounded.to_string_lossy().into_owned());
    let run = |extra: &[&str]| {
        let o = nlos(&[&["init", d.as_str(), "--method", "lct"], extra].concat());
        assert!(o.status.success(), "{extra:?}: {}", text(&o));
    };
    run(&["--out", &p]);
    // Below the 4.5 cm column spacing: only the boundary moves, by the full radius.
    run(&["--out", &r, "--rim-radius", "0.03"]);
    let a = nlos_mesh::io::load(&plain).expect("plain");
    let b = nlos_mesh::io::load(&rounded).expect("rounded");
    assert_eq!(a.n_vertices(), b.n_vertices());
    let mut moved = 0;
    for (u, v) in a.positions().iter().zip(b.positions()) {
        assert_eq!((u.x, u.y), (v.x, v.y), "no vertex moves sideways");
        let dz = v.z - u.z;
        assert!(dz.abs() < 1e-5 || (dz - 0.03).abs() < 1e-5, "moved by {dz}");
        moved += usize::from(dz > 0.015);
    }
    let boundary = b.vertices().filter(|&v| b.is_boundary_vertex(v)).count();
    assert_eq!(moved, boundary, "exactly the boundary vertices recede");
    assert!(moved > 0);
    for bad in ["0", "-1", "inf"] {
        let o = nlos(&["init", d.as_str(), "--method", "lct", "--out", &r, &format!("--rim-radius={bad}")]);
        assert_eq!(o.status.code(), Some(2), "--rim-radius {bad}: {}", text(&o));
        assert!(text(&o).contains("rim_radius"), "{}", text(&o));
    }
}

/// `--print-config` writes the settings as TOML and `--config` reads them back; a Rust caller of
/// `nlos_optim::pipeline` with the same settings gets the same mesh as the command line, byte for byte.
#[test]
fn the_cli_and_the_library_pipeline_make_the_same_mesh() {
    use nlos_optim::pipeline::{Config, Prepared};
    let dir = scratch("pipeline");
    let data = capture(&dir);
    let d = data.to_string_lossy().into_owned();
    // The defaults round-trip.
    let printed = nlos(&["reconstruct", "--print-config"]);
    assert!(printed.status.success(), "{}", text(&printed));
    let defaults = Config::from_toml(&String::from_utf8_lossy(&printed.stdout)).expect("printed defaults parse");
    assert_eq!(defaults, Config::default());
    // A fast configuration, printed and read back.
    let fast = ["schedule.max_stages=1", "schedule.initial_resolution=10", "schedule.max_blocks_per_stage=1"];
    let mut args = vec!["reconstruct", "--print-config", "--seed", "3", "--set", "schedule.shape_iterations=3"];
    for kv in &fast {
        args.extend(["--set", kv]);
    }
    let printed = nlos(&args);
    assert!(printed.status.success(), "{}", text(&printed));
    let file = dir.join("fast.toml");
    std::fs::write(&file, &printed.stdout).expect("write config");
    let config = Config::load(&file).expect("config");
    assert_eq!((config.seed, config.schedule.max_stages, config.schedule.shape_iterations), (3, 1, 3));
    // The command line …
    let cli_dir = dir.join("cli");
    let f = file.to_string_lossy().into_owned();
    let run = nlos(&["reconstruct", &d, "--out", &cli_dir.to_string_lossy(), "--config", &f, "--quiet", "--no-report"]);
    assert!(run.status.success(), "{}", text(&run));
    assert_eq!(Config::load(&cli_dir.join("settings.toml")).expect("saved settings"), config);
    // … and the library.
    let lib_dir = dir.join("lib");
    let prepared = Prepared::load(&data, &config).expect("prepare");
    let params = prepared.params(&config, Some(lib_dir.clone())).expect("params");
    let init = prepared.initial_surface(&config).expect("initial surface");
    nlos_optim::reconstruct(&prepared.measured, &init, &params).expect("reconstruct");
    let read = |p: PathBuf| std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert_eq!(read(cli_dir.join("mesh.obj")), read(lib_dir.join("mesh.obj")));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `render.device = "gpu"`: the same short reconstruction on the GPU backend (lavapipe in CI) ends where the CPU's
/// does, to the metrics' precision (vertices within 0.1 mm, the final loss within 0.1 %). Without any adapter,
/// `"gpu"` is refused with the reason.
#[cfg(feature = "gpu")]
#[test]
fn gpu_reconstruction_matches_the_cpu() {
    let adapter = nlos_render::GpuRenderer::new();
    let dir = scratch("gpu");
    let data = capture(&dir);
    let d = data.to_string_lossy().into_owned();
    let run = |device: &str| {
        let out = dir.join(device);
        let o = out.to_string_lossy().into_owned();
        let set = format!("render.device=\"{device}\"");
        let mut args = vec!["reconstruct", d.as_str(), "--out", &o, "--quiet", "--set", &set];
        args.extend(FAST);
        (nlos(&args), out)
    };
    let gpu = match adapter {
        Ok(_) => run("gpu"),
        Err(e) if std::env::var("NLOS_REQUIRE_GPU").is_ok_and(|v| v == "1") => panic!("NLOS_REQUIRE_GPU=1 but {e}"),
        Err(e) => {
            let (refused, _) = run("gpu");
            assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
            assert!(text(&refused).contains("no GPU adapter found"), "{}", text(&refused));
            eprintln!("skipping the comparison: {e}");
            return;
        }
    };
    assert!(gpu.0.status.success(), "{}", text(&gpu.0));
    let cpu = run("cpu");
    assert!(cpu.0.status.success(), "{}", text(&cpu.0));
    let (mg, mc) = (
        nlos_mesh::io::load(gpu.1.join("mesh.obj")).expect("GPU mesh"),
        nlos_mesh::io::load(cpu.1.join("mesh.obj")).expect("CPU mesh"),
    );
    assert_eq!((mg.n_vertices(), mg.n_faces()), (mc.n_vertices(), mc.n_faces()), "same topology");
    let worst = mg.positions().iter().zip(mc.positions()).map(|(a, b)| a.distance(*b)).fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "GPU and CPU vertices differ by {worst} m");
    let loss = |dir: &Path| -> f64 {
        let log: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("run_log.json")).expect("log")).expect("json");
        log["iterations"].as_array().and_then(|a| a.last()).and_then(|r| r["loss"].as_f64()).expect("a loss")
    };
    let (lg, lc) = (loss(&gpu.1), loss(&cpu.1));
    assert!((lg - lc).abs() <= 1e-3 * lc.abs(), "final loss {lg} on the GPU, {lc} on the CPU");
}

/// The default command (no `--init`) on captures that are not confocal: one laser (centre and corner) and a
/// 2 × 2 laser grid, each × 16 × 16 sensors. `auto` takes the phasor field, says so in the run's output and
/// its settings, the start lies at the square's depth (one start: its receding and measured rims are the same
/// surface), and `--init lct` is a clear input error.
#[test]
fn the_default_command_reconstructs_non_confocal_captures() {
    let dir = scratch("nonconfocal");
    for (name, lasers) in [
        ("centre", PointSet::list(vec![Vec3::ZERO])),
        ("corner", PointSet::list(vec![Vec3::new(-0.25, -0.25, 0.0)])),
        ("grid", PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid")),
    ] {
        let sub = dir.join(name);
        std::fs::create_dir_all(&sub).expect("dir");
        let sensors = PointSet::wall_grid(16, 16, 0.25, 0.25).expect("grid");
        let data = square_capture(&sub.join("square_nc.hdf5"), Scan::exhaustive(lasers, sensors));
        let out = sub.join("run");
        let (d, o) = (data.to_string_lossy().into_owned(), out.to_string_lossy().into_owned());
        let mut args = vec!["reconstruct", &d, "--out", &o];
        args.extend(FAST);
        let run = nlos(&args);
        assert!(run.status.success(), "{name}: {}", text(&run));
        assert!(text(&run).contains("init auto: a non-confocal scan"), "{name}: {}", text(&run));
        // The square's volume has no dim rim, so its receding and measured starts are one surface: one run.
        assert!(!text(&run).contains("start: the data chose"), "{name}: {}", text(&run));
        assert!(!out.join("start_choice.json").exists() && !out.join("start_candidates").exists(), "{name}");
        let settings = std::fs::read_to_string(out.join("settings.toml")).expect("settings");
        assert!(settings.starts_with("# init = \"auto\" chose \"pf\""), "{name}: {settings}");
        let init = nlos_mesh::io::load(out.join("init.obj")).expect("init mesh");
        let mean_z = init.positions().iter().map(|p| p.z).sum::<f32>() / init.positions().len() as f32;
        assert!((mean_z - 0.35).abs() < 0.02, "{name}: phasor-field start at {mean_z} m, square at 0.35 m");
        assert!(out.join("mesh.obj").is_file() && out.join("report.html").is_file(), "{name}");
        if name == "centre" {
            let lct = nlos(&["reconstruct", &d, "--out", &sub.join("lct").to_string_lossy(), "--init", "lct"]);
            assert_eq!(lct.status.code(), Some(2), "{}", text(&lct));
            assert!(text(&lct).contains("--init pf"), "{}", text(&lct));
            let info = nlos(&["info", &d]);
            assert!(text(&info).contains("straight in front of the scan"), "{}", text(&info));
        }
    }
}

/// A batch job's log (stderr a pipe, no display session): one plain progress line per block, the device
/// chosen in one line, and no `error:` line from the GPU probe's drivers on a run that succeeds.
#[test]
fn a_batch_log_has_a_line_per_block_and_no_driver_errors() {
    let dir = scratch("batch-log");
    let data = capture(&dir);
    let out = dir.join("run");
    let (d, o) = (data.to_string_lossy().into_owned(), out.to_string_lossy().into_owned());
    let schedule = ["--set", "schedule.max_stages=2", "--set", "schedule.max_blocks_per_stage=2"];
    let mut args = vec!["reconstruct", d.as_str(), "--out", o.as_str(), "--no-report"];
    args.extend(&FAST[2..4]);
    args.extend(&FAST[6..8]);
    args.extend(schedule);
    let run = Command::new(env!("CARGO_BIN_EXE_nlos"))
        .args(&args)
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .output()
        .expect("run nlos");
    assert!(run.status.success(), "{}", text(&run));
    let (stdout, stderr) = (String::from_utf8_lossy(&run.stdout), String::from_utf8_lossy(&run.stderr));
    let blocks: usize = stdout
        .split(" blocks in ")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no block count in {stdout}"));
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("progress: ")).collect();
    assert!(blocks >= 2, "{stdout}");
    // The last lines say how much of the capture the surface explains.
    assert!(
        stdout.lines().any(|l| l.starts_with("fit: the surface explains ") && l.contains("% of the light")),
        "{stdout}"
    );
    assert_eq!(lines.len(), blocks, "{stderr}");
    for (i, l) in lines.iter().enumerate() {
        assert!(l.contains(&format!(" block {} ", i + 1)) && l.contains(" faces ") && l.contains(" left"), "{l}");
    }
    assert!(lines.last().is_some_and(|l| l.starts_with("progress: stage 2/2 ")), "{stderr}");
    assert_eq!(stderr.lines().filter(|l| l.starts_with("device: ")).count(), 1, "{stderr}");
    assert!(!stderr.lines().any(|l| l.starts_with("error")), "{stderr}");
    let quiet = nlos(&[&args[..], &["--quiet"]].concat());
    assert!(quiet.status.success(), "{}", text(&quiet));
    assert!(!String::from_utf8_lossy(&quiet.stderr).contains("progress:"), "{}", text(&quiet));
}

/// Never exit status 0 with almost no surface: the shared general-NLOS capture thinned to every 4th spot each
/// way (256 of its 4,096 pairs; the spots form a 64 × 64 grid in the file's order) either ends with a mesh
/// that keeps at least `nlos_optim::MIN_SURFACE_KEPT` of its start's area, or fails (exit 1) saying what was
/// kept and where to look — with everything written. What it catches: a run that ends in a sliver (2 faces of
/// 0.006 cm² from a start of 0.43 m² before the check) reported as a result.
#[test]
fn a_run_never_succeeds_with_almost_no_surface() {
    let Some(general) = nlos_testdata::shared("measured/general_nlos/data.mat") else { return };
    let dir = scratch("sparse");
    let full = dir.join("full.npy");
    let o = nlos(&["convert", general.to_str().expect("utf-8"), "--bin-width-ps", "32", full.to_str().expect("utf-8")]);
    assert!(o.status.success(), "{}", text(&o));
    let t = nlos_transient::read(&full).expect("read back");
    let keep: Vec<usize> = (0..64).step_by(4).flat_map(|iy| (0..64).step_by(4).map(move |ix| 64 * iy + ix)).collect();
    let thin = t.select(&keep).expect("thinned");
    let file = dir.join("thin.npy");
    nlos_transient::write(&thin, &file, Format::NpyJson).expect("write");
    let out = dir.join("run");
    let o = nlos(&["reconstruct", file.to_str().expect("utf-8"), "--out", out.to_str().expect("utf-8"), "--quiet"]);
    let mesh = nlos_mesh::io::load(out.join("mesh.obj")).expect("the mesh is written either way");
    let start = nlos_mesh::io::load(out.join("init.obj")).expect("the start is written");
    let kept = mesh.surface_area() / start.surface_area();
    if o.status.success() {
        assert!(kept >= nlos_optim::MIN_SURFACE_KEPT, "exit 0 with {kept:.2e} of the start's area: {}", text(&o));
    } else {
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains("almost no surface") && text(&o).contains("init.obj"), "{}", text(&o));
        assert!(out.join("report.html").exists(), "the report is written before the failure");
    }
}

/// A capture of noise alone (confocal 24 × 24, Poisson counts of mean 0.3 in every bin, no scene) never ends
/// as a result: the default command writes its mesh and report, then exits 1 saying that the surface explains
/// no more than an empty scene would (the capture's background alone), with the figures, and where to look.
#[test]
fn a_capture_of_noise_alone_fails_after_writing_everything() {
    let dir = scratch("noise");
    let (scan, time) = (
        Scan::confocal(PointSet::wall_grid(24, 24, 0.25, 0.25).expect("grid")),
        TimeAxis::new(0.0, 0.0048, 300).expect("axis"),
    );
    let mut rng = nlos_transient::rng::SplitMix64::new(7);
    // Poisson(0.3) by inversion of its distribution function.
    let mut poisson = || {
        let (u, mut k, mut p) = (rng.next_f32(), 0u32, (-0.3f32).exp());
        let mut cdf = p;
        while u > cdf && k < 20 {
            k += 1;
            p *= 0.3 / k as f32;
            cdf += p;
        }
        k as f32
    };
    let data: Vec<f32> = (0..24 * 24 * 300).map(|_| poisson()).collect();
    let file = dir.join("noise.npy");
    let capture = nlos_transient::Transient::new(scan, time, data).expect("capture");
    nlos_transient::write(&capture, &file, Format::NpyJson).expect("write");
    let out = dir.join("run");
    let o = nlos(&["reconstruct", file.to_str().expect("utf-8"), "--out", out.to_str().expect("utf-8"), "--quiet"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let said = text(&o);
    assert!(said.contains("explains no more than an empty scene would") && said.contains("init.obj"), "{said}");
    assert!(out.join("mesh.obj").exists() && out.join("report.html").exists(), "everything is written first");
    let log: nlos_optim::RunLog =
        serde_json::from_slice(&std::fs::read(out.join("run_log.json")).expect("run log")).expect("json");
    let fit = log.fit.expect("the record");
    assert!(fit.data >= fit.empty && fit.explained() == Some(0.0), "{fit:?}");
}
