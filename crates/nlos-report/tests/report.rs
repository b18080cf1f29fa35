//! End-to-end test of the report on a tiny synthetic run directory: a tilted plane rendered on a 16 × 16
//! confocal scan is the measurement, the final mesh and the ground truth; a flat plane is the initial
//! surface; the run log has two stages.

use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::SurfaceMesh;
use nlos_optim::{IterationRecord, RunLog, StepKind};
use nlos_render::{RenderParams, Renderer, Visibility};
use nlos_report::{ReportError, ReportOptions, write_report};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};
use nlos_viz::Colormap;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("report-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// A 0.3 m square grid of 6 × 6 quads at depth `z(x) = z0 + slope·x`, faces toward the wall (−z).
fn plane(z0: f32, slope: f32) -> SurfaceMesh {
    let n = 6usize;
    let mut pos = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (-0.15 + 0.3 * i as f32 / n as f32, -0.15 + 0.3 * j as f32 / n as f32);
            pos.push(Vec3::new(x, y, z0 + slope * x));
        }
    }
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = (i + (n + 1) * j) as u32;
            let (b, c, d) = (a + 1, a + n as u32 + 2, a + n as u32 + 1);
            tris.push([a, c, b]);
            tris.push([a, d, c]);
        }
    }
    SurfaceMesh::from_triangles(&pos, &tris).expect("plane mesh")
}

fn render_params() -> RenderParams {
    RenderParams { visibility: Visibility::Off, ..RenderParams::default() }
}

fn measure(mesh: &SurfaceMesh) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(16, 16, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.004, 256).expect("axis");
    let (p, t) = mesh.to_triangles();
    let r = Renderer::new(&p, &t, &scan, &time, render_params()).expect("renderer");
    r.forward_transient(&Lambertian::new(1.0f32).expect("brdf")).expect("render")
}

fn record(iteration: u64, stage: u32, loss: f64) -> IterationRecord {
    IterationRecord {
        iteration,
        stage,
        block: 0,
        kind: if iteration % 4 == 3 { StepKind::Reflectance } else { StepKind::Shape },
        loss,
        data: 0.9 * loss,
        regulariser: 2.0,
        reg_weight: 0.05 * loss,
        scale: 1.0,
        step_size: 1e-3,
        faces: 72,
        vertices: 49,
        time_s: iteration as f64 * 0.1,
        noise_floor: None,
    }
}

/// A run directory: final mesh and ground truth tilted (z from 0.32 to 0.38 m along x), flat initial
/// surface and a two-stage log; no run record (`checkpoint.json`), so the report renders with the default
/// reflectance (a real run's record is read in nlos-cli's `reconstruct` tests).
fn run_dir(name: &str) -> (PathBuf, Transient, SurfaceMesh) {
    let dir = scratch(name);
    let truth = plane(0.35, 0.2);
    nlos_mesh::io::save(&truth, dir.join("mesh.obj")).expect("mesh");
    nlos_mesh::io::save(&plane(0.35, 0.0), dir.join("init.obj")).expect("init");
    nlos_mesh::io::save(&truth, dir.join("stage_00.obj")).expect("stage");
    let log = RunLog {
        iterations: (0..20).map(|i| record(i, u32::from(i >= 12), 1.0 / (1.0 + i as f64))).collect(),
        rollbacks: 1,
        intersections: Vec::new(),
        stages: Vec::new(),
        residual: Vec::new(),
        collisions: Vec::new(),
        start: None,
        fit: Some(nlos_optim::FitQuality { data: 0.1, empty: 1.0, noise_floor: Some(0.08), detection: Some(2400.0) }),
    };
    std::fs::write(dir.join("run_log.json"), serde_json::to_vec(&log).expect("log json")).expect("log");
    let measured = measure(&truth);
    (dir, measured, truth)
}

fn decode(path: &Path) -> (usize, usize, Vec<u8>) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).expect("open png")));
    let mut reader = dec.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("png frame");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width as usize, info.height as usize, buf)
}

