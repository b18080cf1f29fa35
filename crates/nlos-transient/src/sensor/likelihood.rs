//! The Poisson negative log-likelihood of photon counts under the sensor's linear model, with gradients,
//! for fitting counts rather than intensities.
//!
//! ## Model
//! Expected counts `y = α·A x + b`: `x` the rendered transient (expected flux), `A` the jitter operator
//! ([`BinKernel`]), `α` an intensity scale and `b` the background per bin. Counts `n_k ~ Poisson(y_k)`.
//!
//! ## Value
//! The negative log-likelihood up to the constant `Σ ln n_k!`, written as the Poisson half-deviance so that
//! it is 0 at a perfect fit and well scaled:
//!
//! `L = Σ_k [ y_k − n_k + n_k·ln(n_k / y_k) ]`   (the `n_k ln(n_k/y_k)` term is 0 when `n_k = 0`).
//!
//! ## Gradients
//! With `r_k = ∂L/∂y_k = 1 − n_k/y_k`:
//! `∂L/∂x = α·Aᵀ r`, `∂L/∂α = Σ_k r_k·(A x)_k`, `∂L/∂b = Σ_k r_k`.
//!
//! Guard: `y_k` is floored at `1e-12` (used consistently in value and gradient) so that a model predicting
//! no light where photons were counted gives a large finite loss and a gradient that pushes `y` up, not
//! NaN.

use crate::error::{Result, TransientError};
use crate::sensor::jitter::BinKernel;

/// Floor on expected counts (see the module docs).
const Y_FLOOR: f64 = 1e-12;

/// Value and gradients of the Poisson negative log-likelihood.
#[derive(Debug, Clone, PartialEq)]
pub struct PoissonNll {
    /// `L = Σ_k [y_k − n_k + n_k ln(n_k/y_k)]`.
    pub value: f64,
    /// `∂L/∂x = α·Aᵀ(1 − n/y)`, same layout as the flux.
    pub grad_flux: Vec<f64>,
    /// `∂L/∂α = Σ_k (1 − n_k/y_k)·(A x)_k`.
    pub grad_scale: f64,
    /// `∂L/∂b = Σ_k (1 − n_k/y_k)`.
    pub grad_background: f64,
}

/// The Poisson NLL of `counts` given the flux `flux` (both measurement-major, `bins` per histogram),
/// the sensor response `kernel`, the intensity scale `scale` and the background per bin `background`.
/// See the [module docs](self) for the equations.
///
/// # Errors
/// [`TransientError::InvalidArgument`] when the lengths differ or do not split into histograms of
/// `bins`, a count is negative or not finite, a flux value is not finite, `scale` is not finite, or
/// `background` is not finite and ≥ 0.
pub fn poisson_nll(
    flux: &[f32],
    counts: &[f32],
    bins: usize,
    kernel: &BinKernel,
    scale: f64,
    background: f64,
) -> Result<PoissonNll> {
    let bad = |name: &'static str, reason: String| TransientError::InvalidArgument { name, reason };
    if flux.len() != counts.len() {
        return Err(bad("counts", format!("{} counts for {} flux values", counts.len(), flux.len())));
    }
    if let Some(i) = counts.iter().position(|c| !(c.is_finite() && *c >= 0.0)) {
        return Err(bad("counts", format!("value {} at index {i}; counts are finite and ≥ 0", counts[i])));
    }
    if let Some(i) = flux.iter().position(|v| !v.is_finite()) {
        return Err(bad("flux", format!("value {} at index {i} is not finite", flux[i])));
    }
    if !scale.is_finite() {
        return Err(bad("scale", format!("{scale} is not finite")));
    }
    if !(background.is_finite() && background >= 0.0) {
        return Err(bad("background", format!("{background} must be finite and ≥ 0 (counts per bin)")));
    }
    let x: Vec<f64> = flux.iter().map(|&v| f64::from(v)).collect();
    let mut ax = vec![0.0; x.len()];
    kernel.apply_f64(&x, bins, &mut ax)?;
    let mut value = 0.0;
    let mut grad_scale = 0.0;
    let mut grad_background = 0.0;
    let mut r = vec![0.0; x.len()];
    for ((rk, &axk), &nk) in r.iter_mut().zip(&ax).zip(counts) {
        let n = f64::from(nk);
        let y = (scale * axk + background).max(Y_FLOOR);
        value += y - n + if n > 0.0 { n * (n / y).ln() } else { 0.0 };
        *rk = 1.0 - n / y;
        grad_scale += *rk * axk;
        grad_background += *rk;
    }
    let mut grad_flux = vec![0.0; x.len()];
    kernel.adjoint_f64(&r, bins, &mut grad_flux)?;
    for g in &mut grad_flux {
        *g *= scale;
    }
    Ok(PoissonNll { value, grad_flux, grad_scale, grad_background })
}
