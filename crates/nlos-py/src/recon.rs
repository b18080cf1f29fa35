//! Volumes (LCT, f-k, FBP), the start surface and the reconstruction, all through the library pipeline
//! ([`nlos_optim::pipeline`]) with the settings of `nlos reconstruct --config`, given as JSON by the
//! Python side (a dict with the TOML file's sections).

use std::ops::ControlFlow;
use std::path::PathBuf;

use numpy::PyArray3;
use numpy::ndarray::Array3;
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use nlos_optim::pipeline::{self, Config, Method, Prepared, Start};
use nlos_optim::{Hooks, Progress, RunRecord};

use crate::capture::Capture;
use crate::errors::{self, ConfigError};

/// The settings, from the Python side's JSON (absent fields keep their defaults). They go through the TOML
/// reader of `nlos reconstruct --config`, whose errors quote the offending line (so name the field).
fn config(settings: &str) -> PyResult<Config> {
    config_over(None, settings)
}

/// The settings over `base` (a run's saved settings; none: the defaults): the given sections replace
/// `base`'s fields one by one ([`Config::overridden`]), as `--set` does on the command line.
fn config_over(base: Option<&Config>, settings: &str) -> PyResult<Config> {
    let json: serde_json::Value =
        serde_json::from_str(settings).map_err(|e| ConfigError::new_err(format!("settings: {e}")))?;
    let given = toml::Table::try_from(json).map_err(|e| ConfigError::new_err(format!("settings: {e}")))?;
    match base {
        None => Config::default().overridden(given),
        Some(base) => base.overridden(given),
    }
    .map_err(errors::optim)
}

/// The default settings as JSON (every field; the same values `nlos reconstruct --print-config` prints).
#[pyfunction]
pub(crate) fn default_settings() -> PyResult<String> {
    serde_json::to_string(&Config::default()).map_err(|e| ConfigError::new_err(e.to_string()))
}

/// A volumetric reconstruction of a capture: `method` `"lct"` (with `snr`), `"fk"`, `"fbp"`, `"pf"` or `"carve"`
/// (`nlos_init::Method`), on the capture
/// prepared as `nlos reconstruct` and `nlos init` prepare it with the default settings (`Prepared::volume`:
/// direct light gated automatically). Returns `(volume, axes)`: the volume (nx, ny, nz) float32 and
/// `{"x"|"y"|"z": (first voxel centre, spacing)}` in metres.
#[pyfunction]
#[pyo3(signature = (capture, method = "lct", snr = None))]
pub(crate) fn volume<'py>(
    py: Python<'py>,
    capture: PyRef<'py, Capture>,
    method: &str,
    snr: Option<f64>,
) -> PyResult<(Py<PyArray3<f32>>, Bound<'py, PyDict>)> {
    let t = capture.transient(py)?;
    let method: Method = method.parse().map_err(|e| pyo3::exceptions::PyValueError::new_err(format!("method: {e}")))?;
    let config = Config::default();
    let vol = py
        .detach(|| Prepared::new(t, &config).and_then(|p| p.volume(method, nlos_init::Model::Lambert, snr)))
        .map_err(errors::optim)?;
    let axes = PyDict::new(py);
    for (name, axis) in [("x", vol.x), ("y", vol.y), ("z", vol.z)] {
        axes.set_item(name, (axis.start, axis.step))?;
    }
    // `data[(ix + nx·iy)·nz + iz]` is C order for the shape (ny, nx, nz).
    let array = Array3::from_shape_vec((vol.ny, vol.nx, vol.nz), vol.data).map_err(errors::init)?;
    Ok((PyArray3::from_owned_array(py, array).unbind(), axes))
}

/// The start surface `nlos reconstruct` would begin from with these settings: `(vertices, faces)`.
#[pyfunction]
pub(crate) fn initial_surface(
    py: Python<'_>,
    capture: PyRef<'_, Capture>,
    settings: &str,
) -> PyResult<crate::mesh::MeshArrays> {
    let config = config(settings)?;
    let t = capture.transient(py)?;
    let mesh =
        py.detach(|| Prepared::new(t, &config).and_then(|p| p.initial_surface(&config))).map_err(errors::optim)?;
    crate::mesh::to_arrays(py, &mesh)
}

