//! Scan geometry: where the laser and the sensor looked on the relay wall.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::{MEMORY, Result, TransientError};

/// How the points of a [`PointSet`] are arranged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Layout {
    /// A regular grid of `nx × ny` points stored with x fastest: point `ix + nx·iy`.
    Grid {
        /// Points along the first (x) axis.
        nx: usize,
        /// Points along the second (y) axis.
        ny: usize,
    },
    /// An unstructured list of points.
    List,
}

/// A set of points on the relay wall with their wall normals.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointSet {
    /// Positions, metres.
    pub points: Vec<Vec3>,
    /// Unit wall normals, one per point.
    pub normals: Vec<Vec3>,
    /// Arrangement of the points.
    pub layout: Layout,
}

impl PointSet {
    /// A grid of `nx × ny` points with normal +z on the wall z = 0, x and y each running over
    /// `linspace(-half_width, half_width, n)` (the Stanford LCT convention).
    ///
    /// # Errors
    /// [`TransientError::InvalidValue`] for a zero-sized grid or a non-finite or negative half width.
    pub fn wall_grid(nx: usize, ny: usize, half_width_x: f64, half_width_y: f64) -> Result<Self> {
        if nx == 0 || ny == 0 {
            return Err(invalid("grid", format!("{nx} × {ny} grid has no points")));
        }
        for (name, w) in [("half_width_x", half_width_x), ("half_width_y", half_width_y)] {
            if !(w.is_finite() && w >= 0.0) {
                return Err(invalid(name, format!("{w} must be finite and >= 0 metres")));
            }
        }
        let lin = |i: usize, n: usize, w: f64| if n == 1 { 0.0 } else { -w + 2.0 * w * i as f64 / (n - 1) as f64 };
        let mut points = Vec::with_capacity(nx * ny);
        for iy in 0..ny {
            for ix in 0..nx {
                points.push(Vec3::new(lin(ix, nx, half_width_x) as f32, lin(iy, ny, half_width_y) as f32, 0.0));
            }
        }
        Ok(Self { normals: vec![Vec3::Z; points.len()], points, layout: Layout::Grid { nx, ny } })
    }

    /// The grid a [`Layout::List`] forms, if any: `Some((nx, ny, x_fastest))` when the points lie on one
    /// plane `z = const` with one normal, on an axis-aligned regular grid of at least 2 × 2 points, in row
    /// order (`x_fastest`: index `ix + nx·iy`, as [`Layout::Grid`]) or column order (`iy + ny·ix`). Positions
    /// may be off by 1 % of a spacing (the precision of decimal files). A [`Layout::Grid`] gives its own
    /// dimensions.
    pub fn regular_grid(&self) -> Option<(usize, usize, bool)> {
        if let Layout::Grid { nx, ny } = self.layout {
            return Some((nx, ny, true));
        }
        let p = &self.points;
        let n = p.len();
        if n < 4 || self.normals.iter().any(|m| *m != self.normals[0]) {
            return None;
        }
        // The first run of points along one axis gives the fast dimension.
        for x_fastest in [true, false] {
            let fast = |v: Vec3| if x_fastest { v.x } else { v.y };
            let slow = |v: Vec3| if x_fastest { v.y } else { v.x };
            let step = fast(p[1]) - fast(p[0]);
            if step == 0.0 || !step.is_finite() || (slow(p[1]) - slow(p[0])).abs() > 0.01 * step.abs() {
                continue;
            }
            let run = p.iter().position(|q| (slow(*q) - slow(p[0])).abs() > 0.01 * step.abs()).unwrap_or(n);
            if run < 2 || !n.is_multiple_of(run) || n / run < 2 {
                continue;
            }
            let rows = n / run;
            let slow_step = slow(p[run]) - slow(p[0]);
            let tol = 0.01 * step.abs().min(slow_step.abs());
            let regular = slow_step.abs() > 0.0
                && p.iter().enumerate().all(|(i, q)| {
                    let (i_fast, i_slow) = ((i % run) as f32, (i / run) as f32);
                    (fast(*q) - (fast(p[0]) + i_fast * step)).abs() <= tol
                        && (slow(*q) - (slow(p[0]) + i_slow * slow_step)).abs() <= tol
                        && (q.z - p[0].z).abs() <= tol
                });
            if regular {
                return Some(if x_fastest { (run, rows, true) } else { (rows, run, false) });
            }
        }
        None
    }

