//! Project automation.
//!
//! - `cargo xtask reconstruct`: the built-in demo, no arguments or data needed — simulate the built-in scene
//!   (a bumpy Lambertian patch 0.4 m behind the wall, rendered by `nlos-render` on a 24 × 24 confocal scan
//!   with Poisson photon noise), then run the product on it exactly as a user would: `nlos info`,
//!   `nlos preview`, `nlos reconstruct` (LCT initialisation → optimised mesh) and `nlos eval` of the run: its
//!   start and its result against the ground truth, side by side. Outputs go to `out/reconstruct/`.
//! - `cargo xtask reconstruct ARGS…`: forwards to `nlos reconstruct ARGS…`.
//! - `cargo xtask accept <bunny|soap|reference|ggx|real|preprocessed|sensor|nonconfocal|relay|detail|holes|all> [--quick] [--photons N] [--photon-seed S] [-- ARGS…]`:
//!   the acceptance runs (see `accept.rs`); each replaces its scenario's section of `docs/results.md`.
//! - `cargo xtask benchmark znlos DIR [-- ARGS…]`: `nlos benchmark DIR ARGS…` (every Z-NLOS capture of DIR
//!   with ground-truth maps beside it: LCT, f-k and the surface fit, scored against the maps); its table
//!   replaces the `znlos` section of `docs/results.md`.
//! - `cargo xtask fuzz [--minutes N] [TARGET…]`: a fuzzing campaign, N minutes (default 60) per target of
//!   `fuzz/` (cargo-fuzz on nightly, installed when missing); each target's campaign adds to its row of
//!   `docs/results.md` when it ran on the same code (see `fuzz.rs`).
//! - `cargo xtask status`: regenerates the README's status table from `docs/results.md`, marking stale each
//!   row whose inputs changed since it ran (see `board.rs`).
//! - `cargo xtask accept --stale [--fuzz-minutes M] [--dry-run]`: re-runs every stale row, longest first.
//! - `cargo xtask guard`: CI's subset of the board (the bunny, the `holes` slots); fails when a check the
//!   committed board shows passing fails now.
//! - `cargo xtask fixtures`: regenerates `fixtures/` (see `fixtures/README.md`).
//! - `cargo xtask test [ARGS…]`: `cargo test --workspace ARGS…`, then the count of tests skipped for want of
//!   the shared data.
//! - `cargo xtask help`.

mod accept;
mod board;
mod fuzz;
mod refresh;
mod znlos;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("reconstruct") if args.len() > 1 => nlos(&args.iter().map(String::as_str).collect::<Vec<_>>()),
        Some("reconstruct") => demo(),
        Some("accept") if args.iter().any(|a| a == "--stale") => refresh::refresh(&workspace_root(), &args[1..]),
        Some("accept") => accept::accept(&workspace_root(), &args[1..]),
        Some("guard") => board::guard::guard(&workspace_root(), &args[1..]),
        Some("fixtures") => fixtures(),
        Some("test") => test(&args[1..]),
        Some("status") => accept::update_readme(&workspace_root()),
        Some("benchmark") => znlos::benchmark(&args[1..]),
        Some("fuzz") => fuzz::fuzz(&workspace_root(), &args[1..]),
        None | Some("help" | "--help" | "-h") => {
            println!("usage: cargo xtask reconstruct             the built-in demo (no data needed)");
            println!("       cargo xtask reconstruct ARGS...     the same as `nlos reconstruct ARGS...`");
            println!(
                "       cargo xtask accept SCENARIO [--quick] [--photons N] [--photon-seed S] [-- RECONSTRUCT_ARGS...]"
            );
            println!("                                           acceptance runs, SCENARIO: bunny, soap, reference,");
            println!("                                           ggx, real, preprocessed, sensor, nonconfocal, relay,");
            println!("                                           detail, holes, all;");
            println!("                                           writes docs/results.md");
            println!("       cargo xtask benchmark znlos DIR [-- ARGS...]");
            println!(
                "                                           LCT, f-k and the fit on DIR's Z-NLOS captures against"
            );
            println!("                                           their depth/normal maps; writes docs/results.md");
            println!("       cargo xtask fuzz [--minutes N] [TARGET...]");
            println!(
                "                                           N minutes (60) per fuzz target; writes docs/results.md"
            );
            println!("       cargo xtask accept --stale [--fuzz-minutes M] [--dry-run]");
            println!("                                           every stale row re-run, longest first");
            println!("       cargo xtask status                  the README's status table from docs/results.md,");
            println!("                                           stale rows marked");
            println!("       cargo xtask guard                   CI: the bunny and the holes slots against the board");
            println!(
                "       cargo xtask fixtures                regenerate fixtures/ (the bunny start needs ../shared/data)"
            );
            println!("       cargo xtask test [ARGS...]          every test, then how many skipped for want of data");
            Ok(())
        }
        Some(other) => Err(format!("unknown task `{other}`; try `cargo xtask help`")),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e}");
            ExitCode::FAILURE
        }
    }
}

