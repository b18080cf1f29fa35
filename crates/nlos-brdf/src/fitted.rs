//! [`FittedBrdf`]: what rendering and fitting need from a model beyond [`Brdf`] — its parameters as a flat
//! vector (so the renderer's gradients and every finite-difference test are written once for all models), and
//! its unconstrained parameters θ (`crate::param`) with their chain rule (so the optimiser's reflectance steps
//! are written once too).
//!
//! A model implements it next to its [`Brdf`] impl (`lambert.rs`, `ggx.rs`, `retro.rs`); code that picks the
//! model at run time holds an [`AnyBrdf`] (`model.rs`) and calls the concrete type through
//! [`with_brdf!`](crate::with_brdf).

use crate::brdf::Brdf;
use crate::error::Result;
use crate::model::{AnyBrdf, Model};

/// An `f32` BRDF whose parameters are rendered, differentiated and fitted.
///
/// Two parametrisations: the physical parameters ([`FittedBrdf::params`], in [`FittedBrdf::PARAM_NAMES`]
/// order, the renderer's `Gradient::brdf`), and θ ([`FittedBrdf::theta`]), the unconstrained reals an
/// optimiser moves (the maps of `crate::param`: every finite θ is a valid BRDF). θ lists only the fitted
/// components; what θ leaves fixed (GGX's Fresnel kind and masking, the retroreflector's lobe width) is read
/// from `self`, the template [`FittedBrdf::with_theta`] is called on.
pub trait FittedBrdf: Brdf<Scalar = f32> + Copy {
    /// The model, by name.
    const MODEL: Model;
    /// Parameter names, in the order of [`FittedBrdf::params`] and of the renderer's `Gradient::brdf`.
    const PARAM_NAMES: &'static [&'static str];
    /// The power of the path length τ by which the measurement of a small face falls along a confocal path
    /// ([`Model::distance_power`]: 4, or 2 for a retroreflector). The renderer's splat rule corrects its
    /// fall-off by it.
    const DISTANCE_POWER: f32 = Self::MODEL.distance_power() as f32;
    /// Whether the BRDF is one albedo times a fixed function of the directions: a pure scale of every
    /// rendering, which a closed-form intensity scale absorbs (then θ has nothing left to fit).
    const SCALE_ONLY: bool;

    /// The parameter vector.
    fn params(&self) -> Vec<f32>;
    /// The same model with other parameter values (validated by the model's constructor).
    ///
    /// # Errors
    /// A [`crate::BrdfError`] when a value is out of the model's domain.
    fn with_params(&self, params: &[f32]) -> Result<Self>;
    /// `∂f/∂(parameters)` as an array (first `PARAM_NAMES.len()` entries used).
    fn param_grad_array(g: &Self::ParamGrad) -> [f32; 4];
    /// The roughness α of a glossy (microfacet) lobe worth importance sampling, None for none (the
    /// default). Used by the renderer's lobe sampling.
    fn lobe_alpha(&self) -> Option<f32> {
        None
    }
    /// The BRDF in words, with its parameters (a run report's line).
    fn describe(&self) -> String;
    /// The same BRDF as an [`AnyBrdf`].
    fn to_any(&self) -> AnyBrdf;

    /// θ of the fitted parameters (f64: an optimiser accumulates steps in it, and checkpoints keep it exact).
    fn theta(&self) -> Vec<f64>;
    /// The BRDF θ maps to, with what θ leaves fixed taken from `self`.
    ///
    /// # Errors
    /// A [`crate::BrdfError`] only for a non-finite θ.
    fn with_theta(&self, theta: &[f64]) -> Result<Self>;
    /// Chain rule: `∂E/∂θ` at θ from `∂E/∂(physical parameters)` (in [`FittedBrdf::PARAM_NAMES`] order), one
    /// entry per component of θ.
    fn chain_theta(&self, theta: &[f64], d_params: &[f32]) -> Vec<f64>;
}

/// Entry `i` of `v`, or `fallback` past its end (a short vector reads as missing values, which the models'
/// constructors reject when the fallback is NaN).
pub(crate) fn entry<T: Copy>(v: &[T], i: usize, fallback: T) -> T {
    v.get(i).copied().unwrap_or(fallback)
}
