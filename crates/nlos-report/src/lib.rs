//! # nlos-report
//!
//! The report of a reconstruction run ("PNGs of measured vs rendered time-summed images and x–t
//! slices, a loss-curve plot, a one-page HTML report that shows them"). From a run directory written by
//! `nlos_optim::reconstruct` / `nlos reconstruct` — `mesh.obj` (final), `init.obj` (initial surface, when
//! present), `run_log.json`, `checkpoint.json` (for the reflectance), `stage_NN.obj` — and the measured
//! capture, [`write_report`] writes into the same directory:
//!
//! | file | what |
//! |---|---|
//! | `summed.png` | measured vs rendered time-summed images (for a sensor list: summed histograms) |
//! | `xt_slice.png` | measured vs rendered x–t slices through the middle sensor row |
//! | `loss.png` | total loss, data term and weighted regulariser per iteration, stage starts marked |
//! | `depth_init.png`, `depth_final.png`, `depth_gt.png` | depth maps seen from the wall (+z rays) |
//! | `relief.png` | the final (and ground-truth) depth minus its local mean: small relief such as lettering |
//! | `coverage.png` | with a ground truth: the evaluation's ray grid coloured by hit, missed, extra and off pixels, for the initial and final meshes ([`figures::coverage_figure`]) |
//! | `albedo.png` | the fitted albedo per vertex where the final mesh is seen (runs that fit one) |
//! | `residual.png` | where the light is left unexplained: the residual back-projected by the start's method (the LCT's linear, signed form on confocal grids) as a front view and an x–z slice; for photon counts on a confocal grid, coloured only beyond the back-projection of the model's own Poisson noise, shown beside it ([`residual`]) |
//! | `unexplained.png` | photon counts: the data term above its noise floor per spot over the wall, and its split in time — before, within and after each spot's return ([`unexplained`]) |
//! | `report.html` | one page: run parameters, metrics, per-stage table, the images, and an interactive 3-D view of the initial and final meshes (and the ground truth), coloured by depth, by distance to the ground truth or by the final mesh's support (`nlos_optim::support`), embedded so it works offline from the folder alone ([`view3d`]) |
//!
//! **Rendering.** The final mesh is rendered with `nlos_render` at the capture's geometry and time axis,
//! with the run's reflectance and per-vertex albedo (from the checkpoint) and the renderer settings of the run
//! ([`ReportOptions::render`]). The measured data's scale is arbitrary, so the rendering is shown as
//! `s*·I` with the closed-form scale of the run's loss (`nlos_optim::DataTerm::optimal_scale`: for L2,
//! `s* = ⟨I, Ĩ⟩/⟨I, I⟩`, eq. 7 of Tsai et al. 2019 minimised over s), computed on the bins after the
//! direct-light gate — the bins the figures show.
//!
//! **Depth maps.** +z rays from a grid over [`ReportOptions::area`] (default: the scan's bounding
//! rectangle), first hits through `nlos_mesh`'s BVH ([`figures::depth_map`]); all depth maps share one
//! colour range, the 2nd–95th percentile of the ground truth's depths (else the final mesh's), so
//! millimetre relief stays visible.
//!
//! **Metrics** (with a ground truth): `nlos_mesh::metrics::evaluate` of the initial and final meshes,
//! on a [`ReportOptions::eval_grid`]² grid over the same rectangle.
#![warn(missing_docs)]

pub mod error;
pub mod figures;
mod html;
pub mod residual;
mod run;
pub mod unexplained;
pub mod view3d;

use std::path::{Path, PathBuf};

use nlos_init::Method;
use nlos_mesh::SurfaceMesh;
use nlos_mesh::metrics::Metrics;
use nlos_optim::{DataTerm, Loss, Reflectance, RunLog, RunRecord, SensorFit};
use nlos_render::{RenderParams, Renderer};
use nlos_transient::Transient;
use nlos_viz::{Extent, RgbImage};

pub use error::{ReportError, Result};
pub use figures::DepthView;

/// The HTML page's file name in the run directory.
pub const REPORT_FILE: &str = "report.html";
/// The final mesh (written by `nlos_optim` when a run finishes).
pub const MESH_FILE: &str = "mesh.obj";
/// The initial surface (written by `nlos reconstruct`).
pub const INIT_FILE: &str = "init.obj";

