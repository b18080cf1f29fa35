//! Smooth, unconstrained reparametrisation of the BRDF parameters for gradient-based optimisation.
//!
//! An optimiser moves unconstrained reals θ; each maps smoothly (C^∞, strictly monotone, never a flat clamp)
//! onto its parameter's domain, so every θ gives a valid BRDF and no gradient is cut off at a bound:
//!
//! | parameter | domain | map | derivative |
//! |---|---|---|---|
//! | albedo ρ_d, ρ, specular ρ_s | `[0, ∞)` | `ρ = softplus(θ) = ln(1 + eᶿ)` | `σ(θ)` |
//! | roughness α | `[ALPHA_MIN, ALPHA_MAX]` | `α = α_min + (α_max − α_min) σ(θ)` | `(α_max − α_min) σ(1 − σ)` |
//! | Schlick F0 | `[0, 1]` | `F0 = σ(θ) = 1/(1 + e^{−θ})` | `σ(1 − σ)` |
//!
//! Softplus rather than `exp` for the albedos: it is linear for large θ (no exploding steps when the
//! albedo absorbs the capture's radiometric scale) and still reaches 0 smoothly. A logistic rather than
//! `exp(θ)` clamped to `[α_min, 1]` for α: the clamp would zero the gradient on its plateaus.
//! The inverse maps (`from_*`) send a boundary value (albedo 0, F0 ∈ {0, 1}, α at a bound) to a large but
//! finite θ, pulled in by a relative `1e-6` (an albedo of 0 becomes about θ = ln 1e-6 ≈ −13.8).

use crate::error::Result;
use crate::fresnel::Fresnel;
use crate::ggx::{ALPHA_MAX, ALPHA_MIN, Ggx, GgxGrad};
use crate::lambert::{Lambertian, LambertianGrad};
use crate::microfacet::Masking;
use crate::real::Real;

/// Logistic function `σ(x) = 1/(1 + e^{−x})`, evaluated without overflow for either sign.
#[inline(always)]
pub fn sigmoid<T: Real>(x: T) -> T {
    if x >= T::ZERO {
        T::ONE / (T::ONE + (-x).exp())
    } else {
        let e = x.exp();
        e / (T::ONE + e)
    }
}

/// `ln(p/(1 − p))`, the inverse of [`sigmoid`], with `p` pulled into `[1e-6, 1 − 1e-6]` so that the bounds
/// map to finite values.
#[inline]
pub fn logit<T: Real>(p: T) -> T {
    let eps = T::from_f64(1e-6);
    let p = p.max(eps).min(T::ONE - eps);
    (p / (T::ONE - p)).ln()
}

/// `softplus(x) = ln(1 + eˣ)`, evaluated as `max(x, 0) + ln(1 + e^{−|x|})` to avoid overflow.
#[inline(always)]
pub fn softplus<T: Real>(x: T) -> T {
    x.max(T::ZERO) + (-x.abs()).exp().ln_1p()
}

/// Inverse of [`softplus`]: `y + ln(1 − e^{−y})` for `y > 0`, with `y` floored at `1e-6`.
#[inline]
pub fn softplus_inv<T: Real>(y: T) -> T {
    let y = y.max(T::from_f64(1e-6));
    y + (-(-y).exp_m1()).ln()
}

/// α from its unconstrained parameter: `α_min + (α_max − α_min) σ(θ)`.
#[inline(always)]
fn alpha_of<T: Real>(theta: T) -> T {
    let lo = T::from_f64(ALPHA_MIN);
    let hi = T::from_f64(ALPHA_MAX);
    // Rounding of lo + (hi − lo)·1 can exceed hi by an ulp in f32; the clamp acts only where σ' ≈ 0.
    (lo + (hi - lo) * sigmoid(theta)).min(hi)
}

/// Unconstrained parameters of a [`Lambertian`]: `albedo = softplus(self.albedo)`.
///
/// # Example
/// ```
/// use nlos_brdf::{Lambertian, LambertianTheta};
/// let theta = LambertianTheta::from_lambertian(&Lambertian::new(0.3f64)?);
/// assert!((theta.to_lambertian()?.albedo() - 0.3).abs() < 1e-12);
/// # Ok::<(), nlos_brdf::BrdfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(bound = "")]
pub struct LambertianTheta<T: Real> {
    /// θ of the albedo.
    pub albedo: T,
}

impl<T: Real> LambertianTheta<T> {
    /// The θ that maps to `brdf` (see the module docs for boundary values).
    pub fn from_lambertian(brdf: &Lambertian<T>) -> Self {
        Self { albedo: softplus_inv(brdf.albedo()) }
    }

    /// The BRDF these parameters map to.
    ///
    /// # Errors
    /// [`crate::BrdfError::InvalidAlbedo`] only if θ is NaN or `+∞` (every finite θ is valid).
    pub fn to_lambertian(&self) -> Result<Lambertian<T>> {
        Lambertian::new(softplus(self.albedo))
    }

    /// Chain rule: ∂f/∂θ from ∂f/∂(physical parameters).
    #[inline]
    pub fn chain(&self, grad: &LambertianGrad<T>) -> Self {
        Self { albedo: grad.albedo * sigmoid(self.albedo) }
    }
}

