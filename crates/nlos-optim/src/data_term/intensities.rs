//! The data term: [`nlos_render::Loss`] (L2 of eq. (7) of Tsai et al. 2019, or Poisson NLL) with optional
//! per-bin weights and an unknown global intensity scale `s` solved in closed form at every evaluation.
//!
//! The measured data's radiometric scale is arbitrary (laser power, detector efficiency, the wall albedo,
//! the renderer's scale convention), so the data term compares the measurement `Ĩ` with `s·I`:
//! ```text
//! E*(I) = min_s E(s·I; Ĩ)
//! L2:       E = ½ Σ w (s I − Ĩ)²                ⇒  s* = ⟨I, Ĩ⟩_w / ⟨I, I⟩_w
//! Poisson:  E = Σ w (s I − Ĩ ln(s I))            ⇒  s* = Σ w Ĩ / Σ w I
//! ```
//! (`⟨a, b⟩_w = Σ w a b`; both minimisers are exact, the Poisson one ignores the renderer's floor clamp,
//! which only acts on bins where `s I` is below the floor.)
//!
//! **Gradient.** By the envelope theorem, `dE*/dI = ∂E/∂I (s*, I)` because `∂E/∂s = 0` at `s*`: the
//! gradient is that of the loss with `s` held fixed at its optimum, `dE*/dI = s* · E'(s* I)`, and no term
//! through `s*(I)` is needed. `tests::envelope_gradient_matches_finite_differences` checks this.
//!
//! **Guards.** When `⟨I, I⟩_w` (or `Σ w I`) is zero or not finite — nothing rendered falls in the time
//! window — or `s*` is not positive (L2 with a rendering anti-correlated to the data), `s*` is undefined or
//! useless; the caller's fallback scale is used instead (the previous iteration's).

use nlos_render::Loss;

use crate::error::{OptimError, Result};

/// A data term: loss, optional per-(measurement, bin) weights, whether to solve the scale.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DataTerm {
    /// The loss (L2 of eq. 7 or Poisson NLL), from `nlos_render`.
    pub loss: Loss,
    /// Optional non-negative weight per (measurement, bin), measurement-major.
    /// In the settings record as their count and FNV-1a digest (`serialize_weights`), not the values.
    #[serde(serialize_with = "serialize_weights")]
    pub weights: Option<Vec<f32>>,
    /// Solve the global intensity scale in closed form (default true); if false, `s = 1`.
    pub solve_scale: bool,
    /// The measurement holds photon counts (Poisson noise, e.g. a raw SPAD histogram or a simulated
    /// capture): the automatic regulariser weight is then set against the data term above its noise floor
    /// ([`DataTerm::noise_floor`]) rather than the whole data term. Default false (`nlos reconstruct` sets
    /// it when every value of the capture is a non-negative integer).
    pub counts: bool,
}

impl Default for DataTerm {
    fn default() -> Self {
        Self { loss: Loss::L2, weights: None, solve_scale: true, counts: false }
    }
}

/// The settings record's form of [`DataTerm::weights`]: `{ "len": n, "fnv1a": h }` over the weights'
/// bits (a run's record must not hold a copy of the capture's size).
fn serialize_weights<S: serde::Serializer>(w: &Option<Vec<f32>>, s: S) -> std::result::Result<S::Ok, S::Error> {
    use serde::ser::SerializeStruct;
    match w {
        None => s.serialize_none(),
        Some(w) => {
            let h = w
                .iter()
                .flat_map(|v| v.to_bits().to_le_bytes())
                .fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3));
            let mut st = s.serialize_struct("Weights", 2)?;
            st.serialize_field("len", &w.len())?;
            st.serialize_field("fnv1a", &h)?;
            st.end()
        }
    }
}

