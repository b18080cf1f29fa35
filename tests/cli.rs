//! The `nlos` command end to end, in-process ([`nlos_cli::run`]), on the built-in fixtures: `info`,
//! `reconstruct` (a short schedule, with the report and the ground truth), `eval`, and `--resume` of the
//! finished run; a capture in the seed's own `.mat` format whose point list forms a grid; bad input exits 2.

use std::process::ExitCode;

mod common;
#[path = "../crates/nlos-transient/tests/support/mat5_writer.rs"]
mod mat5_writer;
use common::{FAST, fixture_arg as fixture, scratch};

fn nlos(args: &[&str]) -> ExitCode {
    nlos_cli::run(std::iter::once("nlos").chain(args.iter().copied()))
}

#[test]
fn reconstruct_eval_and_resume_on_the_builtin_capture() {
    let (capture, truth) = (fixture("capture.hdf5"), fixture("truth.obj"));
    assert_eq!(nlos(&["info", &capture]), ExitCode::SUCCESS);
    let run = scratch("cli-run");
    let out = run.to_string_lossy().into_owned();
    let args = [&["reconstruct", &capture, "--out", &out, "--gt", &truth, "--quiet", "--glb"][..], &FAST].concat();
    assert_eq!(nlos(&args), ExitCode::SUCCESS);
    for file in ["mesh.obj", "mesh.glb", "init.obj", "report.html", "settings.toml", "run_log.json"] {
        assert!(run.join(file).is_file(), "{file} missing");
    }
    let mesh = run.join("mesh.obj").to_string_lossy().into_owned();
    assert_eq!(nlos(&["eval", &mesh, "--gt", &truth]), ExitCode::SUCCESS);
    // A finished run resumes to the same mesh.
    let before = std::fs::read(run.join("mesh.obj")).expect("mesh");
    assert_eq!(nlos(&["reconstruct", &capture, "--out", &out, "--resume", "--quiet"]), ExitCode::SUCCESS);
    assert_eq!(std::fs::read(run.join("mesh.obj")).expect("mesh"), before);
}

#[test]
fn bad_input_exits_2() {
    let dir = scratch("cli-bad");
    let garbage = dir.join("garbage.hdf5");
    std::fs::write(&garbage, b"not a capture").expect("write");
    let g = garbage.to_string_lossy().into_owned();
    let out = dir.join("run").to_string_lossy().into_owned();
    assert_eq!(nlos(&["info", &g]), ExitCode::from(2));
    assert_eq!(nlos(&["reconstruct", &g, "--out", &out]), ExitCode::from(2));
    assert_eq!(
        nlos(&["reconstruct", &fixture("capture.hdf5"), "--out", &out, "--set", "no.such=1"]),
        ExitCode::from(2)
    );
    assert_eq!(nlos(&["no-such-command"]), ExitCode::from(2));
}

/// A capture in Tsai et al.'s `.mat` format (`transient` M×T, `lighting` M×3 with x fastest, `bin_width`),
/// written here from the built-in capture: its point list forms a 2-D grid, so `nlos init` (LCT) and
/// `nlos reconstruct` run on it with no option about the layout.
#[test]
fn a_tsai_capture_whose_points_form_a_grid_runs_with_defaults() {
    let t = nlos_transient::read(common::fixture("capture.hdf5")).expect("fixture");
    let (m, bins) = (t.measurements(), t.bins());
    assert_eq!(t.time().t0, 0.0, "the Tsai format has no time origin");
    let mut transient = vec![0.0f64; m * bins];
    for r in 0..m {
        for (k, v) in t.histogram(r).iter().enumerate() {
            transient[r + m * k] = f64::from(*v); // column-major M×T
        }
    }
    let pts = &t.scan().lasers().points;
    let lighting: Vec<f64> = (0..3).flat_map(|c| pts.iter().map(move |p| f64::from(p[c]))).collect();
    let vars = vec![
        mat5_writer::double("transient", &[m as i32, bins as i32], transient),
        mat5_writer::double("lighting", &[m as i32, 3], lighting),
        mat5_writer::scalar("bin_width", t.time().bin_width),
    ];
    let dir = scratch("cli-tsai");
    let file = dir.join("capture.mat");
    std::fs::write(&file, mat5_writer::write(&vars, mat5_writer::Options::default())).expect("write");
    let read = nlos_transient::read(&file).expect("read back");
    assert_eq!(read.scan().lasers().layout, t.scan().lasers().layout, "read as the grid it is");
    let f = file.to_string_lossy().into_owned();
    let start = dir.join("start.obj").to_string_lossy().into_owned();
    assert_eq!(nlos(&["init", &f, "--out", &start]), ExitCode::SUCCESS);
    let out = dir.join("run").to_string_lossy().into_owned();
    assert_eq!(nlos(&[&["reconstruct", &f, "--out", &out, "--quiet"][..], &FAST].concat()), ExitCode::SUCCESS);
    assert!(dir.join("run/mesh.obj").is_file());
}
