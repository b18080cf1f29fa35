//! A run killed with SIGKILL right after its first checkpoint and continued with `--resume` ends with the
//! same mesh and the same run log (bit for bit, wall-clock times aside) as an uninterrupted run with the
//! same seed ("A run killed mid-way (SIGKILL) and resumed ends with the same result").

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
use nlos_transient::{Format, PointSet, Scan, TimeAxis};

mod common;
use common::text;

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    common::scratch("resume", name)
}

/// A 0.2 m square with a 3 cm ridge, 0.35 m from the wall, on a 12 × 12 confocal scan, 256 bins of 4 mm.
fn capture(dir: &Path) -> PathBuf {
    let (h, d) = (0.1f32, 0.35f32);
    let positions = [
        Vec3::new(-h, -h, d),
        Vec3::new(0.0, -h, d - 0.03),
        Vec3::new(h, -h, d),
        Vec3::new(h, h, d),
        Vec3::new(0.0, h, d - 0.03),
        Vec3::new(-h, h, d),
    ];
    let triangles = [[0u32, 4, 1], [0, 5, 4], [1, 3, 2], [1, 4, 3]]; // normals toward the wall
    let scan = Scan::confocal(PointSet::wall_grid(12, 12, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.004, 256).expect("axis");
    let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
    let renderer = Renderer::new(&positions, &triangles, &scan, &time, params).expect("renderer");
    let t = renderer.forward_transient(&Lambertian::new(1.0f32).expect("brdf")).expect("render");
    let file = dir.join("ridge.hdf5");
    nlos_transient::write(&t, &file, Format::Tal).expect("write");
    file
}

/// The ridge as photon counts (200 at the strongest bin, 2 background counts per bin) gated before it reached
/// us (bins 0..40 zeroed): fitted through the Poisson model with a response that depends on the start surface
/// (`Prepared::with_start_response`), which a resumed run must take again from `init.obj`.
fn gated_capture(dir: &Path) -> PathBuf {
    let flux = nlos_transient::read(capture(dir)).expect("read");
    let top = flux.data().iter().copied().fold(0.0f32, f32::max);
    let bins = flux.bins();
    let counts: Vec<f32> = flux
        .data()
        .iter()
        .enumerate()
        .map(|(i, &v)| if i % bins < 40 { 0.0 } else { (200.0 * v / top + 2.0).round() })
        .collect();
    let t = nlos_transient::Transient::new(flux.scan().clone(), *flux.time(), counts).expect("counts");
    assert_eq!(t.zero_gate(), Some(40));
    let file = dir.join("ridge_gated.hdf5");
    nlos_transient::write(&t, &file, Format::Tal).expect("write");
    file
}

/// Fast settings: 3 stages × up to 2 blocks of 6 shape steps, seed 11; every block writes a checkpoint.
fn command(data: &Path, out: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_nlos"));
    c.arg("reconstruct").arg(data).arg("--out").arg(out);
    c.args(["--set", "schedule.max_stages=3", "--set", "schedule.initial_resolution=8"]);
    c.args([
        "--set",
        "schedule.max_blocks_per_stage=2",
        "--set",
        "schedule.shape_iterations=6",
        "--seed",
        "11",
        "--quiet",
    ]);
    c
}

/// Positions and triangles of an OBJ, exactly as written.
fn mesh(path: &Path) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let m = nlos_mesh::io::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    m.to_triangles()
}

/// The run log without its wall-clock times (the only non-deterministic fields: each iteration's `time_s`,
/// each block's collision handling `seconds`).
fn log_without_times(dir: &Path) -> serde_json::Value {
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("run_log.json")).expect("log")).expect("log json");
    for r in v["iterations"].as_array_mut().expect("iterations") {
        r["time_s"] = serde_json::Value::Null;
    }
    for r in v["collisions"].as_array_mut().expect("collisions") {
        r["seconds"] = serde_json::Value::Null;
    }
    v
}

#[test]
fn sigkilled_run_resumes_to_the_uninterrupted_result() {
    let dir = scratch("kill");
    let data = capture(&dir);
    resumes_to_the_uninterrupted_result(&dir, &data);
}

#[test]
fn a_gated_capture_resumes_to_the_uninterrupted_result() {
    let dir = scratch("gated");
    let data = gated_capture(&dir);
    resumes_to_the_uninterrupted_result(&dir, &data);
}

fn resumes_to_the_uninterrupted_result(dir: &Path, data: &Path) {
    let data = data.to_path_buf();

    // The reference: one uninterrupted run.
    let whole = dir.join("whole");
    let t0 = Instant::now();
    let r = command(&data, &whole).arg("--no-report").output().expect("run nlos");
    assert!(r.status.success(), "{}", text(&r));
    let whole_s = t0.elapsed().as_secs_f64();

    // The same run, SIGKILLed as soon as its first checkpoint exists.
    let killed = dir.join("killed");
    let mut child = command(&data, &killed).stdout(Stdio::null()).stderr(Stdio::null()).spawn().expect("spawn");
    let ck = killed.join("checkpoint.json");
    let deadline = Instant::now() + Duration::from_secs(60);
    while !ck.is_file() {
        assert!(child.try_wait().expect("wait").is_none(), "the run ended before writing a checkpoint");
        assert!(Instant::now() < deadline, "no checkpoint after 60 s");
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().expect("SIGKILL"); // std's Child::kill sends SIGKILL on Unix
    let status = child.wait().expect("reap");
    assert!(!status.success(), "the run finished before it could be killed ({whole_s:.2} s uninterrupted)");
    assert!(!killed.join("mesh.obj").exists(), "the run finished before it was killed: nothing tested");
    let ck_text = std::fs::read_to_string(&ck).expect("checkpoint");
    assert!(ck_text.contains("\"finished\":null"), "checkpoint of a finished run");

    // Resume to the end; the report is written after the resumed run too.
    let r = command(&data, &killed).arg("--resume").output().expect("resume");
    assert!(r.status.success(), "{}", text(&r));
    assert!(killed.join("report.html").is_file(), "no report after --resume: {}", text(&r));

    let (pw, tw) = mesh(&whole.join("mesh.obj"));
    let (pk, tk) = mesh(&killed.join("mesh.obj"));
    assert_eq!(tw, tk, "triangles differ");
    assert_eq!(pw.len(), pk.len());
    // Bit-exact: f32 positions compared by their bits.
    let differing =
        pw.iter().zip(&pk).filter(|(a, b)| a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits));
    assert_eq!(differing.count(), 0, "positions differ after resume");
    assert_eq!(log_without_times(&whole), log_without_times(&killed), "run logs differ");
}