    /// A list of points, all with wall normal +z.
    pub fn list(points: Vec<Vec3>) -> Self {
        Self { normals: vec![Vec3::Z; points.len()], points, layout: Layout::List }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// `(nx, ny)` when the layout is a grid.
    pub fn grid_dims(&self) -> Option<(usize, usize)> {
        match self.layout {
            Layout::Grid { nx, ny } => Some((nx, ny)),
            Layout::List => None,
        }
    }

    /// The spacing `(dx, dy)` of a [`Layout::Grid`] (metres): its extent along each axis over the gaps
    /// between its points (0 along an axis of one point); `None` for a list or an empty set.
    pub fn grid_spacing(&self) -> Option<(f64, f64)> {
        let (nx, ny) = self.grid_dims()?;
        let (lo, hi) = self.bounds()?;
        let step = |lo: f32, hi: f32, n: usize| if n > 1 { f64::from(hi - lo) / (n - 1) as f64 } else { 0.0 };
        Some((step(lo.x, hi.x, nx), step(lo.y, hi.y, ny)))
    }

    /// The lateral spacing of the points (metres): a [`Layout::Grid`]'s larger step, or for a list the side
    /// of the square each point covers in the points' bounding box in x and y (`√(area / n)`; a regular grid
    /// written as a list gets its step back, up to the `n/(n−1)` of its edges). `None` for a set of fewer
    /// than two points or one on a line.
    pub fn spacing(&self) -> Option<f64> {
        if let Some((dx, dy)) = self.grid_spacing() {
            return Some(dx.max(dy)).filter(|s| *s > 0.0);
        }
        let (lo, hi) = self.bounds()?;
        let area = f64::from(hi.x - lo.x) * f64::from(hi.y - lo.y);
        (self.len() >= 2 && area > 0.0).then(|| (area / self.len() as f64).sqrt())
    }

    /// Axis-aligned bounds `(min, max)` of the points; `None` when empty.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.points.first()?;
        Some(self.points.iter().fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
    }

    /// Checks that normals match points, the grid size matches, every value is finite and normals are unit.
    ///
    /// # Errors
    /// [`TransientError::WrongShape`], [`TransientError::NonFinite`] or [`TransientError::InvalidValue`]
    /// naming `field`.
    pub fn validate(&self, field: &str) -> Result<()> {
        if self.points.is_empty() {
            return Err(invalid(field, "no points (zero-sized scan)".into()));
        }
        if self.normals.len() != self.points.len() {
            return Err(TransientError::WrongShape {
                file: MEMORY.into(),
                field: format!("{field}.normals"),
                expected: format!("{} normals (one per point)", self.points.len()),
                found: format!("{}", self.normals.len()),
            });
        }
        if let Layout::Grid { nx, ny } = self.layout
            && nx.checked_mul(ny) != Some(self.points.len())
        {
            return Err(TransientError::WrongShape {
                file: MEMORY.into(),
                field: field.into(),
                expected: format!("{nx} × {ny} grid points"),
                found: format!("{}", self.points.len()),
            });
        }
        if let Some(i) = self.points.iter().position(|p| !p.is_finite()) {
            return Err(TransientError::NonFinite { file: MEMORY.into(), field: format!("{field}.points"), index: i });
        }
        if let Some(i) = self.normals.iter().position(|n| !n.is_finite() || (n.length() - 1.0).abs() > 1e-3) {
            return Err(invalid(
                &format!("{field}.normals"),
                format!("normal {i} = {:?} is not a finite unit vector", self.normals[i]),
            ));
        }
        Ok(())
    }

    /// The points `kept` (in that order, indices checked by the caller) as a list.
    pub(crate) fn pick(&self, kept: &[usize]) -> Self {
        Self {
            points: kept.iter().map(|&i| self.points[i]).collect(),
            normals: kept.iter().map(|&i| self.normals[i]).collect(),
            layout: Layout::List,
        }
    }

    /// The points of a sub-grid taking every `step_x`-th column and `step_y`-th row (grids only), and the
    /// indices of the kept points.
    pub(crate) fn subsample(&self, step_x: usize, step_y: usize) -> Option<(Self, Vec<usize>)> {
        let (nx, ny) = self.grid_dims()?;
        let kept: Vec<usize> =
            (0..ny).step_by(step_y).flat_map(|iy| (0..nx).step_by(step_x).map(move |ix| ix + nx * iy)).collect();
        let sub =
            Self { layout: Layout::Grid { nx: nx.div_ceil(step_x), ny: ny.div_ceil(step_y) }, ..self.pick(&kept) };
        Some((sub, kept))
    }
}

/// Which laser spot goes with which sensor spot: confocal, exhaustive or paired.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ScanPattern {
    /// The laser spot and the sensor spot coincide: one measurement per point.
    Confocal(PointSet),
    /// Every laser point with every sensor point: measurement `m = il · n_sensors + is`.
    Exhaustive {
        /// Laser spots on the wall.
        lasers: PointSet,
        /// Sensor spots on the wall.
        sensors: PointSet,
    },
    /// Measurement `m` lights laser spot `m` and records at sensor spot `m` (two galvos, or a SPAD and a
    /// laser on separate mirrors, as in "Non-line-of-sight imaging with irregular relay surfaces"). The two
    /// sets have the same length; neither needs to be a grid or lie on a plane.
    Paired {
        /// Laser spot of each measurement.
        lasers: PointSet,
        /// Sensor spot of each measurement.
        sensors: PointSet,
    },
}

