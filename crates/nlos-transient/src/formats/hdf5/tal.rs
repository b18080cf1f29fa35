//! y-tal HDF5_TAL: the capture format of the `tal` toolkit (Royo, Sultan, Muñoz, Jarabo et al., y-tal,
//! <https://github.com/diegoroyo/tal>; layout from `tal/io/capture_data.py` and `tal/enums.py`).
//!
//! | dataset | content |
//! |---|---|
//! | `H` | histograms, time first: `(T, Sx, Sy)`, `(T, Lx, Ly, Sx, Sy)`, `(T, Si)` or `(T, Li, Si)` |
//! | `H_format` | [`HFormat`] (y-tal writes an int32 enum of shape `(1,)`) |
//! | `sensor_grid_xyz`, `sensor_grid_normals` | `(X, Y, 3)` or `(N, 3)` per `sensor_grid_format` |
//! | `laser_grid_xyz`, `laser_grid_normals` | the same for the laser spots |
//! | `sensor_grid_format`, `laser_grid_format` | [`GridFormat`] |
//! | `sensor_xyz`, `laser_xyz` | device positions `(3,)` (optional; h5py `Empty` when unknown) |
//! | `delta_t`, `t_start` | bin width and start of bin 0, metres of optical path |
//! | `t_accounts_first_and_last_bounces` | whether times include the device legs (h5py bool) |
//! | `scene_info` | YAML string (read: ignored; written: `original_format: nlos`) |
//! | `volume_format` | deprecated, ignored |
//!
//! Mapping to [`Transient`] (our points: grid point `ix + nx·iy`; data `data[m·bins + k]`):
//! - `T_Sx_Sy`: `H[k, ix, iy]` with `sensor_grid_xyz[ix, iy, :]`. When the laser grid has the same shape
//!   as the sensor grid and the same positions (to `numpy.allclose` tolerances, as y-tal's
//!   `is_confocal` checks), the scan is confocal over the sensor grid. When the laser grid holds a single
//!   point, it is an exhaustive scan with one laser spot. Anything else (paired, non-confocal spots) has
//!   no place in our model and is rejected.
//! - `T_Si`: `H[k, i]` with `sensor_grid_xyz[i, :]`; confocal or single laser spot as above.
//! - `T_Lx_Ly_Sx_Sy`: `H[k, lx, ly, sx, sy]`: exhaustive, measurement `il·n_sensors + is`.
//! - `T_Li_Si`: `H[k, li, si]`: exhaustive over two point lists.
//! - Grids in `X_Y_3` become [`Layout::Grid`] `{nx: X, ny: Y}`, grids in `N_3` [`Layout::List`].
//! - `t_accounts_first_and_last_bounces` → [`TimeAxis::includes_device_legs`]; `sensor_xyz` /
//!   `laser_xyz` → device positions. `delta_t` and `t_start` may be f32 (y-tal writes float32) or f64; a
//!   missing or empty `t_start` means 0.
//!
//! Writing: confocal grid → `T_Sx_Sy`; confocal list → `T_Si`; exhaustive with two grids →
//! `T_Lx_Ly_Sx_Sy`; exhaustive with a single laser spot → `T_Sx_Sy` / `T_Si` with a one-point laser
//! grid; any other exhaustive scan → `T_Li_Si` (a grid in a `T_Li_Si` file is stored as `N_3`, so its
//! grid shape is not kept). A paired scan has no y-tal layout and is refused with
//! [`TransientError::CannotWrite`] (write `.npy` + `.json` or `.exr`). `H` is float32, gzip-compressed in chunks; positions and normals float32;
//! `delta_t` and `t_start` are written as **float64** (y-tal writes float32; y-tal and h5py read either),
//! so our own files round-trip bit-exactly.
//!
//! [`Layout::Grid`]: crate::Layout::Grid
//! [`Layout::List`]: crate::Layout::List
//! [`TimeAxis::includes_device_legs`]: crate::TimeAxis::includes_device_legs

use std::path::Path;

use glam::Vec3;
use hdf5_pure::{EnumTypeBuilder, FileBuilder, make_i8_type};

use super::{H5, shape_str};
use crate::error::{Result, TransientError};
use crate::scan::{Layout, PointSet, Scan, ScanPattern};
use crate::time_axis::TimeAxis;
use crate::transient::Transient;

