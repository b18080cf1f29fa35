//! `nlos eval` end to end: meshes written with `nlos_mesh::io`, the shared soap bar against itself
//! (skipped with a message when `shared/data` is absent), and bad input (exit 2, `error:` naming the file).

use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_mesh::{SurfaceMesh, shapes};

use nlos_testdata::mat5;
use serde_json::Value;

mod common;
use common::{nlos, stderr};

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    common::scratch("eval", name)
}

/// A 0.6 m square grid plane centred on the z axis at depth `z`.
fn plane(quads: usize, z: f32) -> SurfaceMesh {
    let mut m = shapes::plane_grid(0.6, 0.6, quads, quads);
    for p in m.positions_mut() {
        *p += Vec3::new(-0.3, -0.3, z);
    }
    m
}

/// Runs `nlos eval` and parses its single stdout line.
fn eval_json(args: &[&str]) -> Value {
    let o = nlos(&[args, &["--json"]].concat());
    assert!(o.status.success(), "nlos eval failed: {}", stderr(&o));
    let out = String::from_utf8(o.stdout).expect("utf-8");
    assert_eq!(out.lines().count(), 1, "one JSON line expected: {out}");
    serde_json::from_str(out.trim_end()).expect("valid JSON")
}

fn num(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} missing or not a number in {v}"))
}

#[test]
fn planes_one_centimetre_apart() {
    let dir = scratch("planes");
    let (rec, gt) = (dir.join("rec.ply"), dir.join("gt.obj"));
    nlos_mesh::io::save(&plane(7, 0.41), &rec).expect("write rec");
    nlos_mesh::io::save(&plane(5, 0.40), &gt).expect("write gt");
    let v = eval_json(&["eval", rec.to_str().expect("utf-8"), "--gt", gt.to_str().expect("utf-8")]);
    assert_eq!(num(&v, "coverage"), 1.0);
    assert_eq!(v["grid"], 128);
    assert_eq!(v["gt_pixels"], 128 * 128);
    for key in [
        "depth_error_mean",
        "depth_error_median",
        "depth_error_rms",
        "depth_error_max",
        "depth_error_mean_interior",
        "depth_error_mean_silhouette",
    ] {
        assert!((num(&v, key) - 0.01).abs() < 1e-6, "{key} = {}", v[key]);
    }
    assert!((num(&v, "chamfer") - 0.02).abs() < 1e-6);
    assert!(num(&v, "normal_error_mean_deg") < 0.05);
    // the depth maps stay out of the JSON line
    assert!(v.get("depth_reconstruction").is_none());

    let v = eval_json(&["eval", rec.to_str().expect("utf-8"), "--gt", gt.to_str().expect("utf-8"), "--grid", "16"]);
    assert_eq!(v["grid"], 16);
    assert_eq!(v["both_pixels"], 256);
}

#[test]
fn map_draws_the_coverage_picture() {
    let dir = scratch("map");
    let (rec, gt, png) = (dir.join("rec.obj"), dir.join("gt.obj"), dir.join("coverage.png"));
    // A 0.2 m plane 1 cm behind a 0.6 m one: hit by both within 5 mm in the middle, missed around it.
    let mut small = shapes::plane_grid(0.2, 0.2, 4, 4);
    for p in small.positions_mut() {
        *p += Vec3::new(-0.1, -0.1, 0.403);
    }
    nlos_mesh::io::save(&small, &rec).expect("write rec");
    nlos_mesh::io::save(&plane(5, 0.40), &gt).expect("write gt");
    let (r, g, m) = (rec.to_str().expect("utf-8"), gt.to_str().expect("utf-8"), png.to_str().expect("utf-8"));
    let v = eval_json(&["eval", r, "--gt", g, "--map", m]);
    let coverage = num(&v, "coverage");
    assert!((coverage - 0.16).abs() < 0.02, "coverage {coverage}");
    let bytes = std::fs::read(&png).expect("coverage picture written");
    assert_eq!(&bytes[1..4], b"PNG");
    // An unwritable path is an error that names it.
    let bad = dir.join("no/such/dir/c.png");
    let o = nlos(&["eval", r, "--gt", g, "--map", bad.to_str().expect("utf-8")]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("no/such/dir"), "{}", stderr(&o));
}

#[test]
fn soap_against_itself() {
    let Some(soap) = nlos_testdata::shared("meshes/soap_centered.obj") else { return };
    let soap = soap.to_str().expect("utf8");
    let v = eval_json(&["eval", soap, "--gt", soap]);
    assert_eq!(num(&v, "coverage"), 1.0);
    assert!(v["gt_pixels"].as_u64().expect("count") > 1000, "{v}");
    assert_eq!(num(&v, "depth_error_max"), 0.0);
    assert_eq!(num(&v, "chamfer"), 0.0);
    eprintln!("soap vs itself: {v}");
}

