//! Paired scans (measurement i = laser spot i with sensor spot i): the general-NLOS files as published, what
//! each writer does with a paired scan, and the typed errors of bad pairings.

use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_testdata::mat5::{self, Options, double};
use nlos_transient::{Format, PointSet, ReadOptions, Scan, ScanPattern, TimeAxis, Transient, TransientError};

type R = Result<(), TransientError>;

fn tmp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nlos-paired-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// `data.mat` and `setup.mat` of an `a × b` pair grid with `bins` bins, as the general-NLOS code stores
/// them (column-major): `data(i, j, k) = 100·i + 10·j + k`; lasers on a wall bent by `z = 0.02·x²`, sensors
/// 0.27 m to their left.
fn general_nlos_files(dir: &Path, a: usize, b: usize, bins: usize) {
    let laser = |i: usize, j: usize| {
        let (x, y) = (-0.5 + 0.1 * j as f64, 0.4 - 0.1 * i as f64);
        [x, y, 0.02 * x * x]
    };
    let sensor = |i: usize, j: usize| {
        let [x, y, _] = laser(i, j);
        [x - 0.27, y, 0.02 * (x - 0.27) * (x - 0.27)]
    };
    let column_major = |f: &dyn Fn(usize, usize) -> [f64; 3]| -> Vec<f64> {
        (0..3)
            .flat_map(|c| (0..b).flat_map(move |j| (0..a).map(move |i| (i, j, c))))
            .map(|(i, j, c)| f(i, j)[c])
            .collect()
    };
    let dims = [a as i32, b as i32, 3];
    let setup =
        [double("laserpoints", &dims, column_major(&laser)), double("detectpoints", &dims, column_major(&sensor))];
    std::fs::write(dir.join("setup.mat"), mat5::write(&setup, Options::default())).expect("write setup");
    let data: Vec<f64> =
        (0..bins).flat_map(|k| (0..b).flat_map(move |j| (0..a).map(move |i| (100 * i + 10 * j + k) as f64))).collect();
    let data = [double("data", &[a as i32, b as i32, bins as i32], data)];
    std::fs::write(dir.join("data.mat"), mat5::write(&data, Options::default())).expect("write data");
}

