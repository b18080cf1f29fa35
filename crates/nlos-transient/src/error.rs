//! The one error type of this crate.

use std::path::PathBuf;

/// Everything that can go wrong when reading, writing, building or transforming a [`Transient`].
///
/// Each variant names the file (or `<memory>` for in-memory input) and, where there is one, the field,
/// and its message says what to do about it.
///
/// [`Transient`]: crate::Transient
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TransientError {
    /// The operating system refused to open, read or write the file.
    #[error("{file}: I/O error: {source} (check that the path exists and is readable/writable)")]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The content matches none of the supported formats.
    #[error(
        "{file}: unrecognised transient format ({reason}); supported: Stanford LCT/f-k .mat, Tsai 2019 .mat, \
         Z-NLOS HDF5, y-tal HDF5_TAL, .npy + .json sidecar, OpenEXR"
    )]
    UnknownFormat {
        /// The file.
        file: PathBuf,
        /// What was seen.
        reason: String,
    },
    /// The format is recognised but this version or variant of it is not supported.
    #[error(
        "{file}: unsupported {what} (convert the file with the tool that wrote it, e.g. save -v7 or -v7.3 in MATLAB)"
    )]
    Unsupported {
        /// The file.
        file: PathBuf,
        /// What is unsupported.
        what: String,
    },
    /// A required field (variable, dataset, attribute, key) is absent.
    #[error("{file}: missing field `{field}` ({hint})")]
    MissingField {
        /// The file.
        file: PathBuf,
        /// The field's name.
        field: String,
        /// How to fix it.
        hint: String,
    },
    /// A capture stored as two files lacks the second one beside the first.
    #[error("{file}: needs its companion file {companion}, not found: {what}; put the two files in one folder")]
    MissingCompanion {
        /// The file given.
        file: PathBuf,
        /// Where the companion was looked for.
        companion: PathBuf,
        /// What the two files hold.
        what: String,
    },
    /// A field has a shape that does not fit the others.
    #[error("{file}: field `{field}` has shape {found}, expected {expected}")]
    WrongShape {
        /// The file.
        file: PathBuf,
        /// The field's name.
        field: String,
        /// The expected shape, in words.
        expected: String,
        /// The shape found.
        found: String,
    },
    /// A field has the wrong element type or class.
    #[error("{file}: field `{field}` has type {found}, expected {expected}")]
    WrongType {
        /// The file.
        file: PathBuf,
        /// The field's name.
        field: String,
        /// The expected type.
        expected: String,
        /// The type found.
        found: String,
    },
    /// A field holds a value outside its domain (negative bin width, zero-sized grid, …).
    #[error("{file}: field `{field}` is invalid: {reason}")]
    InvalidValue {
        /// The file, or `<memory>`.
        file: PathBuf,
        /// The field's name.
        field: String,
        /// Why, and what would be valid.
        reason: String,
    },
    /// A NaN or an infinity where finite numbers are required.
    #[error(
        "{file}: field `{field}` holds a non-finite value (NaN or Inf) at flat index {index}; clean the data or mask it before loading"
    )]
    NonFinite {
        /// The file, or `<memory>`.
        file: PathBuf,
        /// The field's name.
        field: String,
        /// Flat index of the first offending element.
        index: usize,
    },
    /// The file ends before the structure it declares.
    #[error("{file}: truncated: {detail} (the file was cut short; copy it again)")]
    Truncated {
        /// The file.
        file: PathBuf,
        /// What was being read.
        detail: String,
    },
    /// The container is internally inconsistent (bad header, bad compression stream, bad offsets).
    #[error("{file}: malformed: {detail}")]
    Malformed {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// The format cannot hold this transient (e.g. writing an exhaustive scan where only grids fit).
    #[error("{file}: cannot write as {format}: {reason}")]
    CannotWrite {
        /// The file.
        file: PathBuf,
        /// The format.
        format: String,
        /// Why.
        reason: String,
    },
    /// An operation was called with an argument outside its domain.
    #[error("invalid argument `{name}`: {reason}")]
    InvalidArgument {
        /// The argument's name.
        name: &'static str,
        /// Why, and what would be valid.
        reason: String,
    },
}

/// Shorthand for `Result<T, TransientError>`.
pub type Result<T, E = TransientError> = std::result::Result<T, E>;

/// The name used in errors for data that does not come from a file.
pub const MEMORY: &str = "<memory>";
