//! `nlos reconstruct`: capture → initial surface (LCT, f-k or a mesh file) → optimised mesh.
//!
//! The command composes the library crates: [`nlos_init`] for the initial surface, [`nlos_optim`] for the
//! analysis-by-synthesis loop, [`nlos_mesh::io`] for the meshes, [`nlos_report`] for the report. It
//! computes nothing itself.
//!
//! The command line is saved as `DIR/command.json` so that `nlos report DIR --data DATA` regenerates the
//! report with the same preprocessing (rebinning, subsampling), renderer settings and sensor fit.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use nlos_brdf::{Fresnel, Ggx};
use nlos_init::{CarveParams, FkParams, LctParams, SurfaceParams, carve, fk, lct, volume_to_surface};
use nlos_mesh::SurfaceMesh;
use nlos_optim::{
    Hooks, Progress, ProgressEvent, ReconstructParams, Reflectance, SamplingSchedule, SensorBackground, SensorFit,
    StopReason,
};
use nlos_render::{RenderParams, Sampling, SplatRule, Visibility};
use nlos_report::ReportOptions;
use nlos_transient::Transient;
use nlos_transient::sensor::{BackgroundWindow, BinKernel, JitterResponse};

use crate::CliError;

/// Arguments of `nlos reconstruct`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The capture (any readable format).
    data: PathBuf,
    /// Output directory: `mesh.obj`, `mesh.ply` (`mesh.glb` with --glb), `init.obj`, `stage_NN.obj`,
    /// `run_log.json`, `checkpoint.json`, `command.json`, and the report `report.html` with its PNGs.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Initial surface: `lct` (extracted as by `nlos init --method lct`: the settings for compact objects),
    /// `fk`, `carve` (space carving from first returns), or a mesh file (OBJ/PLY/GLB) whose faces face the
    /// wall.
    #[arg(long, default_value = "lct", value_name = "lct|fk|carve|MESH")]
    init: String,
    /// With `--init lct|fk|carve`: turn the initial surface back toward its boundary, vertices within this
    /// distance (metres) of it receding by a quarter circle of this radius (`nlos_init::rim`; as `nlos init
    /// --rim-radius`). Off by default: on the seed-setup bunny 0.02 raised coverage 85.0 → 87.7 % and 86.1 →
    /// 87.2 % over two photon draws but also the mean depth error (1.32 → 1.47, 1.56 → 1.67 mm).
    #[arg(long, value_name = "METRES")]
    rim_radius: Option<f64>,
    /// Reflectance model to fit: `lambert` or `ggx` (α starts at --alpha).
    #[arg(long, default_value = "lambert", value_name = "lambert|ggx")]
    brdf: String,
    /// Initial GGX roughness α (with --brdf ggx).
    #[arg(long, default_value_t = 0.3)]
    alpha: f32,
    /// Seed of the run (a run is a deterministic function of its inputs and seed).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Continue the run whose checkpoint is in --out, with the same options as that run (they are in
    /// `--out`'s command.json; other settings are an error, not a silently different run).
    #[arg(long)]
    resume: bool,
    /// Coarse-to-fine stages at most (default 3; the seed's 4).
    #[arg(long)]
    stages: Option<u32>,
    /// Resolution of the first stage: target edge length 0.5 m / RES (default 48; the seed's 64).
    #[arg(long, value_name = "RES")]
    resolution: Option<f64>,
    /// Blocks per stage at most (default 4).
    #[arg(long)]
    blocks: Option<u32>,
    /// Adam steps per shape block (default 20).
    #[arg(long)]
    iterations: Option<u32>,
    /// Sum K consecutive bins of the capture before anything else (faster, coarser).
    #[arg(long, value_name = "K")]
    rebin: Option<usize>,
    /// Zero the bins that begin before this path length (metres) before fitting: the direct reflection
    /// off the wall is in no three-bounce rendering, and left in it would dominate the data term. `auto`
    /// (the default) finds where the direct light ends in the summed histogram (`nlos init`'s gate; a
    /// capture without direct light, e.g. a simulation, is left as it is), `off` keeps every bin.
    #[arg(long, value_name = "METRES|auto|off", default_value = "auto", value_parser = crate::init::parse_gate)]
    gate: nlos_init::Gate,
    /// Drop the bins whose path length exceeds 2 × this depth (metres) before anything else: for a confocal
    /// scan, everything deeper than it (late background, a far wall) is then neither fitted nor in the
    /// initial surface. `auto` (the default) does not fit the bins after the last return, where the summed
    /// histogram holds only background (`Transient::signal_end_path`, plus 5 %; a capture without
    /// background, e.g. a simulation, keeps its whole axis), and takes the initial surface from voxels up to
    /// that depth (the initial volume still sees the whole axis): left in, an L2 fit explains that
    /// background with far, large surfaces. `off` keeps the whole axis.
    #[arg(long, value_name = "METRES|auto|off", default_value = "auto", value_parser = parse_max_depth)]
    max_depth: MaxDepth,
    /// Keep every K-th scan row and column before anything else (faster, coarser).
    #[arg(long, value_name = "K")]
    subsample: Option<usize>,
    /// Visibility of the surface from the wall spots: `cached` (one shadow ray per triangle and measurement,
    /// recomputed after every remeshing; the default), `live` (per sample, slow, exact) or `off` (no
    /// occlusion: right for height fields only).
    #[arg(long, default_value = "cached", value_name = "cached|live|off")]
    visibility: String,
    /// Largest subdivision level of the renderer's closed-form time integration (`nlos_render::SplatRule`):
    /// a face is cut into at most N² sub-triangles, as many as its path length's curvature needs (large faces
    /// only; default 8).
    #[arg(long, default_value_t = 8, value_name = "N")]
    max_level: u32,
    /// Also write the final mesh as binary glTF, `mesh.glb`.
    #[arg(long)]
    glb: bool,
    /// Ground-truth mesh (OBJ/PLY/GLB): the report adds its depth map and the metrics of the initial and
    /// final meshes (as `nlos eval`).
    #[arg(long, value_name = "GT.obj")]
    gt: Option<PathBuf>,
    /// Fit photon counts (Poisson NLL of scale·J(I) + background) through this SPAD timing response: a
    /// jitter file (`JitterResponse::load`: MATLAB v7.3 `t_*`/`counts_*`, or HDF5 `counts` +
    /// `timebin_width_ps`), `ideal` for no jitter, `direct` for the capture's own response, taken from its
    /// direct reflection off the wall (`JitterResponse::from_direct_return`: real confocal captures, whose
    /// heavy response tail a plain fit explains with surfaces further back), `off` for an L2 fit on
    /// intensities, or `auto` (the default): `direct` for photon counts that hold a direct reflection (real
    /// captures), `off` otherwise (simulations, non-integer data, --temporal-blur).
    #[arg(long, value_name = "FILE|ideal|direct|off|auto", default_value = "auto")]
    sensor: String,
    /// Background of the sensor fit: expected counts per bin, or `auto` to estimate it from the bins
    /// before the first return (the default). Needs --sensor.
    #[arg(long, value_name = "COUNTS_PER_BIN|auto", requires = "sensor")]
    background: Option<String>,
    /// Learning rate of interior vertices, as a fraction of the stage's target edge length per Adam step
    /// (default 0.05).
    #[arg(long, value_name = "F")]
    lr: Option<f64>,
    /// Learning rate of boundary vertices, same unit (default 0.02).
    #[arg(long, value_name = "F")]
    lr_boundary: Option<f64>,
    /// Learning rate of the reflectance parameters θ (default 0.05).
    #[arg(long, value_name = "F")]
    lr_reflectance: Option<f64>,
    /// β of the automatic normal-smoothing weight λ = β·E_data/R at the start of each block (default 0.1).
    #[arg(long, value_name = "BETA")]
    smoothing: Option<f64>,
    /// Weight w of the boundary-smoothing term (the boundary curves' umbrella operator,
    /// `nlos_optim::boundary_smoothing`) relative to normal smoothing: the regulariser is λ(R + w·R_∂);
    /// 0 turns it off (default 1).
    #[arg(long, value_name = "W")]
    boundary_smoothing: Option<f64>,
    /// Coarse-to-fine in time: full widths at half maximum (metres of path, comma-separated, one per
    /// stage from the first) of the Gaussian blur of the rendered and measured histograms in the data term
    /// (`nlos_optim::temporal`); later stages fit the unblurred histograms. `off` (the default) blurs no
    /// stage. `0.02,0.0075` widens the pull in depth of the first two stages (seed-setup bunny, two photon
    /// draws: Chamfer distance −1 to −3 mm and normal error −1.4 to −2.1°, coverage and mean depth error
    /// within the draws' spread; the independent renderer's bunny: mean depth error +0.25 mm). L2 fits
    /// only: not with --sensor (blurred counts are not Poisson).
    #[arg(long, value_name = "METRES,...|off")]
    temporal_blur: Option<String>,
    /// Spatially varying albedo (`nlos_optim::albedo`): fit a map of the albedo over the wall plane with
    /// cells of CELL metres, alongside the shape (`off`, the default: one albedo for the whole surface). For
    /// objects with printed patterns (a resolution chart), whose dark print a uniform albedo turns into
    /// relief. The report shows the map (`albedo.png`).
    #[arg(long, value_name = "CELL|off", default_value = "off")]
    albedo_map: String,
    /// Noise of the capture, for the smoothing weight: `counts` (Poisson photon counts: λ is set against
    /// the misfit above the noise floor), `none` (λ against the whole data term, the seed's rule), or
    /// `auto` (the default): `counts` when every value is a non-negative integer. --sensor implies counts.
    #[arg(long, default_value = "auto", value_name = "auto|counts|none")]
    noise: String,
    /// Boundary vertices move only in depth, keeping the initial silhouette (by default they move freely).
    #[arg(long)]
    depth_only_boundary: bool,
    /// Keep boundary faces that no measurement can see (by default they are deleted before each remeshing).
    #[arg(long)]
    keep_unlit: bool,
    /// Boundary pruning after every block: the number of rounds (each deletes the boundary faces whose
    /// deletion lowers the data term by more than the margin, then tests the faces it exposed;
    /// `nlos_optim::prune`), or `off`.
    #[arg(long, value_name = "ROUNDS|off", default_value = "3")]
    prune: String,
    /// Margin κ of the pruning test (a face goes when ΔE < −κ·½c; 0 is the plain sign test; default 0.5).
    #[arg(long, value_name = "KAPPA", default_value_t = 0.5)]
    prune_margin: f64,
    /// Significance z of the pruning test for photon counts (a face goes when ΔE < −κ·½c − z·σ, σ the
    /// standard deviation of ΔE under Poisson noise; 0, the default, is the margin test alone). 2 keeps
    /// more of the rim and more dim spurious faces (seed-setup bunny: coverage +1.4 points, mean depth
    /// error +0.2 mm; glossy GGX α 0.2 bunny: coverage +5.3 points, normal error −0.8°). Unused for
    /// captures that are not counts (`--noise`) and with --sensor.
    #[arg(long, value_name = "Z", default_value_t = 0.0)]
    prune_significance: f64,
    /// Boundary growth after every block (after pruning): faces across the boundary edges are added where
    /// they lower the data term (`nlos_optim::grow`).
    #[arg(long)]
    grow: bool,
    /// Margin κ of the growth test (a quad is added when ΔE⁺ < −κ·½c; default 0.5).
    #[arg(long, value_name = "KAPPA", default_value_t = 0.5)]
    grow_margin: f64,
    /// Angles (degrees, comma-separated) by which growth proposals turn away from the wall (default 0,30,60).
    #[arg(long, value_name = "DEG,...", default_value = "0,30,60")]
    grow_angles: String,
    /// Grow only in the first N coarse-to-fine stages (default: every stage).
    #[arg(long, value_name = "N")]
    grow_stages: Option<u32>,
    /// Residual back-projection at the end of the first stages (--residual-stages): the LCT of the fit's residual
    /// proposes surface patches away from the mesh, added where they lower the data term
    /// (`nlos_optim::residual`; confocal grid scans only): `on` or `off`.
    #[arg(long, value_name = "on|off", default_value = "on")]
    residual: String,
    /// Residual columns closer than this to the mesh are left to the shape steps (metres; default 0.005).
    #[arg(long, value_name = "METRES", default_value_t = 0.005)]
    residual_separation: f64,
    /// Margin κ of the residual patches' test (a face joins a patch when ΔE⁺ < −κ·½c; default 0.5).
    #[arg(long, value_name = "KAPPA", default_value_t = 0.5)]
    residual_margin: f64,
    /// Tilts (degrees, comma-separated) of the residual patches' normals away from the wall normal, each
    /// tried at four azimuths besides the untilted patch (default 40,70).
    #[arg(long, value_name = "DEG,...", default_value = "40,70")]
    residual_tilts: String,
    /// Propose residual patches after each of the first N stages (the last stage never proposes; default
    /// 1: after stage 0 only, later residuals are at the noise level).
    #[arg(long, value_name = "N", default_value_t = 1)]
    residual_stages: u32,
    /// Do not write the report (`nlos report` writes it later).
    #[arg(long)]
    no_report: bool,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

