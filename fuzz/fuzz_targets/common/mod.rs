//! What several fuzz targets share: MAT v5 framing and a small capture.
#![allow(dead_code)]

use std::borrow::Cow;
use std::sync::OnceLock;

use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// `data` as a MAT v5 file: inputs that do not start with the signature get a valid 128-byte little-endian
/// v5 header, so that the fuzzer spends its time in the variables.
pub fn mat_v5(data: &[u8]) -> Cow<'_, [u8]> {
    if data.starts_with(b"MATLAB") {
        return Cow::Borrowed(data);
    }
    let mut owned = vec![b' '; 128];
    owned[..6].copy_from_slice(b"MATLAB");
    owned[124..126].copy_from_slice(&0x0100u16.to_le_bytes());
    owned[126..128].copy_from_slice(b"IM");
    owned.extend_from_slice(data);
    Cow::Owned(owned)
}

/// A small confocal capture: 4 × 4 points, 64 bins of integer counts with a return at bin 40.
pub fn capture() -> &'static Transient {
    static CAPTURE: OnceLock<Transient> = OnceLock::new();
    CAPTURE.get_or_init(|| {
        let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.25, 0.25).expect("grid"));
        let time = TimeAxis::new(0.0, 0.02, 64).expect("axis");
        let data = (0..16 * 64usize).map(|i| if (i % 64).abs_diff(40) < 3 { 20.0 } else { 1.0 }).collect();
        Transient::new(scan, time, data).expect("capture")
    })
}