/// The kind of a [`ScanPattern`], by the name the file formats and the Python package use for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PatternKind {
    /// [`ScanPattern::Confocal`]: `confocal`.
    Confocal,
    /// [`ScanPattern::Exhaustive`]: `exhaustive`.
    Exhaustive,
    /// [`ScanPattern::Paired`]: `paired`.
    Paired,
}

impl PatternKind {
    /// Every kind, in the order of [`ScanPattern`].
    pub const ALL: [Self; 3] = [Self::Confocal, Self::Exhaustive, Self::Paired];

    /// The name: `confocal`, `exhaustive` or `paired`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Confocal => "confocal",
            Self::Exhaustive => "exhaustive",
            Self::Paired => "paired",
        }
    }
}

impl std::fmt::Display for PatternKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is no [`PatternKind`]'s (its message names the three).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0:?} is not \"confocal\", \"exhaustive\" or \"paired\"")]
pub struct UnknownPattern(pub String);

impl std::str::FromStr for PatternKind {
    type Err = UnknownPattern;

    /// Parses a name of [`PatternKind::name`].
    ///
    /// # Errors
    /// [`UnknownPattern`] for any other.
    fn from_str(s: &str) -> std::result::Result<Self, UnknownPattern> {
        Self::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| UnknownPattern(s.to_owned()))
    }
}

impl ScanPattern {
    /// The pattern's kind.
    pub fn kind(&self) -> PatternKind {
        match self {
            Self::Confocal(_) => PatternKind::Confocal,
            Self::Exhaustive { .. } => PatternKind::Exhaustive,
            Self::Paired { .. } => PatternKind::Paired,
        }
    }
}

/// Scan geometry: the pattern of wall points plus optional device positions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scan {
    /// Wall points.
    pub pattern: ScanPattern,
    /// Position of the laser device (the start of the first leg), if known.
    pub laser_device: Option<Vec3>,
    /// Position of the sensor device (the end of the last leg), if known.
    pub sensor_device: Option<Vec3>,
}

impl Scan {
    /// A confocal scan over `points`, device positions unknown.
    pub fn confocal(points: PointSet) -> Self {
        Self { pattern: ScanPattern::Confocal(points), laser_device: None, sensor_device: None }
    }

    /// An exhaustive scan, device positions unknown.
    pub fn exhaustive(lasers: PointSet, sensors: PointSet) -> Self {
        Self { pattern: ScanPattern::Exhaustive { lasers, sensors }, laser_device: None, sensor_device: None }
    }

    /// A paired scan (measurement `m` = laser spot `m` with sensor spot `m`), device positions unknown.
    /// [`Scan::validate`] checks that the two sets have the same length.
    pub fn paired(lasers: PointSet, sensors: PointSet) -> Self {
        Self { pattern: ScanPattern::Paired { lasers, sensors }, laser_device: None, sensor_device: None }
    }