/// The file in the output directory that keeps the command line of the run.
const COMMAND_FILE: &str = "command.json";

fn fail<E: std::fmt::Display>(e: E) -> CliError {
    CliError::Failure(e.to_string())
}

fn bad<E: std::fmt::Display>(e: E) -> CliError {
    CliError::Input(e.to_string())
}

/// `--max-depth`: where the time axis ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum MaxDepth {
    /// After the last return (`Transient::signal_end_path`).
    Auto,
    /// The whole axis.
    Off,
    /// At twice this depth (metres) of path.
    Depth(f64),
}

impl std::fmt::Display for MaxDepth {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Auto => f.write_str("auto (after the last return)"),
            Self::Off => f.write_str("off"),
            Self::Depth(d) => write!(f, "{d} m"),
        }
    }
}

fn parse_max_depth(s: &str) -> Result<MaxDepth, String> {
    match s {
        "auto" => Ok(MaxDepth::Auto),
        "off" | "none" => Ok(MaxDepth::Off),
        _ => s
            .parse::<f64>()
            .ok()
            .filter(|d| d.is_finite() && *d > 0.0)
            .map(MaxDepth::Depth)
            .ok_or_else(|| format!("`{s}` is not a depth in metres (finite, > 0), `auto` or `off`")),
    }
}

