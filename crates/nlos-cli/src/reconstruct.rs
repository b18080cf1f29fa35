//! `nlos reconstruct`: capture → initial surface (LCT, f-k or a mesh file) → optimised mesh.
//!
//! The command composes the library crates: [`nlos_init`] for the initial surface, [`nlos_optim`] for the
//! analysis-by-synthesis loop, [`nlos_mesh::io`] for the meshes. It computes nothing itself.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use nlos_brdf::{Fresnel, Ggx};
use nlos_init::{FkParams, LctParams, SurfaceParams, fk, lct, volume_to_surface};
use nlos_mesh::SurfaceMesh;
use nlos_optim::{Hooks, Progress, ProgressEvent, ReconstructParams, Reflectance, SamplingSchedule, StopReason};
use nlos_render::{DeterministicRule, Visibility};

use crate::CliError;

/// Arguments of `nlos reconstruct`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The capture (any readable format).
    data: PathBuf,
    /// Output directory: `mesh.obj`, `mesh.ply`, `init.obj`, `stage_NN.obj`, `run_log.json`,
    /// `checkpoint.json`.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Initial surface: `lct`, `fk`, or a mesh file (OBJ/PLY) whose faces face the wall.
    #[arg(long, default_value = "lct", value_name = "lct|fk|MESH")]
    init: String,
    /// Reflectance model to fit: `lambert` or `ggx` (α starts at --alpha).
    #[arg(long, default_value = "lambert", value_name = "lambert|ggx")]
    brdf: String,
    /// Initial GGX roughness α (with --brdf ggx).
    #[arg(long, default_value_t = 0.3)]
    alpha: f32,
    /// Seed of the run (a run is a deterministic function of its inputs and seed).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Continue the run whose checkpoint is in --out.
    #[arg(long)]
    resume: bool,
    /// Coarse-to-fine stages at most (default: the seed's 4).
    #[arg(long)]
    stages: Option<u32>,
    /// Resolution of the first stage: target edge length 0.5 m / RES (default: the seed's 64).
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
    /// Keep every K-th scan row and column before anything else (faster, coarser).
    #[arg(long, value_name = "K")]
    subsample: Option<usize>,
    /// Visibility of the surface from the wall spots: `cached` (one shadow ray per triangle and measurement,
    /// recomputed after every remeshing; the default), `live` (per sample, slow, exact) or `off` (no
    /// occlusion: right for height fields only).
    #[arg(long, default_value = "cached", value_name = "cached|live|off")]
    visibility: String,
    /// Largest subdivision level of the noise-free quadrature (n² samples per triangle and measurement at
    /// most; default 8). Higher is more accurate and slower.
    #[arg(long, default_value_t = 8, value_name = "N")]
    max_level: u32,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

fn fail<E: std::fmt::Display>(e: E) -> CliError {
    CliError::Failure(e.to_string())
}

fn bad<E: std::fmt::Display>(e: E) -> CliError {
    CliError::Input(e.to_string())
}

/// Runs `nlos reconstruct`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    let mut measured = nlos_transient::read(&args.data).map_err(CliError::input)?;
    if let Some(k) = args.rebin {
        measured = measured.rebin(k).map_err(CliError::input)?;
    }
    if let Some(k) = args.subsample {
        measured = measured.subsample(k, k).map_err(CliError::input)?;
    }
    std::fs::create_dir_all(&args.out).map_err(|e| fail(format!("{}: {e}", args.out.display())))?;
    let params = params(args)?;
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
        nlos_optim::resume(&measured, &params, hooks).map_err(bad)?
    } else {
        let init = initial_surface(args, &measured)?;
        save(&init, &args.out.join("init.obj"))?;
        nlos_optim::reconstruct_with(&measured, &init, &params, hooks).map_err(bad)?
    };
    if let Some(bar) = bar {
        bar.finish_and_clear();
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
    Ok(())
}

/// The optimiser's parameters from the arguments (documented defaults otherwise).
fn params(args: &Args) -> Result<ReconstructParams, CliError> {
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
    p.sampling = SamplingSchedule::Deterministic(DeterministicRule {
        max_level: args.max_level,
        ..DeterministicRule::default()
    });
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
    p.validate().map_err(bad)?;
    Ok(p)
}

/// The initial surface: a volumetric reconstruction turned into a mesh, or a mesh file.
fn initial_surface(args: &Args, measured: &nlos_transient::Transient) -> Result<SurfaceMesh, CliError> {
    let volume = match args.init.as_str() {
        "lct" => lct(measured, &LctParams::default()).map_err(bad)?,
        "fk" => fk(measured, &FkParams::default()).map_err(bad)?,
        file => return nlos_mesh::io::load(file).map_err(bad),
    };
    let surface = volume_to_surface(&volume, &SurfaceParams::default()).map_err(bad)?;
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
