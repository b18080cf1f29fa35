//! `nlos render`: simulate the measurements of a mesh.
//!
//! Composes [`nlos_mesh::io`] (the mesh), [`nlos_transient`] (the setup and the output file, and the SPAD
//! model for `--photons`) and [`nlos_render`] (the transient, with the box kernel of eq. 3 that simulates a
//! measurement). It computes nothing itself.

use std::path::PathBuf;

use nlos_brdf::{Fresnel, Ggx, Lambertian};
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::sensor::{PhotonBudget, SpadModel};
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient};

use crate::CliError;

/// Arguments of `nlos render`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The mesh (OBJ or PLY); faces reflect on the side of `(v1 − v0) × (v2 − v0)` unless --two-sided.
    mesh: PathBuf,
    /// The output capture; the format follows the extension (.hdf5 → y-tal HDF5_TAL, .npy → npy + json,
    /// .exr → EXR).
    #[arg(long, value_name = "DATA")]
    out: PathBuf,
    /// Copy the scan geometry and time axis of this capture (any readable format). Default: the seed's
    /// setup — confocal 64 × 64 over [−0.25, 0.25]² m, 1200 bins of 1.2 mm from path length 0.
    #[arg(long, value_name = "FILE")]
    setup: Option<PathBuf>,
    /// Reflectance: `lambert` (albedo 1) or `ggx` (specular 1, no diffuse, F = 1, roughness --alpha).
    #[arg(long, default_value = "lambert", value_name = "lambert|ggx")]
    brdf: String,
    /// GGX roughness α in [0.001, 1].
    #[arg(long, default_value_t = 0.3)]
    alpha: f32,
    /// Both sides of every face reflect.
    #[arg(long)]
    two_sided: bool,
    /// `exact`: noise-free adaptive quadrature; `mc`: the seed's stratified area sampling (--spp samples
    /// per measurement).
    #[arg(long, default_value = "exact", value_name = "exact|mc")]
    mode: String,
    /// Samples per measurement in `--mode mc`.
    #[arg(long, default_value_t = 20_000)]
    spp: u32,
    /// Seed of the sampling and of the photon noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Replace the expected transient by Poisson photon counts with this many detected photons per
    /// measurement on average (the SPAD model's ideal detector).
    #[arg(long, value_name = "N")]
    photons: Option<f64>,
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
    let (scan, time) = match &args.setup {
        Some(file) => {
            let t = nlos_transient::read(file).map_err(CliError::input)?;
            (t.scan().clone(), *t.time())
        }
        None => (
            Scan::confocal(PointSet::wall_grid(64, 64, 0.25, 0.25).map_err(bad)?),
            TimeAxis::new(0.0, 0.0012, 1200).map_err(bad)?,
        ),
    };
    let sampling = match args.mode.as_str() {
        "exact" => Sampling::Deterministic(DeterministicRule::default()),
        "mc" if args.spp > 0 => Sampling::Stratified { samples_per_measurement: args.spp, seed: args.seed },
        "mc" => return Err(bad("--spp must be at least 1")),
        other => return Err(bad(format!("--mode `{other}`: expected `exact` or `mc`"))),
    };
    if let Some(n) = args.photons {
        if !(n.is_finite() && n > 0.0) {
            return Err(bad(format!("--photons {n}: must be finite and > 0")));
        }
    }
    let mesh = nlos_mesh::io::load(&args.mesh).map_err(bad)?;
    let (positions, triangles) = mesh.to_triangles();
    let params =
        RenderParams { kernel: Kernel::Box, sampling, visibility: Visibility::Live, two_sided: args.two_sided };
    let renderer = Renderer::new(&positions, &triangles, &scan, &time, params).map_err(bad)?;
    let rendered: Transient = match args.brdf.as_str() {
        "lambert" | "lambertian" => renderer.forward_transient(&Lambertian::new(1.0f32).map_err(bad)?),
        "ggx" => renderer.forward_transient(&Ggx::new(0.0, 1.0, args.alpha, Fresnel::One).map_err(bad)?),
        other => return Err(bad(format!("--brdf `{other}`: expected `lambert` or `ggx`"))),
    }
    .map_err(bad)?;
    let out = match args.photons {
        Some(n) => SpadModel::ideal(PhotonBudget::PerMeasurement(n)).simulate(&rendered, args.seed).map_err(bad)?,
        None => rendered,
    };
    nlos_transient::write(&out, &args.out, format).map_err(CliError::output)?;
    println!(
        "{}: {} measurements × {} bins, total {:.6e}",
        args.out.display(),
        out.measurements(),
        out.bins(),
        out.data().iter().map(|&v| f64::from(v)).sum::<f64>()
    );
    Ok(())
}