/// y-tal's `HFormat`: the meaning of each dimension of `H` (values as in `tal/enums.py`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HFormat {
    /// `H` is `(T, Sx, Sy)`: a grid of sensor points (confocal, or one laser spot).
    TSxSy = 1,
    /// `H` is `(T, Lx, Ly, Sx, Sy)`: every laser grid point with every sensor grid point.
    TLxLySxSy = 2,
    /// `H` is `(T, Si)`: a list of sensor points (confocal, or one laser spot).
    TSi = 3,
    /// `H` is `(T, Li, Si)`: every laser point with every sensor point, as lists.
    TLiSi = 4,
}

impl HFormat {
    /// The y-tal name (`T_Sx_Sy`, …).
    pub fn name(self) -> &'static str {
        match self {
            HFormat::TSxSy => "T_Sx_Sy",
            HFormat::TLxLySxSy => "T_Lx_Ly_Sx_Sy",
            HFormat::TSi => "T_Si",
            HFormat::TLiSi => "T_Li_Si",
        }
    }

    /// The format for a stored value, `None` for `UNKNOWN` (0) and anything else.
    pub fn from_value(v: f64) -> Option<Self> {
        [HFormat::TSxSy, HFormat::TLxLySxSy, HFormat::TSi, HFormat::TLiSi].into_iter().find(|f| *f as i32 as f64 == v)
    }
}

/// y-tal's `GridFormat`: the shape of a `*_grid_xyz` / `*_grid_normals` array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridFormat {
    /// `(N, 3)`: a list of points.
    N3 = 1,
    /// `(X, Y, 3)`: a grid, `xyz[ix, iy, :]`.
    XY3 = 2,
}

/// A point set read from a TAL grid, with the `H` dimensions it spans.
struct Grid {
    set: PointSet,
    /// `[X, Y]` for a grid, `[N]` for a list.
    dims: Vec<usize>,
}

impl Grid {
    /// Offset within the flattened `H` dimensions of this grid of our point `p`.
    fn offset(&self, p: usize) -> usize {
        match self.dims.as_slice() {
            [x, y] => (p % x) * y + p / x,
            _ => p,
        }
    }
}

fn read_grid(h: &H5<'_>, who: &str) -> Result<Grid> {
    let xyz_name = format!("{who}_grid_xyz");
    let nrm_name = format!("{who}_grid_normals");
    let fmt_name = format!("{who}_grid_format");
    let xyz = h.f64_array(&xyz_name, "y-tal HDF5_TAL files hold the wall points in `*_grid_xyz`")?;
    let declared = if h.has(&fmt_name) { Some(h.scalar(&fmt_name, "")?) } else { None };
    let wrong = |field: &str, expected: &str, found: &[usize]| TransientError::WrongShape {
        file: h.path().into(),
        field: field.into(),
        expected: expected.into(),
        found: shape_str(found),
    };
    let dims = match (declared, xyz.shape.as_slice()) {
        (Some(2.0) | None, [x, y, 3]) => vec![*x, *y],
        (Some(1.0) | None, [n, 3]) => vec![*n],
        (None, [3]) => vec![1],
        (Some(v), _) if v != 1.0 && v != 2.0 => {
            return Err(TransientError::Unsupported {
                file: h.path().into(),
                what: format!("`{fmt_name}` = {v} (y-tal GridFormat N_3 = 1 and X_Y_3 = 2 are supported)"),
            });
        }
        (Some(v), s) => {
            let expected = if v == 2.0 { "(X, Y, 3) for X_Y_3" } else { "(N, 3) for N_3" };
            return Err(wrong(&xyz_name, expected, s));
        }
        (None, s) => return Err(wrong(&xyz_name, "(X, Y, 3) or (N, 3)", s)),
    };
    let n: usize = dims.iter().product();
    if n == 0 {
        return Err(TransientError::InvalidValue {
            file: h.path().into(),
            field: xyz_name,
            reason: format!("zero-sized grid {}", shape_str(&xyz.shape)),
        });
    }
    let normals = if h.has(&nrm_name) {
        let a = h.f64_array(&nrm_name, "")?;
        if a.values.len() != xyz.values.len() {
            return Err(wrong(&nrm_name, &format!("{} (as `{xyz_name}`)", shape_str(&xyz.shape)), &a.shape));
        }
        Some(a.values)
    } else {
        None
    };
    // Our point p = ix + X·iy sits at TAL row ix·Y + iy.
    let tmp = Grid { set: PointSet::list(Vec::new()), dims: dims.clone() };
    let at = |v: &[f64], p: usize| {
        let r = tmp.offset(p) * 3;
        Vec3::new(v[r] as f32, v[r + 1] as f32, v[r + 2] as f32)
    };
    let points: Vec<Vec3> = (0..n).map(|p| at(&xyz.values, p)).collect();
    let normals = match &normals {
        Some(v) => (0..n).map(|p| at(v, p)).collect(),
        None => vec![Vec3::Z; n],
    };
    let layout = match dims.as_slice() {
        [x, y] => Layout::Grid { nx: *x, ny: *y },
        _ => Layout::List,
    };
    let set = PointSet { points, normals, layout };
    set.validate(&xyz_name).map_err(|e| super::super::with_file(e, h.path()))?;
    Ok(Grid { set, dims })
}

