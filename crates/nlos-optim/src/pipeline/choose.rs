//! Two starts, and the data choose between them ([`StartRim::Choose`]).
//!
//! One laser's volume places the dim rim of an object ambiguously: the lateral blur puts it at the depth
//! of the brighter interior, and whether the true rim recedes (a convex object's silhouette) or comes toward
//! the wall (a dish with its inside toward the wall) is the object's, not the volume's. So both starts run
//! the first stage (with its pruning and residual patches) and one block of the next, each in its own
//! directory under [`CANDIDATES_DIR`], and the run goes on from the one whose **misfit** (the normalised
//! data term above its noise floor, [`crate::IterationRecord::noise_floor`]; the data term itself for an L2
//! fit) is lower at the next stage's first step. There both fits are judged on the same stage's capture
//! with the same normaliser, after each has had a stage to settle, and after the residual patches have
//! added what each start lacked: measured on the `nonconfocal` acceptance scenario's captures, the end of
//! the first stage itself chooses wrongly for one of them (docs/accuracy.md).
//!
//! The chosen candidate's files move into the run directory and its run resumes there
//! ([`crate::resume`]), so its result is the same as a run started from it alone; the other's directory
//! stays for comparison. [`CHOICE_FILE`] records the choice. A run interrupted while the candidates run
//! resumes them ([`super::run`] with [`super::Start::Resume`]).

use std::cell::Cell;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use nlos_mesh::SurfaceMesh;
use serde::{Deserialize, Serialize};

use super::files::{CANDIDATES_DIR, CHOICE_FILE, INIT_FILE, create_dir};
use super::{Config, Prepared, StartRim};
use crate::error::{OptimError, Result};
use crate::reconstruct::record::write_atomic;
use crate::{CHECKPOINT_FILE, Hooks, Outcome, Progress, ProgressEvent, RUN_LOG_FILE, ReconstructParams, RunLog};

/// Which start the data chose, and by how much ([`CHOICE_FILE`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StartChoice {
    /// The rim the run went on from.
    pub chosen: StartRim,
    /// Every candidate, in the order they ran.
    pub candidates: Vec<Candidate>,
}

/// One candidate start at the point of comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Its rim.
    pub rim: StartRim,
    /// Faces of its start.
    pub start_faces: usize,
    /// The normalised data term above its noise floor at the comparison ([`misfit_at_choice`]).
    pub misfit: f64,
    /// The stage (0-based) of the step compared: 1 when the run reached a second stage, else 0 (its last
    /// step).
    pub stage: u32,
}

impl std::fmt::Display for StartChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let each: Vec<String> = self.candidates.iter().map(|c| format!("{} {:.5}", c.rim, c.misfit)).collect();
        let at = if self.candidates.iter().all(|c| c.stage >= 1) {
            "the second stage's first step"
        } else {
            "the end of the run's only stage"
        };
        write!(
            f,
            "the data chose the {} rim (data term above its noise floor at {at}: {})",
            self.chosen,
            each.join(", ")
        )
    }
}

