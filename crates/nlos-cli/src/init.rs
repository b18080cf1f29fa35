//! `nlos init`: a volumetric reconstruction (LCT, f-k migration, filtered backprojection or space
//! carving) turned into the initial surface mesh, with a PNG of the front view and the depth map beside it.

use std::path::{Path, PathBuf};

use nlos_init::{
    Gate, InitError, InitMethod, Method, Model, PfParams, SurfaceParams, Threshold, Volume, volume_to_surface,
};
use nlos_optim::pipeline::{Config, Prepared, Setting};
use nlos_viz::{Colormap, Extent, Figure, Norm, Panel, ScalarGrid, Scale};

use crate::CliError;
use crate::progress::Step;

/// Arguments of `nlos init`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    read: crate::choices::ReadArgs,
    /// The capture file (any readable format; LCT and f-k need a confocal grid scan, the phasor field takes
    /// any).
    file: PathBuf,
    /// Reconstruction method.
    #[arg(long, value_parser = crate::choices::start_parser(), default_value = "auto")]
    method: InitMethod,
    /// Where to write the surface mesh (format from the extension: .obj, .ply, .glb). A PNG with the
    /// front view and the depth map is written beside it (same name, .png).
    #[arg(long, value_name = "MESH")]
    out: PathBuf,
    /// Also write the volume as a NumPy .npy file (f32, shape (ny, nx, nz)).
    #[arg(long, value_name = "NPY")]
    volume: Option<PathBuf>,
    /// Zero the bins before this path length (metres); `auto` estimates where the direct light ends,
    /// `off` keeps everything.
    #[arg(long, value_name = "METRES|auto|off", default_value = "auto", value_parser = parse_gate)]
    gate: Gate,
    /// Sum this many consecutive time bins first (4 suits the 4 ps Stanford captures).
    #[arg(long, value_name = "N", default_value_t = 1)]
    merge: usize,
    /// Ignore everything deeper than this (metres).
    #[arg(long, value_name = "METRES")]
    max_depth: Option<f64>,
    /// Extract the surface only from voxels at least this deep (metres).
    #[arg(long, value_name = "METRES")]
    min_depth: Option<f64>,
    /// Wiener signal-to-noise ratio of the LCT [default: 0.1, or 0.8 with --retroreflective (the Stanford
    /// captures' reference values are 0.08 and 0.8)].
    #[arg(long)]
    snr: Option<f64>,
    /// Virtual wavelength of the phasor field (metres of path) [default: 3 × the wall points' spacing].
    #[arg(long, value_name = "METRES")]
    wavelength: Option<f64>,
    /// Periods of the phasor field's carrier within its pulse's ±3σ [default: 2].
    #[arg(long, value_name = "N")]
    cycles: Option<f64>,
    /// Depth between the phasor field's voxels (metres) [default: the wavelength / 8]; half a bin of path puts
    /// a voxel at every bin's depth.
    #[arg(long, value_name = "METRES")]
    depth_step: Option<f64>,
    /// Radiometric weighting for retroreflective instead of diffuse surfaces (LCT, FBP): the return falls as
    /// 1/r², as the Stanford captures' reference code assumes for every scene but the diffuse S.
    #[arg(long)]
    retroreflective: bool,
    /// Mask threshold: `otsu`, a fraction of the maximum (`0.3`) or an absolute value (`abs:1e-6`). Given,
    /// the plain extraction is used (this threshold, largest region, arg-max depth); left out, LCT uses
    /// the settings for compact objects (`SurfaceParams::object`: Otsu seed grown to 10 %, receding
    /// rim) and the other methods Otsu's threshold.
    #[arg(long, value_parser = parse_threshold)]
    threshold: Option<Threshold>,
    /// Keep every region above the threshold, not only the largest.
    #[arg(long)]
    all_regions: bool,
    /// Hysteresis fraction (0–1) of the largest column maximum down to which the mask grows from its seed
    /// (the settings for compact objects use 0.1). Lower keeps dim parts (a rabbit's ears) and more of
    /// the albedo halo around the object; `nlos reconstruct` prunes what the data do not support
    /// (`boundary.prune_rounds`).
    #[arg(long, value_name = "FRACTION")]
    grow: Option<f32>,
    /// Smoothing passes over the depth map.
    #[arg(long, default_value_t = 0)]
    smooth: usize,
    /// Remesh isotropically to this edge length (metres).
    #[arg(long, value_name = "METRES")]
    edge: Option<f64>,
    /// Turn the surface back toward its boundary: vertices within this distance (metres) of it recede by a
    /// quarter circle of this radius, as a smooth object's surface does at its silhouette
    /// (`nlos_init::rim`). Off by default.
    #[arg(long, value_name = "METRES")]
    rim_radius: Option<f64>,
}

