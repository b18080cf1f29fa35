//! MAT v5 formats: Stanford LCT (real captures), Tsai 2019 and Stanford f-k (generated files), and
//! malformed inputs.

use nlos_testdata::mat5;

use std::path::Path;
use std::time::Instant;

use mat5::{Options, Stored, Var, cell_var, char_var, double, scalar, stored, write};
use nlos_transient::formats::{Format, detect_bytes, read_bytes_as};
use nlos_transient::{Layout, Transient, TransientError};

/// Reads a real capture, or `None` (with a reason on stderr) when the shared data are absent.
fn real(name: &str) -> Option<Transient> {
    let path = nlos_testdata::shared(&format!("measured/{name}"))?;
    assert_eq!(nlos_transient::detect(&path).expect("detect"), Format::LctMat);
    let start = Instant::now();
    let t = nlos_transient::read(&path).expect("read real LCT capture");
    eprintln!("{name}: read in {:.3} s", start.elapsed().as_secs_f64());
    Some(t)
}

fn total(t: &Transient) -> f64 {
    t.data().iter().map(|&v| f64::from(v)).sum()
}

fn check_lct_geometry(t: &Transient, half_width: f32) {
    let pts = t.scan().lasers();
    assert!(t.scan().is_confocal());
    assert_eq!(pts.layout, Layout::Grid { nx: 64, ny: 64 });
    assert_eq!(t.bins(), 2048);
    assert_eq!(t.time().bin_width, 0.0012);
    assert_eq!(t.time().t0, 0.0);
    assert!(!t.time().includes_device_legs);
    let (lo, hi) = pts.bounds().expect("points");
    for (a, b) in [(lo.x, -half_width), (lo.y, -half_width), (hi.x, half_width), (hi.y, half_width)] {
        assert!((a - b).abs() < 1e-6, "extent {lo:?}..{hi:?}, expected ±{half_width}");
    }
    assert!(lo.z == 0.0 && hi.z == 0.0);
}

#[test]
fn lct_diffuse_s() {
    let Some(t) = real("data_diffuse_s.mat") else { return };
    check_lct_geometry(&t, 0.35);
    // Independent figure: the sum of rect_data computed with scipy.
    assert_eq!(total(&t), 71_809_550.0);
}

#[test]
fn lct_resolution_chart_peak_depth() {
    let Some(t) = real("data_resolution_chart_40cm.mat") else { return };
    check_lct_geometry(&t, 0.2);
    assert_eq!(total(&t), 239_775_059.0);
    let auto = t.summed_peak_depth(None).expect("depth");
    assert!((auto - 0.425).abs() <= 0.005, "auto-gated peak depth {auto}");
    let gated = t.summed_peak_depth(Some(0.72)).expect("depth");
    assert!((gated - 0.425).abs() <= 0.005, "peak depth after 0.72 m {gated}");
}

#[test]
fn lct_s_u() {
    let Some(t) = real("data_s_u.mat") else { return };
    check_lct_geometry(&t, 0.35);
    assert_eq!(total(&t), 53_190_216.0);
}

/// The LCT axis mapping documented in `formats::mat`: MAT index i runs along −x, j along −y.
#[test]
fn lct_axis_mapping_and_class() {
    let (n, bins) = (4usize, 6usize);
    let mut v = vec![0u16; n * n * bins];
    for t in 0..bins {
        for j in 0..n {
            for i in 0..n {
                v[i + n * j + n * n * t] = (1 + i + 10 * j + 100 * t) as u16;
            }
        }
    }
    let dims = [n as i32, n as i32, bins as i32];
    for opt in [
        Options::default(),
        Options { compress: true, big_endian: false },
        Options { compress: false, big_endian: true },
    ] {
        // Class double, stored as uint16: the MATLAB layout of the real files.
        let bytes =
            write(&[stored("rect_data", &dims, mat5::DOUBLE, Stored::U16(v.clone())), scalar("width", 0.25)], opt);
        let f = Path::new("lct.mat");
        assert_eq!(detect_bytes(&bytes, f).expect("detect"), Format::LctMat);
        let t = read_bytes_as(&bytes, Format::LctMat, f).expect("read");
        let lin = |k: usize| -0.25 + 0.5 * k as f32 / (n - 1) as f32;
        for j in 0..n {
            for i in 0..n {
                let m = (n - 1 - i) + n * (n - 1 - j);
                let p = t.scan().lasers().points[m];
                assert!((p.x + lin(i)).abs() < 1e-6 && (p.y + lin(j)).abs() < 1e-6, "{p:?} for ({i}, {j})");
                for k in 0..bins {
                    assert_eq!(t.histogram(m)[k], (1 + i + 10 * j + 100 * k) as f32);
                }
            }
        }
    }
}