pub(crate) fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."))
}

fn demo() -> Result<(), String> {
    let out = workspace_root().join("out/reconstruct");
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let scene = nlos_optim::builtin::BuiltinScene::default();
    println!(
        "[1/5] built-in scene: {:.2} m Lambertian patch at {:.2} m with a {:.0} mm bump toward the wall; \
         {}×{} confocal scan, {} bins of {:.1} mm, {} photons per measurement",
        scene.size,
        scene.depth,
        scene.bump * 1e3,
        scene.grid,
        scene.grid,
        scene.bins,
        scene.bin_width * 1e3,
        scene.photons
    );
    let truth = scene.mesh().map_err(|e| e.to_string())?;
    let truth_file = out.join("truth.obj");
    nlos_mesh::io::save(&truth, &truth_file).map_err(|e| e.to_string())?;
    let (_, noisy) = scene.capture(&truth).map_err(|e| e.to_string())?;
    let capture = out.join("capture.hdf5");
    nlos_transient::write(&noisy, &capture, nlos_transient::Format::Tal).map_err(|e| e.to_string())?;
    let s = |p: &Path| p.to_string_lossy().into_owned();
    println!("[2/5] nlos info {}", capture.display());
    nlos(&["info", &s(&capture)])?;
    let png = out.join("preview.png");
    println!("[3/5] nlos preview → {}", png.display());
    nlos(&["preview", &s(&capture), "--out", &s(&png)])?;
    let run = out.join("run");
    println!("[4/5] nlos reconstruct (LCT initialisation, 2 coarse-to-fine stages) → {}", run.display());
    let started = std::time::Instant::now();
    nlos(&[
        "reconstruct",
        &s(&capture),
        "--out",
        &s(&run),
        "--set",
        "schedule.max_stages=2",
        "--set",
        "schedule.initial_resolution=20",
        "--set",
        "schedule.max_blocks_per_stage=2",
        "--set",
        "schedule.shape_iterations=15",
        "--seed",
        "1",
        // Only the report uses it: depth map, metrics and coverage picture against the truth.
        "--gt",
        &s(&truth_file),
    ])?;
    println!(
        "      reconstruction took {:.0} s; outputs in {} (the report: {})",
        started.elapsed().as_secs_f64(),
        out.display(),
        run.join("report.html").display()
    );
    // The demo ends with the figures that say whether it worked.
    println!(
        "[5/5] nlos eval {} --gt {}: the start (LCT) and the result against the truth",
        run.display(),
        truth_file.display()
    );
    nlos(&["eval", &s(&run), "--gt", &s(&truth_file)])?;
    Ok(())
}

