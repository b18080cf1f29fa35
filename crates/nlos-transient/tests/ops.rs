//! Tests of the transient operations on synthetic data with known answers.

use glam::Vec3;
use nlos_transient::{PointSet, Scan, TimeAxis, Transient, TransientError};

fn ramp(nx: usize, ny: usize, bins: usize) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(nx, ny, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.1, 0.002, bins).expect("axis");
    let data = (0..nx * ny * bins).map(|i| (i % 97) as f32 + 0.5).collect();
    Transient::new(scan, time, data).expect("transient")
}

#[test]
fn new_rejects_wrong_shape_nan_and_empty_grid() {
    let scan = Scan::confocal(PointSet::wall_grid(2, 2, 0.1, 0.1).expect("grid"));
    let time = TimeAxis::new(0.0, 0.001, 3).expect("axis");
    assert!(matches!(
        Transient::new(scan.clone(), time, vec![0.0; 11]),
        Err(TransientError::WrongShape { field, .. }) if field == "data"
    ));
    let mut data = vec![0.0; 12];
    data[7] = f32::NAN;
    assert!(matches!(Transient::new(scan, time, data), Err(TransientError::NonFinite { index: 7, .. })));
    assert!(PointSet::wall_grid(0, 4, 0.1, 0.1).is_err());
    assert!(TimeAxis::new(0.0, 0.0, 4).is_err());
    assert!(TimeAxis::new(0.0, -1.0, 4).is_err());
    assert!(TimeAxis::new(f64::NAN, 1.0, 4).is_err());
    assert!(TimeAxis::new(0.0, 1.0, 0).is_err());
    let empty = Scan::confocal(PointSet::list(vec![]));
    assert!(Transient::new(empty, time, vec![]).is_err());
}

#[test]
fn wall_grid_follows_linspace_and_x_fastest() {
    let p = PointSet::wall_grid(3, 2, 0.5, 0.2).expect("grid");
    assert_eq!(p.points[0], Vec3::new(-0.5, -0.2, 0.0));
    assert_eq!(p.points[1], Vec3::new(0.0, -0.2, 0.0));
    assert_eq!(p.points[2], Vec3::new(0.5, -0.2, 0.0));
    assert_eq!(p.points[3], Vec3::new(-0.5, 0.2, 0.0));
    assert!(p.normals.iter().all(|n| *n == Vec3::Z));
}

#[test]
fn crop_keeps_values_and_moves_t0() {
    let t = ramp(3, 2, 50);
    let c = t.crop_bins(10, 20).expect("crop");
    assert_eq!(c.bins(), 10);
    assert!((c.time().t0 - (0.1 + 10.0 * 0.002)).abs() < 1e-15);
    for m in 0..t.measurements() {
        assert_eq!(c.histogram(m), &t.histogram(m)[10..20]);
    }
    assert!(t.crop_bins(20, 20).is_err());
    assert!(t.crop_bins(0, 51).is_err());
    let p = t.crop_path(0.1 + 0.0205, 0.1 + 0.0399).expect("crop path");
    assert_eq!((p.time().t0, p.bins()), (t.time().bin_start(10), 10));
    assert!(t.crop_path(5.0, 6.0).is_err(), "a window beyond the axis is an error");
    assert!(t.crop_path(0.3, 0.2).is_err());
}

#[test]
fn rebin_sums_groups_and_drops_the_remainder() {
    let t = ramp(2, 2, 10);
    let r = t.rebin(3).expect("rebin");
    assert_eq!(r.bins(), 3);
    assert!((r.time().bin_width - 0.006).abs() < 1e-15);
    for m in 0..4 {
        let h = t.histogram(m);
        for k in 0..3 {
            assert_eq!(r.histogram(m)[k], h[3 * k] + h[3 * k + 1] + h[3 * k + 2]);
        }
    }
    assert!(t.rebin(0).is_err());
    assert!(t.rebin(11).is_err());
    assert_eq!(t.rebin(1).expect("identity"), t);
}

