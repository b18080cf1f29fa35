//! `nlos.Capture`: a transient capture whose histograms live in a NumPy array.
//!
//! The array is the capture's storage: [`load`] moves the reader's buffer into NumPy without a copy, and
//! `Capture.data` returns that same array every time (writes to it change the capture). The geometry
//! (scan points, laser points, grid) and the time axis are read-only properties.

use std::path::PathBuf;

use numpy::PyArray2;
use numpy::ndarray::Array2;
use pyo3::prelude::*;

use nlos_transient::{Format, PatternKind, PointSet, Scan, TimeAxis, Transient};

use crate::{arrays, errors};

/// A transient capture: `data[m, k]` is measurement `m`'s bin `k`, the integral over path lengths
/// `[t0 + k·dt, t0 + (k+1)·dt)` of the light that went laser spot → hidden scene → sensor spot.
#[pyclass(module = "nlos")]
pub(crate) struct Capture {
    pub(crate) scan: Scan,
    pub(crate) time: TimeAxis,
    pub(crate) format: Option<Format>,
    pub(crate) data: Py<PyArray2<f32>>,
}

impl Capture {
    /// Wraps a transient, moving its buffer into NumPy.
    pub(crate) fn new(py: Python<'_>, t: Transient, format: Option<Format>) -> PyResult<Self> {
        let (m, bins) = (t.measurements(), t.bins());
        let (scan, time, data) = t.into_parts();
        let array = Array2::from_shape_vec((m, bins), data).map_err(errors::capture)?;
        Ok(Self { scan, time, format, data: PyArray2::from_owned_array(py, array).unbind() })
    }

    /// The capture as the library's type (one copy of the histograms, checked finite).
    pub(crate) fn transient(&self, py: Python<'_>) -> PyResult<Transient> {
        let data = self.data.bind(py);
        let (values, _) =
            arrays::floats_2d("Capture.data", data.as_any(), Some(self.scan.measurements()), Some(self.time.bins))?;
        Transient::new(self.scan.clone(), self.time, values).map_err(errors::capture)
    }
}

fn points_array<'py>(py: Python<'py>, points: &PointSet) -> PyResult<Bound<'py, PyArray2<f32>>> {
    vec3_array(py, &points.points)
}

fn normals_array<'py>(py: Python<'py>, points: &PointSet) -> PyResult<Bound<'py, PyArray2<f32>>> {
    vec3_array(py, &points.normals)
}

fn vec3_array<'py>(py: Python<'py>, v: &[glam::Vec3]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let flat: Vec<f32> = v.iter().flat_map(|p| p.to_array()).collect();
    let array = Array2::from_shape_vec((v.len(), 3), flat).map_err(errors::capture)?;
    Ok(PyArray2::from_owned_array(py, array))
}

#[pymethods]
impl Capture {
    /// The histograms, measurements × bins, float32: the capture's own storage (no copy).
    #[getter]
    fn data(&self, py: Python<'_>) -> Py<PyArray2<f32>> {
        self.data.clone_ref(py)
    }