fn tsai_vars(m: usize, bins: usize, transient: Stored, class: u8) -> Vec<Var> {
    let lighting: Vec<f64> = (0..3)
        .flat_map(|c| (0..m).map(move |r| if c == 2 { 0.0 } else { 0.1 * (r as f64) - 0.05 * c as f64 }))
        .collect();
    vec![stored("transient", &[m as i32, bins as i32], class, transient), double("lighting", &[m as i32, 3], lighting)]
}

#[test]
fn tsai_layout_in_several_storage_classes() {
    let (m, bins) = (5usize, 7usize);
    // transient(r, k) = r + 10 k, column-major.
    let vals: Vec<f64> = (0..bins).flat_map(|k| (0..m).map(move |r| (r + 10 * k) as f64)).collect();
    let cases = [
        (Stored::F64(vals.clone()), mat5::DOUBLE),
        (Stored::F32(vals.iter().map(|&v| v as f32).collect()), mat5::SINGLE),
        (Stored::U8(vals.iter().map(|&v| v as u8).collect()), mat5::DOUBLE),
        (Stored::I16(vals.iter().map(|&v| v as i16).collect()), mat5::INT16),
        (Stored::I32(vals.iter().map(|&v| v as i32).collect()), mat5::INT32),
    ];
    for (data, class) in cases {
        for compress in [false, true] {
            let bytes = write(&tsai_vars(m, bins, data.clone(), class), Options { compress, big_endian: false });
            let f = Path::new("tsai.mat");
            assert_eq!(detect_bytes(&bytes, f).expect("detect"), Format::TsaiMat);
            let t = read_bytes_as(&bytes, Format::TsaiMat, f).expect("read");
            assert!(t.scan().is_confocal());
            assert_eq!(t.scan().lasers().layout, Layout::List);
            assert_eq!((t.measurements(), t.bins()), (m, bins));
            assert_eq!((t.time().t0, t.time().bin_width), (0.0, 0.0012));
            for r in 0..m {
                let p = t.scan().lasers().points[r];
                assert!((p.x - 0.1 * r as f32).abs() < 1e-6 && (p.y - (0.1 * r as f32 - 0.05)).abs() < 1e-6);
                for k in 0..bins {
                    assert_eq!(t.histogram(r)[k], (r + 10 * k) as f32);
                }
            }
        }
    }
}

#[test]
fn tsai_bin_width_gt_transient_and_sensor() {
    let (m, bins) = (3usize, 4usize);
    let mut vars = tsai_vars(m, bins, Stored::F64(vec![1.0; m * bins]), mat5::DOUBLE);
    vars[0].name = "gt_transient".into();
    vars.push(scalar("bin_width", 0.003));
    let lighting = vars[1].clone();
    let mut sensor = lighting.clone();
    sensor.name = "sensor".into();
    vars.push(sensor);
    let f = Path::new("setup.mat");
    let bytes = write(&vars, Options::default());
    assert_eq!(detect_bytes(&bytes, f).expect("detect"), Format::TsaiMat);
    let t = read_bytes_as(&bytes, Format::TsaiMat, f).expect("read");
    assert_eq!(t.time().bin_width, 0.003);
    assert!(t.scan().is_confocal());
    // A sensor that differs from the lighting is a paired capture: measurement r lights lighting[r] and
    // records at sensor[r].
    let mut other = lighting;
    other.name = "sensor".into();
    if let mat5::Body::Numeric { data: Stored::F64(v), .. } = &mut other.body {
        v[0] += 1.0;
    }
    *vars.last_mut().expect("sensor") = other;
    let t = read_bytes_as(&write(&vars, Options::default()), Format::TsaiMat, f).expect("paired");
    assert_eq!(t.scan().pattern_name(), "paired");
    assert_eq!(t.measurements(), m);
    let g = t.scan().measurement(0);
    assert_eq!(g.sensor.x, g.laser.x + 1.0);
    assert_eq!(t.scan().measurement(1).sensor, t.scan().measurement(1).laser);
}