/// A capture as `nlos reconstruct` uses it ([`load_capture`]).
struct Capture {
    /// As read and rebinned, before the gate and `--max-depth`: it still holds the direct reflection off the
    /// wall (the capture's own response, `--sensor direct`) and the background-only bins at the end of the
    /// axis.
    read: Transient,
    /// Whether the gate zeroed the direct light.
    gated: bool,
    /// After the gate and `--max-depth` (the volumetric initialisers work on any bins).
    full: Transient,
    /// `full` cut at `--max-depth auto` and subsampled: what the optimiser fits.
    measured: Transient,
    /// The depth beyond which the initial surface takes no voxel (`--max-depth auto`).
    surface_depth: Option<f64>,
}

/// The capture at each step of its preparation ([`Capture`]).
///
/// `--max-depth auto` drops the late bins from the fitted data only: the initial volume is reconstructed
/// from the whole axis and its surface is cut at the depth instead. The LCT's volume depends on the
/// length of the axis it resamples (a simulation of the bunny with 0.01 background counts per bin, cut
/// after its last return at 0.57 m, gave an initial surface with a mean depth error of 9.6 mm against
/// 8.5 mm from the whole axis, and a fit of 7.3 against 5.8 mm).
fn load_capture(args: &Args) -> Result<Capture, CliError> {
    let mut read = nlos_transient::read(&args.data).map_err(CliError::input)?;
    if let Some(k) = args.rebin {
        read = read.rebin(k).map_err(CliError::input)?;
    }
    let gate = args.gate.path(&read).map_err(bad)?.filter(|g| *g > read.time().t0);
    let mut full = match gate {
        Some(g) => read.gate(g).map_err(CliError::input)?,
        None => read.clone(),
    };
    let mut fitted = None;
    let mut surface_depth = None;
    match args.max_depth {
        MaxDepth::Off => {}
        MaxDepth::Depth(d) => {
            let t0 = full.time().t0;
            full = full.crop_path(t0, 2.0 * d).map_err(|e| bad(format!("--max-depth {d}: {e}")))?;
        }
        MaxDepth::Auto => {
            let ax = *full.time();
            let end = full.signal_end_path(gate.unwrap_or(ax.t0));
            if end < ax.end() {
                let confocal = full.scan().is_confocal();
                let depth = if confocal { format!(" (depth {:.4} m)", end / 2.0) } else { String::new() };
                eprintln!(
                    "--max-depth auto: the last return ends at {end:.4} m of path{depth}; the {} later bins hold \
                     only background and are not fitted (--max-depth off keeps them)",
                    ax.bins - ((end - ax.t0) / ax.bin_width).ceil() as usize,
                );
                fitted = Some(full.crop_path(ax.t0, end).map_err(|e| bad(format!("--max-depth auto: {e}")))?);
                surface_depth = confocal.then_some(end / 2.0);
            }
        }
    }
    let fitted = fitted.unwrap_or_else(|| full.clone());
    let measured = match args.subsample {
        Some(k) => fitted.subsample(k, k).map_err(CliError::input)?,
        None => fitted,
    };
    Ok(Capture { read, gated: gate.is_some(), full, measured, surface_depth })
}

