//! The `nlos` command end to end, in-process ([`nlos_cli::run`]), on the built-in fixtures: `info`,
//! `reconstruct` (a short schedule, with the report and the ground truth), `eval`, and `--resume` of the
//! finished run; a capture in Tsai et al. 2019's own `.mat` format whose point list forms a grid; bad input exits 2.

use std::process::ExitCode;

mod common;
use common::{FAST, fixture_arg as fixture, scratch};
use nlos_testdata::mat5;

fn nlos(args: &[&str]) -> ExitCode {
    nlos_cli::run(std::iter::once("nlos").chain(args.iter().copied()))
}

#[test]
fn reconstruct_eval_and_resume_on_the_builtin_capture() {
    let (capture, truth) = (fixture("capture.hdf5"), fixture("truth.obj"));
    assert_eq!(nlos(&["info", &capture]), ExitCode::SUCCESS);
    let run = scratch("cli-run");
    let out = run.to_string_lossy().into_owned();
    let args = [&["reconstruct", &capture, "--out", &out, "--gt", &truth, "--quiet", "--glb"][..], &FAST].concat();
    assert_eq!(nlos(&args), ExitCode::SUCCESS);
    for file in ["mesh.obj", "mesh.glb", "init.obj", "report.html", "settings.toml", "run_log.json"] {
        assert!(run.join(file).is_file(), "{file} missing");
    }
    let mesh = run.join("mesh.obj").to_string_lossy().into_owned();
    assert_eq!(nlos(&["eval", &mesh, "--gt", &truth]), ExitCode::SUCCESS);
    // The run itself: its start and its result side by side (as the demo ends).
    assert_eq!(nlos(&["eval", &out, "--gt", &truth]), ExitCode::SUCCESS);
    // A finished run resumes to the same mesh.
    let before = std::fs::read(run.join("mesh.obj")).expect("mesh");
    assert_eq!(nlos(&["reconstruct", &capture, "--out", &out, "--resume", "--quiet"]), ExitCode::SUCCESS);
    assert_eq!(std::fs::read(run.join("mesh.obj")).expect("mesh"), before);
}

#[test]
fn bad_input_exits_2() {
    let dir = scratch("cli-bad");
    let garbage = dir.join("garbage.hdf5");
    std::fs::write(&garbage, b"not a capture").expect("write");
    let g = garbage.to_string_lossy().into_owned();
    let out = dir.join("run").to_string_lossy().into_owned();
    assert_eq!(nlos(&["info", &g]), ExitCode::from(2));
    assert_eq!(nlos(&["reconstruct", &g, "--out", &out]), ExitCode::from(2));
    assert_eq!(
        nlos(&["reconstruct", &fixture("capture.hdf5"), "--out", &out, "--set", "no.such=1"]),
        ExitCode::from(2)
    );
    assert_eq!(nlos(&["no-such-command"]), ExitCode::from(2));
}

/// A capture in Tsai et al.'s `.mat` format (`transient` M×T, `lighting` M×3 with x fastest, `bin_width`),
/// written here from the built-in capture: its point list forms a 2-D grid, so `nlos init` (LCT) and
/// `nlos reconstruct` run on it with no option about the layout.
#[test]
fn a_tsai_capture_whose_points_form_a_grid_runs_with_defaults() {
    let t = nlos_transient::read(common::fixture("capture.hdf5")).expect("fixture");
    let (m, bins) = (t.measurements(), t.bins());
    assert_eq!(t.time().t0, 0.0, "the Tsai format has no time origin");
    let mut transient = vec![0.0f64; m * bins];
    for r in 0..m {
        for (k, v) in t.histogram(r).iter().enumerate() {
            transient[r + m * k] = f64::from(*v); // column-major M×T
        }
    }
    let pts = &t.scan().lasers().points;
    let lighting: Vec<f64> = (0..3).flat_map(|c| pts.iter().map(move |p| f64::from(p[c]))).collect();
    let vars = vec![
        mat5::double("transient", &[m as i32, bins as i32], transient),
        mat5::double("lighting", &[m as i32, 3], lighting),
        mat5::scalar("bin_width", t.time().bin_width),
    ];
    let dir = scratch("cli-tsai");
    let file = dir.join("capture.mat");
    std::fs::write(&file, mat5::write(&vars, mat5::Options::default())).expect("write");
    let read = nlos_transient::read(&file).expect("read back");
    assert_eq!(read.scan().lasers().layout, t.scan().lasers().layout, "read as the grid it is");
    let f = file.to_string_lossy().into_owned();
    let start = dir.join("start.obj").to_string_lossy().into_owned();
    assert_eq!(nlos(&["init", &f, "--out", &start]), ExitCode::SUCCESS);
    let out = dir.join("run").to_string_lossy().into_owned();
    assert_eq!(nlos(&[&["reconstruct", &f, "--out", &out, "--quiet"][..], &FAST].concat()), ExitCode::SUCCESS);
    assert!(dir.join("run/mesh.obj").is_file());
}

