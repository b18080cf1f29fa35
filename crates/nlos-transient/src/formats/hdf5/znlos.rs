//! Zaragoza Z-NLOS HDF5 (Galindo, Marco, Jarabo, Gutierrez et al., "A dataset for benchmarking
//! time-resolved non-line-of-sight imaging", <https://graphics.unizar.es/nlos_dataset/>).
//!
//! Sources for the layout (no specification is published; these are the dataset's own and the most used
//! readers): the dataset's MATLAB class `NLOSData.m` and C++ loader (`DatasetLoader`, `NLOSData`), y-tal's
//! converter `tal/io/format.py` (`__convert_dict_znlos_to_tal`), and TOTRI's `ZaragozaDataset`.
//!
//! - Field names (new, then old): `data`; `deltaT`/`deltat`; `t0`; `cameraGridPositions`/`cameraPos`;
//!   `cameraGridNormals`/`cameraNormal`; `cameraPosition`/`cameraOrigin`; `cameraGridPoints` (grid
//!   counts); `laserGridPositions`/`laserPos`; `laserGridNormals`/`laserNorm`;
//!   `laserPosition`/`laserOrigin`; `laserGridPoints`; `isConfocal`. `cameraGridSize`, `laserGridSize`,
//!   `hiddenVolume*` and `t` are not needed.
//! - Array order: the files are written column-major, so in HDF5 (C order) `data` is
//!   `(channels, T, bounces, camera grid…, laser grid…)` and grid positions `(3, grid…)`. A root attribute
//!   `data order = "row-major"` marks files with every dimension reversed; they are read through the
//!   reversed view. The leading dimensions are `(T)`, `(T, bounces)` or `(channels, T, bounces)`;
//!   channels and bounces are **summed** (as `NLOSData(…, 'bounces', 'sum')` and y-tal do: the first
//!   bounce slot is empty in rendered data, so this is the sum of every indirect bounce).
//! - Exhaustive data hold the camera grid dimensions before the laser grid's (y-tal's reading). When the
//!   shapes only fit the other order (`NLOSData.m`'s reading), that order is used; for grids of equal
//!   shape y-tal's order is assumed.
//! - Grid: the grid dimensions of the positions are those of the data; our point `p` is the C-order flat
//!   index over them (last dimension fastest), so a 2-D grid `(A, B)` becomes [`Layout::Grid`]
//!   `{nx: B, ny: A}`. Positions stored as a flat list `(3, N)` become a grid of `cameraGridPoints`
//!   (`[fastest, slowest]` counts, TOTRI's reading) when those multiply to `N`, else a list.
//! - Confocal: `isConfocal` when present, else the laser grid equals the camera grid.
//! - Time: `deltaT` and `t0` are metres of optical path, and the times **include** the first and last
//!   legs (laser → wall, wall → SPAD): [`TimeAxis::includes_device_legs`] is set and the device
//!   positions come from `laserPosition` / `cameraPosition`, so [`Transient::remove_device_legs`] works.
//! - Frame: Z-NLOS scenes put the relay wall in a plane of constant y (its grids span x and z; TOTRI
//!   rotates them with `(x, z, −y)`). When every wall normal is along ±y, points, normals and device
//!   positions are rotated by ±90° about x so that the normals become +z (our convention: wall z = 0,
//!   hidden scene at z > 0). Distances, and so times, are unchanged.
//!
//! [`Layout::Grid`]: crate::Layout::Grid
//! [`TimeAxis::includes_device_legs`]: crate::TimeAxis::includes_device_legs
//! [`Transient::remove_device_legs`]: crate::Transient::remove_device_legs

use glam::Vec3;

use super::{H5, attr_text, shape_str};
use crate::error::{Result, TransientError};
use crate::scan::{Layout, PointSet, Scan, ScanPattern};
use crate::time_axis::TimeAxis;
use crate::transient::Transient;

/// An N-d array seen in the canonical (column-major-written) order: `shape` and the strides into the
/// stored flat buffer.
struct View {
    shape: Vec<usize>,
    strides: Vec<usize>,
}

impl View {
    fn new(stored: &[usize], reversed: bool) -> Self {
        let mut strides = vec![1usize; stored.len()];
        for i in (0..stored.len().saturating_sub(1)).rev() {
            strides[i] = strides[i + 1].saturating_mul(stored[i + 1]);
        }
        let mut shape = stored.to_vec();
        if reversed {
            shape.reverse();
            strides.reverse();
        }
        Self { shape, strides }
    }
}

/// Flat C-order index `p` over `dims` → offset with `strides`.
fn offset(p: usize, dims: &[usize], strides: &[usize]) -> usize {
    let mut rest = p;
    let mut off = 0usize;
    for (d, s) in dims.iter().zip(strides).rev() {
        if *d > 0 {
            off = off.saturating_add((rest % d).saturating_mul(*s));
            rest /= d;
        }
    }
    off
}

struct Points {
    /// Grid dimensions as they appear in `data` (C order).
    dims: Vec<usize>,
    set: PointSet,
}

