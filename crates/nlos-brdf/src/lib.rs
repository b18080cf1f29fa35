//! # nlos-brdf
//!
//! Reflectance models for non-line-of-sight surface reconstruction (Tsai, Sankaranarayanan & Gkioulekas,
//! CVPR 2019): [`Lambertian`] and [`Ggx`] (Walter et al. 2007 microfacet over a Lambertian base), each
//! evaluated **with all its gradients in one call**, plus importance sampling for multiple importance
//! sampling of glossy surfaces.
//!
//! ```text
//! f(ω_l, ω_s, n) = ρ_d/π + ρ_s · D(h) · G(ω_l, ω_s) · F(ω_l·h) / (4 (n·ω_l)(n·ω_s))
//! h = (ω_l + ω_s)/|ω_l + ω_s|
//! ```
//! `ω_l` points from the surface point toward the laser spot, `ω_s` toward the sensor spot, `n` is the
//! surface normal. `D` is GGX/Trowbridge–Reitz, `G` Smith (separable by default, height-correlated optional,
//! [`Masking`]), `F` is 1 by default or Schlick ([`Fresnel`]).
//!
//! ## Example
//! ```
//! use glam::Vec3;
//! use nlos_brdf::{Brdf, Fresnel, Ggx};
//! let brdf = Ggx::new(0.3f32, 1.0, 0.2, Fresnel::One)?;
//! // Unnormalised inputs are fine: x → laser spot, x → sensor spot, triangle normal.
//! let g = brdf.eval_grad(Vec3::new(0.1, 0.0, 0.9), Vec3::new(-0.2, 0.1, 1.1), Vec3::new(0.0, 0.0, 2.0));
//! assert!(g.value > 0.0 && g.d_params.alpha.is_finite());
//! let sample = brdf.sample(Vec3::new(0.1, 0.0, 0.9), Vec3::Z, [0.2, 0.5, 0.5]).expect("front-facing");
//! assert!(sample.pdf > 0.0 && sample.omega.z > 0.0);
//! # Ok::<(), nlos_brdf::BrdfError>(())
//! ```
//!
//! ## Design
//! **A trait with static dispatch, not an enum.** The renderer calls the BRDF billions of times in a loop
//! whose model is fixed for a whole reconstruction. Writing the loop generic over `B: Brdf` monomorphises it
//! per model: no per-call branch, the Lambertian loop collapses to a constant (its direction gradients are
//! zero), and each model returns its own fixed-size [`Brdf::ParamGrad`] record (1 parameter vs 4) with no
//! allocation and no padding to the largest model. An enum would put a `match` in the innermost loop and
//! force a common parameter-gradient layout. Nothing is boxed and every method is `#[inline]`.
//!
//! **Generic over the scalar.** All formulas are written once over [`Real`] (`f32` with [`glam::Vec3`] for
//! the renderer, `f64` with [`glam::DVec3`]); the tests check the `f32` analytic gradients against the
//! same code in `f64` and both against central finite differences in `f64`. `Ggx` alone means `Ggx<f32>`.
//!
//! ## What is differentiated
//! [`Brdf::eval_grad`] returns the gradient of the **composed** function
//! `F(ω_l, ω_s, n) = f(ω_l/|ω_l|, ω_s/|ω_s|, n/|n|)` with respect to the raw, unconstrained 3-vectors
//! `ω_l, ω_s, n ∈ ℝ³ \ {0}`. All normalisations are inside: of the three inputs and of the half vector
//! `h = (ω̂_l + ω̂_s)/|ω̂_l + ω̂_s|`. Consequences for the renderer's chain rule:
//! * pass `laser_spot − x`, `sensor_spot − x` and the unnormalised triangle normal `(v1−v0)×(v2−v0)` and
//!   chain directly: the normalisation Jacobians are already applied;
//! * at unit inputs the gradients are tangent (`∂F/∂ω·ω = 0`), so chaining again through one's own
//!   normalisation is harmless (the projection is idempotent);
//! * the value never depends on input lengths — for [`Lambertian`] and [`Ggx`]; [`Retroreflective`] reads
//!   `|ω_l||ω_s|` (its `1/r²` return, see [`retro`]), and its gradients carry that term, so the same chain
//!   rule holds.
//!
//! Derivation (unit `l, s, n`; `μ_l = n·l`, `μ_s = n·s`, `c = n·h`, `u = l·h = |l+s|/2`):
//! `∇_l = f_μl n + f_c (n − c h)/|l+s| + f_u h/2`, likewise for `s`, `∇_n = f_μl l + f_μs s + f_c h`, then each
//! is mapped through `(I − v̂v̂ᵀ)/|v|`. The scalar partials `f_μ`, `f_c`, `f_u`, `∂/∂α` come from
//! [`microfacet::d_grad`], [`Masking::vis_grad`] and [`Fresnel::f_grad`].
//!
//! The confocal path ([`Brdf::eval_grad_confocal`], `ω_l = ω_s = ω`, `h = ω`) returns the total derivative
//! along the shared direction: `d_omega = d_omega_l + d_omega_s` of the general path.
//!
//! Back-facing configurations (`n·ω_l ≤ 0` or `n·ω_s ≤ 0`) return 0 and zero gradients: f jumps there,
//! so the gradient of the step is 0 almost everywhere (the boundary term is the renderer's business).
//!
//! ## Parameters
//! Constructors validate their domains and return [`BrdfError`]; for optimisation, [`GgxTheta`] and
//! [`LambertianTheta`] give a smooth unconstrained reparametrisation (softplus albedos, logistic α in
//! `[ALPHA_MIN, ALPHA_MAX]`, logistic F0) with the chain rule (see [`param`]).
//!
//! ## Sampling
//! [`sampling`] has cosine-weighted hemisphere sampling and VNDF sampling of GGX (Heitz 2018) with their
//! solid-angle pdfs; [`Brdf::sample`] / [`Brdf::pdf`] mix the lobes for MIS.
#![warn(missing_docs)]
// `!(x > 0)` is deliberate throughout: unlike `x <= 0` it is also true for NaN, which is how zero-length or
// non-finite inputs fall into the "back-facing → 0" branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod brdf;
pub mod error;
pub mod fresnel;
pub mod ggx;
pub mod lambert;
pub mod microfacet;
pub mod model;
pub mod param;
pub mod real;
pub mod retro;
pub mod sampling;

pub use brdf::{Brdf, BrdfSample, ConfocalGrad, Grad, Lobe};
pub use error::{BrdfError, Result};
pub use fresnel::Fresnel;
pub use ggx::{ALPHA_MAX, ALPHA_MIN, Ggx, GgxGrad};
pub use lambert::{Lambertian, LambertianGrad};
pub use microfacet::Masking;
pub use model::{AnyBrdf, FittedBrdf, Model};
pub use param::{GgxTheta, LambertianTheta};
pub use real::{Real, V3, Vector3};
pub use retro::{RETRO_LOBE_WIDTH, Retroreflective, RetroreflectiveGrad};