/// How the report is made.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportOptions {
    /// Page title (default "nlos reconstruction").
    pub title: String,
    /// Run parameters to list, in order (e.g. the command line's), besides what the run directory tells.
    pub parameters: Vec<(String, String)>,
    /// The renderer settings of the run (kernel, sampling, visibility, sidedness), used to render the final
    /// mesh. Default: [`RenderParams::default`].
    pub render: RenderParams,
    /// The run's loss, which defines the closed-form scale (default L2).
    pub loss: Loss,
    /// The run's noise-aware sensor fit, if any (`nlos_optim::ReconstructParams::sensor`): the rendering is
    /// then shown as expected counts `α*·J(I) + b` (jitter kernel `J`, background `b`, the fit's scale `α*`
    /// on the whole capture), as the fit saw it. Default None.
    pub sensor: Option<SensorFit>,
    /// Direct-light gate, metres of path: bins before it are left out of the figures and the scale;
    /// `None` (default) estimates it (`Transient::direct_light_end`).
    pub gate: Option<f64>,
    /// Sensor row of the x–t slices (default: the middle row).
    pub slice_row: Option<usize>,
    /// The rectangle of the wall (`[x0, x1]`, `[y0, y1]`, metres) under the depth maps and the metrics' ray
    /// grid. `None` (default): the bounding rectangle of `measured`'s sensor points. A run fitted on a
    /// subsampled grid passes the whole capture's rectangle, so that the metrics are those of `nlos eval`
    /// (Tsai et al. 2019's setup's 64 × 64 grid spans [−0.25, 0.25]² m, its every-other-point subsample only
    /// [−0.25, 0.242]²).
    pub area: Option<([f32; 2], [f32; 2])>,
    /// Pixels per side of the depth maps (default 256; 1..=4096).
    pub depth_grid: usize,
    /// Pixels per side of the metrics' ray grid (default 128, as `nlos eval`; 1..=4096).
    pub eval_grid: usize,
    /// Side of the relief filter's box, metres (default 0.025).
    pub relief_box: f64,
    /// The volumetric method that back-projects the residual (`residual.png`, [`residual`]): the run's start
    /// method. `None` (default): the method the scan gets when none is named ([`Method::for_scan`]).
    pub backprojection: Option<Method>,
}

impl Default for ReportOptions {
    fn default() -> Self {
        Self {
            title: "nlos reconstruction".into(),
            parameters: Vec::new(),
            render: RenderParams::default(),
            loss: Loss::L2,
            sensor: None,
            gate: None,
            slice_row: None,
            area: None,
            depth_grid: 256,
            eval_grid: 128,
            relief_box: 0.025,
            backprojection: None,
        }
    }
}

/// What [`write_report`] wrote and found.
#[derive(Debug, Clone)]
pub struct Report {
    /// The HTML page.
    pub html: PathBuf,
    /// The images, file names relative to the run directory, in page order.
    pub images: Vec<String>,
    /// The closed-form intensity scale of the final rendering against the gated measurement.
    pub scale: f64,
    /// Relative residual `‖s*·I − Ĩ‖ / ‖Ĩ‖` over the gated bins.
    pub relative_residual: f64,
    /// The direct-light gate used (metres of path; the axis start when nothing was gated).
    pub gate: f64,
    /// Metrics of the initial surface against the ground truth (with a ground truth and `init.obj`).
    pub metrics_init: Option<Metrics>,
    /// Metrics of the final mesh against the ground truth.
    pub metrics_final: Option<Metrics>,
    /// Photon counts: where the data term above its noise floor lies ([`unexplained::split`]).
    pub unexplained: Option<unexplained::Split>,
}

fn read(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| ReportError::Io { file: path.to_owned(), source })
}

fn load_mesh(path: &Path, hint: &'static str) -> Result<SurfaceMesh> {
    if !path.is_file() {
        return Err(ReportError::MissingFile { file: path.to_owned(), hint });
    }
    Ok(nlos_mesh::metrics::load_for_eval(path)?)
}

