//! The renderer: geometry in structure-of-arrays form, the forward pass (eq. 1–5 of Tsai et al. 2019) and
//! the adjoint pass (Proposition 1, with the normal and area terms). See the crate docs for the derivation.

use std::sync::Arc;
use std::sync::atomic::AtomicUsize;

use glam::Vec3;
use nlos_brdf::{AnyBrdf, FittedBrdf, Model};
use nlos_transient::{Scan, TimeAxis, Transient};

use crate::brdf::gpu_terms;
use crate::error::{RenderError, Result};
use crate::kernel::{Kernel, KernelEval};
use crate::loss::Loss;
use soa::Isa;

mod backend;
mod cache;
pub(crate) mod cpu;
#[cfg(feature = "gpu")]
pub(crate) mod gpu;
mod params;
pub(crate) mod scene;
pub(crate) mod soa;
pub(crate) mod splat;

use backend::Backend;
use cpu::CpuBackend;
use cpu::lobe::Lobe;
use params::check_params;
pub use params::{
    DeterministicRule, Device, Gradient, LossAndGradient, RenderParams, RowSpan, Sampling, SplatRule, Visibility,
};
use scene::Scene;

/// Where a renderer with settings `params` runs when [`Renderer::set_device`] is given `device`, and why, in
/// words for a run's log: `the CPU (render.device = "auto": …)` or `the GPU NAME (…)`; for [`Device::Gpu`]
/// where none can run, `none: …` and the reason `set_device` reports. Opens the process's GPU as
/// `set_device` does (once per process; the passes' BRDF is checked per call, not here).
pub fn describe_device(device: Device, params: &RenderParams) -> String {
    if device == Device::Cpu {
        return "the CPU (render.device = \"cpu\")".into();
    }
    #[cfg(feature = "gpu")]
    {
        gpu::describe(device == Device::Gpu, params)
    }
    #[cfg(not(feature = "gpu"))]
    {
        let _ = params;
        if device == Device::Gpu {
            "none: render.device = \"gpu\", but this build has no GPU backend".into()
        } else {
            "the CPU (render.device = \"auto\": this build has no GPU backend)".into()
        }
    }
}

/// Whether the GPU backend (feature `gpu`) runs a renderer with settings `params` for the reflectance model
/// `model`, or why not, in words naming what to change: the splat rule with the tent kernel, cached or no
/// visibility, and a model the shader evaluates ([`AnyBrdf`]'s GPU terms: Lambertian and retroreflective, not
/// GGX). The one place that decides: the renderer sends calls it refuses to the CPU, and settings that
/// require the GPU for them (`render.device = "gpu"`, `nlos render --device gpu`) are refused with this reason.
///
/// # Errors
/// The reason, when the GPU backend does not run these settings.
pub fn gpu_support(model: Model, params: &RenderParams) -> std::result::Result<(), String> {
    gpu_settings(params)?;
    if has_gpu_terms(model) {
        return Ok(());
    }
    let with: Vec<String> = Model::ALL.into_iter().filter(|&m| has_gpu_terms(m)).map(|m| format!("\"{m}\"")).collect();
    Err(format!("the reflectance model \"{model}\" has no GPU version ({} have one)", with.join(" and ")))
}

/// Whether `model`'s BRDF has the shader's terms (the roughness is irrelevant to that).
fn has_gpu_terms(model: Model) -> bool {
    AnyBrdf::unit(model, 0.5).ok().as_ref().and_then(gpu_terms).is_some()
}

/// Whether the renderer's settings, whatever the BRDF, have a GPU version ([`gpu_support`]).
fn gpu_settings(p: &RenderParams) -> std::result::Result<(), String> {
    if !(matches!(p.sampling, Sampling::Splat(_)) && p.kernel == Kernel::Tent) {
        return Err("only the splat rule with the tent kernel runs on the GPU (Sampling::Splat)".into());
    }
    if p.visibility == Visibility::Live {
        return Err("live shadow rays do not run on the GPU: use Visibility::Cached or Off".into());
    }
    Ok(())
}

