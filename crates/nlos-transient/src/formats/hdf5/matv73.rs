//! MATLAB v7.3 MAT-files (HDF5 with a 512-byte MATLAB header): Stanford f-k (`meas`, `tofgrid`) and
//! Stanford LCT (`rect_data`, `width`).
//!
//! MATLAB writes an array of size `d1×…×dn` as an HDF5 dataset of dimensions `(dn, …, d1)` holding the
//! column-major values unchanged, with a `MATLAB_class` attribute (`double`, `single`, `uint16`, …). We
//! reverse the dimensions back to MATLAB's and keep the flat order, then apply the same conventions as
//! the MAT v5 readers in [`mat`](super::super::mat) (see its module docs and
//! [`fk_from_arrays`](super::super::mat)): f-k 32 ps bins, `tofgrid` removed per pixel, 2 m wall unless
//! `width`/`wall_size` say otherwise; LCT 1.2 mm bins, scan points `linspace(-width, width, N)`, MAT
//! index `i` along −x and `j` along −y. The `MATLAB_class` attribute is honoured: numeric classes are
//! converted from the storage type; `char`, `logical`, `cell`, `struct` and the like are rejected.

use super::{ArrayF64, H5, attr_text, shape_str};
use crate::error::{Result, TransientError};
use crate::formats::mat::{FK_DEFAULT_HALF_WIDTH, LCT_BIN_WIDTH, fk_from_arrays};
use crate::formats::with_file;
use crate::scan::{PointSet, Scan};
use crate::time_axis::TimeAxis;
use crate::transient::Transient;

const NUMERIC_CLASSES: [&str; 10] =
    ["double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"];

/// Checks the `MATLAB_class` attribute of `name` (when present) is numeric.
fn check_class(h: &H5<'_>, name: &str) -> Result<()> {
    let attrs = h.dataset_attrs(name);
    if let Some(class) = attrs.get("MATLAB_class").and_then(attr_text)
        && !NUMERIC_CLASSES.contains(&class.as_str())
    {
        return Err(TransientError::WrongType {
            file: h.path().into(),
            field: name.into(),
            expected: "a numeric MATLAB class (double, single, intN, uintN)".into(),
            found: format!("MATLAB class `{class}`"),
        });
    }
    Ok(())
}

/// MATLAB dimensions (HDF5 dimensions reversed) of a numeric variable.
fn matlab_dims(a: &ArrayF64) -> Vec<usize> {
    a.shape.iter().rev().copied().collect()
}

fn dims3(h: &H5<'_>, name: &str, dims: &[usize], expected: &str) -> Result<[usize; 3]> {
    match dims {
        [a, b, c] => Ok([*a, *b, *c]),
        _ => Err(TransientError::WrongShape {
            file: h.path().into(),
            field: name.into(),
            expected: expected.into(),
            found: shape_str(dims),
        }),
    }
}

fn optional_positive(h: &H5<'_>, name: &str) -> Result<Option<f64>> {
    if !h.has(name) {
        return Ok(None);
    }
    check_class(h, name)?;
    let v = h.finite_scalar(name, "")?;
    if v > 0.0 {
        Ok(Some(v))
    } else {
        Err(TransientError::InvalidValue {
            file: h.path().into(),
            field: name.into(),
            reason: format!("{v} must be > 0 metres"),
        })
    }
}

pub(super) fn read_fk(h: &H5<'_>) -> Result<Transient> {
    let file = h.path();
    let half_width = match (optional_positive(h, "width")?, optional_positive(h, "wall_size")?) {
        (Some(w), _) => w,
        (None, Some(s)) => s / 2.0,
        (None, None) => FK_DEFAULT_HALF_WIDTH,
    };
    check_class(h, "meas")?;
    let (shape, meas) = h.f32_array("meas", "Stanford f-k files hold the N×N×T histograms in `meas`")?;
    let dims: Vec<usize> = shape.iter().rev().copied().collect();
    let dims = dims3(h, "meas", &dims, "N×N×T in MATLAB (T×N×N in HDF5)")?;
    if !h.has("tofgrid") {
        return Err(TransientError::MissingField {
            file: file.into(),
            field: "tofgrid".into(),
            hint: "the per-pixel device→wall→device time in ps; save `tofgrid` (from the dataset's tof.mat) \
                   into this file"
                .into(),
        });
    }
    check_class(h, "tofgrid")?;
    let tof = h.f64_array("tofgrid", "")?;
    if matlab_dims(&tof) != dims[..2] {
        return Err(TransientError::WrongShape {
            file: file.into(),
            field: "tofgrid".into(),
            expected: format!("{}×{} (one delay per scan point of `meas`)", dims[0], dims[1]),
            found: shape_str(&matlab_dims(&tof)),
        });
    }
    fk_from_arrays(&meas, dims, &tof.values, half_width, file)
}

pub(super) fn read_lct(h: &H5<'_>) -> Result<Transient> {
    let file = h.path();
    check_class(h, "width")?;
    let width = h.finite_scalar("width", "half the side of the square scan area, metres")?;
    check_class(h, "rect_data")?;
    let (shape, rect) = h.f32_array("rect_data", "Stanford LCT files hold the N×N×T histograms in `rect_data`")?;
    let dims: Vec<usize> = shape.iter().rev().copied().collect();
    let [n, n2, bins] = dims3(h, "rect_data", &dims, "N×N×T in MATLAB (T×N×N in HDF5)")?;
    if n != n2 || n == 0 || bins == 0 {
        return Err(TransientError::WrongShape {
            file: file.into(),
            field: "rect_data".into(),
            expected: "N×N×T with N, T > 0 (a square scan grid × time bins)".into(),
            found: shape_str(&dims),
        });
    }
    if let Some(i) = rect.iter().position(|v| !v.is_finite()) {
        return Err(TransientError::NonFinite { file: file.into(), field: "rect_data".into(), index: i });
    }
    let plane = n * n;
    let mut data = vec![0.0f32; plane * bins];
    for (idx, &v) in rect.iter().enumerate() {
        let (i, j, k) = (idx % n, (idx / n) % n, idx / plane);
        // ix = N-1-i, iy = N-1-j, as the MAT v5 LCT reader (see `mat` module docs).
        let m = (n - 1 - i) + n * (n - 1 - j);
        if let Some(d) = data.get_mut(m * bins + k) {
            *d = v;
        }
    }
    let points = PointSet::wall_grid(n, n, width, width).map_err(|e| match with_file(e, file) {
        TransientError::InvalidValue { file, reason, .. } => {
            TransientError::InvalidValue { file, field: "width".into(), reason }
        }
        e => e,
    })?;
    let time = TimeAxis::new(0.0, LCT_BIN_WIDTH, bins).map_err(|e| with_file(e, file))?;
    Transient::new(Scan::confocal(points), time, data).map_err(|e| with_file(e, file))
}
