//! Fuzz target: the general-NLOS pair reader (`data.mat` with `setup.mat` beside it: a paired scan on a curved
//! wall, its normals from a cubic surface through the spots) on arbitrary bytes. The input's first four bytes
//! say how long the `data.mat` part is (little-endian), the fifth which file `read_general_nlos` is given (it
//! finds the other beside it, both written to a scratch folder), and the rest is `data.mat` then `setup.mat`;
//! each part gets a MAT v5 header when it lacks one. Any panic is a bug; every input must give `Ok` or a
//! typed error.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nlos_transient::ReadOptions;
use nlos_transient::formats::mat::{read_general_nlos, read_general_nlos_pair};

#[path = "common/mod.rs"]
mod common;

fuzz_target!(|input: &[u8]| {
    let Some((head, rest)) = input.split_first_chunk::<5>() else { return };
    let split = (u32::from_le_bytes([head[0], head[1], head[2], head[3]]) as usize).min(rest.len());
    let which = head[4];
    let (data, setup) = rest.split_at(split);
    let (data, setup) = (common::mat_v5(data), common::mat_v5(setup));
    let dir = Path::new("<memory>");
    if let Ok(t) = read_general_nlos_pair(&data, &setup, dir, 0.0096) {
        let _ = t.validate();
    }
    // Through the files, as a user's command reads them: either file given, the other found beside it.
    let scratch = std::env::temp_dir().join(format!("nlos-fuzz-general-nlos-{}", std::process::id()));
    if std::fs::create_dir_all(&scratch).is_ok()
        && std::fs::write(scratch.join("data.mat"), &*data).is_ok()
        && std::fs::write(scratch.join("setup.mat"), &*setup).is_ok()
    {
        let given = scratch.join(if which % 2 == 0 { "data.mat" } else { "setup.mat" });
        let bytes = if which % 2 == 0 { &data } else { &setup };
        let options = ReadOptions { bin_width: Some(0.0096) };
        if let Ok(t) = read_general_nlos(bytes, &given, &options) {
            let _ = t.validate();
        }
    }
});