#[test]
fn writes_every_figure_and_an_html_page_that_shows_them() {
    let (dir, measured, truth) = run_dir("full");
    let opts = ReportOptions {
        render: render_params(),
        parameters: vec![("data".into(), "tilted <plane>".into())],
        ..ReportOptions::default()
    };
    let report = write_report(&dir, &measured, Some(&truth), &opts).expect("report");
    for name in [
        "summed.png",
        "xt_slice.png",
        "loss.png",
        "depth_init.png",
        "depth_final.png",
        "depth_gt.png",
        "relief.png",
        "coverage.png",
        "residual.png",
    ] {
        assert!(report.images.iter().any(|i| i == name), "{name} not in {:?}", report.images);
    }
    let html = std::fs::read_to_string(dir.join("report.html")).expect("html");
    for name in &report.images {
        let (w, h, _) = decode(&dir.join(name));
        assert!(w >= 300 && h >= 200 && w <= 4000 && h <= 4000, "{name}: {w} x {h}");
        assert!(html.contains(&format!("<img src=\"{name}\"")), "report.html does not show {name}");
    }
    // Every image the page links exists, and parameters are escaped.
    for part in html.split("<img src=\"").skip(1) {
        let name = &part[..part.find('"').expect("closing quote")];
        assert!(dir.join(name).is_file(), "{name} linked but missing");
    }
    assert!(html.contains("tilted &lt;plane&gt;"));
    assert!(html.contains("stage_00.obj"));
    // The verdict of the run's fit-quality record, in words, above the settings.
    let verdict = html.find("<b>Fit:</b> the surface explains 98 % of the light above the noise").expect("verdict");
    assert!(verdict < html.find("<h2>Settings</h2>").expect("settings"), "the verdict comes before the settings");
    let depth = html.find("<h2>Depth maps seen from the wall</h2>").expect("depth maps");
    assert!(
        depth < verdict && verdict < html.find("<h2>Result</h2>").expect("result"),
        "the surface, then the verdict"
    );
    assert!(
        html.find("<h2>Stages</h2>").expect("stages") < html.find("<h2>Settings</h2>").expect("settings"),
        "the settings last"
    );
    // The depth error split at the ground truth's silhouette (nlos_mesh::metrics::SILHOUETTE_BAND = 2).
    assert!(html.contains("depth error, mean inside (≥ 3 pixels from the silhouette)"));
    assert!(html.contains("depth error, mean on the silhouette band"));
    // The final mesh is the truth and rendered the same way: scale 1, no residual, perfect metrics, while
    // the flat initial surface is off by up to 30 mm.
    assert!((report.scale - 1.0).abs() < 1e-4, "scale {}", report.scale);
    assert!(report.relative_residual < 1e-3, "residual {}", report.relative_residual);
    let fin = report.metrics_final.expect("final metrics");
    assert!(fin.coverage > 0.99 && fin.depth_error_mean.expect("mean") < 1e-5, "{fin:?}");
    let init = report.metrics_init.expect("initial metrics");
    let init_err = init.depth_error_mean.expect("init mean");
    assert!(init_err > 0.01 && init_err < 0.02, "flat start: {init_err} m (expected ≈ 15 mm)");
    // The coverage picture: the flat start is off by more than 5 mm over much of the plane (orange), the
    // final mesh matches (near white).
    let (_, _, px) = decode(&dir.join("coverage.png"));
    let count = |c: [u8; 3]| px.chunks_exact(3).filter(|p| *p == c).count();
    assert!(count([240, 150, 20]) > 1000, "orange (off) pixels: {}", count([240, 150, 20]));
    assert!(count([235, 235, 235]) > 1000, "white (hit within 5 mm) pixels: {}", count([235, 235, 235]));
}

/// Nearest viridis parameter of a colour, when the colour is (within rounding) on the colormap.
fn viridis_t(c: [u8; 3]) -> Option<f32> {
    let (mut best, mut best_d) = (0.0, u32::MAX);
    for k in 0..=1000 {
        let t = k as f32 / 1000.0;
        let v = Colormap::Viridis.map(t).0;
        let d: u32 = (0..3).map(|i| (i32::from(v[i]) - i32::from(c[i])).unsigned_abs().pow(2)).sum();
        if d < best_d {
            (best, best_d) = (t, d);
        }
    }
    (best_d <= 3).then_some(best)
}

#[test]
fn depth_png_of_a_tilted_plane_is_monotone_along_the_tilt() {
    let (dir, measured, truth) = run_dir("tilt");
    let opts = ReportOptions { render: render_params(), ..ReportOptions::default() };
    write_report(&dir, &measured, Some(&truth), &opts).expect("report");
    let (w, h, px) = decode(&dir.join("depth_final.png"));
    // The middle row of the image crosses the plot area: find its first long run of colormap/miss pixels.
    let y = h / 2;
    let at = |x: usize| [px[3 * (x + w * y)], px[3 * (x + w * y) + 1], px[3 * (x + w * y) + 2]];
    let grey = [128u8, 128, 128];
    let mut run: Vec<Option<f32>> = Vec::new();
    for x in 0..w {
        let c = at(x);
        let v = if c == grey { Some(None) } else { viridis_t(c).map(Some) };
        match v {
            Some(t) => run.push(t),
            None if run.len() >= 200 => break,
            None => run.clear(),
        }
    }
    assert!(run.len() >= 200, "no plot area found on row {y} ({} pixels)", run.len());
    let ts: Vec<f32> = run.iter().flatten().copied().collect();
    // The plane covers x ∈ [−0.15, 0.15] of the [−0.25, 0.25] view: 60 % of the row, misses at both ends.
    assert!(ts.len() > run.len() / 2 && ts.len() < run.len() * 7 / 10, "{} of {} hit", ts.len(), run.len());
    assert!(run[0].is_none() && run[run.len() - 1].is_none(), "misses expected at both ends");
    assert!(ts.windows(2).all(|p| p[1] >= p[0]), "depth colours not monotone along the tilt: {ts:?}");
    assert!(ts[0] < 0.05 && ts[ts.len() - 1] > 0.95, "colours span {} to {}", ts[0], ts[ts.len() - 1]);
}