pub(crate) fn parse_gate(s: &str) -> Result<Gate, String> {
    match s {
        "auto" => Ok(Gate::Auto),
        "off" | "none" => Ok(Gate::None),
        _ => s
            .parse::<f64>()
            .ok()
            .filter(|g| g.is_finite())
            .map(Gate::Path)
            .ok_or_else(|| format!("`{s}` is not a path length in metres, `auto` or `off`")),
    }
}

fn parse_threshold(s: &str) -> Result<Threshold, String> {
    if s == "otsu" {
        return Ok(Threshold::Otsu);
    }
    let bad = || format!("`{s}` is not `otsu`, a fraction in [0, 1] or `abs:VALUE`");
    if let Some(v) = s.strip_prefix("abs:") {
        return v.parse::<f32>().ok().filter(|v| v.is_finite()).map(Threshold::Absolute).ok_or_else(bad);
    }
    s.parse::<f32>().ok().filter(|v| (0.0..=1.0).contains(v)).map(Threshold::Relative).ok_or_else(bad)
}

fn optim_error(e: nlos_optim::OptimError) -> CliError {
    match e {
        nlos_optim::OptimError::Init(e) => init_error(e),
        other => CliError::Input(other.to_string()),
    }
}

fn init_error(e: InitError) -> CliError {
    match e {
        InitError::Transient(e) => CliError::input(e),
        InitError::Mesh(e) => CliError::Failure(e.to_string()),
        e @ (InitError::NotConfocal { .. } | InitError::NotGrid { .. }) => {
            CliError::Input(format!("{e} (`--method pf`, or `--method auto`, the default, which chooses it)"))
        }
        other => CliError::Input(other.to_string()),
    }
}

pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    // The outputs are checked before the work that makes them.
    nlos_mesh::io::check_save_extension(&args.out).map_err(|e| CliError::Input(format!("--out: {e}")))?;
    crate::check_output(&args.out, "--out")?;
    if let Some(path) = &args.volume {
        if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy")) {
            return Err(CliError::Input(format!(
                "--volume {}: the volume is written as NumPy .npy; name it .npy",
                path.display()
            )));
        }
        crate::check_output(path, "--volume")?;
    }
    let step = Step::spinner(format!("init: reading {}", args.file.display()));
    let t = args.read.read(&args.file)?;
    let reflectance = if args.retroreflective { Model::Retroreflective } else { Model::Lambert };
    // The capture is prepared as `nlos reconstruct` prepares it (one library path: rebin, gate, the bins after
    // the last return, the depth the start may reach), with the same defaults.
    let mut config = Config::default();
    config.capture.rebin = args.merge;
    config.capture.gate = match args.gate {
        Gate::Auto => Setting::AUTO,
        Gate::None => Setting::OFF,
        Gate::Path(g) => Setting::Value(g),
    };
    config.capture.max_depth = args.max_depth.map_or(Setting::AUTO, Setting::Value);
    // The preparation notes what `auto` chooses; a method given by name needs no such note.
    config.init = args.method.clone();
    let prepared = Prepared::new(t, &config).map_err(optim_error)?;
    step.finish();
    for note in &prepared.notes {
        eprintln!("{note}");
    }
    let method = match &args.method {
        InitMethod::Volume(method) => *method,
        // The parser takes `auto` and the methods' names only.
        InitMethod::Auto | InitMethod::Mesh(_) => Method::for_scan(prepared.full.scan()).0,
    };
    let step = Step::spinner(format!("init: {method} volume"));
    let vol = if method == Method::Pf {
        let defaults = PfParams::default();
        let params = PfParams {
            reflectance,
            wavelength: args.wavelength,
            cycles: args.cycles.unwrap_or(defaults.cycles),
            depth_step: args.depth_step,
            ..defaults
        };
        prepared.pf_volume(&params).map_err(optim_error)?
    } else {
        prepared.volume(method, reflectance, args.snr).map_err(optim_error)?
    };
    // Given a threshold, the plain extraction (this threshold, largest region, arg-max depth); else the
    // start's own settings (the settings for compact objects for LCT).
    let base = match args.threshold {
        None => prepared.surface_params(method),
        Some(_) => SurfaceParams { max_depth: prepared.surface_depth, ..SurfaceParams::default() },
    };
    let params = SurfaceParams {
        threshold: args.threshold.unwrap_or(base.threshold),
        min_depth: args.min_depth,
        max_depth: args.max_depth.or(base.max_depth),
        largest_component: !args.all_regions,
        smoothing_iterations: args.smooth,
        target_edge_length: args.edge,
        grow_threshold: args.grow.or(base.grow_threshold),
        rim_radius: args.rim_radius,
        ..base
    };
    step.finish();
    let step = Step::spinner("init: surface");
    let surface = volume_to_surface(&vol, &params).map_err(init_error)?;
    step.finish();
    nlos_mesh::io::save(&surface.mesh, &args.out).map_err(|e| CliError::Failure(e.to_string()))?;
    if let Some(path) = &args.volume {
        std::fs::write(path, vol.to_npy())
            .map_err(|e| CliError::Failure(format!("cannot write {}: {e}", path.display())))?;
    }
    let png = args.out.with_extension("png");
    figure(&vol, &surface.depth, &surface.mask, &png)?;
    let kept = surface.mask.iter().filter(|&&k| k).count();
    outln!(
        "{:?}: {} × {} × {} volume; {kept} of {} columns kept (threshold {:.3e}), median depth {} m; \
         {} vertices, {} triangles → {}; figure {}",
        method,
        vol.nx,
        vol.ny,
        vol.nz,
        vol.nx * vol.ny,
        surface.threshold,
        surface.median_depth().map_or("-".into(), |d| format!("{d:.4}")),
        surface.positions.len(),
        surface.triangles.len(),
        args.out.display(),
        png.display()
    );
    Ok(())
}

