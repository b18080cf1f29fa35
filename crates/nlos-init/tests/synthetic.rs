//! Synthetic captures rendered in the test by quadrature: a Lambertian square at a known depth.

use nlos_init::{
    CarveParams, FbpParams, FkParams, Gate, LctParams, SurfaceParams, carve, fbp, fk, lct, volume_to_surface,
};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// Confocal transient of a Lambertian square of side `side` parallel to the wall at depth `d`, facing
/// it, by midpoint quadrature on a `step` grid: each area element `dA` at distance `R` from scan point
/// `p` adds `cos²θ_wall · cos²θ_object / R⁴ · dA = d⁴ / R⁸ · dA` at path `2R` (both legs, unit albedo).
fn plane_transient(n: usize, half_width: f64, d: f64, side: f64, bin: f64, bins: usize) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(n, n, half_width, half_width).expect("grid"));
    let mut t = Transient::zeros(scan, TimeAxis::new(0.0, bin, bins).expect("axis")).expect("zeros");
    let step = 0.002;
    let k = (side / step).round() as usize;
    for m in 0..n * n {
        let p = t.scan().measurement(m).laser;
        let h = t.histogram_mut(m);
        for a in 0..k {
            for b in 0..k {
                let x = -side / 2.0 + (a as f64 + 0.5) * step;
                let y = -side / 2.0 + (b as f64 + 0.5) * step;
                let r2 = (x - p.x as f64).powi(2) + (y - p.y as f64).powi(2) + d * d;
                let r = r2.sqrt();
                let bin_i = (2.0 * r / bin) as usize;
                if bin_i < bins {
                    h[bin_i] += (d.powi(4) / r2.powi(4) * step * step) as f32;
                }
            }
        }
    }
    t
}

#[test]
fn lct_and_fk_find_a_plane_within_one_bin() {
    let (d, bin) = (0.4, 0.0048);
    let t = plane_transient(32, 0.25, d, 0.3, bin, 256);
    let bin_depth = bin / 2.0;
    let vol = lct(&t, &LctParams { gate: Gate::None, ..LctParams::default() }).expect("lct");
    let s = volume_to_surface(&vol, &SurfaceParams::default()).expect("surface");
    let median = s.median_depth().expect("kept");
    eprintln!("LCT plane: median depth {median:.4} m (true {d}), {} columns", s.mask.iter().filter(|&&k| k).count());
    let vol = fk(&t, &FkParams { gate: Gate::None, ..FkParams::default() }).expect("fk");
    let s2 = volume_to_surface(&vol, &SurfaceParams::default()).expect("surface");
    let median2 = s2.median_depth().expect("kept");
    eprintln!("f-k plane: median depth {median2:.4} m (true {d})");
    let vol = fbp(&t, &FbpParams { gate: Gate::None, ..FbpParams::default() }).expect("fbp");
    let median3 = volume_to_surface(&vol, &SurfaceParams::default()).expect("surface").median_depth().expect("kept");
    eprintln!("FBP plane: median depth {median3:.4} m (true {d})");
    assert!((median3 - d).abs() <= 2.0 * bin_depth, "FBP depth {median3} vs {d}");
    let vol = carve(&t, &CarveParams { gate: Gate::None, ..CarveParams::default() }).expect("carve");
    let s4 = volume_to_surface(&vol, &SurfaceParams::default()).expect("surface");
    let median4 = s4.median_depth().expect("kept");
    eprintln!(
        "carving plane: median depth {median4:.4} m (true {d}), {} columns",
        s4.mask.iter().filter(|&&k| k).count()
    );
    assert!((median4 - d).abs() <= 2.0 * bin_depth, "carving depth {median4} vs {d}");
    assert!((median - d).abs() <= bin_depth, "LCT depth {median} vs {d}");
    assert!((median2 - d).abs() <= bin_depth, "f-k depth {median2} vs {d}");
}