/// The ground truth of `--gt` (non-manifold meshes accepted, as by `nlos eval`).
fn load_gt(args: &Args) -> Result<Option<SurfaceMesh>, CliError> {
    args.gt
        .as_ref()
        .map(|p| nlos_mesh::metrics::load_for_eval(p).map_err(|e| bad(format!("--gt {}: {e}", p.display()))))
        .transpose()
}

/// Runs `nlos reconstruct`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    let capture = load_capture(args)?;
    let params = params(args, &capture)?;
    let (full, measured, surface_depth) = (capture.full, capture.measured, capture.surface_depth);
    let gt = load_gt(args)?;
    std::fs::create_dir_all(&args.out).map_err(|e| fail(format!("{}: {e}", args.out.display())))?;
    let argv: Vec<String> = std::env::args_os().map(|a| a.to_string_lossy().into_owned()).collect();
    let command = serde_json::json!({ "argv": argv }).to_string();
    std::fs::write(args.out.join(COMMAND_FILE), command).map_err(|e| fail(format!("{}: {e}", args.out.display())))?;
    let bar = (!args.quiet).then(|| progress_bar(&params));
    let mut on_progress = |p: &Progress| {
        if let Some(bar) = &bar {
            bar.set_length(p.iterations_planned.max(1));
            bar.set_position(p.iteration);
            bar.set_message(format!(
                "stage {}/{} · loss {:.4e} · {} faces · L {:.1} mm",
                p.stage + 1,
                p.max_stages,
                p.loss,
                p.faces,
                p.target_edge_length * 1e3
            ));
            if p.event == ProgressEvent::BlockEnd {
                bar.tick();
            }
        }
        ControlFlow::Continue(())
    };
    let hooks = Hooks { progress: Some(&mut on_progress), evolve: None };
    let outcome = if args.resume {
        nlos_optim::resume(&measured, &params, hooks).map_err(|e| match e {
            // Real captures default to their own response since `--sensor auto` (2026-11-25): a run started
            // before, by L2, resumes with `--sensor off`.
            nlos_optim::OptimError::SettingsChanged { .. } if args.sensor == "auto" && params.sensor.is_some() => {
                bad(format!(
                    "{e} (this capture is fitted through its own response by default, `--sensor auto`; a run \
                     started by an earlier version fitted it by L2 and resumes with `--sensor off`)"
                ))
            }
            e => bad(e),
        })?
    } else {
        // The initial surface from the whole scan grid: --subsample trades the optimiser's lateral
        // sampling for speed, but a volumetric reconstruction from the subsampled grid is blurred twice as
        // wide (on the seed-setup bunny at --subsample 2: mean depth error 8.3 mm and 4,088 evaluation
        // pixels, against 5.2 mm and 2,866 from the full grid).
        let init = initial_surface(args, &full, surface_depth)?;
        save(&init, &args.out.join("init.obj"))?;
        nlos_optim::reconstruct_with(&measured, &init, &params, hooks).map_err(bad)?
    };
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    if args.glb {
        save(&outcome.mesh, &args.out.join("mesh.glb"))?;
    }
    let last = outcome.log.iterations.last();
    println!(
        "{}: {} faces, {} vertices after {} blocks (stage {}); loss {:.4e}; scale {:.4e}; stop: {}",
        args.out.join("mesh.obj").display(),
        outcome.mesh.n_faces(),
        outcome.mesh.n_vertices(),
        outcome.blocks_done,
        outcome.stage + 1,
        last.map_or(f64::NAN, |r| r.loss),
        outcome.scale,
        match outcome.stop {
            StopReason::MaxStages => "all stages ran",
            StopReason::FaceLimit => "face limit",
            StopReason::Interrupted => "interrupted (resume with --resume)",
        }
    );
    if outcome.stop != StopReason::Interrupted && !args.no_report {
        write_report(args, &measured, wall_area(&full), &params, gt.as_ref()).map_err(|e| match e {
            CliError::Input(m) | CliError::Failure(m) => {
                CliError::Failure(format!("the mesh is written, but not the report: {m}"))
            }
        })?;
    }
    Ok(())
}

