//! The report's figures, each a function of plain inputs (a capture, a run log, a depth map) returning an
//! [`RgbImage`]; [`crate::write_report`] composes them.

use nlos_mesh::SurfaceMesh;
use nlos_mesh::metrics::EvalParams;
use nlos_optim::{RunLog, StepKind};
use nlos_transient::Transient;
use nlos_viz::{Colormap, Extent, Figure, Interp, MarkerAxis, Norm, Panel, Rgb, RgbImage, ScalarGrid, Scale, Series};

use crate::error::{ReportError, Result};

/// Decades below the maximum that the log-scaled x–t slices show.
pub const SLICE_DECADES: f64 = 3.0;

/// Side of the time-summed image panels, pixels.
const SIDE: usize = 320;

fn capture_error(reason: impl Into<String>) -> ReportError {
    ReportError::Capture { reason: reason.into() }
}

/// The physical extents (x, y) of a capture's sensor grid (pixel edges around the grid points).
///
/// # Errors
/// [`ReportError::Capture`] when the sensor points are not a grid; [`ReportError::Viz`] for a degenerate
/// extent.
pub fn grid_extents(t: &Transient) -> Result<(Extent, Extent)> {
    let (nx, ny) = t.sensor_grid().ok_or_else(|| capture_error("the sensor points are not a grid"))?;
    let p = &t.scan().sensors().points;
    let (first, last_x, last_y) = (p[0], p[nx - 1], p[nx * (ny - 1)]);
    let ex = Extent::from_centres(f64::from(first.x), f64::from(last_x.x), nx)?;
    let ey = Extent::from_centres(f64::from(first.y), f64::from(last_y.y), ny)?;
    Ok((ex, ey))
}

/// Plot-area size keeping the aspect ratio of `(ex, ey)`, the longer side `side` pixels.
fn aspect_size(ex: Extent, ey: Extent, side: usize) -> (usize, usize) {
    let (wx, wy) = ((ex.max() - ex.min()).abs(), (ey.max() - ey.min()).abs());
    if wx >= wy {
        (side, ((side as f64 * wy / wx).round() as usize).max(40))
    } else {
        (((side as f64 * wx / wy).round() as usize).max(40), side)
    }
}

/// Measured beside rendered time-summed images (one shared linear colour scale), for a grid scan.
///
/// `rendered` should already carry the intensity scale (`s · I`), so that both panels are comparable.
///
/// # Errors
/// [`ReportError::Capture`] when the captures are not grids of the same shape; drawing errors.
pub fn summed_figure(measured: &Transient, rendered: &Transient, notes: &[String]) -> Result<RgbImage> {
    let (nx, ny) = measured.sensor_grid().ok_or_else(|| capture_error("the sensor points are not a grid"))?;
    if rendered.sensor_grid() != Some((nx, ny)) {
        return Err(capture_error("the rendered transient's sensor grid differs from the measurement's"));
    }
    let m = measured.time_summed_image()?;
    let r = rendered.time_summed_image()?;
    let (ex, ey) = grid_extents(measured)?;
    let hi = m.iter().chain(&r).copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max);
    let norm = Norm::linear(0.0, if hi > 0.0 { f64::from(hi) } else { 1.0 })?;
    let (w, h) = aspect_size(ex, ey, SIDE);
    let mg = ScalarGrid::new(&m, nx, ny, ex, ey)?;
    let rg = ScalarGrid::new(&r, nx, ny, ex, ey)?;
    let mut fig = Figure::new("time-summed: measured vs rendered");
    fig.notes.extend(notes.iter().cloned());
    fig.panels = vec![
        Panel::image(mg, norm).with_title("measured").with_labels("x (m)", "y (m)").with_size(w, h),
        Panel::image(rg, norm)
            .with_title("rendered (final mesh, x scale)")
            .with_labels("x (m)", "y (m)")
            .with_size(w, h)
            .with_colorbar("counts"),
    ];
    Ok(fig.render()?)
}

