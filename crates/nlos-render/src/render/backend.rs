//! The seam between the renderer and where its passes run ([`Backend`]): a backend reads the backend-neutral
//! [`Scene`] and evaluates the forward pass (eq. 1 of Tsai et al. 2019) and the adjoint pass
//! (Proposition 1) of a BRDF on it, and says which settings it runs ([`Backend::supports`]).
//!
//! Two backends: the CPU's (`cpu::CpuBackend`: every setting, the reference, always there) and the GPU's
//! (`gpu::GpuBackend`, feature `gpu`: what [`crate::gpu_support`] accepts, where an adapter is found).
//! [`super::Renderer`] holds them as trait objects, the CPU last, and runs each pass on the first that
//! supports it and succeeds (`Backends::run` in the parent module). The trait is compiled in every build;
//! only `accelerator` (the parent's), which opens a GPU, depends on the feature. A new backend implements this
//! trait in its own module and is returned by `accelerator` for its [`super::Device`] variant.

use nlos_brdf::{AnyBrdf, Model};

use super::scene::Scene;
use super::{Device, Gradient, RenderParams};
use crate::error::Result;

/// Where the renderer's forward and adjoint passes run.
pub(crate) trait Backend: std::fmt::Debug + Send + Sync {
    /// The device it runs on.
    fn device(&self) -> Device;

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
    fn forward(&self, scene: &Scene, brdf: &AnyBrdf) -> Result<Vec<f32>>;

    /// The adjoint pass of `d_loss = dE/dI` (`measurements × bins` values, checked by the caller).
    ///
    /// # Errors
    /// What kept the backend from running the pass.
    fn adjoint(&self, scene: &Scene, brdf: &AnyBrdf, d_loss: &[f32]) -> Result<Gradient>;
}