/// What [`DataTerm::evaluate`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct DataEval {
    /// `E(s·I; Ĩ)` (f64 sum).
    pub value: f64,
    /// The scale used (`s*`, or the fallback, or 1 without scale solving).
    pub scale: f64,
    /// `dE*/dI = s · E'(s·I)`, per (measurement, bin): feed this to `Renderer::adjoint`.
    pub d_rendered: Vec<f32>,
}

impl DataTerm {
    /// Checks weights (length, finite, ≥ 0) against a transient of `len` values.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`], [`OptimError::InvalidParameter`] for a negative or non-finite weight.
    pub fn validate(&self, len: usize) -> Result<()> {
        if let Some(w) = &self.weights {
            if w.len() != len {
                return Err(OptimError::LengthMismatch { what: "weights", expected: len, got: w.len() });
            }
            if let Some(x) = w.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                return Err(OptimError::InvalidParameter {
                    name: "weights",
                    value: f64::from(*x),
                    reason: "every weight must be finite and >= 0",
                });
            }
        }
        if let Loss::PoissonNll { floor } = self.loss
            && !(floor > 0.0 && floor.is_finite())
        {
            return Err(OptimError::InvalidParameter {
                name: "loss.floor",
                value: f64::from(floor),
                reason: "the Poisson floor must be finite and > 0 (e.g. 1e-12)",
            });
        }
        Ok(())
    }

    /// The closed-form optimal scale `s*` (module docs), or `None` where it is undefined or not positive.
    pub fn optimal_scale(&self, rendered: &[f32], measured: &[f32]) -> Option<f64> {
        let w = |i: usize| self.weights.as_ref().map_or(1.0, |w| f64::from(w[i]));
        let (mut num, mut den) = (0.0f64, 0.0f64);
        match self.loss {
            Loss::L2 => {
                for i in 0..rendered.len().min(measured.len()) {
                    let r = f64::from(rendered[i]);
                    num += w(i) * r * f64::from(measured[i]);
                    den += w(i) * r * r;
                }
            }
            Loss::PoissonNll { .. } => {
                for i in 0..rendered.len().min(measured.len()) {
                    num += w(i) * f64::from(measured[i]);
                    den += w(i) * f64::from(rendered[i]);
                }
            }
        }
        let s = num / den;
        // Guard: den = 0 (no signal) gives inf/NaN; s ≤ 0 would zero or invert the gradient.
        (den > 0.0 && s.is_finite() && s > 0.0).then_some(s)
    }

    /// `E`, the scale and `dE*/dI` for `rendered` against `measured`. With scale solving, `s*` is used when
    /// defined, else `fallback_scale`.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] for buffers of different lengths, and the errors of
    /// [`DataTerm::validate`].
    pub fn evaluate(&self, rendered: &[f32], measured: &[f32], fallback_scale: f64) -> Result<DataEval> {
        if measured.len() != rendered.len() {
            return Err(OptimError::LengthMismatch { what: "measured", expected: rendered.len(), got: measured.len() });
        }
        let scale = self.scale_for(rendered, measured, fallback_scale)?;
        let s32 = scale as f32;
        let scaled: Vec<f32> = rendered.iter().map(|r| s32 * r).collect();
        let (value, mut d) = self.loss.evaluate(&scaled, measured, self.weights.as_deref())?;
        // Chain rule through I ↦ s·I with s held fixed (envelope theorem, module docs).
        for x in &mut d {
            *x *= s32;
        }
        Ok(DataEval { value, scale, d_rendered: d })
    }

    /// The scale [`DataTerm::evaluate`] renders at: `s*` when solved and defined, else `fallback_scale` (1
    /// without scale solving).
    ///
    /// # Errors
    /// As [`DataTerm::evaluate`].
    pub fn scale_for(&self, rendered: &[f32], measured: &[f32], fallback_scale: f64) -> Result<f64> {
        if measured.len() != rendered.len() {
            return Err(OptimError::LengthMismatch { what: "measured", expected: rendered.len(), got: measured.len() });
        }
        self.validate(rendered.len())?;
        Ok(if self.solve_scale { self.optimal_scale(rendered, measured).unwrap_or(fallback_scale) } else { 1.0 })
    }

    /// The data term of one histogram at a fixed scale: `E(s·I; Ĩ)` over `rendered_row` and `measured_row`
    /// (equal lengths), whose first value is value `offset` of the whole transient (for the weights). The
    /// data term is the sum of these over the histograms; boundary pruning ([`crate::prune`]) compares them
    /// with and without a face.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] for rows of different lengths or weights that do not cover the row.
    pub fn row_value(&self, rendered_row: &[f32], measured_row: &[f32], offset: usize, scale: f64) -> Result<f64> {
        self.row_value_in(rendered_row, measured_row, offset, scale, 0..rendered_row.len())
    }

    /// [`DataTerm::row_value`] summed over the bins `window` of the row only (clamped to the row): the data
    /// term is a sum over bins, so two rows that differ only inside `window` differ by exactly the
    /// difference of these values (`crate::data_term::RowLoss`).
    ///
    /// # Errors
    /// As [`DataTerm::row_value`].
    pub fn row_value_in(
        &self,
        rendered_row: &[f32],
        measured_row: &[f32],
        offset: usize,
        scale: f64,
        window: std::ops::Range<usize>,
    ) -> Result<f64> {
        if measured_row.len() != rendered_row.len() {
            return Err(OptimError::LengthMismatch {
                what: "measured row",
                expected: rendered_row.len(),
                got: measured_row.len(),
            });
        }
        let weights = match &self.weights {
            Some(w) => Some(w.get(offset..offset + rendered_row.len()).ok_or(OptimError::LengthMismatch {
                what: "weights",
                expected: offset + rendered_row.len(),
                got: w.len(),
            })?),
            None => None,
        };
        let w = window.start.min(rendered_row.len())..window.end.min(rendered_row.len());
        let w = w.start.min(w.end)..w.end;
        // Exactly as `evaluate`: scaled in f32, then the renderer's loss (without allocating).
        Ok(self.loss.value_scaled(
            &rendered_row[w.clone()],
            scale as f32,
            &measured_row[w.clone()],
            weights.map(|x| &x[w]),
        )?)
    }

    /// The expected data term if the measurement were Poisson counts with means `μ = scale·rendered`
    /// (the part of the data term no surface can remove when the model is exact):
    /// ```text
    /// L2:       E[½ Σ w (μ − n)²]            = ½ Σ w μ                     (Var n = μ)
    /// Poisson:  E[Σ w (μ − n ln μ)] − (E − D) = Σ w (d(μ) + n − n ln n)
    /// ```
    /// with `D` the half-deviance and `d` its expectation ([`expected_half_deviance`]): for
    /// the Poisson loss, whose value is not zero at a perfect fit, `E − floor = D − Σ w d(μ)` is the misfit
    /// above the noise.
    ///
    /// # Errors
    /// As [`DataTerm::evaluate`]: buffers or weights of different lengths, invalid weights.
    pub fn noise_floor(&self, rendered: &[f32], measured: &[f32], scale: f64) -> Result<f64> {
        if measured.len() != rendered.len() {
            return Err(OptimError::LengthMismatch { what: "measured", expected: rendered.len(), got: measured.len() });
        }
        self.validate(rendered.len())?;
        let w = |i: usize| self.weights.as_ref().map_or(1.0, |w| f64::from(w[i]));
        let n = rendered.len();
        Ok(match self.loss {
            Loss::L2 => (0..n).map(|i| 0.5 * w(i) * (scale * f64::from(rendered[i])).max(0.0)).sum(),
            Loss::PoissonNll { .. } => (0..n)
                .map(|i| {
                    let mu = (scale * f64::from(rendered[i])).max(0.0);
                    let c = f64::from(measured[i]).max(0.0);
                    let c_ln_c = if c > 0.0 { c * c.ln() } else { 0.0 };
                    w(i) * (expected_half_deviance(mu) + c - c_ln_c)
                })
                .sum(),
        })
    }

    /// A positive normaliser for the data term: `½ Σ w Ĩ²` for L2, `Σ w Ĩ` for Poisson — the loss of a zero
    /// rendering (up to constants), so the normalised data term is ≈ 1 at a blank start and ≪ 1 at a fit. It
    /// makes loss values and Adam's ε independent of the capture's arbitrary units. `None` for an all-zero
    /// measurement.
    pub fn normaliser(&self, measured: &[f32]) -> Option<f64> {
        let w = |i: usize| self.weights.as_ref().map_or(1.0, |w| f64::from(w[i]));
        let n: f64 = match self.loss {
            Loss::L2 => (0..measured.len()).map(|i| 0.5 * w(i) * f64::from(measured[i]).powi(2)).sum(),
            Loss::PoissonNll { .. } => (0..measured.len()).map(|i| w(i) * f64::from(measured[i]).abs()).sum(),
        };
        (n > 0.0 && n.is_finite()).then_some(n)
    }
}

