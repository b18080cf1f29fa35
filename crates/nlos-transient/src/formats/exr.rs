//! OpenEXR: one f32 channel, width = bins, height = measurements, geometry in header attributes.

use std::path::Path;

use crate::error::{Result, TransientError};
use crate::transient::Transient;

/// Decodes EXR bytes.
///
/// # Errors
/// Any [`TransientError`].
pub fn read(_bytes: &[u8], file: &Path) -> Result<Transient> {
    Err(TransientError::Unsupported { file: file.into(), what: "EXR (reader not yet written)".into() })
}

/// Encodes `transient` as EXR bytes.
///
/// # Errors
/// Any [`TransientError`].
pub fn write(_transient: &Transient, file: &Path) -> Result<Vec<u8>> {
    Err(TransientError::Unsupported { file: file.into(), what: "EXR (writer not yet written)".into() })
}
