//! A run directory from start to end: the one place that creates it, writes its settings and start surface,
//! and starts or resumes the optimisation in it. `nlos reconstruct` and the Python package's `reconstruct`
//! both call [`run`], so the same settings give the same directory from either, and either resumes it.
//!
//! A directory holds (besides what [`crate::reconstruct()`] writes: `checkpoint.json`, `run_log.json`,
//! `stage_NN.obj`, `mesh.obj`, `mesh.ply`):
//! - [`SETTINGS_FILE`]: the run's [`Config`] as TOML, written once when the run starts and never on
//!   resume, so a resumed run keeps the settings it was started with ([`saved_config`] reads them back; a
//!   setting changed on resume is refused by the checkpoint's settings record, naming it);
//! - [`INIT_FILE`]: the start surface.

use std::path::Path;

use super::files::{CANDIDATES_DIR, INIT_FILE, SETTINGS_FILE, create_dir};
use super::{Config, Prepared};
use crate::error::{OptimError, Result};
use crate::reconstruct::record::write_atomic;
use crate::{Hooks, Outcome, ReconstructParams};

/// Whether [`run`] starts a run or continues the one in its directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// A new run: the settings and the start surface are written, then the optimisation starts from it.
    New,
    /// Continue from the directory's checkpoint with its settings (nothing of the run is rewritten).
    Resume,
}

/// The settings a run directory was started with (its [`SETTINGS_FILE`]), `None` when it has none.
///
/// # Errors
/// [`OptimError::Io`] for an unreadable file, [`OptimError::Config`] for one that does not parse.
pub fn saved_config(dir: &Path) -> Result<Option<Config>> {
    let path = dir.join(SETTINGS_FILE);
    if path.exists() { Config::load(&path).map(Some) } else { Ok(None) }
}

/// Checks that `dir` holds a run to resume (its checkpoint) before anything is read or written, so that a
/// resume in the wrong directory fails at once and leaves it as it was.
///
/// # Errors
/// [`OptimError::Checkpoint`] when the checkpoint is missing or cannot be read.
pub fn check_resumable(dir: &Path) -> Result<()> {
    let path = dir.join(crate::CHECKPOINT_FILE);
    // Interrupted while its candidate starts ran: they resume (super::choose).
    if !path.exists() && dir.join(CANDIDATES_DIR).is_dir() {
        return Ok(());
    }
    std::fs::File::open(&path)
        .map(drop)
        .map_err(|e| OptimError::Checkpoint { message: crate::reconstruct::checkpoint_unreadable(&e), path })
}

/// Runs the reconstruction of `prepared` with `config` and `params` (from [`Prepared::params`]) in the run
/// directory `params.out_dir` (none: nothing is written).
///
/// [`Start::New`] creates the directory, writes [`SETTINGS_FILE`] (atomically), extracts the start surface
/// ([`Prepared::start_candidates`]), writes it as [`INIT_FILE`] and optimises from it
/// ([`crate::reconstruct_with`]); of two candidate starts, the data choose one after the first stage
/// ([`super::StartChoice`]). [`Start::Resume`] continues from the directory's checkpoint
/// ([`crate::resume`]), or the candidates' runs when it was interrupted before the choice.
///
/// # Errors
/// [`OptimError::InvalidParameter`] to resume without a directory; I/O in the directory; those of
/// [`Prepared::initial_surface`], [`crate::reconstruct_with`] and [`crate::resume`].
pub fn run(
    prepared: &Prepared,
    config: &Config,
    params: &ReconstructParams,
    start: Start,
    hooks: Hooks<'_>,
) -> Result<Outcome> {
    match start {
        Start::Resume
            if params
                .out_dir
                .as_deref()
                .is_some_and(|d| !d.join(crate::CHECKPOINT_FILE).exists() && d.join(CANDIDATES_DIR).is_dir()) =>
        {
            super::choose::run(prepared, config, params, prepared.start_candidates(config)?, hooks)
        }
        Start::Resume => {
            // The response of a gated capture depends on the start surface (Prepared::with_start_response):
            // the same start gives the same response as when the run began.
            let params = match params.out_dir.as_deref() {
                Some(dir) if prepared.takes_response_from_start(config, params) => {
                    let start = nlos_mesh::io::load(dir.join(INIT_FILE))?;
                    prepared.with_start_response(config, params, &start)?
                }
                _ => params.clone(),
            };
            crate::resume(&prepared.measured, &params, hooks)
        }
        Start::New => {
            if let Some(dir) = &params.out_dir {
                create_dir(dir)?;
                let mut settings = config.to_toml()?;
                if config.init == super::InitMethod::Auto {
                    let (method, why) = config.init.resolve(prepared.full.scan());
                    settings.insert_str(0, &format!("# init = \"auto\" chose \"{method}\": {why}\n"));
                }
                write_atomic(&dir.join(SETTINGS_FILE), settings.as_bytes())?;
            }
            let mut candidates = prepared.start_candidates(config)?;
            if candidates.len() > 1 {
                return super::choose::run(prepared, config, params, candidates, hooks);
            }
            let init = candidates.swap_remove(0).1;
            if let Some(dir) = &params.out_dir {
                nlos_mesh::io::save(&init, dir.join(INIT_FILE))?;
            }
            let params = prepared.with_start_response(config, params, &init)?;
            crate::reconstruct_with(&prepared.measured, &init, &params, hooks)
        }
    }
}