#[test]
fn bad_input_exits_2_naming_the_file() {
    let dir = scratch("bad");
    let gt = dir.join("gt.obj");
    nlos_mesh::io::save(&plane(2, 0.4), &gt).expect("write gt");
    let gt_s = gt.to_str().expect("utf-8");

    let missing = dir.join("missing.obj");
    let o = nlos(&["eval", missing.to_str().expect("utf-8"), "--gt", gt_s]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).starts_with("error: ") && stderr(&o).contains("missing.obj"), "{}", stderr(&o));

    // malformed: a face with an index out of range
    let broken = dir.join("broken.obj");
    std::fs::write(&broken, "v 0 0 1\nv 1 0 1\nf 1 2 9\n").expect("write");
    let o = nlos(&["eval", broken.to_str().expect("utf-8"), "--gt", gt_s]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).starts_with("error: ") && stderr(&o).contains("broken.obj"), "{}", stderr(&o));
    assert!(o.stdout.is_empty());

    // a ground truth that no ray reaches (behind the wall): exit 2, both files named
    let behind = dir.join("behind.obj");
    nlos_mesh::io::save(&plane(2, -0.4), &behind).expect("write");
    let o = nlos(&["eval", gt_s, "--gt", behind.to_str().expect("utf-8")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("behind.obj") && stderr(&o).contains("gt.obj"), "{}", stderr(&o));

    // grid out of range
    let o = nlos(&["eval", gt_s, "--gt", gt_s, "--grid", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).starts_with("error: "), "{}", stderr(&o));
}

/// `--threshold` sets "coverage within": planes 1 cm apart are covered, but not within 5 mm; within 2 cm.
#[test]
fn coverage_within_the_threshold() {
    let dir = scratch("within");
    let (rec, gt) = (dir.join("rec.obj"), dir.join("gt.obj"));
    nlos_mesh::io::save(&plane(7, 0.41), &rec).expect("write rec");
    nlos_mesh::io::save(&plane(5, 0.40), &gt).expect("write gt");
    let (r, g) = (rec.to_str().expect("utf-8"), gt.to_str().expect("utf-8"));
    let v = eval_json(&["eval", r, "--gt", g]);
    assert_eq!((num(&v, "coverage"), num(&v, "coverage_within"), num(&v, "coverage_threshold")), (1.0, 0.0, 0.005));
    let v = eval_json(&["eval", r, "--gt", g, "--threshold", "0.02"]);
    assert_eq!(num(&v, "coverage_within"), 1.0);
}

/// A little-endian f32 `.npy` of `shape`, C order.
fn npy(path: &Path, data: &[f32], shape: &[usize]) {
    let bytes = nlos_transient::formats::npy::encode_npy_f32(data, shape).expect("npy");
    std::fs::write(path, bytes).expect("write npy");
}

