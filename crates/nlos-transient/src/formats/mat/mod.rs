//! MATLAB level-5 MAT-files (v5/v6/v7): Stanford LCT, Tsai et al. 2019 and Stanford f-k captures (and
//! Z-NLOS as NeTF preprocessed it, `znlos`).
//!
//! The container is parsed by this crate's own defensive MAT v5 reader (`v5`, see its docs for why not
//! the `matfile` crate). MATLAB v7.3 files are HDF5 and go through [`super::hdf5`]; the f-k conversion
//! is shared through `fk_from_arrays` (crate-private).
//!
//! # Stanford LCT (O'Toole, Lindell, Wetzstein, "Confocal non-line-of-sight imaging based on the
//! light-cone transform", Nature 555, 2018; data and code at <http://www.computationalimaging.org>)
//! - `rect_data`: N×N×T histograms, column-major (`i + N·j + N²·t`). Class double, but MATLAB stores the
//!   counts as uint16 on disk; the class is honoured (values are converted from the storage type to the
//!   class, then to `f32`).
//! - `width`: HALF the side of the square scan area, metres. Scan points are `linspace(-width, width, N)`
//!   along each axis on the wall z = 0 ([`PointSet::wall_grid`]), confocal.
//! - Time: not stored. The reference code hard-codes 4 ps bins and `c = 3e8` m/s, so one bin is exactly
//!   [`LCT_BIN_WIDTH`] = 1.2 mm of path (we follow the reference, not 299 792 458 m/s, which would give
//!   1.1992 mm and shift a 0.4 m depth by 0.3 mm). `t0 = 0`: the direct reflection off the wall is at
//!   bin 0, and times are path lengths `l → x → s` (the device legs were calibrated away).
//! - **Axis mapping** (checked on the data): MAT index `i` (first dimension) runs along −x and `j`
//!   (second) along −y, i.e. grid point `ix = N−1−i`, `iy = N−1−j` (point index `ix + N·iy`, x fastest).
//!   Evidence: the time-summed image (after `gate(0.72)`) is too blurred to resolve a letter (each pixel
//!   integrates the whole scene), so we reconstructed `data_diffuse_s.mat` and `data_s_u.mat` with the
//!   reference LCT algorithm (reimplemented in NumPy; max over depth 0.3–0.7 m for the S, 0.7–1.2 m for
//!   the U of the SU scene) and displayed the 8 possible mappings with x to the right and y up, as seen
//!   from the wall looking into the hidden scene. The four that put `i` along y show the S on its side. Of
//!   the four with `i` along x, two are mirrored; the other two, `(x, y) = (+i, +j)` and its half turn
//!   `(−i, −j)`, both show a correct S (the letter is symmetric under a half turn), but only `(−i, −j)`
//!   shows the U upright (opening upwards; `(+i, +j)` shows ∩). Assuming the letters face the wall and
//!   stand upright, `(−i, −j)` is the mapping. (Tsai et al.'s `compute_init_su.m` builds `lighting` from
//!   `ndgrid(x, y)` with `x = +i`, `y = +j`: the same data rotated by a half turn about z relative to
//!   ours, which does not matter to their method; we read their files as they store them.)
//!
//! # Tsai et al. 2019 (Tsai, Sankaranarayanan, Gkioulekas, "Beyond volumetric albedo — a surface
//! optimization framework for non-line-of-sight imaging", CVPR 2019; code at
//! <https://github.com/cmu-ci-lab/nlos_surface_optimization>)
//! - `transient`: M×T (one row per measurement), `lighting`: M×3 laser = sensor positions (confocal),
//!   read as a list with wall normal +z, which [`crate::read`] lays out as a grid when the points form one
//!   (`Transient::with_grid_layout`). Their measured files are made
//!   by `exp_su/compute_init_su.m`: `transient = reshape(rect_data, 64*64, 2048)` with bins 1–600 zeroed,
//!   `lighting = [x(:) y(:) 0]` from `ndgrid(linspace(-width, width, 64))`, saved with only those two
//!   variables. Their synthetic setup files (`main_create_gt.py`) hold `gt_transient` instead of
//!   `transient`, plus `bin_width` (metres of path, `distance_resolution = 1.2e-3`) and `sensor`
//!   (equal to `lighting`); both are honoured when present, and a `sensor` apart from `lighting` makes the
//!   scan paired (measurement r = laser `lighting[r]` with sensor `sensor[r]`).
//! - Time: their code (`OPT.distance_resolution = 1.2*10**-3`, path-length bins starting at the wall)
//!   uses [`TSAI_BIN_WIDTH`] = 1.2 mm per bin and `t0 = 0`, times `l → x → s`; used when `bin_width` is
//!   not stored.
//!
//! # Stanford f-k (Lindell, Wetzstein, O'Toole, "Wave-based non-line-of-sight imaging using fast f-k
//! migration", SIGGRAPH 2019; code at <https://github.com/computational-imaging/nlos-fk>)
//! - `meas`: N×N×T histograms of 32 ps bins ([`FK_BIN_WIDTH`] = 9.6 mm with the reference `c = 3e8`),
//!   dimension order `(y, x, t)` as the reference `demo.m` comments it (`imresize3d(meas, 128, 128,
//!   2048); % y, x, t`).
//! - `tofgrid`: N×N, picoseconds per scan point: the device → wall → device time. The reference
//!   `cnlos_reconstruction.m` rectifies with `circshift(meas(ii,jj,:), -floor(tofgrid(ii,jj) / 32))`. We
//!   shift each histogram earlier by exactly `tofgrid / 32` bins instead (fractional, with
//!   [`Transient::remove_device_legs`]'s piecewise-constant resampling, zero fill rather than
//!   wrap-around), so that `t0 = 0` is exactly the wall for every pixel; the reference's floor leaves each
//!   pixel's zero up to one bin (9.6 mm) late. The result has `includes_device_legs = false`. The
//!   datasets ship `tofgrid` in a separate `tof.mat`; when `meas` comes without `tofgrid`, a v5 `tof.mat`
//!   beside the file is used.
//! - Scan area: not stored; every planar f-k scene is a 2 m × 2 m wall (`wall_size = 2` in `demo.m`,
//!   `width = wall_size / 2`), so the half width defaults to [`FK_DEFAULT_HALF_WIDTH`] = 1 m; a stored
//!   `width` (half side, as in LCT files) or `wall_size` (full side) overrides it.
//! - Orientation (not checked on data: no f-k file is at hand): the reference's front view shows
//!   `meas(i, j)` with row `i` downwards and column `j` to the right (its flips and reversed tick vectors
//!   cancel), which we take as the view from the wall: `ix = j`, `iy = N−1−i`.
//!
//! [`PointSet::wall_grid`]: crate::PointSet::wall_grid
//! [`Layout::List`]: crate::Layout::List
//! [`Transient::remove_device_legs`]: crate::Transient::remove_device_legs