/// Turns off Mesa's Vulkan device-selection layer on a machine without a display session, so that looking
/// for a GPU prints no `error: XDG_RUNTIME_DIR is invalid …` (the layer's, not a failure); nothing without
/// the feature `gpu`. See `gpu::silence_display_probe`.
///
/// # Safety
/// Changes the process's environment ([`std::env::set_var`]): call it before any other thread can read the
/// environment, as at the top of `main`.
#[allow(unsafe_code)] // `std::env::set_var` is unsafe; the contract is the caller's (above)
pub unsafe fn silence_display_probe() {
    #[cfg(feature = "gpu")]
    // SAFETY: the caller's contract, passed on.
    unsafe {
        gpu::silence_display_probe();
    }
}

/// Measurements per task of the forward pass (their histograms stay in L1/L2 while each block of triangles
/// is swept over them).
const M_CHUNK: usize = 8;
/// Measurements between flushes of the adjoint's f32 per-triangle accumulators into f64, which bounds the
/// length of every f32 sum.
const FLUSH: usize = 16;

/// A transient renderer for one mesh topology, scan and time axis: the scene (backend-neutral geometry) and the
/// backends its passes run on — the CPU's always, a GPU's once attached ([`Renderer::set_device`]).
///
/// Build once per topology ([`Renderer::new`]), move vertices with [`Renderer::set_positions`], render with
/// [`Renderer::forward`], differentiate with [`Renderer::adjoint`] or [`Renderer::loss_and_gradient`].
#[derive(Debug)]
pub struct Renderer {
    scene: Scene,
    /// The CPU's passes that no other backend runs (steady state, per-triangle shares).
    cpu: CpuBackend,
    /// Where the forward and adjoint passes run: the attached accelerator ([`Renderer::set_device`]) where it
    /// takes the pass, else the CPU.
    backends: Backends,
}

impl Renderer {
    /// Validates the inputs and builds the geometry (and the BVH and cache the visibility mode needs).
    ///
    /// Degenerate triangles (zero or non-finite area) are skipped: they have no area to integrate over.
    ///
    /// # Errors
    /// [`RenderError::NonFiniteVertex`], [`RenderError::IndexOutOfRange`], [`RenderError::InvalidSetup`]
    /// for an invalid or empty scan / time axis, [`RenderError::InvalidParameter`] for bad params.
    pub fn new(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        scan: &Scan,
        time: &TimeAxis,
        params: RenderParams,
    ) -> Result<Self> {
        Self::new_observed(positions, triangles, scan, time, params, None)
    }

    /// [`Renderer::new`] that counts, in `progress`, every measurement its CPU passes finish: the cached
    /// visibility's (once here, and at each [`Renderer::refresh_visibility`]) and each forward pass's. A
    /// long render shows its progress from another thread by reading it (`nlos render`: a bar, or lines in
    /// a log). GPU passes are not counted.
    ///
    /// # Errors
    /// As [`Renderer::new`].
    pub fn new_observed(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        scan: &Scan,
        time: &TimeAxis,
        params: RenderParams,
        progress: Option<Arc<AtomicUsize>>,
    ) -> Result<Self> {
        let cpu = CpuBackend::detect();
        Ok(Self {
            scene: Scene::new(positions, triangles, scan, time, params, progress)?,
            cpu,
            backends: Backends::cpu(cpu),
        })
    }

    /// Moves the vertices (same topology). With [`Visibility::Live`] the BVH is rebuilt; with
    /// [`Visibility::Cached`] the cache is kept (visibility held fixed) until [`Renderer::refresh_visibility`].
    ///
    /// # Errors
    /// [`RenderError::TopologyChanged`] for a different vertex count, [`RenderError::NonFiniteVertex`].
    pub fn set_positions(&mut self, positions: &[Vec3]) -> Result<()> {
        self.scene.set_positions(positions)
    }

