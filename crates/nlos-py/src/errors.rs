//! The package's exceptions: one base class, one subclass per library crate's error, so that a user can
//! catch `nlos.NlosError` or the precise kind. Bad arrays are `ValueError`s (as NumPy's own), raised by
//! [`crate::arrays`].

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(nlos, NlosError, PyException, "Base class of every error raised by nlos.");
create_exception!(
    nlos,
    CaptureError,
    NlosError,
    "A capture file cannot be read or written (truncated, malformed, unsupported), or its contents are invalid."
);
create_exception!(nlos, MeshError, NlosError, "A mesh is unusable (malformed file, non-manifold, degenerate, empty).");
create_exception!(nlos, RenderError, NlosError, "The renderer refused its inputs (mesh, setup or reflectance).");
create_exception!(nlos, InitError, NlosError, "A volumetric reconstruction (LCT, f-k, FBP) failed.");
create_exception!(
    nlos,
    ConfigError,
    NlosError,
    "A reconstruction setting is unknown or out of range, or a resumed run's settings differ."
);
create_exception!(nlos, ReconstructError, NlosError, "The reconstruction failed (diverged, checkpoint, output).");

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("NlosError", py.get_type::<NlosError>())?;
    m.add("CaptureError", py.get_type::<CaptureError>())?;
    m.add("MeshError", py.get_type::<MeshError>())?;
    m.add("RenderError", py.get_type::<RenderError>())?;
    m.add("InitError", py.get_type::<InitError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("ReconstructError", py.get_type::<ReconstructError>())?;
    Ok(())
}

pub(crate) fn capture(e: impl std::fmt::Display) -> PyErr {
    CaptureError::new_err(e.to_string())
}

pub(crate) fn mesh(e: impl std::fmt::Display) -> PyErr {
    MeshError::new_err(e.to_string())
}

pub(crate) fn render(e: impl std::fmt::Display) -> PyErr {
    RenderError::new_err(e.to_string())
}

pub(crate) fn init(e: impl std::fmt::Display) -> PyErr {
    InitError::new_err(e.to_string())
}

/// An error of the reconstruction crate, as the exception its kind calls for.
pub(crate) fn optim(e: nlos_optim::OptimError) -> PyErr {
    use nlos_optim::OptimError as E;
    match e {
        E::Config { .. } | E::SettingsChanged { .. } | E::InvalidParameter { .. } => {
            ConfigError::new_err(e.to_string())
        }
        E::Capture { .. } => CaptureError::new_err(e.to_string()),
        E::Mesh(_) | E::EmptyMesh { .. } => MeshError::new_err(e.to_string()),
        E::Init(_) => InitError::new_err(e.to_string()),
        other => ReconstructError::new_err(other.to_string()),
    }
}
