//! HDF5 formats: y-tal HDF5_TAL (real files and round trips), Z-NLOS and MAT v7.3 (generated files),
//! `read_dataset_f64` on the real SPAD files, and malformed input.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use nlos_testdata::mat5;

use glam::Vec3;
use hdf5_pure::{AttrValue, FileBuilder};
use nlos_transient::formats::{self, Format, hdf5};
use nlos_transient::{Layout, PointSet, Scan, ScanPattern, TimeAxis, Transient, TransientError};

fn shared(rel: &str) -> Option<PathBuf> {
    nlos_testdata::shared(rel)
}

/// Parses a NumPy v1.0 little-endian float32 C-order `.npy`: (shape, values).
fn read_npy_f32(path: &Path) -> (Vec<usize>, Vec<f32>) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..6], b"\x93NUMPY");
    assert_eq!(b[6], 1, "NumPy format v1.0");
    let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(&b[10..10 + hlen]).unwrap();
    assert!(header.contains("'descr': '<f4'"), "{header}");
    assert!(header.contains("'fortran_order': False"), "{header}");
    let shape_txt = header.split("'shape': (").nth(1).unwrap().split(')').next().unwrap();
    let shape: Vec<usize> =
        shape_txt.split(',').filter(|s| !s.trim().is_empty()).map(|s| s.trim().parse().unwrap()).collect();
    let data = b[10 + hlen..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    (shape, data)
}

#[test]
fn reference_tal_files_read_and_equal_their_npy() {
    for name in ["plane_quadrature", "plane_mc", "ggx_plane_quadrature", "ggx_plane_mc", "bunny_mc"] {
        let Some(h5) = shared(&format!("reference/{name}.hdf5")) else { return };
        assert_eq!(formats::detect(&h5).unwrap(), Format::Tal, "{name}");
        let t = formats::read(&h5).unwrap();
        assert!(t.scan().is_confocal(), "{name}");
        let pts = t.scan().sensors();
        assert_eq!(pts.layout, Layout::Grid { nx: 64, ny: 64 });
        assert_eq!(t.bins(), 512);
        assert!((t.time().bin_width - 0.004).abs() < 1e-9, "{}", t.time().bin_width);
        assert_eq!(t.time().t0, 0.0);
        assert!(!t.time().includes_device_legs);
        // README: s[iy, ix] = (−0.25 + (ix + 0.5)·0.5/64, −0.25 + (iy + 0.5)·0.5/64, 0), exact in f32.
        for iy in 0..64 {
            for ix in 0..64 {
                let f = |i: usize| (-0.25 + (i as f64 + 0.5) * 0.5 / 64.0) as f32;
                assert_eq!(pts.points[ix + 64 * iy], Vec3::new(f(ix), f(iy), 0.0), "{name} ({ix}, {iy})");
                assert_eq!(pts.normals[ix + 64 * iy], Vec3::Z);
            }
        }
        assert_eq!(t.scan().laser_device, Some(Vec3::new(0.0, -0.35, 0.2)));
        let Some(npy) = shared(&format!("reference/{name}.npy")) else { return };
        // README "Array layouts": the cube is H[iy, ix, k], shape (ny, nx, bins).
        let (shape, cube) = read_npy_f32(&npy);
        assert_eq!(shape, vec![64, 64, 512]);
        for iy in 0..64 {
            for ix in 0..64 {
                let h = t.histogram(ix + 64 * iy);
                let r = &cube[(iy * 64 + ix) * 512..(iy * 64 + ix + 1) * 512];
                assert!(h.iter().zip(r).all(|(a, b)| a.to_bits() == b.to_bits()), "{name} pixel ({ix}, {iy})");
            }
        }
    }
}

#[test]
fn read_dataset_f64_on_the_spad_files() {
    if let Some(p) = shared("sensor/spad_jitter.mat") {
        let (t, shape) = hdf5::read_dataset_f64(&p, "t_1").unwrap();
        assert_eq!(shape, vec![1, 901]);
        // Seconds: about −84 ps to 649 ps.
        assert!((t[0] + 84e-12).abs() < 1e-12, "{}", t[0]);
        assert!((t[900] - 649e-12).abs() < 1e-12, "{}", t[900]);
        let (c, shape) = hdf5::read_dataset_f64(&p, "counts_1").unwrap();
        assert_eq!((shape, c.len()), (vec![1, 901], 901));
        assert!(c.iter().all(|v| *v >= 0.0) && c.iter().sum::<f64>() > 0.0);
        let e = hdf5::read_dataset_f64(&p, "nope").unwrap_err();
        assert!(matches!(e, TransientError::MissingField { ref field, .. } if field == "nope"), "{e}");
    }
    if let Some(p) = shared("sensor/spad_impulse_response.hdf5") {
        let (c, shape) = hdf5::read_dataset_f64(&p, "counts").unwrap();
        assert_eq!(shape, vec![1201, 1]);
        assert_eq!(c[0], 19.0);
        assert_eq!(c.iter().sum::<f64>(), 2_819_902.0);
        let (w, shape) = hdf5::read_dataset_f64(&p, "timebin_width_ps").unwrap();
        assert_eq!((w, shape), (vec![0.75], vec![]));
        assert!(matches!(formats::detect(&p), Err(TransientError::UnknownFormat { .. })));
    }
}