#[test]
fn gate_zeroes_bins_that_begin_before_the_cut() {
    let t = ramp(2, 1, 20);
    // bin k begins at 0.1 + 0.002 k; a cut at 0.1071 zeroes bins 0..=3 (bin 3 begins at 0.106).
    let g = t.gate(0.1071).expect("gate");
    for m in 0..2 {
        assert!(g.histogram(m)[..4].iter().all(|&v| v == 0.0));
        assert_eq!(&g.histogram(m)[4..], &t.histogram(m)[4..]);
    }
    assert!(t.gate(f64::NAN).is_err());
    assert_eq!(t.gate(0.0).expect("no-op"), t);
}

#[test]
fn subsample_keeps_every_kth_point_of_grid() {
    let t = ramp(5, 4, 3);
    let s = t.subsample(2, 3).expect("subsample");
    assert_eq!(s.scan().lasers().grid_dims(), Some((3, 2)));
    let kept = [0usize, 2, 4, 15, 17, 19];
    for (i, &m) in kept.iter().enumerate() {
        assert_eq!(s.histogram(i), t.histogram(m));
        assert_eq!(s.scan().lasers().points[i], t.scan().lasers().points[m]);
    }
    assert!(t.subsample(0, 1).is_err());
    let list = Transient::zeros(Scan::confocal(PointSet::list(vec![Vec3::ZERO])), *t.time()).expect("list");
    assert!(list.subsample(2, 2).is_err());
}

