//! HDF5 containers: y-tal HDF5_TAL (read/write), Z-NLOS (read), f-k MAT v7.3 (read).

use std::path::Path;

use super::Format;
use crate::error::{Result, TransientError};
use crate::transient::Transient;

/// Decides which HDF5-based format `bytes` (starting at the HDF5 superblock) hold.
///
/// # Errors
/// [`TransientError::UnknownFormat`] when the datasets match no known layout.
pub fn classify(_bytes: &[u8], file: &Path) -> Result<Format> {
    Err(TransientError::Unsupported { file: file.into(), what: "HDF5 (reader not yet written)".into() })
}

/// Reads an HDF5 file in `format`.
///
/// # Errors
/// Any [`TransientError`].
pub fn read(_bytes: &[u8], _format: Format, file: &Path) -> Result<Transient> {
    Err(TransientError::Unsupported { file: file.into(), what: "HDF5 (reader not yet written)".into() })
}

/// Encodes `transient` as HDF5_TAL bytes.
///
/// # Errors
/// Any [`TransientError`].
pub fn write_tal(_transient: &Transient, file: &Path) -> Result<Vec<u8>> {
    Err(TransientError::Unsupported { file: file.into(), what: "HDF5 (writer not yet written)".into() })
}
