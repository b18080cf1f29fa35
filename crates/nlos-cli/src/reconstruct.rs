//! `nlos reconstruct`: capture → initial surface (LCT, f-k, phasor field, carving or a mesh file) → optimised mesh.
//!
//! The command parses, calls [`nlos_optim::pipeline`] (capture preparation, every `auto` decision, the
//! initial surface, the run directory: [`pipeline::run`]), and prints. Every setting lives in
//! [`nlos_optim::pipeline::Config`]: `--print-config` writes the defaults as TOML, `--config FILE` reads
//! them back, `--set KEY=VALUE` changes one; the flags below are shorthands for the settings changed most.
//!
//! The run directory is the library's ([`pipeline::run`]); its settings are saved as `DIR/settings.toml`, so that `--resume` and `nlos report DIR --data DATA`
//! use exactly the settings of the run.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use nlos_brdf::Model;
use nlos_mesh::SurfaceMesh;
use nlos_optim::pipeline::{self, Config, InitMethod, Prepared, SensorChoice, Start};
use nlos_optim::{Hooks, IntersectionCheck, Progress, ProgressEvent, ReconstructParams, StopReason};
use nlos_report::ReportOptions;

use crate::CliError;
use crate::choices::brdf_parser;

/// Arguments of `nlos reconstruct`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The capture (any readable format).
    #[arg(required_unless_present = "print_config")]
    data: Option<PathBuf>,
    /// Output directory: `mesh.obj`, `mesh.ply` (`mesh.glb` with --glb), `init.obj`, `stage_NN.obj`,
    /// `run_log.json`, `checkpoint.json`, `settings.toml`, and the report `report.html` with its PNGs.
    #[arg(long, value_name = "DIR", required_unless_present = "print_config")]
    out: Option<PathBuf>,
    /// Settings file (TOML, as `--print-config` writes it; absent fields keep their defaults). With
    /// `--resume` the run's own `DIR/settings.toml` is the default.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Print the settings (the defaults, or those of --config and the other options) as TOML and exit.
    #[arg(long)]
    print_config: bool,
    /// Change one setting: `KEY=VALUE` with KEY as in `--print-config` (`schedule.max_stages=2`,
    /// `capture.gate=0.3`); repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Initial surface: `auto` (the light-cone transform on a confocal scan on a regular grid, the phasor
    /// field on any other scan; the choice and why go to the log and `settings.toml`), a method of `nlos init
    /// --method` by name (`lct`, `pf`, …: `nlos init --help` lists them), or a mesh file (OBJ/PLY/GLB) whose
    /// faces face the wall [default: auto].
    #[arg(long, value_name = "auto|METHOD|MESH")]
    init: Option<InitMethod>,
    /// Reflectance model to fit (GGX's α starts at `reflectance.alpha`; `retroreflective` also weights the
    /// LCT start for a 1/r² return, as the Stanford captures' reference code does for every scene but the
    /// diffuse S) [default: lambert].
    #[arg(long, value_parser = brdf_parser())]
    brdf: Option<Model>,
    /// Fit photon counts through this SPAD timing response: a jitter file, `ideal` for no jitter, `direct`
    /// for the capture's own (its direct reflection off the wall), `off` for an L2 fit of intensities, or
    /// `auto`: `direct` for photon counts that hold a direct reflection (real captures); on a capture gated
    /// before it reached us (counts, or counts scaled by a constant), its first strong returns with the start
    /// surface's spread taken out; `off` otherwise [default: auto].
    #[arg(long, value_name = "auto|off|ideal|direct|FILE")]
    sensor: Option<SensorChoice>,
    /// Bin width in picoseconds, for captures whose files do not store it: general-NLOS `data.mat` +
    /// `setup.mat` (32 ps in the published experiment); `capture.bin_width_ps` [default: the file's].
    #[arg(long, value_name = "PS")]
    bin_width_ps: Option<f64>,
    /// Sum K consecutive bins of the capture before anything else (faster, coarser) [default: 1].
    #[arg(long, value_name = "K")]
    rebin: Option<usize>,
    /// Fit every K-th scan row and column (faster, coarser; the initial surface sees them all) [default: 1].
    #[arg(long, value_name = "K")]
    subsample: Option<usize>,
    /// Seed of the run (a run is a deterministic function of its inputs and seed) [default: 0].
    #[arg(long)]
    seed: Option<u64>,
    /// Continue the run whose checkpoint is in --out, with its settings (`DIR/settings.toml`); a changed
    /// setting is an error that names it.
    #[arg(long)]
    resume: bool,
    /// Ground-truth mesh (OBJ/PLY/GLB): the report adds its depth map and the metrics of the initial and
    /// final meshes (as `nlos eval`).
    #[arg(long, value_name = "GT.obj")]
    gt: Option<PathBuf>,
    /// Also write the final mesh as binary glTF, `mesh.glb`.
    #[arg(long)]
    glb: bool,
    /// Do not write the report (`nlos report` writes it later).
    #[arg(long)]
    no_report: bool,
    /// Hide the progress (a bar on a terminal, one line per block in a log), the sensor fit's and the device's
    /// description (what `auto` cut from the capture is still said).
    #[arg(long)]
    quiet: bool,
}

