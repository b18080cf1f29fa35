//! The isotropic GGX (Trowbridge–Reitz) microfacet distribution `D`, Smith's `Λ` and `G1`, and the
//! combined "visibility" term `V = G/(4 |n·ω_l| |n·ω_s|)` for both Smith variants, each with its
//! derivatives.
//!
//! References: Walter, Marschner, Li, Torrance, "Microfacet Models for Refraction through Rough Surfaces",
//! EGSR 2007 (eq. numbers "W07"); Heitz, "Understanding the Masking-Shadowing Function in Microfacet-Based
//! BRDFs", JCGT 3(2) 2014 ("H14").
//!
//! All cosines here are of unit vectors; callers guarantee the front-facing precondition (`μ > 0`).

use crate::real::Real;

/// Which Smith masking-shadowing function G couples the two directions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
pub enum Masking {
    /// Separable (uncorrelated) form `G = G1(ω_l) G1(ω_s)` (W07 eq. 23, H14 eq. 98) — Tsai et al. 2019's model.
    #[default]
    Separable,
    /// Height-correlated form `G = 1/(1 + Λ(ω_l) + Λ(ω_s))` (H14 eq. 99): more accurate, slightly brighter.
    HeightCorrelated,
}

/// GGX normal distribution `D(m)` (W07 eq. 33) from `cos θ_m` and `sin² θ_m`.
///
/// W07 writes `D = α² / (π cos⁴θ (α² + tan²θ)²)`; multiplying out, `D = α² / (π (α² cos²θ + sin²θ)²)`.
/// Taking `sin²θ` separately (e.g. as `|n × m|²`) keeps `D` accurate near its peak in `f32`, where
/// `1 − cos²θ` would cancel catastrophically for small α. `cos_theta ≤ 0` is not checked (χ⁺ is the
/// caller's business).
#[inline(always)]
pub fn d<T: Real>(cos_theta: T, sin2_theta: T, alpha: T) -> T {
    let a2 = alpha * alpha;
    let k = a2 * cos_theta * cos_theta + sin2_theta;
    a2 / (T::PI * k * k)
}

/// `D` (W07 eq. 33) and its derivatives `(D, ∂D/∂cos θ, ∂D/∂α)`.
///
/// `∂D/∂cos θ` is taken on the unit sphere (`sin²θ = 1 − cos²θ`): with `k = α²cos²θ + sin²θ`,
/// `∂k/∂cos θ = −2 cos θ (1 − α²)`, so `∂D/∂cos θ = 4 α² cos θ (1 − α²) / (π k³)` and
/// `∂D/∂α = 2α (k − 2α² cos²θ) / (π k³)`.
#[inline(always)]
pub fn d_grad<T: Real>(cos_theta: T, sin2_theta: T, alpha: T) -> (T, T, T) {
    let a2 = alpha * alpha;
    let c2 = cos_theta * cos_theta;
    let k = a2 * c2 + sin2_theta;
    // k ≥ α² min(cos²θ + sin²θ) ≈ α² ≥ 1e-6 for unit m: no division by zero.
    let inv_pi_k3 = T::FRAC_1_PI / (k * k * k);
    let value = a2 * k * inv_pi_k3;
    let d_cos = T::from_f64(4.0) * a2 * cos_theta * (T::ONE - a2) * inv_pi_k3;
    let d_alpha = T::TWO * alpha * (k - T::TWO * a2 * c2) * inv_pi_k3;
    (value, d_cos, d_alpha)
}

/// `S(μ) = √(α² + (1 − α²) μ²) = μ √(1 + α² tan²θ)`, the square root shared by Λ and G1.
#[inline(always)]
fn s<T: Real>(mu: T, alpha: T) -> T {
    let a2 = alpha * alpha;
    (a2 + (T::ONE - a2) * mu * mu).sqrt()
}

/// Smith's Λ for GGX (H14 eq. 72): `Λ(μ) = (−1 + √(1 + α² tan²θ)) / 2`, with `μ = cos θ > 0`.
///
/// Written as `(S(μ)/μ − 1)/2` with `S = √(α² + (1 − α²)μ²)`; grows like `α/(2μ)` at grazing angles.
#[inline(always)]
pub fn lambda<T: Real>(mu: T, alpha: T) -> T {
    (s(mu, alpha) / mu - T::ONE) * T::HALF
}

/// Smith masking `G1(ω) = 1/(1 + Λ(ω))` (H14 eq. 43; W07 eq. 34 for GGX), with `μ = cos θ > 0`.
///
/// Evaluated as `2μ / (μ + S(μ))`, finite and → 0 at grazing angles (no `tan θ` blow-up).
#[inline(always)]
pub fn g1<T: Real>(mu: T, alpha: T) -> T {
    T::TWO * mu / (mu + s(mu, alpha))
}

/// The visibility term `V = G(ω_l, ω_s) / (4 μ_l μ_s)` and its derivatives.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Visibility<T> {
    /// V.
    pub v: T,
    /// ∂V/∂μ_l.
    pub d_mu_l: T,
    /// ∂V/∂μ_s.
    pub d_mu_s: T,
    /// ∂V/∂α.
    pub d_alpha: T,
}

