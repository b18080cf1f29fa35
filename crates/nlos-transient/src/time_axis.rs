//! The time axis of a transient: bins of optical path length.

use serde::{Deserialize, Serialize};

use crate::error::{Result, TransientError};

/// Speed of light in vacuum, metres per second. Used to convert bin widths given in seconds.
pub const SPEED_OF_LIGHT: f64 = 299_792_458.0;

/// The speed of light the capture formats' reference code uses for bin widths (3e8 m/s): Stanford's 4 ps
/// is 1.2 mm, f-k's and general-NLOS's 32 ps 9.6 mm. Picoseconds read and printed for a capture's bins use
/// it ([`TimeAxis::bin_width_ps`]), so that they round-trip as typed.
pub const CAPTURE_SPEED_OF_LIGHT: f64 = 3e8;

/// The time axis of a transient, expressed as optical path length (metres, `c·t`).
///
/// Bin `k` holds the **integral** of the time-resolved signal over path lengths
/// `[t0 + k·bin_width, t0 + (k+1)·bin_width)` — a histogram, not a density.
///
/// By convention (see `docs/ARCHITECTURE.md`) times are the path length of `l → x → s` only; captures whose
/// times also include the device→wall and wall→device legs set [`TimeAxis::includes_device_legs`], and
/// [`Transient::remove_device_legs`](crate::Transient::remove_device_legs) converts them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimeAxis {
    /// Path length at the start of bin 0, metres.
    pub t0: f64,
    /// Width of one bin, metres of path length (> 0).
    pub bin_width: f64,
    /// Number of bins (> 0).
    pub bins: usize,
    /// Whether the times include the laser-device → laser-spot and sensor-spot → sensor-device legs.
    pub includes_device_legs: bool,
}

impl TimeAxis {
    /// A time axis of `bins` bins of `bin_width` metres starting at path length `t0`, legs excluded.
    ///
    /// # Errors
    /// [`TransientError::InvalidValue`] when `bins == 0`, `bin_width` is not finite and positive, or `t0`
    /// is not finite.
    pub fn new(t0: f64, bin_width: f64, bins: usize) -> Result<Self> {
        let axis = Self { t0, bin_width, bins, includes_device_legs: false };
        axis.validate()?;
        Ok(axis)
    }

    /// Checks the invariants (finite `t0`, finite positive `bin_width`, at least one bin).
    ///
    /// # Errors
    /// [`TransientError::InvalidValue`] naming the offending field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: String| TransientError::InvalidValue {
            file: crate::error::MEMORY.into(),
            field: field.into(),
            reason,
        };
        if !self.t0.is_finite() {
            return Err(bad("t0", format!("{} is not finite", self.t0)));
        }
        if !(self.bin_width.is_finite() && self.bin_width > 0.0) {
            return Err(bad("bin_width", format!("{} must be finite and > 0 (metres of path)", self.bin_width)));
        }
        if self.bins == 0 {
            return Err(bad("bins", "a transient needs at least one time bin".into()));
        }
        Ok(())
    }

    /// Bin width in seconds (`bin_width / c`).
    pub fn bin_width_seconds(&self) -> f64 {
        self.bin_width / SPEED_OF_LIGHT
    }

    /// Path length at the start of bin `k` (metres). `k` may equal `bins` (the end of the axis).
    pub fn bin_start(&self, k: usize) -> f64 {
        self.t0 + k as f64 * self.bin_width
    }

    /// Path length at the centre of bin `k` (metres).
    pub fn bin_center(&self, k: usize) -> f64 {
        self.t0 + (k as f64 + 0.5) * self.bin_width
    }

    /// Path length at the end of the last bin (metres).
    pub fn end(&self) -> f64 {
        self.bin_start(self.bins)
    }

    /// The bin that holds path length `t`, or `None` when `t` lies outside the axis.
    pub fn bin_of(&self, t: f64) -> Option<usize> {
        let k = ((t - self.t0) / self.bin_width).floor();
        (k >= 0.0 && k < self.bins as f64).then_some(k as usize)
    }
}
