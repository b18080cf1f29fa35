//! `nlos eval`: metrics of a reconstructed mesh against the ground truth, as one JSON line.
//!
//! Loads both meshes with [`nlos_mesh::metrics::load_for_eval`] ([`nlos_mesh::io`] readers; non-manifold
//! triangle lists are accepted unwelded) and prints the [`nlos_mesh::metrics::Metrics`] of
//! [`nlos_mesh::metrics::evaluate`] (coverage and depth error from a +z ray grid over the wall, Chamfer
//! and Hausdorff distances, normal angular error) serialised by `serde_json`; with `--map`, also the
//! coverage picture of `nlos_report::figures::coverage_figure`.

use std::path::{Path, PathBuf};

use nlos_mesh::metrics::{EvalParams, MAX_GRID, evaluate, load_for_eval};
use nlos_mesh::{MeshError, SurfaceMesh};

use crate::CliError;

/// Arguments of `nlos eval`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The reconstructed mesh (OBJ, PLY or GLB, detected from its content).
    mesh: PathBuf,
    /// The ground-truth mesh (OBJ, PLY or GLB).
    #[arg(long, value_name = "GT")]
    gt: PathBuf,
    /// Rays per side of the grid over the wall's scan area [−0.25, 0.25]² m (1 to 4096).
    #[arg(long, default_value_t = 128, value_name = "N")]
    grid: usize,
    /// Also draw the coverage picture as this PNG: the ray grid coloured by hit within 5 mm, hit but
    /// further apart, missed and extra pixels (as the run report's `coverage.png`).
    #[arg(long, value_name = "PNG")]
    map: Option<PathBuf>,
}

/// Reads a mesh; errors name the file.
fn load(path: &Path) -> Result<SurfaceMesh, CliError> {
    load_for_eval(path).map_err(|e| match e {
        // these already name the file
        MeshError::Io { .. } | MeshError::Format { .. } => CliError::Input(e.to_string()),
        other => CliError::Input(format!("{}: {other}", path.display())),
    })
}

/// Runs `nlos eval`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    if args.grid == 0 || args.grid > MAX_GRID {
        return Err(CliError::Input(format!("--grid {} is out of range; use 1 to {MAX_GRID}", args.grid)));
    }
    // either may be non-manifold (scanned or exported models): see `load_for_eval`
    let reconstruction = load(&args.mesh)?;
    let ground_truth = load(&args.gt)?;
    let params = EvalParams { grid: args.grid, ..EvalParams::default() };
    let metrics = evaluate(&reconstruction, &ground_truth, &params).map_err(|e| {
        CliError::Input(format!("evaluating {} against {}: {e}", args.mesh.display(), args.gt.display()))
    })?;
    if let Some(png) = &args.map {
        let view =
            nlos_report::figures::DepthView { grid: params.grid, x_range: params.x_range, y_range: params.y_range };
        let title = args.mesh.file_name().map_or_else(|| "reconstruction".into(), |n| n.to_string_lossy().into_owned());
        let fig = nlos_report::figures::coverage_figure(
            &[(&title, &metrics.depth_reconstruction)],
            &metrics.depth_ground_truth,
            &view,
        )
        .map_err(|e| CliError::Failure(format!("drawing the coverage picture: {e}")))?;
        fig.save_png(png).map_err(|e| CliError::Failure(format!("cannot write {}: {e}", png.display())))?;
    }
    let line = serde_json::to_string(&metrics).map_err(|e| CliError::Failure(format!("encoding JSON: {e}")))?;
    println!("{line}");
    Ok(())
}
