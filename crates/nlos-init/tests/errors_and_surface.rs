//! Typed errors on bad input, and the geometry of the extracted surface.

use glam::Vec3;
use nlos_init::{
    Axis, FkParams, Gate, GrowReference, InitError, LctParams, SurfaceParams, Threshold, Volume, fk, lct,
    otsu_threshold, volume_to_surface,
};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

fn grid_transient() -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.2, 0.2).expect("grid"));
    Transient::zeros(scan, TimeAxis::new(0.0, 0.01, 64).expect("axis")).expect("zeros")
}

#[test]
fn exhaustive_input_is_refused_by_lct_and_fk_and_lists_by_fbp() {
    let p = PointSet::wall_grid(4, 4, 0.2, 0.2).expect("grid");
    let t = Transient::zeros(Scan::exhaustive(p.clone(), p), TimeAxis::new(0.0, 0.01, 32).expect("axis")).expect("t");
    assert!(matches!(lct(&t, &LctParams::default()), Err(InitError::NotConfocal { .. })));
    assert!(matches!(fk(&t, &FkParams::default()), Err(InitError::NotConfocal { .. })));
    // Filtered backprojection handles exhaustive scans (tests/rendered.rs), but not sensor lists.
    let list = PointSet::list(vec![Vec3::ZERO, Vec3::X, Vec3::Y]);
    let g = PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid");
    let t = Transient::zeros(Scan::exhaustive(g, list), TimeAxis::new(0.0, 0.01, 32).expect("axis")).expect("t");
    assert!(matches!(nlos_init::fbp(&t, &nlos_init::FbpParams::default()), Err(InitError::NotGrid { .. })));
}

#[test]
fn list_scans_legs_and_bad_parameters_are_typed_errors() {
    let list = PointSet::list(vec![Vec3::ZERO, Vec3::X]);
    let t = Transient::zeros(Scan::confocal(list), TimeAxis::new(0.0, 0.01, 32).expect("axis")).expect("t");
    assert!(matches!(lct(&t, &LctParams::default()), Err(InitError::NotGrid { .. })));
    let mut t = grid_transient();
    for snr in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(lct(&t, &LctParams { snr, ..LctParams::default() }), Err(InitError::InvalidParameter { .. })));
    }
    let p = LctParams { bin_merge: 0, ..LctParams::default() };
    assert!(matches!(lct(&t, &p), Err(InitError::InvalidParameter { .. })));
    let p = LctParams { bin_merge: 64, ..LctParams::default() };
    assert!(matches!(lct(&t, &p), Err(InitError::Empty { .. })));
    let p = LctParams { gate: Gate::Path(f64::NAN), ..LctParams::default() };
    assert!(matches!(lct(&t, &p), Err(InitError::InvalidParameter { .. })));
    t.time_mut().t0 = 0.005; // half a bin: not aligned with path 0
    assert!(matches!(lct(&t, &LctParams::default()), Err(InitError::TimeOrigin { .. })));
    t.time_mut().t0 = 0.0;
    t.time_mut().includes_device_legs = true;
    assert!(matches!(fk(&t, &FkParams::default()), Err(InitError::DeviceLegs)));
    // NaN smuggled in through data_mut.
    let mut t = grid_transient();
    t.data_mut()[5] = f32::NAN;
    assert!(matches!(
        lct(&t, &LctParams { gate: Gate::None, ..LctParams::default() }),
        Err(InitError::NonFinite { .. })
    ));
}

#[test]
fn time_origin_after_the_wall_is_padded() {
    // A capture starting 10 bins after the wall reconstructs like the same capture padded with zeros.
    let mut a = grid_transient();
    a.histogram_mut(27)[40] = 1.0;
    let scan = a.scan().clone();
    let mut b = Transient::zeros(scan, TimeAxis::new(0.1, 0.01, 54).expect("axis")).expect("zeros");
    b.histogram_mut(27)[30] = 1.0;
    let p = LctParams { gate: Gate::None, ..LctParams::default() };
    let (va, vb) = (lct(&a, &p).expect("a"), lct(&b, &p).expect("b"));
    assert_eq!(va.nz, vb.nz);
    for (x, y) in va.data.iter().zip(&vb.data) {
        assert!((x - y).abs() <= 1e-5 * va.data.iter().copied().fold(0.0, f32::max));
    }
}