#[test]
fn select_keeps_measurements_with_their_spots_in_order() {
    let t = ramp(5, 4, 3);
    let s = t.select(&[7, 2, 19]).expect("select");
    assert_eq!(s.scan().lasers().grid_dims(), None, "a list");
    for (i, &m) in [7usize, 2, 19].iter().enumerate() {
        assert_eq!(s.histogram(i), t.histogram(m));
        assert_eq!(s.scan().lasers().points[i], t.scan().lasers().points[m]);
    }
    // Paired: the laser and sensor spots of each kept measurement travel together.
    let (l, r) =
        (PointSet::wall_grid(2, 2, 0.1, 0.1).expect("grid"), PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"));
    let paired = Transient::zeros(Scan::paired(l.clone(), r.clone()), *t.time()).expect("paired");
    let p = paired.select(&[3, 0]).expect("select");
    assert_eq!(p.scan().lasers().points, vec![l.points[3], l.points[0]]);
    assert_eq!(p.scan().sensors().points, vec![r.points[3], r.points[0]]);
    // Bad input: typed errors, never a panic.
    assert!(matches!(t.select(&[]), Err(TransientError::InvalidArgument { name: "kept", .. })));
    assert!(matches!(t.select(&[20]), Err(TransientError::InvalidArgument { name: "kept", .. })));
    let exhaustive = Transient::zeros(Scan::exhaustive(l, r), *t.time()).expect("exhaustive");
    assert!(exhaustive.select(&[0]).is_err());
}

#[test]
fn exhaustive_subsample_and_indices() {
    let l = PointSet::wall_grid(2, 2, 0.1, 0.1).expect("grid");
    let s = PointSet::wall_grid(3, 1, 0.1, 0.1).expect("grid");
    let scan = Scan::exhaustive(l, s);
    assert_eq!(scan.measurements(), 12);
    assert_eq!(scan.indices(7), (2, 1));
    let time = TimeAxis::new(0.0, 1.0, 2).expect("axis");
    let data: Vec<f32> = (0..24).map(|i| i as f32).collect();
    let t = Transient::new(scan, time, data).expect("t");
    let sub = t.subsample(2, 1).expect("subsample");
    // lasers keep columns 0 of each row (points 0, 2); sensors keep 0 and 2.
    assert_eq!(sub.measurements(), 4);
    let expect_m = [0usize, 2, 6, 8];
    for (i, &m) in expect_m.iter().enumerate() {
        assert_eq!(sub.histogram(i), t.histogram(m));
    }
}

#[test]
fn summaries_find_peaks_and_totals() {
    let scan = Scan::confocal(PointSet::wall_grid(2, 1, 0.1, 0.1).expect("grid"));
    let time = TimeAxis::new(0.0, 0.0012, 1000).expect("axis");
    let mut t = Transient::zeros(scan, time).expect("t");
    t.histogram_mut(0)[300] = 2.0;
    t.histogram_mut(0)[10] = 1.0;
    t.histogram_mut(1)[500] = 4.0;
    assert_eq!(t.peak_bins(), vec![300, 500]);
    assert_eq!(t.time_summed(), vec![3.0, 4.0]);
    let summed = t.summed_histogram();
    assert_eq!((summed[10], summed[300], summed[500]), (1.0, 2.0, 4.0));
    let d = t.summed_peak_depth(Some(0.0)).expect("depth");
    assert!((d - 500.5 * 0.0012 / 2.0).abs() < 1e-12);
    let d = t.summed_peak_depth(Some(0.5)).expect("gated depth");
    assert!((d - 500.5 * 0.0012 / 2.0).abs() < 1e-12);
    assert!(t.summed_peak_depth(Some(10.0)).is_err());
}

#[test]
fn direct_light_end_separates_the_wall_return_from_the_object() {
    // A decaying direct reflection from bin 0 and a weaker object return at bin 700.
    let scan = Scan::confocal(PointSet::wall_grid(1, 1, 0.0, 0.0).expect("grid"));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let data: Vec<f32> = (0..1200)
        .map(|k| {
            let k = k as f32;
            1e6 * (-k / 40.0).exp() + 30.0 + 5e3 * (-((k - 700.0) / 8.0).powi(2)).exp()
        })
        .collect();
    let t = Transient::new(scan, time, data).expect("t");
    let end = t.direct_light_end();
    assert!(end > 0.3 && end < 700.0 * 0.0012, "direct light ends at {end}");
    let depth = t.summed_peak_depth(None).expect("depth");
    assert!((depth - 700.5 * 0.0006).abs() < 1e-9, "depth {depth}");
    // Without an object return, the whole axis is kept.
    let flat = Transient::new(t.scan().clone(), time, vec![1.0; 1200]).expect("flat");
    assert_eq!(flat.direct_light_end(), 0.0);
}

#[test]
fn remove_device_legs_shifts_by_the_leg_lengths_exactly() {
    // One scan point at the origin; laser device 0.3 m away, sensor device 0.5 m away: shift 0.8 m.
    let scan = Scan {
        laser_device: Some(Vec3::new(0.0, -0.3, 0.0)),
        sensor_device: Some(Vec3::new(0.3, 0.0, 0.4)),
        ..Scan::confocal(PointSet::list(vec![Vec3::ZERO]))
    };
    let mut time = TimeAxis::new(0.0, 0.01, 200).expect("axis");
    time.includes_device_legs = true;
    let mut data = vec![0.0; 200];
    data[150] = 7.0; // path 1.50..1.51 incl. legs → 0.70..0.71 without
    data[120] = 1.0;
    let t = Transient::new(scan, time, data).expect("t");
    let r = t.remove_device_legs().expect("remove");
    assert!(!r.time().includes_device_legs);
    let h = r.histogram(0);
    assert!((h[70] - 7.0).abs() < 1e-5 && (h[40] - 1.0).abs() < 1e-5, "{:?}", &h[38..72]);
    assert!((h.iter().sum::<f32>() - 8.0).abs() < 1e-5);
    assert!(r.remove_device_legs().is_err(), "legs are already removed");
    let mut no_dev = t.clone();
    no_dev.scan_mut().laser_device = None;
    assert!(no_dev.remove_device_legs().is_err());
}

#[test]
fn fractional_leg_shift_conserves_and_splits_mass() {
    let scan = Scan {
        laser_device: Some(Vec3::new(0.0, 0.0, 0.0125)),
        sensor_device: Some(Vec3::new(0.0, 0.0, 0.0)),
        ..Scan::confocal(PointSet::list(vec![Vec3::ZERO]))
    };
    let mut time = TimeAxis::new(0.0, 0.01, 10).expect("axis");
    time.includes_device_legs = true;
    let mut data = vec![0.0; 10];
    data[5] = 4.0;
    let r = Transient::new(scan, time, data).expect("t").remove_device_legs().expect("remove");
    // Shift of 1.25 bins: bin 5 ([5, 6)) lands on [3.75, 4.75) → 1 into bin 3, 3 into bin 4.
    let h = r.histogram(0);
    assert!((h[3] - 1.0).abs() < 1e-5 && (h[4] - 3.0).abs() < 1e-5, "{h:?}");
}

/// Photon counts of 16 measurements: background `b` per bin, a strong return at bin 400 (peak ≈ 400
/// counts) and a weaker one (`second` × that) at bin 800, on 1200 bins of 1.2 mm.
fn two_returns(b: f64, second: f64) -> Transient {
    use nlos_transient::rng::Pcg32;
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.1, 0.1).expect("grid"));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let mut rng = Pcg32::new(7, 1);
    let data: Vec<f32> = (0..16 * 1200)
        .map(|i| {
            let k = (i % 1200) as f64;
            let bump = |c: f64| (-((k - c) / 10.0).powi(2)).exp();
            rng.poisson(b + 400.0 * (bump(400.0) + second * bump(800.0))) as f32
        })
        .collect();
    Transient::new(scan, time, data).expect("transient")
}