/// A Tsai file whose `lighting` is a 4 × 3 grid (x fastest, as their `compute_init_su.m` writes it) reads as
/// a grid; in column order it is reordered into one (points and histograms together); a list that is no
/// grid stays a list.
#[test]
fn tsai_lighting_that_forms_a_grid_is_a_grid() {
    let (nx, ny, bins) = (4usize, 3usize, 5usize);
    let m = nx * ny;
    let at = |i: usize, x_fastest: bool| {
        let (ix, iy) = if x_fastest { (i % nx, i / nx) } else { (i / ny, i % ny) };
        (-0.3 + 0.2 * ix as f64, -0.1 + 0.1 * iy as f64)
    };
    for x_fastest in [true, false] {
        // Column-major M×3, and transient(r, k) = 100 ix + 10 iy + k: each histogram names its point.
        let lighting: Vec<f64> =
            (0..3).flat_map(|c| (0..m).map(move |r| [at(r, x_fastest).0, at(r, x_fastest).1, 0.0][c])).collect();
        let label = |r: usize| {
            let (x, y) = at(r, x_fastest);
            100.0 * ((x + 0.3) / 0.2).round() + 10.0 * ((y + 0.1) / 0.1).round()
        };
        let transient: Vec<f64> = (0..bins).flat_map(|k| (0..m).map(move |r| label(r) + k as f64)).collect();
        let vars = vec![
            double("transient", &[m as i32, bins as i32], transient),
            double("lighting", &[m as i32, 3], lighting),
        ];
        let t = read_bytes_as(&write(&vars, Options::default()), Format::TsaiMat, Path::new("grid.mat")).expect("read");
        assert_eq!(t.scan().lasers().layout, Layout::Grid { nx, ny }, "x fastest: {x_fastest}");
        for iy in 0..ny {
            for ix in 0..nx {
                let i = ix + nx * iy;
                let p = t.scan().lasers().points[i];
                assert!((f64::from(p.x) - (-0.3 + 0.2 * ix as f64)).abs() < 1e-6, "{x_fastest} {ix} {iy}: {p}");
                assert!((f64::from(p.y) - (-0.1 + 0.1 * iy as f64)).abs() < 1e-6, "{x_fastest} {ix} {iy}: {p}");
                assert_eq!(t.histogram(i)[2], (100 * ix + 10 * iy + 2) as f32);
            }
        }
        // The grid methods accept it: subsampling keeps every other column.
        assert_eq!(t.subsample(2, 1).expect("grid").scan().lasers().layout, Layout::Grid { nx: 2, ny });
    }
    // Five points on a line with one out of step: a list.
    let t = read_bytes_as(
        &write(&tsai_vars(5, 3, Stored::F64(vec![1.0; 15]), mat5::DOUBLE), Options::default()),
        Format::TsaiMat,
        Path::new("list.mat"),
    )
    .expect("read");
    assert_eq!(t.scan().lasers().layout, Layout::List);
}

/// A NeTF-preprocessed Z-NLOS file: 3 × 2 wall points on the plane y = `wall_y` (column q of the positions
/// at x = 0.1·(q mod 3) − 0.1, z = 0.2·⌊q / 3⌋ − 0.1), `data` 4 × 3 × 2 whose histogram stored s-th
/// (column-major: `data(:, i, j)`, s = i + 3j) holds `s + 10 k`, plus the optional fields.
fn netf_vars(wall_y: f64, centre: Option<[f64; 3]>, extra: Vec<Var>) -> Vec<Var> {
    let (a, b, bins) = (3usize, 2usize, 4usize);
    let pos: Vec<f64> =
        (0..a * b).flat_map(|p| [0.1 * (p % a) as f64 - 0.1, wall_y, 0.2 * (p / a) as f64 - 0.1]).collect();
    let data: Vec<f64> = (0..a * b).flat_map(|p| (0..bins).map(move |k| (p + 10 * k) as f64)).collect();
    let mut vars = vec![
        double("data", &[bins as i32, a as i32, b as i32], data),
        double("cameraGridPositions", &[3, (a * b) as i32], pos),
        double("deltaT", &[1, 1], vec![0.01]),
    ];
    if let Some(c) = centre {
        vars.push(double("hiddenVolumePosition", &[3, 1], c.to_vec()));
    }
    vars.extend(extra);
    vars
}

