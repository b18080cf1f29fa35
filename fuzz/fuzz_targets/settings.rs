//! Fuzz target: a settings file (`nlos reconstruct --config`, a run's `settings.toml` on `--resume`) as TOML
//! text → `Config`, then everything that resolves it against a capture (`Prepared::new`, `params`, the
//! start's surface settings). Any panic is a bug; every input must give `Ok` or a typed error.
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use nlos_optim::pipeline::{Config, Prepared, Volumetric};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// A small confocal capture: 4 × 4 points, 64 bins of integer counts with a bump.
fn capture() -> &'static Transient {
    static CAPTURE: OnceLock<Transient> = OnceLock::new();
    CAPTURE.get_or_init(|| {
        let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.25, 0.25).expect("grid"));
        let time = TimeAxis::new(0.0, 0.02, 64).expect("axis");
        let data = (0..16 * 64usize).map(|i| if (i % 64).abs_diff(40) < 3 { 20.0 } else { 1.0 }).collect();
        Transient::new(scan, time, data).expect("capture")
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(config) = Config::from_toml(text) else { return };
    let _ = config.to_toml();
    let Ok(prepared) = Prepared::new(capture().clone(), &config) else { return };
    let _ = prepared.params(&config, None);
    let _ = prepared.surface_params(Volumetric::Lct);
});