/// Measured beside rendered x–t slices through sensor row `row` (log colour scale over
/// [`SLICE_DECADES`] decades below the measured maximum, shared), with the direct-light gate marked.
///
/// # Errors
/// [`ReportError::Capture`] when the captures are not grids of the same shape or `row` is outside it;
/// drawing errors.
pub fn slice_figure(measured: &Transient, rendered: &Transient, row: usize, gate: Option<f64>) -> Result<RgbImage> {
    let (nx, _) = measured.sensor_grid().ok_or_else(|| capture_error("the sensor points are not a grid"))?;
    if rendered.sensor_grid() != measured.sensor_grid() || rendered.bins() != measured.bins() {
        return Err(capture_error("the rendered transient's shape differs from the measurement's"));
    }
    let m = measured.grid_row_slice(row)?;
    let r = rendered.grid_row_slice(row)?;
    let (ex, _) = grid_extents(measured)?;
    let ax = measured.time();
    let path = Extent::new(ax.t0, ax.end())?;
    let hi = m.iter().chain(&r).copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max);
    let norm = Norm::log(if hi > 0.0 { f64::from(hi) } else { 1.0 }, SLICE_DECADES)?;
    let y = measured.scan().sensors().points[nx * row].y;
    let mut fig = Figure::new(format!("x-t slice at y = {y:.3} m (row {row}): measured vs rendered"));
    fig.notes.push(format!("log colour scale over {SLICE_DECADES} decades, shared"));
    for (k, (v, title)) in [(&m, "measured"), (&r, "rendered")].into_iter().enumerate() {
        let g = ScalarGrid::new(v, ax.bins, nx, path, ex)?;
        let mut p = Panel::image(g, norm)
            .with_title(title)
            .with_labels("path length (m)", "x (m)")
            .with_size(420, 240)
            .with_colormap(Colormap::Magma)
            .with_interp(Interp::Area);
        if let Some(g) = gate {
            p = p.with_marker(MarkerAxis::X, g, "gate", Rgb::new(80, 200, 255));
        }
        if k == 1 {
            p = p.with_colorbar("counts (log)");
        }
        fig.panels.push(p);
    }
    fig.columns = 1;
    Ok(fig.render()?)
}

/// Measured and rendered histograms summed over all measurements, as two curves (for scans whose sensor
/// points are a list, where no image exists).
///
/// # Errors
/// Drawing errors (e.g. an all-NaN capture).
pub fn histogram_figure(measured: &Transient, rendered: &Transient) -> Result<RgbImage> {
    let ax = measured.time();
    let x: Vec<f64> = (0..ax.bins).map(|k| ax.bin_center(k)).collect();
    let m = measured.summed_histogram();
    let r = rendered.summed_histogram();
    let panel =
        Panel::lines(vec![Series::new(&x, &m, "measured", Rgb::BLACK), Series::new(&x, &r, "rendered", Rgb::RED)])?
            .with_title("summed histogram")
            .with_labels("path length (m)", "counts")
            .with_size(640, 320);
    let mut fig = Figure::new("measured vs rendered (sensor points are a list: no image)");
    fig.panels = vec![panel];
    Ok(fig.render()?)
}

/// The loss curve: total loss, normalised data term and weighted regulariser `λR` per iteration on a log
/// axis, with the first iteration of every stage after the first marked.
///
/// # Errors
/// [`ReportError::InvalidOption`] for an empty log; drawing errors.
pub fn loss_figure(log: &RunLog) -> Result<RgbImage> {
    let it = &log.iterations;
    if it.is_empty() {
        return Err(ReportError::InvalidOption { name: "run log", reason: "no iteration recorded".into() });
    }
    let x: Vec<f64> = it.iter().map(|r| r.iteration as f64).collect();
    let total: Vec<f64> = it.iter().map(|r| r.loss).collect();
    let data: Vec<f64> = it.iter().map(|r| r.data).collect();
    let reg: Vec<f64> = it.iter().map(|r| r.reg_weight * r.regulariser).collect();
    let finite_pos = || total.iter().chain(&data).chain(&reg).copied().filter(|v| v.is_finite() && *v > 0.0);
    let hi = finite_pos().fold(0.0f64, f64::max);
    let lo = finite_pos().fold(f64::INFINITY, f64::min);
    // Enough decades to show every positive value, at least 1, at most 12.
    let decades = if hi > 0.0 { ((hi * 1.2 / lo).log10() + 0.2).clamp(1.0, 12.0) } else { 1.0 };
    let mut panel = Panel::lines(vec![
        Series::new(&x, &total, "total", Rgb::BLACK),
        Series::new(&x, &data, "data", Rgb::BLUE),
        Series::new(&x, &reg, "lambda x reg.", Rgb::new(0, 150, 60)),
    ])?
    .with_y_scale(Scale::Log { decades })
    .with_labels("iteration", "loss (normalised)")
    .with_size(640, 320);
    for w in it.windows(2) {
        if w[1].stage != w[0].stage {
            panel = panel.with_marker(
                MarkerAxis::X,
                w[1].iteration as f64,
                format!("stage {}", w[1].stage + 1),
                Rgb::new(200, 60, 60),
            );
        }
    }
    let shape = it.iter().filter(|r| r.kind == StepKind::Shape).count();
    let mut fig = Figure::new("loss per iteration");
    fig.notes.push(format!(
        "{} iterations ({shape} shape, {} reflectance), {} rollbacks; dashed lines: stage starts",
        it.len(),
        it.len() - shape,
        log.rollbacks
    ));
    fig.panels = vec![panel];
    Ok(fig.render()?)
}