fn netf(vars: &[Var]) -> Result<Transient, TransientError> {
    let bytes = write(vars, Options::default());
    let f = Path::new("netf.mat");
    assert_eq!(detect_bytes(&bytes, f).expect("detect"), Format::ZNlosMat);
    read_bytes_as(&bytes, Format::ZNlosMat, f)
}

/// The axes: their wall y = w with the scene at y < w is our z = 0 with the scene at z > 0 by `(x, z, −(y − w))`
/// — the rotation the Z-NLOS HDF5 reader applies to walls whose normals are −y (`hdf5_formats.rs`,
/// `to_ours`) — and `(x, −z, y − w)` for a scene at y > w; `data(:, i, j)` pairs with column i·B + j
/// (NeTF's row-by-row flattening), and `deltaT` is a distance from the wall: bins of twice it in path.
#[test]
fn netf_znlos_axes_and_data_order() {
    let t = netf(&netf_vars(0.3, Some([0.0, -0.2, 0.0]), vec![])).expect("read");
    assert!(t.scan().is_confocal() && !t.time().includes_device_legs);
    assert_eq!((t.time().t0, t.time().bin_width, t.bins()), (0.0, 0.02, 4));
    assert_eq!(t.scan().lasers().layout, Layout::Grid { nx: 3, ny: 2 });
    for p in 0..6 {
        let q = t.scan().lasers().points[p];
        let (x, z) = (0.1 * (p % 3) as f32 - 0.1, 0.2 * (p / 3) as f32 - 0.1);
        assert!((q - glam::Vec3::new(x, z, 0.0)).length() < 1e-6, "point {p}: {q}");
        assert_eq!(t.scan().lasers().normals[p], glam::Vec3::Z);
        // Column p is data(:, i, j) with p = 2i + j, stored s-th with s = i + 3j.
        let s = (p / 2 + 3 * (p % 2)) as f32;
        assert_eq!(t.histogram(p), &[s, s + 10.0, s + 20.0, s + 30.0], "point {p}");
    }
    // The scene on the other side: z mirrored (the grid's rows run the other way, so they are relabelled).
    let t = netf(&netf_vars(0.3, Some([0.0, 0.9, 0.0]), vec![])).expect("read");
    let q = &t.scan().lasers().points;
    assert!(q.iter().all(|p| p.z == 0.0) && q.iter().any(|p| (p.y - 0.1).abs() < 1e-6));
}

/// A file whose returns all begin after its hidden volume could return holds the device legs.
#[test]
fn netf_znlos_times_with_the_device_legs() {
    let legs = vec![
        double("cameraPosition", &[3, 1], vec![0.0, 1.3, 0.0]),
        double("hiddenVolumeSize", &[1, 1], vec![0.001]),
        scalar("t0", 2.0),
    ];
    // The box (1 mm, 0.2 m from the wall) returns within 0.5 m of path; the data begin at 2.0 m.
    let t = netf(&netf_vars(0.0, Some([0.0, -0.2, 0.0]), legs)).expect("read");
    assert!(t.time().includes_device_legs);
    assert_eq!(t.scan().sensor_device, Some(glam::Vec3::new(0.0, 0.0, -1.3)));
    // t0 is a distance from the wall, as deltaT: 4 m of path.
    assert_eq!(t.time().t0, 4.0);
}

