//! Coarse-to-fine in time: the data term of the early stages compares Gaussian-blurred histograms.
//!
//! The time-shift part of the gradient (Proposition 1 of Tsai et al. 2019) comes from the kernel's
//! derivative `dK_k/dτ`, which is non-zero only within a bin or two of a sample's path length. A surface
//! whose light arrives many bins away from where the measurement has it (the rim of an LCT surface, blurred
//! toward the brighter interior and so too near the wall by 2–4 cm) therefore feels no pull toward the
//! right depth: the residual there is its own light, which shifting does not reduce, and
//! [`crate::prune`] deletes it. The remedy is the temporal analogue of the spatial coarse-to-fine schedule:
//! in the first stages the data term is
//! ```text
//! E_σ = ½ ‖s·G_σ I − G_σ Ĩ‖²,        ∂E_σ/∂I = G_σᵀ (s·(s G_σ I − G_σ Ĩ)) = G_σ (…)
//! ```
//! with `G_σ` a Gaussian blur along each histogram's time axis (zero beyond its ends). `G_σ` is symmetric,
//! so its adjoint is itself: the renderer's forward pass and adjoint are unchanged, the blur wraps them. A
//! face whose light is within a few σ of the measured return now sees the overlap grow as it moves toward
//! it. Later stages use smaller σ, and the last ones none (the schedule
//! [`crate::ReconstructParams::temporal_blur`]).
//!
//! **Noise floor.** For Poisson counts with means `μ`, the blurred histogram's variance is
//! `Σ_k g_k² μ_{i−k}` per bin, so the L2 data term's noise floor `½ Σ μ` ([`crate::DataTerm::noise_floor`])
//! becomes `½ (Σ_k g_k²) Σ μ`: [`TemporalBlur::noise_factor`] (tested statistically below).
//!
//! **Why not a wider renderer kernel.** `nlos_render::Kernel::Gaussian` renders the same blur exactly,
//! but splats every sample into `10σ` bins instead of the tent's two: stage 0 of the seed-setup bunny took
//! 169 s for one block at σ = 6.8 bins (all twelve blocks of the tent: 337 s). The separable blur costs
//! `O(bins · taps)` per histogram, independent of the samples.
//!
//! Pruning, growth and residual patches keep testing faces against the unblurred data: their tests are
//! exact per face, and a blurred test would also keep a face whose light is merely near the right time.

use rayon::prelude::*;

use crate::error::{OptimError, Result};

/// Largest accepted full width at half maximum, in bins (a larger blur erases every depth cue).
pub const MAX_FWHM_BINS: f64 = 1000.0;

/// A normalised, symmetric Gaussian blur along the time axis of each histogram.
///
/// ```
/// use nlos_optim::TemporalBlur;
/// let g = TemporalBlur::new(4.0)?;
/// let mut x = vec![0.0f32; 64];
/// x[32] = 1.0;
/// let y = g.apply(&x, 64)?;
/// assert!((y.iter().sum::<f32>() - 1.0).abs() < 1e-6);
/// assert!((y[30] / y[32] - 0.5).abs() < 0.02); // half maximum at ±FWHM/2 = ±2 bins
/// # Ok::<(), nlos_optim::OptimError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct TemporalBlur {
    fwhm_bins: f64,
    /// `g_{−r} … g_r`, summing to 1.
    taps: Vec<f64>,
}