use std::path::Path;

use glam::Vec3;

pub mod general_nlos;
mod v5;
mod znlos;

use super::{Container, Format, read_file, sniff, with_file};
use crate::error::{MEMORY, Result, TransientError};
use crate::scan::{PointSet, Scan};
use crate::time_axis::TimeAxis;
use crate::transient::Transient;
use v5::{MatFile, NumericArray, VarHeader};

/// Bin width of the Stanford LCT captures: 4 ps at the reference code's `c = 3e8` m/s, metres of path.
pub const LCT_BIN_WIDTH: f64 = 0.0012;

/// Default bin width of Tsai et al. 2019 captures (`distance_resolution` in their code), metres of path.
pub const TSAI_BIN_WIDTH: f64 = 0.0012;

/// Bin width of the Stanford f-k captures: 32 ps at the reference code's `c = 3e8` m/s, metres of path.
pub const FK_BIN_WIDTH: f64 = 0.0096;

/// Bin width of the Stanford f-k captures in picoseconds (the unit of `tofgrid`).
pub const FK_BIN_PS: f64 = 32.0;

/// Half the side of the scanned wall of the planar Stanford f-k scenes (2 m × 2 m), metres.
pub const FK_DEFAULT_HALF_WIDTH: f64 = 1.0;

/// Decides which MAT-based format a v5 MAT-file holds from its variable names (only the variables'
/// headers are read; compressed variables are inflated just far enough to read their names).
///
/// `rect_data` → [`Format::LctMat`]; `meas` → [`Format::FkMat`]; `lighting` with `transient` (or
/// `gt_transient`) → [`Format::TsaiMat`]; `data` with `cameraGridPositions` and `deltaT` →
/// [`Format::ZNlosMat`]; `data` alone, or `laserpoints` with `detectpoints` → [`Format::GeneralNlosMat`].
///
/// # Errors
/// [`TransientError::UnknownFormat`] naming the variables found when they match no known layout;
/// container errors ([`TransientError::Truncated`], [`TransientError::Malformed`],
/// [`TransientError::Unsupported`]).
pub fn classify(bytes: &[u8], file: &Path) -> Result<Format> {
    let m = MatFile::parse(bytes, file)?;
    let has = |n: &str| m.header(n).is_some();
    if has("rect_data") {
        Ok(Format::LctMat)
    } else if has("meas") {
        Ok(Format::FkMat)
    } else if has("lighting") && (has("transient") || has("gt_transient")) {
        Ok(Format::TsaiMat)
    } else if has("data") && has("cameraGridPositions") && has("deltaT") {
        Ok(Format::ZNlosMat)
    } else if general_nlos::is_setup(&m) || (has("data") && m.headers().count() == 1) {
        Ok(Format::GeneralNlosMat)
    } else {
        Err(TransientError::UnknownFormat {
            file: file.into(),
            reason: format!(
                "MAT v5 file with {}; expected `rect_data` + `width` (Stanford LCT), `transient` + `lighting` \
                 (Tsai 2019), `meas` + `tofgrid` (Stanford f-k), `data` + `cameraGridPositions` + `deltaT` \
                 (Z-NLOS as NeTF preprocessed it), `data` alone or `laserpoints` + `detectpoints` (general-NLOS \
                 data.mat and setup.mat)",
                m.names()
            ),
        })
    }
}