#[test]
fn netf_znlos_bad_input_is_typed() {
    let mut vars = netf_vars(0.0, None, vec![]);
    vars[1] = double("cameraGridPositions", &[3, 5], vec![0.0; 15]);
    assert!(matches!(netf(&vars), Err(TransientError::WrongShape { ref field, .. }) if field == "cameraGridPositions"));
    let mut vars = netf_vars(0.0, None, vec![]);
    vars[2] = double("deltaT", &[1, 1], vec![-1.0]);
    assert!(matches!(netf(&vars), Err(TransientError::InvalidValue { ref field, .. }) if field == "deltaT"));
    let mut vars = netf_vars(0.0, None, vec![]);
    if let mat5::Body::Numeric { data: Stored::F64(v), .. } = &mut vars[1].body {
        v[4] = f64::NAN;
    }
    assert!(matches!(netf(&vars), Err(TransientError::NonFinite { ref field, .. }) if field == "cameraGridPositions"));
    // A wall that is not a plane of constant y or z.
    let mut vars = netf_vars(0.0, None, vec![]);
    if let mat5::Body::Numeric { data: Stored::F64(v), .. } = &mut vars[1].body {
        v[1] = 0.05;
        v[5] = 0.03;
    }
    assert!(matches!(netf(&vars), Err(TransientError::Unsupported { .. })));
}

/// An f-k file: rows × cols × bins, pixel (i, j) with one count at bin 20, tofgrid(i, j) in ps.
fn fk_vars(rows: usize, cols: usize, bins: usize, tof: &dyn Fn(usize, usize) -> f64) -> Vec<Var> {
    let mut meas = vec![0u16; rows * cols * bins];
    let mut tofgrid = vec![0.0; rows * cols];
    for i in 0..rows {
        for j in 0..cols {
            meas[i + rows * j + rows * cols * 20] = (1 + i + 10 * j) as u16;
            tofgrid[i + rows * j] = tof(i, j);
        }
    }
    vec![
        stored("meas", &[rows as i32, cols as i32, bins as i32], mat5::DOUBLE, Stored::U16(meas)),
        double("tofgrid", &[rows as i32, cols as i32], tofgrid),
    ]
}

#[test]
fn fk_integer_shift_is_exact_and_orientation_documented() {
    let (rows, cols, bins) = (3usize, 4usize, 32usize);
    let vars = fk_vars(rows, cols, bins, &|i, j| 32.0 * (i + 2 * j) as f64);
    for compress in [false, true] {
        let bytes = write(&vars, Options { compress, big_endian: false });
        let f = Path::new("/nonexistent-nlos-dir/fk.mat");
        assert_eq!(detect_bytes(&bytes, f).expect("detect"), Format::FkMat);
        let t = read_bytes_as(&bytes, Format::FkMat, f).expect("read");
        assert_eq!(t.scan().lasers().layout, Layout::Grid { nx: cols, ny: rows });
        assert!(!t.time().includes_device_legs);
        assert_eq!((t.time().t0, t.time().bin_width), (0.0, 0.0096));
        let (lo, hi) = t.scan().lasers().bounds().expect("points");
        assert!((lo.x + 1.0).abs() < 1e-6 && (hi.y - 1.0).abs() < 1e-6, "default 2 m × 2 m wall");
        for i in 0..rows {
            for j in 0..cols {
                // Column j is x; row 0 is the top (largest y).
                let m = j + cols * (rows - 1 - i);
                let h = t.histogram(m);
                let mut expected = vec![0.0f32; bins];
                expected[20 - (i + 2 * j)] = (1 + i + 10 * j) as f32;
                assert_eq!(h, expected.as_slice(), "pixel ({i}, {j})");
            }
        }
    }
}

#[test]
fn fk_fractional_shift_splits_counts() {
    // 48 ps = 1.5 bins: a count at bin 20 moves to the interval [18.5, 19.5): half in bin 18, half in 19.
    let vars = fk_vars(2, 2, 32, &|_, _| 48.0);
    let t = read_bytes_as(&write(&vars, Options::default()), Format::FkMat, Path::new("/nonexistent/fk.mat"))
        .expect("read");
    for m in 0..4 {
        let h = t.histogram(m);
        let c: f32 = h.iter().sum();
        assert!((h[18] - c / 2.0).abs() < 1e-6 && (h[19] - c / 2.0).abs() < 1e-6, "{h:?}");
    }
}

