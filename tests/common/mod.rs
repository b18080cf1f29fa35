//! Helpers shared by the cross-crate tests: the built-in fixtures, scratch directories, a short schedule.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A file of `fixtures/builtin/` (the built-in scene's ground truth, capture and start).
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/builtin").join(name)
}

/// [`fixture`] as a string argument for the command line.
pub fn fixture_arg(name: &str) -> String {
    fixture(name).to_string_lossy().into_owned()
}

/// An empty directory under the target's scratch space, unique to this test process.
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("suite-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// `nlos reconstruct` settings for a run of seconds: one stage, one block, three shape steps.
pub const FAST: [&str; 8] = [
    "--set",
    "schedule.max_stages=1",
    "--set",
    "schedule.initial_resolution=12",
    "--set",
    "schedule.max_blocks_per_stage=1",
    "--set",
    "schedule.shape_iterations=3",
];
