//! Project automation.
//!
//! - `cargo xtask reconstruct [--out DIR] [--data FILE]`: the main job on the built-in scene (no arguments
//!   needed). Today it runs the stages that exist: the built-in scene's transient is synthesised, written in
//!   every writable format, read back, inspected with `nlos info` and previewed with `nlos preview`. It grows
//!   into the full reconstruction as the renderer, initialisers and optimiser land.
//! - `cargo xtask help`.

mod builtin;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("reconstruct") => reconstruct(&args[1..]),
        None | Some("help" | "--help" | "-h") => {
            println!("usage: cargo xtask reconstruct [--out DIR] [--data FILE]");
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

fn reconstruct(args: &[String]) -> Result<(), String> {
    let mut out = workspace_root().join("out/reconstruct");
    let mut data: Option<PathBuf> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--out" => out = it.next().ok_or("--out needs a directory")?.into(),
            "--data" => data = Some(it.next().ok_or("--data needs a file")?.into()),
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;

    let input = match data {
        Some(file) => file,
        None => {
            let scene = builtin::BuiltinScene::default();
            println!(
                "[1/4] built-in scene: Lambertian square, side {:.2} m, at depth {:.2} m; {}×{} confocal scan",
                2.0 * scene.half_size,
                scene.depth,
                scene.grid,
                scene.grid
            );
            let t = scene.render().map_err(|e| e.to_string())?;
            let file = out.join("builtin.hdf5");
            for (name, format) in [
                ("builtin.hdf5", nlos_transient::Format::Tal),
                ("builtin.npy", nlos_transient::Format::NpyJson),
                ("builtin.exr", nlos_transient::Format::Exr),
            ] {
                let path = out.join(name);
                nlos_transient::write(&t, &path, format).map_err(|e| e.to_string())?;
                let back = nlos_transient::read(&path).map_err(|e| e.to_string())?;
                if back != t {
                    return Err(format!("{}: read back differs from what was written", path.display()));
                }
            }
            println!("[2/4] wrote and re-read {} (TAL), builtin.npy + .json, builtin.exr: bit-exact", file.display());
            let depth = t.summed_peak_depth(None).map_err(|e| e.to_string())?;
            println!("      summed-histogram peak depth {depth:.4} m (square at {:.4} m)", scene.depth);
            file
        }
    };
    println!("[3/4] nlos info {}", input.display());
    nlos(&["info", &input.to_string_lossy()])?;
    let png = out.join("preview.png");
    println!("[4/4] nlos preview {} --out {}", input.display(), png.display());
    nlos(&["preview", &input.to_string_lossy(), "--out", &png.to_string_lossy()])?;
    println!("done: outputs in {}", out.display());
    Ok(())
}

/// Runs the `nlos` CLI (built in release mode) with `args`.
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
