//! Fuzz target: MAT v5 detection and the three MAT-based readers (Stanford LCT, Tsai 2019, Stanford f-k)
//! on arbitrary bytes. Any panic is a bug; every input must give `Ok` or a typed error.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nlos_transient::formats::{Format, detect_bytes, read_bytes_as};

#[path = "common/mod.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let bytes = common::mat_v5(data);
    // An in-memory name: no sibling `tof.mat` is looked up.
    let file = Path::new("<memory>");
    let _ = detect_bytes(&bytes, file);
    for format in [Format::LctMat, Format::TsaiMat, Format::FkMat] {
        let _ = read_bytes_as(&bytes, format, file);
    }
});
