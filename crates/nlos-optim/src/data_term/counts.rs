//! The noise-aware data term (Tsai et al. 2019, Sec. 7 propose it): fit photon **counts** through
//! the SPAD's linear response instead of intensities.
//!
//! ## Model
//! The rendered transient `I` (expected flux, arbitrary units) becomes expected counts
//! ```text
//! μ(I) = α·J I + b
//! ```
//! with `J` the sensor's timing response (convolution with the jitter kernel on the transient's bins,
//! [`nlos_transient::sensor::BinKernel`]), `α` an unknown global intensity scale and `b` the background
//! (dark counts + ambient light) per bin. The counts are `n_k ~ Poisson(μ_k)`, so the data term is the
//! Poisson negative log-likelihood, written as the half-deviance (0 at a perfect fit, same as
//! [`nlos_transient::sensor::poisson_nll`]):
//! ```text
//! E(I, α) = Σ_k [ μ_k − n_k + n_k ln(n_k / μ_k) ]          (μ_k floored at 1e-12)
//! ```
//!
//! ## Scale: 1-D Newton
//! `∂E/∂α = Σ_k a_k (1 − n_k/μ_k)` with `a = J I`, and `∂²E/∂α² = Σ_k n_k a_k²/μ_k² ≥ 0`: `E` is convex in
//! `α`. Without background the minimiser is closed-form, `α₀ = Σ n / Σ a`; with `b > 0`, `∂E/∂α(α₀) ≥ 0`,
//! so the root lies in `(0, α₀]`. Newton's method is run on `∂E/∂α` inside that bracket, falling back to
//! bisection whenever a step leaves it (safeguarded Newton), to a relative tolerance of 1e-12. When the
//! root is not positive (the background alone explains the counts) the caller's fallback scale is used.
//!
//! ## Gradient
//! By the envelope theorem (`∂E/∂α = 0` at `α*`), `dE*/dI = ∂E/∂I(α*) = α*·Jᵀ(1 − n/μ)` — the jitter
//! operator's adjoint applied to the NLL's derivative with respect to `μ`. `tests::whole_data_term_gradient`
//! checks value and gradient by finite differences, re-solving `α` at every perturbed `I`.
//!
//! ## Background
//! Fixed (known from a dark measurement or the sensor model) or estimated once per run from the bins
//! before the first return of the measured counts ([`nlos_transient::sensor::estimate_background`]).
//!
//! ## Noise floor (for the automatic regulariser weight)
//! The seed sets the smoothing weight from the ratio of the data term to the regulariser at the start of
//! a block (`λ = β·E/R`). With photon counts, `E` is mostly the deviance that Poisson noise leaves even
//! at the true surface: at 100 photons per histogram the reducible part is a few percent of `E`, so the
//! ratio rule smooths about 15× harder than the misfit warrants (measured on the sensor scenario:
//! started from the true bunny, the data term rose while the regulariser fell). [`SensorFit::noise_floor`]
//! is the expectation of the data term if the current expected counts were exact,
//! ```text
//! E_floor = Σ_k d(μ_k),   d(μ) = E_{n~Poisson(μ)}[μ − n + n ln(n/μ)] = E[n ln n] − μ ln μ
//! ```
//! ([`expected_half_deviance`]: the series for μ ≤ 50, `½ + 1/(12μ) + 1/(12μ²)` above; McCullagh &
//! Nelder 1989, §6.2), and the optimiser weighs the regulariser against `E − E_floor` instead of `E`.
//!
//! **Why one file of ~850 lines.** It is one data term: its value and gradient, its noise floor and the
//! per-row forms the boundary tests use all read the same per-measurement constants and the same response
//! operator, and must stay the same function of them; split, a change to one form could not be checked
//! against the others in one reading. The tests at the bottom check them against each other.

use nlos_transient::Transient;
use nlos_transient::sensor::{BackgroundWindow, BinKernel, JitterResponse, SpadModel, estimate_background};

use std::sync::RwLock;

use rayon::prelude::*;

#[cfg(test)]
use crate::data_term::intensities::DEVIANCE_SERIES_MAX_MU;
use crate::data_term::intensities::DataEval;
use crate::data_term::intensities::expected_half_deviance;
use crate::data_term::response::ResponseOp;
use crate::error::{OptimError, Result};

/// Floor on expected counts (value and gradient), as in `nlos_transient::sensor::likelihood`.
const MU_FLOOR: f64 = 1e-12;

