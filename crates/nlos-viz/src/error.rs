//! The error type of this crate.

use std::path::PathBuf;

/// Everything that can go wrong when building or encoding a figure.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VizError {
    /// A scalar grid whose size or extent does not make sense.
    #[error("invalid grid: {reason}")]
    InvalidGrid {
        /// What is wrong, and what would be valid.
        reason: String,
    },
    /// An image of zero size or larger than [`MAX_DIMENSION`](crate::MAX_DIMENSION) on a side.
    #[error("invalid image size {width} × {height}: {reason}")]
    InvalidSize {
        /// Requested width in pixels.
        width: usize,
        /// Requested height in pixels.
        height: usize,
        /// Why it is refused.
        reason: String,
    },
    /// An argument outside its domain (a non-finite range, mismatched lengths, …).
    #[error("invalid argument `{name}`: {reason}")]
    InvalidArgument {
        /// The argument's name.
        name: &'static str,
        /// Why, and what would be valid.
        reason: String,
    },
    /// The PNG encoder failed.
    #[error("PNG encoding failed: {0}")]
    Png(#[from] png::EncodingError),
    /// Writing the file failed.
    #[error("{file}: I/O error: {source} (check that the folder exists and is writable)")]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// Shorthand for `Result<T, VizError>`.
pub type Result<T, E = VizError> = std::result::Result<T, E>;