fn read_points(h: &H5<'_>, reversed: bool, who: &str, names: [&[&str]; 3]) -> Result<Points> {
    let file = h.path();
    let [pos_names, nrm_names, count_names] = names;
    let pos_name = h.first_of(pos_names).ok_or_else(|| TransientError::MissingField {
        file: file.into(),
        field: pos_names[0].into(),
        hint: format!("Z-NLOS files hold the {who} spots on the wall in `{}`", pos_names.join("` or `")),
    })?;
    let pos = h.f64_array(pos_name, "")?;
    let v = View::new(&pos.shape, reversed);
    let (dims, coord_stride, grid_strides) = match v.shape.as_slice() {
        [3] => (vec![], v.strides[0], vec![]),
        [3, rest @ ..] => (rest.to_vec(), v.strides[0], v.strides[1..].to_vec()),
        [rest @ .., 3] => (rest.to_vec(), v.strides[v.shape.len() - 1], v.strides[..rest.len()].to_vec()),
        _ => {
            return Err(TransientError::WrongShape {
                file: file.into(),
                field: pos_name.into(),
                expected: "(3, grid…) or (grid…, 3) positions".into(),
                found: shape_str(&pos.shape),
            });
        }
    };
    let n: usize = dims.iter().product();
    if n == 0 {
        return Err(TransientError::InvalidValue {
            file: file.into(),
            field: pos_name.into(),
            reason: format!("zero-sized grid {}", shape_str(&pos.shape)),
        });
    }
    let get = |vals: &[f64], p: usize| {
        let o = offset(p, &dims, &grid_strides);
        let c = |j: usize| vals.get(o + j * coord_stride).copied().unwrap_or(f64::NAN) as f32;
        Vec3::new(c(0), c(1), c(2))
    };
    let points: Vec<Vec3> = (0..n).map(|p| get(&pos.values, p)).collect();
    let normals = match h.first_of(nrm_names) {
        Some(name) => {
            let a = h.f64_array(name, "")?;
            if a.values.len() != pos.values.len() || View::new(&a.shape, reversed).shape != v.shape {
                return Err(TransientError::WrongShape {
                    file: file.into(),
                    field: name.into(),
                    expected: format!("{} (as `{pos_name}`)", shape_str(&pos.shape)),
                    found: shape_str(&a.shape),
                });
            }
            (0..n).map(|p| get(&a.values, p)).collect()
        }
        None => vec![Vec3::Z; n],
    };
    let mut layout = match dims.as_slice() {
        [a, b] => Layout::Grid { nx: *b, ny: *a },
        _ => Layout::List,
    };
    if let (1, Some(c)) = (dims.len(), h.first_of(count_names)) {
        let counts = h.f64_array(c, "")?.values;
        if let [fast, slow] = counts.as_slice() {
            let (nx, ny) = (*fast as usize, *slow as usize);
            if nx as f64 == *fast && ny as f64 == *slow && nx.checked_mul(ny) == Some(n) {
                layout = Layout::Grid { nx, ny };
            }
        }
    }
    Ok(Points { dims, set: PointSet { points, normals, layout } })
}

fn device(h: &H5<'_>, names: &[&str]) -> Result<Option<Vec3>> {
    let Some(name) = h.first_of(names) else { return Ok(None) };
    let a = h.f64_array(name, "")?;
    match a.values.as_slice() {
        [x, y, z] => Ok(Some(Vec3::new(*x as f32, *y as f32, *z as f32))),
        _ => Err(TransientError::WrongShape {
            file: h.path().into(),
            field: name.into(),
            expected: "3 values (a device position)".into(),
            found: shape_str(&a.shape),
        }),
    }
}

/// Rotation taking the wall normal `±y` to `+z` (a proper rotation about x), when every normal is along
/// ±y.
fn frame_rotation(sets: &[&PointSet]) -> Option<fn(Vec3) -> Vec3> {
    let normals = || sets.iter().flat_map(|s| s.normals.iter());
    if normals().all(|n| n.y < -0.99) {
        Some(|v: Vec3| Vec3::new(v.x, v.z, -v.y))
    } else if normals().all(|n| n.y > 0.99) {
        Some(|v: Vec3| Vec3::new(v.x, -v.z, v.y))
    } else {
        None
    }
}