/// Writes the report of the run in `args.out` ([`nlos_report::write_report`]) and prints where.
fn write_report(
    args: &Args,
    measured: &Transient,
    area: Option<([f32; 2], [f32; 2])>,
    params: &ReconstructParams,
    gt: Option<&SurfaceMesh>,
) -> Result<(), CliError> {
    let opts = ReportOptions { area, ..report_options(args, params) };
    let report = nlos_report::write_report(&args.out, measured, gt, &opts).map_err(|e| match e {
        nlos_report::ReportError::MissingFile { .. } | nlos_report::ReportError::Json { .. } => bad(e),
        other => fail(other),
    })?;
    println!("{}: {} figures", report.html.display(), report.images.len());
    Ok(())
}

/// `nlos report DIR --data DATA [--gt GT]`: the report of the run in `dir`, with the command line saved in
/// `dir/command.json` (its data file and ground truth replaced by `data` and `gt`), or the defaults when
/// there is none.
pub(crate) fn report_for_run(dir: &Path, data: &Path, gt: Option<&Path>) -> Result<(), CliError> {
    let file = dir.join(COMMAND_FILE);
    let argv: Vec<String> = match std::fs::read(&file) {
        Ok(bytes) => {
            let v: serde_json::Value =
                serde_json::from_slice(&bytes).map_err(|e| bad(format!("{}: {e}", file.display())))?;
            v["argv"]
                .as_array()
                .map(|a| a.iter().filter_map(|x| x.as_str().map(String::from)).collect())
                .ok_or_else(|| bad(format!("{}: no `argv` list", file.display())))?
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            ["nlos", "reconstruct", "-", "--out", "-"].map(String::from).to_vec()
        }
        Err(e) => return Err(fail(format!("{}: {e}", file.display()))),
    };
    let cli = <crate::Cli as clap::Parser>::try_parse_from(&argv)
        .map_err(|e| bad(format!("{}: the saved command line does not parse: {e}", file.display())))?;
    let crate::Command::Reconstruct(mut args) = cli.command else {
        return Err(bad(format!("{}: not an `nlos reconstruct` command line", file.display())));
    };
    args.data = data.to_owned();
    args.out = dir.to_owned();
    if let Some(g) = gt {
        args.gt = Some(g.to_owned());
    }
    let capture = load_capture(&args)?;
    let params = params(&args, &capture)?;
    let gt = load_gt(&args)?;
    write_report(&args, &capture.measured, wall_area(&capture.full), &params, gt.as_ref())
}

