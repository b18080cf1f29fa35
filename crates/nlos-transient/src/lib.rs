//! # nlos-transient
//!
//! Transient (time-resolved) non-line-of-sight captures: the data model, the operations users need, and
//! readers and writers for every standard format.
//!
//! ## Conventions
//! - Units are metres. The relay wall is the plane z = 0 with normal +z; the hidden scene is at z > 0.
//! - Time is **optical path length** (metres, `c·t`) of the path laser spot `l` → hidden point `x` →
//!   sensor spot `s` only, unless [`TimeAxis::includes_device_legs`] says the device→wall and wall→device
//!   legs are included (then [`Transient::remove_device_legs`] converts).
//! - Bin `k` holds the integral of the signal over `[t0 + k·Δ, t0 + (k+1)·Δ)`: a histogram, not a density.
//! - Data are `f32`, contiguous, one histogram per measurement (measurement-major). Grid scans store
//!   points with x fastest: point `ix + nx·iy`.
//!
//! ## Example
//! ```
//! use nlos_transient::{PointSet, Scan, TimeAxis, Transient};
//! let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.25, 0.25)?);
//! let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.0012, 1000)?)?;
//! t.histogram_mut(0)[700] = 5.0;
//! assert!((t.summed_peak_depth(Some(0.0))? - 0.4203).abs() < 1e-9); // bin centre 700.5 × 1.2 mm, halved
//! let coarse = t.rebin(4)?;
//! assert_eq!(coarse.bins(), 250);
//! # Ok::<(), nlos_transient::TransientError>(())
//! ```
#![warn(missing_docs)]

pub mod describe;
pub mod error;
#[cfg(feature = "formats")]
pub mod formats;
mod ops;
mod ops_views;
pub mod rng;
pub mod scan;
pub mod sensor;
pub mod time_axis;
pub mod transient;

pub use error::{Result, TransientError};
#[cfg(feature = "formats")]
pub use formats::{Format, ReadOptions, detect, read, read_with, write};
pub use scan::{Layout, Measurement, PatternKind, PointSet, Scan, ScanPattern};

pub use describe::Quantity;
pub use time_axis::{CAPTURE_SPEED_OF_LIGHT, SPEED_OF_LIGHT, TimeAxis};
pub use transient::Transient;