/// Floor of the resolved background, as a fraction of the mean count per bin. A candidate surface that
/// renders no light in a bin where photons were counted would otherwise meet `μ = 0` (an infinite NLL,
/// clamped, with a gradient `n/1e-12`); every real SPAD has some background, and a floor this small changes
/// the fit of bins with signal negligibly.
pub const MIN_BACKGROUND_FRACTION: f64 = 1e-3;

/// The Poisson half-deviance of one bin, `μ − n + n ln(n/μ)` (`0 · ln 0 = 0`): the data term of the
/// sensor fit per bin (module docs), zero exactly at `μ = n`.
fn half_deviance(mu: f64, n: f64) -> f64 {
    mu - n + if n > 0.0 { n * (n / mu).ln() } else { 0.0 }
}

/// `Σ_k d(μ_k + δ_k; n_k) − d(μ_k; n_k)` for the half-deviance `d` of a bin ([`half_deviance`]), with
/// `δ_k = max(μ_k + c·j_k, floor) − μ_k`: a share `j` moved by `c` through a row's expected counts `μ`. Each
/// bin's change is `δ − n ln(1 + x)`, `x = δ/μ`: no logarithm where no photon was counted, and none where
/// `|x| < 10⁻³` (the long tail of a real capture's response), where the series `x − x²/2 + x³/3 − x⁴/4` is
/// exact to `x⁵/5 < 2·10⁻¹⁶`. Written for the vector units: the series in four running sums, then the
/// logarithm for the few bins at the share's core.
fn deviance_changes(mu: &[f64], moved: &[f64], counts: &[f64], c: f64) -> f64 {
    // (δ, x = δ/μ, the bin's change by the series where |x| < 10⁻³ and 0 elsewhere): branch-free.
    let term = |m: f64, j: f64, n: f64| {
        let delta = (m + c * j).max(MU_FLOOR) - m;
        let x = delta / m;
        let series = delta - n * x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - 0.25 * x)));
        (delta, x, if x.abs() < 1e-3 { series } else { 0.0 })
    };
    let mut acc = [0.0f64; 4];
    let split = mu.len() / 4 * 4;
    let (m4, j4, n4) = (mu[..split].chunks_exact(4), moved[..split].chunks_exact(4), counts[..split].chunks_exact(4));
    for ((m4, j4), n4) in m4.zip(j4).zip(n4) {
        for i in 0..4 {
            acc[i] += term(m4[i], j4[i], n4[i]).2;
        }
    }
    let mut total = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for i in split..mu.len() {
        total += term(mu[i], moved[i], counts[i]).2;
    }
    // The bins the series leaves out: `δ − n ln(1 + x)`, one logarithm each where a photon was counted.
    for ((&m, &j), &n) in mu.iter().zip(moved).zip(counts) {
        let (delta, x, _) = term(m, j, n);
        if x.abs() >= 1e-3 {
            total += delta - if n > 0.0 { n * x.ln_1p() } else { 0.0 };
        }
    }
    total
}

/// Where the background level `b` (expected counts per bin) comes from.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum SensorBackground {
    /// A known level, counts per bin (≥ 0).
    Fixed(f64),
    /// Estimated once, at the start of the run, from these bins of the measured counts (e.g.
    /// [`BackgroundWindow::Auto`]: the bins before the first return).
    Estimate(BackgroundWindow),
}

/// The noise-aware fit: jitter kernel on the measurement's bins and background (module docs).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SensorFit {
    /// The timing response `J` on the measurement's bins ([`BinKernel::identity`] for an ideal sensor).
    pub kernel: BinKernel,
    /// The background level.
    pub background: SensorBackground,
}

impl SensorFit {
    /// A fit with the jitter `response` resampled onto bins of `bin_width` metres of path (the
    /// measurement's [`nlos_transient::TimeAxis::bin_width`]).
    ///
    /// # Errors
    /// [`OptimError::Sensor`] for a bin width that is not finite and positive.
    pub fn from_jitter(response: &JitterResponse, bin_width: f64, background: SensorBackground) -> Result<Self> {
        Ok(Self { kernel: response.to_bins(bin_width).map_err(OptimError::Sensor)?, background })
    }