/// The file in the output directory that keeps the command line and the ground truth of the run.
const COMMAND_FILE: &str = "command.json";

fn fail<E: std::fmt::Display>(e: E) -> CliError {
    CliError::Failure(e.to_string())
}

fn bad<E: std::fmt::Display>(e: E) -> CliError {
    CliError::Input(e.to_string())
}

/// A library error as bad input, with the flag of this command that a refused start asks for.
fn optim_error(e: nlos_optim::OptimError) -> CliError {
    match &e {
        nlos_optim::OptimError::Init(
            nlos_init::InitError::NotConfocal { .. } | nlos_init::InitError::NotGrid { .. },
        ) => bad(format!("{e} (`--init pf`, or leave --init out: `auto` chooses the phasor field for this capture)")),
        _ => bad(e),
    }
}

/// The settings of the run: `--config` (or, resuming, the run's own), then `--set`, then the flags.
fn config(args: &Args) -> Result<Config, CliError> {
    let saved = match (&args.out, args.resume, &args.config) {
        (Some(dir), true, None) => pipeline::saved_config(dir).map_err(bad)?,
        _ => None,
    };
    let mut config = match (&args.config, saved) {
        (Some(file), _) => Config::load(file).map_err(bad)?,
        (None, Some(saved)) => saved,
        (None, None) => Config::default(),
    };
    if !args.set.is_empty() {
        config = with_settings(&config, &args.set)?;
    }
    if let Some(init) = &args.init {
        config.init = init.clone();
    }
    if let Some(brdf) = args.brdf {
        config.reflectance.model = brdf;
    }
    if let Some(sensor) = &args.sensor {
        config.sensor.response = sensor.clone();
    }
    if let Some(ps) = args.bin_width_ps {
        config.capture.bin_width_ps = pipeline::Setting::Value(ps);
    }
    if let Some(k) = args.rebin {
        config.capture.rebin = k;
    }
    if let Some(k) = args.subsample {
        config.capture.subsample = k;
    }
    if let Some(seed) = args.seed {
        config.seed = seed;
    }
    Ok(config)
}