    /// Rebuilds the BVH at the current positions and, in [`Visibility::Cached`] mode, recomputes the cache.
    pub fn refresh_visibility(&mut self) {
        self.scene.refresh_visibility();
    }

    /// The scan.
    pub fn scan(&self) -> &Scan {
        &self.scene.scan
    }

    /// The time axis.
    pub fn time(&self) -> &TimeAxis {
        &self.scene.time
    }

    /// The parameters.
    pub fn params(&self) -> &RenderParams {
        &self.scene.params
    }

    /// Multiple importance sampling of glossy surfaces in [`Sampling::Stratified`] mode (confocal scans; off
    /// by default): a share `φ = lobe_fraction · Ω_t/(Ω_t + 4πα²)` of each (triangle, measurement)'s expected
    /// sample count (`Ω_t` the triangle's solid angle seen from the spot: a lobe wider than the triangle is
    /// left to area sampling) is drawn from the BRDF's microfacet lobe instead of uniformly over the area,
    /// stratified in the polar angle — a microfacet normal `m` from the GGX
    /// distribution `D(m)(m·n)` about the triangle's normal (roughness [`FittedBrdf::lobe_alpha`]), mapped
    /// to the point where the ray from the laser spot along `−m` meets the triangle's plane (for a confocal
    /// measurement the half vector there is exactly `m`), kept when inside the triangle. Every sample, of
    /// either strategy, is weighted by the balance heuristic `1/(c₁ p₁(x) + c₂ p₂(x))` (Veach 1997, §9.2;
    /// `p₁ = 1/A`, `p₂ = D(m)(n·m)²/|x − l|²` the lobe density on the plane, `c₁ = (1 − φ)c`, `c₂ = φc` the
    /// expected counts), so the estimator stays unbiased; the weights are held fixed when differentiating,
    /// as the area weights are. Glossy lobes (small α) are then sampled where they peak — Tsai et al. 2019's
    /// stated weakness: on a specular plane (`tests/mis.rs`, 64 samples per measurement, `lobe_fraction`
    /// 0.9) the single-render error drops to 0.56× at α = 0.1, 0.87× at α = 0.15, and is unchanged (1.03×)
    /// at α = 0.2. No effect for a BRDF without a lobe, for exhaustive scans or for deterministic sampling.
    /// `lobe_fraction = 0` turns it off.
    ///
    /// # Errors
    /// [`RenderError::InvalidParameter`] unless `0 ≤ lobe_fraction < 1`.
    pub fn set_lobe_sampling(&mut self, lobe_fraction: f32) -> Result<()> {
        self.scene.set_lobe_sampling(lobe_fraction)
    }

    /// Chooses where [`Renderer::forward`] and [`Renderer::adjoint`] (and so the loss-and-gradient) run: the
    /// CPU, or a GPU through the feature `gpu`'s backend ([`crate::GpuRenderer`], one adapter shared by the
    /// process). The GPU runs what [`gpu_support`] accepts (the splat rule with the tent kernel, cached or no
    /// visibility, the Lambertian and retroreflective models); a call it cannot take (another BRDF, a device error) runs on the CPU, and a device
    /// error is reported once on stderr. Results on a GPU match the CPU's to f32 rounding and repeat bit for
    /// bit on the same device; the CPU path is unchanged. Everything else (steady state, per-triangle shares,
    /// visibility) stays on the CPU.
    ///
    /// # Errors
    /// [`RenderError::Gpu`] for [`Device::Gpu`] when the build has no GPU backend, no adapter is found, or the
    /// renderer's settings have no GPU version. [`Device::Auto`] never fails: it takes the CPU then.
    pub fn set_device(&mut self, device: Device) -> Result<()> {
        self.backends.attach(device, &self.scene.params)
    }