/// The wall-side view of the depth maps: a square ray grid over a rectangle of the wall.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthView {
    /// Pixels per side.
    pub grid: usize,
    /// x extent on the wall, metres.
    pub x_range: [f32; 2],
    /// y extent on the wall, metres.
    pub y_range: [f32; 2],
}

impl DepthView {
    /// The view over the bounding rectangle of a capture's wall spots, laser and sensor spots together (a
    /// paired scan's sensors sit beside its lasers, and the hidden scene faces both).
    ///
    /// # Errors
    /// [`ReportError::Capture`] when the points do not span a rectangle of positive area.
    pub fn over_scan(t: &Transient, grid: usize) -> Result<Self> {
        let scan = t.scan();
        let (mut x0, mut x1, mut y0, mut y1) = (f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY);
        for p in scan.sensors().points.iter().chain(&scan.lasers().points) {
            (x0, x1, y0, y1) = (x0.min(p.x), x1.max(p.x), y0.min(p.y), y1.max(p.y));
        }
        if !(x1 > x0 && y1 > y0) {
            return Err(capture_error("the wall spots do not span a rectangle of the wall: no depth view"));
        }
        Ok(Self { grid, x_range: [x0, x1], y_range: [y0, y1] })
    }

    /// The view over the rectangle `x_range × y_range` of the wall (metres).
    ///
    /// # Errors
    /// [`ReportError::InvalidOption`] (`area`) unless both ranges are finite with `min < max`.
    pub fn over_area(x_range: [f32; 2], y_range: [f32; 2], grid: usize) -> Result<Self> {
        let ok = |r: [f32; 2]| r[0].is_finite() && r[1].is_finite() && r[0] < r[1];
        if !(ok(x_range) && ok(y_range)) {
            return Err(ReportError::InvalidOption {
                name: "area",
                reason: format!("x {x_range:?}, y {y_range:?} m: each range must be finite with min < max"),
            });
        }
        Ok(Self { grid, x_range, y_range })
    }

    /// The ray-grid parameters of `nlos_mesh::metrics` for this view.
    pub fn eval_params(&self) -> EvalParams {
        EvalParams { grid: self.grid, x_range: self.x_range, y_range: self.y_range, ..EvalParams::default() }
    }
}

/// Depth map of `mesh` seen from the wall: z (metres) of the first hit of the +z ray through each pixel
/// centre of `view` (`NaN` for none), `ix + grid·iy` (ray casting through `nlos_mesh`'s BVH,
/// [`nlos_mesh::metrics::depth_map`]).
///
/// # Errors
/// [`ReportError::Mesh`] for an invalid grid, an empty mesh or non-finite positions.
pub fn depth_map(mesh: &SurfaceMesh, view: &DepthView) -> Result<Vec<f32>> {
    Ok(nlos_mesh::metrics::depth_map(mesh, &view.eval_params())?)
}

/// The `q`-quantile (0..=1) of the finite values, by sorting.
fn quantile(values: &[f32], q: f64) -> Option<f64> {
    let mut v: Vec<f32> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f32::total_cmp);
    let i = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(f64::from(v[i]))
}