#[test]
fn signal_end_path_ends_after_the_last_return_that_stands_above_the_background() {
    // The second return at 20 % of the first is signal: the end lies just after it (bin 800 ± 3 widths),
    // with the 5 % margin.
    let t = two_returns(2.0, 0.2);
    let end = t.signal_end_path(0.0);
    let last = 0.0012 * 830.0;
    assert!(end > 800.0 * 0.0012 && end <= 1.05 * last, "end {end}");
    // At 1 % it is not: the end follows the first return.
    let t = two_returns(2.0, 0.01);
    let end = t.signal_end_path(0.0);
    assert!(end > 400.0 * 0.0012 && end < 1.05 * 0.0012 * 440.0, "end {end}");
    // No background (a simulation): the whole axis.
    let t = two_returns(0.0, 0.01);
    assert_eq!(t.signal_end_path(0.0), t.time().end());
    // Nothing at or after min_path: the whole axis.
    assert_eq!(t.signal_end_path(10.0), t.time().end());
}

/// `PointSet::grid_spacing`: a grid's extent over its gaps per axis; none for a list.
#[test]
fn grid_spacing_of_a_grid_and_of_a_list() {
    let g = nlos_transient::PointSet::wall_grid(5, 3, 0.2, 0.1).expect("grid");
    let (dx, dy) = g.grid_spacing().expect("a grid");
    assert!((dx - 0.1).abs() < 1e-6 && (dy - 0.1).abs() < 1e-6, "({dx}, {dy})");
    let list = nlos_transient::PointSet::list(g.points.clone());
    assert_eq!(list.grid_spacing(), None);
}

/// A flat face's return (every measurement lit in the same bins, an abrupt rise and a long tail that ends at bin
/// 1000) on an axis from the wall, without background.
fn flat_face_return() -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.25, 0.25).expect("grid"));
    let bins = 1200;
    let time = TimeAxis::new(0.0, 0.0012, bins).expect("axis");
    let data = (0..16 * bins)
        .map(|i| {
            let k = i % bins;
            if !(700..1000).contains(&k) { 0.0 } else { (400.0 * (-((k - 700) as f32) / 300.0).exp()).round() }
        })
        .collect();
    Transient::new(scan, time, data).expect("transient")
}

#[test]
fn a_crop_is_not_a_gate() {
    let sim = flat_face_return();
    assert_eq!(sim.zero_gate(), None, "the whole simulation ends in zeros: no background");
    // Cut from bin 500 to 900 (as `nlos convert --crop-bins 500..900`): zeros, then an abrupt return that
    // lasts to the end of the axis. Only the axis, which starts 0.6 m from the wall, says no direct light
    // was there to be removed.
    let crop = sim.crop_bins(500, 900).expect("crop");
    assert_eq!(crop.leading_zero_bins(), 200);
    assert_eq!(crop.zero_gate(), None, "the darkness before the first return is not a gate");
    // The same light on an axis from the wall, its first bins zeroed by a gate, with a background after it.
    let mut gated = crop.clone();
    gated.time_mut().t0 = 0.0;
    for h in gated.data_mut().chunks_mut(400) {
        for v in &mut h[200..] {
            *v += 1.0;
        }
    }
    assert_eq!(gated.zero_gate(), Some(200));
}