#[test]
fn missing_files_and_bad_options_are_typed_errors() {
    let (dir, measured, _) = run_dir("bad");
    let opts = ReportOptions { depth_grid: 0, ..ReportOptions::default() };
    assert!(matches!(write_report(&dir, &measured, None, &opts), Err(ReportError::InvalidOption { .. })));
    for area in [([0.1, -0.1], [-0.1, 0.1]), ([-0.1, 0.1], [f32::NAN, 0.1]), ([0.0, 0.0], [-0.1, 0.1])] {
        let opts = ReportOptions { area: Some(area), ..ReportOptions::default() };
        let e = write_report(&dir, &measured, None, &opts).expect_err("bad area");
        assert!(matches!(e, ReportError::InvalidOption { name: "area", .. }), "{area:?}: {e}");
    }
    // A run record of another version (an older build's checkpoint) is refused, saying both versions.
    std::fs::write(dir.join("checkpoint.json"), br#"{"version": 3, "reflectance": {"lambert": {"albedo": 1.0}}}"#)
        .expect("write");
    let e = write_report(&dir, &measured, None, &ReportOptions::default()).expect_err("old record");
    assert!(matches!(e, ReportError::Optim(_)) && e.to_string().contains("record version 3"), "{e}");
    std::fs::remove_file(dir.join("checkpoint.json")).expect("rm");
    std::fs::remove_file(dir.join("mesh.obj")).expect("rm");
    let e = write_report(&dir, &measured, None, &ReportOptions::default()).expect_err("no mesh");
    assert!(matches!(e, ReportError::MissingFile { .. }) && e.to_string().contains("mesh.obj"), "{e}");
    std::fs::write(dir.join("run_log.json"), b"{ nope").expect("write");
    let e = write_report(&dir, &measured, None, &ReportOptions::default()).expect_err("bad log");
    assert!(matches!(e, ReportError::Json { .. }), "{e}");
}

/// The residual's back-projection shows where the mesh misses light: measured the whole plane, rendered
/// only its left half (x < 0), the LCT's signed volume of the difference is the right half's light, positive,
/// and next to nothing over the left half that both hold.
#[test]
fn the_residual_back_projection_lights_up_where_the_mesh_is_missing() {
    let full = plane(0.35, 0.0);
    let (p, t) = full.to_triangles();
    let left: Vec<[u32; 3]> = t.iter().copied().filter(|f| f.iter().all(|&v| p[v as usize].x <= 0.0)).collect();
    let half = SurfaceMesh::from_triangles(&p, &left).expect("left half");
    let (measured, rendered) = (measure(&full), measure(&half));
    let b = nlos_report::residual::backproject(
        nlos_init::Method::Lct,
        nlos_init::Model::Lambert,
        &measured,
        &rendered,
        None,
    )
    .expect("back-projection");
    let (v, residual) = (&b.measured, b.residual());
    // Columns well inside each half (the LCT blurs a few voxels across x = 0).
    let (mut right, mut left) = (Vec::new(), Vec::new());
    for iy in 0..v.ny {
        for ix in 0..v.nx {
            let (x, y) = (v.x.at(ix), v.y.at(iy));
            let col = &residual[(ix + v.nx * iy) * v.nz..(ix + v.nx * iy + 1) * v.nz];
            let top = col.iter().copied().fold(0.0f32, |a, x| if x.abs() > a.abs() { x } else { a });
            if y.abs() < 0.1 && (0.04..0.12).contains(&x) {
                right.push(top);
            } else if y.abs() < 0.1 && (-0.12..-0.04).contains(&x) {
                left.push(top);
            }
        }
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    assert!(!right.is_empty() && !left.is_empty());
    assert!(mean(&right) > 0.3, "right half {:.3} of the capture's peak", mean(&right));
    assert!(mean(&left).abs() < 0.3 * mean(&right), "left {:.3} against right {:.3}", mean(&left), mean(&right));
}
