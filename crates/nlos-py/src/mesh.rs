//! Meshes as `(vertices (n, 3) float32, faces (m, 3) uint32)` pairs: reading, writing, and the metrics
//! of `nlos eval`.

use std::path::PathBuf;

use numpy::PyArray2;
use numpy::ndarray::Array2;
use pyo3::prelude::*;

use nlos_mesh::SurfaceMesh;
use nlos_mesh::metrics::{EvalParams, MAX_GRID, evaluate as eval_meshes, load_for_eval};

use crate::{arrays, errors};

/// A pair of NumPy arrays: vertices (n, 3) float32 and faces (m, 3) uint32.
pub(crate) type MeshArrays = (Py<PyArray2<f32>>, Py<PyArray2<u32>>);

pub(crate) fn to_arrays(py: Python<'_>, mesh: &SurfaceMesh) -> PyResult<MeshArrays> {
    let (positions, triangles) = mesh.to_triangles();
    let v = Array2::from_shape_vec((positions.len(), 3), positions.iter().flat_map(|p| p.to_array()).collect())
        .map_err(errors::mesh)?;
    let f = Array2::from_shape_vec((triangles.len(), 3), triangles.iter().flatten().copied().collect())
        .map_err(errors::mesh)?;
    Ok((PyArray2::from_owned_array(py, v).unbind(), PyArray2::from_owned_array(py, f).unbind()))
}

/// A mesh from `(vertices, faces)` arrays, checked.
pub(crate) fn from_arrays(name: &str, vertices: &Bound<'_, PyAny>, faces: &Bound<'_, PyAny>) -> PyResult<SurfaceMesh> {
    let positions = arrays::points(&format!("{name} vertices"), vertices, None)?;
    let triangles = arrays::faces(&format!("{name} faces"), faces, positions.len())?;
    SurfaceMesh::from_triangles(&positions, &triangles).map_err(|e| errors::mesh(format!("{name}: {e}")))
}

/// A mesh given as a path or as a `(vertices, faces)` pair.
fn mesh_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<SurfaceMesh> {
    if let Ok(path) = obj.extract::<PathBuf>() {
        return load_for_eval(&path).map_err(errors::mesh);
    }
    let (v, f): (Bound<'_, PyAny>, Bound<'_, PyAny>) = obj.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(format!("{name}: expected a path or a (vertices, faces) pair"))
    })?;
    from_arrays(name, &v, &f)
}

/// Reads a mesh (OBJ, PLY, GLB): `(vertices, faces)`.
#[pyfunction]
pub(crate) fn read_mesh(py: Python<'_>, path: PathBuf) -> PyResult<MeshArrays> {
    let mesh = py.detach(|| nlos_mesh::io::load(&path)).map_err(errors::mesh)?;
    to_arrays(py, &mesh)
}

/// Writes a mesh; the format follows the extension (`.obj`, `.ply`, `.glb`).
#[pyfunction]
pub(crate) fn write_mesh(path: PathBuf, vertices: &Bound<'_, PyAny>, faces: &Bound<'_, PyAny>) -> PyResult<()> {
    let mesh = from_arrays("mesh", vertices, faces)?;
    nlos_mesh::io::save(&mesh, &path).map_err(errors::mesh)
}

/// The metrics of `nlos eval` as a JSON string (the Python side makes them a `Metrics`): coverage and
/// depth errors on a `grid` × `grid` +z ray grid over `x_range` × `y_range` of the wall (default
/// [−0.25, 0.25]² m), Chamfer, Hausdorff, normal error.
#[pyfunction]
#[pyo3(signature = (mesh, gt, grid = 128, x_range = None, y_range = None))]
pub(crate) fn evaluate(
    py: Python<'_>,
    mesh: &Bound<'_, PyAny>,
    gt: &Bound<'_, PyAny>,
    grid: usize,
    x_range: Option<(f32, f32)>,
    y_range: Option<(f32, f32)>,
) -> PyResult<String> {
    if grid == 0 || grid > MAX_GRID {
        return Err(pyo3::exceptions::PyValueError::new_err(format!("grid: {grid} is not in 1..={MAX_GRID}")));
    }
    let range = |name: &str, r: Option<(f32, f32)>, default: [f32; 2]| match r {
        None => Ok(default),
        Some((a, b)) if a.is_finite() && b.is_finite() && a < b => Ok([a, b]),
        Some((a, b)) => Err(pyo3::exceptions::PyValueError::new_err(format!(
            "{name}: ({a}, {b}) must be finite with min < max (metres on the wall)"
        ))),
    };
    let defaults = EvalParams::default();
    let (x_range, y_range) =
        (range("x_range", x_range, defaults.x_range)?, range("y_range", y_range, defaults.y_range)?);
    let (reconstruction, truth) = (mesh_arg("mesh", mesh)?, mesh_arg("gt", gt)?);
    let params = EvalParams { grid, x_range, y_range, ..defaults };
    let metrics = py.detach(|| eval_meshes(&reconstruction, &truth, &params)).map_err(errors::mesh)?;
    serde_json::to_string(&metrics).map_err(errors::mesh)
}
