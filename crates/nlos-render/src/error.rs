//! The one error type of the crate.

use thiserror::Error;

/// Everything that can go wrong when building a [`crate::Renderer`] or running a pass. Each variant says the
/// cause and the fix.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RenderError {
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {index} is not finite ({value:?}); remove or repair the vertex before rendering")]
    NonFiniteVertex {
        /// Index into the positions.
        index: usize,
        /// The offending position.
        value: [f32; 3],
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {vertex} but there are only {vertices} vertices; \
         fix the index buffer or pass the matching positions"
    )]
    IndexOutOfRange {
        /// Triangle number.
        triangle: usize,
        /// The bad vertex index.
        vertex: u32,
        /// Number of vertices supplied.
        vertices: usize,
    },
    /// A buffer has the wrong length.
    #[error("{what} has {got} values but {expected} were expected; pass one value per (measurement, bin)")]
    LengthMismatch {
        /// Which buffer.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Supplied length.
        got: usize,
    },
    /// A parameter is outside its domain.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Supplied value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// The scan or the time axis is unusable.
    #[error("invalid scan or time axis: {0}; build them with nlos_transient's validated constructors")]
    InvalidSetup(String),
    /// New positions do not match the topology the renderer was built with.
    #[error("set_positions got {got} vertices but the renderer has {expected}; build a new Renderer after a remesh")]
    TopologyChanged {
        /// Vertices the renderer was built with.
        expected: usize,
        /// Vertices supplied.
        got: usize,
    },
    /// The GPU backend cannot run this request: no adapter, a setting it does not implement, a size beyond the
    /// device's limits, or a device error.
    #[error("GPU backend: {0}")]
    Gpu(String),
    /// A BRDF parameter vector could not be turned into a BRDF.
    #[error("BRDF parameters rejected: {0}; keep them in the model's domain (see nlos_brdf)")]
    Brdf(#[from] nlos_brdf::BrdfError),
}

/// Result alias of the crate.
pub type Result<T> = std::result::Result<T, RenderError>;