/// `--gt-depth/--gt-normal`: a plane against its own maps scores 0 and 0°; a tilted plane scores its tilt;
/// missing normals (NaN, Inf) are left out of the normal error, Inf depths are no surface; maps of the wrong
/// size, with non-unit normals or the wrong axis are errors naming the file.
#[test]
fn depth_and_normal_maps() {
    let dir = scratch("maps");
    let (w, h) = (40usize, 30usize);
    // The wall rectangle [−0.2, 0.2] × [−0.15, 0.15]: 1 cm pixels.
    let depth = vec![0.4f32; w * h];
    let normal: Vec<f32> = (0..w * h).flat_map(|_| [0.0, 0.0, -1.0]).collect();
    let (d, n) = (dir.join("depth.npy"), dir.join("normal.npy"));
    npy(&d, &depth, &[h, w]);
    npy(&n, &normal, &[h, w, 3]);
    let (ds, ns) = (d.to_str().expect("utf-8"), n.to_str().expect("utf-8"));
    let flat = dir.join("flat.obj");
    nlos_mesh::io::save(&plane(6, 0.4), &flat).expect("write");
    let ext = ["--extent", "-0.2,0.2,-0.15,0.15"];
    let f = flat.to_str().expect("utf-8");
    let v = eval_json(&[&["eval", f, "--gt-depth", ds, "--gt-normal", ns][..], &ext].concat());
    assert_eq!((num(&v, "coverage"), num(&v, "coverage_within")), (1.0, 1.0));
    assert!(num(&v, "depth_error_mean") < 1e-6 && num(&v, "normal_error_mean_deg") < 0.05, "{v}");
    // Tilted by 10° about y (through the plate's centre).
    let mut tilted = plane(6, 0.0);
    let q = glam::Quat::from_rotation_y(10f32.to_radians());
    for p in tilted.positions_mut() {
        *p = q * *p + Vec3::new(0.0, 0.0, 0.4);
    }
    let t = dir.join("tilted.obj");
    nlos_mesh::io::save(&tilted, &t).expect("write");
    let v = eval_json(&[&["eval", t.to_str().expect("utf-8"), "--gt-depth", ds, "--gt-normal", ns][..], &ext].concat());
    assert!((num(&v, "normal_error_mean_deg") - 10.0).abs() < 0.05, "{v}");
    // Bad maps.
    let bad = dir.join("bad.npy");
    let b = bad.to_str().expect("utf-8");
    let fails = |args: &[&str], what: &str| {
        let o = nlos(&[&["eval", f, "--gt-depth", ds][..], args].concat());
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(stderr(&o).contains(what), "{args:?}: {}", stderr(&o));
    };
    npy(&bad, &normal[..(h - 1) * w * 3], &[h - 1, w, 3]);
    fails(&["--gt-normal", b], "bad.npy");
    let mut long = normal.clone();
    long[5] = -2.0;
    npy(&bad, &long, &[h, w, 3]);
    fails(&["--gt-normal", b], "not a finite unit vector");
    // A normal map without a value at one pixel (NaN, or Inf as the published maps mark no surface): that
    // pixel is left out of the normal error only.
    let mut nan = normal.clone();
    nan[5] = f32::NAN;
    nan[3 * 7] = f32::INFINITY;
    npy(&bad, &nan, &[h, w, 3]);
    let v = eval_json(&[&["eval", f, "--gt-depth", ds, "--gt-normal", b][..], &ext].concat());
    assert_eq!((num(&v, "both_pixels"), num(&v, "normal_pixels")), ((w * h) as f64, (w * h - 2) as f64), "{v}");
    // Inf in the depth map is no surface.
    let mut holes = depth.clone();
    holes[..w].fill(f32::INFINITY);
    npy(&bad, &holes, &[h, w]);
    let v = eval_json(&[&["eval", f, "--gt-depth", b][..], &ext].concat());
    assert_eq!(num(&v, "gt_pixels"), (w * h - w) as f64, "{v}");
    npy(&bad, &normal, &[3, h, w]);
    fails(&["--gt-normal", b], "last axis");
    let away: Vec<f32> = normal.iter().map(|x| -x).collect();
    npy(&bad, &away, &[h, w, 3]);
    fails(&["--gt-normal", b], "face away");
}

/// `--gt-depth … --map`: the coverage picture on the map's own grid (a square map); a map that is not square
/// is an error saying so, before anything is written.
#[test]
fn map_draws_the_coverage_picture_against_depth_maps() {
    let dir = scratch("depth-map-picture");
    let n = 20usize;
    let (d, png) = (dir.join("depth.npy"), dir.join("coverage.png"));
    npy(&d, &vec![0.4f32; n * n], &[n, n]);
    let flat = dir.join("flat.obj");
    nlos_mesh::io::save(&plane(6, 0.4), &flat).expect("write");
    let (f, ds, m) = (flat.to_str().expect("utf-8"), d.to_str().expect("utf-8"), png.to_str().expect("utf-8"));
    let ext = ["--extent", "-0.2,0.2,-0.2,0.2"];
    let v = eval_json(&[&["eval", f, "--gt-depth", ds, "--map", m][..], &ext].concat());
    assert_eq!(num(&v, "coverage_within"), 1.0, "{v}");
    let bytes = std::fs::read(&png).expect("coverage picture written");
    assert_eq!(&bytes[1..4], b"PNG");
    std::fs::remove_file(&png).expect("remove");
    npy(&d, &vec![0.4f32; n * (n - 2)], &[n - 2, n]);
    let o = nlos(&[&["eval", f, "--gt-depth", ds, "--map", m][..], &ext].concat());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("square") && stderr(&o).contains("depth.npy"), "{}", stderr(&o));
    assert!(!png.exists(), "nothing drawn for a map that is not square");
}

