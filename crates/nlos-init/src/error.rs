//! The crate's error type.

use nlos_mesh::MeshError;
use nlos_transient::TransientError;

/// Everything that can go wrong in `nlos-init`; each variant says the cause and the fix.
#[derive(Debug, thiserror::Error)]
pub enum InitError {
    /// The method needs a confocal scan.
    #[error(
        "{method} needs a confocal scan (laser and sensor on the same spot) but this capture is a {scan} scan; \
         start it from the phasor field (method `pf`), which takes any scan"
    )]
    NotConfocal {
        /// The method that refused the input.
        method: &'static str,
        /// The capture's kind of scan ([`nlos_transient::Scan::kind`]): `one-laser`, `multi-laser`, `paired`.
        scan: &'static str,
    },
    /// The method needs scan points on a regular grid.
    #[error(
        "{method} needs scan points on a regular nx × ny grid but this capture's points are an unstructured \
         list (or, for the phasor field, span no area); start it from the phasor field (method `pf`), which takes \
         any points spanning an area, or resample the capture onto a grid"
    )]
    NotGrid {
        /// The method that refused the input.
        method: &'static str,
    },
    /// The grid is not regular (or too small).
    #[error("the scan grid cannot be used by {method}: {reason}; use a regular grid of ≥ 2 × 2 points on z = 0")]
    BadGrid {
        /// The method that refused the input.
        method: &'static str,
        /// What is wrong with the grid.
        reason: String,
    },
    /// The time axis includes the device legs.
    #[error(
        "the capture's times include the device → wall and wall → device legs; call \
         `Transient::remove_device_legs` (or `nlos convert --remove-legs`) first"
    )]
    DeviceLegs,
    /// The time axis does not start a whole number of bins after path length 0.
    #[error(
        "the time axis starts at path length {t0} m, which is not a whole number (≥ 0) of bins of {bin_width} m \
         after the wall; the volumetric methods need bins aligned with path length 0: crop or shift the capture"
    )]
    TimeOrigin {
        /// Path length at the start of bin 0, metres.
        t0: f64,
        /// Bin width, metres.
        bin_width: f64,
    },
    /// A parameter is out of range.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// The valid range, and what to do.
        reason: &'static str,
    },
    /// NaN or infinity in an input.
    #[error("non-finite value (NaN or infinity) in {what} at index {index}; clean the input (e.g. replace NaN by 0)")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// First offending index.
        index: usize,
    },
    /// Nothing to work with.
    #[error("{what}")]
    Empty {
        /// What is empty, and what to try.
        what: String,
    },
    /// An inconsistent volume.
    #[error("invalid volume: {reason}")]
    BadVolume {
        /// What is inconsistent.
        reason: String,
    },
    /// A start method's name that is none of [`crate::Method::ALL`].
    #[error("{got:?} is not a start method: give {known}")]
    UnknownMethod {
        /// The name given.
        got: String,
        /// The methods' names (`"lct", "fk", … or "carve"`).
        known: String,
    },
    /// An error from `nlos-transient` (reading or transforming the capture).
    #[error(transparent)]
    Transient(#[from] TransientError),
    /// An error from `nlos-mesh` (building or remeshing the surface).
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

/// `Result` with [`InitError`].
pub type Result<T> = std::result::Result<T, InitError>;