    /// Where the forward and adjoint passes run: [`Device::Gpu`] when a GPU is attached
    /// ([`Renderer::set_device`]), else [`Device::Cpu`].
    pub fn device(&self) -> Device {
        self.backends.device()
    }

    /// Sets one reflectance factor per mesh triangle (`None`: all 1): triangle t's contribution to the
    /// forward pass, and to every gradient, is multiplied by `w_t` — a spatially varying albedo constant over
    /// each face, on top of the BRDF. The factors are kept across [`Renderer::set_positions`]; the adjoint
    /// pass returns dE/dw_t in [`Gradient::faces`]. A factor of 0 makes the triangle black: it is skipped, but
    /// it still casts shadows (visibility sees geometry only).
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] unless there is one factor per triangle,
    /// [`RenderError::InvalidParameter`] for a negative or non-finite factor.
    pub fn set_face_weights(&mut self, weights: Option<&[f32]>) -> Result<()> {
        self.scene.set_face_weights(weights)
    }

    /// The per-triangle reflectance factors set by [`Renderer::set_face_weights`], if any.
    pub fn face_weights(&self) -> Option<&[f32]> {
        self.scene.face_weights.as_deref()
    }

    /// Number of skipped degenerate triangles.
    pub fn degenerate_triangles(&self) -> usize {
        self.scene.degenerate_triangles()
    }

    /// Number of values of a transient (measurements × bins).
    pub fn len(&self) -> usize {
        self.scene.len()
    }

    /// Whether the transient is empty (never: the scan and time axis are validated non-empty).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The forward pass, eq. (1): `I[m·bins + k] = Σ_t ∫_t K_k(τ(x)) f(x) v(x,l) v(x,s) dA(x)` with f the
    /// product of eq. (2) (see the crate docs for the scale convention).
    pub fn forward<B: FittedBrdf>(&self, brdf: &B) -> Vec<f32> {
        self.forward_any(&brdf.to_any())
    }

    /// [`Renderer::forward`] wrapped as a [`Transient`] with the renderer's scan and time axis.
    ///
    /// # Errors
    /// [`RenderError::InvalidSetup`] if the transient crate rejects the combination (it should not).
    pub fn forward_transient<B: FittedBrdf>(&self, brdf: &B) -> Result<Transient> {
        Transient::new(self.scene.scan.clone(), self.scene.time, self.forward(brdf))
            .map_err(|e| RenderError::InvalidSetup(e.to_string()))
    }

    /// The adjoint pass: given `d_loss[m·bins + k] = dE/dI`, returns dE/d(vertices) and dE/d(BRDF
    /// parameters) of the same estimator the forward pass computes (same samples, same kernel, visibility
    /// held fixed). Samples are recomputed, nothing is stored between passes.
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] when `d_loss` is not measurements × bins long.
    pub fn adjoint<B: FittedBrdf>(&self, brdf: &B, d_loss: &[f32]) -> Result<Gradient> {
        self.adjoint_any(&brdf.to_any(), d_loss)
    }

    /// Steady-state (time-integrated) intensity, one value per measurement: `S(l, s) = ∫_S f(x) v(x,l) v(x,s)
    /// dA(x)`, eq. (1) without the temporal kernel — what a conventional (non-transient) camera would record
    /// at s under a continuous source at l. Tsai et al. 2019 note that the method applies to any radiometric
    /// measurement; this is the simplest one. Equals the time sum of [`Renderer::forward`] (any kernel)
    /// whenever the time axis holds every path length; the same samples and visibility as the transient.
    pub fn forward_steady<B: FittedBrdf>(&self, brdf: &B) -> Vec<f32> {
        self.cpu.view(&self.scene).forward_with(brdf, &KernelEval::steady())
    }

    /// Adjoint of [`Renderer::forward_steady`]: given `d_loss[m] = dE/dS_m` (one per measurement), dE/d(vertices)
    /// and dE/d(BRDF parameters) (no time-shift term: S does not depend on path length).
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] when `d_loss` does not hold one value per measurement.
    pub fn adjoint_steady<B: FittedBrdf>(&self, brdf: &B, d_loss: &[f32]) -> Result<Gradient> {
        self.cpu.view(&self.scene).adjoint_with(brdf, d_loss, &KernelEval::steady())
    }

    /// [`Renderer::loss_and_gradient`] for steady-state measurements (`measured`: one value per measurement).
    ///
    /// # Errors
    /// As [`Loss::evaluate`].
    pub fn loss_and_gradient_steady<B: FittedBrdf>(
        &self,
        brdf: &B,
        measured: &[f32],
        loss: Loss,
        weights: Option<&[f32]>,
    ) -> Result<LossAndGradient> {
        let rendered = self.forward_steady(brdf);
        let (e, adj) = loss.evaluate(&rendered, measured, weights)?;
        let gradient = self.adjoint_steady(brdf, &adj)?;
        Ok(LossAndGradient { loss: e, gradient, rendered })
    }

    /// Forward pass, loss, adjoint pass: `E(I; measured)` and its gradient (eq. 6–7 of Tsai et al. 2019 for
    /// [`Loss::L2`]).
    ///
    /// # Errors
    /// As [`Loss::evaluate`].
    pub fn loss_and_gradient<B: FittedBrdf>(
        &self,
        brdf: &B,
        measured: &[f32],
        loss: Loss,
        weights: Option<&[f32]>,
    ) -> Result<LossAndGradient> {
        let rendered = self.forward(brdf);
        let (e, adj) = loss.evaluate(&rendered, measured, weights)?;
        let gradient = self.adjoint(brdf, &adj)?;
        Ok(LossAndGradient { loss: e, gradient, rendered })
    }

    /// The forward pass of one mesh triangle: its share of [`Renderer::forward`] (same samples, kernel and
    /// visibility; summed over every triangle it equals the forward pass up to f32 rounding). Sparse: one
    /// [`RowSpan`] per measurement the triangle reaches, holding the bins from its first to its last
    /// non-zero one. Used to ask what the loss would be without a face (boundary pruning in `nlos-optim`).
    ///
    /// Degenerate triangles (skipped by the forward pass) give no rows.
    ///
    /// # Errors
    /// [`RenderError::InvalidParameter`] when `triangle` is not a triangle of the mesh.
    pub fn forward_triangle<B: FittedBrdf>(&self, brdf: &B, triangle: usize) -> Result<Vec<RowSpan>> {
        self.cpu.view(&self.scene).forward_triangle(brdf, triangle)
    }
}

