//! Z-NLOS captures as NeTF preprocessed them (Shen et al., "Non-line-of-sight imaging via neural transient
//! fields", TPAMI 2021): a MAT v5 file per scene, the format the neural and inverse-rendering NLOS methods
//! (NeTF, NLOS-NeuS, the Gaussian and self-calibrating ones) compare on.
//!
//! # Layout
//! - `data`: T×A×B double: T time bins over an A×B wall grid (NeTF's `load_zaragoza256_data` reads it as
//!   `(L, M, N)`); a T×N array is accepted too.
//! - `cameraGridPositions`: 3×N (or 3×A×B, or N×3) wall points, N = A·B, metres. The histogram `data(:, a, b)`
//!   belongs to column **`a·B + b`** (0-based) of the positions: NeTF's preprocessing (`zaragoza_preprocess.m`)
//!   flattens the grid of positions row by row (`(i − 1)·N + j`), and its training code pairs them by
//!   `nlos_data.reshape(L, −1)` in C order. (Not MATLAB's column-major order: on the published bunny that
//!   mirrors the capture about the grid's diagonal, and its first returns no longer match the ground truth;
//!   `tests/znlos_published.rs`.)
//! - `deltaT`: the bin width as a **one-way distance** from the wall, metres (see Time). `t0` (optional,
//!   default 0; not in the published files): bin 0's start in the same unit.
//! - `cameraPosition`, `hiddenVolumePosition`, `hiddenVolumeSize` (optional): the SPAD's position, the
//!   centre and side(s) of the box that holds the hidden scene. `cameraGridSize` (optional): the side(s) of
//!   the wall's scan area, read by `super::znlos_wall`. Anything else is not needed. Every file is confocal.

//! # Axes
//! Z-NLOS walls are planes of constant y (their scenes put the hidden object at y < 0 of a wall at y = 0;
//! NeTF's bunny box is centred at y = −0.5). Ours is the plane z = 0 with the scene at z > 0. The wall's
//! coordinate is subtracted and the points turned by a proper rotation about x that sends the scene's side
//! to +z: `(x, y, z) ↦ (x, z, −y)` for a scene at y < 0 (the side is `hiddenVolumePosition`'s; without it,
//! y < 0), `(x, −z, y)` for y > 0. A wall of constant z is only moved (and turned half about x when the scene
//! is at z < 0). Distances, hence times, are unchanged; [`crate::Transient::with_grid_layout`] then lays the
//! points out as the grid they form (`crate::read` does it for every format).
//!
//! # Time
//! Bin `i` is the sphere of **radius** `i·deltaT` around its scan point: the loaders and renderers of the
//! methods that use these files compute `r = i·c·deltaT` with `c = 1`. Why: NeTF's preprocessing of the
//! dataset's HDF5 (whose bins are `deltaT` of optical path, device legs included — our Z-NLOS HDF5
//! reader) shifts each histogram by the device legs and then averages pairs of bins
//! (`(data(:,:,1:2:end) + data(:,:,2:2:end)) / 2`) while keeping `deltaT`: one bin of the file is `2·deltaT`
//! of path from the wall and back (`t = 2r`), so the time axis read here has bins of `2·deltaT` from
//! `2·t0`. On the published bunny (`deltaT` 3 mm) the first bin holding signal, about 100, is 0.30 m, the
//! ground truth's nearest depth 0.299 m; reading `deltaT` as path instead puts every surface at half its
//! depth.
//!
//! A file whose returns all begin after the farthest point of its hidden volume could return (`2 ·` the
//! largest wall-to-box distance, plus four bins) must still include the device legs (laser → wall and
//! wall → SPAD, as the dataset's HDF5 does): the time axis is then marked [`TimeAxis::includes_device_legs`]
//! with the SPAD (and, confocal, the laser) at `cameraPosition`, so that
//! [`crate::Transient::remove_device_legs`] takes them off. A direct reflection off the wall, where
//! present, stays in the data: the gate of the reconstruction removes it as for any capture.

use std::path::Path;

use glam::Vec3;

use super::v5::MatFile;
use super::{invalid, positive_scalar, wrong_shape};
use crate::error::{Result, TransientError};
use crate::scan::{PointSet, Scan};
use crate::time_axis::TimeAxis;
use crate::transient::Transient;

