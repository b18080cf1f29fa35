//! The GGX microfacet BRDF with a Lambertian base: `f = ρ_d/π + ρ_s D G F / (4 |n·ω_l| |n·ω_s|)`.

use crate::brdf::{Brdf, BrdfSample, ConfocalGrad, Grad, Lobe};
use crate::error::{BrdfError, Result};
use crate::fresnel::Fresnel;
use crate::lambert::check_albedo;
use crate::microfacet::{Masking, d, d_grad};
use crate::real::{Real, V3, Vector3, normalize_with_inv_len, project_through_normalize};
use crate::sampling::{
    Frame, pdf_cosine_hemisphere, pdf_vndf_reflection, sample_cosine_hemisphere, sample_vndf_reflection,
};

/// Smallest accepted GGX roughness α. Below it the lobe is narrower than `f32` directions can resolve.
pub const ALPHA_MIN: f64 = 1e-3;
/// Largest accepted GGX roughness α.
pub const ALPHA_MAX: f64 = 1.0;

/// GGX (Trowbridge–Reitz) microfacet reflectance over a Lambertian base (Walter et al. 2007, eq. 20):
///
/// `f(ω_l, ω_s, n) = ρ_d/π + ρ_s · D(h) · G(ω_l, ω_s) · F(ω_l·h) / (4 (n·ω_l)(n·ω_s))`,
/// `h = (ω_l + ω_s)/|ω_l + ω_s|`, for `n·ω_l > 0` and `n·ω_s > 0`; 0 otherwise.
///
/// * `D`: [`crate::microfacet::d`] (W07 eq. 33) with roughness α ∈ [[`ALPHA_MIN`], [`ALPHA_MAX`]].
/// * `G`: Smith, [`Masking::Separable`] by default (Tsai et al. 2019's), [`Masking::HeightCorrelated`] optional.
/// * `F`: [`Fresnel::One`] by default (Tsai et al. 2019's), [`Fresnel::Schlick`] optional.
///
/// Fields are private so that every value satisfies the parameter domains; build with [`Ggx::new`] or,
/// inside an optimiser, from unconstrained parameters with [`crate::GgxTheta`].
///
/// # Edge cases
/// Inputs need not be unit length (they are normalised inside, and the gradients include that
/// normalisation; see [`Grad`]). Back-facing or degenerate (zero, NaN) inputs give 0 and zero gradients.
/// At grazing angles the value stays finite: `G/(4 μ_l μ_s)` is evaluated in the cancelled form
/// `1/((μ_l + S_l)(μ_s + S_s))`.
///
/// # Example
/// ```
/// use glam::Vec3;
/// use nlos_brdf::{Brdf, Fresnel, Ggx, Masking};
/// let brdf = Ggx::new(0.2f32, 0.8, 0.3, Fresnel::One)?.with_masking(Masking::HeightCorrelated);
/// let (l, s, n) = (Vec3::new(0.3, 0.1, 1.0), Vec3::new(-0.2, 0.4, 1.0), Vec3::Z);
/// let g = brdf.eval_grad(l, s, n);
/// assert_eq!(g.value, brdf.eval(l, s, n));
/// assert!(g.value > 0.2 / std::f32::consts::PI);
/// // Confocal fast path: total derivative along the shared direction.
/// let c = brdf.eval_grad_confocal(l, n);
/// let general = brdf.eval_grad(l, l, n);
/// assert!((c.value - general.value).abs() < 1e-5 * general.value);
/// let sum = general.d_omega_l + general.d_omega_s;
/// assert!((c.d_omega - sum).length() < 1e-4 * sum.length().max(1.0));
/// // Invalid parameters are rejected.
/// assert!(Ggx::new(0.2f32, 0.8, 0.0, Fresnel::One).is_err());
/// # Ok::<(), nlos_brdf::BrdfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "GgxRaw<T>", into = "GgxRaw<T>", bound = "")]
pub struct Ggx<T: Real = f32> {
    albedo_diffuse: T,
    specular: T,
    alpha: T,
    fresnel: Fresnel<T>,
    masking: Masking,
}

/// ∂f/∂(parameters) of [`Ggx`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GgxGrad<T> {
    /// ∂f/∂ρ_d.
    pub albedo_diffuse: T,
    /// ∂f/∂ρ_s.
    pub specular: T,
    /// ∂f/∂α.
    pub alpha: T,
    /// ∂f/∂F0 (0 with [`Fresnel::One`]).
    pub f0: T,
}

