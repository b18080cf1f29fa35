//! The data term: how far a rendering is from the measurement, with its gradient — one concept, in one place.
//!
//! Which form a run uses:
//! - [`intensities`] ([`DataTerm`]): intensities compared by L2 (eq. 7 of Tsai et al. 2019) or a Poisson
//!   NLL, with optional per-bin weights and the unknown global scale solved in closed form at every step;
//! - [`counts`] ([`SensorFit`]): photon counts through the SPAD's timing response with a background,
//!   `scale·J(I) + b`, by their Poisson NLL (set [`crate::ReconstructParams::sensor`]); it replaces the
//!   first where it is set;
//! - [`response`]: the timing response `J` applied to a whole capture at the cost it needs (direct or FFT),
//!   and the response of summed bins;
//! - [`rows`] ([`RowTerm`]): either term one histogram at a time, as boundary pruning and the residual
//!   patches test a face's share.
//!
//! Both forms also give the expected value of the term at the current rendering if it were exact (their
//! noise floor), against which the automatic regulariser weight is set.

pub mod counts;
pub mod intensities;
pub mod response;
pub mod rows;

pub use counts::{SensorBackground, SensorFit, SensorModel, SensorRows};
pub use intensities::{DataEval, DataTerm, expected_half_deviance};
pub use rows::{RowLoss, RowTerm};