/// A 3-vector variable (3, 1×3 or 3×1), or None when absent.
fn vec3(m: &MatFile<'_>, file: &Path, name: &str) -> Result<Option<Vec3>> {
    if m.header(name).is_none() {
        return Ok(None);
    }
    let a = m.numeric(name, "a 3-vector in metres")?;
    // `to_f64` rejects NaN and infinities; a value beyond f32's range would still overflow.
    let v = a.to_f64(file)?;
    let &[x, y, z] = v.as_slice() else {
        return Err(wrong_shape(file, &a.header, "3 values (x, y, z)"));
    };
    let p = Vec3::new(x as f32, y as f32, z as f32);
    if !p.is_finite() {
        return Err(invalid(file, name, format!("({x}, {y}, {z}) m does not fit in f32")));
    }
    Ok(Some(p))
}

/// The map from the file's frame to ours: the wall's constant coordinate removed, the scene's side to +z.
fn frame(file: &Path, points: &[Vec3], scene: Option<Vec3>) -> Result<impl Fn(Vec3) -> Vec3 + use<>> {
    let spread = |f: fn(Vec3) -> f32| {
        let (lo, hi) =
            points.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(f(*p)), hi.max(f(*p))));
        (hi - lo, 0.5 * (hi + lo))
    };
    let ((sx, _), (sy, wy), (sz, wz)) = (spread(|p| p.x), spread(|p| p.y), spread(|p| p.z));
    let extent = sx.max(sy).max(sz);
    let flat = |s: f32| s <= 1e-4 * extent;
    let (axis, wall) = if flat(sy) {
        (1, wy)
    } else if flat(sz) {
        (2, wz)
    } else {
        return Err(TransientError::Unsupported {
            file: file.into(),
            what: format!(
                "`cameraGridPositions` that do not lie on a plane of constant y or z (spread {sx:.4}, {sy:.4}, \
                 {sz:.4} m in x, y, z); only flat walls facing along y (Z-NLOS) or z are read"
            ),
        });
    };
    // The scene's side: hiddenVolumePosition's, else Z-NLOS's (y < 0; +z for a z-wall).
    let side = match scene {
        Some(c) if axis == 1 && c.y != wall => (c.y - wall).signum(),
        Some(c) if axis == 2 && c.z != wall => (c.z - wall).signum(),
        _ if axis == 1 => -1.0,
        _ => 1.0,
    };
    Ok(move |p: Vec3| match (axis, side > 0.0) {
        (1, false) => Vec3::new(p.x, p.z, -(p.y - wall)),
        (1, true) => Vec3::new(p.x, -p.z, p.y - wall),
        (_, true) => Vec3::new(p.x, p.y, p.z - wall),
        (_, false) => Vec3::new(p.x, -p.y, -(p.z - wall)),
    })
}

/// Reads a NeTF-preprocessed Z-NLOS `.mat` (see the module docs).
pub(super) fn read(m: &MatFile<'_>, file: &Path) -> Result<Transient> {
    let d = m.numeric("data", "NeTF's Z-NLOS files hold the T×A×B histograms in `data`")?;
    // `cols`: B of a T×A×B array (data(:, a, b) is position column a·B + b), 1 for T×N.
    let (bins, n, cols) = match d.header.dims.as_slice() {
        [t, a, b] => (*t, a * b, *b),
        [t, n] => (*t, *n, 1),
        _ => return Err(wrong_shape(file, &d.header, "T×A×B (time bins × wall grid) or T×N")),
    };
    if bins == 0 || n == 0 {
        return Err(invalid(file, "data", format!("{} has no data (zero bins or wall points)", d.header.describe())));
    }
    let pos = m.numeric("cameraGridPositions", "the wall points, 3×N metres")?;
    let p = pos.to_f64(file)?;
    let dims = pos.header.dims.clone();
    let at: Box<dyn Fn(usize, usize) -> f64> =
        if dims.first() == Some(&3) && dims.iter().skip(1).product::<usize>() == n {
            Box::new(move |i: usize, c: usize| p[c + 3 * i])
        } else if dims.len() == 2 && dims[0] == n && dims[1] == 3 {
            Box::new(move |i: usize, c: usize| p[i + n * c])
        } else {
            return Err(wrong_shape(file, &pos.header, format!("3×{n} (one column per wall point of `data`)")));
        };
    let points: Vec<Vec3> = (0..n).map(|i| Vec3::new(at(i, 0) as f32, at(i, 1) as f32, at(i, 2) as f32)).collect();
    if let Some(i) = points.iter().position(|q| !q.is_finite()) {
        return Err(TransientError::NonFinite { file: file.into(), field: "cameraGridPositions".into(), index: i });
    }
    // One-way distances per bin (module docs, Time): paths of twice that.
    let delta = 2.0 * positive_scalar(m, file, "deltaT", "bin width as a distance from the wall, metres")?;
    let t0 = if m.header("t0").is_some() { 2.0 * m.numeric("t0", "bin 0's distance")?.scalar(file)? } else { 0.0 };
    if !t0.is_finite() {
        return Err(invalid(file, "t0", format!("{} must be finite (metres from the wall)", t0 / 2.0)));
    }
    let camera = vec3(m, file, "cameraPosition")?;
    let centre = vec3(m, file, "hiddenVolumePosition")?;
    let to_ours = frame(file, &points, centre)?;
    let mut data = vec![0.0f32; n * bins];
    let rows = n / cols;
    d.for_each_f32(file, |idx, v| {
        // Stored column-major: idx = k + T·(a + A·b); the histogram of position column a·B + b.
        let (k, s) = (idx % bins, idx / bins);
        let p = (s % rows) * cols + s / rows;
        if let Some(x) = data.get_mut(p * bins + k) {
            *x = v;
        }
    })?;
    let time = TimeAxis::new(t0, delta, bins).map_err(|e| super::with_file(e, file))?;
    let scan = Scan::confocal(PointSet::list(points.iter().map(|q| to_ours(*q)).collect()));
    let mut t = Transient::new(scan, time, data).map_err(|e| super::with_file(e, file))?;
    if let (Some(cam), Some(c), Some(half)) = (camera, centre, box_half(m, file)?) {
        let far = points.iter().map(|w| farthest_corner(*w, c, half)).fold(0.0f64, f64::max);
        if first_return_path(&t).is_some_and(|f| f > 2.0 * far + 4.0 * delta) {
            t.time_mut().includes_device_legs = true;
            t.scan_mut().laser_device = Some(to_ours(cam));
            t.scan_mut().sensor_device = Some(to_ours(cam));
        }
    }
    Ok(t)
}