fn device(h: &H5<'_>, name: &str) -> Result<Option<Vec3>> {
    if !h.has(name) {
        return Ok(None);
    }
    let a = h.f64_array(name, "")?;
    match a.values.as_slice() {
        [] => Ok(None),
        [x, y, z] => {
            let v = Vec3::new(*x as f32, *y as f32, *z as f32);
            if v.is_finite() {
                Ok(Some(v))
            } else {
                Err(TransientError::NonFinite { file: h.path().into(), field: name.into(), index: 0 })
            }
        }
        _ => Err(TransientError::WrongShape {
            file: h.path().into(),
            field: name.into(),
            expected: "(3,) device position".into(),
            found: shape_str(&a.shape),
        }),
    }
}

/// `numpy.allclose(a, b)` for two point sets.
fn allclose(a: &PointSet, b: &PointSet) -> bool {
    a.len() == b.len()
        && a.points.iter().zip(&b.points).all(|(p, q)| {
            (0..3).all(|i| (f64::from(p[i]) - f64::from(q[i])).abs() <= 1e-8 + 1e-5 * f64::from(q[i]).abs())
        })
}

pub(super) fn read(h: &H5<'_>) -> Result<Transient> {
    let file = h.path();
    let fmt_value = h.scalar("H_format", "y-tal HDF5_TAL files say what the dimensions of `H` are in `H_format`")?;
    let format = HFormat::from_value(fmt_value).ok_or_else(|| TransientError::Unsupported {
        file: file.into(),
        what: format!("`H_format` = {fmt_value} (supported: T_Sx_Sy = 1, T_Lx_Ly_Sx_Sy = 2, T_Si = 3, T_Li_Si = 4)"),
    })?;
    let sensors = read_grid(h, "sensor")?;
    let lasers = read_grid(h, "laser")?;
    let (h_shape, values) = h.f32_array("H", "y-tal HDF5_TAL files hold the histograms in `H`")?;
    let bins = h_shape.first().copied().unwrap_or(0);
    let exhaustive_h = matches!(format, HFormat::TLxLySxSy | HFormat::TLiSi);
    let want_grid = matches!(format, HFormat::TSxSy | HFormat::TLxLySxSy);
    for g in [&sensors, &lasers].into_iter().take(if exhaustive_h { 2 } else { 1 }) {
        if want_grid != (g.dims.len() == 2) {
            return Err(TransientError::WrongShape {
                file: file.into(),
                field: if std::ptr::eq(g, &sensors) { "sensor_grid_xyz" } else { "laser_grid_xyz" }.into(),
                expected: format!("{} for H_format {}", if want_grid { "(X, Y, 3)" } else { "(N, 3)" }, format.name()),
                found: shape_str(&g.dims),
            });
        }
    }
    let mut expected = vec![bins];
    if exhaustive_h {
        expected.extend(&lasers.dims);
    }
    expected.extend(&sensors.dims);
    if h_shape != expected || bins == 0 {
        return Err(TransientError::WrongShape {
            file: file.into(),
            field: "H".into(),
            expected: format!(
                "{} (T > 0 bins, then the {} grid dimensions) for H_format {}",
                shape_str(&expected),
                if exhaustive_h { "laser and sensor" } else { "sensor" },
                format.name()
            ),
            found: shape_str(&h_shape),
        });
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(TransientError::NonFinite { file: file.into(), field: "H".into(), index: i });
    }
    let (pattern, n_l) = if exhaustive_h {
        let n_l = lasers.set.len();
        (ScanPattern::Exhaustive { lasers: lasers.set.clone(), sensors: sensors.set.clone() }, n_l)
    } else if lasers.set.len() == sensors.set.len() && allclose(&lasers.set, &sensors.set) {
        (ScanPattern::Confocal(sensors.set.clone()), 1)
    } else if lasers.set.len() == 1 {
        (ScanPattern::Exhaustive { lasers: lasers.set.clone(), sensors: sensors.set.clone() }, 1)
    } else {
        return Err(TransientError::Unsupported {
            file: file.into(),
            what: format!(
                "`H_format` {} with {} laser spots that differ from the {} sensor spots (a paired, \
                 non-confocal scan has no equivalent here)",
                format.name(),
                lasers.set.len(),
                sensors.set.len()
            ),
        });
    };
    let n_s = sensors.set.len();
    let per_bin = n_l * n_s;
    let mut data = vec![0.0f32; per_bin * bins];
    for il in 0..n_l {
        let lo = if exhaustive_h { lasers.offset(il) * n_s } else { 0 };
        for is in 0..n_s {
            let src = lo + sensors.offset(is);
            let m = il * n_s + is;
            let out = &mut data[m * bins..(m + 1) * bins];
            for (k, o) in out.iter_mut().enumerate() {
                *o = values.get(k * per_bin + src).copied().unwrap_or(0.0);
            }
        }
    }
    let includes_legs = if h.has("t_accounts_first_and_last_bounces") {
        let a = h.f64_array("t_accounts_first_and_last_bounces", "")?;
        a.values.first().is_some_and(|v| *v != 0.0)
    } else {
        false
    };
    let delta_t = h.finite_scalar("delta_t", "bin width in metres of optical path")?;
    let t_start = if h.has("t_start") {
        let a = h.f64_array("t_start", "")?;
        match a.values.as_slice() {
            [] => 0.0,
            [v] if v.is_finite() => *v,
            [_] => return Err(TransientError::NonFinite { file: file.into(), field: "t_start".into(), index: 0 }),
            _ => {
                return Err(TransientError::WrongShape {
                    file: file.into(),
                    field: "t_start".into(),
                    expected: "a single value".into(),
                    found: shape_str(&a.shape),
                });
            }
        }
    } else {
        0.0
    };
    let time = TimeAxis { t0: t_start, bin_width: delta_t, bins, includes_device_legs: includes_legs };
    time.validate().map_err(|e| match super::super::with_file(e, file) {
        TransientError::InvalidValue { file, reason, .. } => {
            TransientError::InvalidValue { file, field: "delta_t".into(), reason }
        }
        e => e,
    })?;
    let scan = Scan { pattern, laser_device: device(h, "laser_xyz")?, sensor_device: device(h, "sensor_xyz")? };
    Transient::new(scan, time, data).map_err(|e| super::super::with_file(e, file))
}