    /// The fit matching a SPAD model: its jitter (identity without one) and its background per bin
    /// ([`SpadModel::background_per_bin`], fixed). Pile-up, dead time and afterpulsing are not part of the
    /// linear model: fit pile-up-corrected counts (`nlos_transient::sensor::coates_correction`).
    ///
    /// # Errors
    /// [`OptimError::Sensor`] for an invalid model or bin width.
    pub fn from_spad(model: &SpadModel, bin_width: f64) -> Result<Self> {
        model.validate().map_err(OptimError::Sensor)?;
        Ok(Self {
            kernel: model.kernel(bin_width).map_err(OptimError::Sensor)?,
            background: SensorBackground::Fixed(model.background_per_bin(bin_width)),
        })
    }

    /// The background level for `measured` counts: the fixed value, or the estimate from its window, at least
    /// [`MIN_BACKGROUND_FRACTION`] × the mean count per bin.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a negative or non-finite fixed level, [`OptimError::Sensor`]
    /// when the window is empty or outside the time axis.
    pub fn resolve_background(&self, measured: &Transient) -> Result<f64> {
        let b = match self.background {
            SensorBackground::Fixed(b) => b,
            SensorBackground::Estimate(window) => {
                estimate_background(measured, window).map_err(OptimError::Sensor)?.per_bin.max(0.0)
            }
        };
        if !(b.is_finite() && b >= 0.0) {
            return Err(OptimError::InvalidParameter {
                name: "sensor.background",
                value: b,
                reason: "the background must be finite and >= 0 (expected counts per bin)",
            });
        }
        let data = measured.data();
        let mean = data.iter().map(|&v| f64::from(v).max(0.0)).sum::<f64>() / data.len().max(1) as f64;
        Ok(b.max(MIN_BACKGROUND_FRACTION * mean))
    }

    /// The model of the counts, `scale · J I + b` per bin (histograms of `bins` bins).
    ///
    /// # Errors
    /// A `rendered` length that is not a multiple of `bins`.
    pub fn expected(&self, rendered: &[f32], bins: usize, background: f64, scale: f64) -> Result<Vec<f64>> {
        Ok(self.jitter(rendered, bins)?.into_iter().map(|a| scale * a + background).collect())
    }

    /// `J I` per histogram of `bins` bins, in f64.
    fn jitter(&self, rendered: &[f32], bins: usize) -> Result<Vec<f64>> {
        let x: Vec<f64> = rendered.iter().map(|&v| f64::from(v)).collect();
        let mut a = vec![0.0; x.len()];
        self.kernel.apply_f64(&x, bins, &mut a).map_err(OptimError::Sensor)?;
        Ok(a)
    }

    /// The scale `α*` minimising `E` for `a = J I` (module docs), or `None` when it is not positive or
    /// undefined (no signal).
    pub fn optimal_scale_jittered(a: &[f64], counts: &[f32], background: f64) -> Option<f64> {
        let (sum_a, sum_n) =
            a.iter().zip(counts).fold((0.0, 0.0), |(sa, sn), (&ak, &nk)| (sa + ak, sn + f64::from(nk)));
        let hi = sum_n / sum_a;
        if !(sum_a > 0.0 && hi.is_finite() && hi > 0.0) {
            return None;
        }
        if background <= 0.0 {
            return Some(hi);
        }
        // g(α) = ∂E/∂α and g'(α); g is increasing (E convex).
        // In chunks summed in order, in parallel: the root does not depend on the number of threads.
        const CHUNK: usize = 1 << 14;
        let derivs = |alpha: f64| {
            let parts: Vec<(f64, f64)> = a
                .par_chunks(CHUNK)
                .zip(counts.par_chunks(CHUNK))
                .map(|(ac, nc)| {
                    let (mut g, mut h) = (0.0, 0.0);
                    for (&ak, &nk) in ac.iter().zip(nc) {
                        let n = f64::from(nk);
                        let mu = (alpha * ak + background).max(MU_FLOOR);
                        g += ak * (1.0 - n / mu);
                        h += n * ak * ak / (mu * mu);
                    }
                    (g, h)
                })
                .collect();
            parts.iter().fold((0.0, 0.0), |(g, h), &(pg, ph)| (g + pg, h + ph))
        };
        // The root is in (0, hi]; at α → 0⁺, g = Σa − Σ n a / b: not negative ⇒ no positive root.
        let (g0, _) = derivs(0.0);
        if g0 >= 0.0 {
            return None;
        }
        let (mut lo, mut up) = (0.0f64, hi);
        let mut alpha = hi;
        for _ in 0..100 {
            let (g, h) = derivs(alpha);
            if g == 0.0 {
                return Some(alpha);
            }
            if g > 0.0 {
                up = alpha;
            } else {
                lo = alpha;
            }
            let newton = alpha - g / h;
            let next = if h > 0.0 && newton > lo && newton < up { newton } else { 0.5 * (lo + up) };
            if (next - alpha).abs() <= 1e-12 * alpha.abs() || (up - lo) <= 1e-14 * up {
                return Some(next);
            }
            alpha = next;
        }
        Some(alpha)
    }

