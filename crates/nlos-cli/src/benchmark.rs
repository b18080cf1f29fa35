//! `nlos benchmark DIR`: the field's shared benchmark — every Z-NLOS capture in DIR (NeTF's `.mat` or the
//! dataset's HDF5) that has ground-truth maps beside it, reconstructed by LCT, f-k and the surface fit
//! (`nlos reconstruct` with the default settings, or `--set` ones), each scored against the maps by
//! [`crate::eval`]'s code, as one Markdown table.
//!
//! Ground truth beside `SCENE.mat` (or `SCENE.hdf5`): `SCENE_depth.npy` or `SCENE_depth.mat` (required),
//! `SCENE_normal.npy` or `.mat` (optional), `SCENE` the capture's stem or the stem cut at an underscore
//! (`bunny_8x8.mat` is scored on `bunny_depth.mat`), laid out as published (`--gt-layout dlct`, the default) or as
//! ours, on the capture's full wall grid (as `nlos eval --wall`): the maps' first and last pixel centres on
//! the outermost points of the full scan grid, so a capture subsampled from 256 × 256 (the published 8 × 8
//! bunny) is scored on the 256 × 256 maps.

use std::path::{Path, PathBuf};
use std::time::Instant;

use nlos_mesh::map_metrics::MapMetrics;
use nlos_transient::Format;

use crate::CliError;
use crate::eval::{GtLayout, MapPlace, score_maps, truth_maps, volume_surface};
use nlos_init::Method;

/// Arguments of `nlos benchmark`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The folder of Z-NLOS captures with their ground-truth maps.
    dir: PathBuf,
    /// Where the surface fits go (one run folder per scene).
    #[arg(long, value_name = "DIR", default_value = "out/benchmark")]
    out: PathBuf,
    /// Also write the table to this Markdown file.
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    /// A setting of the surface fit, as `nlos reconstruct --set`; repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Depth tolerance of "coverage within" (metres).
    #[arg(long, default_value_t = 0.005, value_name = "METRES")]
    threshold: f64,
    /// How the map files lay out their pixels (as `nlos eval --gt-layout`): the Z-NLOS maps as published, or
    /// ours.
    #[arg(long, value_enum, default_value = "dlct")]
    gt_layout: GtLayout,
}

/// The table's header, for a coverage threshold of `threshold` metres.
fn header(threshold: f64) -> String {
    format!(
        "| scene | method | coverage within {} mm | depth error in the mask (mm) | inside (mm) | normal error (°) | \
         time (s) |\n|---|---|---|---|---|---|---|",
        1e3 * threshold
    )
}

/// A capture of the benchmark and its ground-truth maps.
struct Scene {
    name: String,
    capture: PathBuf,
    depth: PathBuf,
    normal: Option<PathBuf>,
}

/// The map `NAME_SUFFIX.npy` or `.mat` beside the capture, NAME its stem or the stem cut at an underscore
/// (`bunny_8x8.mat` finds `bunny_depth.mat`: the published maps serve every size of the capture).
fn beside(capture: &Path, suffix: &str) -> Option<PathBuf> {
    let stem = capture.file_stem()?.to_string_lossy().into_owned();
    let names = std::iter::once(stem.as_str()).chain(stem.rmatch_indices('_').map(|(i, _)| &stem[..i]));
    names
        .filter(|n| !n.is_empty())
        .flat_map(|n| ["npy", "mat"].map(|e| capture.with_file_name(format!("{n}_{suffix}.{e}"))))
        .find(|p| p.is_file())
}

fn scenes(dir: &Path) -> Result<Vec<Scene>, CliError> {
    let entries = std::fs::read_dir(dir).map_err(|e| CliError::Input(format!("{}: {e}", dir.display())))?;
    let mut files: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    files.sort();
    let mut out = Vec::new();
    for capture in files {
        let name = capture.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        if name.ends_with("_depth") || name.ends_with("_normal") {
            continue;
        }
        if !matches!(nlos_transient::detect(&capture), Ok(Format::ZNlosMat | Format::ZNlos)) {
            continue;
        }
        let Some(depth) = beside(&capture, "depth") else {
            eprintln!("{}: no {name}_depth.npy or .mat beside it; left out", capture.display());
            continue;
        };
        out.push(Scene { normal: beside(&capture, "normal"), name, capture, depth });
    }
    Ok(out)
}

fn row(scene: &str, method: &str, m: &MapMetrics, seconds: f64) -> String {
    let mm = |v: Option<f64>| v.map_or_else(|| "–".into(), |x| format!("{:.2}", 1e3 * x));
    let deg = m.normal_error_mean_deg.map_or_else(|| "–".into(), |x| format!("{x:.1} ({} px)", m.normal_pixels));
    format!(
        "| {scene} | {method} | {:.1} % | {} | {} | {deg} | {seconds:.0} |",
        100.0 * m.coverage_within,
        mm(m.depth_error_mean),
        mm(m.depth_error_mean_interior)
    )
}

/// Runs `nlos benchmark`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    let scenes = scenes(&args.dir)?;
    if scenes.is_empty() {
        return Err(CliError::Input(format!(
            "{}: no Z-NLOS capture with a SCENE_depth.npy or .mat beside it",
            args.dir.display()
        )));
    }
    let head = header(args.threshold);
    outln!("{head}");
    let mut table = vec![head];
    for s in &scenes {
        let place = MapPlace::Wall(s.capture.clone());
        let truth = truth_maps(&s.depth, s.normal.as_deref(), args.gt_layout.into(), &place)?;
        let mut score = |method: &str, mesh: &nlos_mesh::SurfaceMesh, t: f64| -> Result<(), CliError> {
            let m = score_maps(mesh, &format!("{} ({method})", s.name), &truth, args.threshold)?;
            let line = row(&s.name, method, &m, t);
            outln!("{line}");
            table.push(line);
            Ok(())
        };
        for (method, label) in [(Method::Lct, "LCT"), (Method::Fk, "f-k")] {
            let t = Instant::now();
            let mesh = volume_surface(&s.capture, method)?;
            score(label, &mesh, t.elapsed().as_secs_f64())?;
        }
        let run_dir = args.out.join(&s.name);
        let mut cmd: Vec<String> = ["nlos", "reconstruct"].map(String::from).to_vec();
        cmd.extend([s.capture.display().to_string(), "--out".into(), run_dir.display().to_string()]);
        cmd.extend(["--quiet".into(), "--no-report".into()]);
        for kv in &args.set {
            cmd.extend(["--set".into(), kv.clone()]);
        }
        let t = Instant::now();
        if crate::run(cmd) != std::process::ExitCode::SUCCESS {
            return Err(CliError::Failure(format!("the surface fit of {} failed", s.capture.display())));
        }
        let mesh = nlos_mesh::metrics::load_for_eval(run_dir.join("mesh.obj"))
            .map_err(|e| CliError::Failure(format!("{}: {e}", run_dir.display())))?;
        score("surface fit", &mesh, t.elapsed().as_secs_f64())?;
    }
    if let Some(file) = &args.table {
        std::fs::write(file, table.join("\n") + "\n")
            .map_err(|e| CliError::Failure(format!("cannot write {}: {e}", file.display())))?;
    }
    Ok(())
}
