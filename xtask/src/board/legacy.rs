//! Sections written before rows recorded their inputs: they name only the commit they ran on (`code: commit
//! `…``). Such a section describes the code as it is when its inputs computed at that commit (in a git
//! worktree of it, under `target/board-legacy/`) equal the inputs now, the shared data excepted (they are not
//! in git; the board assumes them unchanged since). `cargo xtask accept --stale` then writes its inputs line
//! ([`rekeyed`]) instead of re-running it.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use super::inputs::{Fingerprints, INPUTS_LINE, Inputs};
use super::page::CODE_LINE;

/// The commit a section names, unless it ran on uncommitted changes.
pub(crate) fn commit_of(body: &str) -> Option<&str> {
    let line = body.lines().find_map(|l| l.strip_prefix(CODE_LINE))?;
    let (commit, rest) = line.split_once('`')?;
    rest.is_empty().then_some(commit)
}

thread_local! {
    /// Fingerprints of each commit's worktree, computed once per process.
    static AT: RefCell<HashMap<String, Result<Fingerprints, String>>> = RefCell::new(HashMap::new());
}

/// A worktree of `commit` under `target/board-legacy/` (made once, then reused).
fn worktree(root: &Path, commit: &str) -> Result<PathBuf, String> {
    let dir = root.join("target/board-legacy").join(commit);
    if dir.join("Cargo.toml").exists() {
        return Ok(dir);
    }
    let out = Command::new("git")
        .arg("-C")
        .arg(root)
        .args(["worktree", "add", "--force", "--detach"])
        .arg(&dir)
        .arg(commit)
        .output()
        .map_err(|e| format!("cannot run git: {e}"))?;
    if out.status.success() {
        Ok(dir)
    } else {
        Err(format!("commit {commit} not found ({})", String::from_utf8_lossy(&out.stderr).trim()))
    }
}

/// The inputs of row `name` now, when its legacy section ran on code that is the same as now; why not
/// otherwise.
pub(crate) fn equivalent(fp: &mut Fingerprints, name: &str, body: &str) -> Result<Inputs, String> {
    let Some(commit) = commit_of(body) else {
        return Err(if body.contains(CODE_LINE) {
            "ran on uncommitted changes".to_string()
        } else {
            "no inputs recorded".to_string()
        });
    };
    let commands = super::commands_of(body);
    let now = super::row_inputs(fp, name, &commands)?;
    let root = crate::workspace_root();
    let then = AT.with(|at| {
        let mut at = at.borrow_mut();
        let old =
            at.entry(commit.to_string()).or_insert_with(|| worktree(&root, commit).map(|d| Fingerprints::new(&d)));
        match old {
            Ok(old) => super::row_inputs(old, name, &commands),
            Err(e) => Err(e.clone()),
        }
    });
    let then = then.map_err(|e| format!("at {commit}: {e}"))?;
    let differ: Vec<&str> = now
        .0
        .iter()
        .filter(|(k, v)| !k.starts_with("data ") && then.0.get(*k) != Some(*v))
        .map(|(k, _)| k.as_str())
        .collect();
    if differ.is_empty() { Ok(now) } else { Err(format!("changed since {commit}: {}", differ.join(", "))) }
}

/// `body` with its inputs line after its code line.
pub(crate) fn rekeyed(body: &str, inputs: &Inputs) -> String {
    let mut out = String::with_capacity(body.len() + 200);
    for line in body.lines() {
        if line.starts_with(INPUTS_LINE) {
            continue;
        }
        out.push_str(line);
        out.push('\n');
        if line.starts_with(CODE_LINE) {
            out.push_str(&inputs.line());
            out.push('\n');
        }
    }
    out
}