/// Reads a v5 MAT-file in `format` ([`Format::LctMat`], [`Format::TsaiMat`] or [`Format::FkMat`]; see
/// the module docs for each layout's conventions).
///
/// # Errors
/// Any [`TransientError`], naming the file and the variable: missing variable, wrong shape, wrong class
/// (char, cell, struct, complex…), NaN/Inf, truncated or malformed container; [`TransientError::UnknownFormat`]
/// when `format` is not a MAT format.
pub fn read(bytes: &[u8], format: Format, file: &Path) -> Result<Transient> {
    let m = MatFile::parse(bytes, file)?;
    match format {
        Format::LctMat => read_lct(&m, file),
        Format::TsaiMat => read_tsai(&m, file),
        Format::FkMat => read_fk(&m, file),
        Format::ZNlosMat => znlos::read(&m, file),
        other => Err(TransientError::UnknownFormat {
            file: file.into(),
            reason: format!("{other} is not a MAT-file format"),
        }),
    }
}

/// Reads a general-NLOS capture ([`general_nlos`]) from either of its files.
///
/// # Errors
/// As [`read`]; see [`general_nlos`] for what each file must hold.
pub fn read_general_nlos(bytes: &[u8], file: &Path, options: &super::ReadOptions) -> Result<Transient> {
    general_nlos::read(&MatFile::parse(bytes, file)?, file, options)
}

