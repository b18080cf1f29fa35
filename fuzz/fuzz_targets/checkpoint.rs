//! Fuzz target: a run's checkpoint (`checkpoint.json`, read by `nlos reconstruct --resume`) from arbitrary
//! bytes, through `resume` on a small capture. Any panic is a bug; every input must give a typed error (a
//! checkpoint that passes every check would have to match the capture's fingerprint and the settings).
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use nlos_optim::{Hooks, ReconstructParams, resume};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

fn capture() -> &'static Transient {
    static CAPTURE: OnceLock<Transient> = OnceLock::new();
    CAPTURE.get_or_init(|| {
        let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.25, 0.25).expect("grid"));
        let time = TimeAxis::new(0.0, 0.02, 64).expect("axis");
        Transient::new(scan, time, vec![1.0; 16 * 64]).expect("capture")
    })
}

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join(format!("nlos-fuzz-checkpoint-{}", std::process::id()));
    if std::fs::create_dir_all(&dir).is_err() || std::fs::write(dir.join("checkpoint.json"), data).is_err() {
        return;
    }
    let params = ReconstructParams { out_dir: Some(dir), ..ReconstructParams::default() };
    let _ = resume(capture(), &params, Hooks::default());
});