/// The wall rectangle of the report's depth maps and metrics: the bounding rectangle of the whole capture's
/// sensor points, before `--subsample` (the seed setup's [−0.25, 0.25]², as `nlos eval`), as
/// [`nlos_report::DepthView::over_scan`] takes it; `None` when they span no rectangle (the report then
/// tries the fitted grid's, and says why it cannot).
fn wall_area(full: &Transient) -> Option<([f32; 2], [f32; 2])> {
    nlos_report::DepthView::over_scan(full, 1).ok().map(|v| (v.x_range, v.y_range))
}

/// The report's settings: the run's renderer settings, data term and sensor fit, and its command line.
fn report_options(args: &Args, params: &ReconstructParams) -> ReportOptions {
    let sampling = match params.sampling {
        SamplingSchedule::Splat(rule) => Sampling::Splat(rule),
        SamplingSchedule::Deterministic(rule) => Sampling::Deterministic(rule),
        SamplingSchedule::Stratified { initial_samples, .. } => {
            Sampling::Stratified { samples_per_measurement: initial_samples, seed: params.seed }
        }
    };
    let name = args.data.file_name().map_or_else(|| args.data.display().to_string(), |n| n.to_string_lossy().into());
    let opt = |v: Option<String>| v.unwrap_or_else(|| "default".into());
    let parameters = vec![
        ("data", args.data.display().to_string()),
        ("initial surface (--init)", args.init.clone()),
        (
            "reflectance (--brdf)",
            if args.brdf == "ggx" { format!("ggx, alpha0 {}", args.alpha) } else { args.brdf.clone() },
        ),
        ("seed", args.seed.to_string()),
        ("stages", opt(args.stages.map(|v| v.to_string()))),
        ("first-stage resolution", opt(args.resolution.map(|v| v.to_string()))),
        ("blocks per stage", opt(args.blocks.map(|v| v.to_string()))),
        ("shape iterations per block", opt(args.iterations.map(|v| v.to_string()))),
        ("rebin", opt(args.rebin.map(|v| v.to_string()))),
        ("subsample", opt(args.subsample.map(|v| v.to_string()))),
        ("gate", format!("{:?}", args.gate)),
        ("max depth", args.max_depth.to_string()),
        ("visibility", args.visibility.clone()),
        ("quadrature max level", args.max_level.to_string()),
        ("sensor", if params.sensor.is_some() { args.sensor.clone() } else { format!("{} (L2 fit)", args.sensor) }),
        ("background", opt(args.background.clone())),
        (
            "temporal blur (FWHM per stage, m of path)",
            if params.temporal_blur.is_empty() {
                "off".into()
            } else {
                params.temporal_blur.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
            },
        ),
        ("albedo map (cell, m)", args.albedo_map.clone()),
        ("ground truth", opt(args.gt.as_ref().map(|p| p.display().to_string()))),
        ("resumed", args.resume.to_string()),
    ];
    ReportOptions {
        title: format!("nlos reconstruct {name}"),
        parameters: parameters.into_iter().map(|(k, v)| (k.to_string(), v)).collect(),
        render: RenderParams { sampling, ..params.render },
        loss: params.data.loss,
        sensor: params.sensor.clone(),
        ..ReportOptions::default()
    }
}