/// The full scan grid's rectangle in our frame (`super::znlos_wall`), None without `cameraGridSize`
/// or when the points fall outside it.
pub(super) fn wall(m: &MatFile<'_>, file: &Path) -> Result<Option<[f32; 4]>> {
    if m.header("cameraGridSize").is_none() {
        return Ok(None);
    }
    let a = m.numeric("cameraGridSize", "the side(s) of the scanned wall, metres")?;
    let v = a.to_f64(file)?;
    let (sx, sy) = match v.as_slice() {
        [s] => (*s, *s),
        [x, y] => (*x, *y),
        _ => return Err(wrong_shape(file, &a.header, "1 or 2 values (the wall's sides)")),
    };
    if !(sx > 0.0 && sy > 0.0 && sx.is_finite() && sy.is_finite()) {
        return Err(invalid(file, "cameraGridSize", format!("{sx} × {sy} m: the sides must be finite and > 0")));
    }
    let t = read(m, file)?;
    let (hx, hy) = (0.5 * sx as f32, 0.5 * sy as f32);
    let slack = 1e-3 * hx.max(hy);
    let inside = t.scan().sensors().points.iter().all(|p| p.x.abs() <= hx + slack && p.y.abs() <= hy + slack);
    Ok(inside.then_some([-hx, hx, -hy, hy]))
}

/// Half the side(s) of the hidden volume (`hiddenVolumeSize`: one side or three), None when absent.
fn box_half(m: &MatFile<'_>, file: &Path) -> Result<Option<Vec3>> {
    if m.header("hiddenVolumeSize").is_none() {
        return Ok(None);
    }
    let a = m.numeric("hiddenVolumeSize", "the hidden volume's side(s), metres")?;
    let v = a.to_f64(file)?;
    let half = match v.as_slice() {
        [s] => Vec3::splat(*s as f32 * 0.5),
        [x, y, z] => Vec3::new(*x as f32, *y as f32, *z as f32) * 0.5,
        _ => return Err(wrong_shape(file, &a.header, "1 or 3 values")),
    };
    if !(half.is_finite() && half.min_element() >= 0.0) {
        return Err(invalid(file, "hiddenVolumeSize", format!("{} must be finite and ≥ 0", half * 2.0)));
    }
    Ok(Some(half))
}

/// The largest distance from wall point `w` to a corner of the box (centre `c`, half sides `half`).
fn farthest_corner(w: Vec3, c: Vec3, half: Vec3) -> f64 {
    let d = (w - c).abs() + half;
    f64::from(d.length())
}

/// Path length at which the summed histogram first reaches a tenth of its maximum.
fn first_return_path(t: &Transient) -> Option<f64> {
    let sum = t.summed_histogram();
    let peak = sum.iter().copied().fold(0.0f64, f64::max);
    (peak > 0.0).then(|| t.time().bin_start(sum.iter().position(|&s| s >= 0.1 * peak).unwrap_or(0)))
}