/// The plain data term row by row at a fixed scale ([`crate::data_term::RowTerm`]): histogram m of
/// `measured` (`bins` each) against a rendered row. A sum over bins, so a share's changes are evaluated on
/// its window alone (the same bits as the trait's default, which shifts a copy of the whole row).
pub(crate) struct DataTermRows<'a> {
    pub(crate) term: &'a DataTerm,
    pub(crate) measured: &'a [f32],
    pub(crate) bins: usize,
    pub(crate) scale: f64,
}

impl DataTermRows<'_> {
    /// Histogram m of the measurement.
    fn measured_row(&self, m: usize) -> Result<&[f32]> {
        self.measured.get(m * self.bins..(m + 1) * self.bins).ok_or(OptimError::LengthMismatch {
            what: "measured",
            expected: (m + 1) * self.bins,
            got: self.measured.len(),
        })
    }
}

impl crate::data_term::RowTerm for DataTermRows<'_> {
    fn value(&self, m: usize, row: &[f32], window: std::ops::Range<usize>) -> Result<f64> {
        self.term.row_value_in(row, self.measured_row(m)?, m * self.bins, self.scale, window)
    }

    fn changes(&self, m: usize, row: &[f32], share: &nlos_render::RowSpan, ks: &[f32]) -> Result<Vec<f64>> {
        let measured = self.measured_row(m)?;
        if measured.len() != row.len() {
            return Err(OptimError::LengthMismatch { what: "rendered row", expected: measured.len(), got: row.len() });
        }
        // Clamped to the row, as the trait's default.
        let end = (share.first_bin + share.values.len()).min(row.len());
        let window = share.first_bin.min(end)..end;
        let now = self.value(m, row, window.clone())?;
        let (base, measured) = (&row[window.clone()], &measured[window.clone()]);
        let mut shifted = base.to_vec();
        ks.iter()
            .map(|&k| {
                for ((x, v), r) in shifted.iter_mut().zip(&share.values).zip(base) {
                    *x = (*r + k * v).max(0.0);
                }
                let offset = m * self.bins + window.start;
                Ok(self.term.row_value_in(&shifted, measured, offset, self.scale, 0..shifted.len())? - now)
            })
            .collect()
    }
}