#[test]
fn fk_wall_size_and_sibling_tof_file() {
    let dir = std::env::temp_dir().join(format!(
        "nlos-mat-test-{}-{}",
        std::process::id(),
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos())
    ));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let mut vars = fk_vars(2, 3, 24, &|i, _| 32.0 * i as f64);
    let tof = vars.pop().expect("tofgrid");
    vars.push(scalar("wall_size", 0.5));
    let meas_path = dir.join("meas_10min.mat");
    std::fs::write(&meas_path, write(&vars, Options { compress: true, big_endian: false })).expect("write");
    // Without tof.mat: a typed error naming the field.
    let r = nlos_transient::read(&meas_path);
    assert!(matches!(r, Err(TransientError::MissingField { ref field, .. }) if field == "tofgrid"), "{r:?}");
    std::fs::write(dir.join("tof.mat"), write(&[tof], Options::default())).expect("write");
    let t = nlos_transient::read(&meas_path).expect("read with tof.mat beside");
    let (_, hi) = t.scan().lasers().bounds().expect("points");
    assert!((hi.x - 0.25).abs() < 1e-6);
    // Row i = 1 (bottom row, iy = 0) was shifted by one bin.
    assert_eq!(t.histogram(0)[19], 2.0);
    assert_eq!(t.histogram(3)[20], 1.0);
    let _ = std::fs::remove_dir_all(&dir);
}

fn lct_vars() -> Vec<Var> {
    let vals: Vec<u16> = (0..4 * 4 * 8).map(|k| (k % 7) as u16).collect();
    vec![stored("rect_data", &[4, 4, 8], mat5::DOUBLE, Stored::U16(vals)), scalar("width", 0.3)]
}

fn read_err(vars: &[Var], format: Format) -> TransientError {
    let f = Path::new("bad.mat");
    let bytes = write(vars, Options::default());
    match read_bytes_as(&bytes, format, f) {
        Ok(_) => panic!("read a malformed {format} file"),
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("bad.mat"), "error does not name the file: {msg}");
            e
        }
    }
}

#[test]
fn every_prefix_is_an_error() {
    let small_fk = fk_vars(2, 2, 24, &|_, _| 0.0);
    let files: [(&str, Vec<Var>, Format); 3] = [
        ("lct", lct_vars(), Format::LctMat),
        ("tsai", tsai_vars(3, 4, Stored::F64(vec![1.0; 12]), mat5::DOUBLE), Format::TsaiMat),
        ("fk", small_fk, Format::FkMat),
    ];
    let f = Path::new("/nonexistent-nlos-dir/prefix.mat");
    for (name, vars, format) in files {
        for opt in [
            Options::default(),
            Options { compress: true, big_endian: false },
            Options { compress: false, big_endian: true },
        ] {
            let bytes = write(&vars, opt);
            assert!(read_bytes_as(&bytes, format, f).is_ok(), "{name} full file");
            for n in 0..bytes.len() {
                let p = &bytes[..n];
                if let Ok(detected) = detect_bytes(p, f) {
                    assert!(read_bytes_as(p, detected, f).is_err(), "{name} {opt:?}: prefix {n} read as {detected}");
                }
                assert!(read_bytes_as(p, format, f).is_err(), "{name} {opt:?}: prefix {n} read");
            }
        }
    }
}

#[test]
fn wrong_types_are_typed_errors() {
    let mut vars = lct_vars();
    vars[0] = char_var("rect_data", "not numbers");
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::WrongType { ref field, .. } if field == "rect_data"), "{e:?}");
    vars[0] = cell_var("rect_data");
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::WrongType { ref field, .. } if field == "rect_data"), "{e:?}");
    let mut vars = lct_vars();
    vars[1] = char_var("width", "0.3");
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::WrongType { ref field, .. } if field == "width"), "{e:?}");
    // Complex data.
    let mut vars = lct_vars();
    if let mat5::Body::Numeric { complex, .. } = &mut vars[0].body {
        *complex = true;
    }
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::WrongType { .. }), "{e:?}");
    let mut vars = tsai_vars(3, 4, Stored::F64(vec![1.0; 12]), mat5::DOUBLE);
    vars[1] = cell_var("lighting");
    let e = read_err(&vars, Format::TsaiMat);
    assert!(matches!(e, TransientError::WrongType { ref field, .. } if field == "lighting"), "{e:?}");
}