/// Reconstructs the hidden surface, as `nlos reconstruct` does: returns a dict with `vertices`, `faces`,
/// `reflectance`, `scale`, `stop`, `notes` and `log` (the run log as JSON text). With `out`, the run
/// directory gets `mesh.obj`, `init.obj`, `settings.toml`, the run log and checkpoints, exactly as `nlos
/// reconstruct --out` writes them (`resume=True` continues from them, leaving `settings.toml` as the run
/// was started). `progress(dict)` is called after every iteration; Ctrl-C stops the run after the
/// current block's checkpoint and raises `KeyboardInterrupt`.
#[pyfunction]
#[pyo3(signature = (capture, settings, out = None, resume = false, progress = None))]
pub(crate) fn reconstruct<'py>(
    py: Python<'py>,
    capture: PyRef<'py, Capture>,
    settings: &str,
    out: Option<PathBuf>,
    resume: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let saved = match (&out, resume) {
        (Some(dir), true) => pipeline::saved_config(dir).map_err(errors::optim)?,
        (None, true) => return Err(ConfigError::new_err("resume: a run directory (out) is needed to resume from")),
        _ => None,
    };
    // Resuming, the run's own settings are the base (as `nlos reconstruct --resume`).
    let config = config_over(saved.as_ref(), settings)?;
    let t = capture.transient(py)?;
    let prepared = py.detach(|| Prepared::new(t, &config)).map_err(errors::optim)?;
    let params = prepared.params(&config, out.clone()).map_err(errors::optim)?;
    let start = if resume { Start::Resume } else { Start::New };
    let mut interrupt: Option<PyErr> = None;
    let mut callback_error: Option<PyErr> = None;
    let outcome = py.detach(|| {
        let mut on_progress = |p: &Progress| -> ControlFlow<()> {
            Python::attach(|py| {
                if let Err(e) = py.check_signals() {
                    if e.is_instance_of::<PyKeyboardInterrupt>(py) {
                        interrupt.get_or_insert(e);
                    } else {
                        callback_error.get_or_insert(e);
                    }
                }
                if let Some(cb) = &progress {
                    let record = PyDict::new(py);
                    let _ = record.set_item("stage", p.stage);
                    let _ = record.set_item("iteration", p.iteration);
                    let _ = record.set_item("iterations_planned", p.iterations_planned);
                    let _ = record.set_item("loss", p.loss);
                    let _ = record.set_item("faces", p.faces);
                    let _ = record.set_item("elapsed_s", p.elapsed_s);
                    if let Err(e) = cb.call1(py, (record,)) {
                        callback_error.get_or_insert(e);
                    }
                }
            });
            if interrupt.is_some() || callback_error.is_some() {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        };
        let hooks = Hooks { progress: Some(&mut on_progress), evolve: None };
        pipeline::run(&prepared, &config, &params, start, hooks)
    });
    if let Some(e) = interrupt.or(callback_error) {
        return Err(e);
    }
    let outcome = outcome.map_err(errors::optim)?;
    let result = PyDict::new(py);
    let (v, f) = crate::mesh::to_arrays(py, &outcome.mesh)?;
    result.set_item("vertices", v)?;
    result.set_item("faces", f)?;
    let brdf = outcome.reflectance.brdf().map_err(errors::optim)?;
    result.set_item("reflectance", to_json(&brdf)?)?;
    result.set_item("log", to_json(&outcome.log)?)?;
    result.set_item("stop", to_json(&outcome.stop)?)?;
    result.set_item("scale", outcome.scale)?;
    result.set_item("albedo", outcome.albedo.clone().map(|a| numpy::PyArray1::from_vec(py, a)))?;
    result.set_item("support", outcome.support.clone().map(|s| numpy::PyArray1::from_vec(py, s)))?;
    result.set_item("notes", prepared.notes.clone())?;
    set_fit(&result, outcome.log.fit.as_ref())?;
    // The run directory holds everything by now; a run that kept almost no surface, or whose surface explains
    // no more than an empty scene, raises, saying why, with
    // what it made as the exception's `result` (the Python side turns it into a `Reconstruction`).
    if let Err(e) = outcome.check_surface_kept().and_then(|()| outcome.check_explains()) {
        let err = errors::optim(e);
        err.value(py).setattr("result", &result)?;
        return Err(err);
    }
    Ok(result)
}

/// The run recorded in run directory `dir` (its checkpoint, read through [`RunRecord::read`], the one way any
/// crate reads it): the surface and fit as its last finished block left them, in the dictionary
/// [`reconstruct`] returns (`stop` is null while the run has blocks left; `notes` is empty: they belong to
/// the capture's preparation, not to the record).
#[pyfunction]
pub(crate) fn read_run(py: Python<'_>, dir: PathBuf) -> PyResult<Bound<'_, PyDict>> {
    let record = py.detach(|| RunRecord::read(&dir)).map_err(errors::optim)?;
    let mesh = record.surface().mesh().map_err(errors::optim)?;
    let result = PyDict::new(py);
    let (v, f) = crate::mesh::to_arrays(py, &mesh)?;
    result.set_item("vertices", v)?;
    result.set_item("faces", f)?;
    let brdf = record.reflectance().brdf().map_err(errors::optim)?;
    result.set_item("reflectance", to_json(&brdf)?)?;
    result.set_item("log", to_json(record.log())?)?;
    result.set_item("stop", to_json(&record.finished())?)?;
    result.set_item("scale", record.scale())?;
    let albedo: Option<Vec<f32>> = record.albedo().map(|a| a.iter().map(|&x| x as f32).collect());
    result.set_item("albedo", albedo.map(|a| numpy::PyArray1::from_vec(py, a)))?;
    result.set_item("support", record.vertex_support().map(|s| numpy::PyArray1::from_vec(py, s)))?;
    result.set_item("notes", Vec::<String>::new())?;
    set_fit(&result, record.log().fit.as_ref())?;
    Ok(result)
}

/// The fit-quality verdict in words (`fit`) and the share of the light it explains (`explained`), None for a
/// run not finished ([`nlos_optim::FitQuality`]).
fn set_fit(result: &Bound<'_, PyDict>, fit: Option<&nlos_optim::FitQuality>) -> PyResult<()> {
    result.set_item("fit", fit.map(nlos_optim::FitQuality::describe))?;
    result.set_item("explained", fit.and_then(nlos_optim::FitQuality::explained))
}

/// JSON text of a serialisable part of the outcome (the Python side parses it).
fn to_json<T: serde::Serialize>(value: &T) -> PyResult<String> {
    serde_json::to_string(value).map_err(|e| errors::ReconstructError::new_err(format!("encoding the outcome: {e}")))
}
