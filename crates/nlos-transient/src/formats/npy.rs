//! `.npy` data with a `.json` sidecar: this project's exchange format.

use std::path::Path;

use crate::error::{Result, TransientError};
use crate::transient::Transient;

/// Reads the pair (`.npy` file, `.json` sidecar) from disk.
///
/// # Errors
/// Any [`TransientError`].
pub fn read_pair(npy: &Path, _json: &Path) -> Result<Transient> {
    Err(TransientError::Unsupported { file: npy.into(), what: "npy (reader not yet written)".into() })
}

/// Decodes `.npy` bytes with their sidecar.
///
/// # Errors
/// Any [`TransientError`].
pub fn read(_npy: &[u8], _json: &[u8], file: &Path) -> Result<Transient> {
    Err(TransientError::Unsupported { file: file.into(), what: "npy (reader not yet written)".into() })
}

/// Encodes `transient` as (`.npy` bytes, `.json` bytes).
///
/// # Errors
/// Any [`TransientError`].
pub fn write(_transient: &Transient, file: &Path) -> Result<(Vec<u8>, Vec<u8>)> {
    Err(TransientError::Unsupported { file: file.into(), what: "npy (writer not yet written)".into() })
}