/// `config` with `--set KEY=VALUE` applied ([`Config::overridden`]): VALUE is read as a TOML value (a
/// number, `true`, a list), or as a string when it is not one; KEY's dots name its sections.
fn with_settings(config: &Config, set: &[String]) -> Result<Config, CliError> {
    let mut overrides = toml::Table::new();
    for kv in set {
        let Some((key, value)) = kv.split_once('=') else {
            return Err(bad(format!("--set {kv}: expected KEY=VALUE (keys as `nlos reconstruct --print-config`)")));
        };
        let value = format!("v = {value}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(value.to_owned()));
        let mut node = &mut overrides;
        let mut parts = key.trim().split('.').peekable();
        while let Some(part) = parts.next() {
            if parts.peek().is_none() {
                node.insert(part.to_owned(), value.clone());
            } else {
                let entry = node.entry(part.to_owned()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
                node = match entry {
                    toml::Value::Table(t) => t,
                    _ => return Err(bad(format!("--set {kv}: `{part}` is set as a value by another --set"))),
                };
            }
        }
    }
    config.overridden(overrides).map_err(|e| bad(format!("--set: {e}")))
}

/// Runs `nlos reconstruct`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    let config = config(args)?;
    if args.print_config {
        outln!("{}", config.to_toml().map_err(bad)?.trim_end());
        return Ok(());
    }
    let (Some(data), Some(out)) = (&args.data, &args.out) else {
        return Err(bad("give the capture and --out DIR"));
    };
    if args.resume {
        pipeline::check_resumable(out).map_err(|e| bad(format!("--resume: {e}")))?;
    }
    let prepared = Prepared::load(data, &config).map_err(optim_error)?;
    let params = prepared.params(&config, Some(out.clone())).map_err(optim_error)?;
    if !args.quiet {
        let full = &prepared.full;
        eprintln!(
            "capture: {}; {}; {}",
            full.scan().describe(),
            full.time().describe(),
            nlos_transient::Quantity::of(full.data()).noun()
        );
    }
    for note in &prepared.notes {
        eprintln!("{note}");
    }
    if !args.quiet {
        eprintln!("sensor: {}", prepared.describe_sensor(&config, &params));
        eprintln!("device: {}", nlos_optim::describe_device(&params));
    }
    let gt = load_gt(args.gt.as_deref())?;
    std::fs::create_dir_all(out).map_err(|e| fail(format!("{}: {e}", out.display())))?;
    let mut reporter = Reporter::new(args.quiet, &params);
    let mut on_progress = |p: &Progress| {
        reporter.update(p);
        ControlFlow::Continue(())
    };
    let hooks = Hooks { progress: Some(&mut on_progress), evolve: None };
    let start = if args.resume { Start::Resume } else { Start::New };
    if start == Start::New {
        write_command(args, out)?;
    }
    let outcome = pipeline::run(&prepared, &config, &params, start, hooks).map_err(optim_error)?;
    reporter.finish();
    if args.glb {
        save(&outcome.mesh, &out.join("mesh.glb"))?;
    }
    let last = outcome.log.iterations.last();
    outln!(
        "{}: {} faces, {} vertices after {} blocks in {} stages; loss {:.4e}; scale {:.4e}; stop: {}",
        out.join("mesh.obj").display(),
        outcome.mesh.n_faces(),
        outcome.mesh.n_vertices(),
        outcome.blocks_done,
        outcome.log.stages.len(),
        last.map_or(f64::NAN, |r| r.loss),
        outcome.scale,
        match outcome.stop {
            StopReason::MaxStages => "all stages ran",
            StopReason::FaceLimit => "face limit",
            StopReason::TimeBudget => "time budget",
            StopReason::Interrupted => "interrupted (resume with --resume)",
        }
    );
    if let Some(fit) = &outcome.log.fit {
        outln!("fit: the surface {}", fit.describe());
    }
    if let Some(choice) = pipeline::saved_choice(out).map_err(optim_error)? {
        outln!("start: {choice}; the other's run: {}", out.join(pipeline::CANDIDATES_DIR).display());
    }
    let coarsened: Vec<String> = outcome
        .log
        .stages
        .iter()
        .filter(|r| r.edge_length > r.schedule_edge_length * (1.0 + 1e-9))
        .map(|r| {
            format!(
                "stage {} at {:.1} mm (schedule {:.1} mm)",
                r.stage,
                1e3 * r.edge_length,
                1e3 * r.schedule_edge_length
            )
        })
        .collect();
    if !coarsened.is_empty() {
        outln!(
            "budget: {} edges, so that every stage ran whole within schedule.reference_seconds = {} (seconds of \
             the 2-core reference machine, predicted from face counts)",
            coarsened.join(", "),
            params.schedule.reference_seconds
        );
    }
    // Collision handling should leave the checks after the start nothing to find (nlos_optim::reconstruct).
    let found: Vec<String> = outcome
        .log
        .intersections
        .iter()
        .filter(|r| r.check != IntersectionCheck::Start && r.pairs > 0)
        .map(|r| format!("stage {} block {}: {} pairs", r.stage, r.block, r.pairs))
        .collect();
    if !found.is_empty() {
        eprintln!(
            "warning: the surface intersected itself after the start ({}); the faces were deleted \
             (run_log.json \"intersections\"; stages and blocks numbered from 0, as there and in stage_NN.obj)",
            found.join(", ")
        );
    }
    if outcome.stop != StopReason::Interrupted && !args.no_report {
        let run = Run { data, out, config: &config, resumed: args.resume };
        write_report(&run, &prepared, &params, gt.as_ref()).map_err(|e| match e {
            CliError::Input(m) | CliError::Failure(m) => {
                CliError::Failure(format!("the mesh is written, but not the report: {m}"))
            }
            CliError::Closed => CliError::Closed,
        })?;
    }
    // Everything is written; a run that kept almost no surface, or whose surface explains no more of the
    // capture than an empty scene, still ends as a failure, saying why.
    outcome.check_surface_kept().map_err(|e| CliError::Failure(e.to_string()))?;
    outcome.check_explains().map_err(|e| CliError::Failure(e.to_string()))
}

/// Writes `command.json` (the run's command line and ground truth) in the output directory; the library
/// writes the rest ([`pipeline::run`]).
fn write_command(args: &Args, out: &Path) -> Result<(), CliError> {
    let path = out.join(COMMAND_FILE);
    let argv: Vec<String> = std::env::args_os().map(|a| a.to_string_lossy().into_owned()).collect();
    let gt = args.gt.as_ref().map(|p| p.display().to_string());
    std::fs::write(&path, serde_json::json!({ "argv": argv, "gt": gt }).to_string())
        .map_err(|e| fail(format!("{}: {e}", path.display())))
}

/// The ground truth of `--gt` (non-manifold meshes accepted, as by `nlos eval`).
fn load_gt(gt: Option<&Path>) -> Result<Option<SurfaceMesh>, CliError> {
    gt.map(|p| nlos_mesh::metrics::load_for_eval(p).map_err(|e| bad(format!("--gt {}: {e}", p.display())))).transpose()
}

/// What the report says about the run.
struct Run<'a> {
    data: &'a Path,
    out: &'a Path,
    config: &'a Config,
    resumed: bool,
}