/// Reads a general-NLOS capture from the bytes of its two files (`data.mat`, then `setup.mat`; `dir` is where
/// messages say they are) with bins of `bin_width` metres of path: the reader without the file system, for
/// fuzzing and for captures held in memory.
///
/// # Errors
/// As [`read_general_nlos`], the companion file aside; [`TransientError::InvalidValue`] for a bin width that is
/// not finite and positive.
pub fn read_general_nlos_pair(data: &[u8], setup: &[u8], dir: &Path, bin_width: f64) -> Result<Transient> {
    let (data_file, setup_file) = (dir.join(general_nlos::DATA_FILE), dir.join(general_nlos::SETUP_FILE));
    general_nlos::check_bin_width(bin_width, &data_file)?;
    let d = MatFile::parse(data, &data_file)?;
    let s = MatFile::parse(setup, &setup_file)?;
    general_nlos::from_pair(&d, &data_file, &s, &setup_file, bin_width)
}

/// One numeric variable of a MAT v5 file, for arrays that are not captures (depth and normal maps; NaN and
/// infinities are "no value" and come back as NaN): the variable `name`, or the file's only numeric variable
/// when `name` is None. Returns the values in **C order** (an `H×W` MATLAB matrix comes back as rows of W,
/// element `(r, c)` at `c + W·r`; an `H×W×3` array's element `(r, c, k)` at `k + 3·(c + W·r)`), the MATLAB
/// dimensions and the variable's name.
///
/// # Errors
/// As [`read`]; [`TransientError::MissingField`] when `name` is absent or the file holds no or several
/// numeric variables (naming them).
pub fn read_array(path: &Path, name: Option<&str>) -> Result<(Vec<f32>, Vec<usize>, String)> {
    decode_array(&super::read_file(path)?, path, name)
}

/// [`read_array`] on the bytes of a file (`path` names it in errors).
///
/// # Errors
/// As [`read_array`].
pub fn decode_array(bytes: &[u8], path: &Path, name: Option<&str>) -> Result<(Vec<f32>, Vec<usize>, String)> {
    let m = MatFile::parse(bytes, path)?;
    let chosen = match name {
        Some(n) => n.to_owned(),
        None => {
            let numeric: Vec<&VarHeader> = m.headers().filter(|h| h.class.is_numeric()).collect();
            match numeric.as_slice() {
                [one] => one.name.clone(),
                _ => {
                    return Err(TransientError::MissingField {
                        file: path.into(),
                        field: "array".into(),
                        hint: format!("expected one numeric variable, found {}; name the one to read", m.names()),
                    });
                }
            }
        }
    };
    let a = m.numeric(&chosen, "the array to read")?;
    let dims = a.header.dims.clone();
    // MATLAB stores column-major: the first index fastest.
    let c_order = super::npy::fortran_to_c(&a.to_f32_map(path)?, &dims);
    Ok((c_order, dims, chosen))
}

/// The wall grid of a NeTF-preprocessed Z-NLOS file (`cameraGridSize`), in our frame: `[x0, x1, y0, y1]`,
/// the rectangle from one outermost point of the **full** scan grid to the other, centred at the origin of
/// the file's frame as the dataset's walls are. A file subsampled from a finer grid (the published 8 × 8
/// bunny, every 32nd point of 256) keeps the full grid's size, so its ground-truth maps (256 × 256) are
/// placed by this rectangle, not by the points the file holds. None when the file has no `cameraGridSize`
/// or when its points do not lie inside that rectangle (a wall not centred at the origin).
///
/// # Errors
/// As [`read`] for the file and `cameraGridSize` (wrong shape, non-finite or non-positive sides).
pub fn znlos_wall(path: &Path) -> Result<Option<[f32; 4]>> {
    znlos_wall_bytes(&super::read_file(path)?, path)
}

/// [`znlos_wall`] on the bytes of a file (`path` names it in errors).
///
/// # Errors
/// As [`znlos_wall`].
pub fn znlos_wall_bytes(bytes: &[u8], path: &Path) -> Result<Option<[f32; 4]>> {
    let m = MatFile::parse(bytes, path)?;
    znlos::wall(&m, path)
}

pub(super) fn wrong_shape(file: &Path, h: &VarHeader, expected: impl Into<String>) -> TransientError {
    TransientError::WrongShape {
        file: file.into(),
        field: h.name.clone(),
        expected: expected.into(),
        found: h.describe(),
    }
}