impl Masking {
    /// `V = G / (4 μ_l μ_s)` for this masking model, without derivatives (μ > 0 both).
    #[inline(always)]
    pub fn vis<T: Real>(self, mu_l: T, mu_s: T, alpha: T) -> T {
        match self {
            Masking::Separable => {
                // G1(μ)/(2μ) = 1/(μ + S(μ)) (W07 eq. 34 divided by 2μ): finite even at μ = 0.
                T::ONE / ((mu_l + s(mu_l, alpha)) * (mu_s + s(mu_s, alpha)))
            }
            Masking::HeightCorrelated => {
                // G2/(4 μ_l μ_s) with G2 = 1/(1 + Λ_l + Λ_s) (H14 eq. 99) = 1/(2 (μ_s S_l + μ_l S_s)).
                T::HALF / (mu_s * s(mu_l, alpha) + mu_l * s(mu_s, alpha))
            }
        }
    }

    /// `V = G / (4 μ_l μ_s)` (W07 eq. 20's G over its denominator) and its derivatives.
    ///
    /// Separable: `V = v₁(μ_l) v₁(μ_s)` with `v₁(μ) = G1(μ)/(2μ) = 1/(μ + S(μ))`,
    /// `v₁' = −v₁² (1 + (1 − α²) μ / S)`, `∂v₁/∂α = −v₁² α (1 − μ²)/S`.
    /// Height-correlated: `V = 1/(2Q)`, `Q = μ_s S(μ_l) + μ_l S(μ_s)`, `∂V/∂Q = −2V²`.
    #[inline(always)]
    pub fn vis_grad<T: Real>(self, mu_l: T, mu_s: T, alpha: T) -> Visibility<T> {
        let a2 = alpha * alpha;
        let one_m_a2 = T::ONE - a2;
        let s_l = s(mu_l, alpha);
        let s_s = s(mu_s, alpha);
        // S ≥ α ≥ 1e-3 > 0: the divisions by S are safe.
        let ds_dmu_l = one_m_a2 * mu_l / s_l;
        let ds_dmu_s = one_m_a2 * mu_s / s_s;
        let ds_da_l = alpha * (T::ONE - mu_l * mu_l) / s_l;
        let ds_da_s = alpha * (T::ONE - mu_s * mu_s) / s_s;
        match self {
            Masking::Separable => {
                let v_l = T::ONE / (mu_l + s_l);
                let v_s = T::ONE / (mu_s + s_s);
                let v = v_l * v_s;
                Visibility {
                    v,
                    d_mu_l: -v * v_l * (T::ONE + ds_dmu_l),
                    d_mu_s: -v * v_s * (T::ONE + ds_dmu_s),
                    d_alpha: -v * (v_l * ds_da_l + v_s * ds_da_s),
                }
            }
            Masking::HeightCorrelated => {
                let q = mu_s * s_l + mu_l * s_s;
                let v = T::HALF / q;
                let dv_dq = -T::TWO * v * v;
                Visibility {
                    v,
                    d_mu_l: dv_dq * (mu_s * ds_dmu_l + s_s),
                    d_mu_s: dv_dq * (s_l + mu_l * ds_dmu_s),
                    d_alpha: dv_dq * (mu_s * ds_da_l + mu_l * ds_da_s),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn g1_matches_lambda_form() {
        for &alpha in &[0.001f64, 0.1, 0.5, 1.0] {
            for &mu in &[1e-4f64, 0.1, 0.5, 0.99, 1.0] {
                let from_lambda = 1.0 / (1.0 + lambda(mu, alpha));
                // W07 eq. 34 with tan²θ = (1 − μ²)/μ².
                let w07 = 2.0 / (1.0 + (1.0 + alpha * alpha * (1.0 - mu * mu) / (mu * mu)).sqrt());
                assert!((g1(mu, alpha) - from_lambda).abs() < 1e-12);
                assert!((g1(mu, alpha) - w07).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn d_matches_walter_form_and_normalises() {
        // W07 eq. 33 form, and ∫ D(m) cos θ_m dω_m = 1 (W07 eq. 4) by midpoint quadrature in u = tan²θ/α².
        for &alpha in &[0.01f64, 0.2, 1.0] {
            let theta = 0.3f64;
            let (st, ct) = theta.sin_cos();
            let t2 = (st / ct).powi(2);
            let w07 = alpha * alpha / (std::f64::consts::PI * ct.powi(4) * (alpha * alpha + t2).powi(2));
            assert!((d(ct, st * st, alpha) / w07 - 1.0).abs() < 1e-12);
            let n = 200_000;
            let mut sum = 0.0;
            for i in 0..n {
                // θ = atan(α tan(π/2 · x)), x ∈ (0, 1): concentrates nodes where D is large.
                let x = (i as f64 + 0.5) / n as f64;
                let t = alpha * (std::f64::consts::FRAC_PI_2 * x).tan();
                let th = t.atan();
                let dth = alpha * std::f64::consts::FRAC_PI_2
                    / (std::f64::consts::FRAC_PI_2 * x).cos().powi(2)
                    / (1.0 + t * t);
                let (s, c) = th.sin_cos();
                sum += d(c, s * s, alpha) * c * s * 2.0 * std::f64::consts::PI * dth / n as f64;
            }
            assert!((sum - 1.0).abs() < 1e-6, "alpha {alpha}: {sum}");
        }
    }
}