impl TemporalBlur {
    /// The blur of full width at half maximum `fwhm_bins` (in bins): taps `g_k ∝ exp(−k²/2σ²)`,
    /// `σ = FWHM/(2√(2 ln 2))`, for `|k| ≤ ⌈4σ⌉`, normalised to sum 1 (the truncated mass, 6·10⁻⁵, is
    /// spread over the kept taps).
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] (`temporal_blur`) unless `0 < fwhm_bins ≤` [`MAX_FWHM_BINS`].
    pub fn new(fwhm_bins: f64) -> Result<Self> {
        if !(fwhm_bins > 0.0 && fwhm_bins <= MAX_FWHM_BINS) {
            return Err(OptimError::InvalidParameter {
                name: "temporal_blur",
                value: fwhm_bins,
                reason: "the blur's full width at half maximum lies in (0, 1000] bins (leave a stage out of the \
                         schedule to fit it unblurred)",
            });
        }
        let sigma = fwhm_bins / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
        let r = (4.0 * sigma).ceil() as i64;
        let mut taps: Vec<f64> = (-r..=r).map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp()).collect();
        let sum: f64 = taps.iter().sum();
        taps.iter_mut().for_each(|g| *g /= sum);
        Ok(Self { fwhm_bins, taps })
    }

    /// Full width at half maximum, in bins.
    pub fn fwhm_bins(&self) -> f64 {
        self.fwhm_bins
    }

    /// The taps `g_{−r} … g_r` (odd count, symmetric, summing to 1).
    pub fn taps(&self) -> &[f64] {
        &self.taps
    }

    /// `Σ_k g_k²`: the factor by which the blur scales the variance of independent (Poisson) bin noise, and
    /// so the L2 data term's noise floor (module docs).
    pub fn noise_factor(&self) -> f64 {
        self.taps.iter().map(|g| g * g).sum()
    }

    /// Blurs every histogram of `data` (measurement-major, `bins` per histogram; zero beyond the ends, so
    /// light within `4σ` of an end partly leaves the axis). The operator is symmetric: it is its own
    /// adjoint, `⟨G x, y⟩ = ⟨x, G y⟩`.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] when `bins` is 0 or does not divide `data.len()`.
    pub fn apply(&self, data: &[f32], bins: usize) -> Result<Vec<f32>> {
        if bins == 0 || !data.len().is_multiple_of(bins) {
            return Err(OptimError::LengthMismatch {
                what: "blurred histograms",
                expected: data.len().checked_div(bins).map_or(0, |m| m * bins),
                got: data.len(),
            });
        }
        let r = self.taps.len() / 2;
        let mut out = vec![0.0f32; data.len()];
        out.par_chunks_mut(bins).zip(data.par_chunks(bins)).for_each(|(o, row)| {
            for (i, oi) in o.iter_mut().enumerate() {
                // Taps j with 0 ≤ i + j − r < bins.
                let (lo, hi) = (r.saturating_sub(i), (bins + r - i).min(self.taps.len()));
                let mut acc = 0.0f64;
                for j in lo..hi {
                    acc += self.taps[j] * f64::from(row[i + j - r]);
                }
                *oi = acc as f32;
            }
        });
        Ok(out)
    }
}