    /// The pattern's name as the file formats write it: `confocal`, `exhaustive` or `paired`.
    pub fn pattern_name(&self) -> &'static str {
        self.pattern.kind().name()
    }

    /// Whether laser and sensor spots coincide.
    pub fn is_confocal(&self) -> bool {
        matches!(self.pattern, ScanPattern::Confocal(_))
    }

    /// Number of measurements (histograms).
    pub fn measurements(&self) -> usize {
        match &self.pattern {
            ScanPattern::Confocal(p) => p.len(),
            ScanPattern::Exhaustive { lasers, sensors } => lasers.len() * sensors.len(),
            ScanPattern::Paired { lasers, .. } => lasers.len(),
        }
    }

    /// The laser points (the scan points when confocal).
    pub fn lasers(&self) -> &PointSet {
        match &self.pattern {
            ScanPattern::Confocal(p) => p,
            ScanPattern::Exhaustive { lasers, .. } | ScanPattern::Paired { lasers, .. } => lasers,
        }
    }

    /// The sensor points (the scan points when confocal).
    pub fn sensors(&self) -> &PointSet {
        match &self.pattern {
            ScanPattern::Confocal(p) => p,
            ScanPattern::Exhaustive { sensors, .. } | ScanPattern::Paired { sensors, .. } => sensors,
        }
    }

    /// Whether the laser spots outnumber the sensor spots (several lasers seen by one sensor spot; never on a
    /// confocal or paired scan, whose sets have one length).
    pub fn lasers_are_dense(&self) -> bool {
        self.lasers().len() > self.sensors().len()
    }

    /// The denser of the laser and sensor sets ([`Scan::lasers_are_dense`]; the sensors on a tie): the points
    /// that resolve the scene laterally — the scan points of a confocal scan, the sensor grid of a one-laser
    /// capture, the laser spots of a paired scan.
    pub fn dense_points(&self) -> &PointSet {
        if self.lasers_are_dense() { self.lasers() } else { self.sensors() }
    }

    /// `(laser index, sensor index)` of measurement `m`.
    ///
    /// # Panics
    /// When `m >= self.measurements()`.
    pub fn indices(&self, m: usize) -> (usize, usize) {
        assert!(m < self.measurements(), "measurement {m} out of range");
        match &self.pattern {
            ScanPattern::Confocal(_) | ScanPattern::Paired { .. } => (m, m),
            ScanPattern::Exhaustive { sensors, .. } => (m / sensors.len(), m % sensors.len()),
        }
    }

    /// Laser spot, laser wall normal, sensor spot and sensor wall normal of measurement `m`.
    ///
    /// # Panics
    /// When `m >= self.measurements()`.
    pub fn measurement(&self, m: usize) -> Measurement {
        let (il, is) = self.indices(m);
        let (l, s) = (self.lasers(), self.sensors());
        Measurement {
            laser: l.points[il],
            laser_normal: l.normals[il],
            sensor: s.points[is],
            sensor_normal: s.normals[is],
        }
    }

    /// Checks every point set and the device positions.
    ///
    /// # Errors
    /// As [`PointSet::validate`]; [`TransientError::NonFinite`] for a non-finite device position.
    pub fn validate(&self) -> Result<()> {
        match &self.pattern {
            ScanPattern::Confocal(p) => p.validate("scan_points")?,
            ScanPattern::Exhaustive { lasers, sensors } => {
                lasers.validate("laser_points")?;
                sensors.validate("sensor_points")?;
                on_the_grid_plane(lasers, "laser_points", sensors, "sensor grid")?;
                on_the_grid_plane(sensors, "sensor_points", lasers, "laser grid")?;
            }
            ScanPattern::Paired { lasers, sensors } => {
                lasers.validate("laser_points")?;
                sensors.validate("sensor_points")?;
                if lasers.len() != sensors.len() {
                    return Err(TransientError::WrongShape {
                        file: MEMORY.into(),
                        field: "sensor_points".into(),
                        expected: format!("{} points (one per laser point: a paired scan)", lasers.len()),
                        found: format!("{}", sensors.len()),
                    });
                }
                on_the_relay_surface(lasers, sensors)?;
            }
        }
        for (field, d) in [("laser_device", self.laser_device), ("sensor_device", self.sensor_device)] {
            if d.is_some_and(|d| !d.is_finite()) {
                return Err(TransientError::NonFinite { file: MEMORY.into(), field: field.into(), index: 0 });
            }
        }
        Ok(())
    }
}

/// How far (metres) a spot may lie off the plane of the other set's grid: the relay wall's own roughness and
/// calibration error, far below any hidden object's depth.
pub const MAX_OFF_WALL: f32 = 0.02;

/// Checks that every point of `points` lies within [`MAX_OFF_WALL`] of the plane of `grid` when `grid` is a
/// grid (a grid lies in one plane of constant z; a list, a curved wall, is not checked).
fn on_the_grid_plane(points: &PointSet, field: &str, grid: &PointSet, grid_name: &str) -> Result<()> {
    if !matches!(grid.layout, Layout::Grid { .. }) || grid.is_empty() {
        return Ok(());
    }
    let plane = grid.points.iter().map(|p| p.z).sum::<f32>() / grid.len() as f32;
    match points.points.iter().enumerate().find(|(_, p)| (p.z - plane).abs() > MAX_OFF_WALL) {
        Some((i, p)) => Err(invalid(
            field,
            format!(
                "spot {i} at z = {} m lies {:.3} m off the plane of the {grid_name} (z = {plane} m); laser and \
                 sensor spots lie on the relay wall: give both in the same frame (metres, wall at z = 0)",
                p.z,
                (p.z - plane).abs()
            ),
        )),
        None => Ok(()),
    }
}

