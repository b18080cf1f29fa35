//! The Fresnel factor F of the microfacet model.

use crate::real::Real;

/// Fresnel factor of the GGX lobe.
///
/// The seed has no Fresnel term ([`Fresnel::One`], the default); [`Fresnel::Schlick`] is Schlick's
/// approximation with reflectance `f0` at normal incidence.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(bound = "")]
pub enum Fresnel<T: Real> {
    /// F = 1 (no Fresnel effect).
    #[default]
    One,
    /// Schlick (1994, eq. 15): `F(u) = F0 + (1 − F0)(1 − u)⁵`, `u = ω·h`.
    Schlick {
        /// Reflectance at normal incidence, in `[0, 1]`.
        f0: T,
    },
}

impl<T: Real> Fresnel<T> {
    /// `F(u)` for `u = ω_l·h = ω_s·h` (cosine between either direction and the half vector).
    #[inline(always)]
    pub fn f(self, u: T) -> T {
        self.f_grad(u).0
    }

    /// `(F, ∂F/∂u, ∂F/∂F0)` (Schlick 1994, eq. 15); `∂F/∂F0 = 0` for [`Fresnel::One`].
    #[inline(always)]
    pub fn f_grad(self, u: T) -> (T, T, T) {
        match self {
            Fresnel::One => (T::ONE, T::ZERO, T::ZERO),
            Fresnel::Schlick { f0 } => {
                // u = |ω_l + ω_s|/2 can round to slightly above 1 in f32; (1 − u) < 0 would flip the sign of the
                // odd powers. The clamp only acts where (1 − u)⁴ ≈ 0, so the gradient stays consistent.
                let x = (T::ONE - u).max(T::ZERO);
                let x2 = x * x;
                let x4 = x2 * x2;
                let x5 = x4 * x;
                (f0 + (T::ONE - f0) * x5, -T::from_f64(5.0) * (T::ONE - f0) * x4, T::ONE - x5)
            }
        }
    }

    /// `F0` if Schlick, `None` for [`Fresnel::One`].
    #[inline]
    pub fn f0(self) -> Option<T> {
        match self {
            Fresnel::One => None,
            Fresnel::Schlick { f0 } => Some(f0),
        }
    }
}
