//! `nlos render`: simulate the measurements of a mesh.
//!
//! Composes [`nlos_mesh::io`] (the mesh), [`nlos_transient`] (the setup and the output file, and the SPAD
//! model for `--photons`: [`nlos_transient::sensor::SpadModel`] — jitter, background, dead time with
//! pile-up, afterpulsing, in that physical order) and [`nlos_render`] (the transient, with the box kernel
//! of eq. 3 that simulates a measurement). It computes nothing itself.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicUsize;

use nlos_brdf::Model;
use nlos_render::with_brdf;
use nlos_render::{AnyBrdf, DeterministicRule, Kernel, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::sensor::{JitterResponse, PhotonBudget, SpadModel};
use nlos_transient::{Format, PointSet, SPEED_OF_LIGHT, Scan, TimeAxis, Transient};

use crate::CliError;
use crate::choices::{DeviceArg, ModeArg, VisibilityArg, brdf_parser};
use crate::progress::Step;

/// Arguments of `nlos render`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    read: crate::choices::ReadArgs,
    /// The mesh (OBJ, PLY or GLB; any triangle list, manifold or not); faces reflect on the side of
    /// `(v1 − v0) × (v2 − v0)` unless --two-sided. A PLY's per-vertex `albedo` (as `nlos reconstruct`
    /// writes `mesh.ply`) scales each face's reflectance by the mean of its corners' (print on a surface).
    mesh: PathBuf,
    /// The output capture; the format follows the extension (.hdf5 → y-tal HDF5_TAL, .npy → npy + json,
    /// .exr → EXR).
    #[arg(long, value_name = "DATA")]
    out: PathBuf,
    /// Copy the scan geometry and time axis of this capture (any readable format). Default: Tsai et al. 2019's
    /// setup — confocal 64 × 64 over [−0.25, 0.25]² m, 1200 bins of 1.2 mm from path length 0.
    #[arg(long, value_name = "FILE")]
    setup: Option<PathBuf>,
    /// Reflectance: `lambert` (albedo 1), `ggx` (specular 1, no diffuse, F = 1, roughness --alpha) or
    /// `retroreflective` (return 1, 1° lobe).
    #[arg(long, value_parser = brdf_parser(), default_value = "lambert")]
    brdf: Model,
    /// GGX roughness α in [0.001, 1].
    #[arg(long, default_value_t = 0.3)]
    alpha: f32,
    /// Both sides of every face reflect.
    #[arg(long)]
    two_sided: bool,
    /// `exact`: noise-free, each face's path-length density integrated over each bin in closed form (box
    /// kernel: a bin holds the integral over it); `quadrature`: the adaptive point quadrature (box kernel,
    /// sub-triangles of at most half a bin; slower and less accurate); `mc`: Tsai et al. 2019's stratified area
    /// sampling (--spp samples per measurement); `splat`: the optimiser's closed-form rule (tent kernel; the
    /// mode the GPU runs).
    #[arg(long, value_enum, default_value = "exact")]
    mode: ModeArg,
    /// Largest subdivision level: of the closed forms (`exact`, `splat`: 1..=64, faces are cut where their
    /// path length departs from linear), or of the `quadrature` (each sub-triangle spans at most half a bin
    /// of path length, up to level² sub-triangles per triangle and measurement).
    #[arg(long, default_value_t = 64, value_name = "N")]
    max_level: u32,
    /// Visibility: `cached` (one visible fraction per triangle and measurement from --vis-level²
    /// shadow rays: fast, and exact away from shadow boundaries), `live` (a shadow ray per sample: exact,
    /// slow on large meshes), `off` (no occlusion).
    #[arg(long, value_enum, default_value = "cached")]
    visibility: VisibilityArg,
    /// Sub-triangle level of the cached visibility rays (level² rays per triangle and measurement; level 1
    /// adds a bin-level error of 7e-4 against level 8 on the shared bunny, level 2 2.8e-4 at 3× the time).
    #[arg(long, default_value_t = 1, value_name = "N")]
    vis_level: u32,
    /// Where to render: `cpu`, `gpu` (needs `--mode splat` and visibility `cached` or `off`, Lambertian or
    /// retroreflective; fails with the reason where there is no adapter) or `auto` (a hardware GPU where one
    /// is found and the settings allow, else the CPU).
    #[arg(long, value_enum, default_value = "cpu")]
    device: DeviceArg,
    /// Samples per measurement in `--mode mc`.
    #[arg(long, default_value_t = 20_000)]
    spp: u32,
    /// Seed of the sampling and of the photon noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Replace the expected transient by SPAD photon counts with this many detected signal photons per
    /// measurement on average. Alone: an ideal photon counter (Poisson counts); the options below add the
    /// other effects of the SPAD model.
    #[arg(long, value_name = "N")]
    photons: Option<f64>,
    /// Timing jitter: the SPAD's measured response (`JitterResponse::load`: MATLAB v7.3 `t_*`/`counts_*`,
    /// e.g. `spad_jitter.mat`, or HDF5 `counts` + `timebin_width_ps`). Needs --photons.
    #[arg(long, value_name = "FILE", requires = "photons", conflicts_with = "jitter_fwhm")]
    jitter: Option<PathBuf>,
    /// Timing jitter: a Gaussian response of this full width at half maximum, picoseconds. Needs --photons.
    #[arg(long, value_name = "PS", requires = "photons")]
    jitter_fwhm: Option<f64>,
    /// Dark-count plus ambient background rate, detected counts per second. Needs --photons.
    #[arg(long, value_name = "RATE", requires = "photons")]
    background: Option<f64>,
    /// Dead time (hold-off) after a detection, seconds; turns on first-photon detection with pile-up.
    /// Needs --photons and --rep-rate.
    #[arg(long, value_name = "S", requires_all = ["photons", "rep_rate"])]
    dead_time: Option<f64>,
    /// Laser repetition rate, Hz (the SPAD model's default is 10 MHz). Needs --photons.
    #[arg(long, value_name = "HZ", requires = "photons")]
    rep_rate: Option<f64>,
    /// Acquisition time per measurement, seconds (the SPAD model's default is 0.1 s). Needs --photons.
    #[arg(long, value_name = "S", requires = "photons")]
    exposure: Option<f64>,
    /// Afterpulsing probability per detection, in [0, 1). Needs --photons.
    #[arg(long, value_name = "P", requires = "photons")]
    afterpulse: Option<f64>,
}