/// A MATLAB depth map (column-major, NaN outside the object) reads as the same image: a plate covering the
/// left half of the wall scores coverage 1 on the half the map marks, and the right half is no surface.
#[test]
fn a_matlab_depth_map_with_nan_background() {
    let dir = scratch("mat-map");
    let (w, h) = (20usize, 10usize);
    // depth(r, c) = 0.4 on columns c < 10, NaN elsewhere; MATLAB stores (r, c) at r + h·c.
    let col_major: Vec<f64> = (0..w).flat_map(|c| (0..h).map(move |_| if c < 10 { 0.4 } else { f64::NAN })).collect();
    let vars = vec![mat5::double("depth", &[h as i32, w as i32], col_major)];
    let m = dir.join("depth.mat");
    std::fs::write(&m, mat5::write(&vars, mat5::Options::default())).expect("write");
    let flat = dir.join("flat.obj");
    nlos_mesh::io::save(&plane(6, 0.4), &flat).expect("write");
    let v = eval_json(&[
        "eval",
        flat.to_str().expect("utf-8"),
        "--gt-depth",
        m.to_str().expect("utf-8"),
        "--extent=-0.2,0.2,-0.1,0.1",
    ]);
    assert_eq!((v["gt_pixels"].as_u64(), num(&v, "coverage_within")), (Some(100), 1.0), "{v}");
}

/// A 0.24 m square plate at 0.35 m, in 2 cm squares, leaving out those whose centre `skip` says.
fn plate(skip: impl Fn(f32, f32) -> bool) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for j in 0..12 {
        for i in 0..12 {
            let (x0, y0) = (-0.12 + 0.02 * i as f32, -0.12 + 0.02 * j as f32);
            if skip(x0 + 0.01, y0 + 0.01) {
                continue;
            }
            let b = positions.len() as u32;
            for (dx, dy) in [(0.0, 0.0), (0.02, 0.0), (0.0, 0.02), (0.02, 0.02)] {
                positions.push(Vec3::new(x0 + dx, y0 + dy, 0.35));
            }
            triangles.extend([[b, b + 2, b + 1], [b + 1, b + 2, b + 3]]); // normals −z: toward the wall
        }
    }
    (positions, triangles)
}

