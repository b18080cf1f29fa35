//! Fuzzes the `.npy` + JSON sidecar reader. The first input byte picks the mode:
//! - even: the rest is the `.npy` bytes, read with a fixed valid sidecar (a 3 × 2 confocal grid, 5 bins);
//! - odd: the rest is the sidecar JSON, read with a fixed valid `.npy` of shape (2, 3, 5).
//!
//! Also fuzzes the bare-array loader with the same bytes. Neither may panic.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nlos_transient::formats::npy;

const SIDECAR: &str = r#"{"format": "nlos-transient", "version": 1, "data": "f.npy", "dtype": "<f4", "shape": [2, 3, 5],
  "time": {"t0": 0.5, "bin_width": 0.004, "bins": 5, "includes_device_legs": false},
  "scan": {"pattern": "confocal", "points": {"grid": [3, 2], "x": [-0.25, 0.0, 0.25], "y": [-0.25, 0.25], "z": 0.0,
  "normal": [0.0, 0.0, 1.0]}, "laser_device": null, "sensor_device": null}}"#;

fn valid_npy() -> Vec<u8> {
    let data: Vec<f32> = (0..30).map(|i| i as f32).collect();
    npy::encode_npy_f32(&data, &[2, 3, 5]).unwrap_or_default()
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    let file = Path::new("fuzz.npy");
    if mode % 2 == 0 {
        let _ = npy::read(rest, SIDECAR.as_bytes(), file);
        let _ = npy::decode_npy_array(rest, file);
    } else {
        let _ = npy::read(&valid_npy(), rest, file);
    }
});
