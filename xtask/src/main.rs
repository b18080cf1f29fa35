//! Project automation.
//!
//! - `cargo xtask reconstruct`: the built-in demo, no arguments or data needed — simulate the built-in scene
//!   (a bumpy Lambertian patch 0.4 m behind the wall, rendered by `nlos-render` on a 24 × 24 confocal scan
//!   with Poisson photon noise), then run the product on it exactly as a user would: `nlos info`,
//!   `nlos preview`, `nlos reconstruct` (LCT initialisation → optimised mesh) and `nlos eval` of the LCT
//!   initial mesh and of the result against the ground truth. Outputs go to `out/reconstruct/`.
//! - `cargo xtask reconstruct ARGS…`: forwards to `nlos reconstruct ARGS…`.
//! - `cargo xtask accept <bunny|soap|reference|ggx|real|sensor|all> [--quick] [--photons N] [--photon-seed S] [-- ARGS…]`:
//!   the acceptance runs of issues 8 and 9 (see `accept.rs`), appended to `docs/acceptance.md`.
//! - `cargo xtask fixtures`: regenerates `fixtures/` from `../shared/data` (see `fixtures/README.md`).
//! - `cargo xtask help`.

mod accept;
mod builtin;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("reconstruct") if args.len() > 1 => nlos(&args.iter().map(String::as_str).collect::<Vec<_>>()),
        Some("reconstruct") => demo(),
        Some("accept") => accept::accept(&workspace_root(), &args[1..]),
        Some("fixtures") => fixtures(),
        None | Some("help" | "--help" | "-h") => {
            println!("usage: cargo xtask reconstruct             the built-in demo (no data needed)");
            println!("       cargo xtask reconstruct ARGS...     the same as `nlos reconstruct ARGS...`");
            println!(
                "       cargo xtask accept SCENARIO [--quick] [--photons N] [--photon-seed S] [-- RECONSTRUCT_ARGS...]"
            );
            println!("                                           acceptance runs, SCENARIO: bunny, soap, reference,");
            println!("                                           ggx, real, sensor or all; docs/acceptance.md");
            println!("       cargo xtask fixtures                regenerate fixtures/ from ../shared/data");
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

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."))
}

fn demo() -> Result<(), String> {
    let out = workspace_root().join("out/reconstruct");
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let scene = builtin::BuiltinScene::default();
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
    let truth = scene.mesh()?;
    let truth_file = out.join("truth.obj");
    nlos_mesh::io::save(&truth, &truth_file).map_err(|e| e.to_string())?;
    let (_, noisy) = scene.capture(&truth)?;
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
    println!("      reconstruction took {:.0} s", started.elapsed().as_secs_f64());
    println!("[5/5] nlos eval against the ground truth (coverage, depth error in metres, Chamfer, normal error)");
    for (what, mesh) in [("LCT initial mesh", run.join("init.obj")), ("reconstruction  ", run.join("mesh.obj"))] {
        print!("      {what}: ");
        std::io::Write::flush(&mut std::io::stdout()).map_err(|e| e.to_string())?;
        nlos(&["eval", &s(&mesh), "--gt", &s(&truth_file)])?;
    }
    println!("done: outputs in {}", out.display());
    Ok(())
}

/// Runs the `nlos` CLI (built in release mode) with `args`.
/// `fixtures/bunny_lct_start.obj`: the LCT start of the shared bunny at the seed's setup, as `nlos reconstruct`
/// makes it — the ground truth rendered by `nlos render` (confocal 64 × 64 over [−0.25, 0.25]² m, 1200 bins
/// of 1.2 mm), 1000 photons per measurement (Poisson, seed 1), `nlos init` (LCT, default settings). The
/// renderer's loop benchmark (`crates/nlos-render/benches/loop_cost.rs`) remeshes it as the optimiser does.
fn fixtures() -> Result<(), String> {
    let root = workspace_root();
    let bunny = root.join("../shared/data/meshes/bunny_centered.obj");
    if !bunny.exists() {
        return Err(format!("{} not found: the fixtures are made from the shared data", bunny.display()));
    }
    let tmp = root.join("out/fixtures");
    std::fs::create_dir_all(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    let capture = tmp.join("bunny_1000ph.hdf5");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    println!("[1/2] nlos render (the shared bunny, seed setup, 1000 photons, seed 1; a few minutes)");
    nlos(&["render", &s(&bunny), "--out", &s(&capture), "--photons", "1000", "--seed", "1"])?;
    let dir = root.join("fixtures");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let start = dir.join("bunny_lct_start.obj");
    println!("[2/2] nlos init → {}", start.display());
    nlos(&["init", &s(&capture), "--out", &s(&start)])?;
    // `nlos init` writes a figure beside the mesh; the fixture is the mesh alone.
    let _ = std::fs::remove_file(start.with_extension("png"));
    Ok(())
}

fn nlos(args: &[&str]) -> Result<(), String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(workspace_root())
        .args(["run", "--quiet", "--release", "--package", "nlos-cli", "--bin", "nlos", "--"])
        .args(args)
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if status.success() { Ok(()) } else { Err(format!("`nlos {}` failed ({status})", args.join(" "))) }
}