fn flat_volume(nx: usize, ny: usize, nz: usize, bright: impl Fn(usize, usize) -> bool, iz: usize) -> Volume {
    let mut data = vec![0.0f32; nx * ny * nz];
    for iy in 0..ny {
        for ix in 0..nx {
            if bright(ix, iy) {
                data[(ix + nx * iy) * nz + iz] = 1.0;
            }
        }
    }
    Volume {
        nx,
        ny,
        nz,
        x: Axis { start: -0.1, step: 0.01 },
        y: Axis { start: -0.1, step: 0.01 },
        z: Axis { start: 0.005, step: 0.01 },
        data,
    }
}

#[test]
fn surface_faces_the_wall_and_keeps_the_largest_region() {
    // A 6 × 6 square and a 2 × 2 speck, both at depth 0.305 m.
    let vol = flat_volume(
        16,
        16,
        40,
        |x, y| (2..8).contains(&x) && (3..9).contains(&y) || (12..14).contains(&x) && (12..14).contains(&y),
        30,
    );
    let largest = SurfaceParams { min_region_fraction: 1.0, ..SurfaceParams::default() };
    let s = volume_to_surface(&vol, &largest).expect("surface");
    assert_eq!(s.mask.iter().filter(|&&k| k).count(), 36);
    assert_eq!(s.triangles.len(), 2 * 25);
    assert!((s.median_depth().expect("kept") - 0.305).abs() < 1e-6);
    for t in &s.triangles {
        let [a, b, c] = t.map(|i| s.positions[i as usize]);
        assert!((b - a).cross(c - a).z < 0.0, "triangle {t:?} faces away from the wall");
    }
    assert_eq!(s.mesh.n_faces(), 50);
    // The object settings keep regions of at least 5 % of the largest too: the speck has 4 / 36.
    let s = volume_to_surface(&vol, &SurfaceParams::object()).expect("surface");
    assert_eq!(s.triangles.len(), 2 * 25 + 2);
    let s = volume_to_surface(&vol, &SurfaceParams { min_region_fraction: 0.2, ..SurfaceParams::object() })
        .expect("surface");
    assert_eq!(s.triangles.len(), 2 * 25);
    // Without the largest-region filter both squares are kept.
    let s =
        volume_to_surface(&vol, &SurfaceParams { largest_component: false, ..SurfaceParams::default() }).expect("s");
    assert_eq!(s.triangles.len(), 2 * 25 + 2);
    // Remeshing to 2 cm edges keeps the surface at its depth.
    let p = SurfaceParams { target_edge_length: Some(0.02), ..SurfaceParams::default() };
    let s = volume_to_surface(&vol, &p).expect("remeshed");
    assert!(!s.triangles.is_empty());
    assert!(s.positions.iter().all(|p| (p.z - 0.305).abs() < 1e-4));
}

#[test]
fn empty_or_invalid_volumes_are_typed_errors() {
    let zero = flat_volume(8, 8, 8, |_, _| false, 0);
    assert!(matches!(volume_to_surface(&zero, &SurfaceParams::default()), Err(InitError::Empty { .. })));
    let mut nan = flat_volume(8, 8, 8, |_, _| true, 3);
    nan.data[7] = f32::NAN;
    assert!(matches!(volume_to_surface(&nan, &SurfaceParams::default()), Err(InitError::NonFinite { .. })));
    let mut short = flat_volume(8, 8, 8, |_, _| true, 3);
    short.data.pop();
    assert!(matches!(volume_to_surface(&short, &SurfaceParams::default()), Err(InitError::BadVolume { .. })));
    let empty = Volume { nx: 0, ..flat_volume(8, 8, 8, |_, _| true, 3) };
    assert!(matches!(volume_to_surface(&empty, &SurfaceParams::default()), Err(InitError::BadVolume { .. })));
    let one = flat_volume(8, 8, 8, |x, y| x == 3 && y == 3, 3);
    assert!(matches!(volume_to_surface(&one, &SurfaceParams::default()), Err(InitError::Empty { .. })));
    let ok = flat_volume(8, 8, 8, |_, _| true, 3);
    let bad = SurfaceParams { threshold: Threshold::Relative(2.0), ..SurfaceParams::default() };
    assert!(matches!(volume_to_surface(&ok, &bad), Err(InitError::InvalidParameter { .. })));
    let bad = SurfaceParams { target_edge_length: Some(-1.0), ..SurfaceParams::default() };
    assert!(matches!(volume_to_surface(&ok, &bad), Err(InitError::InvalidParameter { .. })));
    let bad = SurfaceParams { min_depth: Some(5.0), ..SurfaceParams::default() };
    assert!(matches!(volume_to_surface(&ok, &bad), Err(InitError::Empty { .. })));
}

