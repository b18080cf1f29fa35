//! The `.npy` + JSON sidecar and OpenEXR formats: bit-exact round trips through `write`/`read`, foreign
//! files, the reference data, and malformed input.

use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_transient::formats::npy;
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient, TransientError};

type R = Result<(), TransientError>;
/// A change to a valid sidecar and the field the resulting error must name.
type Case = (Box<dyn FnOnce(&mut serde_json::Value)>, &'static str);

/// A fresh, unique temporary directory for one test.
fn tmp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nlos-npy-exr-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// Data with awkward floats: subnormals, signed zeros, huge and tiny values, arbitrary bit patterns.
fn awkward(n: usize) -> Vec<f32> {
    let special = [
        -0.0,
        0.0,
        f32::from_bits(1),
        -f32::from_bits(0x007f_ffff),
        f32::MIN_POSITIVE,
        f32::MAX,
        -f32::MAX,
        1e38,
        1e-40,
        0.1,
        1.0 / 3.0,
        16_777_217.0,
    ];
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    (0..n)
        .map(|i| {
            if i < special.len() {
                return special[i];
            }
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            let v = f32::from_bits((state >> 32) as u32);
            if v.is_finite() { v } else { f32::from_bits(1) }
        })
        .collect()
}

fn odd_points(n: usize, seed: f32) -> Vec<Vec3> {
    (0..n).map(|i| Vec3::new(seed * i as f32 / 7.0, -0.0, 1e-38 * i as f32 + 0.1)).collect()
}

fn scans() -> Result<Vec<(&'static str, Scan, bool)>, TransientError> {
    let mut grid = PointSet::wall_grid(4, 3, 0.25, 0.1)?;
    grid.points[0].x = -0.0;
    let mut tilted = PointSet::list(odd_points(5, 0.3));
    tilted.normals[2] = Vec3::new(0.0, 0.6, 0.8);
    let mut irregular_grid = PointSet::wall_grid(3, 2, 0.2, 0.2)?;
    irregular_grid.points[4] += Vec3::new(1e-7, 0.0, 1e-9);
    let mut with_devices = Scan::confocal(PointSet::wall_grid(2, 2, 0.5, 0.5)?);
    with_devices.laser_device = Some(Vec3::new(0.0, -0.35, 0.2));
    with_devices.sensor_device = Some(Vec3::new(1.0 / 3.0, f32::from_bits(1), -0.0));
    Ok(vec![
        ("confocal_grid", Scan::confocal(grid), false),
        ("confocal_list", Scan::confocal(tilted.clone()), false),
        ("confocal_irregular_grid", Scan::confocal(irregular_grid), false),
        (
            "exhaustive_grid",
            Scan::exhaustive(PointSet::wall_grid(2, 2, 0.3, 0.3)?, PointSet::wall_grid(3, 1, 0.1, 0.0)?),
            false,
        ),
        ("exhaustive_list", Scan::exhaustive(tilted, PointSet::list(odd_points(2, -1.7))), false),
        ("devices_and_legs", with_devices, true),
        ("paired_grid", Scan::paired(PointSet::wall_grid(3, 2, 0.3, 0.2)?, PointSet::list(odd_points(6, 0.9))), false),
        ("paired_curved", Scan::paired(curved(0.0), curved(0.27)), false),
    ])
}

/// Five spots on a wall curved by ±3 cm, shifted `dx` along x, each with its own normal.
fn curved(dx: f32) -> PointSet {
    let points: Vec<Vec3> =
        (0..5).map(|i| i as f32 * 0.1 - 0.2).map(|x| Vec3::new(x + dx, 0.05 * x, 0.03 * (5.0 * x).sin())).collect();
    let normals = points.iter().map(|p| Vec3::new(-0.15 * (5.0 * (p.x - dx)).cos(), 0.0, 1.0).normalize()).collect();
    PointSet { points, normals, layout: nlos_transient::Layout::List }
}

fn make(scan: Scan, legs: bool, bins: usize) -> Result<Transient, TransientError> {
    let mut time = TimeAxis::new(0.1 + 0.2, 0.0012000000000000001, bins)?;
    time.includes_device_legs = legs;
    let n = scan.measurements() * bins;
    Transient::new(scan, time, awkward(n))
}

/// Bitwise comparison (so that `-0.0` vs `0.0` and every mantissa bit count).
fn assert_bit_exact(a: &Transient, b: &Transient, what: &str) {
    assert_eq!(format!("{:?}", a.scan()), format!("{:?}", b.scan()), "{what}: scan");
    assert_eq!(a.time().t0.to_bits(), b.time().t0.to_bits(), "{what}: t0");
    assert_eq!(a.time().bin_width.to_bits(), b.time().bin_width.to_bits(), "{what}: bin_width");
    assert_eq!(a.time(), b.time(), "{what}: time");
    let bits = |t: &Transient| t.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert!(bits(a) == bits(b), "{what}: data differ");
}

#[test]
fn round_trips_are_bit_exact() -> R {
    let dir = tmp_dir("round_trips");
    for (name, scan, legs) in scans()? {
        let t = make(scan, legs, 7)?;
        for (format, ext) in [(Format::NpyJson, "npy"), (Format::Exr, "exr")] {
            let path = dir.join(format!("{name}.{ext}"));
            nlos_transient::write(&t, &path, format)?;
            assert_eq!(nlos_transient::detect(&path)?, format);
            let back = nlos_transient::read(&path)?;
            assert_bit_exact(&t, &back, &format!("{name}.{ext}"));
        }
        // The npy pair can also be opened through its sidecar.
        let back = nlos_transient::read(dir.join(format!("{name}.json")))?;
        assert_bit_exact(&t, &back, &format!("{name}.json"));
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

#[test]
fn npy_shapes_follow_the_scan() -> R {
    let dir = tmp_dir("npy_shapes");
    for (name, scan, legs) in scans()? {
        let t = make(scan, legs, 3)?;
        let path = dir.join(format!("{name}.npy"));
        nlos_transient::write(&t, &path, Format::NpyJson)?;
        let (values, shape) = npy::read_npy_array(&path)?;
        let expected = match t.scan().pattern {
            nlos_transient::ScanPattern::Confocal(ref p)
            | nlos_transient::ScanPattern::Paired { lasers: ref p, .. } => match p.grid_dims() {
                Some((nx, ny)) => vec![ny, nx, 3],
                None => vec![p.len(), 3],
            },
            _ => vec![t.measurements(), 3],
        };
        assert_eq!(shape, expected, "{name}");
        assert_eq!(values.len(), t.data().len());
        let json: serde_json::Value = serde_json::from_slice(
            &std::fs::read(path.with_extension("json"))
                .map_err(|source| TransientError::Io { file: path.clone(), source })?,
        )
        .map_err(|e| TransientError::Malformed { file: path.clone(), detail: e.to_string() })?;
        assert_eq!(json["format"], "nlos-transient");
        assert_eq!(json["version"], 1);
        assert_eq!(json["data"], format!("{name}.npy"));
        assert_eq!(json["dtype"], "<f4");
        assert_eq!(json["shape"], serde_json::json!(expected));
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

fn reference(name: &str) -> Option<PathBuf> {
    nlos_testdata::shared(&format!("reference/{name}"))
}

#[test]
fn reads_the_independent_reference_cube() -> R {
    let Some(path) = reference("plane_quadrature.npy") else { return Ok(()) };
    let (values, shape) = npy::read_npy_array(&path)?;
    assert_eq!(shape, vec![64, 64, 512]);
    let total: f64 = values.iter().map(|&v| f64::from(v)).sum();
    assert!((total / 91.42858 - 1.0).abs() < 1e-3, "total {total}");
    // The same cube as a transient: a 64 × 64 confocal grid, 512 bins of 4 mm (README section 2).
    let xs: Vec<f32> = (0..64).map(|i| -0.25 + (i as f32 + 0.5) * 0.5 / 64.0).collect();
    let points = xs.iter().flat_map(|&y| xs.iter().map(move |&x| Vec3::new(x, y, 0.0))).collect();
    let set =
        PointSet { points, normals: vec![Vec3::Z; 4096], layout: nlos_transient::Layout::Grid { nx: 64, ny: 64 } };
    let t = Transient::new(Scan::confocal(set), TimeAxis::new(0.0, 0.004, 512)?, values)?;
    let dir = tmp_dir("reference");
    for (format, ext) in [(Format::NpyJson, "npy"), (Format::Exr, "exr")] {
        let out = dir.join(format!("plane.{ext}"));
        nlos_transient::write(&t, &out, format)?;
        assert_bit_exact(&t, &nlos_transient::read(&out)?, ext);
    }
    // The .npy we write is byte-identical to the reference (same NumPy v1.0 header layout).
    let ours =
        std::fs::read(dir.join("plane.npy")).map_err(|source| TransientError::Io { file: dir.clone(), source })?;
    let theirs = std::fs::read(&path).map_err(|source| TransientError::Io { file: path.clone(), source })?;
    assert!(ours == theirs, "our .npy differs from NumPy's");
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

#[test]
fn reads_other_reference_arrays() -> R {
    let Some(path) = reference("bunny_quadrature_stride4_pixels.npy") else { return Ok(()) };
    let (values, shape) = npy::read_npy_array(&path)?;
    assert_eq!(shape, vec![256, 2]);
    assert!(values.iter().all(|v| v.fract() == 0.0 && (0.0..64.0).contains(v)));
    Ok(())
}

/// A pair as written by the Python snippet of `docs/formats/npy-json.md` (float64 data, `json.dump`).
fn python_style_pair() -> (Vec<u8>, Vec<u8>) {
    let (nx, ny, bins) = (3usize, 2usize, 4usize);
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({ny}, {nx}, {bins}), }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut npy = b"\x93NUMPY\x01\x00".to_vec();
    npy.extend_from_slice(&(header.len() as u16).to_le_bytes());
    npy.extend_from_slice(header.as_bytes());
    for i in 0..nx * ny * bins {
        npy.extend_from_slice(&(i as f64 * 0.5).to_le_bytes());
    }
    let json = r#"{"format": "nlos-transient", "version": 1, "data": "capture.npy", "dtype": "<f8", "shape": [2, 3, 4],
        "time": {"t0": 0.0, "bin_width": 0.004, "bins": 4, "includes_device_legs": false},
        "scan": {"pattern": "confocal",
                 "points": {"grid": [3, 2], "x": [-0.25, 0.0, 0.25], "y": [-0.25, 0.25], "z": 0.0,
                            "normal": [0.0, 0.0, 1.0]},
                 "laser_device": null, "sensor_device": null}}"#;
    (npy, json.as_bytes().to_vec())
}

#[test]
fn reads_a_python_written_pair() -> R {
    let (npy_bytes, json) = python_style_pair();
    let t = npy::read(&npy_bytes, &json, Path::new("capture.npy"))?;
    assert_eq!(t.scan().lasers().grid_dims(), Some((3, 2)));
    assert_eq!(t.scan().lasers().points[4], Vec3::new(0.0, 0.25, 0.0));
    assert_eq!(t.histogram(1), &[2.0, 2.5, 3.0, 3.5]);
    assert_eq!(t.time().bin_width, 0.004);
    // Fortran-order (2, 12) variant of a list scan: data[m, k] stored column-major.
    let mut header = "{'descr': '>f4', 'fortran_order': True, 'shape': (2, 3), }".to_owned();
    header.push('\n');
    let mut f = b"\x93NUMPY\x02\x00".to_vec();
    f.extend_from_slice(&(header.len() as u32).to_le_bytes());
    f.extend_from_slice(header.as_bytes());
    for k in 0..3 {
        for m in 0..2 {
            f.extend_from_slice(&((10 * m + k) as f32).to_be_bytes());
        }
    }
    let json = br#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bin_width":1,"bins":3},
        "scan":{"pattern":"confocal","points":{"points":[[0,0,0],[1,0,0]]}}}"#;
    let t = npy::read(&f, json, Path::new("f.npy"))?;
    assert_eq!(t.data(), &[0.0, 1.0, 2.0, 10.0, 11.0, 12.0]);
    Ok(())
}

fn valid_npy_pair() -> Result<(Transient, Vec<u8>, Vec<u8>), TransientError> {
    let t = make(Scan::confocal(PointSet::wall_grid(3, 2, 0.25, 0.25)?), false, 5)?;
    let (npy_bytes, json) = npy::write(&t, Path::new("v.npy"))?;
    Ok((t, npy_bytes, json))
}

#[test]
fn every_prefix_of_a_valid_npy_is_an_error() -> R {
    let (_, npy_bytes, json) = valid_npy_pair()?;
    npy::read(&npy_bytes, &json, Path::new("v.npy"))?;
    for n in 0..npy_bytes.len() {
        let r = npy::read(&npy_bytes[..n], &json, Path::new("v.npy"));
        assert!(r.is_err(), "prefix of {n} bytes was accepted");
    }
    // (The sidecar ends with a newline: every prefix shorter than the JSON text itself.)
    for n in 0..json.trim_ascii_end().len() {
        assert!(npy::read(&npy_bytes, &json[..n], Path::new("v.npy")).is_err(), "sidecar prefix {n} accepted");
    }
    Ok(())
}

#[test]
fn every_prefix_of_a_valid_exr_is_an_error() -> R {
    let t = make(Scan::confocal(PointSet::wall_grid(3, 2, 0.25, 0.25)?), true, 40)?;
    let bytes = nlos_transient::formats::exr::write(&t, Path::new("v.exr"))?;
    assert_bit_exact(&t, &nlos_transient::formats::exr::read(&bytes, Path::new("v.exr"))?, "exr");
    for n in 0..bytes.len() {
        let r = nlos_transient::formats::exr::read(&bytes[..n], Path::new("v.exr"));
        assert!(r.is_err(), "prefix of {n} bytes was accepted");
    }
    Ok(())
}

fn npy_with(header: &str, data: &[u8]) -> Vec<u8> {
    let mut h = header.to_owned();
    h.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(h.len() as u16).to_le_bytes());
    out.extend_from_slice(h.as_bytes());
    out.extend_from_slice(data);
    out
}

fn field_of(e: &TransientError) -> String {
    match e {
        TransientError::MissingField { field, .. }
        | TransientError::WrongShape { field, .. }
        | TransientError::WrongType { field, .. }
        | TransientError::InvalidValue { field, .. }
        | TransientError::NonFinite { field, .. } => field.clone(),
        other => format!("<{other}>"),
    }
}

#[test]
fn malformed_npy_inputs_name_file_and_field() -> R {
    let (_, _, json) = valid_npy_pair()?;
    let f = Path::new("v.npy");
    let zeros = |n: usize, size: usize| vec![0u8; n * size];
    // Header shape disagrees with the sidecar (6 measurements × 5 bins).
    let e =
        npy::read(&npy_with("{'descr': '<f4', 'fortran_order': False, 'shape': (5, 5), }", &zeros(25, 4)), &json, f)
            .expect_err("wrong shape");
    assert_eq!(field_of(&e), "npy header.shape", "{e}");
    assert!(e.to_string().contains("v.npy") && e.to_string().contains("(6, 5)"), "{e}");
    let e =
        npy::read(&npy_with("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 2, 5), }", &zeros(30, 4)), &json, f)
            .expect_err("transposed grid");
    assert_eq!(field_of(&e), "npy header.shape", "{e}");
    // Unsupported dtypes.
    for descr in ["<c8", "|O", "<U4", "<M8[ns]"] {
        let h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': (6, 5), }}");
        let e = npy::read(&npy_with(&h, &zeros(30, 8)), &json, f).expect_err(descr);
        assert!(matches!(e, TransientError::WrongType { .. }), "{descr}: {e}");
        assert_eq!(field_of(&e), "npy header.descr");
    }
    // NaN and infinity in the data.
    for bad in [f32::NAN, f32::NEG_INFINITY] {
        let mut data = [0.0f32; 30];
        data[17] = bad;
        let raw: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let e = npy::read(&npy_with("{'descr': '<f4', 'fortran_order': False, 'shape': (6, 5), }", &raw), &json, f)
            .expect_err("nan");
        assert!(matches!(e, TransientError::NonFinite { index: 17, .. }), "{e}");
        assert_eq!(field_of(&e), "npy data");
    }
    // Zero-sized array.
    let e = npy::read(&npy_with("{'descr': '<f4', 'fortran_order': False, 'shape': (0, 5), }", &[]), &json, f)
        .expect_err("zero");
    assert_eq!(field_of(&e), "npy header.shape", "{e}");
    Ok(())
}

fn sidecar_with(edit: impl FnOnce(&mut serde_json::Value)) -> Result<Vec<u8>, TransientError> {
    let (_, _, json) = valid_npy_pair()?;
    let mut v: serde_json::Value = serde_json::from_slice(&json)
        .map_err(|e| TransientError::Malformed { file: "v.json".into(), detail: e.to_string() })?;
    edit(&mut v);
    Ok(v.to_string().into_bytes())
}

#[test]
fn malformed_sidecars_name_file_and_field() -> R {
    let (_, npy_bytes, _) = valid_npy_pair()?;
    let f = Path::new("dir/v.npy");
    let cases: Vec<Case> = vec![
        (Box::new(|v| v["shape"] = serde_json::json!([3, 2, 5])), "sidecar.shape"),
        (Box::new(|v| v["dtype"] = serde_json::json!("<f8")), "sidecar.dtype"),
        (Box::new(|v| v["time"]["bin_width"] = serde_json::json!(0)), "sidecar.time.bin_width"),
        (Box::new(|v| v["time"]["bins"] = serde_json::json!(6)), "npy header.shape"),
        (Box::new(|v| v["time"]["t0"] = serde_json::json!("zero")), "sidecar.time.t0"),
        (Box::new(|v| v["scan"]["pattern"] = serde_json::json!("raster")), "sidecar.scan.pattern"),
        (Box::new(|v| v["scan"]["points"]["grid"] = serde_json::json!([2, 3])), "sidecar.scan.points.x"),
        (Box::new(|v| v["scan"]["points"]["normal"] = serde_json::json!([0, 0, 2])), "sidecar.scan.points.normal"),
        (
            Box::new(|v| {
                v["scan"]["points"] = serde_json::json!({"grid": [0, 0], "x": [], "y": [], "z": 0});
                v["shape"] = serde_json::json!([0, 0, 5]);
            }),
            "sidecar.scan.points",
        ),
        (Box::new(|v| v["scan"]["laser_device"] = serde_json::json!([0, 1])), "sidecar.scan.laser_device"),
        (
            Box::new(|v| {
                if let Some(o) = v.as_object_mut() {
                    o.remove("time");
                }
            }),
            "sidecar.time",
        ),
    ];
    for (edit, field) in cases {
        let json = sidecar_with(edit)?;
        let e = npy::read(&npy_bytes, &json, f).expect_err(field);
        assert_eq!(field_of(&e), field, "{e}");
        let file = if field.starts_with("npy") { "dir/v.npy" } else { "dir/v.json" };
        assert!(e.to_string().starts_with(file), "{e}");
    }
    let json = sidecar_with(|v| v["version"] = serde_json::json!(2))?;
    assert!(matches!(npy::read(&npy_bytes, &json, f), Err(TransientError::Unsupported { .. })));
    assert!(matches!(npy::read(&npy_bytes, b"[1, 2]", f), Err(TransientError::WrongType { .. })));
    assert!(matches!(npy::read(&npy_bytes, b"{\"a\": ", f), Err(TransientError::Malformed { .. })));
    Ok(())
}

#[test]
fn missing_sidecar_names_the_path_and_says_to_write_it() -> R {
    let dir = tmp_dir("missing_sidecar");
    let (_, npy_bytes, _) = valid_npy_pair()?;
    let path = dir.join("lonely.npy");
    std::fs::write(&path, &npy_bytes).map_err(|source| TransientError::Io { file: path.clone(), source })?;
    let json = dir.join("lonely.json");
    let e = npy::read_pair(&path, &json).expect_err("no sidecar");
    let msg = e.to_string();
    assert!(matches!(e, TransientError::MissingField { .. }), "{msg}");
    assert!(msg.contains(&json.display().to_string()) && msg.contains("write"), "{msg}");
    // Through the generic reader the error still names the sidecar path.
    let msg = nlos_transient::read(&path).expect_err("no sidecar").to_string();
    assert!(msg.contains(&json.display().to_string()), "{msg}");
    // The bare array still loads.
    assert_eq!(npy::read_npy_array(&path)?.1, vec![2, 3, 5]);
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

// ---------------------------------------------------------------------------------------------------------
// EXR written by other tools

fn foreign_exr(
    channels: &[(&str, bool)],
    width: usize,
    height: usize,
    attrs: Vec<(&str, exr::prelude::AttributeValue)>,
) -> Vec<u8> {
    use exr::prelude::*;
    let mut layer_attrs = LayerAttributes::default();
    for (k, v) in attrs {
        layer_attrs.other.insert(Text::from(k), v);
    }
    let mut list = SmallVec::new();
    for (i, &(name, half)) in channels.iter().enumerate() {
        let values = (0..width * height).map(|j| (j + i) as f32 * 0.5);
        let samples = if half {
            FlatSamples::F16(values.map(f16::from_f32).collect())
        } else {
            FlatSamples::F32(values.collect())
        };
        list.push(AnyChannel::new(name, samples));
    }
    let encoding =
        Encoding { compression: Compression::RLE, blocks: Blocks::ScanLines, line_order: LineOrder::Increasing };
    let layer = Layer::new((width, height), layer_attrs, encoding, AnyChannels::sort(list));
    let image = Image::from_layer(layer);
    let mut out = Vec::new();
    image.write().to_buffered(std::io::Cursor::new(&mut out)).expect("write test exr");
    out
}

fn geometry_text(m: usize, bins: usize) -> exr::prelude::AttributeValue {
    let json = format!(
        r#"{{"format":"nlos-transient","version":1,"time":{{"t0":0,"bin_width":0.01,"bins":{bins}}},
           "scan":{{"pattern":"confocal","points":{{"points":{}}}}}}}"#,
        serde_json::json!((0..m).map(|i| [i as f32 * 0.1, 0.0, 0.0]).collect::<Vec<_>>())
    );
    exr::prelude::AttributeValue::Text(exr::prelude::Text::from(json.as_str()))
}

#[test]
fn reads_foreign_exr_channels() -> R {
    let f = Path::new("foreign.exr");
    // One half-float channel of any name.
    let bytes = foreign_exr(&[("transient", true)], 4, 3, vec![("nlos", geometry_text(3, 4))]);
    let t = nlos_transient::formats::exr::read(&bytes, f)?;
    assert_eq!(t.histogram(2), &[4.0, 4.5, 5.0, 5.5]);
    // RGB: the R channel is used.
    let bytes = foreign_exr(&[("R", false), ("G", false), ("B", false)], 4, 3, vec![("nlos", geometry_text(3, 4))]);
    let t = nlos_transient::formats::exr::read(&bytes, f)?;
    assert_eq!(t.histogram(0), &[0.0, 0.5, 1.0, 1.5]); // G and B are offset by 0.5 and 1
    // Two channels, neither Y nor R.
    let bytes = foreign_exr(&[("A", false), ("B", false)], 4, 3, vec![("nlos", geometry_text(3, 4))]);
    let e = nlos_transient::formats::exr::read(&bytes, f).expect_err("no usable channel");
    assert_eq!(field_of(&e), "exr channel", "{e}");
    // No geometry.
    let bytes = foreign_exr(&[("Y", false)], 4, 3, vec![]);
    let e = nlos_transient::formats::exr::read(&bytes, f).expect_err("no attribute");
    assert_eq!(field_of(&e), "exr attribute nlos", "{e}");
    // Geometry of the wrong size.
    let bytes = foreign_exr(&[("Y", false)], 4, 3, vec![("nlos", geometry_text(2, 4))]);
    let e = nlos_transient::formats::exr::read(&bytes, f).expect_err("size");
    assert_eq!(field_of(&e), "exr data window", "{e}");
    // Bad JSON field.
    let bad = exr::prelude::AttributeValue::Text(exr::prelude::Text::from(
        r#"{"format":"nlos-transient","version":1,"time":{"t0":0,"bin_width":-1,"bins":4},"scan":{}}"#,
    ));
    let bytes = foreign_exr(&[("Y", false)], 4, 3, vec![("nlos", bad)]);
    let e = nlos_transient::formats::exr::read(&bytes, f).expect_err("bin width");
    assert_eq!(field_of(&e), "exr attribute nlos.time.bin_width", "{e}");
    Ok(())
}

#[test]
fn exr_rejects_nan_and_oversized_transients() -> R {
    let f = Path::new("n.exr");
    let mut t = make(Scan::confocal(PointSet::list(odd_points(2, 1.0))), false, 3)?;
    let good = nlos_transient::formats::exr::write(&t, f)?;
    // Patch a NaN in through the exr crate: write the same header with a NaN sample.
    t.data_mut()[4] = f32::NAN;
    let json = {
        use exr::prelude::*;
        let meta = MetaData::read_from_buffered(std::io::Cursor::new(&good), false).expect("meta");
        meta.headers[0].own_attributes.other.get(&Text::from("nlos")).cloned().expect("nlos attribute")
    };
    let mut data = t.data().to_vec();
    data[4] = f32::NAN;
    let bytes = {
        use exr::prelude::*;
        let mut a = LayerAttributes::default();
        a.other.insert(Text::from("nlos"), json);
        let layer = Layer::new((3, 2), a, Encoding::default(), AnyChannels::sort(smallvec::smallvec_inline(data)));
        let mut out = Vec::new();
        Image::from_layer(layer).write().to_buffered(std::io::Cursor::new(&mut out)).expect("write");
        out
    };
    let e = nlos_transient::formats::exr::read(&bytes, f).expect_err("nan");
    assert!(matches!(e, TransientError::NonFinite { index: 4, .. }), "{e}");
    assert_eq!(field_of(&e), "exr channel Y");
    // Too many bins for one EXR scan line block.
    let wide = Transient::zeros(
        Scan::confocal(PointSet::list(vec![Vec3::ZERO])),
        TimeAxis::new(0.0, 1e-3, nlos_transient::formats::exr::MAX_BINS + 1)?,
    )?;
    let e = nlos_transient::formats::exr::write(&wide, f).expect_err("too wide");
    assert!(matches!(e, TransientError::CannotWrite { .. }), "{e}");
    Ok(())
}

mod smallvec {
    //! One-channel list for the NaN test.
    use exr::prelude::{AnyChannel, FlatSamples, SmallVec};

    pub fn smallvec_inline(data: Vec<f32>) -> SmallVec<[AnyChannel<FlatSamples>; 4]> {
        let mut list = SmallVec::new();
        list.push(AnyChannel::new("Y", FlatSamples::F32(data)));
        list
    }
}

#[test]
fn large_point_lists_round_trip() -> R {
    // 20 000 irregular points: a long JSON in the sidecar and in the EXR text attribute.
    let mut set = PointSet::list(odd_points(20_000, 0.77));
    set.normals[7] = Vec3::new(0.6, 0.0, 0.8);
    let t = make(Scan::confocal(set), false, 2)?;
    let dir = tmp_dir("large_lists");
    for (format, ext) in [(Format::NpyJson, "npy"), (Format::Exr, "exr")] {
        let path = dir.join(format!("big.{ext}"));
        nlos_transient::write(&t, &path, format)?;
        assert_bit_exact(&t, &nlos_transient::read(&path)?, ext);
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

/// `exr::read_image` (depth and normal maps): one channel is height × width, R, G, B is height × width × 3
/// with x, y, z interleaved per pixel; other channel sets are typed errors.
#[test]
fn exr_maps() {
    let dir = std::env::temp_dir().join(format!("nlos-exr-map-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let f = dir.join("m.exr");
    // Channel i holds (pixel + i)/2 (see `foreign_exr`).
    std::fs::write(&f, foreign_exr(&[("Z", false)], 4, 3, vec![])).expect("write");
    let (v, shape) = nlos_transient::formats::exr::read_image(&f).expect("depth");
    assert_eq!((shape, v[5]), (vec![3, 4], 2.5));
    std::fs::write(&f, foreign_exr(&[("R", false), ("G", false), ("B", true)], 4, 3, vec![])).expect("write");
    let (v, shape) = nlos_transient::formats::exr::read_image(&f).expect("normals");
    assert_eq!(shape, vec![3, 4, 3]);
    // Pixel 5: R = 2.5, G = 3.0, B = 3.5 (channels sorted B, G, R in the file: read by name).
    assert_eq!(&v[15..18], &[2.5, 3.0, 3.5]);
    std::fs::write(&f, foreign_exr(&[("A", false), ("Q", false)], 4, 3, vec![])).expect("write");
    assert!(matches!(nlos_transient::formats::exr::read_image(&f), Err(TransientError::Unsupported { .. })));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A laser spot off the plane of the sensor grid (here 0.3 m into the hidden scene) is refused by the reader,
/// naming the file and the field; a spot within the wall's tolerance is read.
#[test]
fn a_spot_off_the_grid_plane_names_file_and_field() -> R {
    let scan = Scan::exhaustive(PointSet::list(vec![Vec3::ZERO]), PointSet::wall_grid(3, 2, 0.2, 0.1)?);
    let t = Transient::new(scan, TimeAxis::new(0.0, 0.01, 5)?, vec![1.0; 30])?;
    let f = Path::new("dir/nc.npy");
    let (npy_bytes, json) = npy::write(&t, f)?;
    let mut v: serde_json::Value = serde_json::from_slice(&json)
        .map_err(|e| TransientError::Malformed { file: "nc.json".into(), detail: e.to_string() })?;
    v["scan"]["lasers"]["points"] = serde_json::json!([[0.0, 0.0, 0.3]]);
    let e = npy::read(&npy_bytes, v.to_string().as_bytes(), f).expect_err("off the wall");
    assert!(field_of(&e).contains("laser_points"), "{e}");
    assert!(e.to_string().contains("dir/nc") && e.to_string().contains("off the plane of the sensor grid"), "{e}");
    v["scan"]["lasers"]["points"] = serde_json::json!([[0.0, 0.0, 0.005]]);
    npy::read(&npy_bytes, v.to_string().as_bytes(), f)?;
    Ok(())
}
