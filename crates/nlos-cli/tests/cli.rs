//! End-to-end tests of the `nlos` binary on files written by `nlos_transient::write` and on the real
//! captures in `shared/data/measured` (skipped with a message when absent).

use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient};

mod common;
use common::{nlos, stderr, stdout};

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    common::scratch("cli", name)
}

/// A confocal 8 × 6 grid with a background, direct light at the start and a hidden return at 0.8–0.85 m of path.
fn synthetic() -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(8, 6, 0.25, 0.2).expect("grid"));
    let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.01, 120).expect("axis")).expect("transient");
    for m in 0..t.measurements() {
        let h = t.histogram_mut(m);
        h.fill(0.25); // ambient background
        h[0] = 1000.0;
        h[1] = 300.0;
        h[2] = 50.0;
        h[80 + m % 5] = 20.0 + m as f32;
        h[100] = 0.5;
    }
    t
}

/// Writes `t` in the first format whose writer works, returning the path (the `Option` keeps the callers'
/// `let … else`); every writer failing is a failure of the test, never a skip.
fn write_any(t: &Transient, dir: &Path) -> Option<(PathBuf, Format)> {
    let mut errors = Vec::new();
    for (f, ext) in [(Format::NpyJson, "npy"), (Format::Exr, "exr"), (Format::Tal, "hdf5")] {
        let p = dir.join(format!("capture.{ext}"));
        match nlos_transient::write(t, &p, f) {
            Ok(()) => return Some((p, f)),
            Err(e) => errors.push(format!("{}: {e}", f.name())),
        }
    }
    panic!("no capture writer works: {}", errors.join("; "));
}

fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).expect("png written");
    let dec = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = dec.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("png data");
    (info.width, info.height)
}

