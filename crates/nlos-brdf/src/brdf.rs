//! The [`Brdf`] trait and the value+gradient records it returns.

use crate::real::{Real, V3, Vector3};

/// A reflectance model that the renderer evaluates, differentiates and samples.
///
/// All methods are allocation-free and `#[inline]` in the implementations; write the renderer generic over
/// `B: Brdf` so that each model gets its own monomorphised inner loop (see the crate docs for why this is a
/// trait and not an enum).
///
/// # Conventions
/// * `omega_l` points from the surface point toward the laser spot, `omega_s` toward the sensor spot, `n` is
///   the surface normal. None needs to be unit length: every method normalises its inputs, and the gradients
///   are those of the composed function `f(ω_l/|ω_l|, ω_s/|ω_s|, n/|n|)` with respect to the raw vectors —
///   except [`crate::Retroreflective`], whose value also reads `|ω_l||ω_s|` (pass the vectors in metres; its
///   gradients include that length term).
/// * Back-facing configurations (`n·ω_l ≤ 0` or `n·ω_s ≤ 0`) and degenerate (zero or non-finite) vectors
///   give value 0 and all gradients 0.
pub trait Brdf: Copy + std::fmt::Debug + Send + Sync {
    /// Scalar precision (`f32` for the renderer, `f64` for references).
    type Scalar: Real;
    /// ∂f/∂(each model parameter), a small `Copy` record.
    type ParamGrad: Copy + std::fmt::Debug + Default + PartialEq;

    /// f(ω_l, ω_s, n) in 1/sr.
    fn eval(&self, omega_l: V3<Self::Scalar>, omega_s: V3<Self::Scalar>, n: V3<Self::Scalar>) -> Self::Scalar;

    /// f and all its gradients in one call (see [`Grad`]).
    fn eval_grad(
        &self,
        omega_l: V3<Self::Scalar>,
        omega_s: V3<Self::Scalar>,
        n: V3<Self::Scalar>,
    ) -> Grad<Self::Scalar, Self::ParamGrad>;

    /// Confocal fast path: f(ω, ω, n).
    fn eval_confocal(&self, omega: V3<Self::Scalar>, n: V3<Self::Scalar>) -> Self::Scalar;

    /// Confocal fast path with gradients; `d_omega` is the total derivative with respect to the shared
    /// direction, i.e. `d_omega_l + d_omega_s` of [`Brdf::eval_grad`] at `ω_l = ω_s = ω`.
    fn eval_grad_confocal(
        &self,
        omega: V3<Self::Scalar>,
        n: V3<Self::Scalar>,
    ) -> ConfocalGrad<Self::Scalar, Self::ParamGrad>;

    /// Importance-samples an outgoing direction given the fixed direction `omega_i` (either ω_l or ω_s: the
    /// model is reciprocal) from `u`, three independent uniform numbers in `[0, 1)` (`u[0]` selects the
    /// lobe). Returns `None` when `omega_i` is back-facing or the sampled direction falls below the surface
    /// (possible for the specular lobe); the returned pdf is the density of the whole sampler, so
    /// `∫_{H²} pdf ≤ 1` and the missing mass is the probability of `None`.
    fn sample(
        &self,
        omega_i: V3<Self::Scalar>,
        n: V3<Self::Scalar>,
        u: [Self::Scalar; 3],
    ) -> Option<BrdfSample<Self::Scalar>>;

    /// The solid-angle density with which [`Brdf::sample`] produces `omega_o` (for multiple importance
    /// sampling); 0 when either direction is back-facing.
    fn pdf(&self, omega_i: V3<Self::Scalar>, omega_o: V3<Self::Scalar>, n: V3<Self::Scalar>) -> Self::Scalar;
}

/// The value of f and its gradients, from [`Brdf::eval_grad`].
///
/// The direction and normal gradients are with respect to the **raw, unnormalised** input vectors of the
/// composed function `f(ω_l/|ω_l|, ω_s/|ω_s|, n/|n|)`: pass `laser_spot − x` unnormalised and the
/// unnormalised triangle normal and chain straight into them. At unit inputs they are tangent
/// (`d_omega_l · ω_l = 0`, …), so chaining them again through your own normalisation is harmless.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Grad<T: Real, P> {
    /// f in 1/sr.
    pub value: T,
    /// ∂f/∂(model parameters).
    pub d_params: P,
    /// ∂f/∂ω_l.
    pub d_omega_l: V3<T>,
    /// ∂f/∂ω_s.
    pub d_omega_s: V3<T>,
    /// ∂f/∂n.
    pub d_n: V3<T>,
}

/// The value of f and its gradients on the confocal path, from [`Brdf::eval_grad_confocal`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ConfocalGrad<T: Real, P> {
    /// f(ω, ω, n) in 1/sr.
    pub value: T,
    /// ∂f/∂(model parameters).
    pub d_params: P,
    /// Total derivative with respect to the shared, unnormalised direction ω.
    pub d_omega: V3<T>,
    /// ∂f/∂n with respect to the unnormalised normal.
    pub d_n: V3<T>,
}

impl<T: Real, P: Default> Grad<T, P> {
    /// Value 0 and every gradient 0 (back-facing or degenerate input).
    #[inline(always)]
    pub fn zero() -> Self {
        Self {
            value: T::ZERO,
            d_params: P::default(),
            d_omega_l: V3::<T>::ZERO,
            d_omega_s: V3::<T>::ZERO,
            d_n: V3::<T>::ZERO,
        }
    }
}

impl<T: Real, P: Default> ConfocalGrad<T, P> {
    /// Value 0 and every gradient 0 (back-facing or degenerate input).
    #[inline(always)]
    pub fn zero() -> Self {
        Self { value: T::ZERO, d_params: P::default(), d_omega: V3::<T>::ZERO, d_n: V3::<T>::ZERO }
    }
}

/// Which lobe a sample was drawn from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Lobe {
    /// The Lambertian lobe (cosine-weighted hemisphere sampling).
    Diffuse,
    /// The GGX lobe (visible-normal sampling, Heitz 2018).
    Specular,
}

/// A direction drawn by [`Brdf::sample`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrdfSample<T: Real> {
    /// The sampled unit direction (world space), on the front side of the surface.
    pub omega: V3<T>,
    /// Its density with respect to solid angle under the whole (lobe-mixing) sampler, > 0.
    pub pdf: T,
    /// The lobe it came from.
    pub lobe: Lobe,
}
