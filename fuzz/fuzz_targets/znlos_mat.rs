//! Fuzz target: the Z-NLOS `.mat` reader (NeTF's preprocessing: `data`, `cameraGridPositions`, `deltaT`, …)
//! on arbitrary bytes, with the wall of its full grid (`cameraGridSize`). Any panic is a bug; every input must
//! give `Ok` or a typed error.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nlos_transient::formats::{Format, detect_bytes, read_bytes_as};

#[path = "common/mod.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let bytes = common::mat_v5(data);
    let file = Path::new("<memory>");
    let _ = detect_bytes(&bytes, file);
    if let Ok(t) = read_bytes_as(&bytes, Format::ZNlosMat, file) {
        let _ = t.validate();
    }
    let _ = nlos_transient::formats::mat::znlos_wall_bytes(&bytes, file);
});
