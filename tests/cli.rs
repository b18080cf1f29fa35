//! The `nlos` command end to end, in-process ([`nlos_cli::run`]), on the built-in fixtures: `info`,
//! `reconstruct` (a short schedule, with the report and the ground truth), `eval`, and `--resume` of the
//! finished run; bad input exits 2.

use std::process::ExitCode;

mod common;
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