    /// Value, scale and `dE*/dI` of the noise-aware data term for the rendered transient `rendered`
    /// (expected flux) against `counts` (both measurement-major, `bins` per histogram), background
    /// `background` (from [`SensorFit::resolve_background`]). With `solve_scale`, `α*` is used when
    /// defined, else `fallback_scale`; without, `α = 1`.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] for buffers of different lengths, [`OptimError::Sensor`] when they do
    /// not split into histograms of `bins`, [`OptimError::InvalidParameter`] for negative or non-finite
    /// counts or background.
    pub fn evaluate(
        &self,
        rendered: &[f32],
        counts: &[f32],
        bins: usize,
        background: f64,
        solve_scale: bool,
        fallback_scale: f64,
    ) -> Result<DataEval> {
        if counts.len() != rendered.len() {
            return Err(OptimError::LengthMismatch { what: "measured", expected: rendered.len(), got: counts.len() });
        }
        if let Some(c) = counts.iter().find(|c| !(c.is_finite() && **c >= 0.0)) {
            return Err(OptimError::InvalidParameter {
                name: "measured",
                value: f64::from(*c),
                reason: "the sensor fit needs photon counts: finite and >= 0",
            });
        }
        if !(background.is_finite() && background >= 0.0) {
            return Err(OptimError::InvalidParameter {
                name: "sensor.background",
                value: background,
                reason: "the background must be finite and >= 0 (expected counts per bin)",
            });
        }
        let model = SensorModel::new(self.clone(), bins, background, counts)?;
        Ok(model.evaluate(rendered, counts, solve_scale, fallback_scale)?.0)
    }

    /// The data term of one histogram at a fixed scale: `Σ_k μ_k − n_k + n_k ln(n_k/μ_k)` with
    /// `μ = scale·J I + b` over `rendered_row` (one histogram of expected flux) and `counts_row`. The data
    /// term of [`SensorFit::evaluate`] is the sum of these; boundary pruning ([`crate::prune`]) compares them
    /// with and without a face.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] for rows of different lengths or an empty row.
    pub fn row_value(&self, rendered_row: &[f32], counts_row: &[f32], background: f64, scale: f64) -> Result<f64> {
        self.row_value_in(rendered_row, counts_row, background, scale, 0..rendered_row.len())
    }

    /// [`SensorFit::row_value`] summed over the bins that a change of the bins `window` can reach through the
    /// timing response (`window` widened by the kernel's support on both sides, clamped to the row): two
    /// rows that differ only inside `window` differ by exactly the difference of these values
    /// (`crate::data_term::RowLoss`).
    ///
    /// # Errors
    /// As [`SensorFit::row_value`].
    pub fn row_value_in(
        &self,
        rendered_row: &[f32],
        counts_row: &[f32],
        background: f64,
        scale: f64,
        window: std::ops::Range<usize>,
    ) -> Result<f64> {
        if counts_row.len() != rendered_row.len() {
            return Err(OptimError::LengthMismatch {
                what: "measured row",
                expected: rendered_row.len(),
                got: counts_row.len(),
            });
        }
        if rendered_row.is_empty() {
            return Err(OptimError::LengthMismatch { what: "rendered row", expected: 1, got: 0 });
        }
        let reach = self.kernel.first().unsigned_abs() as usize + self.kernel.weights().len();
        let n = rendered_row.len();
        let (lo, hi) = (window.start.saturating_sub(reach), window.end.saturating_add(reach).min(n));
        let lo = lo.min(hi);
        // `J I` on those bins only (a row of a real capture is a thousand bins, a face's window a few dozen).
        let a = self.kernel.apply_window(rendered_row, lo..hi);
        Ok(a.iter()
            .zip(&counts_row[lo..hi])
            .map(|(&ak, &nk)| half_deviance((scale * ak + background).max(MU_FLOOR), f64::from(nk)))
            .sum())
    }