/// The blur of `stage` under a schedule of full widths in metres of path (`schedule[stage]`; stages past
/// its end, and widths of 0, are unblurred), on bins of `bin_width` metres.
///
/// # Errors
/// As [`TemporalBlur::new`], for a width that is negative, not finite or above [`MAX_FWHM_BINS`] bins.
pub fn stage_blur(schedule: &[f64], stage: u32, bin_width: f64) -> Result<Option<TemporalBlur>> {
    match schedule.get(stage as usize) {
        None => Ok(None),
        Some(&0.0) => Ok(None),
        Some(&w) => TemporalBlur::new(w / bin_width).map(Some),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn taps_are_a_normalised_symmetric_gaussian_with_the_asked_width() {
        for fwhm in [0.5, 1.0, 3.0, 16.0, 40.0] {
            let g = TemporalBlur::new(fwhm).unwrap();
            let t = g.taps();
            assert_eq!(t.len() % 2, 1);
            assert!((t.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let r = t.len() / 2;
            for k in 0..r {
                assert_eq!(t[k], t[t.len() - 1 - k]);
            }
            // Variance σ² of the continuous Gaussian (sampling at integers adds < 1e-6 for σ ≥ 1).
            let sigma = fwhm / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
            let var: f64 = t.iter().enumerate().map(|(j, g)| g * (j as f64 - r as f64).powi(2)).sum();
            if sigma >= 1.0 {
                assert!((var / (sigma * sigma) - 1.0).abs() < 2e-3, "fwhm {fwhm}: variance {var} vs {}", sigma * sigma);
            }
        }
    }

    #[test]
    fn blur_is_its_own_adjoint_and_keeps_the_sum_away_from_the_ends() {
        let g = TemporalBlur::new(7.0).unwrap();
        let bins = 50;
        let mut s = 12345u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 33) as f64 / (1u64 << 31) as f64) as f32 - 0.5
        };
        let x: Vec<f32> = (0..3 * bins).map(|_| rnd()).collect();
        let y: Vec<f32> = (0..3 * bins).map(|_| rnd()).collect();
        let (gx, gy) = (g.apply(&x, bins).unwrap(), g.apply(&y, bins).unwrap());
        let dot = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(p, q)| f64::from(*p) * f64::from(*q)).sum::<f64>();
        assert!((dot(&gx, &y) - dot(&x, &gy)).abs() < 1e-5, "{} vs {}", dot(&gx, &y), dot(&x, &gy));
        // An impulse in the middle of a histogram keeps its mass, and each histogram is blurred on its own.
        let mut d = vec![0.0f32; 3 * bins];
        d[bins + 25] = 2.0;
        let gd = g.apply(&d, bins).unwrap();
        assert!((gd[bins..2 * bins].iter().sum::<f32>() - 2.0).abs() < 1e-5);
        assert!(gd[..bins].iter().chain(&gd[2 * bins..]).all(|v| *v == 0.0));
        // The blurred impulse is the taps.
        let r = g.taps().len() / 2;
        for (j, t) in g.taps().iter().enumerate() {
            assert!((f64::from(gd[bins + 25 + j - r]) - 2.0 * t).abs() < 1e-6);
        }
    }

    #[test]
    fn noise_factor_is_the_variance_of_blurred_poisson_noise() {
        // Statistical test: the mean of ½‖G(n − μ)‖² over Poisson draws n ~ P(μ) is ½ Σg² Σμ (the blurred
        // L2 noise floor), away from the ends of the axis.
        let g = TemporalBlur::new(6.0).unwrap();
        let bins = 200;
        let mu: Vec<f32> = (0..bins).map(|i| 5.0 + 20.0 * (-(((i as f32) - 100.0) / 30.0).powi(2)).exp()).collect();
        let mut rng = nlos_transient::sensor::Pcg32::new(7, 3);
        let gm = g.apply(&mu, bins).unwrap();
        let (draws, mut sum) = (400, 0.0f64);
        let inner = 20..180; // away from the ends, where the blur loses mass
        for _ in 0..draws {
            let n: Vec<f32> = mu.iter().map(|&m| rng.poisson(f64::from(m)) as f32).collect();
            let gn = g.apply(&n, bins).unwrap();
            sum += inner.clone().map(|i| 0.5 * (f64::from(gn[i]) - f64::from(gm[i])).powi(2)).sum::<f64>();
        }
        let measured = sum / f64::from(draws);
        let predicted = 0.5 * g.noise_factor() * inner.map(|i| f64::from(mu[i])).sum::<f64>();
        // Standard error of the mean over 400 draws of a sum of ~160 correlated squares: a few per cent.
        assert!((measured / predicted - 1.0).abs() < 0.06, "measured {measured}, predicted {predicted}");
        // Unblurred, the factor would be 1: the blur removes most of the noise.
        assert!(g.noise_factor() < 0.25);
    }

    #[test]
    fn bad_widths_and_shapes_are_typed_errors() {
        for w in [0.0, -1.0, f64::NAN, f64::INFINITY, 1001.0] {
            assert!(matches!(TemporalBlur::new(w), Err(OptimError::InvalidParameter { name: "temporal_blur", .. })));
        }
        let g = TemporalBlur::new(2.0).unwrap();
        assert!(matches!(g.apply(&[1.0; 10], 3), Err(OptimError::LengthMismatch { .. })));
        assert!(matches!(g.apply(&[1.0; 10], 0), Err(OptimError::LengthMismatch { .. })));
        assert!(stage_blur(&[0.02, 0.0], 1, 0.001).unwrap().is_none());
        assert!(stage_blur(&[0.02], 5, 0.001).unwrap().is_none());
        assert!((stage_blur(&[0.02], 0, 0.001).unwrap().unwrap().fwhm_bins() - 20.0).abs() < 1e-9);
        assert!(stage_blur(&[-0.02], 0, 0.001).is_err());
    }
}
