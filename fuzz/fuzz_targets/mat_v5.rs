//! Fuzz target: MAT v5 detection and the three MAT-based readers (Stanford LCT, Tsai 2019, Stanford f-k)
//! on arbitrary bytes. Any panic is a bug; every input must give `Ok` or a typed error.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nlos_transient::formats::{Format, detect_bytes, read_bytes_as};

fuzz_target!(|data: &[u8]| {
    // Make most inputs look like MAT-files so the fuzzer spends its time inside the parser: inputs that
    // do not start with the signature get a valid 128-byte little-endian v5 header prepended.
    let mut owned;
    let bytes = if data.starts_with(b"MATLAB") {
        data
    } else {
        owned = vec![b' '; 128];
        owned[..6].copy_from_slice(b"MATLAB");
        owned[124..126].copy_from_slice(&0x0100u16.to_le_bytes());
        owned[126..128].copy_from_slice(b"IM");
        owned.extend_from_slice(data);
        &owned
    };
    // An in-memory name: no sibling `tof.mat` is looked up.
    let file = Path::new("<memory>");
    let _ = detect_bytes(bytes, file);
    for format in [Format::LctMat, Format::TsaiMat, Format::FkMat] {
        let _ = read_bytes_as(bytes, format, file);
    }
});