/// `nlos benchmark` end to end on a folder of Z-NLOS files of our own: the built-in capture written in
/// NeTF's `.mat` layout (their wall y = 0, scene at y < 0) with ground-truth depth and normal maps beside
/// it, and a second capture without maps (left out). One table: LCT, f-k and the surface fit, scored.
#[test]
fn benchmark_runs_on_znlos_files_with_maps() {
    let t = nlos_transient::read(common::fixture("capture.hdf5")).expect("fixture");
    let (nx, ny) = t.scan().lasers().grid_dims().expect("grid");
    let (m, bins) = (t.measurements(), t.bins());
    // NeTF's layout: data T × ny × nx, data(:, iy, ix) (stored column-major at iy + ny·ix) with position
    // column iy·nx + ix = our point ix + nx·iy; their (x, 0, y) is our (x, y, 0); deltaT half a path bin.
    let mut data = vec![0.0f64; m * bins];
    for p in 0..m {
        let (ix, iy) = (p % nx, p / nx);
        let at = bins * (iy + ny * ix);
        data[at..at + bins].iter_mut().zip(t.histogram(p)).for_each(|(d, v)| *d = f64::from(*v));
    }
    let pos: Vec<f64> = t.scan().lasers().points.iter().flat_map(|p| [f64::from(p.x), 0.0, f64::from(p.y)]).collect();
    let vars = vec![
        mat5::double("data", &[bins as i32, ny as i32, nx as i32], data),
        mat5::double("cameraGridPositions", &[3, m as i32], pos),
        mat5::double("deltaT", &[1, 1], vec![0.5 * t.time().bin_width]),
        mat5::double("hiddenVolumePosition", &[3, 1], vec![0.0, -0.4, 0.0]),
    ];
    let dir = scratch("benchmark");
    let data_dir = dir.join("znlos");
    std::fs::create_dir_all(&data_dir).expect("dir");
    let bytes = mat5::write(&vars, mat5::Options::default());
    std::fs::write(data_dir.join("patch.mat"), &bytes).expect("write");
    std::fs::write(data_dir.join("unscored.mat"), &bytes).expect("write");
    // Ground-truth maps on the scan grid (one pixel per scan point, row 0 at the largest y).
    let (lo, hi) = t.scan().lasers().bounds().expect("points");
    let (hx, hy) = (0.5 * (hi.x - lo.x) / (nx - 1) as f32, 0.5 * (hi.y - lo.y) / (ny - 1) as f32);
    let grid = nlos_mesh::map_metrics::MapGrid {
        width: nx,
        height: ny,
        x_range: [lo.x - hx, hi.x + hx],
        y_range: [lo.y - hy, hi.y + hy],
    };
    let truth = nlos_mesh::metrics::load_for_eval(common::fixture("truth.obj")).expect("truth");
    let maps = nlos_mesh::map_metrics::mesh_maps(&truth, &grid).expect("maps");
    let depth: Vec<f32> = maps.depth.iter().map(|z| if z.is_nan() { 0.0 } else { *z }).collect();
    let normals: Vec<f32> = maps.normals.expect("normals").iter().flat_map(|n| n.to_array()).collect();
    let npy = |name: &str, v: &[f32], shape: &[usize]| {
        let bytes = nlos_transient::formats::npy::encode_npy_f32(v, shape).expect("npy");
        std::fs::write(data_dir.join(name), bytes).expect("write");
    };
    npy("patch_depth.npy", &depth, &[ny, nx]);
    npy("patch_normal.npy", &normals, &[ny, nx, 3]);
    let table = dir.join("table.md");
    let (d, o, tb) =
        (data_dir.to_string_lossy(), dir.join("runs").to_string_lossy().into_owned(), table.to_string_lossy());
    let mut args = vec!["benchmark", &d, "--out", &o, "--table", &tb, "--gt-layout", "image"];
    args.extend(FAST);
    assert_eq!(nlos(&args), ExitCode::SUCCESS);
    let text = std::fs::read_to_string(&table).expect("table");
    let rows: Vec<&str> = text.lines().filter(|l| l.starts_with("| patch |")).collect();
    assert_eq!(rows.len(), 3, "{text}");
    assert!(!text.contains("unscored"), "{text}");
    for (row, method) in rows.iter().zip(["LCT", "f-k", "surface fit"]) {
        assert!(row.contains(method), "{row}");
        // Coverage within 5 mm: a number, not a dash.
        let within: f64 = row.split('|').nth(3).and_then(|c| c.trim().trim_end_matches(" %").parse().ok()).expect(row);
        assert!(within > 0.0, "{row}");
    }
}