/// The colour range of the depth maps: the 2nd to 95th percentile of the hit depths (metres), so that
/// steep rims and stray far triangles (which take few pixels but many millimetres) do not compress the
/// object's front, and its relief, into a few colours; widened to 1 mm when flatter. `None` when nothing
/// is hit.
pub fn depth_range(depth: &[f32]) -> Option<(f64, f64)> {
    let (lo, hi) = (quantile(depth, 0.02)?, quantile(depth, 0.95)?);
    let mid = 0.5 * (lo + hi);
    Some(if hi - lo < 1e-3 { (mid - 5e-4, mid + 5e-4) } else { (lo, hi) })
}

/// A depth map as an image, in millimetres, x right and y up as seen from the wall, viridis over `range`
/// (metres; near = dark), rays that miss in grey.
///
/// # Errors
/// [`ReportError::InvalidOption`] when `depth` does not hold `grid²` values; drawing errors.
pub fn depth_figure(depth: &[f32], view: &DepthView, range: (f64, f64), title: &str) -> Result<RgbImage> {
    let n = view.grid;
    if depth.len() != n * n {
        return Err(ReportError::InvalidOption {
            name: "depth",
            reason: format!("{} values for a {n} x {n} grid", depth.len()),
        });
    }
    let mm: Vec<f32> = depth.iter().map(|z| z * 1e3).collect();
    let ex = Extent::new(f64::from(view.x_range[0]), f64::from(view.x_range[1]))?;
    let ey = Extent::new(f64::from(view.y_range[0]), f64::from(view.y_range[1]))?;
    let g = ScalarGrid::new(&mm, n, n, ex, ey)?;
    let (w, h) = aspect_size(ex, ey, 360);
    let hits = depth.iter().filter(|z| z.is_finite()).count();
    let mut fig = Figure::new(title);
    fig.notes.push(format!(
        "+z rays from a {n} x {n} grid on the wall, {:.1} % hit; colours span {:.1} to {:.1} mm",
        100.0 * hits as f64 / (n * n) as f64,
        range.0 * 1e3,
        range.1 * 1e3
    ));
    fig.notes.push("x to the right as in wall coordinates: text facing the wall reads mirrored".into());
    fig.panels = vec![
        Panel::image(g, Norm::linear(range.0 * 1e3, range.1 * 1e3)?)
            .with_labels("x (m)", "y (m)")
            .with_size(w, h)
            .with_colorbar("depth z (mm)"),
    ];
    Ok(fig.render()?)
}

/// The fitted per-vertex albedo (`nlos_optim::albedo`) where the final mesh is seen: at each pixel of `view`
/// the albedo of the first hit of its +z ray, interpolated between the hit face's corners; grey where the ray
/// misses. x right and y up as seen from the wall, like the depth maps; colours from 0 to the 98th
/// percentile.
///
/// # Errors
/// [`ReportError::InvalidOption`] when `albedo` does not hold one value per vertex of `mesh`; mesh and
/// drawing errors.
pub fn albedo_figure(mesh: &SurfaceMesh, albedo: &[f32], view: &DepthView) -> Result<RgbImage> {
    let (positions, triangles) = mesh.to_triangles();
    if albedo.len() != positions.len() {
        return Err(ReportError::InvalidOption {
            name: "albedo",
            reason: format!("{} values for a mesh of {} vertices", albedo.len(), positions.len()),
        });
    }
    let bvh = nlos_mesh::TriangleBvh::from_triangles(&positions, &triangles)?;
    let grid = view.eval_params();
    let n = view.grid;
    let values: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = grid.pixel_center(k % n, k / n);
            match bvh.ray_first_hit(glam::Vec3::new(x, y, 0.0), glam::Vec3::Z, f32::INFINITY) {
                Some(h) => {
                    let t = triangles[h.triangle as usize];
                    let b = h.barycentric;
                    albedo[t[0] as usize] * b.x + albedo[t[1] as usize] * b.y + albedo[t[2] as usize] * b.z
                }
                None => f32::NAN,
            }
        })
        .collect();
    let hi = quantile(&values, 0.98).filter(|h| *h > 0.0).unwrap_or(1.0);
    let ex = Extent::new(f64::from(view.x_range[0]), f64::from(view.x_range[1]))?;
    let ey = Extent::new(f64::from(view.y_range[0]), f64::from(view.y_range[1]))?;
    let g = ScalarGrid::new(&values, n, n, ex, ey)?;
    let (w, h) = aspect_size(ex, ey, 360);
    let mut fig = Figure::new("albedo (relative: area mean 1 over the surface)");
    fig.notes.push("one albedo per vertex, interpolated across faces; shown where the final mesh is hit".into());
    fig.notes.push("x to the right as in wall coordinates: text facing the wall reads mirrored".into());
    fig.panels = vec![
        Panel::image(g, Norm::linear(0.0, hi)?)
            .with_labels("x (m)", "y (m)")
            .with_size(w, h)
            .with_colorbar("albedo (relative)"),
    ];
    Ok(fig.render()?)
}