#[test]
fn wrong_shapes_are_typed_errors() {
    let mut vars = lct_vars();
    vars[0] = double("rect_data", &[4, 32], vec![1.0; 128]);
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::WrongShape { ref field, .. } if field == "rect_data"), "{e:?}");
    vars[0] = double("rect_data", &[4, 2, 16], vec![1.0; 128]);
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::WrongShape { ref field, .. } if field == "rect_data"), "{e:?}");
    let mut vars = lct_vars();
    vars[1] = double("width", &[1, 2], vec![0.3, 0.3]);
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::WrongShape { ref field, .. } if field == "width"), "{e:?}");
    let mut vars = tsai_vars(3, 4, Stored::F64(vec![1.0; 12]), mat5::DOUBLE);
    vars[1] = double("lighting", &[3, 2], vec![0.0; 6]);
    let e = read_err(&vars, Format::TsaiMat);
    assert!(matches!(e, TransientError::WrongShape { ref field, .. } if field == "lighting"), "{e:?}");
    let mut vars = fk_vars(2, 3, 24, &|_, _| 0.0);
    vars[1] = double("tofgrid", &[3, 2], vec![0.0; 6]);
    let e = read_err(&vars, Format::FkMat);
    assert!(matches!(e, TransientError::WrongShape { ref field, .. } if field == "tofgrid"), "{e:?}");
}