/// Reads `run_log.json` of a run directory.
///
/// # Errors
/// [`ReportError::MissingFile`], [`ReportError::Io`], [`ReportError::Json`].
pub fn read_run_log(dir: &Path) -> Result<RunLog> {
    let path = dir.join(nlos_optim::RUN_LOG_FILE);
    if !path.is_file() {
        return Err(ReportError::MissingFile { file: path, hint: "nlos reconstruct writes it after every block" });
    }
    serde_json::from_slice(&read(&path)?).map_err(|e| ReportError::Json { file: path, message: e.to_string() })
}

/// The run record of a run directory ([`nlos_optim::RunRecord`], its `checkpoint.json`), or `None` when it
/// has none.
///
/// # Errors
/// [`ReportError::Optim`] for a record that cannot be read, of another version or inconsistent.
pub fn read_record(dir: &Path) -> Result<Option<RunRecord>> {
    if !dir.join(nlos_optim::CHECKPOINT_FILE).is_file() {
        return Ok(None);
    }
    Ok(Some(RunRecord::read(dir)?))
}

fn save(img: &RgbImage, dir: &Path, name: &str, images: &mut Vec<String>) -> Result<()> {
    img.save_png(dir.join(name))?;
    images.push(name.to_string());
    Ok(())
}

fn check_grid(name: &'static str, n: usize) -> Result<()> {
    if (1..=nlos_mesh::metrics::MAX_GRID).contains(&n) {
        Ok(())
    } else {
        Err(ReportError::InvalidOption { name, reason: format!("{n} pixels per side; use 1 to 4096") })
    }
}

