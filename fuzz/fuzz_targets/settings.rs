//! Fuzz target: a settings file (`nlos reconstruct --config`, a run's `settings.toml` on `--resume`) as TOML
//! text → `Config`, then everything that resolves it against a capture (`Prepared::new`, `params`, the
//! start's surface settings). Any panic is a bug; every input must give `Ok` or a typed error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nlos_optim::pipeline::{Config, Method, Prepared};

#[path = "common/mod.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(config) = Config::from_toml(text) else { return };
    let _ = config.to_toml();
    let Ok(prepared) = Prepared::new(common::capture().clone(), &config) else { return };
    let _ = prepared.params(&config, None);
    let _ = prepared.surface_params(Method::Lct);
});