/// Above this mean the expected half-deviance uses its asymptotic expansion (the series and the expansion
/// agree to 1e-5 there).
pub(crate) const DEVIANCE_SERIES_MAX_MU: f64 = 50.0;

/// The variance `σ² = Σ w² μ (s d)² / Σ w (s d)²` (`μ = max(s I, 1)`, the expected counts of the rendering `I`)
/// of the L2 fit of photon counts at scale `s` along a direction `d` of the rendering: the projection of the
/// Poisson noise on the direction the fit moves in, so that `2ΔE / σ²` is the likelihood-ratio statistic of a
/// change of the rendering along `d` by `ΔE`. `terms` yields `(I, d, w)` per bin (`w` the bin's weight, 1 for
/// an unweighted term): the whole rendering along itself for the fit against an empty scene
/// (`crate::FitQuality`), a region's share for the region tests (`crate::regions`). NaN when `d` is 0.
pub(crate) fn counts_variance(terms: impl IntoIterator<Item = (f32, f32, f64)>, scale: f64) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (rendered, direction, w) in terms {
        let share = (scale * f64::from(direction)).powi(2);
        num += w * w * (scale * f64::from(rendered)).max(1.0) * share;
        den += w * share;
    }
    if den > 0.0 { num / den } else { f64::NAN }
}