pub(super) fn invalid(file: &Path, field: &str, reason: String) -> TransientError {
    TransientError::InvalidValue { file: file.into(), field: field.into(), reason }
}

/// Dimensions of a 3-D array, with a zero-size check.
fn dims3(a: &NumericArray<'_>, file: &Path, expected: &str) -> Result<[usize; 3]> {
    let h = &a.header;
    let &[d0, d1, d2] = h.dims.as_slice() else {
        return Err(wrong_shape(file, h, expected));
    };
    if d0 == 0 || d1 == 0 || d2 == 0 {
        return Err(invalid(
            file,
            &h.name,
            format!("{} has no data (zero-sized scan grid or time axis)", h.describe()),
        ));
    }
    Ok([d0, d1, d2])
}

/// A finite positive scalar variable.
pub(super) fn positive_scalar(m: &MatFile<'_>, file: &Path, name: &str, hint: &str) -> Result<f64> {
    let v = m.numeric(name, hint)?.scalar(file)?;
    if !(v.is_finite() && v > 0.0) {
        return Err(invalid(file, name, format!("{v} must be a finite positive number ({hint})")));
    }
    Ok(v)
}

fn read_lct(m: &MatFile<'_>, file: &Path) -> Result<Transient> {
    let width = positive_scalar(m, file, "width", "half the side of the square scan area, metres")?;
    let rect = m.numeric("rect_data", "Stanford LCT files hold the N×N×T histograms in `rect_data`")?;
    let [n, n2, bins] = dims3(&rect, file, "N×N×T (a square scan grid × time bins)")?;
    if n != n2 {
        return Err(wrong_shape(file, &rect.header, "N×N×T (a square scan grid × time bins)"));
    }
    // `numeric` checked that the data hold exactly n·n·bins elements, so this cannot overflow and is
    // bounded by the input.
    let plane = n * n;
    let mut data = vec![0.0f32; plane * bins];
    rect.for_each_f32(file, |idx, v| {
        let (i, j, k) = (idx % n, (idx / n) % n, idx / plane);
        // ix = N-1-i, iy = N-1-j (see the module docs for the evidence).
        let m = (n - 1 - i) + n * (n - 1 - j);
        if let Some(d) = data.get_mut(m * bins + k) {
            *d = v;
        }
    })?;
    let points = PointSet::wall_grid(n, n, width, width).map_err(|e| with_file(e, file))?;
    let time = TimeAxis::new(0.0, LCT_BIN_WIDTH, bins).map_err(|e| with_file(e, file))?;
    Transient::new(Scan::confocal(points), time, data).map_err(|e| with_file(e, file))
}