/// The passes with a BRDF chosen at run time ([`AnyBrdf`]): each calls the generic pass of the same name with
/// the concrete model, so the inner loops stay monomorphised.
impl Renderer {
    /// [`Renderer::forward`].
    pub fn forward_any(&self, brdf: &AnyBrdf) -> Vec<f32> {
        match self.backends.run(&self.scene, brdf, |b| b.forward(&self.scene, brdf)) {
            Ok(out) => out,
            // The CPU's forward pass cannot fail.
            Err(_) => nlos_brdf::with_brdf!(brdf, b => self.cpu.forward(&self.scene, b)),
        }
    }

    /// [`Renderer::adjoint`].
    ///
    /// # Errors
    /// As [`Renderer::adjoint`].
    pub fn adjoint_any(&self, brdf: &AnyBrdf, d_loss: &[f32]) -> Result<Gradient> {
        if d_loss.len() != self.len() {
            return Err(RenderError::LengthMismatch { what: "d_loss", expected: self.len(), got: d_loss.len() });
        }
        self.backends.run(&self.scene, brdf, |b| b.adjoint(&self.scene, brdf, d_loss))
    }

    /// [`Renderer::forward_triangle`].
    ///
    /// # Errors
    /// As [`Renderer::forward_triangle`].
    pub fn forward_triangle_any(&self, brdf: &AnyBrdf, triangle: usize) -> Result<Vec<RowSpan>> {
        nlos_brdf::with_brdf!(brdf, b => self.forward_triangle(b, triangle))
    }
}

