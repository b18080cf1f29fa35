//! The [`Transient`] type: scan geometry, time axis and histogram data.

use serde::{Deserialize, Serialize};

use crate::error::{MEMORY, Result, TransientError};
use crate::scan::Scan;
use crate::time_axis::TimeAxis;

/// A transient capture: one histogram per measurement, all on the same time axis.
///
/// Data are `f32`, contiguous, measurement-major: bin `k` of measurement `m` is `data[m * bins + k]`.
/// For a confocal grid scan measurement `m = ix + nx·iy`; for an exhaustive scan `m = il·n_sensors + is`.
///
/// # Example
/// ```
/// use nlos_transient::{PointSet, Scan, TimeAxis, Transient};
/// let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.25, 0.25)?);
/// let time = TimeAxis::new(0.0, 0.0012, 100)?;
/// let t = Transient::zeros(scan, time)?;
/// assert_eq!(t.data().len(), 16 * 100);
/// # Ok::<(), nlos_transient::TransientError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Transient {
    scan: Scan,
    time: TimeAxis,
    data: Vec<f32>,
}

impl Transient {
    /// Builds a transient after checking that the shapes agree and every value is finite.
    ///
    /// # Errors
    /// [`TransientError::WrongShape`] when `data.len() != measurements × bins`; the errors of
    /// [`Scan::validate`] and [`TimeAxis::validate`]; [`TransientError::NonFinite`] for NaN/Inf data.
    pub fn new(scan: Scan, time: TimeAxis, data: Vec<f32>) -> Result<Self> {
        check(&scan, &time, &data)?;
        Ok(Self { scan, time, data })
    }

    /// An all-zero transient.
    ///
    /// # Errors
    /// As [`Transient::new`].
    pub fn zeros(scan: Scan, time: TimeAxis) -> Result<Self> {
        let n = scan.measurements().checked_mul(time.bins).ok_or_else(|| TransientError::InvalidArgument {
            name: "scan",
            reason: "measurements × bins overflows".into(),
        })?;
        Self::new(scan, time, vec![0.0; n])
    }

    /// The scan geometry.
    pub fn scan(&self) -> &Scan {
        &self.scan
    }

    /// Mutable scan geometry (for setting device positions after reading).
    ///
    /// The number of measurements must not change; [`Transient::validate`] checks it.
    pub fn scan_mut(&mut self) -> &mut Scan {
        &mut self.scan
    }

    /// The time axis.
    pub fn time(&self) -> &TimeAxis {
        &self.time
    }

    /// Mutable time axis (e.g. to declare that times include the device legs). The bin count must not change.
    pub fn time_mut(&mut self) -> &mut TimeAxis {
        &mut self.time
    }

    /// All histograms, measurement-major.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// All histograms, mutable.
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// Consumes the transient and returns its parts.
    pub fn into_parts(self) -> (Scan, TimeAxis, Vec<f32>) {
        (self.scan, self.time, self.data)
    }

    /// Number of measurements.
    pub fn measurements(&self) -> usize {
        self.scan.measurements()
    }

    /// Number of bins per histogram.
    pub fn bins(&self) -> usize {
        self.time.bins
    }

    /// Histogram of measurement `m`.
    ///
    /// # Panics
    /// When `m >= self.measurements()`.
    pub fn histogram(&self, m: usize) -> &[f32] {
        &self.data[m * self.time.bins..(m + 1) * self.time.bins]
    }

    /// Mutable histogram of measurement `m`.
    ///
    /// # Panics
    /// When `m >= self.measurements()`.
    pub fn histogram_mut(&mut self, m: usize) -> &mut [f32] {
        let b = self.time.bins;
        &mut self.data[m * b..(m + 1) * b]
    }

    /// Iterator over histograms in measurement order.
    pub fn histograms(&self) -> std::slice::ChunksExact<'_, f32> {
        self.data.chunks_exact(self.time.bins)
    }

    /// Re-checks every invariant (after using the `_mut` accessors).
    ///
    /// # Errors
    /// As [`Transient::new`].
    pub fn validate(&self) -> Result<()> {
        check(&self.scan, &self.time, &self.data)
    }

    pub(crate) fn from_parts_unchecked(scan: Scan, time: TimeAxis, data: Vec<f32>) -> Self {
        debug_assert_eq!(data.len(), scan.measurements() * time.bins);
        Self { scan, time, data }
    }
}

fn check(scan: &Scan, time: &TimeAxis, data: &[f32]) -> Result<()> {
    scan.validate()?;
    time.validate()?;
    let expected = scan.measurements().checked_mul(time.bins);
    if expected != Some(data.len()) {
        return Err(TransientError::WrongShape {
            file: MEMORY.into(),
            field: "data".into(),
            expected: format!("{} measurements × {} bins", scan.measurements(), time.bins),
            found: format!("{} values", data.len()),
        });
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(TransientError::NonFinite { file: MEMORY.into(), field: "data".into(), index: i });
    }
    Ok(())
}