/// Writes the report of the run ([`nlos_report::write_report`]) and prints where.
fn write_report(
    run: &Run<'_>,
    prepared: &Prepared,
    params: &ReconstructParams,
    gt: Option<&SurfaceMesh>,
) -> Result<(), CliError> {
    let opts = ReportOptions::for_run(run.data, run.config, prepared, params, run.resumed);
    let report = nlos_report::write_report(run.out, &prepared.measured, gt, &opts).map_err(|e| match e {
        nlos_report::ReportError::MissingFile { .. } | nlos_report::ReportError::Json { .. } => bad(e),
        other => fail(other),
    })?;
    outln!("{}: {} figures", report.html.display(), report.images.len());
    if let Some(u) = &report.unexplained {
        let [before, within, after, none] = u.shares().map(|x| 100.0 * x);
        outln!(
            "unexplained: {:.4e} of half-deviance above the noise; {before:.0} % before each spot's return, \
             {within:.0} % within it, {after:.0} % after it, {none:.0} % at spots where the surface makes no light \
             (unexplained.png, residual.png)",
            u.total()
        );
    }
    Ok(())
}

/// `nlos report DIR --data DATA [--gt GT]`: the report of the run in `dir` with its settings
/// (`dir/settings.toml`, or the defaults when there is none) and ground truth (`gt`, or the run's own).
pub(crate) fn report_for_run(dir: &Path, data: &Path, gt: Option<&Path>) -> Result<(), CliError> {
    let config = pipeline::saved_config(dir).map_err(bad)?.unwrap_or_default();
    let saved_gt = match std::fs::read(dir.join(COMMAND_FILE)) {
        Ok(bytes) => {
            serde_json::from_slice::<serde_json::Value>(&bytes).ok().and_then(|v| v["gt"].as_str().map(PathBuf::from))
        }
        Err(_) => None,
    };
    let prepared = Prepared::load(data, &config).map_err(bad)?;
    let params = prepared.params(&config, Some(dir.to_owned())).map_err(bad)?;
    let gt = load_gt(gt.or(saved_gt.as_deref()))?;
    write_report(&Run { data, out: dir, config: &config, resumed: false }, &prepared, &params, gt.as_ref())
}

fn save(mesh: &SurfaceMesh, path: &Path) -> Result<(), CliError> {
    nlos_mesh::io::save(mesh, path).map_err(fail)
}

/// How a run shows its progress on stderr: a bar on a terminal; one plain line per block where stderr is a
/// file or a pipe (a batch job's log, where a bar would hide itself and the log stay empty for the whole run);
/// nothing with `--quiet`.
enum Reporter {
    Bar(indicatif::ProgressBar),
    Lines,
    Quiet,
}

impl Reporter {
    fn new(quiet: bool, params: &ReconstructParams) -> Self {
        use std::io::IsTerminal;
        if quiet {
            Self::Quiet
        } else if std::io::stderr().is_terminal() {
            Self::Bar(progress_bar(params))
        } else {
            Self::Lines
        }
    }

    fn update(&mut self, p: &Progress) {
        match self {
            Self::Bar(bar) => {
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
            Self::Lines if p.event == ProgressEvent::BlockEnd => eprintln!("{}", progress_line(p)),
            Self::Lines | Self::Quiet => {}
        }
    }

    fn finish(self) {
        if let Self::Bar(bar) = self {
            bar.finish_and_clear();
        }
    }
}

/// One block's line for a log: stage, block, faces, loss, elapsed time, and the time the planned iterations
/// left would take at the pace so far — an estimate, low while stages still refine (a finer stage's faces
/// cost more per step) and high when a stage ends early.
fn progress_line(p: &Progress) -> String {
    let left = if p.iteration > 0 && p.iterations_planned > p.iteration {
        p.elapsed_s * (p.iterations_planned - p.iteration) as f64 / p.iteration as f64
    } else {
        0.0
    };
    format!(
        "progress: stage {}/{} · block {} · {} faces · loss {:.4e} · {} elapsed · about {} left at this pace",
        p.stage + 1,
        p.max_stages,
        p.blocks_done,
        p.faces,
        p.loss,
        duration(p.elapsed_s),
        duration(left)
    )
}

/// `95 s`, `12 min 5 s`.
fn duration(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    if s < 60 { format!("{s} s") } else { format!("{} min {} s", s / 60, s % 60) }
}

fn progress_bar(params: &ReconstructParams) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(u64::from(params.schedule.shape_iterations.max(1)));
    let style = indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} ETA {eta} · {msg}")
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> ");
    bar.set_style(style);
    bar
}
