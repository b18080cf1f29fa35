//! `nlos eval`: metrics of a reconstructed mesh against the ground truth, as one JSON line.
//!
//! Loads both meshes with [`nlos_mesh::metrics::load_for_eval`] ([`nlos_mesh::io`] readers; non-manifold
//! triangle lists are accepted unwelded) and prints the [`nlos_mesh::metrics::Metrics`] of
//! [`nlos_mesh::metrics::evaluate`] (coverage and depth error from a +z ray grid over the wall, Chamfer
//! and Hausdorff distances, normal angular error) serialised by `serde_json`.

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
    let line = serde_json::to_string(&metrics).map_err(|e| CliError::Failure(format!("encoding JSON: {e}")))?;
    println!("{line}");
    Ok(())
}
