//! Fuzzes the OpenEXR reader with arbitrary bytes. It must return an error, never panic.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = nlos_transient::formats::exr::read(data, Path::new("fuzz.exr"));
});
