//! Fuzz target: the Z-NLOS `.mat` reader (NeTF's preprocessing: `data`, `cameraGridPositions`, `deltaT`, …)
//! on arbitrary bytes, with the wall of its full grid (`cameraGridSize`). Any panic is a bug; every input must
//! give `Ok` or a typed error.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nlos_transient::formats::{Format, detect_bytes, read_bytes_as};

fuzz_target!(|data: &[u8]| {
    // A valid 128-byte little-endian v5 header before inputs that lack one, so that the fuzzer spends its
    // time in the variables.
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
    let file = Path::new("<memory>");
    let _ = detect_bytes(bytes, file);
    if let Ok(t) = read_bytes_as(bytes, Format::ZNlosMat, file) {
        let _ = t.validate();
    }
    let _ = nlos_transient::formats::mat::znlos_wall_bytes(bytes, file);
});
