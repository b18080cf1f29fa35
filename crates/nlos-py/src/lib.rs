//! # nlos-py
//!
//! The Python module `nlos._nlos`, wrapped by the pure-Python package `nlos` (`python/nlos/`). Thin
//! wrappers only: every computation is a call into the library crates, and every setting of a
//! reconstruction goes through [`nlos_optim::pipeline::Config`], as on the command line.
//!
//! - Arrays cross without a copy where the layout allows: a capture's histograms, a rendering and the
//!   volumes are Rust buffers handed to NumPy ([`numpy::PyArray::from_owned_array`]); inputs are read from
//!   NumPy's memory and checked (shape, dtype, finiteness, index range) with a `ValueError` naming the
//!   argument (module `arrays`).
//! - Errors are typed exceptions (`nlos.NlosError` and its subclasses, module `errors`); no input may make the
//!   library panic, and PyO3 turns any panic that still happens into a Python exception at the boundary.
//! - Long work (rendering, volumes, reconstruction) runs with the GIL released; a reconstruction calls its
//!   progress callback and checks for Ctrl-C after every iteration, stopping after the current block's
//!   checkpoint.

mod arrays;
mod capture;
mod errors;
mod mesh;
mod recon;
mod render;

use pyo3::prelude::*;

/// Runs the `nlos` command line with `args` (without the program name) in this process: the same code as
/// the `nlos` binary ([`nlos_cli::run`]). Returns the exit code.
#[pyfunction]
fn cli(py: Python<'_>, args: Vec<String>) -> u8 {
    let code = py.detach(|| nlos_cli::run(std::iter::once("nlos".to_string()).chain(args)));
    // `ExitCode` is opaque; the command's codes are 0, 1 and 2.
    if code == std::process::ExitCode::SUCCESS {
        0
    } else if code == std::process::ExitCode::from(2) {
        2
    } else {
        1
    }
}

#[pymodule]
fn _nlos(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // SAFETY: the module's initialisation runs once, holding the GIL, before any of the extension's threads
    // (rayon's) exist; Python's own `os.putenv` changes the environment under the same conditions.
    #[allow(unsafe_code)]
    unsafe {
        nlos_render::silence_display_probe();
    }
    errors::register(m)?;
    m.add_class::<capture::Capture>()?;
    m.add_class::<render::Renderer>()?;
    m.add_function(wrap_pyfunction!(capture::load, m)?)?;
    m.add_function(wrap_pyfunction!(capture::confocal_setup, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::write_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(recon::volume, m)?)?;
    m.add_function(wrap_pyfunction!(recon::default_settings, m)?)?;
    m.add_function(wrap_pyfunction!(recon::initial_surface, m)?)?;
    m.add_function(wrap_pyfunction!(recon::reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(recon::read_run, m)?)?;
    m.add_function(wrap_pyfunction!(cli, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // The reflectance models' names (what `brdf=` accepts, besides the alias "lambertian").
    m.add("BRDF_MODELS", pyo3::types::PyTuple::new(m.py(), nlos_brdf::Model::ALL.map(|model| model.name()))?)?;
    Ok(())
}
