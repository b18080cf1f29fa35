//! Test support for the workspace: where the shared data live, and what a test does when they do not.
//!
//! The real captures, ground-truth meshes and reference transients are not in the repository; they live
//! in `../shared/data` beside the checkout (or under `$NLOS_SHARED_DATA`). A test that needs one asks
//! [`shared`]:
//!
//! ```no_run
//! let Some(bunny) = nlos_testdata::shared("meshes/bunny_centered.obj") else { return };
//! ```
//!
//! When the file is absent the test is **skipped visibly**: one line goes straight to the terminal (past
//! the test harness's output capture) with the number of skips so far in this `cargo test` run, and one
//! line is appended to `target/nlos-data-skips-<pid of cargo>.log` (every test binary of a run is a child
//! of the same `cargo` process), which `cargo xtask test` counts and prints once at the end of the run. With `NLOS_REQUIRE_DATA=1` (set by
//! CI) an absent file is a failure instead, so a missing data folder can never pass as green.
//!
//! [`mat5`] writes MATLAB level-5 MAT files, so that tests can make the inputs of the MAT readers;
//! [`scenes`] makes the synthetic meshes the benchmarks and examples share.

pub mod mat5;
pub mod scenes;

use std::io::Write;
use std::path::{Path, PathBuf};

/// The environment variable that turns a skip for want of data into a failure.
pub const REQUIRE_DATA: &str = "NLOS_REQUIRE_DATA";

/// The environment variable naming the shared data folder (default: `../shared/data` beside the workspace).
pub const SHARED_DATA: &str = "NLOS_SHARED_DATA";

/// The prefix of the files (under the target directory) where skips are logged, one line each; the
/// file of a `cargo test` run is `{SKIP_LOG}-{pid of cargo}.log`.
pub const SKIP_LOG: &str = "nlos-data-skips";

/// The workspace root (this crate lives in `crates/nlos-testdata`).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The shared data folder: `$NLOS_SHARED_DATA`, else `../shared/data` beside the workspace.
pub fn root() -> PathBuf {
    match std::env::var_os(SHARED_DATA) {
        Some(dir) => PathBuf::from(dir),
        None => workspace_root().join("../shared/data"),
    }
}

/// `true` when `NLOS_REQUIRE_DATA` is set to anything but `0` or the empty string.
pub fn data_required() -> bool {
    std::env::var(REQUIRE_DATA).is_ok_and(|v| !v.is_empty() && v != "0")
}

/// The path of `rel` under the shared data folder, or `None` when it is absent — after recording the
/// skip (see the crate documentation).
///
/// # Panics
/// When the file is absent and `NLOS_REQUIRE_DATA=1`: CI must not pass without its data.
pub fn shared(rel: &str) -> Option<PathBuf> {
    let path = root().join(rel);
    if path.exists() {
        Some(path)
    } else {
        skip(&format!("{} is absent", path.display()));
        None
    }
}

/// All of `rels` under the shared data folder, or `None` (one skip recorded) when any is absent.
///
/// # Panics
/// As [`shared`].
pub fn shared_all<const N: usize>(rels: [&str; N]) -> Option<[PathBuf; N]> {
    let paths = rels.map(|rel| root().join(rel));
    let missing: Vec<String> = paths.iter().filter(|p| !p.exists()).map(|p| p.display().to_string()).collect();
    if missing.is_empty() {
        Some(paths)
    } else {
        skip(&format!("{} absent", missing.join(", ")));
        None
    }
}

/// The first of `names` found on `PATH` (or the file named by the environment variable `env`, when set),
/// or `None` — after recording the skip — when none is installed. A tool a test needs is an input like
/// the shared data: CI installs it, and under `NLOS_REQUIRE_DATA=1` its absence fails.
///
/// # Panics
/// As [`shared`].
pub fn tool(env: &str, names: &[&str]) -> Option<PathBuf> {
    if let Some(path) = std::env::var_os(env) {
        return Some(PathBuf::from(path));
    }
    let paths = std::env::var_os("PATH").unwrap_or_default();
    let found = names.iter().find_map(|name| std::env::split_paths(&paths).map(|d| d.join(name)).find(|p| p.is_file()));
    if found.is_none() {
        skip(&format!("none of {} is installed (or set {env})", names.join(", ")));
    }
    found
}

/// Records that the running test skipped for want of data: `reason` names what is missing.
///
/// # Panics
/// With `NLOS_REQUIRE_DATA=1`, always.
pub fn skip(reason: &str) {
    let test = std::thread::current().name().unwrap_or("?").to_owned();
    let hint = format!("put the shared data at {} or set {SHARED_DATA}", root().display());
    assert!(!data_required(), "{test}: {reason}, and {REQUIRE_DATA} is set ({hint})");
    let line = format!("{} :: {test}: {reason}", exe_name());
    let mut count = None;
    if let Some(log) = skip_log() {
        if let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(&log) {
            let _ = writeln!(f, "{line}");
        }
        count = std::fs::read_to_string(&log).ok().map(|text| text.lines().count());
    }
    let count = count.map_or_else(String::new, |n| format!(" (skip {n} of this cargo run)"));
    // Straight to the terminal: `eprintln!` would be captured by the harness and shown only on failure.
    let _ = writeln!(std::io::stderr(), "nlos: SKIPPED for want of shared data{count}: {line} ({hint})");
}

/// `target/nlos-data-skips-<parent pid>.log` for a test, bench or example binary under
/// `target/<profile>/{deps,examples}` (the parent is the `cargo` process that runs it).
pub fn skip_log() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let dir = exe.parent()?;
    let name = dir.file_name()?.to_str()?;
    if name != "deps" && name != "examples" {
        return None;
    }
    let cargo = std::os::unix::process::parent_id();
    Some(dir.parent()?.parent()?.join(format!("{SKIP_LOG}-{cargo}.log")))
}

fn exe_name() -> String {
    let exe = std::env::current_exe().ok();
    let stem = exe.as_deref().and_then(Path::file_stem).and_then(|s| s.to_str()).unwrap_or("?");
    // Cargo appends `-<hash>` to test binaries.
    stem.rsplit_once('-').map_or(stem, |(name, _)| name).to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_root_is_found() {
        assert!(workspace_root().join("crates/nlos-testdata/Cargo.toml").exists());
    }

    #[test]
    fn the_log_lies_in_the_target_directory() {
        let log = skip_log().expect("a test binary lives in target/<profile>/deps");
        let name = log.file_name().and_then(|n| n.to_str()).expect("a file name");
        assert!(name.starts_with(SKIP_LOG) && name.ends_with(".log"), "{name}");
    }
}