#[test]
fn zero_sized_grid_nan_and_bad_width() {
    let mut vars = lct_vars();
    vars[0] = double("rect_data", &[0, 0, 8], vec![]);
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::InvalidValue { ref field, .. } if field == "rect_data"), "{e:?}");
    let mut vars = lct_vars();
    let mut v = vec![1.0; 128];
    v[77] = f64::NAN;
    vars[0] = double("rect_data", &[4, 4, 8], v);
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::NonFinite { ref field, index: 77, .. } if field == "rect_data"), "{e:?}");
    let mut vars = lct_vars();
    vars[1] = scalar("width", -0.3);
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::InvalidValue { ref field, .. } if field == "width"), "{e:?}");
    vars[1] = scalar("width", f64::INFINITY);
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::NonFinite { ref field, .. } if field == "width"), "{e:?}");
    let vars = tsai_vars(3, 4, Stored::F64(vec![f64::INFINITY; 12]), mat5::DOUBLE);
    let e = read_err(&vars, Format::TsaiMat);
    assert!(matches!(e, TransientError::NonFinite { ref field, index: 0, .. } if field == "transient"), "{e:?}");
    let mut vars = tsai_vars(3, 4, Stored::F64(vec![1.0; 12]), mat5::DOUBLE);
    vars[1] = double("lighting", &[3, 3], vec![0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let e = read_err(&vars, Format::TsaiMat);
    assert!(matches!(e, TransientError::NonFinite { ref field, .. } if field == "lighting"), "{e:?}");
    let mut vars = fk_vars(2, 2, 24, &|_, _| 0.0);
    vars[1] = double("tofgrid", &[2, 2], vec![0.0, f64::NAN, 0.0, 0.0]);
    let e = read_err(&vars, Format::FkMat);
    assert!(matches!(e, TransientError::NonFinite { ref field, .. } if field == "tofgrid"), "{e:?}");
}

#[test]
fn missing_fields_and_unknown_layouts() {
    let vars = vec![lct_vars().remove(0)];
    let e = read_err(&vars, Format::LctMat);
    assert!(matches!(e, TransientError::MissingField { ref field, .. } if field == "width"), "{e:?}");
    let bytes = write(&[scalar("foo", 1.0), char_var("bar", "x")], Options::default());
    match detect_bytes(&bytes, Path::new("other.mat")) {
        Err(TransientError::UnknownFormat { reason, .. }) => {
            assert!(reason.contains("`foo`") && reason.contains("`bar`"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_zlib_stream_is_malformed() {
    let bytes = write(&lct_vars(), Options { compress: true, big_endian: false });
    let f = Path::new("z.mat");
    // Corrupt the first compressed element beyond its zlib header: the deflate data.
    let mut broken = bytes.clone();
    for b in &mut broken[128 + 8 + 2..128 + 8 + 40] {
        *b ^= 0x5a;
    }
    let r = read_bytes_as(&broken, Format::LctMat, f);
    assert!(matches!(r, Err(TransientError::Malformed { .. } | TransientError::Truncated { .. })), "{r:?}");
    // A stream that is not zlib at all.
    let mut broken = bytes;
    broken[128 + 8] = 0xff;
    let r = detect_bytes(&broken, f);
    assert!(matches!(r, Err(TransientError::Malformed { .. })), "{r:?}");
}

#[test]
fn absurd_dimensions_do_not_allocate() {
    // 2^20 × 2^20 = 2^40 elements declared, 16 bytes present.
    let vars = vec![double("rect_data", &[1 << 20, 1 << 20, 1], vec![1.0, 2.0]), scalar("width", 0.3)];
    for compress in [false, true] {
        let r =
            read_bytes_as(&write(&vars, Options { compress, big_endian: false }), Format::LctMat, Path::new("x.mat"));
        assert!(matches!(r, Err(TransientError::Malformed { .. })), "{r:?}");
    }
    // Negative dimension, and an absurd element length in a tag.
    let vars = vec![double("rect_data", &[-1, 4, 8], vec![]), scalar("width", 0.3)];
    let r = read_bytes_as(&write(&vars, Options::default()), Format::LctMat, Path::new("x.mat"));
    assert!(matches!(r, Err(TransientError::Malformed { .. })), "{r:?}");
    let mut bytes = write(&lct_vars(), Options::default());
    bytes[132..136].copy_from_slice(&u32::MAX.to_le_bytes());
    let r = read_bytes_as(&bytes, Format::LctMat, Path::new("x.mat"));
    assert!(matches!(r, Err(TransientError::Truncated { .. })), "{r:?}");
}

#[test]
fn unsupported_version_and_bad_endian() {
    let mut bytes = write(&lct_vars(), Options::default());
    bytes[124..126].copy_from_slice(&0x0300u16.to_le_bytes());
    let r = detect_bytes(&bytes, Path::new("v.mat"));
    assert!(matches!(r, Err(TransientError::Unsupported { .. })), "{r:?}");
    bytes[126..128].copy_from_slice(b"XX");
    let r = detect_bytes(&bytes, Path::new("v.mat"));
    assert!(matches!(r, Err(TransientError::Malformed { .. })), "{r:?}");
}

/// `mat::read_array`: a MATLAB 2×3 matrix (column-major) comes back in C order, NaN kept and Inf turned
/// into NaN (the published Z-NLOS depth map marks "no surface" with Inf); the only numeric
/// variable is found by itself, a name picks among several.
#[test]
fn read_array_returns_c_order() {
    let dir = std::env::temp_dir().join(format!("nlos-read-array-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let f = dir.join("m.mat");
    // M = [1 2 3; 4 5 NaN] stored column-major: 1 4 2 5 3 NaN; then with Inf for the 5.
    let m = double("depth", &[2, 3], vec![1.0, 4.0, 2.0, f64::INFINITY, 3.0, f64::NAN]);
    std::fs::write(&f, write(std::slice::from_ref(&m), Options::default())).expect("write");
    let (v, _, _) = nlos_transient::formats::mat::read_array(&f, None).expect("read with Inf");
    assert!(v[4].is_nan() && v[5].is_nan(), "Inf and NaN both read as no value: {v:?}");
    let m = double("depth", &[2, 3], vec![1.0, 4.0, 2.0, 5.0, 3.0, f64::NAN]);
    std::fs::write(&f, write(std::slice::from_ref(&m), Options::default())).expect("write");
    let (v, dims, name) = nlos_transient::formats::mat::read_array(&f, None).expect("read");
    assert_eq!((dims, name.as_str()), (vec![2, 3], "depth"));
    assert_eq!(&v[..5], &[1.0, 2.0, 3.0, 4.0, 5.0]);
    assert!(v[5].is_nan());
    std::fs::write(&f, write(&[m, scalar("other", 1.0)], Options::default())).expect("write");
    assert!(matches!(nlos_transient::formats::mat::read_array(&f, None), Err(TransientError::MissingField { .. })));
    assert_eq!(nlos_transient::formats::mat::read_array(&f, Some("other")).expect("named").0, vec![1.0]);
    let _ = std::fs::remove_dir_all(&dir);
}
