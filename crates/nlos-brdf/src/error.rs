//! The one error type of this crate.

/// Why a BRDF could not be built from the given parameters.
///
/// Every variant carries the offending value and its message says how to fix it. Values are widened to
/// `f64` so that one error type serves both precisions.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BrdfError {
    /// An albedo (Lambertian `albedo`, GGX `albedo_diffuse` or `specular`) is negative, NaN or infinite.
    #[error(
        "albedo `{name}` = {value} is invalid: it must be finite and >= 0 (values above 1 are allowed, they \
         absorb the capture's unknown radiometric scale); build from unconstrained parameters with \
         `LambertianTheta`/`GgxTheta` to stay in range"
    )]
    InvalidAlbedo {
        /// Which parameter.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The GGX roughness α is NaN or outside `[ALPHA_MIN, ALPHA_MAX]`.
    #[error(
        "GGX roughness alpha = {value} is outside [{min}, {max}]: clamp it into that range (alpha below {min} \
         is a mirror that f32 cannot evaluate, above {max} the model is not a plausible GGX surface), or \
         build from an unconstrained parameter with `GgxTheta`"
    )]
    InvalidAlpha {
        /// The value given.
        value: f64,
        /// The smallest accepted α ([`crate::ALPHA_MIN`]).
        min: f64,
        /// The largest accepted α ([`crate::ALPHA_MAX`]).
        max: f64,
    },
    /// The Schlick reflectance at normal incidence F0 is NaN or outside `[0, 1]`.
    #[error(
        "Schlick F0 = {value} is outside [0, 1]: it is a reflectance at normal incidence (about 0.04 for \
         dielectrics, 0.5-1 for metals); clamp it, use `Fresnel::One` for Tsai et al. 2019's model, or build from an \
         unconstrained parameter with `GgxTheta`"
    )]
    InvalidF0 {
        /// The value given.
        value: f64,
    },
    /// The lobe width σ of a [`crate::Retroreflective`] surface is NaN or outside `[1e-4, 1]` rad.
    #[error(
        "retroreflector lobe width = {value} rad is outside [1e-4, 1]: it is the observation-angle width of \
         the return (about 0.0175 rad = 1 degree for retroreflective sheeting); below 1e-4 f32 cannot resolve \
         it, above 1 rad the surface is no longer a retroreflector"
    )]
    InvalidLobeWidth {
        /// The value given.
        value: f64,
    },
    /// A reflectance model's name is none of [`crate::Model`]'s.
    #[error("reflectance model {got:?} is unknown: use \"lambert\", \"ggx\" or \"retroreflective\"")]
    UnknownModel {
        /// The name given.
        got: String,
    },
}

/// `Result` with [`BrdfError`].
pub type Result<T, E = BrdfError> = std::result::Result<T, E>;