fn cannot(file: &Path, reason: String) -> TransientError {
    TransientError::CannotWrite { file: file.into(), format: "tal".into(), reason }
}

/// `(dims, xyz, normals)` of a point set in TAL order.
fn grid_arrays(set: &PointSet, as_list: bool) -> (Vec<u64>, Vec<f32>, Vec<f32>) {
    let (dims, order): (Vec<u64>, Vec<usize>) = match (set.layout, as_list) {
        (Layout::Grid { nx, ny }, false) => {
            // TAL row ix·ny + iy holds our point ix + nx·iy.
            (vec![nx as u64, ny as u64, 3], (0..nx).flat_map(|ix| (0..ny).map(move |iy| ix + nx * iy)).collect())
        }
        _ => (vec![set.len() as u64, 3], (0..set.len()).collect()),
    };
    let flat = |v: &[Vec3]| order.iter().flat_map(|&p| v[p].to_array()).collect::<Vec<f32>>();
    (dims, flat(&set.points), flat(&set.normals))
}

pub(super) fn write(t: &Transient, file: &Path) -> Result<Vec<u8>> {
    t.validate().map_err(|e| super::super::with_file(e, file))?;
    let scan = t.scan();
    let bins = t.bins();
    let (format, lasers, sensors, laser_list, sensor_list) = match &scan.pattern {
        ScanPattern::Confocal(p) => {
            let f = if p.grid_dims().is_some() { HFormat::TSxSy } else { HFormat::TSi };
            (f, p, p, false, false)
        }
        ScanPattern::Exhaustive { lasers, sensors } => {
            match (lasers.len(), lasers.grid_dims().is_some(), sensors.grid_dims().is_some()) {
                (1, _, true) => (HFormat::TSxSy, lasers, sensors, false, false),
                (1, _, false) => (HFormat::TSi, lasers, sensors, false, false),
                (_, true, true) => (HFormat::TLxLySxSy, lasers, sensors, false, false),
                _ => (HFormat::TLiSi, lasers, sensors, true, true),
            }
        }
        ScanPattern::Paired { .. } => {
            return Err(TransientError::CannotWrite {
                file: file.into(),
                format: "y-tal HDF5".into(),
                reason: "a paired scan (measurement i = laser spot i with sensor spot i) has no y-tal layout: every \
                         H_format is confocal or pairs each laser spot with every sensor spot; write .npy (with its \
                         .json sidecar) or .exr, which keep the pairing"
                    .into(),
            });
        }
    };
    let (l_dims, l_xyz, l_nrm) = grid_arrays(lasers, laser_list);
    let (s_dims, s_xyz, s_nrm) = grid_arrays(sensors, sensor_list);
    let exhaustive_h = matches!(format, HFormat::TLxLySxSy | HFormat::TLiSi);
    let mut h_dims = vec![bins as u64];
    if exhaustive_h {
        h_dims.extend(&l_dims[..l_dims.len() - 1]);
    }
    h_dims.extend(&s_dims[..s_dims.len() - 1]);
    // H[k, laser dims…, sensor dims…] from data[m·bins + k], m = il·n_s + is.
    let n_s = sensors.len();
    let n_l = if exhaustive_h { lasers.len() } else { 1 };
    let offset = |set: &PointSet, as_list: bool, p: usize| match (set.layout, as_list) {
        (Layout::Grid { nx, ny }, false) => (p % nx) * ny + p / nx,
        _ => p,
    };
    let per_bin = n_l * n_s;
    let mut h = vec![0.0f32; per_bin * bins];
    for il in 0..n_l {
        let lo = if exhaustive_h { offset(lasers, laser_list, il) * n_s } else { 0 };
        for is in 0..n_s {
            let dst = lo + offset(sensors, sensor_list, is);
            for (k, &v) in t.histogram(il * n_s + is).iter().enumerate() {
                h[k * per_bin + dst] = v;
            }
        }
    }
    let enum_err = |e: hdf5_pure::FormatError| cannot(file, format!("HDF5 enum type: {e}"));
    let h_format_t = EnumTypeBuilder::i32_based()
        .value("UNKNOWN", 0)
        .value("T_Sx_Sy", 1)
        .value("T_Lx_Ly_Sx_Sy", 2)
        .value("T_Si", 3)
        .value("T_Li_Si", 4)
        .build()
        .map_err(enum_err)?;
    let grid_t = || EnumTypeBuilder::i32_based().value("UNKNOWN", 0).value("N_3", 1).value("X_Y_3", 2).build();
    let bool_t = EnumTypeBuilder::with_base(make_i8_type()).u8_value("FALSE", 0).u8_value("TRUE", 1).build();
    let mut b = FileBuilder::new();
    // Chunks of at most ~1 MiB along time, whole spatial planes (as h5py's autochunk would split them).
    let plane = per_bin.max(1);
    let chunk_t = ((1usize << 18) / plane).clamp(1, bins) as u64;
    let mut chunks = h_dims.clone();
    chunks[0] = chunk_t;
    b.create_dataset("H").with_f32_data(&h).with_shape(&h_dims).with_chunks(&chunks).with_deflate(4);
    b.create_dataset("H_format").with_enum_i32_data(h_format_t, &[format as i32]);
    for (who, dims, xyz, nrm) in [("sensor", &s_dims, &s_xyz, &s_nrm), ("laser", &l_dims, &l_xyz, &l_nrm)] {
        b.create_dataset(&format!("{who}_grid_xyz")).with_f32_data(xyz).with_shape(dims);
        b.create_dataset(&format!("{who}_grid_normals")).with_f32_data(nrm).with_shape(dims);
        let g = if dims.len() == 3 { GridFormat::XY3 } else { GridFormat::N3 };
        b.create_dataset(&format!("{who}_grid_format")).with_enum_i32_data(grid_t().map_err(enum_err)?, &[g as i32]);
    }
    for (name, d) in [("sensor_xyz", scan.sensor_device), ("laser_xyz", scan.laser_device)] {
        if let Some(d) = d {
            b.create_dataset(name).with_f32_data(&d.to_array());
        }
    }
    let time = t.time();
    b.create_dataset("delta_t").with_f64_data(&[time.bin_width]).with_shape(&[]);
    b.create_dataset("t_start").with_f64_data(&[time.t0]).with_shape(&[]);
    b.create_dataset("t_accounts_first_and_last_bounces")
        .with_enum_u8_data(bool_t.map_err(enum_err)?, &[u8::from(time.includes_device_legs)])
        .with_shape(&[]);
    b.create_dataset("scene_info").with_vlen_strings(&["original_format: nlos\n"]).with_shape(&[]);
    super::guard(file, "HDF5 encoder", || b.finish()).map_err(|e| cannot(file, e.to_string()))
}