    /// The expected value of the data term if the expected counts `μ = scale·J I + b` of `rendered` were
    /// exact, `Σ_k d(μ_k)` ([`expected_half_deviance`]): the part of the data term that no surface can
    /// remove (module docs, "Noise floor").
    ///
    /// # Errors
    /// [`OptimError::Sensor`] when `rendered` does not split into histograms of `bins`.
    pub fn noise_floor(&self, rendered: &[f32], bins: usize, background: f64, scale: f64) -> Result<f64> {
        let a = self.jitter(rendered, bins)?;
        Ok(a.iter().map(|&ak| expected_half_deviance((scale * ak + background).max(0.0))).sum())
    }

    /// The normaliser of the data term, `Σ n` (as [`crate::DataTerm::normaliser`] for Poisson): `None` for
    /// an all-zero capture.
    pub fn normaliser(counts: &[f32]) -> Option<f64> {
        let n: f64 = counts.iter().map(|&c| f64::from(c).abs()).sum();
        (n > 0.0 && n.is_finite()).then_some(n)
    }
}

/// The sensor fit on one stage's capture: its response as an operator on that capture's histograms
/// ([`ResponseOp`]: FFT for long responses), the resolved background, and the part of the data term that
/// depends on the counts alone, `Σ_k n_k ln n_k − n_k`, taken once rather than at every step.
///
/// The data term is then `Σ_k μ_k − Σ_{n_k > 0} n_k ln μ_k + Σ_k (n_k ln n_k − n_k)`: one logarithm per bin
/// that counted a photon.
#[derive(Debug, Clone)]
pub struct SensorModel {
    /// The fit on this stage's bins (its kernel is the response of the summed bins, its background fixed).
    pub fit: SensorFit,
    /// The response operator on histograms of `bins`.
    pub op: ResponseOp,
    /// Bins per histogram.
    pub bins: usize,
    /// Background counts per bin.
    pub background: f64,
    /// `Σ_k n_k ln n_k − n_k` of the counts.
    counts_term: f64,
}

impl SensorModel {
    /// The model of `fit` on histograms of `bins` bins for `counts`, with `background` counts per bin.
    ///
    /// # Errors
    /// [`OptimError::Sensor`] when `counts` does not split into histograms of `bins`.
    pub fn new(fit: SensorFit, bins: usize, background: f64, counts: &[f32]) -> Result<Self> {
        if bins == 0 || !counts.len().is_multiple_of(bins) {
            return Err(OptimError::Sensor(nlos_transient::TransientError::InvalidArgument {
                name: "bins",
                reason: format!("{} values do not split into histograms of {bins} bins", counts.len()),
            }));
        }
        let op = ResponseOp::new(&fit.kernel, bins)?;
        let counts_term = counts
            .chunks(bins)
            .map(|row| {
                row.iter()
                    .map(|&c| {
                        let n = f64::from(c);
                        if n > 0.0 { n * n.ln() - n } else { 0.0 }
                    })
                    .sum::<f64>()
            })
            .sum();
        Ok(Self {
            fit: SensorFit { background: SensorBackground::Fixed(background), ..fit },
            op,
            bins,
            background,
            counts_term,
        })
    }

    /// The model of stage capture with `k` bins summed: the response of the summed bins
    /// ([`crate::data_term::response::summed_response`]) and `k` times the fine background (module docs of
    /// [`crate::data_term::response`]).
    ///
    /// # Errors
    /// As [`SensorModel::new`].
    pub fn summed(fit: &SensorFit, k: usize, fine_background: f64, bins: usize, counts: &[f32]) -> Result<Self> {
        let kernel = crate::data_term::response::summed_response(&fit.kernel, k)?;
        Self::new(SensorFit { kernel, background: fit.background }, bins, k as f64 * fine_background, counts)
    }

    /// `J I` of `rendered`, in f64.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] when `rendered` does not split into histograms.
    pub fn response(&self, rendered: &[f32]) -> Result<Vec<f64>> {
        let x: Vec<f64> = rendered.iter().map(|&v| f64::from(v)).collect();
        let mut a = vec![0.0; x.len()];
        self.op.apply(&x, &mut a)?;
        Ok(a)
    }