/// The relief of a depth map: each hit pixel minus the mean of the hit pixels in the `(2r+1)²` box around
/// it (a high-pass filter through a summed-area table), `NaN` where the ray missed. Removes the object's
/// overall shape and keeps detail smaller than the box, such as relief lettering.
pub fn relief(depth: &[f32], grid: usize, r: usize) -> Vec<f32> {
    let n = grid;
    if depth.len() != n * n || n == 0 {
        return vec![f32::NAN; depth.len()];
    }
    // Summed-area tables of the hit depths and of the hit count, (n+1)² each.
    let w = n + 1;
    let (mut sum, mut cnt) = (vec![0.0f64; w * w], vec![0u32; w * w]);
    for iy in 0..n {
        for ix in 0..n {
            let z = depth[ix + n * iy];
            let (v, c) = if z.is_finite() { (f64::from(z), 1) } else { (0.0, 0) };
            let i = (ix + 1) + w * (iy + 1);
            sum[i] = v + sum[i - 1] + sum[i - w] - sum[i - w - 1];
            cnt[i] = c + cnt[i - 1] + cnt[i - w] - cnt[i - w - 1];
        }
    }
    let mut out = vec![f32::NAN; n * n];
    for iy in 0..n {
        for ix in 0..n {
            let z = depth[ix + n * iy];
            if !z.is_finite() {
                continue;
            }
            let (x0, x1, y0, y1) =
                (ix.saturating_sub(r), (ix + r + 1).min(n), iy.saturating_sub(r), (iy + r + 1).min(n));
            let s = sum[x1 + w * y1] - sum[x0 + w * y1] - sum[x1 + w * y0] + sum[x0 + w * y0];
            let c = cnt[x1 + w * y1] + cnt[x0 + w * y0] - cnt[x0 + w * y1] - cnt[x1 + w * y0];
            out[ix + n * iy] = (f64::from(z) - s / f64::from(c.max(1))) as f32;
        }
    }
    out
}

/// Relief maps (see [`relief`]) side by side, in millimetres, on one symmetric grey scale (near = dark).
///
/// # Errors
/// [`ReportError::InvalidOption`] for a map of the wrong size or no map; drawing errors.
pub fn relief_figure(maps: &[(&str, &[f32])], view: &DepthView, box_m: f64) -> Result<RgbImage> {
    let n = view.grid;
    if maps.is_empty() || maps.iter().any(|(_, m)| m.len() != n * n) {
        return Err(ReportError::InvalidOption { name: "relief", reason: format!("need maps of {n} x {n} values") });
    }
    let mm: Vec<Vec<f32>> = maps.iter().map(|(_, m)| m.iter().map(|z| z * 1e3).collect()).collect();
    let abs: Vec<f32> = mm.iter().flatten().map(|v| v.abs()).collect();
    // The 90th percentile of |relief|: the lettering's millimetres, not the rims' centimetres, set the scale.
    let a = quantile(&abs, 0.9).unwrap_or(1.0).max(0.05);
    let norm = Norm::linear(-a, a)?;
    let ex = Extent::new(f64::from(view.x_range[0]), f64::from(view.x_range[1]))?;
    let ey = Extent::new(f64::from(view.y_range[0]), f64::from(view.y_range[1]))?;
    let (w, h) = aspect_size(ex, ey, 360);
    let mut fig = Figure::new("relief: depth minus its local mean");
    fig.notes.push(format!(
        "box of {:.0} mm; shows detail smaller than the box (e.g. lettering); grey scale +-{a:.2} mm",
        box_m * 1e3
    ));
    let count = mm.len();
    for (k, ((title, _), v)) in maps.iter().zip(&mm).enumerate() {
        let mut p = Panel::image(ScalarGrid::new(v, n, n, ex, ey)?, norm)
            .with_title(title.to_string())
            .with_labels("x (m)", "y (m)")
            .with_size(w, h)
            .with_colormap(Colormap::Grey);
        if k + 1 == count {
            p = p.with_colorbar("relief (mm)");
        }
        fig.panels.push(p);
    }
    Ok(fig.render()?)
}