// ---------------------------------------------------------------- round trips

fn grid(nx: usize, ny: usize, z: f32, seed: f32) -> PointSet {
    let mut p = PointSet::wall_grid(nx, ny, 0.3, 0.2).unwrap();
    for (i, v) in p.points.iter_mut().enumerate() {
        *v += Vec3::new(seed * 1e-3 * i as f32, -seed * 7e-4, z);
    }
    p.normals[0] = Vec3::new(0.6, 0.0, 0.8);
    p
}

fn list(n: usize, seed: f32) -> PointSet {
    let mut p =
        PointSet::list((0..n).map(|i| Vec3::new(0.1 * i as f32 - seed, 0.013 * seed * i as f32, 0.0)).collect());
    p.normals[n - 1] = Vec3::new(0.0, 0.6, 0.8);
    p
}

fn filled(scan: Scan, bins: usize, legs: bool) -> Transient {
    let time = TimeAxis { t0: -0.123_456_789_012_3, bin_width: 0.001_234_567_891_1, bins, includes_device_legs: legs };
    let n = scan.measurements() * bins;
    let data = (0..n).map(|i| ((i * 7919) % 1013) as f32 * 0.37 + 1e-7 * i as f32).collect();
    Transient::new(scan, time, data).unwrap()
}

fn with_devices(mut s: Scan, on: bool) -> Scan {
    if on {
        s.laser_device = Some(Vec3::new(0.1, -0.35, 0.2));
        s.sensor_device = Some(Vec3::new(-0.2, -0.4, 0.25));
    }
    s
}

fn assert_bit_exact(a: &Transient, b: &Transient, what: &str) {
    assert_eq!(a.scan(), b.scan(), "{what}: scan");
    assert_eq!(a.time().t0.to_bits(), b.time().t0.to_bits(), "{what}: t0");
    assert_eq!(a.time().bin_width.to_bits(), b.time().bin_width.to_bits(), "{what}: bin width");
    assert_eq!(a.time(), b.time(), "{what}: time axis");
    assert!(a.data().iter().zip(b.data()).all(|(x, y)| x.to_bits() == y.to_bits()), "{what}: data");
    assert_eq!(a.data().len(), b.data().len());
}

fn scans() -> Vec<(&'static str, Scan)> {
    vec![
        ("confocal grid", Scan::confocal(grid(4, 3, 0.0, 1.0))),
        ("confocal list", Scan::confocal(list(5, 0.5))),
        ("exhaustive grid", Scan::exhaustive(grid(2, 3, 0.0, 2.0), grid(3, 2, 0.01, 3.0))),
        ("exhaustive list", Scan::exhaustive(list(3, 0.2), list(4, 0.7))),
        ("exhaustive grid × list", Scan::exhaustive(grid(2, 2, 0.0, 1.0), list(3, 0.1))),
        ("one laser spot × grid", Scan::exhaustive(list(1, 0.3), grid(3, 2, 0.0, 1.5))),
        ("one laser spot × list", Scan::exhaustive(list(1, 0.3), list(4, 0.9))),
    ]
}

#[test]
fn tal_round_trips_bit_exactly() {
    let f = Path::new("rt.hdf5");
    for (what, scan) in scans() {
        for devices in [false, true] {
            let t = filled(with_devices(scan.clone(), devices), 9, devices);
            let bytes = hdf5::write_tal(&t, f).unwrap();
            assert_eq!(formats::detect_bytes(&bytes, f).unwrap(), Format::Tal, "{what}");
            let back = formats::read_bytes_as(&bytes, Format::Tal, f).unwrap();
            let mut expected = t.clone();
            if what == "exhaustive grid × list" {
                // T_Li_Si stores grids as N_3 point lists: the points are kept, the grid shape is not.
                if let ScanPattern::Exhaustive { lasers, .. } = &mut expected.scan_mut().pattern {
                    lasers.layout = Layout::List;
                }
            }
            assert_bit_exact(&expected, &back, &format!("{what}, devices {devices}"));
        }
    }
}