fn read_tsai(m: &MatFile<'_>, file: &Path) -> Result<Transient> {
    let name = if m.header("transient").is_none() && m.header("gt_transient").is_some() {
        "gt_transient"
    } else {
        "transient"
    };
    let tr = m.numeric(name, "Tsai 2019 files hold the M×T histograms in `transient`")?;
    let &[meas, bins] = tr.header.dims.as_slice() else {
        return Err(wrong_shape(file, &tr.header, "M×T (measurements × time bins)"));
    };
    if meas == 0 || bins == 0 {
        return Err(invalid(file, name, format!("{} has no data (zero measurements or bins)", tr.header.describe())));
    }
    let lighting = m.numeric("lighting", "Tsai 2019 files hold the M×3 laser/sensor positions in `lighting`")?;
    if lighting.header.dims != [meas, 3] {
        return Err(wrong_shape(file, &lighting.header, format!("{meas}×3 (one x, y, z row per measurement)")));
    }
    let bin_width = if m.header("bin_width").is_some() {
        positive_scalar(m, file, "bin_width", "bin width in metres of path length")?
    } else {
        TSAI_BIN_WIDTH
    };
    let l = lighting.to_f64(file)?;
    let rows = |v: &[f64]| -> Vec<Vec3> {
        let col = |c: usize, r: usize| v.get(r + meas * c).copied().unwrap_or(f64::NAN) as f32;
        (0..meas).map(|r| Vec3::new(col(0, r), col(1, r), col(2, r))).collect()
    };
    let points = rows(&l);
    // Their synthetic setups may hold `sensor` positions apart from `lighting`: a paired scan.
    let sensors = match m.header("sensor") {
        Some(_) => {
            let s = m.numeric("sensor", "")?;
            if s.header.dims != lighting.header.dims {
                return Err(wrong_shape(file, &s.header, format!("{meas}×3 (one x, y, z row per measurement)")));
            }
            let s = s.to_f64(file)?;
            (s != l).then(|| rows(&s))
        }
        None => None,
    };
    let mut data = vec![0.0f32; meas * bins];
    tr.for_each_f32(file, |idx, v| {
        let (r, k) = (idx % meas, idx / meas);
        if let Some(d) = data.get_mut(r * bins + k) {
            *d = v;
        }
    })?;
    let scan = match sensors {
        Some(s) => Scan::paired(PointSet::list(points), PointSet::list(s)),
        None => Scan::confocal(PointSet::list(points)),
    };
    let time = TimeAxis::new(0.0, bin_width, bins).map_err(|e| with_file(e, file))?;
    Transient::new(scan, time, data).map_err(|e| match with_file(e, file) {
        TransientError::NonFinite { file, field, index }
            if field.starts_with("scan_points") || field.starts_with("laser_points") =>
        {
            TransientError::NonFinite { file, field: "lighting".into(), index }
        }
        TransientError::NonFinite { file, field, index } if field.starts_with("sensor_points") => {
            TransientError::NonFinite { file, field: "sensor".into(), index }
        }
        e => e,
    })
}

fn read_fk(m: &MatFile<'_>, file: &Path) -> Result<Transient> {
    let half_width = if m.header("width").is_some() {
        positive_scalar(m, file, "width", "half the side of the scanned wall, metres")?
    } else if m.header("wall_size").is_some() {
        positive_scalar(m, file, "wall_size", "side of the scanned wall, metres")? / 2.0
    } else {
        FK_DEFAULT_HALF_WIDTH
    };
    let meas = m.numeric("meas", "Stanford f-k files hold the N×N×T histograms in `meas`")?;
    let dims = dims3(&meas, file, "N×N×T (scan rows y × columns x × time bins)")?;
    let (tof, tof_dims, tof_file) = if m.header("tofgrid").is_some() {
        let t = m.numeric("tofgrid", "")?;
        (t.to_f64(file)?, t.header.dims.clone(), file.to_path_buf())
    } else {
        sibling_tofgrid(file)?.ok_or_else(|| TransientError::MissingField {
            file: file.into(),
            field: "tofgrid".into(),
            hint: "the per-pixel device→wall→device time in ps; the f-k datasets ship it as `tof.mat` beside \
                   `meas_*.mat` — put a MAT v5 `tof.mat` beside this file or save `tofgrid` into it"
                .into(),
        })?
    };
    if tof_dims != dims[..2] {
        return Err(TransientError::WrongShape {
            file: tof_file,
            field: "tofgrid".into(),
            expected: format!("{}×{} (one delay per scan point of `meas`)", dims[0], dims[1]),
            found: tof_dims.iter().map(usize::to_string).collect::<Vec<_>>().join("×"),
        });
    }
    let values = meas.to_f32(file)?;
    drop(meas);
    fk_from_arrays(&values, dims, &tof, half_width, file)
}

/// A `tofgrid`: values (column-major), MATLAB dimensions, and the file it came from.
type TofGrid = (Vec<f64>, Vec<usize>, std::path::PathBuf);