    /// Sensor spots on the wall, (n, 3) metres (for a confocal scan also the laser spots).
    #[getter]
    fn scan_points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        points_array(py, self.scan.sensors())
    }

    /// Laser spots on the wall, (n, 3) metres.
    #[getter]
    fn laser_points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        points_array(py, self.scan.lasers())
    }

    /// Whether laser and sensor spots coincide (one measurement per spot).
    #[getter]
    fn confocal(&self) -> bool {
        self.scan.is_confocal()
    }

    /// `(nx, ny)` when the sensor spots form a grid (x fastest), else None.
    #[getter]
    fn grid(&self) -> Option<(usize, usize)> {
        self.scan.sensors().grid_dims()
    }

    /// Path length at the start of bin 0, metres.
    #[getter]
    fn t0(&self) -> f64 {
        self.time.t0
    }

    /// Bin width, metres of path.
    #[getter]
    fn dt(&self) -> f64 {
        self.time.bin_width
    }

    /// Number of time bins.
    #[getter]
    fn bins(&self) -> usize {
        self.time.bins
    }

    /// Number of measurements (rows of `data`).
    #[getter]
    fn measurements(&self) -> usize {
        self.scan.measurements()
    }

    /// The format the capture was read from (`"lct-mat"`, `"tal"`, …), or None.
    #[getter]
    fn format(&self) -> Option<&'static str> {
        self.format.map(Format::name)
    }

    /// A capture from arrays: `data` (measurements × bins), `scan_points` (n, 3) the sensor spots,
    /// `laser_points` (n_l, 3) for a non-confocal scan (None: confocal), the time axis `t0`, `dt` (metres of
    /// path), `grid = (nx, ny)` when the sensor spots are a grid. `pattern`: `"exhaustive"` (every laser
    /// spot with every sensor spot, `m = il·n + is`; the default with `laser_points`) or `"paired"`
    /// (measurement `m` = laser spot `m` with sensor spot `m`, as many of each). The wall's normals are +z;
    /// [`Capture::with_normals`] sets them for a curved wall.
    #[staticmethod]
    #[pyo3(signature = (data, scan_points, *, dt, t0 = 0.0, laser_points = None, grid = None, pattern = None))]
    fn from_arrays(
        data: &Bound<'_, PyAny>,
        scan_points: &Bound<'_, PyAny>,
        dt: f64,
        t0: f64,
        laser_points: Option<&Bound<'_, PyAny>>,
        grid: Option<(usize, usize)>,
        pattern: Option<&str>,
    ) -> PyResult<Self> {
        let value = pyo3::exceptions::PyValueError::new_err;
        let mut sensor_set = PointSet::list(arrays::points("scan_points", scan_points, None)?);
        if let Some((nx, ny)) = grid {
            if nx * ny != sensor_set.len() {
                return Err(value(format!(
                    "grid: {nx} × {ny} = {} spots, but scan_points has {}",
                    nx * ny,
                    sensor_set.len()
                )));
            }
            sensor_set.layout = nlos_transient::Layout::Grid { nx, ny };
        }
        let lasers = laser_points.map(|l| arrays::points("laser_points", l, None).map(PointSet::list)).transpose()?;
        let kind = pattern.map(str::parse::<PatternKind>).transpose().map_err(|e| value(format!("pattern: {e}")))?;
        let scan = match (kind, lasers) {
            (None | Some(PatternKind::Confocal), None) => Scan::confocal(sensor_set),
            (None | Some(PatternKind::Exhaustive), Some(l)) => Scan::exhaustive(l, sensor_set),
            (Some(PatternKind::Paired), Some(l)) => Scan::paired(l, sensor_set),
            (Some(p @ (PatternKind::Exhaustive | PatternKind::Paired)), None) => {
                return Err(value(format!("pattern: \"{p}\" needs laser_points")));
            }
            (Some(PatternKind::Confocal), Some(_)) => {
                return Err(value("pattern: \"confocal\" takes no laser_points".to_string()));
            }
        };
        scan.validate().map_err(errors::capture)?;
        let (values, [_, bins]) = arrays::floats_2d("data", data, Some(scan.measurements()), None)?;
        let time = TimeAxis::new(t0, dt, bins).map_err(|e| value(format!("t0, dt: {e}")))?;
        let t = Transient::new(scan, time, values).map_err(errors::capture)?;
        Self::new(data.py(), t, None)
    }

    /// The same capture (sharing `data`) with the relay wall's unit normals at each sensor spot
    /// (`scan_normals`, shaped as `scan_points`) and, for a non-confocal scan, at each laser spot
    /// (`laser_normals`; None keeps them): for a curved wall.
    #[pyo3(signature = (scan_normals, laser_normals = None))]
    fn with_normals(
        &self,
        py: Python<'_>,
        scan_normals: &Bound<'_, PyAny>,
        laser_normals: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let mut scan = self.scan.clone();
        let n_s = arrays::points("scan_normals", scan_normals, Some(scan.sensors().len()))?;
        let n_l = laser_normals.map(|n| arrays::points("laser_normals", n, Some(scan.lasers().len()))).transpose()?;
        match (&mut scan.pattern, n_l) {
            (nlos_transient::ScanPattern::Confocal(p), None) => p.normals = n_s,
            (nlos_transient::ScanPattern::Confocal(_), Some(_)) => {
                return Err(pyo3::exceptions::PyValueError::new_err(
                    "laser_normals: a confocal scan's laser spots are its sensor spots; give scan_normals only",
                ));
            }
            (
                nlos_transient::ScanPattern::Exhaustive { lasers, sensors }
                | nlos_transient::ScanPattern::Paired { lasers, sensors },
                n_l,
            ) => {
                sensors.normals = n_s;
                if let Some(n) = n_l {
                    lasers.normals = n;
                }
            }
        }
        scan.validate().map_err(errors::capture)?;
        Ok(Self { scan, time: self.time, format: self.format, data: self.data.clone_ref(py) })
    }

    /// How laser and sensor spots pair up: `"confocal"`, `"exhaustive"` or `"paired"`.
    #[getter]
    fn pattern(&self) -> &'static str {
        self.scan.pattern_name()
    }

    /// The wall's unit normal at each sensor spot, (n, 3).
    #[getter]
    fn scan_normals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        normals_array(py, self.scan.sensors())
    }

    /// The wall's unit normal at each laser spot, (n_l, 3).
    #[getter]
    fn laser_normals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        normals_array(py, self.scan.lasers())
    }

    /// Writes the capture: format from `format` (`"tal"`, `"npy"`, `"exr"`) or from the extension
    /// (`.hdf5`/`.h5` y-tal HDF5, `.npy` with its `.json` sidecar, `.exr`).
    #[pyo3(signature = (path, format = None))]
    fn save(&self, py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<()> {
        let format = match format {
            Some(name) => Format::from_name(name).filter(|f| f.can_write()).ok_or_else(|| {
                pyo3::exceptions::PyValueError::new_err(format!("format: {name:?} is not one of tal, npy, exr"))
            })?,
            None => Format::for_writing_extension(&path).ok_or_else(|| {
                pyo3::exceptions::PyValueError::new_err(format!(
                    "path: cannot tell the format of {} from its extension; use .hdf5, .npy or .exr or pass format",
                    path.display()
                ))
            })?,
        };
        let t = self.transient(py)?;
        py.detach(|| nlos_transient::write(&t, &path, format)).map_err(errors::capture)
    }

    /// The scan and the time axis in the words every `nlos` message uses (`Scan::describe`,
    /// `TimeAxis::describe`).
    fn __repr__(&self) -> String {
        format!(
            "Capture({}; {}{})",
            self.scan.describe(),
            self.time.describe(),
            self.format.map_or_else(String::new, |f| format!("; read as {}", f.name()))
        )
    }
}