#[test]
fn otsu_separates_two_populations() {
    let mut v = vec![0.1f32; 100];
    v.extend(vec![0.9f32; 30]);
    let t = otsu_threshold(&v, 256).expect("threshold");
    assert!(t > 0.1 && t <= 0.9, "{t}");
    assert_eq!(otsu_threshold(&[1.0, 1.0], 256), None);
    assert_eq!(otsu_threshold(&[f32::NAN], 256), None);
}

#[test]
fn npy_export_has_a_valid_header() {
    let v = flat_volume(3, 2, 4, |_, _| true, 1);
    let b = v.to_npy();
    assert!(b.starts_with(b"\x93NUMPY\x01\x00"));
    let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
    assert_eq!((10 + hl) % 64, 0);
    let header = std::str::from_utf8(&b[10..10 + hl]).expect("ascii");
    assert!(header.contains("'shape': (2, 3, 4)"), "{header}");
    assert_eq!(b.len(), 10 + hl + 4 * 24);
}

#[test]
fn carving_handles_exhaustive_scans_and_refuses_lists() {
    // Exhaustive 4 × 4 lasers × 4 × 4 sensors, a point at depth 0.3 above the origin: the first return of
    // each pair is at |p − l| + |p − s|.
    let g = PointSet::wall_grid(4, 4, 0.1, 0.1).expect("grid");
    let scan = Scan::exhaustive(g.clone(), g);
    let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.002, 400).expect("axis")).expect("t");
    let p = Vec3::new(0.0, 0.0, 0.3);
    for m in 0..t.measurements() {
        let me = t.scan().measurement(m);
        let path = (p - me.laser).length() + (p - me.sensor).length();
        t.histogram_mut(m)[(path / 0.002) as usize] = 1.0;
    }
    let vol = nlos_init::carve(&t, &nlos_init::CarveParams { gate: Gate::None, ..Default::default() }).expect("carve");
    let (depth, value) = vol.depth_map(None, None).expect("depth");
    let best = (0..16).max_by(|&a, &b| value[a].total_cmp(&value[b])).expect("columns");
    assert!(value[best] > 0.0);
    // Above a central column (±0.033 m off the point) the union of the carved ellipsoids reaches at least
    // the point's depth (less one bin of first-return quantisation) and not far beyond it.
    assert!((0.298..0.33).contains(&depth[5]), "{}", depth[5]);
    let list = PointSet::list(vec![Vec3::ZERO, Vec3::X]);
    let t = Transient::zeros(Scan::confocal(list), TimeAxis::new(0.0, 0.01, 32).expect("axis")).expect("t");
    assert!(matches!(nlos_init::carve(&t, &Default::default()), Err(InitError::NotGrid { .. })));
    let t = grid_transient();
    assert!(matches!(
        nlos_init::carve(&t, &nlos_init::CarveParams { gate: Gate::None, ..Default::default() }),
        Err(InitError::Empty { .. })
    ));
}

