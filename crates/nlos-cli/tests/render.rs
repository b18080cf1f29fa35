//! End-to-end tests of `nlos render`: a square's transient peaks at its depth, the setup comes from a
//! capture file, photon counts are integers with the requested budget, and bad arguments are input errors.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::Vec3;
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient};

fn nlos(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nlos")).args(args).output().expect("run nlos")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("render-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// A 0.2 m square facing the wall at 0.3 m, and a small setup capture (10 × 10 scan, 300 bins of 4 mm).
fn inputs(dir: &Path) -> (String, String) {
    let (h, d) = (0.1f32, 0.3f32);
    let positions = [Vec3::new(-h, -h, d), Vec3::new(h, -h, d), Vec3::new(h, h, d), Vec3::new(-h, h, d)];
    let mesh = nlos_mesh::SurfaceMesh::from_triangles(&positions, &[[0, 2, 1], [0, 3, 2]]).expect("mesh");
    let mesh_file = dir.join("square.obj");
    nlos_mesh::io::save(&mesh, &mesh_file).expect("save mesh");
    let scan = Scan::confocal(PointSet::wall_grid(10, 10, 0.25, 0.25).expect("grid"));
    let setup = Transient::zeros(scan, TimeAxis::new(0.0, 0.004, 300).expect("axis")).expect("setup");
    let setup_file = dir.join("setup.npy");
    nlos_transient::write(&setup, &setup_file, Format::NpyJson).expect("write setup");
    (mesh_file.to_string_lossy().into_owned(), setup_file.to_string_lossy().into_owned())
}

#[test]
fn renders_a_square_on_the_setup_of_a_capture() {
    let dir = scratch("square");
    let (mesh, setup) = inputs(&dir);
    let out = dir.join("square.hdf5");
    let r = nlos(&["render", &mesh, "--out", &out.to_string_lossy(), "--setup", &setup]);
    assert!(r.status.success(), "{}", text(&r));
    let t = nlos_transient::read(&out).expect("read rendered");
    assert_eq!((t.measurements(), t.bins()), (100, 300));
    let depth = t.summed_peak_depth(Some(0.0)).expect("depth");
    assert!((depth - 0.3).abs() < 0.006, "peak depth {depth} m, square at 0.3 m");
    // Photon counts: integers, about the requested budget per measurement.
    let counts = dir.join("counts.npy");
    let r = nlos(&["render", &mesh, "--out", &counts.to_string_lossy(), "--setup", &setup, "--photons", "500"]);
    assert!(r.status.success(), "{}", text(&r));
    let c = nlos_transient::read(&counts).expect("read counts");
    assert!(c.data().iter().all(|v| v.fract() == 0.0 && *v >= 0.0), "counts must be non-negative integers");
    let per_measurement = c.data().iter().map(|&v| f64::from(v)).sum::<f64>() / c.measurements() as f64;
    assert!((per_measurement - 500.0).abs() < 15.0, "{per_measurement} photons per measurement");
}

#[test]
fn bad_arguments_are_input_errors() {
    let dir = scratch("bad");
    let (mesh, setup) = inputs(&dir);
    let out = dir.join("x.hdf5").to_string_lossy().into_owned();
    for extra in [
        vec!["--brdf", "phong"],
        vec!["--brdf", "ggx", "--alpha", "3"],
        vec!["--mode", "guess"],
        vec!["--mode", "mc", "--spp", "0"],
        vec!["--photons", "-1"],
    ] {
        let mut args = vec!["render", mesh.as_str(), "--out", out.as_str(), "--setup", setup.as_str()];
        args.extend(extra.iter().copied());
        let r = nlos(&args);
        assert_eq!(r.status.code(), Some(2), "{extra:?}: {}", text(&r));
    }
    let r = nlos(&["render", "missing.obj", "--out", &out, "--setup", &setup]);
    assert_eq!(r.status.code(), Some(2), "{}", text(&r));
    assert!(text(&r).contains("missing.obj"));
    let r = nlos(&["render", &mesh, "--out", &dir.join("x.txt").to_string_lossy(), "--setup", &setup]);
    assert_eq!(r.status.code(), Some(2), "{}", text(&r));
}