/// Runs the `nlos` CLI (built in release mode) with `args`.
/// Regenerates `fixtures/`: the built-in scene's ground truth, capture and start (`fixtures/builtin/`, from
/// [`nlos_optim::builtin::BuiltinScene::write_fixtures`]; no data needed, seconds) and, when the shared data
/// are present, `fixtures/bunny_lct_start.obj`: the LCT start of the shared bunny at Tsai et al. 2019's setup, as
/// `nlos reconstruct` makes it — the ground truth rendered by `nlos render` (confocal 64 × 64 over
/// [−0.25, 0.25]² m, 1200 bins of 1.2 mm), 1000 photons per measurement (Poisson, seed 1), `nlos init`
/// (LCT, default settings); the loop benchmark (`benches/loop_cost.rs`) remeshes it as the optimiser does.
/// Idempotent: every step is seeded and deterministic, so a second run writes the same bytes.
fn fixtures() -> Result<(), String> {
    let root = workspace_root();
    let dir = root.join("fixtures");
    let builtin = dir.join("builtin");
    println!("[1/3] built-in scene → {}", builtin.display());
    nlos_optim::builtin::BuiltinScene::default().write_fixtures(&builtin).map_err(|e| e.to_string())?;
    let bunny = root.join("../shared/data/meshes/bunny_centered.obj");
    if !bunny.exists() {
        println!("[2/3] {} is absent: fixtures/bunny_lct_start.obj left as it is", bunny.display());
        return Ok(());
    }
    let tmp = root.join("out/fixtures");
    std::fs::create_dir_all(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    let capture = tmp.join("bunny_1000ph.hdf5");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    println!("[2/3] nlos render (the shared bunny, Tsai et al. 2019's setup, 1000 photons, seed 1; a few minutes)");
    nlos(&["render", &s(&bunny), "--out", &s(&capture), "--photons", "1000", "--seed", "1"])?;
    let start = dir.join("bunny_lct_start.obj");
    println!("[3/3] nlos init → {}", start.display());
    nlos(&["init", &s(&capture), "--out", &s(&start)])?;
    // `nlos init` writes a figure beside the mesh; the fixture is the mesh alone.
    let _ = std::fs::remove_file(start.with_extension("png"));
    Ok(())
}

/// `cargo xtask test`: every test of the workspace (`cargo test --workspace`, with `ARGS` appended), then
/// the count of tests that skipped for want of the shared data, printed once at the end (each skip appends
/// a line to `target/nlos-data-skips-<pid of that cargo>.log`; see `nlos-testdata`). `NLOS_REQUIRE_DATA=1` makes those skips
/// failures instead.
fn test(args: &[String]) -> Result<(), String> {
    let target = std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| workspace_root().join("target"), PathBuf::from);
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    // In the tests, a self-intersection found after a run's start is an error, not a warning
    // (nlos_optim::reconstruct): collision handling must leave nothing to find.
    let strict = std::env::var_os("NLOS_REQUIRE_NO_INTERSECTIONS").unwrap_or_else(|| "1".into());
    let mut child = Command::new(cargo)
        .current_dir(workspace_root())
        .env("NLOS_REQUIRE_NO_INTERSECTIONS", strict)
        .args(["test", "--workspace"])
        .args(args)
        .spawn()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    // The test binaries are children of this cargo process: their skips go to the log named after it.
    let log = target.join(format!("nlos-data-skips-{}.log", child.id()));
    let status = child.wait().map_err(|e| format!("waiting for cargo: {e}"))?;
    let skips = std::fs::read_to_string(&log).unwrap_or_default();
    let _ = std::fs::remove_file(&log);
    let skips: Vec<&str> = skips.lines().collect();
    if skips.is_empty() {
        println!("xtask test: no test skipped for want of shared data");
    } else {
        println!("xtask test: {} tests skipped for want of shared data (../shared/data):", skips.len());
        for line in &skips {
            println!("  {line}");
        }
    }
    if status.success() { Ok(()) } else { Err(format!("`cargo test --workspace` failed ({status})")) }
}

pub(crate) fn nlos(args: &[&str]) -> Result<(), String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(workspace_root())
        .args(["run", "--quiet", "--release", "--package", "nlos-cli", "--bin", "nlos", "--"])
        .args(args)
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if status.success() { Ok(()) } else { Err(format!("`nlos {}` failed ({status})", args.join(" "))) }
}
