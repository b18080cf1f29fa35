//! The Lambertian (ideal diffuse) BRDF.

use crate::brdf::{Brdf, BrdfSample, ConfocalGrad, Grad, Lobe};
use crate::error::{BrdfError, Result};
use crate::real::{Real, V3, Vector3, normalize_with_inv_len};
use crate::sampling::{Frame, pdf_cosine_hemisphere, sample_cosine_hemisphere};

/// Lambertian reflectance `f = ρ/π` on the front side, 0 behind.
///
/// Its only direction dependence is the front-facing test, so every direction and normal gradient is 0
/// (the test is a step; its derivative is 0 almost everywhere).
///
/// # Example
/// ```
/// use glam::Vec3;
/// use nlos_brdf::{Brdf, Lambertian};
/// let brdf = Lambertian::new(0.5f32)?;
/// let g = brdf.eval_grad(Vec3::new(0.0, 1.0, 2.0), Vec3::new(1.0, 0.0, 1.0), Vec3::Z);
/// assert!((g.value - 0.5 / std::f32::consts::PI).abs() < 1e-7);
/// assert!((g.d_params.albedo - 1.0 / std::f32::consts::PI).abs() < 1e-7);
/// assert_eq!(brdf.eval(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, Vec3::Z), 0.0); // back-facing
/// # Ok::<(), nlos_brdf::BrdfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "LambertianRaw<T>", into = "LambertianRaw<T>", bound = "")]
pub struct Lambertian<T: Real = f32> {
    albedo: T,
}

/// ∂f/∂(parameters) of [`Lambertian`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LambertianGrad<T> {
    /// ∂f/∂ρ (`1/π` on the front side).
    pub albedo: T,
}

impl<T: Real> Lambertian<T> {
    /// A Lambertian BRDF with albedo ρ.
    ///
    /// # Errors
    /// [`BrdfError::InvalidAlbedo`] if `albedo` is negative or not finite (values above 1 are accepted).
    pub fn new(albedo: T) -> Result<Self> {
        check_albedo("albedo", albedo)?;
        Ok(Self { albedo })
    }

    /// The albedo ρ.
    #[inline(always)]
    pub fn albedo(&self) -> T {
        self.albedo
    }

    #[inline(always)]
    fn front(omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> bool {
        // Unnormalised dot products have the sign of the cosines; a zero vector gives 0 and NaN compares false,
        // so degenerate input counts as back-facing.
        n.dot(omega_l) > T::ZERO && n.dot(omega_s) > T::ZERO
    }
}

/// Shared validation of an albedo-like parameter.
pub(crate) fn check_albedo<T: Real>(name: &'static str, value: T) -> Result<()> {
    if value.is_finite() && value >= T::ZERO {
        Ok(())
    } else {
        Err(BrdfError::InvalidAlbedo { name, value: value.to_f64() })
    }
}

impl<T: Real> Brdf for Lambertian<T> {
    type Scalar = T;
    type ParamGrad = LambertianGrad<T>;

    #[inline]
    fn eval(&self, omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> T {
        if Self::front(omega_l, omega_s, n) { self.albedo * T::FRAC_1_PI } else { T::ZERO }
    }

    #[inline]
    fn eval_grad(&self, omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> Grad<T, LambertianGrad<T>> {
        if !Self::front(omega_l, omega_s, n) {
            return Grad::zero();
        }
        Grad { value: self.albedo * T::FRAC_1_PI, d_params: LambertianGrad { albedo: T::FRAC_1_PI }, ..Grad::zero() }
    }

    #[inline]
    fn eval_confocal(&self, omega: V3<T>, n: V3<T>) -> T {
        self.eval(omega, omega, n)
    }

    #[inline]
    fn eval_grad_confocal(&self, omega: V3<T>, n: V3<T>) -> ConfocalGrad<T, LambertianGrad<T>> {
        let g = self.eval_grad(omega, omega, n);
        ConfocalGrad { value: g.value, d_params: g.d_params, ..ConfocalGrad::zero() }
    }

    #[inline]
    fn sample(&self, omega_i: V3<T>, n: V3<T>, u: [T; 3]) -> Option<BrdfSample<T>> {
        let (nn, _) = normalize_with_inv_len::<T>(n);
        if !(nn.dot(omega_i) > T::ZERO) {
            return None;
        }
        let frame = Frame::<T>::from_normal(nn);
        let wo = sample_cosine_hemisphere(u[1], u[2]);
        let pdf = pdf_cosine_hemisphere(wo.z());
        // The pole-less rim of the disk maps to z = 0 (pdf 0): not a usable sample.
        if !(pdf > T::ZERO) {
            return None;
        }
        Some(BrdfSample { omega: frame.to_world(wo), pdf, lobe: Lobe::Diffuse })
    }

    #[inline]
    fn pdf(&self, omega_i: V3<T>, omega_o: V3<T>, n: V3<T>) -> T {
        let (nn, _) = normalize_with_inv_len::<T>(n);
        let (wo, _) = normalize_with_inv_len::<T>(omega_o);
        if !(nn.dot(omega_i) > T::ZERO) {
            return T::ZERO;
        }
        pdf_cosine_hemisphere(nn.dot(wo))
    }
}

/// Serialised form of [`Lambertian`], validated on deserialisation.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(bound = "")]
struct LambertianRaw<T: Real> {
    albedo: T,
}

impl<T: Real> TryFrom<LambertianRaw<T>> for Lambertian<T> {
    type Error = BrdfError;
    fn try_from(raw: LambertianRaw<T>) -> Result<Self> {
        Self::new(raw.albedo)
    }
}

impl<T: Real> From<Lambertian<T>> for LambertianRaw<T> {
    fn from(l: Lambertian<T>) -> Self {
        Self { albedo: l.albedo }
    }
}
