//! The seam between the renderer and where its passes run ([`Backend`]): a backend reads the backend-neutral
//! [`Scene`] and evaluates the forward pass (eq. 1 of Tsai et al. 2019) and the adjoint pass
//! (Proposition 1) of a BRDF on it, and says which settings it runs ([`Backend::supports`]).
//!
//! Two backends: the CPU's (`cpu::CpuBackend`: every setting, the reference) and the GPU's (`gpu::GpuBackend`,
//! feature `gpu`: what [`crate::gpu_support`] accepts). [`super::Renderer`] runs each pass on the GPU when one
//! is attached and supports the call, else on the CPU. A new backend implements this trait in its own module
//! and is attached by `Renderer::set_device` (a [`super::Device`] variant).

use nlos_brdf::Model;

use super::scene::Scene;
use super::{Gradient, RenderParams};
use crate::error::Result;
use nlos_brdf::FittedBrdf;

/// Where the renderer's forward and adjoint passes run.
pub(crate) trait Backend {
    /// Whether this backend runs a renderer with settings `params` for BRDFs of `model`, or why not (words
    /// naming what to change).
    ///
    /// # Errors
    /// The reason, when it does not.
    fn supports(&self, model: Model, params: &RenderParams) -> std::result::Result<(), String>;

    /// The forward pass: the transient, `measurements × bins` values, measurement-major.
    ///
    /// # Errors
    /// What kept the backend from running the pass (the CPU's never fails).
    fn forward<B: FittedBrdf>(&self, scene: &Scene, brdf: &B) -> Result<Vec<f32>>;

    /// The adjoint pass of `d_loss = dE/dI` (`measurements × bins` values).
    ///
    /// # Errors
    /// [`crate::RenderError::LengthMismatch`] for a `d_loss` of another length, and what kept the backend from
    /// running the pass.
    fn adjoint<B: FittedBrdf>(&self, scene: &Scene, brdf: &B, d_loss: &[f32]) -> Result<Gradient>;
}