/// Regression (sensor acceptance run, 100 photons per measurement with a background): the object settings
/// grew the mask by hysteresis into the background-lifted columns and took half the wall. The noise floor
/// of the growth (`grow_noise_sigmas`) stops it at the noise; without a background it changes nothing.
#[test]
fn object_growth_stops_at_the_background_noise_floor() {
    // A 6 × 6 bright square (1.0) with a 2-column dim rim (0.3, above the 10 % growth threshold) at
    // 0.305 m, on a 24 × 24 grid whose other columns carry a pseudo-random background of 0.12–0.2 at
    // random depths near the object (0.275–0.325 m, so the depth-jump rule does not separate them).
    let (nx, ny, nz) = (24usize, 24usize, 40usize);
    let square = |x: usize, y: usize| (9..15).contains(&x) && (9..15).contains(&y);
    let rim = |x: usize, y: usize| (7..17).contains(&x) && (7..17).contains(&y) && !square(x, y);
    let with_background = |background: bool| {
        let mut vol = flat_volume(nx, ny, nz, square, 30);
        let mut rng = nlos_transient::rng::SplitMix64::new(12345);
        for iy in 0..ny {
            for ix in 0..nx {
                let r = rng.next_f32();
                if rim(ix, iy) {
                    vol.data[(ix + nx * iy) * nz + 30] = 0.3;
                } else if background && !square(ix, iy) {
                    vol.data[(ix + nx * iy) * nz + 27 + (r * 6.0) as usize] = 0.12 + 0.08 * r;
                }
            }
        }
        vol
    };
    let kept = |vol: &Volume, p: &SurfaceParams| {
        volume_to_surface(vol, p).expect("surface").mask.iter().filter(|&&k| k).count()
    };
    let object = SurfaceParams::object();
    let no_floor = SurfaceParams { grow_noise_sigmas: None, ..object };
    // Clean: square and rim, with or without the floor.
    let clean = with_background(false);
    assert_eq!(kept(&clean, &object), 100);
    assert_eq!(kept(&clean, &no_floor), 100);
    // Background: without the floor the mask grows over most of the wall; with it, square and rim only.
    let noisy = with_background(true);
    assert!(kept(&noisy, &no_floor) > 400, "{}", kept(&noisy, &no_floor));
    assert_eq!(kept(&noisy, &object), 100);
    // An invalid floor is a typed error.
    let bad = SurfaceParams { grow_noise_sigmas: Some(f32::NAN), ..object };
    assert!(matches!(
        volume_to_surface(&noisy, &bad),
        Err(InitError::InvalidParameter { name: "grow_noise_sigmas", .. })
    ));
}

/// A dim part beside a bright one (the `nonconfocal` scenario's ball beside its dish, one laser): grown
/// relative to the volume's peak, the dim part keeps only its core; relative to its own peak, its flanks
/// too, and the bright part is grown as before.
#[test]
fn each_region_grows_down_its_own_flanks() {
    // Bright 6 × 6 square (1.0) with a 1-column flank at 0.15; dim 4 × 4 square (0.3) with a 2-column flank
    // at 0.05: above 10 % of its own peak, below 10 % of the volume's.
    let (nx, ny, nz) = (32usize, 16usize, 40usize);
    let inside =
        |x: usize, y: usize, x0: usize, y0: usize, n: usize| (x0..x0 + n).contains(&x) && (y0..y0 + n).contains(&y);
    let mut vol = flat_volume(nx, ny, nz, |_, _| false, 30);
    for iy in 0..ny {
        for ix in 0..nx {
            let v = if inside(ix, iy, 4, 5, 6) {
                1.0
            } else if inside(ix, iy, 3, 4, 8) {
                0.15
            } else if inside(ix, iy, 20, 6, 4) {
                0.3
            } else if inside(ix, iy, 18, 4, 8) {
                0.05
            } else {
                0.0
            };
            vol.data[(ix + nx * iy) * nz + 30] = v;
        }
    }
    let kept = |reference| {
        let p = SurfaceParams {
            threshold: Threshold::Relative(0.25),
            grow_reference: reference,
            ..SurfaceParams::object()
        };
        let mask = volume_to_surface(&vol, &p).expect("surface").mask;
        let count = |x0, n| (0..nx * ny).filter(|&c| mask[c] && inside(c % nx, c / nx, x0, 4, n)).count();
        (count(3, 8), count(18, 8))
    };
    assert_eq!(kept(GrowReference::Volume), (64, 16), "the dim part keeps its core only");
    assert_eq!(kept(GrowReference::Region), (64, 64), "each part with its flanks");
}
