//! Fuzz target: grid detection from point lists (`PointSet::regular_grid`, `Transient::with_grid_layout`, which
//! every reader applies) on arbitrary points (f32 triples from the bytes, NaN and infinities included), and
//! the grid's spacing and bounds. Any panic is a bug.
#![no_main]

use glam::Vec3;
use libfuzzer_sys::fuzz_target;
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

fuzz_target!(|data: &[u8]| {
    let floats: Vec<f32> = data.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let points: Vec<Vec3> = floats.chunks_exact(3).take(4096).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    let set = PointSet::list(points);
    let _ = set.regular_grid();
    let _ = set.grid_dims();
    let _ = set.bounds();
    let Ok(time) = TimeAxis::new(0.0, 0.01, 4) else { return };
    if let Ok(t) = Transient::zeros(Scan::confocal(set), time) {
        let t = t.with_grid_layout();
        let _ = t.scan().lasers().grid_dims();
    }
});