impl<T: Real> Ggx<T> {
    /// A GGX BRDF with separable Smith masking (change with [`Ggx::with_masking`]).
    ///
    /// # Errors
    /// * [`BrdfError::InvalidAlbedo`] if `albedo_diffuse` or `specular` is negative or not finite;
    /// * [`BrdfError::InvalidAlpha`] if `alpha` is not in [[`ALPHA_MIN`], [`ALPHA_MAX`]];
    /// * [`BrdfError::InvalidF0`] if a Schlick `f0` is not in `[0, 1]`.
    pub fn new(albedo_diffuse: T, specular: T, alpha: T, fresnel: Fresnel<T>) -> Result<Self> {
        check_albedo("albedo_diffuse", albedo_diffuse)?;
        check_albedo("specular", specular)?;
        if !(alpha >= T::from_f64(ALPHA_MIN) && alpha <= T::from_f64(ALPHA_MAX)) {
            return Err(BrdfError::InvalidAlpha { value: alpha.to_f64(), min: ALPHA_MIN, max: ALPHA_MAX });
        }
        if let Fresnel::Schlick { f0 } = fresnel
            && !(f0 >= T::ZERO && f0 <= T::ONE)
        {
            return Err(BrdfError::InvalidF0 { value: f0.to_f64() });
        }
        Ok(Self { albedo_diffuse, specular, alpha, fresnel, masking: Masking::Separable })
    }

    /// The same BRDF with another masking-shadowing model.
    #[must_use]
    pub fn with_masking(mut self, masking: Masking) -> Self {
        self.masking = masking;
        self
    }

    /// Diffuse albedo ρ_d.
    #[inline(always)]
    pub fn albedo_diffuse(&self) -> T {
        self.albedo_diffuse
    }
    /// Specular scale ρ_s.
    #[inline(always)]
    pub fn specular(&self) -> T {
        self.specular
    }
    /// Roughness α.
    #[inline(always)]
    pub fn alpha(&self) -> T {
        self.alpha
    }
    /// The Fresnel model.
    #[inline(always)]
    pub fn fresnel(&self) -> Fresnel<T> {
        self.fresnel
    }
    /// The masking-shadowing model.
    #[inline(always)]
    pub fn masking(&self) -> Masking {
        self.masking
    }

    /// Probability with which [`Brdf::sample`] picks the specular lobe: `w_s/(w_s + w_d)` with
    /// `w_s = ρ_s F̄` (`F̄` = 1, or the cosine-weighted mean `F0 + (1 − F0)/21` of Schlick) and `w_d = ρ_d`;
    /// 0 when both vanish. The pdf returned with each sample is exact whatever this heuristic picks.
    #[inline]
    pub fn specular_probability(&self) -> T {
        let f_mean = match self.fresnel {
            Fresnel::One => T::ONE,
            Fresnel::Schlick { f0 } => f0 + (T::ONE - f0) / T::from_f64(21.0),
        };
        let w_s = self.specular * f_mean;
        let total = w_s + self.albedo_diffuse;
        // Both lobes zero: f ≡ 0, any sampler will do; pick the diffuse one.
        if total > T::ZERO { w_s / total } else { T::ZERO }
    }

    #[inline(always)]
    fn mixture_pdf(&self, wi: V3<T>, wo: V3<T>, p_spec: T) -> T {
        p_spec * pdf_vndf_reflection(wi, wo, self.alpha) + (T::ONE - p_spec) * pdf_cosine_hemisphere(wo.z())
    }
}

impl<T: Real> Brdf for Ggx<T> {
    type Scalar = T;
    type ParamGrad = GgxGrad<T>;

