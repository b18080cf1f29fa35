//! The error type of this crate.

use std::path::PathBuf;

/// Everything that can go wrong while writing a report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// A file the report needs is not in the run directory.
    #[error("{file}: missing ({hint})")]
    MissingFile {
        /// The file.
        file: PathBuf,
        /// What produces it.
        hint: &'static str,
    },
    /// Reading or writing a file failed.
    #[error("{file}: I/O error: {source} (check that the folder exists and is writable)")]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A JSON file of the run directory does not parse.
    #[error("{file}: not a valid run file: {message} (was it written by another version of nlos?)")]
    Json {
        /// The file.
        file: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// The capture cannot be shown (no sensor grid, empty after gating, …).
    #[error("the capture cannot be shown: {reason}")]
    Capture {
        /// Why, and what would work.
        reason: String,
    },
    /// An option outside its domain.
    #[error("invalid report option `{name}`: {reason}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// Why, and what would be valid.
        reason: String,
    },
    /// A mesh could not be read, ray-cast or evaluated.
    #[error(transparent)]
    Mesh(#[from] nlos_mesh::MeshError),
    /// The final mesh could not be rendered.
    #[error("rendering the final mesh: {0}")]
    Render(#[from] nlos_render::RenderError),
    /// An operation on the capture failed.
    #[error(transparent)]
    Transient(#[from] nlos_transient::TransientError),
    /// The run's reflectance is invalid.
    #[error("the run's reflectance: {0}")]
    Optim(#[from] nlos_optim::OptimError),
    /// The back-projection of the capture or of the rendering failed.
    #[error("back-projecting the residual: {0}")]
    Init(#[from] nlos_init::InitError),
    /// A figure could not be drawn or encoded.
    #[error("drawing a figure: {0}")]
    Viz(#[from] nlos_viz::VizError),
}

/// Shorthand for `Result<T, ReportError>`.
pub type Result<T, E = ReportError> = std::result::Result<T, E>;