#[test]
fn tal_write_goes_through_the_atomic_writer() {
    let dir = std::env::temp_dir().join(format!("nlos-hdf5-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("capture.hdf5");
    let t = filled(Scan::confocal(grid(3, 3, 0.0, 1.0)), 5, false);
    formats::write(&t, &path, Format::Tal).unwrap();
    assert_bit_exact(&t, &formats::read(&path).unwrap(), "file");
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------- Z-NLOS

struct ZGrid {
    /// C-order dims (slow, fast).
    dims: [usize; 2],
    y_normal: f32,
}

impl ZGrid {
    /// Positions in the Z-NLOS frame: the wall is y = 0, the grid spans x (fast) and z (slow).
    fn position(&self, p: usize) -> [f32; 3] {
        let (slow, fast) = (p / self.dims[1], p % self.dims[1]);
        [-0.5 + 0.25 * fast as f32, 0.0, 0.3 - 0.2 * slow as f32]
    }
    fn n(&self) -> usize {
        self.dims[0] * self.dims[1]
    }
    /// `(3, slow, fast)` coordinate-major, as the column-major writer stores them.
    fn xyz(&self) -> Vec<f32> {
        (0..3).flat_map(|j| (0..self.n()).map(move |p| self.position(p)[j])).collect()
    }
    fn normals(&self) -> Vec<f32> {
        (0..3).flat_map(|j| (0..self.n()).map(move |_| [0.0, self.y_normal, 0.0][j])).collect()
    }
}

fn znlos_value(c: usize, k: usize, b: usize, s: usize, l: usize) -> f32 {
    (1 + c) as f32 * 0.5 + (k * 100 + b * 10 + s * 1000 + l * 20000) as f32
}

/// A Z-NLOS file: confocal `(1, T, B, cam…)` or exhaustive `(1, T, B, cam…, laser…)`; `old` uses the
/// old field names; `row_major` reverses every dimension and sets the `data order` attribute.
fn znlos_file(cam: &ZGrid, laser: Option<&ZGrid>, old: bool, row_major: bool) -> Vec<u8> {
    let (t, bounces) = (6, 3);
    let n_l = laser.map_or(1, ZGrid::n);
    let mut dims = vec![1, t, bounces, cam.dims[0], cam.dims[1]];
    if let Some(l) = laser {
        dims.extend(l.dims);
    }
    let mut data = Vec::new();
    for k in 0..t {
        for b in 0..bounces {
            for s in 0..cam.n() {
                for l in 0..n_l {
                    data.push(znlos_value(0, k, b, s, l));
                }
            }
        }
    }
    let mut b = FileBuilder::new();
    let put = |b: &mut FileBuilder, name: &str, vals: &[f32], dims: &[usize]| {
        let mut d: Vec<u64> = dims.iter().map(|&d| d as u64).collect();
        let vals = if row_major && d.len() > 1 {
            // Reverse every dimension: element at reversed index = element at original index.
            let n = vals.len();
            let strides: Vec<usize> = (0..dims.len()).map(|i| dims[i + 1..].iter().product()).collect();
            let mut out = vec![0.0; n];
            for (i, v) in vals.iter().enumerate() {
                let idx: Vec<usize> = (0..dims.len()).map(|a| (i / strides[a]) % dims[a]).collect();
                let ri: usize = (0..dims.len()).map(|a| idx[a] * (dims[..a].iter().product::<usize>())).sum();
                out[ri] = *v;
            }
            d.reverse();
            out
        } else {
            vals.to_vec()
        };
        b.create_dataset(name).with_f32_data(&vals).with_shape(&d);
    };
    put(&mut b, "data", &data, &dims);
    let n = |new: &'static str, old_name: &'static str| if old { old_name } else { new };
    put(&mut b, n("cameraGridPositions", "cameraPos"), &cam.xyz(), &[3, cam.dims[0], cam.dims[1]]);
    put(&mut b, n("cameraGridNormals", "cameraNormal"), &cam.normals(), &[3, cam.dims[0], cam.dims[1]]);
    let l = laser.unwrap_or(cam);
    put(&mut b, n("laserGridPositions", "laserPos"), &l.xyz(), &[3, l.dims[0], l.dims[1]]);
    put(&mut b, n("laserGridNormals", "laserNorm"), &l.normals(), &[3, l.dims[0], l.dims[1]]);
    b.create_dataset(n("cameraPosition", "cameraOrigin")).with_f32_data(&[0.0, 0.8, 0.1]).with_shape(&[3, 1]);
    b.create_dataset(n("laserPosition", "laserOrigin")).with_f32_data(&[0.2, 0.9, -0.1]).with_shape(&[3, 1]);
    b.create_dataset(n("deltaT", "deltat")).with_f64_data(&[0.01]).with_shape(&[]);
    b.create_dataset("t0").with_f64_data(&[0.5]).with_shape(&[]);
    if !old {
        b.create_dataset("isConfocal").with_i32_data(&[i32::from(laser.is_none())]).with_shape(&[]);
        b.create_dataset("hiddenVolumePosition").with_f32_data(&[0.0, -0.5, 0.0]);
    }
    if row_major {
        b.set_attr("data order", AttrValue::String("row-major".into()));
    }
    b.finish().unwrap()
}

/// Our frame from the Z-NLOS one for wall normals −y: (x, z, −y).
fn to_ours(p: [f32; 3]) -> Vec3 {
    Vec3::new(p[0], p[2], -p[1])
}

#[test]
fn znlos_confocal_new_and_old_names_and_row_major() {
    let f = Path::new("z.hdf5");
    let cam = ZGrid { dims: [2, 3], y_normal: -1.0 };
    for (old, row_major) in [(false, false), (true, false), (false, true)] {
        let bytes = znlos_file(&cam, None, old, row_major);
        assert_eq!(formats::detect_bytes(&bytes, f).unwrap(), Format::ZNlos);
        let t = formats::read_bytes_as(&bytes, Format::ZNlos, f).unwrap();
        let what = format!("old {old} row-major {row_major}");
        assert!(t.scan().is_confocal(), "{what}");
        let pts = t.scan().sensors();
        assert_eq!(pts.layout, Layout::Grid { nx: 3, ny: 2 }, "{what}");
        for p in 0..6 {
            assert_eq!(pts.points[p], to_ours(cam.position(p)), "{what} point {p}");
            assert_eq!(pts.normals[p], Vec3::Z, "{what}");
            for k in 0..6 {
                let expected: f32 = (0..3).map(|b| znlos_value(0, k, b, p, 0)).sum();
                assert_eq!(t.histogram(p)[k], expected, "{what} point {p} bin {k}");
            }
        }
        assert_eq!((t.time().t0, t.time().bin_width, t.bins()), (0.5, 0.01, 6));
        assert!(t.time().includes_device_legs);
        assert_eq!(t.scan().sensor_device, Some(to_ours([0.0, 0.8, 0.1])));
        assert_eq!(t.scan().laser_device, Some(to_ours([0.2, 0.9, -0.1])));
        let r = t.remove_device_legs().unwrap();
        assert!(!r.time().includes_device_legs);
        // Point 0: legs |laser − l| + |s − camera| in metres, shifted in bins of 0.01 m.
        let g = t.scan().measurement(0);
        let legs =
            t.scan().laser_device.unwrap().distance(g.laser) + g.sensor.distance(t.scan().sensor_device.unwrap());
        assert!(legs > 0.5, "{legs}");
        assert!(r.histogram(0).iter().sum::<f32>() < t.histogram(0).iter().sum::<f32>());
    }
}

#[test]
fn znlos_exhaustive() {
    let f = Path::new("z.hdf5");
    let cam = ZGrid { dims: [2, 2], y_normal: 1.0 };
    let laser = ZGrid { dims: [1, 3], y_normal: 1.0 };
    for (old, row_major) in [(false, false), (true, false), (false, true)] {
        let bytes = znlos_file(&cam, Some(&laser), old, row_major);
        let t = formats::read_bytes_as(&bytes, Format::ZNlos, f).unwrap();
        let what = format!("old {old} row-major {row_major}");
        let ScanPattern::Exhaustive { lasers, sensors } = &t.scan().pattern else { panic!("{what}: not exhaustive") };
        assert_eq!((lasers.len(), sensors.len()), (3, 4), "{what}");
        // Normals +y rotate with (x, −z, y).
        assert_eq!(sensors.points[1], Vec3::new(cam.position(1)[0], -cam.position(1)[2], 0.0), "{what}");
        assert!(sensors.normals.iter().chain(&lasers.normals).all(|n| *n == Vec3::Z), "{what}");
        for il in 0..3 {
            for is in 0..4 {
                let expected: f32 = (0..3).map(|b| znlos_value(0, 2, b, is, il)).sum();
                assert_eq!(t.histogram(il * 4 + is)[2], expected, "{what} laser {il} sensor {is}");
            }
        }
        assert!(t.remove_device_legs().is_ok());
    }
}

// ---------------------------------------------------------------- MAT v7.3

fn mat73(build: impl FnOnce(&mut FileBuilder)) -> Vec<u8> {
    let mut b = FileBuilder::new();
    b.with_userblock(512);
    build(&mut b);
    let mut bytes = b.finish().unwrap();
    let text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 .";
    bytes[..128].fill(b' ');
    bytes[..text.len()].copy_from_slice(text);
    bytes[124..128].copy_from_slice(&[0x00, 0x02, b'I', b'M']);
    bytes
}

fn class(name: &str) -> AttrValue {
    AttrValue::AsciiString(name.into())
}

#[test]
fn fk_and_lct_in_mat_v73() {
    let f = Path::new("meas.mat");
    // MATLAB meas(i, j, t): rows = 2, cols = 3, bins = 8; HDF5 dims (8, 3, 2), same flat order.
    let (rows, cols, bins) = (2usize, 3usize, 8usize);
    let mut meas = vec![0.0f64; rows * cols * bins];
    meas[1 + rows * 2 + rows * cols * 5] = 7.0; // meas(i=1, j=2, t=5)
    let bytes = mat73(|b| {
        b.create_dataset("meas").with_f64_data(&meas).with_shape(&[8, 3, 2]).set_attr("MATLAB_class", class("double"));
        b.create_dataset("tofgrid")
            .with_f64_data(&[0.0; 6])
            .with_shape(&[3, 2])
            .set_attr("MATLAB_class", class("double"));
    });
    assert_eq!(formats::detect_bytes(&bytes, f).unwrap(), Format::FkMat);
    let t = formats::read_bytes_as(&bytes, Format::FkMat, f).unwrap();
    assert_eq!(t.scan().sensors().grid_dims(), Some((cols, rows)));
    // ix = j = 2, iy = rows − 1 − i = 0.
    assert_eq!(t.histogram(2)[5], 7.0);
    assert_eq!(t.data().iter().sum::<f32>(), 7.0);
    assert!((t.time().bin_width - 0.0096).abs() < 1e-12);

    let logical = mat73(|b| {
        b.create_dataset("meas")
            .with_u8_data(&[0; 8])
            .with_shape(&[2, 2, 2])
            .set_attr("MATLAB_class", class("logical"));
        b.create_dataset("tofgrid").with_f64_data(&[0.0; 4]).with_shape(&[2, 2]);
    });
    let e = formats::read_bytes_as(&logical, Format::FkMat, f).unwrap_err();
    assert!(matches!(e, TransientError::WrongType { ref field, .. } if field == "meas"), "{e}");
    let no_tof = mat73(|b| {
        b.create_dataset("meas").with_f64_data(&[0.0; 8]).with_shape(&[2, 2, 2]);
    });
    let e = formats::read_bytes_as(&no_tof, Format::FkMat, f).unwrap_err();
    assert!(matches!(e, TransientError::MissingField { ref field, .. } if field == "tofgrid"), "{e}");

    // LCT: rect_data(i, j, t) uint16-stored double, N = 2, T = 4; width 0.35.
    let mut rect = vec![0u16; 2 * 2 * 4];
    rect[2 * 3] = 9; // rect_data(i=0, j=1, t=1) at 0 + 2·1 + 4·1
    let lct = mat73(|b| {
        b.create_dataset("rect_data")
            .with_u16_data(&rect)
            .with_shape(&[4, 2, 2])
            .set_attr("MATLAB_class", class("uint16"));
        b.create_dataset("width").with_f64_data(&[0.35]).with_shape(&[1, 1]).set_attr("MATLAB_class", class("double"));
    });
    assert_eq!(formats::detect_bytes(&lct, f).unwrap(), Format::LctMat);
    let t = formats::read_bytes_as(&lct, Format::LctMat, f).unwrap();
    // ix = N−1−i = 1, iy = N−1−j = 0.
    assert_eq!(t.histogram(1)[1], 9.0);
    assert_eq!(t.scan().sensors().points[1].x, 0.35);
}

// ---------------------------------------------------------------- malformed input

/// A minimal TAL file with one dataset replaced (`Some`) or removed (`None`).
fn tal_with(replace: &str, with: Option<&dyn Fn(&mut FileBuilder)>) -> Vec<u8> {
    let t = filled(Scan::confocal(grid(2, 2, 0.0, 1.0)), 3, false);
    let good = hdf5::write_tal(&t, Path::new("x")).unwrap();
    let file = hdf5_pure::File::from_bytes(good).unwrap();
    let mut b = FileBuilder::new();
    for name in file.root().datasets().unwrap() {
        let d = file.dataset(&name).unwrap();
        if name == replace {
            if let Some(w) = with {
                w(&mut b);
            }
            continue;
        }
        let shape = d.shape().unwrap();
        match name.as_str() {
            "scene_info" => {
                b.create_dataset(&name).with_vlen_strings(&["x"]).with_shape(&[]);
            }
            _ => {
                b.create_dataset(&name).with_f64_data(&d.read_f64().unwrap()).with_shape(&shape);
            }
        }
    }
    b.finish().unwrap()
}

#[test]
fn tal_malformed_fields_are_typed_errors() {
    let f = Path::new("bad.hdf5");
    let read = |b: &[u8]| formats::read_bytes_as(b, Format::Tal, f).unwrap_err();
    let e = read(&tal_with("delta_t", None));
    assert!(matches!(e, TransientError::MissingField { ref field, .. } if field == "delta_t"), "{e}");
    let e = read(&tal_with("sensor_grid_xyz", None));
    assert!(matches!(e, TransientError::MissingField { ref field, .. } if field == "sensor_grid_xyz"), "{e}");
    let e = read(&tal_with(
        "H",
        Some(&|b: &mut FileBuilder| {
            b.create_dataset("H").with_vlen_strings(&["not numbers"]);
        }),
    ));
    assert!(matches!(e, TransientError::WrongType { ref field, .. } if field == "H"), "{e}");
    let e = read(&tal_with(
        "H",
        Some(&|b: &mut FileBuilder| {
            let mut v = vec![1.0f32; 12];
            v[5] = f32::NAN;
            b.create_dataset("H").with_f32_data(&v).with_shape(&[3, 2, 2]);
        }),
    ));
    assert!(matches!(e, TransientError::NonFinite { ref field, index: 5, .. } if field == "H"), "{e}");
    let e = read(&tal_with(
        "H",
        Some(&|b: &mut FileBuilder| {
            b.create_dataset("H").with_f32_data(&[0.0; 12]).with_shape(&[3, 4, 1]);
        }),
    ));
    assert!(matches!(e, TransientError::WrongShape { ref field, .. } if field == "H"), "{e}");
    let e = read(&tal_with(
        "H_format",
        Some(&|b: &mut FileBuilder| {
            b.create_dataset("H_format").with_i32_data(&[7]);
        }),
    ));
    assert!(matches!(e, TransientError::Unsupported { ref what, .. } if what.contains("H_format")), "{e}");
    for who in ["sensor", "laser"] {
        let zero = |b: &mut FileBuilder| {
            b.create_dataset("sensor_grid_xyz").with_f32_data(&[]).with_shape(&[0, 0, 3]);
        };
        let zero_l = |b: &mut FileBuilder| {
            b.create_dataset("laser_grid_xyz").with_f32_data(&[]).with_shape(&[0, 0, 3]);
        };
        let bytes = if who == "sensor" {
            tal_with("sensor_grid_xyz", Some(&zero))
        } else {
            tal_with("laser_grid_xyz", Some(&zero_l))
        };
        let e = read(&bytes);
        assert!(matches!(e, TransientError::InvalidValue { .. } | TransientError::WrongShape { .. }), "{who}: {e}");
        assert!(e.to_string().contains("grid"), "{e}");
    }
}

#[test]
fn every_prefix_of_a_small_tal_file_is_an_error() {
    let f = Path::new("cut.hdf5");
    let t = filled(Scan::confocal(grid(2, 2, 0.0, 1.0)), 3, true);
    let bytes = hdf5::write_tal(&t, f).unwrap();
    for n in 0..bytes.len() {
        let cut = &bytes[..n];
        assert!(
            formats::detect_bytes(cut, f).is_err() || formats::read_bytes_as(cut, Format::Tal, f).is_err(),
            "prefix {n} of {}",
            bytes.len()
        );
        assert!(formats::read_bytes_as(cut, Format::Tal, f).is_err(), "prefix {n} read");
        assert!(formats::read_bytes_as(cut, Format::ZNlos, f).is_err(), "prefix {n} read");
    }
}

/// Writes one TAL file per scan kind into `$NLOS_TAL_SAMPLES` for an external check with h5py / y-tal
/// (not needed in CI): `NLOS_TAL_SAMPLES=out/tal cargo test --test hdf5_formats -- --ignored samples`.
#[test]
#[ignore = "writes files for an external h5py check"]
fn write_tal_samples_for_h5py() {
    let Ok(dir) = std::env::var("NLOS_TAL_SAMPLES") else { return };
    std::fs::create_dir_all(&dir).unwrap();
    for (i, (what, scan)) in scans().into_iter().enumerate() {
        let t = filled(with_devices(scan, true), 9, true);
        let path = Path::new(&dir).join(format!("{i}_{}.hdf5", what.replace([' ', '×'], "_")));
        formats::write(&t, &path, Format::Tal).unwrap();
        // The values h5py should see: H[0, …] flattened and the first sensor point.
        eprintln!("{} first {:?} t0 {:?}", path.display(), t.histogram(0)[0], t.time().t0);
    }
}

/// Fuzz finding (`fuzz/fuzz_targets/hdf5.rs`): a corrupt chunk index makes `hdf5-pure` 0.47 overflow
/// in `chunked_read.rs` (a panic when overflow checks are on). The reader's `catch_unwind` guard turns
/// it into a typed error naming the dataset.
#[test]
fn regression_hdf5_pure_chunk_offset_overflow_is_malformed() {
    let bytes = include_bytes!("../../../fuzz/regressions/hdf5/hdf5_pure_chunk_offset_overflow.bin");
    let f = Path::new("crash.hdf5");
    let e = formats::read_bytes_as(bytes, Format::Tal, f).unwrap_err();
    assert!(matches!(e, TransientError::Malformed { .. } | TransientError::Truncated { .. }), "{e}");
    assert!(e.to_string().contains("crash.hdf5"), "{e}");
    for format in [Format::ZNlos, Format::FkMat, Format::LctMat] {
        assert!(formats::read_bytes_as(bytes, format, f).is_err());
    }
    let _ = formats::detect_bytes(bytes, f);
}

/// The same Z-NLOS scene as the dataset's HDF5 and as NeTF's `.mat` made from it by NeTF's own
/// `zaragoza_preprocess.m` (done here step by step in MATLAB's index order): `h5read` (every dimension
/// reversed), each histogram shifted earlier by `ceil(device legs / deltaT)` bins, pairs of bins averaged,
/// `permute(data, [3, 1, 2])`, the positions flattened row by row (`(i − 1)·N + j`), `deltaT` kept. Both
/// readers land at the same points with the same normals, and each histogram's mean path agrees within one
/// bin of the HDF5 (the script's whole-bin shift): the HDF5's bins are `deltaT` of path with the device
/// legs, the `.mat`'s `2·deltaT` without them.
///
/// What it catches: the `.mat` reader taking `deltaT` as path per bin (every mean path at half its length)
/// or pairing `data(:, i, j)` with column `i + M·j` (MATLAB's column-major order, not the script's).
#[test]
fn znlos_hdf5_and_netf_mat_agree() {
    let (a, b, t) = (4usize, 5usize, 160usize);
    let n = a * b;
    let delta = 0.004;
    // HDF5 C order: positions (3, A, B), point p = ia·B + ib at (0.1·ib − 0.2, 0, 0.05·ia − 0.1).
    let at = |p: usize| [0.1 * (p % b) as f32 - 0.2, 0.0, 0.05 * (p / b) as f32 - 0.1];
    let camera = [0.0f32, 0.1, 0.0];
    let legs = |p: usize| 2.0 * f64::from(Vec3::from(at(p)).distance(Vec3::from(camera)));
    // Histograms: two returns per point, at hidden paths depending on the point, in bins of the HDF5 axis
    // (which holds the legs).
    let value = |p: usize, k: usize| {
        let hidden = k as f64 * delta - legs(p);
        let bump = |c: f64| (-((hidden - c) / 0.01).powi(2)).exp();
        (bump(0.04 + 0.002 * p as f64) + 0.5 * bump(0.09)) as f32
    };
    let xyz: Vec<f32> = (0..3).flat_map(|c| (0..n).map(move |p| at(p)[c])).collect();
    let normals: Vec<f32> = (0..3).flat_map(|c| (0..n).map(move |_| if c == 1 { -1.0 } else { 0.0 })).collect();
    let data: Vec<f32> = (0..t).flat_map(|k| (0..n).map(move |p| value(p, k))).collect();
    let mut h = FileBuilder::new();
    h.create_dataset("data").with_f32_data(&data).with_shape(&[t as u64, a as u64, b as u64]);
    for (name, v) in [("cameraGridPositions", &xyz), ("laserGridPositions", &xyz)] {
        h.create_dataset(name).with_f32_data(v).with_shape(&[3, a as u64, b as u64]);
    }
    for name in ["cameraGridNormals", "laserGridNormals"] {
        h.create_dataset(name).with_f32_data(&normals).with_shape(&[3, a as u64, b as u64]);
    }
    h.create_dataset("cameraPosition").with_f32_data(&camera).with_shape(&[3, 1]);
    h.create_dataset("laserPosition").with_f32_data(&camera).with_shape(&[3, 1]);
    h.create_dataset("deltaT").with_f64_data(&[delta]).with_shape(&[]);
    h.create_dataset("t0").with_f64_data(&[0.0]).with_shape(&[]);
    h.create_dataset("isConfocal").with_i32_data(&[1]).with_shape(&[]);
    let hdf5 = formats::read_bytes_as(&h.finish().unwrap(), Format::ZNlos, Path::new("scene.hdf5")).unwrap();
    // zaragoza_preprocess.m. h5read: MATLAB data(i, j, k) = HDF5 data[k][j][i] (M = B, N = A), positions
    // cameraGridPositions(i, j, :) likewise; the point of (i, j) is p = j·B + i.
    let (m_rows, n_cols, half) = (b, a, t / 2);
    let point = |i: usize, j: usize| j * b + i;
    let shifted = |p: usize, k: usize| {
        let tdist = (legs(p) / delta).ceil() as usize;
        if k + tdist < t { f64::from(value(p, k + tdist)) } else { 0.0 } // circshift: wraps zeros here
    };
    // After permute([3, 1, 2]): T/2 × M × N, column-major: element (k, i, j) at k + T/2·(i + M·j).
    let mut mat_data = vec![0.0f64; half * n];
    for j in 0..n_cols {
        for i in 0..m_rows {
            for k in 0..half {
                let p = point(i, j);
                mat_data[k + half * (i + m_rows * j)] = 0.5 * (shifted(p, 2 * k) + shifted(p, 2 * k + 1));
            }
        }
    }
    // cameraGridPositions_re(:, (i − 1)·N + j) = cameraGridPositions(i, j, :).
    let mut pos = vec![0.0f64; 3 * n];
    for i in 0..m_rows {
        for j in 0..n_cols {
            for c in 0..3 {
                pos[c + 3 * (i * n_cols + j)] = f64::from(at(point(i, j))[c]);
            }
        }
    }
    let vars = vec![
        mat5::double("data", &[half as i32, m_rows as i32, n_cols as i32], mat_data),
        mat5::double("cameraGridPositions", &[3, n as i32], pos),
        mat5::double("deltaT", &[1, 1], vec![delta]),
        mat5::double("hiddenVolumePosition", &[3, 1], vec![0.0, -0.5, 0.0]),
    ];
    let bytes = mat5::write(&vars, mat5::Options::default());
    let netf = formats::read_bytes_as(&bytes, Format::ZNlosMat, Path::new("scene.mat")).unwrap();
    let (ph, pn) = (hdf5.scan().lasers(), netf.scan().lasers());
    assert_eq!(ph.layout, pn.layout);
    assert_eq!(ph.layout, Layout::Grid { nx: b, ny: a });
    assert!(hdf5.time().includes_device_legs && !netf.time().includes_device_legs);
    assert_eq!((netf.time().t0, netf.time().bin_width), (0.0, 2.0 * delta));
    let mean_path = |tr: &Transient, p: usize, legs: f64| {
        let ax = tr.time();
        let (mut s, mut w) = (0.0, 0.0);
        for (k, v) in tr.histogram(p).iter().enumerate() {
            s += f64::from(*v) * (ax.bin_start(k) + 0.5 * ax.bin_width - legs);
            w += f64::from(*v);
        }
        s / w
    };
    for p in 0..n {
        assert!((ph.points[p] - pn.points[p]).length() < 1e-6, "point {p}: {} vs {}", ph.points[p], pn.points[p]);
        assert!((ph.normals[p] - pn.normals[p]).length() < 1e-6 && pn.normals[p] == Vec3::Z);
        let (th, tn) = (mean_path(&hdf5, p, legs(p)), mean_path(&netf, p, 0.0));
        assert!((th - tn).abs() <= delta, "point {p}: mean path {th:.4} m (HDF5) vs {tn:.4} m (.mat)");
    }
}