fn viz(e: nlos_viz::VizError) -> CliError {
    CliError::Failure(e.to_string())
}

/// Front view (maximum over depth) beside the depth of the kept columns; x right, y up: the view from
/// the wall into the hidden scene.
fn figure(vol: &Volume, depth: &[f32], mask: &[bool], out: &Path) -> Result<(), CliError> {
    let maxp = vol.max_projection();
    let ex = Extent::from_centres(vol.x.at(0), vol.x.at(vol.nx - 1), vol.nx).map_err(viz)?;
    let ey = Extent::from_centres(vol.y.at(0), vol.y.at(vol.ny - 1), vol.ny).map_err(viz)?;
    let kept: Vec<f32> = depth.iter().zip(mask).filter(|&(_, &k)| k).map(|(&d, _)| d).collect();
    let lo = kept.iter().copied().fold(f32::INFINITY, f32::min) as f64;
    let hi = kept.iter().copied().fold(f32::NEG_INFINITY, f32::max) as f64;
    let shown: Vec<f32> = depth.iter().zip(mask).map(|(&d, &k)| if k { d } else { lo as f32 }).collect();
    let mut fig = Figure::new("nlos init");
    fig.panels.push(
        Panel::image(
            ScalarGrid::new(&maxp, vol.nx, vol.ny, ex, ey).map_err(viz)?,
            Norm::auto(&maxp, Scale::Linear).map_err(viz)?,
        )
        .with_colormap(Colormap::Grey)
        .with_labels("x (m)", "y (m)")
        .with_title("front view (max over depth)"),
    );
    fig.panels.push(
        Panel::image(
            ScalarGrid::new(&shown, vol.nx, vol.ny, ex, ey).map_err(viz)?,
            Norm::linear(lo - 1e-3, hi + 1e-3).map_err(viz)?,
        )
        .with_colormap(Colormap::Viridis)
        .with_labels("x (m)", "y (m)")
        .with_title("depth of kept columns")
        .with_colorbar("m"),
    );
    fig.render().map_err(viz)?.save_png(out).map_err(viz)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_and_gates_parse() {
        assert_eq!(parse_threshold("otsu"), Ok(Threshold::Otsu));
        assert_eq!(parse_threshold("0.3"), Ok(Threshold::Relative(0.3)));
        assert_eq!(parse_threshold("abs:1e-6"), Ok(Threshold::Absolute(1e-6)));
        for bad in ["1.5", "-0.1", "abs:nan", "abs:", "x"] {
            assert!(parse_threshold(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_gate("auto"), Ok(Gate::Auto));
        assert_eq!(parse_gate("off"), Ok(Gate::None));
        assert_eq!(parse_gate("0.72"), Ok(Gate::Path(0.72)));
        assert!(parse_gate("inf").is_err());
    }
}