/// The SPAD model of the arguments: the ideal counter of `--photons n`, plus each effect asked for.
fn spad_model(args: &Args, n: f64) -> Result<SpadModel, CliError> {
    let mut m = SpadModel::ideal(PhotonBudget::PerMeasurement(n));
    if let Some(file) = &args.jitter {
        m.jitter = Some(JitterResponse::load(file).map_err(|e| bad(format!("--jitter {}: {e}", file.display())))?);
    }
    if let Some(ps) = args.jitter_fwhm {
        // picoseconds → metres of path, the workspace's time unit
        m.jitter = Some(
            JitterResponse::gaussian(ps * 1e-12 * SPEED_OF_LIGHT).map_err(|e| bad(format!("--jitter-fwhm: {e}")))?,
        );
    }
    if let Some(r) = args.background {
        m.background_rate = r;
    }
    if let Some(f) = args.rep_rate {
        m.rep_rate = f;
    }
    if let Some(t) = args.exposure {
        m.exposure = t;
    }
    if let Some(p) = args.afterpulse {
        m.afterpulse_probability = p;
    }
    if let Some(d) = args.dead_time {
        m.dead_time = d;
        m.pile_up = true;
    }
    m.validate().map_err(bad)?;
    Ok(m)
}

fn bad<E: std::fmt::Display>(e: E) -> CliError {
    CliError::Input(e.to_string())
}