/// The backends of one renderer, in the order a pass tries them: an accelerator first where one is attached,
/// the CPU last.
#[derive(Debug)]
struct Backends {
    accelerator: Option<Box<dyn Backend>>,
    cpu: CpuBackend,
}

impl Backends {
    /// The CPU alone.
    fn cpu(cpu: CpuBackend) -> Self {
        Self { accelerator: None, cpu }
    }

    /// Attaches the accelerator for `device` ([`accelerator`]), or none.
    ///
    /// # Errors
    /// As [`accelerator`].
    fn attach(&mut self, device: Device, params: &RenderParams) -> Result<()> {
        self.accelerator = accelerator(device, params)?;
        Ok(())
    }

    /// Where passes run when the accelerator takes them: its device, else the CPU.
    fn device(&self) -> Device {
        self.accelerator.as_ref().map_or(Device::Cpu, |a| a.device())
    }

    /// Runs `pass` on the first backend that supports `brdf`'s model with the scene's settings and succeeds;
    /// the CPU, last, runs every pass. The one dispatch of the renderer.
    ///
    /// # Errors
    /// The CPU pass's error.
    fn run<T>(&self, scene: &Scene, brdf: &AnyBrdf, pass: impl Fn(&dyn Backend) -> Result<T>) -> Result<T> {
        if let Some(a) = &self.accelerator
            && a.supports(brdf.model(), &scene.params).is_ok()
            && let Ok(out) = pass(a.as_ref())
        {
            return Ok(out);
        }
        pass(&self.cpu)
    }
}

/// The accelerator a renderer with settings `params` gets for `device`: the GPU with the feature `gpu` and an
/// adapter (for [`Device::Auto`], a hardware one whose settings have a GPU version), else none.
///
/// # Errors
/// [`RenderError::Gpu`] for [`Device::Gpu`] when the build has no GPU backend, no adapter is found, or the
/// settings have no GPU version.
fn accelerator(device: Device, params: &RenderParams) -> Result<Option<Box<dyn Backend>>> {
    #[cfg(feature = "gpu")]
    {
        Ok(gpu::attach(device, params)?.map(|g| Box::new(g) as Box<dyn Backend>))
    }
    #[cfg(not(feature = "gpu"))]
    {
        let _ = params;
        match device {
            Device::Gpu => Err(crate::error::RenderError::Gpu(
                "this build has no GPU backend: build with the feature `gpu` (cargo build --features gpu)".into(),
            )),
            Device::Cpu | Device::Auto => Ok(None),
        }
    }
}

/// Calls `f` for the `n²` congruent sub-triangles of level n (n per edge): the "up" sub-triangle with corner
/// (i, j) has its centroid at (i + 1/3, j + 1/3)/n, the "down" one at (i + 2/3, j + 2/3)/n; each carries its
/// corners, centroid and weight `1/n²` (the fraction of the triangle's area).
#[inline(always)]
fn subtriangles(n: u32, mut f: impl FnMut(soa::Sub)) {
    let inv = 1.0 / n as f32;
    let w = inv * inv;
    let p = |i: u32, j: u32| (i as f32 * inv, j as f32 * inv);
    for i in 0..n {
        for j in 0..n - i {
            let centroid = ((i as f32 + 1.0 / 3.0) * inv, (j as f32 + 1.0 / 3.0) * inv);
            f(soa::Sub { corners: [p(i, j), p(i + 1, j), p(i, j + 1)], centroid, w });
            if j + 1 < n - i {
                let centroid = ((i as f32 + 2.0 / 3.0) * inv, (j as f32 + 2.0 / 3.0) * inv);
                f(soa::Sub { corners: [p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)], centroid, w });
            }
        }
    }
}

#[cfg(test)]
mod tests;