/// The sensor fit of `--sensor` / `--background` on the capture's bins.
fn sensor_fit(args: &Args, capture: &Capture) -> Result<Option<SensorFit>, CliError> {
    let (measured, raw, gated) = (&capture.measured, &capture.read, capture.gated);
    let sensor = args.sensor.as_str();
    if sensor == "off" {
        return Ok(None);
    }
    let blur = args.temporal_blur.as_deref().is_some_and(|w| w != "off");
    // `auto` resolved to L2: an explicit --background would be silently dropped, so it is an error.
    let l2 = || match &args.background {
        Some(b) => Err(bad(format!(
            "--background {b} with --sensor auto: {} is fitted by L2 here (not photon counts with a direct \
             reflection, or --temporal-blur), which has no background; give --sensor ideal, direct or a \
             response file for a sensor fit",
            args.data.display()
        ))),
        None => Ok(None),
    };
    if sensor == "auto" && (blur || !nlos_transient::sensor::is_integer_counts(measured.data())) {
        return l2();
    }
    // `auto`: the capture's own response when it holds one (a direct reflection, which the gate removed).
    let direct = match sensor {
        "auto" => match gated.then(|| JitterResponse::from_direct_return(raw).ok()).flatten() {
            Some(r) => Some(r),
            None => return l2(),
        },
        "direct" => Some(
            JitterResponse::from_direct_return(raw)
                .map_err(|e| bad(format!("--sensor direct: {}: {e}", args.data.display())))?,
        ),
        _ => None,
    };
    let background = match args.background.as_deref() {
        None | Some("auto") if gated => {
            // A gated capture's zeroed direct light is not background, and --max-depth may have cut the
            // background-only bins: estimate on the capture as read (`Auto` falls back to the last 10 % of its
            // axis when the direct light leaves no bins before the first return).
            let est = nlos_transient::sensor::estimate_background(raw, BackgroundWindow::Auto).map_err(bad)?;
            if !args.quiet {
                eprintln!(
                    "--background auto: {:.4} counts per bin (bins {}..{} of the capture before the gate)",
                    est.per_bin, est.window.0, est.window.1
                );
            }
            SensorBackground::Fixed(est.per_bin.max(0.0))
        }
        None | Some("auto") => SensorBackground::Estimate(BackgroundWindow::Auto),
        Some(v) => match v.parse::<f64>() {
            Ok(b) if b.is_finite() && b >= 0.0 => SensorBackground::Fixed(b),
            _ => return Err(bad(format!("--background `{v}`: expected counts per bin (finite, >= 0) or `auto`"))),
        },
    };
    let bin_width = measured.time().bin_width;
    if let Some(response) = direct {
        if !args.quiet {
            eprintln!(
                "--sensor {sensor}: fitting the counts through the capture's own response (its direct reflection: \
                 FWHM {:.1} ps, mean delay {:.1} mm of path, {:.0} mm long); --sensor off fits intensities by L2",
                response.fwhm_ps(),
                response.mean_delay() * 1e3,
                response.weights().len() as f64 * response.spacing() * 1e3
            );
        }
        return Ok(Some(SensorFit::from_jitter(&response, bin_width, background).map_err(bad)?));
    }
    Ok(Some(match sensor {
        "ideal" => SensorFit { kernel: BinKernel::identity(), background },
        file => {
            let response = JitterResponse::load(file).map_err(|e| bad(format!("--sensor {file}: {e}")))?;
            SensorFit::from_jitter(&response, bin_width, background).map_err(bad)?
        }
    }))
}

