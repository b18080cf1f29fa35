//! Planes rendered with the project's renderer (`nlos-render`: box kernel, confocal scan, Lambertian,
//! noise-free adaptive quadrature), reconstructed by LCT, f-k and FBP: the depth must come out within one
//! bin, at depths that put the onset at different fractions of a bin, and without a systematic offset
//! (a half-bin or resampling shift in a method would show as a mean error of ±¼ bin or more).

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_init::{FbpParams, FkParams, Gate, LctParams, SurfaceParams, Volume, fbp, fk, lct, volume_to_surface};
use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// Confocal capture of a Lambertian square (side `side`, centred on the z axis) at depth `d`, facing the
/// wall, on an `n × n` grid over `[−hw, hw]²`, `bins` bins of `bin` metres of path from path 0.
fn rendered_plane(n: usize, hw: f64, d: f32, side: f32, bin: f64, bins: usize) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(n, n, hw, hw).expect("grid"));
    let time = TimeAxis::new(0.0, bin, bins).expect("axis");
    let h = side / 2.0;
    // Normal (v1 − v0) × (v2 − v0) = −z: the square faces the wall.
    let p = [Vec3::new(-h, -h, d), Vec3::new(h, h, d), Vec3::new(h, -h, d), Vec3::new(-h, h, d)];
    let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
    let r = Renderer::new(&p, &[[0, 1, 2], [0, 3, 1]], &scan, &time, params).expect("renderer");
    r.forward_transient(&Lambertian::new(1.0f32).expect("albedo")).expect("forward")
}

/// Median depth of the kept columns that face the square (|x|, |y| < `inner`), so that the edge of the
/// square, where every method blurs, does not enter.
fn median_depth_inside(vol: &Volume, inner: f64) -> f64 {
    let s = volume_to_surface(vol, &SurfaceParams::default()).expect("surface");
    let mut ds: Vec<f64> = (0..s.nx * s.ny)
        .filter(|&c| s.mask[c])
        .filter(|&c| vol.x.at(c % vol.nx).abs() < inner && vol.y.at(c / vol.nx).abs() < inner)
        .map(|c| s.depth[c] as f64)
        .collect();
    assert!(ds.len() > 20, "only {} kept columns face the square", ds.len());
    ds.sort_by(f64::total_cmp);
    ds[ds.len() / 2]
}

#[test]
fn rendered_planes_within_one_bin_without_offset() {
    let bin = 0.0048; // path; one depth bin = 2.4 mm
    let depth_bin = bin / 2.0;
    // Depths whose onset bin 2d/Δ has fractional part 0.1, 0.35, 0.6 and 0.85.
    let depths: Vec<f64> = [0.1, 0.35, 0.6, 0.85].iter().map(|f| (160.0 + f) * bin / 2.0).collect();
    let mut errors = [Vec::new(), Vec::new(), Vec::new()];
    for &d in &depths {
        let d = d as f32 as f64;
        let t = rendered_plane(32, 0.25, d as f32, 0.3, bin, 256);
        let l = median_depth_inside(
            &lct(&t, &LctParams { gate: Gate::None, ..LctParams::default() }).expect("reconstruction"),
            0.1,
        );
        let f = median_depth_inside(
            &fk(&t, &FkParams { gate: Gate::None, ..FkParams::default() }).expect("reconstruction"),
            0.1,
        );
        let b = median_depth_inside(
            &fbp(&t, &FbpParams { gate: Gate::None, ..FbpParams::default() }).expect("reconstruction"),
            0.1,
        );
        eprintln!(
            "plane at {d:.5} m (onset bin {:.2}): LCT {l:.5} ({:+.2} bins), f-k {f:.5} ({:+.2}), FBP {b:.5} ({:+.2})",
            2.0 * d / bin,
            (l - d) / depth_bin,
            (f - d) / depth_bin,
            (b - d) / depth_bin
        );
        for (e, v) in errors.iter_mut().zip([l, f, b]) {
            e.push((v - d) / depth_bin);
        }
    }
    for (name, e) in ["LCT", "f-k", "FBP"].iter().zip(&errors) {
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        eprintln!("{name}: errors {e:.2?} bins, mean {mean:+.3}");
        // Each within one (depth) bin of the truth.
        assert!(e.iter().all(|v| v.abs() <= 1.0), "{name}: errors {e:?} bins");
        // Over onsets spread across a bin the voxel quantisation averages out; a half-bin convention
        // error or a resampling shift would not.
        assert!(mean.abs() <= 0.35, "{name}: mean error {mean} bins");
    }
}

#[test]
fn exhaustive_fbp_finds_a_rendered_plane() {
    // 3 × 3 laser spots, 16 × 16 sensor spots; a 0.2 m square at 0.3 m facing the wall.
    let bin = 0.0048;
    let d = 0.3f32;
    let lasers = PointSet::wall_grid(3, 3, 0.1, 0.1).expect("lasers");
    let sensors = PointSet::wall_grid(16, 16, 0.25, 0.25).expect("sensors");
    let scan = Scan::exhaustive(lasers, sensors);
    let time = TimeAxis::new(0.0, bin, 200).expect("axis");
    let h = 0.1f32;
    let p = [Vec3::new(-h, -h, d), Vec3::new(h, h, d), Vec3::new(h, -h, d), Vec3::new(-h, h, d)];
    let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
    let r = Renderer::new(&p, &[[0, 1, 2], [0, 3, 1]], &scan, &time, params).expect("renderer");
    let t = r.forward_transient(&Lambertian::new(1.0f32).expect("albedo")).expect("forward");
    let vol = fbp(&t, &FbpParams { gate: Gate::None, max_depth: Some(0.45), ..FbpParams::default() }).expect("fbp");
    assert_eq!((vol.nx, vol.ny), (16, 16));
    let s = volume_to_surface(&vol, &SurfaceParams::default()).expect("surface");
    let kept: Vec<usize> = (0..256).filter(|&c| s.mask[c]).collect();
    let inside = |c: usize| vol.x.at(c % 16).abs() < 0.1 && vol.y.at(c / 16).abs() < 0.1;
    let mut ds: Vec<f64> = kept.iter().filter(|&&c| inside(c)).map(|&c| s.depth[c] as f64).collect();
    ds.sort_by(f64::total_cmp);
    assert!(!ds.is_empty(), "no kept column faces the square");
    let median = ds[ds.len() / 2];
    let on = ds.len();
    let square = (0..256).filter(|&c| inside(c)).count();
    eprintln!(
        "exhaustive FBP: median depth {median:.4} m (true {d}), kept {} columns, {on} of the {square} facing the square",
        kept.len()
    );
    assert!((median - d as f64).abs() <= bin / 2.0, "depth {median}");
    // The kept region is the square: most of its columns, few others.
    assert!(on as f64 >= 0.8 * square as f64 && kept.len() - on <= square / 4, "kept {} / on {on}", kept.len());
}