/// Runs `nlos render`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    let format = Format::for_writing_extension(&args.out).ok_or_else(|| {
        bad(format!(
            "{}: cannot tell the output format from the extension; use .hdf5, .npy or .exr",
            args.out.display()
        ))
    })?;
    crate::check_output(&args.out, "--out")?;
    if args.setup.is_none() && args.read.bin_width_ps.is_some() {
        return Err(bad(
            "--bin-width-ps is the bin width of the --setup capture (for files that do not store one); without \
             --setup the default setup's 1.2 mm bins are used: give --setup FILE, or leave --bin-width-ps out",
        ));
    }
    let (scan, time) = match &args.setup {
        Some(file) => {
            let t = args.read.read(file)?;
            (t.scan().clone(), *t.time())
        }
        None => (
            Scan::confocal(PointSet::wall_grid(64, 64, 0.25, 0.25).map_err(bad)?),
            TimeAxis::new(0.0, 0.0012, 1200).map_err(bad)?,
        ),
    };
    let sampling = match args.mode {
        ModeArg::Quadrature if args.max_level >= 1 => {
            Sampling::Deterministic(DeterministicRule { max_level: args.max_level, ..DeterministicRule::default() })
        }
        ModeArg::Quadrature => return Err(bad("--max-level must be at least 1")),
        ModeArg::Mc if args.spp > 0 => Sampling::Stratified { samples_per_measurement: args.spp, seed: args.seed },
        ModeArg::Mc => return Err(bad("--spp must be at least 1")),
        ModeArg::Splat | ModeArg::Exact if (1..=64).contains(&args.max_level) => {
            Sampling::Splat(SplatRule { max_level: args.max_level, ..SplatRule::default() })
        }
        ModeArg::Splat | ModeArg::Exact => {
            return Err(bad(format!("--max-level {}: the closed forms take 1..=64", args.max_level)));
        }
    };
    let kernel = if args.mode == ModeArg::Splat { Kernel::Tent } else { Kernel::Box };
    let model = match args.photons {
        Some(n) if !(n.is_finite() && n > 0.0) => return Err(bad(format!("--photons {n}: must be finite and > 0"))),
        Some(n) => Some(spad_model(args, n)?),
        None => None,
    };
    // The renderer needs only the triangles: read them as a soup, so that scanned or exported models with
    // non-manifold edges (e.g. the shared soap bar) render as they are; the renderer checks the indices.
    let bytes = std::fs::read(&args.mesh).map_err(|e| bad(format!("{}: {e}", args.mesh.display())))?;
    let soup = nlos_mesh::io::read_any(&bytes, &args.mesh.display().to_string()).map_err(bad)?;
    let (positions, triangles) = (soup.positions, soup.triangles);
    let face_albedo = soup.albedo.as_ref().map(|a| face_means(a, &triangles));
    let visibility = match args.visibility {
        VisibilityArg::Cached if (1..=16).contains(&args.vis_level) => Visibility::Cached { level: args.vis_level },
        VisibilityArg::Cached => return Err(bad(format!("--vis-level {}: must be in 1..=16", args.vis_level))),
        VisibilityArg::Live => Visibility::Live,
        VisibilityArg::Off => Visibility::Off,
    };
    let params = RenderParams { kernel, sampling, visibility, two_sided: args.two_sided };
    if args.device == DeviceArg::Gpu {
        nlos_render::gpu_support(args.brdf, &params)
            .map_err(|why| bad(format!("--device gpu: {why}; use --device cpu")))?;
    }
    let brdf = AnyBrdf::unit(args.brdf, args.alpha).map_err(bad)?;
    // Progress: each measurement's visibility (cached mode), then its transient.
    let m = scan.measurements();
    let done = Arc::new(AtomicUsize::new(0));
    let passes = 1 + usize::from(matches!(visibility, Visibility::Cached { .. }));
    let what = format!("render: {} triangles × {m} measurements", triangles.len());
    let step = Step::counted(what, Arc::clone(&done), passes * m);
    let mut renderer = Renderer::new_observed(&positions, &triangles, &scan, &time, params, Some(done)).map_err(bad)?;
    renderer.set_device(args.device.into()).map_err(bad)?;
    if let Some(w) = &face_albedo {
        renderer
            .set_face_weights(Some(w))
            .map_err(|e| bad(format!("{}: its vertex albedo: {e}", args.mesh.display())))?;
    }
    let rendered: Transient = with_brdf!(brdf, b => renderer.forward_transient(&b)).map_err(bad)?;
    step.finish();
    let out = match &model {
        Some(m) => {
            let step = Step::spinner("render: photon counts (SPAD model)");
            let counts = m.simulate(&rendered, args.seed).map_err(bad)?;
            step.finish();
            counts
        }
        None => rendered,
    };
    nlos_transient::write(&out, &args.out, format).map_err(CliError::output)?;
    outln!(
        "wrote {}: {} measurements × {} bins, total {:.6e}",
        args.out.display(),
        out.measurements(),
        out.bins(),
        out.data().iter().map(|&v| f64::from(v)).sum::<f64>()
    );
    Ok(())
}

/// Each triangle's reflectance factor from a per-vertex albedo: the mean of its three corners' (an index out
/// of range gives NaN, which the renderer refuses by name).
fn face_means(albedo: &[f32], triangles: &[[u32; 3]]) -> Vec<f32> {
    let at = |v: u32| albedo.get(v as usize).copied().unwrap_or(f32::NAN);
    triangles.iter().map(|t| (at(t[0]) + at(t[1]) + at(t[2])) / 3.0).collect()
}