/// Depth difference (metres) beyond which a pixel hit by both meshes counts as off in [`coverage_figure`].
pub const COVERAGE_TOLERANCE: f32 = 0.005;

/// Colours of the [`coverage_classes`]: hit by both within the tolerance (near white), hit by both but off
/// (orange), missed (red), extra (blue). Pixels hit by neither are drawn grey.
const COVERAGE_COLOURS: [Rgb; 4] = [Rgb::new(235, 235, 235), Rgb::new(240, 150, 20), Rgb::RED, Rgb::BLUE];

/// Classifies the pixels of a reconstruction's depth map against the ground truth's (same grid, NaN where a
/// ray hits nothing), as the coverage metric of `nlos_mesh::metrics` counts them: 0 hit by both with
/// `|z_rec − z_gt| ≤ tolerance`, 1 hit by both but further apart, 2 missed (ground truth only), 3 extra
/// (reconstruction only), NaN hit by neither. Returns the classes and the count of each.
///
/// # Panics
/// When the two maps differ in length.
pub fn coverage_classes(reconstruction: &[f32], ground_truth: &[f32], tolerance: f32) -> (Vec<f32>, [usize; 4]) {
    assert_eq!(reconstruction.len(), ground_truth.len(), "depth maps of one grid");
    let mut counts = [0usize; 4];
    let classes = reconstruction
        .iter()
        .zip(ground_truth)
        .map(|(r, g)| {
            let class = match (r.is_finite(), g.is_finite()) {
                (true, true) if (r - g).abs() <= tolerance => 0,
                (true, true) => 1,
                (false, true) => 2,
                (true, false) => 3,
                (false, false) => return f32::NAN,
            };
            counts[class] += 1;
            class as f32
        })
        .collect();
    (classes, counts)
}