/// Unconstrained parameters of a [`Ggx`] (maps in the module docs). `f0` is used only with Schlick Fresnel.
///
/// # Example
/// ```
/// use glam::DVec3;
/// use nlos_brdf::{Brdf, Fresnel, GgxTheta, Masking};
/// let theta = GgxTheta { albedo_diffuse: -1.0f64, specular: 0.5, alpha: -2.0, f0: -3.0 };
/// let brdf = theta.to_ggx(true, Masking::Separable)?;
/// assert!(brdf.alpha() > 0.1 && brdf.alpha() < 0.2 && matches!(brdf.fresnel(), Fresnel::Schlick { .. }));
/// let g = brdf.eval_grad(DVec3::new(0.2, 0.0, 1.0), DVec3::new(-0.1, 0.3, 1.0), DVec3::Z);
/// let d_theta = theta.chain(&g.d_params); // feed this to the optimiser
/// assert!(d_theta.albedo_diffuse > 0.0);
/// # Ok::<(), nlos_brdf::BrdfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(bound = "")]
pub struct GgxTheta<T: Real> {
    /// θ of ρ_d (softplus).
    pub albedo_diffuse: T,
    /// θ of ρ_s (softplus).
    pub specular: T,
    /// θ of α (scaled logistic).
    pub alpha: T,
    /// θ of F0 (logistic).
    pub f0: T,
}

impl<T: Real> GgxTheta<T> {
    /// The θ that maps to `brdf`; with [`Fresnel::One`] `f0` is set to 0 (F0 = 1/2, unused).
    pub fn from_ggx(brdf: &Ggx<T>) -> Self {
        let lo = T::from_f64(ALPHA_MIN);
        let hi = T::from_f64(ALPHA_MAX);
        Self {
            albedo_diffuse: softplus_inv(brdf.albedo_diffuse()),
            specular: softplus_inv(brdf.specular()),
            alpha: logit((brdf.alpha() - lo) / (hi - lo)),
            f0: brdf.fresnel().f0().map_or(T::ZERO, logit),
        }
    }

    /// The BRDF these parameters map to, with Schlick Fresnel if `schlick` (else F = 1) and `masking`.
    ///
    /// # Errors
    /// A [`crate::BrdfError`] only if some θ is NaN or `+∞` (every finite θ maps to a valid BRDF).
    pub fn to_ggx(&self, schlick: bool, masking: Masking) -> Result<Ggx<T>> {
        let fresnel = if schlick { Fresnel::Schlick { f0: sigmoid(self.f0) } } else { Fresnel::One };
        Ok(Ggx::new(softplus(self.albedo_diffuse), softplus(self.specular), alpha_of(self.alpha), fresnel)?
            .with_masking(masking))
    }

    /// Chain rule: ∂f/∂θ from ∂f/∂(physical parameters) as returned in [`crate::Grad::d_params`].
    #[inline]
    pub fn chain(&self, grad: &GgxGrad<T>) -> Self {
        let s_alpha = sigmoid(self.alpha);
        let s_f0 = sigmoid(self.f0);
        let span = T::from_f64(ALPHA_MAX - ALPHA_MIN);
        Self {
            albedo_diffuse: grad.albedo_diffuse * sigmoid(self.albedo_diffuse),
            specular: grad.specular * sigmoid(self.specular),
            alpha: grad.alpha * span * s_alpha * (T::ONE - s_alpha),
            f0: grad.f0 * s_f0 * (T::ONE - s_f0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_round_trip_and_derivatives_match() {
        for &x in &[-30.0f64, -3.0, -0.1, 0.0, 0.7, 5.0, 40.0] {
            let h = 1e-6;
            let fd = (softplus(x + h) - softplus(x - h)) / (2.0 * h);
            assert!((fd - sigmoid(x)).abs() < 1e-8);
            if x > -10.0 {
                assert!((softplus_inv(softplus(x)) - x).abs() < 1e-6 * (1.0 + x.abs()));
            }
            let fd = (sigmoid(x + h) - sigmoid(x - h)) / (2.0 * h);
            assert!((fd - sigmoid(x) * (1.0 - sigmoid(x))).abs() < 1e-8);
        }
        assert!(softplus(1000.0f32).is_finite() && sigmoid(-1000.0f32) >= 0.0);
        let g = Ggx::new(0.0f64, 2.0, ALPHA_MIN, Fresnel::Schlick { f0: 1.0 }).expect("valid parameters");
        let t = GgxTheta::from_ggx(&g);
        assert!(t.albedo_diffuse.is_finite() && t.alpha.is_finite() && t.f0.is_finite());
        let back = t.to_ggx(true, Masking::Separable).expect("finite theta");
        assert!((back.specular() - 2.0).abs() < 1e-9 && (back.alpha() - ALPHA_MIN).abs() < 2e-6);
        for &x in &[-1e6f32, 1e6] {
            let a = alpha_of(x);
            assert!(a >= ALPHA_MIN as f32 && a <= 1.0);
        }
    }
}
