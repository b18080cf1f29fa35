//! Checked reading of NumPy arrays (or anything `numpy.asarray` accepts): shape, dtype, finiteness and
//! index range, each failure a `ValueError` that names the argument and says what was expected.

use glam::Vec3;
use numpy::{PyArrayDescrMethods, PyReadonlyArray2, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

fn bad(name: &str, what: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{name}: {what}"))
}

/// `numpy.asarray(obj)` as an untyped array.
fn as_array<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyUntypedArray>> {
    let np = obj.py().import("numpy")?;
    let arr = np.call_method1("asarray", (obj,)).map_err(|e| bad(name, format!("not an array ({e})")))?;
    arr.cast_into::<PyUntypedArray>().map_err(|_| bad(name, "not an array"))
}

/// Whether the array's dtype is a floating-point kind, and which width.
fn float_kind(name: &str, arr: &Bound<'_, PyUntypedArray>) -> PyResult<()> {
    let dtype = arr.dtype();
    if dtype.kind() == b'f' && (dtype.itemsize() == 4 || dtype.itemsize() == 8) {
        Ok(())
    } else {
        Err(bad(name, format!("dtype {dtype} is not float32 or float64")))
    }
}

/// A 2-D float array of shape `(rows?, cols?)` (None: any), as row-major `f32` values and its shape.
pub(crate) fn floats_2d(
    name: &str,
    obj: &Bound<'_, PyAny>,
    rows: Option<usize>,
    cols: Option<usize>,
) -> PyResult<(Vec<f32>, [usize; 2])> {
    let arr = as_array(name, obj)?;
    float_kind(name, &arr)?;
    let shape = arr.shape().to_vec();
    let expected = |n: Option<usize>| n.map_or_else(|| "N".to_string(), |n| n.to_string());
    if shape.len() != 2 || rows.is_some_and(|r| r != shape[0]) || cols.is_some_and(|c| c != shape[1]) {
        return Err(bad(name, format!("shape {shape:?}, expected ({}, {})", expected(rows), expected(cols))));
    }
    let np = obj.py().import("numpy")?;
    // float32, C order: a view when it already is, one conversion otherwise.
    let c = np.call_method1("ascontiguousarray", (arr, "float32"))?;
    let typed: PyReadonlyArray2<'_, f32> = c.extract()?;
    let values = typed.as_slice().map_err(|e| bad(name, e))?.to_vec();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(bad(
            name,
            format!("element {} (row {}) is {}; every value must be finite", i, i / shape[1].max(1), values[i]),
        ));
    }
    Ok((values, [shape[0], shape[1]]))
}

/// An `(n, 3)` float array of points (vertex positions, wall points).
pub(crate) fn points(name: &str, obj: &Bound<'_, PyAny>, n: Option<usize>) -> PyResult<Vec<Vec3>> {
    let (v, _) = floats_2d(name, obj, n, Some(3))?;
    Ok(v.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
}

/// An `(m, 3)` integer array of triangle corners, each in `0..vertices`.
pub(crate) fn faces(name: &str, obj: &Bound<'_, PyAny>, vertices: usize) -> PyResult<Vec<[u32; 3]>> {
    let arr = as_array(name, obj)?;
    let dtype = arr.dtype();
    if !matches!(dtype.kind(), b'i' | b'u') {
        return Err(bad(name, format!("dtype {dtype} is not an integer type")));
    }
    let shape = arr.shape().to_vec();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(bad(name, format!("shape {shape:?}, expected (M, 3)")));
    }
    let np = obj.py().import("numpy")?;
    let c = np.call_method1("ascontiguousarray", (arr, "int64"))?;
    let typed: PyReadonlyArray2<'_, i64> = c.extract()?;
    let values = typed.as_slice().map_err(|e| bad(name, e))?;
    let mut out = Vec::with_capacity(shape[0]);
    for (t, tri) in values.chunks_exact(3).enumerate() {
        let mut corners = [0u32; 3];
        for (k, &i) in tri.iter().enumerate() {
            if i < 0 || i as u64 >= vertices as u64 {
                return Err(bad(name, format!("face {t} corner {k} is {i}; indices must lie in 0..{vertices}")));
            }
            corners[k] = i as u32;
        }
        out.push(corners);
    }
    Ok(out)
}