/// The expected Poisson half-deviance `d(μ) = E[μ − n + n ln(n/μ)]` of one bin with `n ~ Poisson(μ)`
/// ([`crate::data_term::counts`]'s module docs, "Noise floor"): ≈ `μ ln(1/μ)` for `μ → 0`, → ½ for large `μ` (Wilks: twice the
/// deviance is χ²₁). `0` for `μ ≤ 0` or not finite.
pub fn expected_half_deviance(mu: f64) -> f64 {
    if !(mu.is_finite() && mu > 0.0) {
        return 0.0;
    }
    if mu > DEVIANCE_SERIES_MAX_MU {
        return 0.5 + 1.0 / (12.0 * mu) + 1.0 / (12.0 * mu * mu);
    }
    // E[n ln n] = Σ_{n≥2} p(n)·n ln n with p(n) = p(n−1)·μ/n; the terms n = 0, 1 vanish. Summed until
    // past the mode and the terms are negligible (at most μ + 12√μ + 30 terms for μ ≤ 50).
    let mut p = (-mu).exp() * mu; // p(1)
    let mut sum = 0.0;
    let n_max = (mu + 12.0 * mu.sqrt() + 30.0) as u32;
    for n in 2..=n_max {
        let nf = f64::from(n);
        p *= mu / nf;
        let term = p * nf * nf.ln();
        sum += term;
        if nf > mu && term < 1e-17 * sum.max(1e-300) {
            break;
        }
    }
    // Guard: the difference of two nearly equal terms can round below zero for tiny μ.
    (sum - mu * mu.ln()).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_variance_is_the_poisson_variance_along_the_direction() {
        // A direction on bins of 4 expected counts: σ² = 4; where the counts fall below one the variance is
        // held at 1 (μ = max(s I, 1)); bins the direction does not touch do not count; no direction: NaN.
        let v = counts_variance([(2.0, 1.0, 1.0), (2.0, 3.0, 1.0), (50.0, 0.0, 1.0)], 2.0);
        assert!((v - 4.0).abs() < 1e-12, "{v}");
        let v = counts_variance([(0.1, 1.0, 1.0), (0.2, 2.0, 1.0)], 1.0);
        assert!((v - 1.0).abs() < 1e-12, "{v}");
        // Weights w: Σ w² μ d² / Σ w d².
        let v = counts_variance([(4.0, 1.0, 2.0), (9.0, 1.0, 1.0)], 1.0);
        assert!((v - (4.0 * 4.0 + 9.0) / 3.0).abs() < 1e-12, "{v}");
        assert!(counts_variance([(3.0, 0.0, 1.0)], 1.0).is_nan());
    }

    /// `DataTermRows::changes` over the share's window gives the bits of the trait's default over the whole
    /// row, for both losses, with and without weights, for a share inside the row and one past its end.
    #[test]
    fn row_changes_on_the_window_are_the_whole_rows_changes() {
        use crate::data_term::RowTerm;
        let (bins, rows) = (40, 3);
        let rendered: Vec<f32> = (0..bins * rows).map(|i| 0.5 + ((i * 7 % 11) as f32) * 0.1).collect();
        let measured: Vec<f32> = (0..bins * rows).map(|i| 2.0 + ((i * 5 % 13) as f32) * 0.25).collect();
        let weights: Vec<f32> = (0..bins * rows).map(|i| 0.5 + (i % 3) as f32 * 0.5).collect();
        let ks = [-1.0f32, 1.0, 2.0];
        for loss in [Loss::L2, Loss::PoissonNll { floor: 1e-6 }] {
            for w in [None, Some(weights.clone())] {
                let term = DataTerm { loss, weights: w, solve_scale: true, counts: true };
                let rows_term = DataTermRows { term: &term, measured: &measured, bins, scale: 1.3 };
                let whole = |m: usize, row: &[f32], window: std::ops::Range<usize>| {
                    term.row_value_in(row, &measured[m * bins..(m + 1) * bins], m * bins, 1.3, window)
                };
                for (m, first_bin) in [(1, 12), (2, 35)] {
                    let share = nlos_render::RowSpan {
                        measurement: m,
                        first_bin,
                        values: vec![0.3, 0.7, 0.2, 0.9, 0.1, 0.4, 0.6, 0.8],
                    };
                    let row = &rendered[m * bins..(m + 1) * bins];
                    let fast = rows_term.changes(m, row, &share, &ks).expect("ok");
                    let slow = whole.changes(m, row, &share, &ks).expect("ok");
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&fast), bits(&slow), "{loss:?}, share at {first_bin}");
                }
            }
        }
    }

    fn data() -> (Vec<f32>, Vec<f32>, Vec<f32>) {
        let rendered: Vec<f32> = (0..40).map(|i| 0.5 + ((i * 7 % 11) as f32) * 0.1).collect();
        let measured: Vec<f32> = (0..40).map(|i| 2.0 + ((i * 5 % 13) as f32) * 0.25).collect();
        let weights: Vec<f32> = (0..40).map(|i| 0.5 + (i % 3) as f32 * 0.5).collect();
        (rendered, measured, weights)
    }

    #[test]
    fn l2_scale_is_the_least_squares_minimiser() {
        let (r, m, _) = data();
        let t = DataTerm::default();
        let s = t.optimal_scale(&r, &m).expect("defined");
        let e = |s: f64| t.loss.evaluate(&r.iter().map(|x| s as f32 * x).collect::<Vec<_>>(), &m, None).expect("ok").0;
        assert!(e(s) <= e(s * 1.001) && e(s) <= e(s * 0.999));
        // Exact data: s* recovers the true factor.
        let m3: Vec<f32> = r.iter().map(|x| 3.0 * x).collect();
        assert!((t.optimal_scale(&r, &m3).expect("defined") - 3.0).abs() < 1e-6);
    }

    #[test]
    fn poisson_scale_is_the_nll_minimiser() {
        let (r, m, w) = data();
        let t =
            DataTerm { loss: Loss::PoissonNll { floor: 1e-12 }, weights: Some(w), solve_scale: true, counts: false };
        let s = t.optimal_scale(&r, &m).expect("defined");
        let e = |s: f64| {
            let sc: Vec<f32> = r.iter().map(|x| s as f32 * x).collect();
            t.loss.evaluate(&sc, &m, t.weights.as_deref()).expect("ok").0
        };
        assert!(e(s) <= e(s * 1.001) && e(s) <= e(s * 0.999));
    }

    #[test]
    fn envelope_gradient_matches_finite_differences() {
        let (r, m, w) = data();
        for term in [
            DataTerm::default(),
            DataTerm { loss: Loss::L2, weights: Some(w.clone()), solve_scale: true, counts: false },
            DataTerm {
                loss: Loss::PoissonNll { floor: 1e-12 },
                weights: Some(w.clone()),
                solve_scale: true,
                counts: false,
            },
        ] {
            let g = term.evaluate(&r, &m, 1.0).expect("ok");
            // E*(I) = min_s E(s I), re-solving s at every perturbed I.
            let e_star = |i: usize, h: f32| {
                let mut rr = r.clone();
                rr[i] += h;
                term.evaluate(&rr, &m, 1.0).expect("ok").value
            };
            for i in [0, 3, 17, 39] {
                let h = 1e-2f32;
                let fd = (e_star(i, h) - e_star(i, -h)) / (2.0 * f64::from(h));
                let an = f64::from(g.d_rendered[i]);
                assert!((fd - an).abs() <= 2e-3 * (1.0 + an.abs()), "{:?} bin {i}: fd {fd} vs {an}", term.loss);
            }
        }
    }

    #[test]
    fn no_signal_falls_back_and_validation_rejects_bad_weights() {
        let t = DataTerm::default();
        assert_eq!(t.optimal_scale(&[0.0; 4], &[1.0; 4]), None);
        assert_eq!(t.evaluate(&[0.0; 4], &[1.0; 4], 2.5).expect("ok").scale, 2.5);
        let bad = DataTerm { weights: Some(vec![1.0, -1.0]), ..DataTerm::default() };
        assert!(matches!(bad.evaluate(&[1.0; 2], &[1.0; 2], 1.0), Err(OptimError::InvalidParameter { .. })));
        assert!(matches!(t.evaluate(&[1.0; 2], &[1.0; 3], 1.0), Err(OptimError::LengthMismatch { .. })));
        assert_eq!(t.normaliser(&[0.0; 3]), None);
    }

    /// Statistical test: over Poisson draws from the model, the mean data term (scale fixed at the model's)
    /// equals the noise floor, for both losses (2,000 draws, 5 standard errors).
    #[test]
    fn noise_floor_is_the_mean_data_term_of_poisson_counts() {
        let (r, _, w) = data();
        let scale = 2.5;
        let mut rng = nlos_transient::rng::Pcg32::new(11, 0);
        for loss in [Loss::L2, Loss::PoissonNll { floor: 1e-12 }] {
            let t = DataTerm { loss, weights: Some(w.clone()), solve_scale: false, counts: true };
            let scaled: Vec<f32> = r.iter().map(|x| scale as f32 * x).collect();
            let (mut sum, mut sum2, mut floor_sum) = (0.0, 0.0, 0.0);
            let draws = 2000;
            for _ in 0..draws {
                let counts: Vec<f32> = scaled.iter().map(|&mu| rng.poisson(f64::from(mu)) as f32).collect();
                let (e, _) = t.loss.evaluate(&scaled, &counts, t.weights.as_deref()).expect("ok");
                // The Poisson floor depends on the counts (its n − n ln n part): compare E − floor with 0.
                let f = t.noise_floor(&r, &counts, scale).expect("floor");
                let x = e - f;
                sum += x;
                sum2 += x * x;
                floor_sum += f;
            }
            let mean = sum / f64::from(draws);
            let se = ((sum2 / f64::from(draws) - mean * mean) / f64::from(draws)).sqrt();
            assert!(mean.abs() < 5.0 * se + 1e-9 * floor_sum.abs(), "{loss:?}: mean E − floor {mean} ± {se}");
        }
        // L2's floor is ½ Σ w μ exactly.
        let t = DataTerm { weights: Some(w.clone()), ..DataTerm::default() };
        let want: f64 = r.iter().zip(&w).map(|(&x, &wi)| 0.5 * f64::from(wi) * scale * f64::from(x)).sum();
        assert!((t.noise_floor(&r, &r, scale).expect("floor") - want).abs() < 1e-9 * want);
        // Bad input is a typed error, not a panic.
        assert!(matches!(t.noise_floor(&r, &r[1..], scale), Err(OptimError::LengthMismatch { .. })));
        let short = DataTerm { weights: Some(w[1..].to_vec()), ..DataTerm::default() };
        assert!(matches!(short.noise_floor(&r, &r, scale), Err(OptimError::LengthMismatch { .. })));
    }
}
