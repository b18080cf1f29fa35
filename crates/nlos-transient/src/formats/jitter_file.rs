//! Measured SPAD timing responses from files: [`JitterResponse::load`] (MATLAB v7.3 or HDF5, the two layouts
//! of the shared data). Here rather than in [`crate::sensor`], so that the sensor model does not depend on
//! the file formats (the crate's modules form no cycle, and the sensor model builds without the `formats`
//! feature).

use std::path::Path;

use crate::SPEED_OF_LIGHT;
use crate::error::{Result, TransientError};
use crate::formats::hdf5::read_dataset_f64;
use crate::sensor::JitterResponse;

impl JitterResponse {
    /// Loads a measured timing response from a MATLAB v7.3 or HDF5 file, recognising the two layouts of
    /// the shared data (`../shared/data/sensor/`):
    ///
    /// - **`t_1` + `counts_1`** (`spad_jitter.mat`, 1×901 each): `t_1` are the sample **centres** in
    ///   **seconds** — the file's own values run from −8.387e-11 to 6.490e-10 with a uniform spacing of
    ///   8.14e-13 s (0.814 ps), although the data README says picoseconds. Units are decided from the
    ///   spacing: below 1e-6 the values are seconds, otherwise picoseconds (no SPAD response is sampled
    ///   coarser than a microsecond, and none finer than 1e-6 ps). Zero delay is where the file puts it
    ///   (`t_1 = 0` at the peak of `counts_1`).
    /// - **`counts` + `timebin_width_ps`** (`spad_impulse_response.hdf5`, 1201×1 `uint16`, 0.75 ps):
    ///   no time origin is stored, so zero delay is put at the centre of the maximum sample.
    ///
    /// Either way, times become path lengths `c·t` (c = 299 792 458 m/s), and the constant floor is
    /// subtracted as in [`JitterResponse::from_histogram`].
    ///
    /// # Errors
    /// The reading errors of [`read_dataset_f64`]; [`TransientError::MissingField`] when neither layout is
    /// present; [`TransientError::WrongShape`] when times and counts differ in length;
    /// [`TransientError::InvalidValue`] for non-uniform or non-increasing times and the errors of
    /// [`JitterResponse::from_histogram`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let file = |field: &str, reason: String| TransientError::InvalidValue {
            file: path.into(),
            field: field.into(),
            reason,
        };
        match read_dataset_f64(path, "t_1") {
            Ok((t, _)) => {
                let (counts, _) = read_dataset_f64(path, "counts_1")?;
                if counts.len() != t.len() {
                    return Err(TransientError::WrongShape {
                        file: path.into(),
                        field: "counts_1".into(),
                        expected: format!("{} samples, as `t_1`", t.len()),
                        found: format!("{} samples", counts.len()),
                    });
                }
                if t.len() < 2 {
                    return Err(file("t_1", "needs at least two samples to define a spacing".into()));
                }
                let n = t.len();
                let step = (t[n - 1] - t[0]) / (n - 1) as f64;
                if !(step.is_finite() && step > 0.0) {
                    return Err(file("t_1", "times must be finite and increasing".into()));
                }
                // Uniform sampling: every step within 5 % of the mean step.
                if let Some(i) = t.windows(2).position(|w| ((w[1] - w[0]) - step).abs() > 0.05 * step) {
                    return Err(file("t_1", format!("non-uniform spacing at sample {i}; resample first")));
                }
                let to_seconds = if step < 1e-6 { 1.0 } else { 1e-12 };
                let spacing = step * to_seconds * SPEED_OF_LIGHT;
                let origin = t[0] * to_seconds * SPEED_OF_LIGHT - 0.5 * spacing;
                Self::from_histogram(origin, spacing, &counts, true).map_err(|e| with_file(e, path))
            }
            Err(TransientError::MissingField { .. }) => {
                let (counts, _) = read_dataset_f64(path, "counts").map_err(|e| match e {
                    TransientError::MissingField { file, .. } => TransientError::MissingField {
                        file,
                        field: "t_1/counts_1 or counts/timebin_width_ps".into(),
                        hint: "a timing response needs either times `t_1` with `counts_1`, or `counts` with \
                               `timebin_width_ps`"
                            .into(),
                    },
                    e => e,
                })?;
                let (w, _) = read_dataset_f64(path, "timebin_width_ps")?;
                let width_ps = w.first().copied().unwrap_or(f64::NAN);
                if !(width_ps.is_finite() && width_ps > 0.0) {
                    return Err(file("timebin_width_ps", format!("{width_ps} must be finite and > 0")));
                }
                let spacing = width_ps * 1e-12 * SPEED_OF_LIGHT;
                let peak = counts.iter().enumerate().fold(0, |b, (i, &c)| if c > counts[b] { i } else { b });
                let origin = -(peak as f64 + 0.5) * spacing;
                Self::from_histogram(origin, spacing, &counts, true).map_err(|e| with_file(e, path))
            }
            Err(e) => Err(e),
        }
    }
}

/// Re-labels an in-memory error with the file it came from.
fn with_file(e: TransientError, path: &Path) -> TransientError {
    match e {
        TransientError::InvalidValue { field, reason, .. } => {
            TransientError::InvalidValue { file: path.into(), field, reason }
        }
        TransientError::NonFinite { field, index, .. } => TransientError::NonFinite { file: path.into(), field, index },
        e => e,
    }
}
