//! MATLAB level-5 MAT-files: Stanford LCT, Tsai 2019 and Stanford f-k (v5) captures.

use std::path::Path;

use super::Format;
use crate::error::{Result, TransientError};
use crate::transient::Transient;

/// Decides which MAT-based format a v5 MAT-file holds from its variable names.
///
/// # Errors
/// [`TransientError::UnknownFormat`] when the variables match no known layout.
pub fn classify(_bytes: &[u8], file: &Path) -> Result<Format> {
    Err(TransientError::Unsupported { file: file.into(), what: "MAT v5 (reader not yet written)".into() })
}

/// Reads a v5 MAT-file in `format`.
///
/// # Errors
/// Any [`TransientError`].
pub fn read(_bytes: &[u8], _format: Format, file: &Path) -> Result<Transient> {
    Err(TransientError::Unsupported { file: file.into(), what: "MAT v5 (reader not yet written)".into() })
}
