//! The files of a run directory that the pipeline writes besides the loop's own
//! ([`crate::RunRecord`], `run_log.json`, `stage_NN.obj`, `mesh.obj`, `mesh.ply`), and the one place that
//! creates the directory.

use std::path::Path;

use crate::error::{OptimError, Result};

/// The file of a run directory that keeps the run's settings ([`super::Config::to_toml`]).
pub const SETTINGS_FILE: &str = "settings.toml";
/// The file of a run directory that keeps the start surface.
pub const INIT_FILE: &str = "init.obj";
/// The folder of a run directory that holds each candidate start's run, one folder per rim
/// (`start_candidates/receding`, `start_candidates/measured`).
pub const CANDIDATES_DIR: &str = "start_candidates";
/// The file of a run directory that records which start the data chose ([`super::StartChoice`]).
pub const CHOICE_FILE: &str = "start_choice.json";

/// Creates the run directory (and its parents).
///
/// # Errors
/// [`OptimError::Io`] naming the directory.
pub(super) fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|source| OptimError::Io {
        path: dir.to_owned(),
        fix: OptimError::WRITE_FIX,
        source,
    })
}