/// How far (metres) a spot of a paired scan may lie from the least-squares plane of all its spots, at the
/// least: a curved relay surface bends a few centimetres (the general-NLOS wall: −1.7 … +2.9 cm over 1.5 m).
/// The limit grows with the scan (a tenth of its extent), so that large curved walls are accepted.
pub const MAX_OFF_PLANE: f32 = 0.1;

/// Checks that every spot of a paired scan lies on the relay surface: within [`MAX_OFF_PLANE`] (or a tenth
/// of the scan's extent) of the least-squares plane through all spots, and that each wall normal faces the
/// side of the hidden scene (`n·ẑ > 0`, the wall seen from the scene). A spot further off is a point in the
/// hidden volume or behind the wall, usually a unit (mm for m) or axis mistake.
fn on_the_relay_surface(lasers: &PointSet, sensors: &PointSet) -> Result<()> {
    let all: Vec<Vec3> = lasers.points.iter().chain(&sensors.points).copied().collect();
    let fit = fit_plane(&all);
    let (lo, hi) = all.iter().fold((all[0], all[0]), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let extent = (hi - lo).truncate().max_element();
    let limit = MAX_OFF_PLANE.max(0.1 * extent);
    for (set, field) in [(lasers, "laser_points"), (sensors, "sensor_points")] {
        if let Some((i, (p, d))) =
            set.points.iter().map(|p| (p, fit.distance(*p))).enumerate().find(|(_, (_, d))| d.abs() > limit)
        {
            let side = if d > 0.0 { "in front of the wall, in the hidden volume" } else { "behind the wall" };
            return Err(invalid(
                field,
                format!(
                    "spot {i} at {p:?} lies {:.3} m {side} (the plane through all spots, z = {:.3} m at its centre; \
                     at most {limit:.3} m allowed); laser and sensor spots lie on the relay surface: give both in \
                     the same frame (metres, wall near z = 0, hidden scene at z > 0)",
                    d.abs(),
                    fit.centre.z
                ),
            ));
        }
        if let Some(i) = set.normals.iter().position(|n| n.z <= 0.0) {
            return Err(invalid(
                &format!("{field}.normals"),
                format!(
                    "normal {i} = {:?} faces away from the hidden scene (z > 0); the wall normal at a spot points \
                     into the hidden scene",
                    set.normals[i]
                ),
            ));
        }
    }
    Ok(())
}

/// A plane through `centre` with unit normal `normal` (`normal.z ≥ 0`).
struct Plane {
    centre: Vec3,
    normal: Vec3,
}

impl Plane {
    /// Signed distance along the normal (positive on the hidden scene's side).
    fn distance(&self, p: Vec3) -> f32 {
        (p - self.centre).dot(self.normal)
    }
}

/// The least-squares plane `z = a + b·x + c·y` through `points` (a wall is never vertical in this frame); the
/// plane `z = mean` when the points are collinear.
fn fit_plane(points: &[Vec3]) -> Plane {
    let n = points.len() as f64;
    let c = points.iter().fold(glam::DVec3::ZERO, |a, p| a + p.as_dvec3()) / n;
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let d = p.as_dvec3() - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
        sxz += d.x * d.z;
        syz += d.y * d.z;
    }
    let det = sxx * syy - sxy * sxy;
    let (b, cc) = if det.abs() > 1e-12 * (sxx * syy).max(1e-30) {
        ((sxz * syy - syz * sxy) / det, (syz * sxx - sxz * sxy) / det)
    } else {
        (0.0, 0.0)
    };
    let normal = glam::DVec3::new(-b, -cc, 1.0).normalize();
    Plane { centre: c.as_vec3(), normal: normal.as_vec3() }
}

/// The wall geometry of one measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Laser spot `l` on the wall.
    pub laser: Vec3,
    /// Wall normal at `l`.
    pub laser_normal: Vec3,
    /// Sensor spot `s` on the wall.
    pub sensor: Vec3,
    /// Wall normal at `s`.
    pub sensor_normal: Vec3,
}

fn invalid(field: &str, reason: String) -> TransientError {
    TransientError::InvalidValue { file: MEMORY.into(), field: field.into(), reason }
}
