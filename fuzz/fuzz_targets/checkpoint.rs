//! Fuzz target: a run's checkpoint (`checkpoint.json`, read by `nlos reconstruct --resume`) from arbitrary
//! bytes, through `resume` on a small capture. Any panic is a bug; every input must give a typed error (a
//! checkpoint that passes every check would have to match the capture's fingerprint and the settings).
#![no_main]

use libfuzzer_sys::fuzz_target;
use nlos_optim::{Hooks, ReconstructParams, resume};

#[path = "common/mod.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join(format!("nlos-fuzz-checkpoint-{}", std::process::id()));
    if std::fs::create_dir_all(&dir).is_err() || std::fs::write(dir.join("checkpoint.json"), data).is_err() {
        return;
    }
    let params = ReconstructParams { out_dir: Some(dir), ..ReconstructParams::default() };
    let _ = resume(common::capture(), &params, Hooks::default());
});