/// Where each mesh covers the ground truth, on the evaluation's ray grid (`maps`: a title and the
/// metrics' depth maps of a reconstruction, `ground_truth` the ground truth's): one panel per mesh, coloured
/// by [`coverage_classes`] with [`COVERAGE_TOLERANCE`], its coverage and counts in the panel title. The
/// picture of the coverage metric: what a reconstruction misses (red) and where it adds surface the
/// ground truth does not have (blue).
///
/// # Errors
/// [`ReportError::InvalidOption`] for no map or maps that do not hold `grid²` values; drawing errors.
pub fn coverage_figure(maps: &[(&str, &[f32])], ground_truth: &[f32], view: &DepthView) -> Result<RgbImage> {
    let n = view.grid;
    if maps.is_empty() || ground_truth.len() != n * n || maps.iter().any(|(_, m)| m.len() != n * n) {
        return Err(ReportError::InvalidOption { name: "coverage", reason: format!("need maps of {n} x {n} values") });
    }
    let ex = Extent::new(f64::from(view.x_range[0]), f64::from(view.x_range[1]))?;
    let ey = Extent::new(f64::from(view.y_range[0]), f64::from(view.y_range[1]))?;
    let (w, h) = aspect_size(ex, ey, 360);
    let mut fig = Figure::new("coverage: the reconstruction against the ground truth, seen from the wall");
    fig.notes.push(format!(
        "+z rays from a {n} x {n} grid; white: hit by both within {:.0} mm; orange: hit by both, further apart",
        COVERAGE_TOLERANCE * 1e3
    ));
    fig.notes.push("red: missed (ground truth only); blue: extra (reconstruction only); grey: neither".into());
    let classes: Vec<(String, Vec<f32>)> = maps
        .iter()
        .map(|(title, m)| {
            let (c, k) = coverage_classes(m, ground_truth, COVERAGE_TOLERANCE);
            let gt = k[0] + k[1] + k[2];
            let coverage = if gt > 0 { 100.0 * (k[0] + k[1]) as f64 / gt as f64 } else { f64::NAN };
            (format!("{title}: {coverage:.1} % covered; {} missed, {} off, {} extra", k[2], k[1], k[3]), c)
        })
        .collect();
    let norm = Norm::linear(0.0, (COVERAGE_COLOURS.len() - 1) as f64)?;
    for (title, c) in &classes {
        fig.panels.push(
            Panel::image(ScalarGrid::new(c, n, n, ex, ey)?, norm)
                .with_title(title.clone())
                .with_labels("x (m)", "y (m)")
                .with_size(w, h)
                .with_interp(Interp::Nearest)
                .with_colormap(Colormap::Palette(&COVERAGE_COLOURS)),
        );
    }
    Ok(fig.render()?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_classes_follow_the_metric() {
        let nan = f32::NAN;
        let gt = [0.40, 0.40, 0.40, nan, nan, 0.40];
        let rec = [0.40, 0.404, 0.42, 0.41, nan, nan];
        let (c, k) = coverage_classes(&rec, &gt, COVERAGE_TOLERANCE);
        assert_eq!(&c[..4], &[0.0, 0.0, 1.0, 3.0]);
        assert!(c[4].is_nan());
        assert_eq!(c[5], 2.0);
        assert_eq!(k, [2, 1, 1, 1], "within, off, missed, extra");
    }

    #[test]
    fn coverage_figure_needs_maps_of_the_grid() {
        let view = DepthView { grid: 4, x_range: [-0.1, 0.1], y_range: [-0.1, 0.1] };
        let gt = vec![0.4f32; 16];
        assert!(coverage_figure(&[], &gt, &view).is_err());
        assert!(coverage_figure(&[("short", &gt[..15])], &gt, &view).is_err());
        assert!(coverage_figure(&[("ok", &gt)], &gt[..15], &view).is_err());
        let img = coverage_figure(&[("ok", &gt)], &gt, &view).expect("figure");
        assert!(img.width() > 100 && img.height() > 100);
    }

    #[test]
    fn relief_removes_a_plane_and_keeps_a_step() {
        let n = 40;
        // A tilted plane with a 2 mm bump in a 4 × 4 pixel square.
        let d: Vec<f32> = (0..n * n)
            .map(|i| {
                let (x, y) = (i % n, i / n);
                let bump = if (18..22).contains(&x) && (18..22).contains(&y) { -0.002 } else { 0.0 };
                0.4 + 0.001 * x as f32 + bump
            })
            .collect();
        let r = relief(&d, n, 6);
        // Away from the bump and the border a plane's local mean is the plane itself.
        assert!(r[10 + n * 10].abs() < 1e-5, "{}", r[10 + n * 10]);
        // On the bump: about −2 mm (less the bump's share of the box mean).
        assert!(r[20 + n * 20] < -0.0015, "{}", r[20 + n * 20]);
        let mut holes = d.clone();
        holes[0] = f32::NAN;
        assert!(relief(&holes, n, 6)[0].is_nan());
    }

    #[test]
    fn depth_range_ignores_outliers_and_widens_flat_maps() {
        let mut d = vec![0.4f32; 1000];
        d[0] = 5.0;
        d[1] = f32::NAN;
        let (lo, hi) = depth_range(&d).expect("range");
        assert!((hi - lo - 1e-3).abs() < 1e-9 && (lo - 0.3995).abs() < 1e-6);
        let ramp: Vec<f32> = (0..=100).map(|i| i as f32 * 1e-3).collect();
        let (lo, hi) = depth_range(&ramp).expect("range");
        assert!((lo - 0.002).abs() < 1e-6 && (hi - 0.095).abs() < 1e-6, "{lo} {hi}");
        assert!(depth_range(&[f32::NAN]).is_none());
    }
}