/// Reads `tofgrid` from a MAT v5 `tof.mat` beside `file` (the layout of the f-k datasets), if there is one.
fn sibling_tofgrid(file: &Path) -> Result<Option<TofGrid>> {
    if file == Path::new(MEMORY) || file.file_name().is_some_and(|n| n == "tof.mat") {
        return Ok(None);
    }
    let path = file.with_file_name("tof.mat");
    if !path.is_file() {
        return Ok(None);
    }
    let bytes = read_file(&path)?;
    match sniff(&bytes) {
        Some(Container::MatV5) => {
            let m = MatFile::parse(&bytes, &path)?;
            if m.header("tofgrid").is_none() {
                return Ok(None);
            }
            let t = m.numeric("tofgrid", "")?;
            Ok(Some((t.to_f64(&path)?, t.header.dims.clone(), path.clone())))
        }
        Some(Container::MatV73) => Err(TransientError::Unsupported {
            file: path,
            what: "MAT v7.3 `tof.mat` beside a v5 f-k measurement file (save `tofgrid` into the measurement \
                   file, or re-save tof.mat with -v7)"
                .into(),
        }),
        _ => Ok(None),
    }
}

/// Builds a Stanford f-k transient from decoded arrays; shared by the MAT v5 reader and the v7.3 (HDF5)
/// reader.
///
/// - `meas`: the `meas` values in MATLAB column-major order, `dims = [rows, cols, bins]` in MATLAB order
///   (`meas(i, j, t)` at `i + rows·j + rows·cols·t`; row `i` is y, column `j` is x). An HDF5 reader of a
///   v7.3 file sees the dataset with its dimensions reversed (`[bins, cols, rows]`, C order) but the same
///   flat buffer: pass that buffer with the MATLAB dimensions.
/// - `tofgrid`: `rows × cols` delays in picoseconds, column-major (`tofgrid(i, j)` at `i + rows·j`).
/// - `half_width`: half the side of the scanned wall, metres ([`FK_DEFAULT_HALF_WIDTH`] when the file
///   does not say).
///
/// Result: confocal `cols × rows` wall grid ([`PointSet::wall_grid`] with both half widths
/// `half_width`), point `ix + cols·iy` with `ix = j`, `iy = rows−1−i`; each histogram shifted earlier
/// by exactly `tofgrid(i, j) / 32` bins (see the module docs); [`FK_BIN_WIDTH`] bins, `t0 = 0`,
/// `includes_device_legs = false`.
///
/// # Errors
/// [`TransientError::WrongShape`] when the lengths do not match `dims`; [`TransientError::InvalidValue`]
/// for a zero-sized grid or an invalid half width; [`TransientError::NonFinite`] naming `meas` or
/// `tofgrid`. All name `file`.
///
/// [`PointSet::wall_grid`]: crate::PointSet::wall_grid
pub(crate) fn fk_from_arrays(
    meas: &[f32],
    dims: [usize; 3],
    tofgrid: &[f64],
    half_width: f64,
    file: &Path,
) -> Result<Transient> {
    let [rows, cols, bins] = dims;
    if rows == 0 || cols == 0 || bins == 0 {
        return Err(invalid(file, "meas", format!("{rows}×{cols}×{bins} has no data (zero-sized scan grid)")));
    }
    let plane = rows.checked_mul(cols);
    let total = plane.and_then(|p| p.checked_mul(bins));
    let shape = |field: &str, expected: String, found: usize| TransientError::WrongShape {
        file: file.into(),
        field: field.into(),
        expected,
        found: format!("{found} values"),
    };
    let (Some(plane), Some(total)) = (plane, total) else {
        return Err(shape("meas", format!("{rows}×{cols}×{bins} values (overflows)"), meas.len()));
    };
    if meas.len() != total {
        return Err(shape("meas", format!("{rows}×{cols}×{bins} = {total} values"), meas.len()));
    }
    if tofgrid.len() != plane {
        return Err(shape("tofgrid", format!("{rows}×{cols} = {plane} values"), tofgrid.len()));
    }
    if !(half_width.is_finite() && half_width > 0.0) {
        return Err(invalid(file, "width", format!("half width {half_width} must be finite and > 0 metres")));
    }
    let non_finite = |field: &str, index| TransientError::NonFinite { file: file.into(), field: field.into(), index };
    if let Some(i) = meas.iter().position(|v| !v.is_finite()) {
        return Err(non_finite("meas", i));
    }
    if let Some(i) = tofgrid.iter().position(|v| !v.is_finite()) {
        return Err(non_finite("tofgrid", i));
    }
    let point = |i: usize, j: usize| j + cols * (rows - 1 - i);
    // Pass 1, in source order (cache-friendly reads): unshifted histograms, measurement-major.
    let mut data = vec![0.0f32; total];
    for (idx, &v) in meas.iter().enumerate() {
        let (i, j, k) = (idx % rows, (idx / rows) % cols, idx / plane);
        if let Some(d) = data.get_mut(point(i, j) * bins + k) {
            *d = v;
        }
    }
    // Pass 2: remove the device legs, per pixel.
    let mut scratch = vec![0.0f32; bins];
    for (p, &tof) in tofgrid.iter().enumerate() {
        let (i, j) = (p % rows, p / rows);
        let m = point(i, j);
        if let Some(h) = data.get_mut(m * bins..(m + 1) * bins) {
            scratch.copy_from_slice(h);
            crate::ops::shift_histogram(&scratch, tof / FK_BIN_PS, h);
        }
    }
    let points = PointSet::wall_grid(cols, rows, half_width, half_width).map_err(|e| with_file(e, file))?;
    let time = TimeAxis::new(0.0, FK_BIN_WIDTH, bins).map_err(|e| with_file(e, file))?;
    Transient::new(Scan::confocal(points), time, data).map_err(|e| with_file(e, file))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fk_from_arrays_shifts_and_orients() -> Result<()> {
        // 2 rows × 3 cols × 8 bins; pixel (i, j) has a single count at bin 4 + i, delay 32·(i + j) ps.
        let (rows, cols, bins) = (2, 3, 8);
        let mut meas = vec![0.0f32; rows * cols * bins];
        let mut tof = vec![0.0f64; rows * cols];
        for i in 0..rows {
            for j in 0..cols {
                meas[i + rows * j + rows * cols * (4 + i)] = 1.0 + (i * cols + j) as f32;
                tof[i + rows * j] = 32.0 * (i + j) as f64;
            }
        }
        let t = fk_from_arrays(&meas, [rows, cols, bins], &tof, 1.0, Path::new("x.mat"))?;
        assert_eq!(t.scan().lasers().grid_dims(), Some((cols, rows)));
        assert!(!t.time().includes_device_legs);
        for i in 0..rows {
            for j in 0..cols {
                let h = t.histogram(j + cols * (rows - 1 - i));
                let k = 4 + i - (i + j);
                assert_eq!(h[k], 1.0 + (i * cols + j) as f32, "pixel ({i}, {j})");
                assert_eq!(h.iter().sum::<f32>(), h[k]);
            }
        }
        // Row 0 of the MATLAB array is the top of the wall (largest y).
        assert!(t.scan().lasers().points[cols * (rows - 1)].y > 0.0);
        Ok(())
    }

    #[test]
    fn fk_from_arrays_rejects_bad_lengths_and_values() {
        let f = Path::new("x.mat");
        let r = fk_from_arrays(&[0.0; 7], [2, 2, 2], &[0.0; 4], 1.0, f);
        assert!(matches!(r, Err(TransientError::WrongShape { ref field, .. }) if field == "meas"), "{r:?}");
        let r = fk_from_arrays(&[0.0; 8], [2, 2, 2], &[0.0; 3], 1.0, f);
        assert!(matches!(r, Err(TransientError::WrongShape { ref field, .. }) if field == "tofgrid"), "{r:?}");
        let r = fk_from_arrays(&[0.0; 8], [2, 2, 2], &[0.0, f64::NAN, 0.0, 0.0], 1.0, f);
        assert!(matches!(r, Err(TransientError::NonFinite { index: 1, .. })), "{r:?}");
        let r = fk_from_arrays(&[], [0, 2, 2], &[], 1.0, f);
        assert!(matches!(r, Err(TransientError::InvalidValue { .. })), "{r:?}");
        let r = fk_from_arrays(&[0.0; 8], [2, 2, 2], &[0.0; 4], -1.0, f);
        assert!(matches!(r, Err(TransientError::InvalidValue { .. })), "{r:?}");
    }
}