/// The optimiser's parameters from the arguments (documented defaults otherwise).
fn params(args: &Args, capture: &Capture) -> Result<ReconstructParams, CliError> {
    let measured = &capture.measured;
    let mut p = ReconstructParams { seed: args.seed, out_dir: Some(args.out.clone()), ..ReconstructParams::default() };
    // Checked whatever the model, so a typo never silently runs a long reconstruction with another α.
    if !(1e-3..=1.0).contains(&args.alpha) {
        return Err(bad(format!("--alpha {}: GGX roughness must lie in [0.001, 1]", args.alpha)));
    }
    p.reflectance = match args.brdf.as_str() {
        "lambert" | "lambertian" => Reflectance::default(),
        "ggx" => Reflectance::from_ggx(&Ggx::new(0.0, 1.0, args.alpha, Fresnel::One).map_err(bad)?),
        other => return Err(bad(format!("--brdf `{other}`: expected `lambert` or `ggx`"))),
    };
    p.render.visibility = match args.visibility.as_str() {
        "cached" => Visibility::Cached { level: 1 },
        "live" => Visibility::Live,
        "off" => Visibility::Off,
        other => return Err(bad(format!("--visibility `{other}`: expected `cached`, `live` or `off`"))),
    };
    if args.max_level == 0 {
        return Err(bad("--max-level must be at least 1"));
    }
    if args.max_level > 64 {
        return Err(bad(format!("--max-level {}: at most 64", args.max_level)));
    }
    p.sampling = SamplingSchedule::Splat(SplatRule { max_level: args.max_level, ..SplatRule::default() });
    if let Some(s) = args.stages {
        p.schedule.max_stages = s;
    }
    if let Some(r) = args.resolution {
        p.schedule.initial_resolution = r;
    }
    if let Some(b) = args.blocks {
        p.schedule.max_blocks_per_stage = b;
    }
    if let Some(i) = args.iterations {
        p.schedule.shape_iterations = i;
    }
    if let Some(x) = args.lr {
        p.lr_interior = x;
    }
    if let Some(x) = args.lr_boundary {
        p.lr_boundary = x;
    }
    if let Some(x) = args.lr_reflectance {
        p.lr_reflectance = x;
    }
    if let Some(x) = args.smoothing {
        p.regulariser_ratio = x;
    }
    if let Some(x) = args.boundary_smoothing {
        p.boundary_smoothing = x;
    }
    p.data.counts = match args.noise.as_str() {
        "auto" => nlos_transient::sensor::is_integer_counts(measured.data()),
        "counts" => true,
        "none" => false,
        other => return Err(bad(format!("--noise `{other}`: expected `auto`, `counts` or `none`"))),
    };
    p.remove_unlit_boundary_faces = !args.keep_unlit;
    let angles = numbers("--grow-angles", &args.grow_angles)?;
    p.grow = args.grow.then_some(nlos_optim::GrowParams { angles, margin: args.grow_margin, stages: args.grow_stages });
    p.prune = match args.prune.as_str() {
        "off" => None,
        n => match n.parse::<u32>() {
            Ok(rounds) if rounds > 0 => Some(nlos_optim::PruneParams {
                rounds,
                margin: args.prune_margin,
                significance: args.prune_significance,
                ..nlos_optim::PruneParams::default()
            }),
            _ => return Err(bad(format!("--prune `{n}`: expected `off` or a number of rounds ≥ 1"))),
        },
    };
    p.residual = match args.residual.as_str() {
        "off" => None,
        "on" => Some(nlos_optim::ResidualParams {
            separation: args.residual_separation,
            stages: Some(args.residual_stages),
            margin: args.residual_margin,
            tilts: numbers("--residual-tilts", &args.residual_tilts)?,
            ..nlos_optim::ResidualParams::default()
        }),
        r => return Err(bad(format!("--residual `{r}`: expected `on` or `off`"))),
    };
    p.boundary_depth_only = args.depth_only_boundary;
    p.sensor = sensor_fit(args, capture)?;
    p.temporal_blur = match args.temporal_blur.as_deref() {
        None => p.temporal_blur,
        Some(w) if p.sensor.is_some() && w != "off" => {
            return Err(bad(format!(
                "--temporal-blur {w} with --sensor: the sensor fit's Poisson likelihood needs the raw counts \
                 (blurred counts are not Poisson); leave --temporal-blur out"
            )));
        }
        Some("off") => Vec::new(),
        Some(list) => numbers("--temporal-blur", list)?,
    };
    p.albedo_map = match args.albedo_map.as_str() {
        "off" => None,
        c => Some(nlos_optim::AlbedoMapParams {
            cell: c
                .parse()
                .map_err(|e| bad(format!("--albedo-map `{c}`: expected `off` or a cell size in metres: {e}")))?,
            ..nlos_optim::AlbedoMapParams::default()
        }),
    };
    p.validate().map_err(bad)?;
    Ok(p)
}

/// A comma-separated list of numbers (`--grow-angles` and `--residual-tilts` in degrees, `--temporal-blur`
/// in metres); their ranges are checked by the parameters' `validate`.
fn numbers(flag: &str, list: &str) -> Result<Vec<f64>, CliError> {
    list.split(',')
        .map(|a| a.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| bad(format!("{flag} `{list}`: {e}")))
}

/// The initial surface: a volumetric reconstruction turned into a mesh, or a mesh file.
fn initial_surface(
    args: &Args,
    measured: &nlos_transient::Transient,
    max_depth: Option<f64>,
) -> Result<SurfaceMesh, CliError> {
    let volume = match args.init.as_str() {
        "lct" => lct(measured, &LctParams::default()).map_err(bad)?,
        "fk" => fk(measured, &FkParams::default()).map_err(bad)?,
        "carve" => carve(measured, &CarveParams::default()).map_err(bad)?,
        file if args.rim_radius.is_some() => {
            return Err(bad(format!(
                "--rim-radius shapes the initial surface that --init lct|fk|carve extracts; the mesh {file} is \
                 used as given (round its rim with `nlos init --rim-radius` or leave the option out)"
            )));
        }
        file => return nlos_mesh::io::load(file).map_err(bad),
    };
    // LCT's volume gets the settings for compact objects, as `nlos init --method lct` without a threshold:
    // Otsu's threshold alone keeps only the brightest columns (about half the bunny's silhouette).
    let mut surface_params = if args.init == "lct" { SurfaceParams::object() } else { SurfaceParams::default() };
    surface_params.max_depth = surface_params.max_depth.or(max_depth);
    surface_params.rim_radius = args.rim_radius;
    let surface = volume_to_surface(&volume, &surface_params).map_err(bad)?;
    Ok(surface.mesh)
}

fn save(mesh: &SurfaceMesh, path: &Path) -> Result<(), CliError> {
    nlos_mesh::io::save(mesh, path).map_err(fail)
}

fn progress_bar(params: &ReconstructParams) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(u64::from(params.schedule.shape_iterations.max(1)));
    let style = indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} ETA {eta} · {msg}")
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> ");
    bar.set_style(style);
    bar
}