    /// Value, scale and `dE*/dI` of the data term ([`SensorFit::evaluate`]), and `J I` (for
    /// [`SensorModel::noise_floor`]).
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] for buffers of different lengths.
    pub fn evaluate(
        &self,
        rendered: &[f32],
        counts: &[f32],
        solve_scale: bool,
        fallback_scale: f64,
    ) -> Result<(DataEval, Vec<f64>)> {
        if counts.len() != rendered.len() {
            return Err(OptimError::LengthMismatch { what: "measured", expected: rendered.len(), got: counts.len() });
        }
        let a = self.response(rendered)?;
        let b = self.background;
        let scale =
            if solve_scale { SensorFit::optimal_scale_jittered(&a, counts, b).unwrap_or(fallback_scale) } else { 1.0 };
        let mut r = vec![0.0; a.len()];
        // Per-row sums, then summed in row order: the value does not depend on the number of threads.
        let rows: Vec<f64> = r
            .par_chunks_mut(self.bins)
            .zip(a.par_chunks(self.bins))
            .zip(counts.par_chunks(self.bins))
            .map(|((rr, ar), nr)| {
                let mut v = 0.0;
                for ((rk, &ak), &nk) in rr.iter_mut().zip(ar).zip(nr) {
                    let n = f64::from(nk);
                    let mu = (scale * ak + b).max(MU_FLOOR);
                    v += if n > 0.0 { mu - n * mu.ln() } else { mu };
                    *rk = 1.0 - n / mu;
                }
                v
            })
            .collect();
        let value = rows.iter().sum::<f64>() + self.counts_term;
        let mut g = vec![0.0; r.len()];
        self.op.adjoint(&r, &mut g)?;
        let d_rendered = g.iter().map(|&v| (scale * v) as f32).collect();
        Ok((DataEval { value, scale, d_rendered }, a))
    }

    /// [`SensorFit::noise_floor`] from `a = J I` ([`SensorModel::evaluate`]'s second value).
    pub fn noise_floor(&self, a: &[f64], scale: f64) -> f64 {
        let rows: Vec<f64> = a
            .par_chunks(self.bins)
            .map(|ar| ar.iter().map(|&ak| expected_half_deviance((scale * ak + self.background).max(0.0))).sum())
            .collect();
        rows.iter().sum()
    }

    /// The expected counts `scale · J I + b` of `rendered`.
    ///
    /// # Errors
    /// As [`SensorModel::response`].
    pub fn expected(&self, rendered: &[f32], scale: f64) -> Result<Vec<f64>> {
        Ok(self.response(rendered)?.into_iter().map(|a| scale * a + self.background).collect())
    }
}

/// A sensor fit's data term over a capture, histogram by histogram, as boundary pruning and growth take it
/// ([`crate::data_term::RowTerm`]).
///
/// The term is `Σ_k d(s·(J I)_k + b; n_k)` with `J` the timing response's convolution: linear in `I` up to
/// the deviance, so a face's share `I_f` changes `J I` by `k·J I_f` on the bins `J` carries the share to,
/// and `E(I + k I_f) − E(I)` needs `J I` on those bins once and `J I_f` once, whatever the number of `k`.
/// (Convolving each shifted row, the generic path, cost three convolutions over the share widened by the
/// response on both sides: 92 % of a real capture's fit went there.)
#[derive(Debug, Clone, Copy)]
pub struct SensorRows<'a> {
    /// The fit (timing response, background model).
    pub fit: &'a SensorFit,
    /// The capture's counts, measurement-major, `bins` per histogram.
    pub counts: &'a [f32],
    /// Bins per histogram.
    pub bins: usize,
    /// Background counts per bin, resolved ([`SensorFit::resolve_background`]).
    pub background: f64,
    /// The block's scale `s`.
    pub scale: f64,
    /// `J I` of the current rendering, measurement-major (None: convolved per test over the bins a share
    /// reaches). With a long response (a real capture's: hundreds of bins) that convolution is most of a
    /// test; [`crate::data_term::RowTerm::applied`] keeps this current as faces go.
    pub response: Option<&'a RwLock<Vec<f64>>>,
}