/// The choice recorded in run directory `dir` ([`CHOICE_FILE`]), `None` when it has none (one start ran).
///
/// # Errors
/// [`OptimError::Checkpoint`] for a file that cannot be read or parsed.
pub fn saved_choice(dir: &Path) -> Result<Option<StartChoice>> {
    let path = dir.join(CHOICE_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let error = |message: String| OptimError::Checkpoint { path: path.clone(), message };
    let bytes = std::fs::read(&path).map_err(|e| error(e.to_string()))?;
    serde_json::from_slice(&bytes).map(Some).map_err(|e| error(e.to_string()))
}

/// The misfit of a run at the point of comparison: the normalised data term less its noise floor at the
/// first step of stage 1, `None` while the run has not reached it. A run that ended within its first
/// stage is judged at its last step (`finished`).
pub fn misfit_at_choice(log: &RunLog, finished: bool) -> Option<(f64, u32)> {
    let misfit = |r: &crate::IterationRecord| (r.data - r.noise_floor.unwrap_or(0.0), r.stage);
    match log.iterations.iter().find(|r| r.stage >= 1) {
        Some(r) => Some(misfit(r)),
        None if finished => log.iterations.last().map(misfit),
        None => None,
    }
}

/// How a candidate's run ended.
enum End {
    /// It reached the point of comparison (or finished before it).
    Judged(Candidate, ReconstructParams),
    /// The caller's progress hook stopped it: the whole run stops.
    Interrupted(Outcome),
}

/// Runs each candidate start to the point of comparison in `dir/start_candidates/<rim>` (resuming it
/// where a checkpoint is already there), moves the one with the lower misfit into `dir` and resumes it
/// there. Without a run directory the candidates run in a temporary one, removed at the end.
///
/// # Errors
/// Those of [`crate::reconstruct_with`] and [`crate::resume`] for either run, I/O in the directory.
pub(super) fn run(
    prepared: &Prepared,
    config: &Config,
    params: &ReconstructParams,
    candidates: Vec<(StartRim, SurfaceMesh)>,
    mut hooks: Hooks<'_>,
) -> Result<Outcome> {
    let (dir, temporary) = match &params.out_dir {
        Some(dir) => (dir.clone(), false),
        None => {
            // Unique to this run: runs without a directory may go on in parallel in one process (Python threads).
            static RUNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
            let n = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let dir = std::env::temp_dir().join(format!("nlos-start-choice-{}-{n}", std::process::id()));
            // Left by an earlier process of the same id: nothing in it is this run's.
            let _ = std::fs::remove_dir_all(&dir);
            (dir, true)
        }
    };
    let mut judged = Vec::new();
    for (rim, mesh) in &candidates {
        let sub = dir.join(CANDIDATES_DIR).join(rim.to_string());
        match run_candidate(prepared, config, params, *rim, mesh, &sub, &mut hooks)? {
            End::Judged(candidate, params) => judged.push((candidate, params, sub)),
            End::Interrupted(outcome) => return Ok(outcome),
        }
    }
    // Equal misfits keep the first (the receding rim, the default of every other start).
    let best = (0..judged.len()).fold(0, |b, i| if judged[i].0.misfit < judged[b].0.misfit { i } else { b });
    let choice = StartChoice { chosen: judged[best].0.rim, candidates: judged.iter().map(|j| j.0.clone()).collect() };
    let (_, chosen_params, sub) = judged.swap_remove(best);
    let outcome = if temporary {
        let outcome = crate::resume(&prepared.measured, &chosen_params, hooks);
        // A temporary directory is ours alone: nothing in it is the user's.
        let _ = std::fs::remove_dir_all(&dir);
        outcome?
    } else {
        move_files(&sub, &dir)?;
        let text = serde_json::to_vec_pretty(&choice)
            .map_err(|e| OptimError::Checkpoint { path: dir.join(CHOICE_FILE), message: e.to_string() })?;
        write_atomic(&dir.join(CHOICE_FILE), &text)?;
        crate::resume(&prepared.measured, &ReconstructParams { out_dir: Some(dir), ..chosen_params }, hooks)?
    };
    Ok(outcome)
}

/// One candidate's run from `mesh` in `sub`, to the point of comparison: the caller's progress hook sees
/// every step, and stopping it stops the whole run.
fn run_candidate(
    prepared: &Prepared,
    config: &Config,
    params: &ReconstructParams,
    rim: StartRim,
    mesh: &SurfaceMesh,
    sub: &Path,
    hooks: &mut Hooks<'_>,
) -> Result<End> {
    create_dir(sub)?;
    let params =
        ReconstructParams { out_dir: Some(sub.to_owned()), ..prepared.with_start_response(config, params, mesh)? };
    let judge = |log: &RunLog, finished: bool| {
        misfit_at_choice(log, finished).map(|(misfit, stage)| Candidate {
            rim,
            start_faces: mesh.n_faces(),
            misfit,
            stage,
        })
    };
    // A resumed choice: a candidate already at its point of comparison is not run again.
    let resuming = sub.join(CHECKPOINT_FILE).exists();
    if resuming
        && let Some(log) = read_log(&sub.join(RUN_LOG_FILE))
        && let Some(candidate) = judge(&log, false)
    {
        return Ok(End::Judged(candidate, params));
    }
    if !resuming {
        nlos_mesh::io::save(mesh, sub.join(INIT_FILE))?;
    }
    let (reached, interrupted) = (Cell::new(false), Cell::new(false));
    let mut user = hooks.progress.as_deref_mut();
    let mut stop_at_choice = |p: &Progress| {
        if p.event == ProgressEvent::Iteration && p.stage >= 1 {
            reached.set(true);
        }
        if user.as_mut().is_some_and(|f| f(p).is_break()) {
            interrupted.set(true);
        }
        if p.event == ProgressEvent::BlockEnd && (reached.get() || interrupted.get()) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    // Reborrowed for this run only (the object's lifetime shortened to the borrow's).
    let evolve: Option<&mut dyn crate::Evolve> = match hooks.evolve.as_mut() {
        Some(e) => Some(&mut **e),
        None => None,
    };
    let inner = Hooks { progress: Some(&mut stop_at_choice), evolve };
    let outcome = if resuming {
        crate::resume(&prepared.measured, &params, inner)?
    } else {
        crate::reconstruct_with(&prepared.measured, mesh, &params, inner)?
    };
    if interrupted.get() {
        return Ok(End::Interrupted(outcome));
    }
    let finished = outcome.stop != crate::StopReason::Interrupted;
    let candidate = judge(&outcome.log, finished).ok_or_else(|| OptimError::Checkpoint {
        path: sub.join(RUN_LOG_FILE),
        message: "the candidate start's run stopped before the point of comparison".into(),
    })?;
    Ok(End::Judged(candidate, params))
}

/// The run log at `path`, `None` when it is missing or unreadable (the candidate then runs on).
fn read_log(path: &Path) -> Option<RunLog> {
    serde_json::from_slice(&std::fs::read(path).ok()?).ok()
}

/// Moves every file of `from` into `to` (replacing files of the same name), then removes `from`.
fn move_files(from: &Path, to: &Path) -> Result<()> {
    let io =
        |path: PathBuf| move |source| OptimError::Io { path, fix: "check that the run directory is writable", source };
    for entry in std::fs::read_dir(from).map_err(io(from.to_owned()))? {
        let entry = entry.map_err(io(from.to_owned()))?;
        if entry.file_type().map_err(io(entry.path()))?.is_file() {
            std::fs::rename(entry.path(), to.join(entry.file_name())).map_err(io(entry.path()))?;
        }
    }
    std::fs::remove_dir(from).map_err(io(from.to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the command prints: the winner, each candidate's misfit, and where they were compared (in the
    /// user's 1-based stages).
    #[test]
    fn the_choice_says_which_won_and_where_it_was_judged() {
        let candidate = |rim, misfit, stage| Candidate { rim, start_faces: 10, misfit, stage };
        let mut choice = StartChoice {
            chosen: StartRim::Measured,
            candidates: vec![candidate(StartRim::Receding, 0.0109, 1), candidate(StartRim::Measured, 0.0058, 1)],
        };
        assert_eq!(
            choice.to_string(),
            "the data chose the measured rim (data term above its noise floor at the second stage's first step: \
             receding 0.01090, measured 0.00580)"
        );
        choice.candidates[0].stage = 0;
        assert!(choice.to_string().contains("at the end of the run's only stage"), "{choice}");
    }

    /// The first step of stage 1 is the point of comparison; a run still in stage 0 has none, unless it
    /// finished there (then its last step).
    #[test]
    fn the_misfit_is_taken_at_the_second_stages_first_step() {
        let record = |stage, data, floor| crate::IterationRecord {
            iteration: 0,
            stage,
            block: 0,
            kind: crate::StepKind::Shape,
            loss: data,
            data,
            regulariser: 0.0,
            reg_weight: 0.0,
            scale: 1.0,
            step_size: 0.0,
            faces: 1,
            vertices: 3,
            time_s: 0.0,
            noise_floor: floor,
        };
        let mut log =
            RunLog { iterations: vec![record(0, 0.5, Some(0.1)), record(0, 0.3, Some(0.1))], ..RunLog::default() };
        assert_eq!(misfit_at_choice(&log, false), None);
        assert_eq!(misfit_at_choice(&log, true), Some((0.3 - 0.1, 0)));
        log.iterations.push(record(1, 0.25, Some(0.2)));
        log.iterations.push(record(1, 0.21, Some(0.2)));
        assert_eq!(misfit_at_choice(&log, false), Some((0.25 - 0.2, 1)));
        log.iterations[2].noise_floor = None;
        assert_eq!(misfit_at_choice(&log, false), Some((0.25, 1)), "an L2 fit: the data term itself");
    }
}