#[test]
fn general_nlos_files_read_as_a_paired_scan() -> R {
    let dir = tmp_dir("general_nlos");
    let (a, b, bins) = (3, 4, 5);
    general_nlos_files(&dir, a, b, bins);
    let options = ReadOptions::with_bin_width_ps(Some(32.0));
    for file in ["data.mat", "setup.mat"] {
        let path = dir.join(file);
        assert_eq!(nlos_transient::detect(&path)?, Format::GeneralNlosMat, "{file}");
        let t = nlos_transient::read_with(&path, &options)?;
        assert_eq!(t.scan().pattern_name(), "paired");
        assert_eq!((t.measurements(), t.bins()), (a * b, bins));
        // 32 ps at 3e8 m/s; path 0 at the centre of bin 0.
        assert!((t.time().bin_width - 0.0096).abs() < 1e-12);
        assert!((t.time().t0 + 0.0048).abs() < 1e-12);
        for (i, j) in [(0, 0), (1, 2), (2, 3)] {
            let m = i * b + j;
            assert_eq!(t.histogram(m)[4], (100 * i + 10 * j + 4) as f32, "measurement ({i}, {j})");
            let g = t.scan().measurement(m);
            let x = -0.5 + 0.1 * j as f32;
            assert!((g.laser - Vec3::new(x, 0.4 - 0.1 * i as f32, 0.02 * x * x)).length() < 1e-6);
            assert!((g.sensor.x - (x - 0.27)).abs() < 1e-6);
            // The normals of z = 0.02 x²: (−0.04 x, 0, 1)/‖·‖, from the cubic fit through both sets.
            let want = |x: f32| Vec3::new(-0.04 * x, 0.0, 1.0).normalize();
            assert!(g.laser_normal.angle_between(want(g.laser.x)) < 1e-4, "{:?}", g.laser_normal);
            assert!(g.sensor_normal.angle_between(want(g.sensor.x)) < 1e-4, "{:?}", g.sensor_normal);
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

#[test]
fn general_nlos_errors_name_the_file_and_the_fix() -> R {
    let dir = tmp_dir("general_nlos_errors");
    general_nlos_files(&dir, 2, 2, 3);
    let data = dir.join("data.mat");
    // No bin width: the error says which option gives it.
    match nlos_transient::read(&data) {
        Err(TransientError::MissingField { file, field, hint }) => {
            assert_eq!((file, field.as_str()), (data.clone(), "bin width"));
            assert!(hint.contains("--bin-width-ps 32"), "{hint}");
        }
        other => panic!("{other:?}"),
    }
    let options = ReadOptions::with_bin_width_ps(Some(32.0));
    // Not a bin width.
    for bad in [0.0, -32.0, f64::NAN, 1e12] {
        let e =
            nlos_transient::read_with(&data, &ReadOptions::with_bin_width_ps(Some(bad))).expect_err("not a bin width");
        assert!(matches!(e, TransientError::InvalidValue { ref field, .. } if field == "bin width"), "{bad}: {e}");
    }
    // A bin width for a file that has its own time axis is refused.
    let own = dir.join("own.npy");
    let t = Transient::new(
        Scan::confocal(PointSet::wall_grid(2, 2, 0.1, 0.1)?),
        TimeAxis::new(0.0, 0.01, 3)?,
        vec![0.0; 12],
    )?;
    nlos_transient::write(&t, &own, Format::NpyJson)?;
    let e = nlos_transient::read_with(&own, &options).expect_err("the file has its own axis");
    assert!(matches!(e, TransientError::InvalidValue { ref field, .. } if field == "bin width"), "{e}");
    // The setup beside the data is missing.
    std::fs::remove_file(dir.join("setup.mat")).expect("remove");
    match nlos_transient::read_with(&data, &options) {
        Err(e @ TransientError::MissingCompanion { .. }) => {
            assert!(
                matches!(&e, TransientError::MissingCompanion { file, companion, .. }
                    if *file == data && *companion == dir.join("setup.mat")),
                "{e:?}"
            );
            assert!(e.to_string().contains("the laser and sensor spots are in setup.mat"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    // Given the setup alone, the error is about the setup, and names data.mat as what it needs.
    general_nlos_files(&dir, 2, 2, 3);
    std::fs::remove_file(&data).expect("remove");
    match nlos_transient::read(dir.join("setup.mat")) {
        Err(TransientError::MissingField { file, field, .. }) => {
            assert_eq!((file, field.as_str()), (dir.join("setup.mat"), "bin width"));
        }
        other => panic!("{other:?}"),
    }
    match nlos_transient::read_with(dir.join("setup.mat"), &options) {
        Err(e @ TransientError::MissingCompanion { .. }) => {
            assert!(
                e.to_string().starts_with(&format!("{}: needs its companion file", dir.join("setup.mat").display()))
            );
            assert!(e.to_string().contains("the histograms are in data.mat"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    // A setup whose grid does not match the data's.
    general_nlos_files(&dir, 2, 2, 3);
    let small = tmp_dir("general_nlos_errors_small");
    general_nlos_files(&small, 2, 1, 3);
    std::fs::copy(small.join("setup.mat"), dir.join("setup.mat")).expect("copy");
    match nlos_transient::read_with(&data, &options) {
        Err(TransientError::WrongShape { file, field, .. }) => {
            assert_eq!((file, field.as_str()), (dir.join("setup.mat"), "laserpoints"));
        }
        other => panic!("{other:?}"),
    }
    std::fs::remove_dir_all(&dir).ok();
    std::fs::remove_dir_all(&small).ok();
    Ok(())
}

fn paired(lasers: Vec<Vec3>, sensors: Vec<Vec3>) -> Scan {
    Scan::paired(PointSet::list(lasers), PointSet::list(sensors))
}

#[test]
fn bad_pairings_are_typed_errors_naming_the_field() {
    let row = |n: usize, dx: f32| (0..n).map(|i| Vec3::new(0.1 * i as f32 + dx, 0.0, 0.0)).collect::<Vec<_>>();
    // Lists of different lengths.
    match paired(row(4, 0.0), row(3, 0.27)).validate() {
        Err(TransientError::WrongShape { field, .. }) => assert_eq!(field, "sensor_points"),
        other => panic!("{other:?}"),
    }
    // A non-unit normal.
    let mut s = paired(row(4, 0.0), row(4, 0.27));
    if let ScanPattern::Paired { sensors, .. } = &mut s.pattern {
        sensors.normals[1] = Vec3::new(0.0, 0.0, 2.0);
    }
    match s.validate() {
        Err(TransientError::InvalidValue { field, .. }) => assert_eq!(field, "sensor_points.normals"),
        other => panic!("{other:?}"),
    }
    // A normal facing away from the hidden scene.
    let mut s = paired(row(4, 0.0), row(4, 0.27));
    if let ScanPattern::Paired { lasers, .. } = &mut s.pattern {
        lasers.normals[0] = -Vec3::Z;
    }
    match s.validate() {
        Err(TransientError::InvalidValue { field, .. }) => assert_eq!(field, "laser_points.normals"),
        other => panic!("{other:?}"),
    }
    // A laser spot behind the wall (half a metre), and one in the hidden volume.
    for (dz, side) in [(-0.5, "behind the wall"), (0.8, "in the hidden volume")] {
        let mut lasers = row(8, 0.0);
        lasers[3].z = dz;
        match paired(lasers, row(8, 0.27)).validate() {
            Err(TransientError::InvalidValue { field, reason, .. }) => {
                assert_eq!(field, "laser_points");
                assert!(reason.contains("spot 3") && reason.contains(side), "{reason}");
                assert!(!reason.contains("  "), "a message in one line, no runs of spaces: {reason}");
            }
            other => panic!("{other:?}"),
        }
    }
    // A wall curved by ±3 cm is a wall.
    let mut curved = row(8, 0.0);
    for (i, p) in curved.iter_mut().enumerate() {
        p.z = 0.03 * (i as f32).sin();
    }
    assert!(paired(curved, row(8, 0.27)).validate().is_ok());
}

#[test]
fn a_sidecar_whose_paired_lists_differ_names_the_field() -> R {
    let dir = tmp_dir("sidecar_lengths");
    let t = Transient::new(
        paired(vec![Vec3::ZERO, Vec3::X * 0.1], vec![Vec3::X * 0.3, Vec3::X * 0.4]),
        TimeAxis::new(0.0, 0.01, 2)?,
        vec![1.0; 4],
    )?;
    let path = dir.join("p.npy");
    nlos_transient::write(&t, &path, Format::NpyJson)?;
    let json = dir.join("p.json");
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).expect("read")).expect("json");
    v["scan"]["sensors"]["points"].as_array_mut().expect("points").pop();
    std::fs::write(&json, serde_json::to_vec(&v).expect("encode")).expect("write");
    match nlos_transient::read(&path) {
        Err(TransientError::WrongShape { file, field, .. }) => {
            assert_eq!((file, field.as_str()), (json, "sidecar.scan.sensors"));
        }
        other => panic!("{other:?}"),
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

#[test]
fn y_tal_has_no_paired_layout_and_says_what_to_write() -> R {
    let dir = tmp_dir("tal");
    let t = Transient::new(
        paired(vec![Vec3::ZERO, Vec3::X * 0.1], vec![Vec3::X * 0.3, Vec3::X * 0.4]),
        TimeAxis::new(0.0, 0.01, 2)?,
        vec![1.0; 4],
    )?;
    match nlos_transient::write(&t, dir.join("p.hdf5"), Format::Tal) {
        Err(TransientError::CannotWrite { reason, .. }) => assert!(reason.contains(".npy"), "{reason}"),
        other => panic!("{other:?}"),
    }
    assert!(!dir.join("p.hdf5").exists());
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

/// The published capture: 64 × 64 pairs 0.25–0.29 m apart on a wall within −1.8 … +3 cm, 512 bins, the
/// total photon count as scipy's `loadmat` sums it (8,979,788), and normals within 10° of +z.
#[test]
fn reads_the_published_general_nlos_capture() -> R {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/measured/general_nlos/data.mat");
    if !path.exists() {
        assert!(std::env::var_os("NLOS_REQUIRE_DATA").is_none(), "{} is missing", path.display());
        eprintln!("skipped: {} not found", path.display());
        return Ok(());
    }
    let t = nlos_transient::read_with(&path, &ReadOptions::with_bin_width_ps(Some(32.0)))?;
    assert_eq!((t.measurements(), t.bins()), (4096, 512));
    let total: f64 = t.summed_histogram().iter().sum();
    assert_eq!(total, 8_979_788.0);
    for m in 0..t.measurements() {
        let g = t.scan().measurement(m);
        let gap = g.laser.distance(g.sensor);
        assert!((0.24..0.29).contains(&gap), "measurement {m}: spots {gap} m apart");
        assert!(g.laser.z.abs() < 0.03 && g.sensor.z.abs() < 0.03);
        assert!(g.laser_normal.angle_between(Vec3::Z) < 10f32.to_radians());
    }
    // Measurement (i, j) = (0, 1) is the second of the first row: x grows along j.
    assert!(t.scan().measurement(1).laser.x > t.scan().measurement(0).laser.x);
    // The first 40 bins were zeroed by the authors' preprocessing.
    assert!(t.summed_histogram()[..40].iter().all(|&v| v == 0.0));
    Ok(())
}