impl SensorRows<'_> {
    /// `J I_f` of a share on the output bins `lo..hi` (those its input bins reach through the response).
    fn moved(&self, share: &nlos_render::RowSpan, len: usize) -> (usize, usize, Vec<f64>) {
        let (first, w) = (self.fit.kernel.first(), self.fit.kernel.weights());
        let n = len as i64;
        let (ws, we) = (share.first_bin as i64, (share.first_bin + share.values.len()).min(len) as i64);
        // (J x)[k] = Σ_i w[i]·x[k − first − i]: input bins ws..we reach the outputs ws + first ..
        // we + first + len(w) − 1, and no others.
        let lo = (ws + first).clamp(0, n);
        let hi = (we + first + w.len() as i64 - 1).clamp(lo, n);
        let mut moved = vec![0.0; (hi - lo) as usize];
        // Input bin ws + j spreads v_j·w[i] onto output ws + j + first + i: one contiguous axpy per bin of the
        // share (the share is a few bins, the response hundreds).
        for (j, &v) in share.values.iter().take((we - ws).max(0) as usize).enumerate() {
            let v = f64::from(v);
            let start = ws + j as i64 + first;
            let i0 = (lo - start).clamp(0, w.len() as i64);
            let i1 = (hi - start).clamp(i0, w.len() as i64);
            if i1 == i0 {
                continue;
            }
            let o0 = (start + i0 - lo) as usize;
            for (m, &wi) in moved[o0..].iter_mut().zip(&w[i0 as usize..i1 as usize]) {
                *m += wi * v;
            }
        }
        (lo as usize, hi as usize, moved)
    }

    fn counts_row(&self, m: usize, len: usize) -> Result<&[f32]> {
        let row = self.counts.get(m * self.bins..(m + 1) * self.bins).ok_or(OptimError::LengthMismatch {
            what: "measured counts",
            expected: (m + 1) * self.bins,
            got: self.counts.len(),
        })?;
        if len != self.bins {
            return Err(OptimError::LengthMismatch { what: "rendered row", expected: self.bins, got: len });
        }
        Ok(row)
    }
}

impl crate::data_term::RowTerm for SensorRows<'_> {
    fn value(&self, m: usize, row: &[f32], window: std::ops::Range<usize>) -> Result<f64> {
        self.fit.row_value_in(row, self.counts_row(m, row.len())?, self.background, self.scale, window)
    }

    fn changes(&self, m: usize, row: &[f32], share: &nlos_render::RowSpan, ks: &[f32]) -> Result<Vec<f64>> {
        let counts = self.counts_row(m, row.len())?;
        let (lo, hi, moved) = self.moved(share, row.len());
        let (cached, cached_window);
        let base: &[f64] = match self.response {
            Some(lock) => {
                cached = lock.read().map_err(|_| poisoned())?;
                cached.get(m * self.bins + lo..m * self.bins + hi).ok_or(OptimError::LengthMismatch {
                    what: "cached response",
                    expected: (m + 1) * self.bins,
                    got: cached.len(),
                })?
            }
            None => {
                cached_window = self.fit.kernel.apply_window(row, lo..hi);
                &cached_window
            }
        };
        let (s, b) = (self.scale, self.background);
        let mu: Vec<f64> = base.iter().map(|&a| (s * a + b).max(MU_FLOOR)).collect();
        let counts: Vec<f64> = counts[lo..hi].iter().map(|&c| f64::from(c)).collect();
        Ok(ks.iter().map(|&k| deviance_changes(&mu, &moved, &counts, s * f64::from(k))).collect())
    }

    fn applied(&self, spans: &[nlos_render::RowSpan], add: bool) -> Result<()> {
        let Some(lock) = self.response else { return Ok(()) };
        let mut response = lock.write().map_err(|_| poisoned())?;
        let sign = if add { 1.0 } else { -1.0 };
        for share in spans {
            let (lo, hi, moved) = self.moved(share, self.bins);
            let row = m_row(&mut response, share.measurement, self.bins)?;
            for (x, d) in row[lo..hi].iter_mut().zip(&moved) {
                *x += sign * d;
            }
        }
        Ok(())
    }
}

/// A lock whose holder panicked (a test of another thread): the cache cannot be trusted.
pub(crate) fn poisoned() -> OptimError {
    OptimError::InvalidParameter { name: "response cache", value: 0.0, reason: "a thread panicked while holding it" }
}

/// Histogram `m` of a measurement-major buffer.
fn m_row(buf: &mut [f64], m: usize, bins: usize) -> Result<&mut [f64]> {
    let len = buf.len();
    buf.get_mut(m * bins..(m + 1) * bins).ok_or(OptimError::LengthMismatch {
        what: "cached response",
        expected: (m + 1) * bins,
        got: len,
    })
}

#[cfg(test)]
mod tests;
