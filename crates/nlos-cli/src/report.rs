//! `nlos report DIR --data DATA [--gt GT.obj]`: regenerate the report of a reconstruction run.
//!
//! Re-reads the run's saved command line (`DIR/command.json`) so that the capture is preprocessed and the
//! final mesh rendered exactly as in the run, then calls [`nlos_report::write_report`]. It computes nothing
//! itself.

use std::path::PathBuf;

use crate::CliError;

/// Arguments of `nlos report`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The run directory (`nlos reconstruct --out DIR`): `mesh.obj`, `run_log.json`, `checkpoint.json`, …
    dir: PathBuf,
    /// The capture the run fitted (any readable format).
    #[arg(long, value_name = "DATA")]
    data: PathBuf,
    /// Ground-truth mesh: adds its depth map and the metrics (default: the run's --gt, if any).
    #[arg(long, value_name = "GT.obj")]
    gt: Option<PathBuf>,
}

/// Runs `nlos report`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    crate::reconstruct::report_for_run(&args.dir, &args.data, args.gt.as_deref())
}