    #[inline]
    fn eval(&self, omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> T {
        let (l, _) = normalize_with_inv_len::<T>(omega_l);
        let (s, _) = normalize_with_inv_len::<T>(omega_s);
        let (n, _) = normalize_with_inv_len::<T>(n);
        let mu_l = n.dot(l);
        let mu_s = n.dot(s);
        // Back-facing, or NaN from a zero-length input: f = 0.
        if !(mu_l > T::ZERO && mu_s > T::ZERO) {
            return T::ZERO;
        }
        // |l + s| ≥ n·(l + s) = μ_l + μ_s > 0 here, so h is well defined.
        let hs = l + s;
        let m = hs.length_squared().sqrt();
        let h = hs * (T::ONE / m);
        let cos_h = n.dot(h);
        // sin²θ_h as |n × h|²: accurate near the specular peak, where 1 − cos² would cancel in f32.
        let sin2_h = n.cross(h).length_squared();
        let spec =
            d(cos_h, sin2_h, self.alpha) * self.masking.vis(mu_l, mu_s, self.alpha) * self.fresnel.f(T::HALF * m);
        self.albedo_diffuse * T::FRAC_1_PI + self.specular * spec
    }

    /// Value and all gradients (see the derivation in the crate docs, "What is differentiated").
    #[inline]
    fn eval_grad(&self, omega_l: V3<T>, omega_s: V3<T>, n: V3<T>) -> Grad<T, GgxGrad<T>> {
        let (l, inv_len_l) = normalize_with_inv_len::<T>(omega_l);
        let (s, inv_len_s) = normalize_with_inv_len::<T>(omega_s);
        let (n, inv_len_n) = normalize_with_inv_len::<T>(n);
        let mu_l = n.dot(l);
        let mu_s = n.dot(s);
        // Back-facing, or NaN from a zero-length input: f = 0 and every gradient 0.
        if !(mu_l > T::ZERO && mu_s > T::ZERO) {
            return Grad::zero();
        }
        // |l + s| ≥ μ_l + μ_s > 0 here, so h is well defined.
        let hs = l + s;
        let m = hs.length_squared().sqrt();
        let inv_m = T::ONE / m;
        let h = hs * inv_m;
        let cos_h = n.dot(h);
        // sin²θ_h as |n × h|²: accurate near the specular peak, where 1 − cos² would cancel in f32.
        let sin2_h = n.cross(h).length_squared();
        let (dd, dd_dcos, dd_dalpha) = d_grad(cos_h, sin2_h, self.alpha);
        let vis = self.masking.vis_grad(mu_l, mu_s, self.alpha);
        // u = l·h = |l + s|/2 for unit l, s.
        let (ff, df_du, df_df0) = self.fresnel.f_grad(T::HALF * m);

        let dv = dd * vis.v;
        let rho_f = self.specular * ff;
        let value = self.albedo_diffuse * T::FRAC_1_PI + rho_f * dv;
        let d_params = GgxGrad {
            albedo_diffuse: T::FRAC_1_PI,
            specular: ff * dv,
            alpha: rho_f * (dd_dalpha * vis.v + dd * vis.d_alpha),
            f0: self.specular * dv * df_df0,
        };

        // Partial derivatives of f with respect to the scalar intermediates μ_l, μ_s, cos θ_h, u.
        let f_mu_l = rho_f * dd * vis.d_mu_l;
        let f_mu_s = rho_f * dd * vis.d_mu_s;
        let f_cos = rho_f * vis.v * dd_dcos;
        let f_u = self.specular * dv * df_du;
        // ∇_l cos θ_h = ∇_s cos θ_h = (n − cos θ_h h)/|l + s|, ∇_l u = ∇_s u = h/2.
        let shared = (n - h * cos_h) * (f_cos * inv_m) + h * (f_u * T::HALF);
        let g_l = n * f_mu_l + shared;
        let g_s = n * f_mu_s + shared;
        let g_n = l * f_mu_l + s * f_mu_s + h * f_cos;
        Grad {
            value,
            d_params,
            d_omega_l: project_through_normalize::<T>(l, inv_len_l, g_l),
            d_omega_s: project_through_normalize::<T>(s, inv_len_s, g_s),
            d_n: project_through_normalize::<T>(n, inv_len_n, g_n),
        }
    }

    #[inline]
    fn eval_confocal(&self, omega: V3<T>, n: V3<T>) -> T {
        let (w, _) = normalize_with_inv_len::<T>(omega);
        let (n, _) = normalize_with_inv_len::<T>(n);
        let mu = n.dot(w);
        // Back-facing, or NaN from a zero-length input: f = 0.
        if !(mu > T::ZERO) {
            return T::ZERO;
        }
        // h = ω, u = ω·h = 1 (Schlick F = F0).
        let sin2 = n.cross(w).length_squared();
        let spec = d(mu, sin2, self.alpha) * self.masking.vis(mu, mu, self.alpha) * self.fresnel.f(T::ONE);
        self.albedo_diffuse * T::FRAC_1_PI + self.specular * spec
    }

    #[inline]
    fn eval_grad_confocal(&self, omega: V3<T>, n: V3<T>) -> ConfocalGrad<T, GgxGrad<T>> {
        let (w, inv_len_w) = normalize_with_inv_len::<T>(omega);
        let (n, inv_len_n) = normalize_with_inv_len::<T>(n);
        let mu = n.dot(w);
        // Back-facing, or NaN from a zero-length input: f = 0 and every gradient 0.
        if !(mu > T::ZERO) {
            return ConfocalGrad::zero();
        }
        // h = ω: cos θ_h = μ_l = μ_s = μ, u = 1, so f depends on the directions through μ only.
        let sin2 = n.cross(w).length_squared();
        let (dd, dd_dcos, dd_dalpha) = d_grad(mu, sin2, self.alpha);
        let vis = self.masking.vis_grad(mu, mu, self.alpha);
        let (ff, _, df_df0) = self.fresnel.f_grad(T::ONE);
        let dv = dd * vis.v;
        let rho_f = self.specular * ff;
        let d_params = GgxGrad {
            albedo_diffuse: T::FRAC_1_PI,
            specular: ff * dv,
            alpha: rho_f * (dd_dalpha * vis.v + dd * vis.d_alpha),
            f0: self.specular * dv * df_df0,
        };
        let f_mu = rho_f * (dd * (vis.d_mu_l + vis.d_mu_s) + vis.v * dd_dcos);
        ConfocalGrad {
            value: self.albedo_diffuse * T::FRAC_1_PI + rho_f * dv,
            d_params,
            d_omega: project_through_normalize::<T>(w, inv_len_w, n * f_mu),
            d_n: project_through_normalize::<T>(n, inv_len_n, w * f_mu),
        }
    }

    /// Lobe-mixture sampling: the specular lobe (probability [`Ggx::specular_probability`]) by VNDF
    /// reflection (Heitz 2018), the diffuse lobe by cosine sampling; the pdf is the mixture density
    /// `p_s pdf_vndf_reflection + (1 − p_s) cos θ/π`, ready for MIS.
    #[inline]
    fn sample(&self, omega_i: V3<T>, n: V3<T>, u: [T; 3]) -> Option<BrdfSample<T>> {
        let (wi, _) = normalize_with_inv_len::<T>(omega_i);
        let (n, _) = normalize_with_inv_len::<T>(n);
        let frame = Frame::<T>::from_normal(n);
        let wi = frame.to_local(wi);
        // Back-facing or degenerate (NaN) incident direction.
        if !(wi.z() > T::ZERO) {
            return None;
        }
        let p_spec = self.specular_probability();
        let (wo, lobe) = if u[0] < p_spec {
            (sample_vndf_reflection(wi, self.alpha, u[1], u[2]), Lobe::Specular)
        } else {
            (sample_cosine_hemisphere(u[1], u[2]), Lobe::Diffuse)
        };
        // Reflections about visible normals can still go below the horizon (shadowed): no sample.
        if !(wo.z() > T::ZERO) {
            return None;
        }
        let pdf = self.mixture_pdf(wi, wo, p_spec);
        if !(pdf > T::ZERO) {
            return None;
        }
        Some(BrdfSample { omega: frame.to_world(wo), pdf, lobe })
    }

    #[inline]
    fn pdf(&self, omega_i: V3<T>, omega_o: V3<T>, n: V3<T>) -> T {
        let (wi, _) = normalize_with_inv_len::<T>(omega_i);
        let (wo, _) = normalize_with_inv_len::<T>(omega_o);
        let (n, _) = normalize_with_inv_len::<T>(n);
        let frame = Frame::<T>::from_normal(n);
        let wi = frame.to_local(wi);
        let wo = frame.to_local(wo);
        // Back-facing (or NaN) on either side: never sampled.
        if !(wi.z() > T::ZERO && wo.z() > T::ZERO) {
            return T::ZERO;
        }
        self.mixture_pdf(wi, wo, self.specular_probability())
    }
}

/// Serialised form of [`Ggx`], validated on deserialisation.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(bound = "")]
struct GgxRaw<T: Real> {
    albedo_diffuse: T,
    specular: T,
    alpha: T,
    #[serde(default)]
    fresnel: Fresnel<T>,
    #[serde(default)]
    masking: Masking,
}

impl<T: Real> TryFrom<GgxRaw<T>> for Ggx<T> {
    type Error = BrdfError;
    fn try_from(r: GgxRaw<T>) -> Result<Self> {
        Ok(Self::new(r.albedo_diffuse, r.specular, r.alpha, r.fresnel)?.with_masking(r.masking))
    }
}

impl<T: Real> From<Ggx<T>> for GgxRaw<T> {
    fn from(g: Ggx<T>) -> Self {
        Self {
            albedo_diffuse: g.albedo_diffuse,
            specular: g.specular,
            alpha: g.alpha,
            fresnel: g.fresnel,
            masking: g.masking,
        }
    }
}