#[test]
fn front_view_detail_scores_a_slot_the_volume_shows() {
    use nlos_brdf::Lambertian;
    use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
    use nlos_transient::{Format, PointSet, Scan, TimeAxis};
    let dir = scratch("front_view");
    // A slot 6 cm wide and 16 cm long through the plate, right of its centre, rendered on a 32 × 32 confocal
    // scan. (The LCT volume shows it at about 0.7 of the plate's brightness.)
    let slot = |x: f32, y: f32| (0.02..0.08).contains(&x) && y.abs() < 0.08;
    let (positions, triangles) = plate(slot);
    let scan = Scan::confocal(PointSet::wall_grid(32, 32, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.004, 256).expect("axis");
    let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
    let renderer = Renderer::new(&positions, &triangles, &scan, &time, params).expect("renderer");
    let t = renderer.forward_transient(&Lambertian::new(1.0f32).expect("brdf")).expect("render");
    let capture = dir.join("slot.hdf5");
    nlos_transient::write(&t, &capture, Format::Tal).expect("write");
    let score = |skip: &dyn Fn(f32, f32) -> bool, name: &str| {
        let (p, f) = plate(skip);
        let file = dir.join(name);
        nlos_mesh::io::save(&SurfaceMesh::from_triangles(&p, &f).expect("mesh"), &file).expect("write mesh");
        eval_json(&["eval", file.to_str().expect("utf-8"), "--front-view", capture.to_str().expect("utf-8")])
    };
    let truth = score(&slot, "truth.ply");
    let closed = score(&|_, _| false, "closed.ply");
    let mirrored = score(&|x, y| slot(-x, y), "mirrored.ply");
    eprintln!("truth {truth}\nclosed {closed}\nmirrored {mirrored}");
    assert!(num(&truth, "r") > num(&closed, "r") + 0.15, "truth {truth}, closed {closed}");
    assert!(num(&truth, "r") > num(&mirrored, "r") + 0.15, "truth {truth}, mirrored {mirrored}");
    // The volume's halo lies above its threshold too: the truth covers most of it, not all.
    assert!(num(&truth, "coverage") > 0.6 && num(&truth, "coverage") < num(&closed, "coverage"));
    // A mesh in a run directory is scored against the volume as the run weighted it (its settings say
    // retroreflective), and the command says so; --brdf still wins.
    let run = dir.join("run");
    std::fs::create_dir_all(&run).expect("mkdir");
    std::fs::write(run.join("settings.toml"), "[reflectance]\nmodel = \"retroreflective\"\n").expect("settings");
    std::fs::copy(dir.join("truth.ply"), run.join("mesh.ply")).expect("copy");
    let (m, c) = (run.join("mesh.ply"), capture.to_str().expect("utf-8"));
    let m = m.to_str().expect("utf-8");
    let o = nlos(&["eval", m, "--front-view", c, "--json"]);
    assert!(o.status.success() && stderr(&o).contains("retroreflective, the run's reflectance"), "{}", stderr(&o));
    let own: Value = serde_json::from_slice(&o.stdout).expect("JSON");
    let retro = eval_json(&["eval", m, "--front-view", c, "--brdf", "retroreflective"]);
    let lambert = eval_json(&["eval", m, "--front-view", c, "--brdf", "lambert"]);
    assert_eq!(num(&own, "r"), num(&retro, "r"), "the run's settings: {own}; --brdf retroreflective: {retro}");
    assert_ne!(num(&own, "r"), num(&lambert, "r"), "the weighting changes the volume: {own}, {lambert}");
    // Without a truth or a capture there is nothing to score against.
    let o = nlos(&["eval", dir.join("truth.ply").to_str().expect("utf-8")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// The figures of a table printed by `nlos eval`: per row label, the numbers of its cells (`–` is `None`).
fn table_rows(text: &str) -> Vec<(String, Vec<Option<f64>>)> {
    text.lines()
        .skip(2) // the title and the column names
        .map(|line| {
            let cells: Vec<&str> = line.split("  ").map(str::trim).filter(|c| !c.is_empty()).collect();
            let values = cells[1..]
                .iter()
                .map(|c| c.trim_end_matches(|ch: char| !ch.is_ascii_digit()).trim().parse::<f64>().ok())
                .collect();
            (cells[0].to_owned(), values)
        })
        .collect()
}

/// A run directory of two planes (its start 8 mm off the truth, its result on it) with the given settings.
fn run_dir(name: &str, settings: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    let run = dir.join("run");
    std::fs::create_dir_all(&run).expect("mkdir");
    std::fs::write(run.join("settings.toml"), settings).expect("write settings");
    nlos_mesh::io::save(&plane(6, 0.408), run.join("init.obj")).expect("write");
    nlos_mesh::io::save(&plane(12, 0.4), run.join("mesh.obj")).expect("write");
    let gt = dir.join("truth.obj");
    nlos_mesh::io::save(&plane(10, 0.4), &gt).expect("write");
    (run, gt)
}

#[test]
fn the_table_says_what_the_json_says() {
    let (run, gt) = run_dir("table", "seed = 1\n");
    let (r, g) = (run.to_str().expect("utf-8"), gt.to_str().expect("utf-8"));
    let o = nlos(&["eval", r, "--gt", g, "--grid", "32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).expect("utf-8");
    eprintln!("{text}");
    let header: Vec<&str> = text.lines().nth(1).expect("column names").split_whitespace().collect();
    assert_eq!(header, ["start", "result"], "{text}");
    // `--json`: one line per mesh, start first.
    let o = nlos(&["eval", r, "--gt", g, "--grid", "32", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: Vec<Value> =
        String::from_utf8(o.stdout).expect("utf-8").lines().map(|l| serde_json::from_str(l).expect("JSON")).collect();
    assert_eq!(json.len(), 2);
    let rows = table_rows(&text);
    let expect = [
        ("coverage within 5 mm", "coverage_within", 100.0, 0.05),
        ("depth error inside the silhouette", "depth_error_mean_interior", 1e3, 0.005),
        ("Chamfer distance", "chamfer", 1e3, 0.005),
        ("normal error", "normal_error_mean_deg", 1.0, 0.05),
    ];
    assert_eq!(rows.len(), expect.len(), "{text}");
    for ((label, values), (want, key, unit, half)) in rows.iter().zip(expect) {
        assert_eq!(label, want, "{text}");
        for (value, v) in values.iter().zip(&json) {
            let printed = value.unwrap_or_else(|| panic!("{label}: no figure in {text}"));
            assert!((printed - num(v, key) * unit).abs() <= half + 1e-9, "{label}: {printed} against {v}");
        }
    }
    // The start is 8 mm off the truth, the result on it.
    assert!(json[0]["coverage_within"].as_f64() == Some(0.0) && num(&json[1], "coverage_within") > 0.9, "{text}");
    // A mesh inside the run is named by its role; a folder that holds no run is refused, naming it.
    let o = nlos(&["eval", run.join("mesh.obj").to_str().expect("utf-8"), "--gt", g, "--grid", "32"]);
    let text = String::from_utf8(o.stdout).expect("utf-8");
    assert_eq!(text.lines().nth(1).map(str::trim), Some("result"), "{text}");
    let empty = scratch("table_no_run");
    let o = nlos(&["eval", empty.to_str().expect("utf-8"), "--gt", g]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not a run directory") && stderr(&o).contains("table_no_run"), "{}", stderr(&o));
}