#[test]
fn info_on_synthetic() {
    let dir = scratch("info");
    let Some((file, format)) = write_any(&synthetic(), &dir) else { return };
    let o = nlos(&["info", file.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains(format.name()), "{out}");
    assert!(out.contains("confocal: 48 scan spots on a 8 × 6 grid"), "{out}");
    assert!(out.contains("120 bins of 10 mm"), "{out}");
    assert!(out.contains("peak depth:"), "{out}");
    let o = nlos(&["info", "--json", file.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("json");
    assert_eq!(v["time"]["bins"], 120);
    assert_eq!(v["scan"]["sensors"]["nx"], 8);
    assert_eq!(v["scan"]["wall_extent_m"]["max"][0], 0.25);
    let depth = v["peak"]["depth_m"].as_f64().expect("depth");
    assert!((0.4..0.43).contains(&depth), "{depth}");
}

#[test]
fn convert_round_trips_and_transforms() {
    let dir = scratch("convert");
    let t = synthetic();
    let Some((file, _)) = write_any(&t, &dir) else { return };
    for target in ["copy.npy", "copy.exr", "copy.hdf5"] {
        let out = dir.join(target);
        let o = nlos(&["convert", file.to_str().expect("utf8"), out.to_str().expect("utf8")]);
        if !o.status.success() {
            eprintln!("skipping {target}: {}", stderr(&o));
            continue;
        }
        assert_eq!(nlos_transient::read(&out).expect("read back"), t, "{target}");
    }
    let out = dir.join("small.npy");
    let args = ["--crop-bins", "10..110", "--gate", "0.5", "--rebin", "4", "--subsample", "2"];
    let o = nlos(&[&["convert", file.to_str().expect("utf8"), out.to_str().expect("utf8")], &args[..]].concat());
    if o.status.success() {
        let expected =
            t.crop_bins(10, 110).and_then(|t| t.gate(0.5)).and_then(|t| t.rebin(4)).and_then(|t| t.subsample(2, 2));
        assert_eq!(nlos_transient::read(&out).expect("read back"), expected.expect("library ops"));
    } else {
        eprintln!("skipping transformed convert: {}", stderr(&o));
    }
}

#[test]
fn absurd_arguments_exit_2_without_panicking() {
    let dir = scratch("absurd");
    let Some((file, _)) = write_any(&synthetic(), &dir) else { return };
    let f = file.to_str().expect("utf8");
    let out = dir.join("o.npy");
    let o = out.to_str().expect("utf8");
    let png = dir.join("p.png");
    let p = png.to_str().expect("utf8");
    let cases: Vec<Vec<&str>> = vec![
        vec!["convert", f, o, "--rebin", "0"],
        vec!["convert", f, o, "--rebin", "100000"],
        vec!["convert", f, o, "--gate", "1e9"],
        vec!["convert", f, o, "--gate", "NaN"],
        vec!["convert", f, o, "--crop-bins", "50..10"],
        vec!["convert", f, o, "--crop-bins", "0..99999"],
        vec!["convert", f, o, "--crop-bins", "banana"],
        vec!["convert", f, o, "--subsample", "0"],
        vec!["convert", f, o, "--remove-legs"],
        vec!["convert", f, o, "--format", "lct-mat"],
        vec!["convert", f, o, "--format", "nope"],
        vec!["convert", f, "out.unknown"],
        vec!["preview", f, "--out", p, "--gate", "1e9"],
        vec!["preview", f, "--out", p, "--gate", "soon"],
        vec!["preview", f, "--out", p, "--row", "6"],
        vec!["preview", f, "--out", p, "--until", "-5"],
        vec!["preview", f, "--out", p, "--until", "inf"],
        vec!["preview", f, "--out", p, "--row", "18446744073709551615"],
    ];
    for args in cases {
        let r = nlos(&args);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {}", stderr(&r));
        assert!(stderr(&r).contains("error"), "{args:?}: {}", stderr(&r));
        assert!(!stderr(&r).contains("panicked"), "{args:?}: {}", stderr(&r));
    }
}

#[test]
fn preview_writes_png_for_grid_and_list() {
    let dir = scratch("preview");
    let Some((file, format)) = write_any(&synthetic(), &dir) else { return };
    let png = dir.join("grid.png");
    let o = nlos(&["preview", file.to_str().expect("utf8"), "--out", png.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h) = png_size(&png);
    assert!(w > 360 + 480 && h > 360 && w < 2000 && h < 1000, "{w} × {h}");
    for extra in [["--gate", "off"], ["--gate", "0.3"], ["--gate", "-1"], ["--until", "1.0"]] {
        let o = nlos(
            &[&["preview", file.to_str().expect("utf8"), "--out", png.to_str().expect("utf8")], &extra[..]].concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }

    // A list scan gets the summed histogram.
    let pts = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 0.2, 0.0)];
    let mut t = Transient::zeros(Scan::confocal(PointSet::list(pts)), TimeAxis::new(0.0, 0.01, 50).expect("axis"))
        .expect("transient");
    t.histogram_mut(1)[30] = 4.0;
    let ext = if format == Format::NpyJson {
        "npy"
    } else if format == Format::Exr {
        "exr"
    } else {
        "hdf5"
    };
    let list = dir.join(format!("list.{ext}"));
    if let Err(e) = nlos_transient::write(&t, &list, format) {
        eprintln!("skipping list preview: {e}");
        return;
    }
    let png = dir.join("list.png");
    let o = nlos(&["preview", list.to_str().expect("utf8"), "--out", png.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h) = png_size(&png);
    assert!(w > 640 && h > 320, "{w} × {h}");
}

#[test]
fn missing_truncated_and_garbage_files_exit_2_naming_the_file() {
    let dir = scratch("bad");
    let missing = dir.join("does-not-exist.mat");
    let truncated = dir.join("truncated.mat");
    let garbage = dir.join("garbage.bin");
    let real = nlos_testdata::root().join("measured/data_diffuse_s.mat");
    let head = std::fs::read(&real).map(|b| b[..b.len().min(5000)].to_vec()).unwrap_or_else(|_| {
        let mut b = b"MATLAB 5.0 MAT-file, Platform: GLNXA64".to_vec();
        b.resize(300, b' ');
        b
    });
    std::fs::write(&truncated, head).expect("write");
    std::fs::write(&garbage, b"this is not a capture at all").expect("write");
    for file in [&missing, &truncated, &garbage] {
        let f = file.to_str().expect("utf8");
        let png = dir.join("x.png");
        for args in
            [vec!["info", f], vec!["preview", f, "--out", png.to_str().expect("utf8")], vec!["convert", f, "o.npy"]]
        {
            let o = nlos(&args);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
            let err = stderr(&o);
            assert!(err.starts_with("error: "), "{err}");
            assert!(err.contains(file.file_name().and_then(|n| n.to_str()).expect("name")), "{err}");
        }
    }
}

#[test]
fn unwritable_output_exits_1() {
    let dir = scratch("unwritable");
    let Some((file, _)) = write_any(&synthetic(), &dir) else { return };
    let out = dir.join("no-such-dir").join("p.png");
    let o = nlos(&["preview", file.to_str().expect("utf8"), "--out", out.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("no-such-dir"), "{}", stderr(&o));
}

/// The real captures, when present.
fn measured(name: &str) -> Option<PathBuf> {
    nlos_testdata::shared(&format!("measured/{name}"))
}

#[test]
fn real_capture_info_and_preview() {
    let Some(file) = measured("data_diffuse_s.mat") else { return };
    let f = file.to_str().expect("utf8");
    let o = nlos(&["info", f]);
    if !o.status.success() && stderr(&o).contains("not yet written") {
        eprintln!("skipping: MAT reader not there yet: {}", stderr(&o));
        return;
    }
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for needle in
        ["lct-mat", "confocal: 4096 scan spots on a 64 × 64 grid", "2048 bins of 1.2 mm (4 ps)", "x -0.35 .. 0.35 m"]
    {
        assert!(out.contains(needle), "{needle} not in\n{out}");
    }
    let dir = scratch("real");
    let png = dir.join("s.png");
    let o = nlos(&["preview", f, "--out", png.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", stderr(&o));
    // 360 × 360 image + 480 × 360 slice with margins, at text scale 2, and three lines of notes (the gate, the
    // scan, the time axis).
    assert_eq!(png_size(&png), (1338, 565));
}

#[test]
fn real_capture_peak_depth_and_convert() {
    let Some(file) = measured("data_resolution_chart_40cm.mat") else { return };
    let f = file.to_str().expect("utf8");
    let o = nlos(&["info", "--json", f]);
    if !o.status.success() {
        eprintln!("skipping: {}", stderr(&o));
        return;
    }
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("json");
    let depth = v["peak"]["depth_m"].as_f64().expect("depth");
    assert!((depth - 0.425).abs() <= 0.005, "{depth}");
    assert_eq!(v["scan"]["wall_extent_m"]["max"][0], 0.2);

    let dir = scratch("real-convert");
    let original = nlos_transient::read(&file).expect("read");
    for target in ["chart.npy", "chart.exr", "chart.hdf5"] {
        let out = dir.join(target);
        let o = nlos(&["convert", f, out.to_str().expect("utf8")]);
        if !o.status.success() {
            eprintln!("skipping {target}: {}", stderr(&o));
            continue;
        }
        assert_eq!(nlos_transient::read(&out).expect("read back"), original, "{target}");
    }
}

/// Tsai et al.'s preprocessed S and U (the Stanford capture with bins 1–600 zeroed): `nlos info` names the
/// gate and estimates the background after it, between the direct light's tail and the S (non-zero; the
/// zeroed bins would give nearly 0).
#[test]
fn a_preprocessed_capture_names_its_gate() {
    let Some(file) = measured("tsai_su_transient.mat") else { return };
    let f = file.to_str().expect("utf8");
    let o = nlos(&["info", f]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("gate:          bins 0..600 (path < 0.72 m) are zero in every measurement"), "{out}");
    let o = nlos(&["info", "--json", f]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("json");
    assert_eq!(v["zero_gate"]["bins"], 600);
    let b = v["photon_counts"]["background_per_bin"].as_f64().expect("background");
    let window = v["photon_counts"]["background_window_bins"][0].as_u64().expect("window");
    assert!(b > 0.02 && b < 0.1, "background {b} per bin");
    assert!(window >= 600, "the background window starts at bin {window}, inside the gate");
    // The raw file has no zeroed bins: no gate line.
    if let Some(raw) = measured("data_s_u.mat") {
        let o = nlos(&["info", raw.to_str().expect("utf8")]);
        assert!(!stdout(&o).contains("gate:"), "{}", stdout(&o));
    }
}