pub(super) fn read(h: &H5<'_>) -> Result<Transient> {
    let file = h.path();
    let reversed = h.root_attrs().get("data order").and_then(attr_text).is_some_and(|s| s.trim() == "row-major");
    let camera = read_points(
        h,
        reversed,
        "camera (SPAD)",
        [&["cameraGridPositions", "cameraPos"], &["cameraGridNormals", "cameraNormal"], &["cameraGridPoints"]],
    )?;
    let laser = read_points(
        h,
        reversed,
        "laser",
        [&["laserGridPositions", "laserPos"], &["laserGridNormals", "laserNorm"], &["laserGridPoints"]],
    )?;
    let confocal = if h.has("isConfocal") {
        h.scalar("isConfocal", "")? != 0.0
    } else {
        camera.set.len() == laser.set.len()
            && camera.set.points.iter().zip(&laser.set.points).all(|(a, b)| (*a - *b).abs().max_element() <= 1e-3)
    };
    let (shape, values) = h.f32_array("data", "Z-NLOS files hold the histograms in `data`")?;
    let view = View::new(&shape, reversed);
    // Trailing grid dimensions: camera (confocal), camera then laser, or laser then camera.
    let candidates: Vec<(Vec<usize>, bool)> = if confocal {
        vec![(camera.dims.clone(), false)]
    } else {
        let cl = [camera.dims.clone(), laser.dims.clone()].concat();
        let lc = [laser.dims.clone(), camera.dims.clone()].concat();
        vec![(cl, false), (lc, true)]
    };
    let fits = |g: &[usize]| {
        let r = view.shape.len();
        r > g.len() && r - g.len() <= 3 && view.shape[r - g.len()..] == *g
    };
    let Some((grid_dims, laser_first)) = candidates.into_iter().find(|(g, _)| fits(g)) else {
        return Err(TransientError::WrongShape {
            file: file.into(),
            field: "data".into(),
            expected: format!(
                "(channels?, T, bounces?, {}) for a {} scan{}",
                if confocal { "camera grid" } else { "camera grid, laser grid" },
                if confocal { "confocal" } else { "exhaustive" },
                if reversed { " (row-major file, dimensions reversed)" } else { "" }
            ),
            found: shape_str(&shape),
        });
    };
    let lead = view.shape.len() - grid_dims.len();
    let (t_axis, sum_axes): (usize, Vec<usize>) = match lead {
        1 => (0, vec![]),
        2 => (0, vec![1]),
        _ => (1, vec![0, 2]),
    };
    let bins = view.shape[t_axis];
    if bins == 0 {
        return Err(TransientError::InvalidValue {
            file: file.into(),
            field: "data".into(),
            reason: "no time bins".into(),
        });
    }
    let n_s = camera.set.len();
    let n_l = if confocal { 1 } else { laser.set.len() };
    let (sum_dims, sum_strides): (Vec<usize>, Vec<usize>) =
        sum_axes.iter().map(|&a| (view.shape[a], view.strides[a])).unzip();
    let n_sum: usize = sum_dims.iter().product();
    let grid_strides = &view.strides[lead..];
    let mut data = vec![0.0f32; n_l * n_s * bins];
    for il in 0..n_l {
        for is in 0..n_s {
            // C-order flat index over the trailing grid dimensions.
            let g = if confocal {
                is
            } else if laser_first {
                is + n_s * il
            } else {
                il + n_l * is
            };
            let base = offset(g, &grid_dims, grid_strides);
            let m = il * n_s + is;
            for k in 0..bins {
                let at = base.saturating_add(k.saturating_mul(view.strides[t_axis]));
                let mut acc = 0.0f64;
                for j in 0..n_sum {
                    let o = at.saturating_add(offset(j, &sum_dims, &sum_strides));
                    acc += f64::from(values.get(o).copied().unwrap_or(f32::NAN));
                }
                data[m * bins + k] = acc as f32;
            }
        }
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(TransientError::NonFinite { file: file.into(), field: "data".into(), index: i });
    }
    let delta_name = h.first_of(&["deltaT", "deltat"]).unwrap_or("deltaT");
    let delta_t = h.finite_scalar(delta_name, "bin width in metres of optical path")?;
    let t0 = h.finite_scalar("t0", "path length at the start of bin 0, metres")?;
    let time = TimeAxis { t0, bin_width: delta_t, bins, includes_device_legs: true };
    if delta_t <= 0.0 {
        return Err(TransientError::InvalidValue {
            file: file.into(),
            field: delta_name.into(),
            reason: format!("{delta_t} must be > 0 metres"),
        });
    }
    let mut sensor_device = device(h, &["cameraPosition", "cameraOrigin"])?;
    let mut laser_device = device(h, &["laserPosition", "laserOrigin"])?;
    let (mut cam, mut las) = (camera.set, laser.set);
    let sets: Vec<&PointSet> = if confocal { vec![&cam] } else { vec![&cam, &las] };
    if let Some(rot) = frame_rotation(&sets) {
        for s in [&mut cam, &mut las] {
            s.points.iter_mut().chain(s.normals.iter_mut()).for_each(|v| *v = rot(*v));
        }
        sensor_device = sensor_device.map(rot);
        laser_device = laser_device.map(rot);
    }
    let pattern =
        if confocal { ScanPattern::Confocal(cam) } else { ScanPattern::Exhaustive { lasers: las, sensors: cam } };
    let scan = Scan { pattern, laser_device, sensor_device };
    Transient::new(scan, time, data).map_err(|e| super::super::with_file(e, file))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reversed_view_offsets() {
        // Stored (2, 3) C order; reversed view is (3, 2) with strides (1, 3).
        let v = View::new(&[2, 3], true);
        assert_eq!(v.shape, vec![3, 2]);
        assert_eq!(v.strides, vec![1, 3]);
        assert_eq!(offset(1, &v.shape, &v.strides), 3);
        assert_eq!(offset(2, &v.shape, &v.strides), 1);
    }
}
