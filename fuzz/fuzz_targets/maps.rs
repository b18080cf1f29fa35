//! Fuzz target: the ground-truth map readers of `nlos eval --gt-depth/--gt-normal` (`.npy`, `.mat`, EXR; NaN
//! and Inf as no value), both layouts (`MapLayout`), and the maps' validation and scoring against
//! themselves. The first byte picks the reader. Any panic is a bug.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nlos_mesh::map_metrics::{MapGrid, MapLayout, Maps, evaluate_maps};
use nlos_transient::formats::{exr, mat, npy};

fuzz_target!(|data: &[u8]| {
    let Some((&which, bytes)) = data.split_first() else { return };
    let file = Path::new("<memory>");
    let read = match which % 3 {
        0 => npy::decode_npy_map(bytes, file),
        1 => mat::decode_array(bytes, file, None).map(|(v, d, _)| (v, d)),
        _ => exr::decode_image(bytes, file),
    };
    let Ok((values, shape)) = read else { return };
    for layout in [MapLayout::Image, MapLayout::Dlct] {
        let maps = match shape.as_slice() {
            &[rows, cols] if rows.saturating_mul(cols) <= 1 << 16 => {
                let (depth, width, height) = layout.depth_to_image(&values, [rows, cols]);
                let grid = MapGrid { width, height, x_range: [-0.5, 0.5], y_range: [-0.5, 0.5] };
                Maps { grid, depth, normals: None }
            }
            &[rows, cols, 3] if rows.saturating_mul(cols) <= 1 << 16 => {
                let (normals, width, height) = layout.normals_to_image(&values, [rows, cols]);
                let grid = MapGrid { width, height, x_range: [-0.5, 0.5], y_range: [-0.5, 0.5] };
                let depth = normals.iter().map(|n| if n.is_finite() { 0.5 } else { f32::NAN }).collect();
                Maps { grid, depth, normals: Some(normals) }
            }
            _ => return,
        };
        let _ = maps.validate("<memory>");
        let _ = evaluate_maps(&maps, &maps, 0.005);
    }
});