/// Reads a capture in any supported format (detected from the content). `bin_width_ps`: the bin width
/// for files that do not store it (general-NLOS `data.mat` + `setup.mat`: 32).
#[pyfunction]
#[pyo3(signature = (path, *, bin_width_ps = None))]
pub(crate) fn load(py: Python<'_>, path: PathBuf, bin_width_ps: Option<f64>) -> PyResult<Capture> {
    let options = nlos_transient::ReadOptions::with_bin_width_ps(bin_width_ps);
    let (t, format) = py
        .detach(|| {
            nlos_transient::detect(&path).and_then(|f| nlos_transient::read_with(&path, &options).map(|t| (t, f)))
        })
        .map_err(errors::capture)?;
    Capture::new(py, t, Some(format))
}

/// An empty capture (zeros) that only carries a geometry and a time axis: the setup to render with.
/// Defaults are Tsai et al. 2019's setup: confocal 64 × 64 spots over [−0.25, 0.25]² m, 1200 bins of 1.2 mm.
#[pyfunction]
#[pyo3(signature = (n = 64, half_width = 0.25, bins = 1200, dt = 0.0012, t0 = 0.0))]
pub(crate) fn confocal_setup(
    py: Python<'_>,
    n: usize,
    half_width: f64,
    bins: usize,
    dt: f64,
    t0: f64,
) -> PyResult<Capture> {
    let value = |e: nlos_transient::TransientError| pyo3::exceptions::PyValueError::new_err(e.to_string());
    let scan = Scan::confocal(PointSet::wall_grid(n, n, half_width, half_width).map_err(value)?);
    let time = TimeAxis::new(t0, dt, bins).map_err(value)?;
    Capture::new(py, Transient::zeros(scan, time).map_err(value)?, None)
}