/// Writes the report of the run in `dir` (module documentation: inputs, files, methods) and returns what
/// it wrote. `measured` must be the capture the run fitted (after the same rebinning/subsampling);
/// `ground_truth` adds its depth map and the metrics.
///
/// # Errors
/// [`ReportError::MissingFile`] without `mesh.obj` or `run_log.json`; [`ReportError::InvalidOption`];
/// errors reading the files, rendering, ray casting or drawing.
pub fn write_report(
    dir: &Path,
    measured: &Transient,
    ground_truth: Option<&SurfaceMesh>,
    opts: &ReportOptions,
) -> Result<Report> {
    check_grid("depth_grid", opts.depth_grid)?;
    check_grid("eval_grid", opts.eval_grid)?;
    if !(opts.relief_box.is_finite() && opts.relief_box > 0.0) {
        return Err(ReportError::InvalidOption {
            name: "relief_box",
            reason: format!("{} m; must be finite and > 0", opts.relief_box),
        });
    }
    let log = read_run_log(dir)?;
    let final_mesh = load_mesh(&dir.join(MESH_FILE), "nlos reconstruct writes it when the run finishes")?;
    let init_path = dir.join(INIT_FILE);
    let init_mesh = if init_path.is_file() { Some(load_mesh(&init_path, "")?) } else { None };
    let record = read_record(dir)?;
    let (reflectance, reflectance_note) = match &record {
        Some(r) => (r.reflectance().clone(), "from checkpoint.json"),
        None => (Reflectance::default(), "no checkpoint.json: Lambertian assumed"),
    };

    // ---- render the final mesh and gate both ----
    let ax = *measured.time();
    let gate = opts.gate.unwrap_or_else(|| measured.direct_light_end()).clamp(ax.t0, ax.end());
    let gated = |t: &Transient| -> Result<Transient> { Ok(if gate > ax.t0 { t.gate(gate)? } else { t.clone() }) };
    let (positions, triangles) = final_mesh.to_triangles();
    let mut renderer = Renderer::new(&positions, &triangles, measured.scan(), &ax, opts.render)?;
    // The fitted albedo per vertex of the final mesh (the record's surface is the mesh written at the end).
    let albedo: Option<Vec<f32>> = record
        .as_ref()
        .and_then(RunRecord::albedo)
        .filter(|a| a.len() == positions.len())
        .map(|a| a.iter().map(|&x| x as f32).collect());
    if let Some(a) = &albedo {
        let a64: Vec<f64> = a.iter().map(|&x| f64::from(x)).collect();
        renderer.set_face_weights(Some(&nlos_optim::albedo::face_weights(&a64, &triangles)))?;
    }
    let rendered = renderer.forward_any(&reflectance.brdf()?);
    let measured_g = gated(measured)?;
    let (scaled, scale, background) = match &opts.sensor {
        Some(sensor) => {
            // Expected counts as the sensor fit models them, scale solved on the whole capture like the run.
            let b = sensor.resolve_background(measured)?;
            let x: Vec<f64> = rendered.iter().map(|&v| f64::from(v)).collect();
            let mut a = vec![0.0; x.len()];
            sensor.kernel.apply_f64(&x, ax.bins, &mut a)?;
            let alpha = SensorFit::optimal_scale_jittered(&a, measured.data(), b).unwrap_or(1.0);
            let mu: Vec<f32> = a.iter().map(|&v| (alpha * v + b) as f32).collect();
            (gated(&Transient::new(measured.scan().clone(), ax, mu)?)?, alpha, Some(b))
        }
        None => {
            let rendered = gated(&Transient::new(measured.scan().clone(), ax, rendered)?)?;
            let term = DataTerm { loss: opts.loss, weights: None, solve_scale: true, counts: false };
            let scale = term.optimal_scale(rendered.data(), measured_g.data()).unwrap_or(1.0);
            let mut scaled = rendered;
            scaled.data_mut().iter_mut().for_each(|v| *v = (f64::from(*v) * scale) as f32);
            (scaled, scale, None)
        }
    };
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (r, m) in scaled.data().iter().zip(measured_g.data()) {
        num += (f64::from(*r) - f64::from(*m)).powi(2);
        den += f64::from(*m).powi(2);
    }
    let relative_residual = if den > 0.0 { (num / den).sqrt() } else { f64::NAN };

    // ---- figures ----
    let mut images = Vec::new();
    let gate_note = if gate > ax.t0 {
        format!("bins before {gate:.3} m of path (direct light) left out")
    } else {
        "nothing gated".to_string()
    };
    match measured.sensor_grid() {
        Some((_, ny)) => {
            let notes = [
                gate_note.clone(),
                format!("rendered x {scale:.4e} (closed-form scale); relative residual {relative_residual:.3}"),
            ];
            save(&figures::summed_figure(&measured_g, &scaled, &notes)?, dir, "summed.png", &mut images)?;
            let row = opts.slice_row.unwrap_or(ny / 2);
            let g = (gate > ax.t0).then_some(gate);
            save(&figures::slice_figure(measured, &scaled, row, g)?, dir, "xt_slice.png", &mut images)?;
        }
        None => save(&figures::histogram_figure(&measured_g, &scaled)?, dir, "summed.png", &mut images)?,
    }
    if !log.iterations.is_empty() {
        save(&figures::loss_figure(&log)?, dir, "loss.png", &mut images)?;
    }
    let view = match opts.area {
        Some((x_range, y_range)) => DepthView::over_area(x_range, y_range, opts.depth_grid)?,
        None => DepthView::over_scan(measured, opts.depth_grid)?,
    };
    let d_final = figures::depth_map(&final_mesh, &view)?;
    let d_init = init_mesh.as_ref().map(|m| figures::depth_map(m, &view)).transpose()?;
    let d_gt = ground_truth.map(|m| figures::depth_map(m, &view)).transpose()?;
    let range = figures::depth_range(d_gt.as_deref().unwrap_or(&d_final))
        .or_else(|| figures::depth_range(&d_final))
        .or_else(|| d_init.as_deref().and_then(figures::depth_range))
        .unwrap_or((0.0, 1.0));
    if let Some(d) = &d_init {
        save(&figures::depth_figure(d, &view, range, "depth: initial surface")?, dir, "depth_init.png", &mut images)?;
    }
    save(&figures::depth_figure(&d_final, &view, range, "depth: final mesh")?, dir, "depth_final.png", &mut images)?;
    if let Some(d) = &d_gt {
        save(&figures::depth_figure(d, &view, range, "depth: ground truth")?, dir, "depth_gt.png", &mut images)?;
    }
    if let Some(a) = &albedo {
        save(&figures::albedo_figure(&final_mesh, a, &view)?, dir, "albedo.png", &mut images)?;
    }
    let method = opts.backprojection.unwrap_or_else(|| Method::for_scan(measured.scan()).0);
    // A method that cannot take the scan (or finds nothing in it) leaves the picture out, not the report.
    // Photon counts: the residual judged against a Poisson draw of the model (seed fixed, so a report is
    // reproducible).
    let draw = opts.sensor.is_some().then_some(1);
    if let Ok(b) = residual::backproject(method, reflectance.model(), &measured_g, &scaled, draw) {
        let note = format!("the final mesh rendered as the fit saw it ({gate_note})");
        save(&residual::residual_figure(&b, &note)?, dir, "residual.png", &mut images)?;
    }
    let unexplained = background.map(|b| unexplained::split(&measured_g, &scaled, b)).transpose()?;
    if let (Some(split), Some((nx, ny))) = (&unexplained, measured.sensor_grid()) {
        // One measurement per spot: a confocal grid (the spots' bounds span the grid's centres).
        if split.per_measurement.len() == nx * ny {
            let (lo, hi) = measured.scan().sensors().bounds().unwrap_or_default();
            let ex = Extent::from_centres(f64::from(lo.x), f64::from(hi.x), nx)?;
            let ey = Extent::from_centres(f64::from(lo.y), f64::from(hi.y), ny)?;
            save(&unexplained::unexplained_figure(split, nx, ny, ex, ey)?, dir, "unexplained.png", &mut images)?;
        }
    }
    let pixel = f64::from(view.x_range[1] - view.x_range[0]) / view.grid as f64;
    let radius = ((opts.relief_box / pixel / 2.0).round() as usize).clamp(1, view.grid.max(2) / 2);
    let r_final = figures::relief(&d_final, view.grid, radius);
    let r_gt = d_gt.as_ref().map(|d| figures::relief(d, view.grid, radius));
    let mut maps: Vec<(&str, &[f32])> = vec![("final mesh", &r_final)];
    if let Some(r) = &r_gt {
        maps.push(("ground truth", r));
    }
    let box_m = (2 * radius + 1) as f64 * pixel;
    save(&figures::relief_figure(&maps, &view, box_m)?, dir, "relief.png", &mut images)?;

    // ---- metrics ----
    let eval = DepthView { grid: opts.eval_grid, ..view }.eval_params();
    let (metrics_init, metrics_final) = match ground_truth {
        Some(gt) => (
            init_mesh.as_ref().map(|m| nlos_mesh::metrics::evaluate(m, gt, &eval)).transpose()?,
            Some(nlos_mesh::metrics::evaluate(&final_mesh, gt, &eval)?),
        ),
        None => (None, None),
    };
    if let Some(mf) = &metrics_final {
        let mut maps: Vec<(&str, &[f32])> = Vec::new();
        if let Some(mi) = &metrics_init {
            maps.push(("initial", &mi.depth_reconstruction));
        }
        maps.push(("final", &mf.depth_reconstruction));
        let fig = figures::coverage_figure(&maps, &mf.depth_ground_truth, &DepthView { grid: opts.eval_grid, ..view })?;
        save(&fig, dir, "coverage.png", &mut images)?;
    }

    let report = Report {
        html: dir.join(REPORT_FILE),
        images,
        scale,
        relative_residual,
        gate,
        metrics_init,
        metrics_final,
        unexplained,
    };
    let mut shown = Vec::new();
    if let Some(m) = &init_mesh {
        shown.push(view3d::ViewMesh { name: "initial surface", mesh: m, support: None });
    }
    // How much of their light the data confirm, per vertex of the final mesh (the record's surface).
    let support = record.as_ref().and_then(RunRecord::vertex_support).filter(|s| s.len() == positions.len());
    shown.push(view3d::ViewMesh { name: "final mesh", mesh: &final_mesh, support: support.as_deref() });
    let view3d = view3d::section(&shown, ground_truth)?;
    let page = html::page(&html::PageInputs {
        opts,
        log: &log,
        report: &report,
        reflectance: &reflectance,
        reflectance_note,
        final_mesh: &final_mesh,
        dir,
        eval: &eval,
        gate_note: &gate_note,
        view3d: &view3d,
    });
    let tmp = dir.join(format!("{REPORT_FILE}.tmp"));
    std::fs::write(&tmp, page).map_err(|source| ReportError::Io { file: tmp.clone(), source })?;
    std::fs::rename(&tmp, &report.html).map_err(|source| ReportError::Io { file: report.html.clone(), source })?;
    Ok(report)
}
