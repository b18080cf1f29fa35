//! The sensor's timing response (jitter): loading, Gaussian model, FWHM, resampling onto a transient's
//! bins, and the resulting convolution operator with its adjoint.
//!
//! ## Model
//! A photon arriving at path length `τ_true` is registered at `τ_true + τ` with `τ` drawn from the
//! timing-response density `h(τ)` (SPAD avalanche build-up, electronics, and — in a measured response —
//! the laser pulse width). [`JitterResponse`] stores `h` as a fine histogram: sample `i` holds the mass of
//! `h` over `[origin + i·δ, origin + (i+1)·δ)` (metres of path, `δ` the sample spacing), normalised to
//! `Σ_i w_i = 1`. **Zero delay is the mode (peak)** of a measured response, the convention of the shared
//! `spad_jitter.mat` (its `t_1` is exactly 0 at the maximum of `counts_1`) and of captures whose time
//! zero is calibrated on the peak of the direct return.
//!
//! ## Resampling onto transient bins (mass-conserving)
//! A transient bin `k` holds the integral of a piecewise-constant flux over `[k·Δ, (k+1)·Δ)`, so a photon
//! counted in bin `k` arrived at `(k + u)·Δ` with `u ~ U[0, 1)`. With `s = τ/Δ` it is registered in bin
//! `k + d` exactly when `d ≤ u + s < d + 1`, which has probability `tent(s − d) = max(0, 1 − |s − d|)`.
//! The bin kernel is therefore
//!
//! `K[d] = ∫ h(τ) · tent(τ/Δ − d) dτ`,
//!
//! integrated **exactly** over each piecewise-constant sample of `h` with the tent's antiderivative `T`.
//! Since `Σ_d tent(s − d) = 1` for every `s`, `Σ_d K[d] = Σ_i w_i = 1` (flux is conserved), and since
//! `Σ_d d·tent(s − d) = s`, the kernel's centroid in bins is the response's mean delay over `Δ`.
//!
//! ## Operator
//! [`BinKernel::apply`]: `(A x)[k] = Σ_d K[d] · x[k − d]` per histogram; [`BinKernel::adjoint`]:
//! `(Aᵀ y)[j] = Σ_d K[d] · y[j + d]`. Photons delayed beyond the last bin (or advanced before the first)
//! leave the histogram window, as they do in a real TCSPC window; away from the edges `Σ_k (A x)[k] =
//! Σ_k x[k]`.

use crate::SPEED_OF_LIGHT;
use crate::error::{MEMORY, Result, TransientError};
use crate::ops::median;
use crate::transient::Transient;

/// A timing response `h(τ)` as a fine, normalised histogram of delays (metres of path). See the
/// [module docs](self) for the conventions.
#[derive(Debug, Clone, PartialEq)]
pub struct JitterResponse {
    origin: f64,
    spacing: f64,
    weights: Vec<f64>,
}

fn invalid(field: &str, reason: String) -> TransientError {
    TransientError::InvalidValue { file: MEMORY.into(), field: field.into(), reason }
}

fn arg(name: &'static str, reason: String) -> TransientError {
    TransientError::InvalidArgument { name, reason }
}

impl JitterResponse {
    /// A response from a measured histogram: sample `i` holds `counts[i]`, covering delays
    /// `[origin + i·spacing, origin + (i+1)·spacing)` metres of path.
    ///
    /// With `subtract_floor`, the constant floor (dark counts and ambient light recorded with the
    /// response) is removed first: `floor = min(median(first 5 %), median(last 5 %))` of the samples (at
    /// least one sample each), then `max(0, counts − floor)`. A flat floor left in would act as a spurious
    /// uniform component spread over the whole window. The result is normalised to unit mass and leading
    /// and trailing zero samples are dropped (the origin moves accordingly).
    ///
    /// # Errors
    /// [`TransientError::InvalidValue`] for an empty histogram, non-finite or negative counts, a
    /// non-finite origin, a spacing that is not finite and positive, or a histogram with no mass above the
    /// floor.
    pub fn from_histogram(origin: f64, spacing: f64, counts: &[f64], subtract_floor: bool) -> Result<Self> {
        if counts.is_empty() {
            return Err(invalid("counts", "the timing histogram is empty".into()));
        }
        if !origin.is_finite() {
            return Err(invalid("origin", format!("{origin} is not finite")));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(invalid("spacing", format!("{spacing} must be finite and > 0 (metres of path)")));
        }
        if let Some(i) = counts.iter().position(|c| !c.is_finite()) {
            return Err(TransientError::NonFinite { file: MEMORY.into(), field: "counts".into(), index: i });
        }
        if let Some(i) = counts.iter().position(|&c| c < 0.0) {
            return Err(invalid("counts", format!("sample {i} is negative ({}); counts are ≥ 0", counts[i])));
        }
        let floor = if subtract_floor {
            let edge = (counts.len() / 20).max(1);
            median(&counts[..edge]).min(median(&counts[counts.len() - edge..]))
        } else {
            0.0
        };
        let w: Vec<f64> = counts.iter().map(|&c| (c - floor).max(0.0)).collect();
        let Some(first) = w.iter().position(|&v| v > 0.0) else {
            return Err(invalid("counts", format!("no mass above the floor ({floor}); is this a timing histogram?")));
        };
        let last = w.iter().rposition(|&v| v > 0.0).unwrap_or(first);
        let total: f64 = w[first..=last].iter().sum();
        let weights = w[first..=last].iter().map(|v| v / total).collect();
        Ok(Self { origin: origin + first as f64 * spacing, spacing, weights })
    }

    /// A Gaussian response of full width at half maximum `fwhm` (metres of path), centred on zero delay:
    /// `h(τ) = exp(−τ²/2σ²)/(σ√2π)`, `σ = FWHM / (2√(2 ln 2))`.
    ///
    /// Stored on `±4 FWHM` (±9.4 σ; the mass outside is < 1e-20) with spacing `FWHM/64`, each sample
    /// holding the density at its centre times the spacing, renormalised to unit mass (the midpoint rule's
    /// relative error at this spacing is ~1e-5 per sample and cancels in the normalisation to first order).
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when `fwhm` is not finite and positive.
    pub fn gaussian(fwhm: f64) -> Result<Self> {
        if !(fwhm.is_finite() && fwhm > 0.0) {
            return Err(arg("fwhm", format!("{fwhm} must be finite and > 0 (metres of path)")));
        }
        let sigma = fwhm / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
        let spacing = fwhm / 64.0;
        let half = 256usize; // 4 FWHM / spacing
        let n = 2 * half + 1;
        let origin = -(half as f64 + 0.5) * spacing;
        let w: Vec<f64> = (0..n)
            .map(|i| {
                let tau = origin + (i as f64 + 0.5) * spacing;
                (-0.5 * (tau / sigma).powi(2)).exp()
            })
            .collect();
        let total: f64 = w.iter().sum();
        Ok(Self { origin, spacing, weights: w.into_iter().map(|v| v / total).collect() })
    }

    /// The capture's own timing response, from its direct reflection off the wall.
    ///
    /// A confocal capture whose time zero is calibrated on the wall (path lengths exclude the device legs)
    /// records the laser spot itself at path 0: that return is the system's impulse response — laser pulse,
    /// SPAD jitter and its diffusion tail, electronics — as measured with this capture, which a separate
    /// jitter file may not be (the 40 cm resolution chart's return falls to half in 11 mm of path and keeps
    /// 5 % of its peak 120 mm later; the shared SPAD response falls to half in 7 mm). The response is the
    /// summed histogram from the start of the axis to the end of the direct light
    /// ([`Transient::direct_light_end`]), minus the background floor (the median of the summed histogram
    /// over the last 5 % of the axis), with zero delay at its maximum (the convention of [`Self::load`]).
    ///
    /// **A rising side the capture cut off.** Pre-rectified captures (the Stanford LCT data: "the direct
    /// component starts at the first time bin") begin at the direct return's maximum, so the light that
    /// reaches the sensor before the peak is not in the response. A fit through a response without it cannot
    /// make light arrive before a surface's own path, and explains the early rise of every hidden return with
    /// surface nearer the wall: a flat plane fitted to the 40 cm chart's counts was best at 0.401 m through
    /// the cut response and at 0.404–0.407 m with a Gaussian rise of 3–7.4 bins, whose Poisson deviance was
    /// lower by 2 % at every width (`complete_rising_side`). So when fewer than two bins precede the maximum,
    /// the top of the return (the bins from the maximum on that stay above 80 % of it) is fitted with a
    /// Gaussian (a parabola through their logarithms); the bins before the axis are filled with it down to
    /// three standard deviations before its centre, and zero delay is put at its centre.
    ///
    /// # Errors
    /// [`TransientError::InvalidValue`] (field `direct return`) when the capture holds no direct reflection
    /// before its first hidden return (a simulation, or a capture already gated), or when nothing is left
    /// above the floor.
    pub fn from_direct_return(t: &Transient) -> Result<Self> {
        let ax = *t.time();
        let summed = t.summed_histogram();
        let no_direct = |reason: String| invalid("direct return", reason);
        let end_path = t.direct_light_end();
        let end = ((end_path - ax.t0) / ax.bin_width).floor().max(0.0) as usize;
        let head = (ax.bins / 10).max(1);
        let peak = summed[..head].iter().enumerate().fold(0, |b, (i, &v)| if v > summed[b] { i } else { b });
        if end <= peak + 1 || end > ax.bins {
            return Err(no_direct(format!(
                "no direct reflection off the wall at the start of the axis (the direct light ends at {end_path:.4} \
                 m of path, bin {end}; the first 10 % of the axis peaks at bin {peak}): a simulation, or a capture \
                 already gated, has no response to take"
            )));
        }
        let edge = (ax.bins / 20).max(1);
        let floor = median(&summed[ax.bins - edge..]);
        let counts: Vec<f64> = summed[..end].iter().map(|&c| (c - floor).max(0.0)).collect();
        if counts[peak] <= 0.0 {
            return Err(no_direct(format!(
                "the direct return's peak ({}) is not above the floor ({floor})",
                summed[peak]
            )));
        }
        let (counts, zero) = complete_rising_side(counts, peak);
        Self::from_histogram(-zero * ax.bin_width, ax.bin_width, &counts, false)
    }

    /// A timing response taken from the capture's first strong hidden return, for a capture without a
    /// direct reflection to take it from ([`Self::from_direct_return`]): one gated before it reached us
    /// ([`Transient::zero_gate`]).
    ///
    /// Each measurement's histogram after the direct light ([`Transient::direct_light_end`]) is smoothed
    /// with a box of `w = max(1, 6 mm/Δ)` bins; its first return's peak is the first local maximum of the
    /// smoothed histogram at or above half its largest value. The 5 % of measurements whose peak holds
    /// the most counts are aligned at their peaks and summed from 36 mm of path before to 150 mm after
    /// it (the diffusion tail of the Stanford SPAD keeps 5 % of its peak 120 mm after it; the next return
    /// of a scene is rarely that close behind its first), the background per bin
    /// ([`crate::sensor::estimate_background`], [`crate::sensor::BackgroundWindow::Auto`]) is subtracted,
    /// and zero delay is put at the summed peak.
    ///
    /// What this response holds besides the sensor's is the geometry of the first surface around each
    /// spot's nearest point: a patch facing the wall spreads its return over a few millimetres of path
    /// (a stroke 5 cm wide at 0.6 m: about 1 mm; 20 cm along it: about 16 mm on the late side). The fit
    /// through it therefore explains the sensor's tail and a little of that spread; the peak, where the
    /// depth is read, is the surface's. Given a surface close to the scene's,
    /// [`JitterResponse::from_first_return_deconvolved`] takes that spread out.
    ///
    /// # Errors
    /// [`TransientError::InvalidValue`] (field `first return`) when no measurement has light after the
    /// direct light, or nothing is left above the background.
    pub fn from_first_return(t: &Transient) -> Result<Self> {
        let ax = *t.time();
        let no_return = |reason: String| invalid("first return", reason);
        let FirstReturns { start, before, after, peaks } = FirstReturns::strongest(t)?;
        let background =
            crate::sensor::estimate_background(t, crate::sensor::BackgroundWindow::Auto).map_or(0.0, |e| e.per_bin);
        let mut counts = vec![0.0f64; before + 1 + after];
        let mut used = vec![0usize; counts.len()];
        for &(_, m, p) in &peaks {
            let h = t.histogram(m);
            for (i, c) in counts.iter_mut().enumerate() {
                let Some(k) = (p + i).checked_sub(before).filter(|&k| k < ax.bins && k >= start) else { continue };
                *c += f64::from(h[k]) - background;
                used[i] += 1;
            }
        }
        // Each offset averaged over the measurements that reach it (a peak near the axis's ends reaches fewer).
        let counts: Vec<f64> =
            counts.iter().zip(&used).map(|(&c, &n)| if n > 0 { (c / n as f64).max(0.0) } else { 0.0 }).collect();
        let peak = counts.iter().enumerate().fold(0, |b, (i, &v)| if v > counts[b] { i } else { b });
        if counts[peak] <= 0.0 {
            return Err(no_return(format!(
                "the strongest returns hold nothing above the background ({background} per bin)"
            )));
        }
        Self::from_histogram(-(peak as f64) * ax.bin_width, ax.bin_width, &counts, false)
    }

    /// Delay (metres of path) at the start of sample 0.
    pub fn origin(&self) -> f64 {
        self.origin
    }

    /// Sample spacing, metres of path.
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// The normalised sample masses (`Σ = 1`).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Mean delay `Σ_i w_i · τ_i` (sample centres), metres of path.
    pub fn mean_delay(&self) -> f64 {
        self.weights.iter().enumerate().map(|(i, w)| w * (self.origin + (i as f64 + 0.5) * self.spacing)).sum()
    }

    /// Full width at half maximum, metres of path: the distance between the two half-maximum crossings
    /// of the sampled response (sample values at their centres, crossings located by linear interpolation
    /// between neighbouring samples, searched outwards from the maximum).
    pub fn fwhm(&self) -> f64 {
        let w = &self.weights;
        let peak = w.iter().enumerate().fold(0, |b, (i, &v)| if v > w[b] { i } else { b });
        let half = 0.5 * w[peak];
        // Left crossing: last i < peak with w[i] < half; interpolate between i and i+1.
        let left = (0..peak).rev().find(|&i| w[i] < half).map_or(0.0, |i| {
            i as f64 + (half - w[i]) / (w[i + 1] - w[i]) // w[i+1] ≥ half > w[i], so no division by 0
        });
        let right = (peak + 1..w.len())
            .find(|&i| w[i] < half)
            .map_or((w.len() - 1) as f64, |i| (i - 1) as f64 + (w[i - 1] - half) / (w[i - 1] - w[i]));
        (right - left) * self.spacing
    }

    /// [`JitterResponse::fwhm`] in picoseconds (`FWHM / c`).
    pub fn fwhm_ps(&self) -> f64 {
        self.fwhm() / SPEED_OF_LIGHT * 1e12
    }

    /// The response resampled onto transient bins of width `bin_width` (metres of path), conserving its
    /// integral exactly: `K[d] = ∫ h(τ)·tent(τ/Δ − d) dτ` (see the [module docs](self)).
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when `bin_width` is not finite and positive, or when the
    /// response spans more than 10⁷ bins (a bin width far too small for this response).
    pub fn to_bins(&self, bin_width: f64) -> Result<BinKernel> {
        if !(bin_width.is_finite() && bin_width > 0.0) {
            return Err(arg("bin_width", format!("{bin_width} must be finite and > 0 (metres of path)")));
        }
        let s_lo = self.origin / bin_width;
        let s_hi = (self.origin + self.weights.len() as f64 * self.spacing) / bin_width;
        // Guard: checked in f64 before any cast, so a tiny bin width cannot overflow the bin indices.
        if !(s_hi - s_lo <= 1e7 && s_lo.abs() <= 1e12 && s_hi.abs() <= 1e12) {
            return Err(arg("bin_width", format!("{bin_width} m makes the response span {} bins", s_hi - s_lo)));
        }
        let first = s_lo.floor() as i64 - 1;
        let last = s_hi.ceil() as i64 + 1;
        let len = (last - first + 1) as usize;
        let mut k = vec![0.0f64; len];
        let ds = self.spacing / bin_width;
        for (i, &w) in self.weights.iter().enumerate() {
            if w == 0.0 {
                continue;
            }
            let sa = s_lo + i as f64 * ds;
            let sb = sa + ds;
            let d0 = sa.floor() as i64 - 1;
            let d1 = sb.ceil() as i64 + 1;
            for d in d0..=d1 {
                let frac = (tent_cdf(sb - d as f64) - tent_cdf(sa - d as f64)) / ds;
                let idx = d - first;
                if frac > 0.0 && (0..len as i64).contains(&idx) {
                    k[idx as usize] += w * frac;
                }
            }
        }
        // Renormalise the rounding residue (Σ is 1 analytically) and drop exact-zero ends.
        let total: f64 = k.iter().sum();
        let lo = k.iter().position(|&v| v > 0.0).unwrap_or(0);
        let hi = k.iter().rposition(|&v| v > 0.0).unwrap_or(lo);
        let weights = k[lo..=hi].iter().map(|v| v / total).collect();
        Ok(BinKernel { first: first + lo as i64, weights })
    }
}

/// Fewest bins before a direct return's maximum for its rising side to count as recorded.
const MIN_RISE_BINS: usize = 2;
/// The bins of a return's top: those from the maximum on that stay above this fraction of it.
const TOP_FRACTION: f64 = 0.8;
/// At most this many bins of the top are fitted (a flat top of a slow return would otherwise run on).
const MAX_TOP_BINS: usize = 32;
/// Widest Gaussian that completes a rising side, in bins: four times the most bins of a top.
const MAX_SIGMA_BINS: f64 = 4.0 * MAX_TOP_BINS as f64;

/// A direct return whose rising side the axis cut off ([`JitterResponse::from_direct_return`]), completed.
///
/// `counts` is the floor-free return and `peak` its maximum. When at least [`MIN_RISE_BINS`] bins precede the
/// maximum the return is whole: it comes back unchanged with zero delay at the maximum's centre. Otherwise
/// the top (the bins `peak..` above [`TOP_FRACTION`] of the maximum, at least 3, at most [`MAX_TOP_BINS`]) is
/// fitted by least squares with `ln c(x) = a + b x + q x²` (`x` in bins from the maximum's centre): a Gaussian
/// of centre `μ = −b/2q` (held at or before the maximum's centre) and deviation `σ = √(−1/2q)`. Bins are put
/// before the axis down to `μ − 3σ` and filled with that Gaussian, the recorded bins kept as they are.
/// Returns the histogram and the position of zero delay in bins from its start (the Gaussian's centre).
/// A top that does not curve down (`q ≥ 0`, or fewer than 3 bins above 80 %), or one flatter than a Gaussian of
/// [`MAX_SIGMA_BINS`], is not completed.
pub(crate) fn complete_rising_side(counts: Vec<f64>, peak: usize) -> (Vec<f64>, f64) {
    let whole = (counts, peak as f64 + 0.5);
    if peak >= MIN_RISE_BINS {
        return whole;
    }
    let top = whole.0[peak];
    let n = whole.0[peak..].iter().take(MAX_TOP_BINS).take_while(|&&c| c >= TOP_FRACTION * top).count();
    if n < 3 {
        return whole;
    }
    // Normal equations of the quadratic fit in x = 0..n−1 (the bins' centres from the maximum's): Caruana's
    // Gaussian fit, a least-squares parabola through the logarithms (Caruana, Searle & Shupe, Anal. Chem.
    // 58, 1986).
    let (mut m, mut r) = (glam::DMat3::ZERO, glam::DVec3::ZERO);
    for (i, &c) in whole.0[peak..peak + n].iter().enumerate() {
        let x = i as f64;
        let p = glam::DVec3::new(1.0, x, x * x);
        m += glam::DMat3::from_cols(p * p.x, p * p.y, p * p.z);
        r += p * c.ln();
    }
    let det = m.determinant();
    if det.is_nan() || det.abs() <= 1e-12 {
        return whole;
    }
    let glam::DVec3 { x: a, y: b, z: q } = m.inverse() * r;
    // A top that does not curve down (or a NaN from a degenerate fit) has no Gaussian to complete; nor has one
    // so flat that its 3σ would run past MAX_SIGMA_BINS (a plateau, not a peak: nothing to mirror).
    if q.is_nan() || q >= 0.0 || (-0.5 / q).sqrt() > MAX_SIGMA_BINS {
        return whole;
    }
    let sigma = (-0.5 / q).sqrt();
    let mu = (-b / (2.0 * q)).min(0.0);
    // Bins before the axis: down to μ − 3σ, in absolute bins (the maximum's centre at peak + ½).
    let start = (peak as f64 + 0.5 + mu - 3.0 * sigma).floor();
    let before = (-start).max(0.0) as usize;
    // The fitted maximum's height, at the (held) centre.
    let top_ln = a - b * b / (4.0 * q);
    let gaussian = |x: f64| (top_ln + q * (x - mu) * (x - mu)).exp();
    let mut out: Vec<f64> = (0..before).map(|j| gaussian(j as f64 - before as f64 - peak as f64)).collect();
    out.extend(whole.0);
    (out, before as f64 + peak as f64 + 0.5 + mu)
}

/// Antiderivative of `tent(x) = max(0, 1 − |x|)`: 0 below −1, `(x+1)²/2` on [−1, 0), `1 − (1−x)²/2` on
/// [0, 1), 1 above.
fn tent_cdf(x: f64) -> f64 {
    if x <= -1.0 {
        0.0
    } else if x < 0.0 {
        0.5 * (x + 1.0) * (x + 1.0)
    } else if x < 1.0 {
        1.0 - 0.5 * (1.0 - x) * (1.0 - x)
    } else {
        1.0
    }
}

/// A timing response on transient bins: `K[d]` for `d = first, first+1, …` (`Σ K = 1`), the linear
/// operator `A` of the sensor's temporal response. See the [module docs](self).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BinKernel {
    first: i64,
    weights: Vec<f64>,
}

impl BinKernel {
    /// A kernel from explicit weights: `K[first + i] = weights[i]` (not renormalised).
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] for empty, negative or non-finite weights.
    pub fn new(first: i64, weights: Vec<f64>) -> Result<Self> {
        if weights.is_empty() || weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(arg("weights", "a kernel needs at least one weight, all finite and ≥ 0".into()));
        }
        Ok(Self { first, weights })
    }

    /// The identity (an ideal sensor without jitter): `K[0] = 1`.
    pub fn identity() -> Self {
        Self { first: 0, weights: vec![1.0] }
    }

    /// The offset (in bins) of the first weight.
    pub fn first(&self) -> i64 {
        self.first
    }

    /// The weights `K[first..]`.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    fn check(&self, len: usize, bins: usize, out: usize) -> Result<()> {
        if bins == 0 || !len.is_multiple_of(bins) {
            return Err(arg("bins", format!("{len} values do not split into histograms of {bins} bins")));
        }
        if out != len {
            return Err(arg("out", format!("output holds {out} values, input {len}")));
        }
        Ok(())
    }

    /// `out = A x` per histogram of `bins` bins: `(A x)[k] = Σ_d K[d]·x[k − d]` (f64 accumulation).
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when `x.len()` is not a multiple of `bins` or `out` differs in
    /// length.
    pub fn apply_f64(&self, x: &[f64], bins: usize, out: &mut [f64]) -> Result<()> {
        self.check(x.len(), bins, out.len())?;
        for (xh, oh) in x.chunks_exact(bins).zip(out.chunks_exact_mut(bins)) {
            oh.fill(0.0);
            for (i, &w) in self.weights.iter().enumerate() {
                let d = self.first + i as i64;
                // k − d ∈ [0, bins) ⇔ k ∈ [d, bins + d)
                let k0 = d.max(0) as usize;
                let k1 = (bins as i64 + d).min(bins as i64);
                for k in k0..k1.max(k0 as i64) as usize {
                    oh[k] += w * xh[(k as i64 - d) as usize];
                }
            }
        }
        Ok(())
    }

    /// `(A x)[k]` for the bins `k` in `window` of one histogram `x` (`window` clamped to it), summed in the
    /// same order as [`BinKernel::apply_f64`], so the values are bit-identical to the whole row's: what a
    /// data term over a few bins needs without convolving the whole histogram.
    pub fn apply_window(&self, x: &[f32], window: std::ops::Range<usize>) -> Vec<f64> {
        let bins = x.len() as i64;
        let (lo, hi) = (window.start.min(x.len()), window.end.min(x.len()));
        (lo..hi.max(lo))
            .map(|k| {
                // Weight i reads x[k − first − i]: inside the row for i ∈ [k − first − bins + 1, k − first].
                let top = k as i64 - self.first;
                let i0 = (top - bins + 1).max(0) as usize;
                let i1 = (top + 1).clamp(0, self.weights.len() as i64) as usize;
                let mut acc = 0.0;
                for i in i0..i1.max(i0) {
                    acc += self.weights[i] * f64::from(x[(top - i as i64) as usize]);
                }
                acc
            })
            .collect()
    }

    /// `out = Aᵀ y` per histogram: `(Aᵀ y)[j] = Σ_d K[d]·y[j + d]`.
    ///
    /// # Errors
    /// As [`BinKernel::apply_f64`].
    pub fn adjoint_f64(&self, y: &[f64], bins: usize, out: &mut [f64]) -> Result<()> {
        self.check(y.len(), bins, out.len())?;
        for (yh, oh) in y.chunks_exact(bins).zip(out.chunks_exact_mut(bins)) {
            oh.fill(0.0);
            for (i, &w) in self.weights.iter().enumerate() {
                let d = self.first + i as i64;
                // j + d ∈ [0, bins) ⇔ j ∈ [−d, bins − d)
                let j0 = (-d).max(0) as usize;
                let j1 = (bins as i64 - d).min(bins as i64);
                for j in j0..j1.max(j0 as i64) as usize {
                    oh[j] += w * yh[(j as i64 + d) as usize];
                }
            }
        }
        Ok(())
    }

    /// `A x` for `f32` data (a transient's layout), accumulated in `f64`.
    ///
    /// # Errors
    /// As [`BinKernel::apply_f64`].
    pub fn apply(&self, x: &[f32], bins: usize) -> Result<Vec<f32>> {
        let xd: Vec<f64> = x.iter().map(|&v| f64::from(v)).collect();
        let mut out = vec![0.0; xd.len()];
        self.apply_f64(&xd, bins, &mut out)?;
        Ok(out.into_iter().map(|v| v as f32).collect())
    }

    /// `Aᵀ y` for `f32` data, accumulated in `f64`.
    ///
    /// # Errors
    /// As [`BinKernel::apply_f64`].
    pub fn adjoint(&self, y: &[f32], bins: usize) -> Result<Vec<f32>> {
        let yd: Vec<f64> = y.iter().map(|&v| f64::from(v)).collect();
        let mut out = vec![0.0; yd.len()];
        self.adjoint_f64(&yd, bins, &mut out)?;
        Ok(out.into_iter().map(|v| v as f32).collect())
    }
}

/// The strongest first hidden returns of a capture ([`JitterResponse::from_first_return`]): each
/// measurement's histogram after the direct light ([`Transient::direct_light_end`]) smoothed with a box of
/// `w = max(1, 6 mm/Δ)` bins, its first return's peak the first local maximum at or above half its largest
/// value, and the 5 % of measurements whose peak holds the most counts kept.
pub(crate) struct FirstReturns {
    /// First bin searched (the direct light's end).
    pub start: usize,
    /// Bins kept before each peak (36 mm of path).
    pub before: usize,
    /// Bins kept after each peak (150 mm of path).
    pub after: usize,
    /// (peak counts of the smoothed histogram, measurement, peak bin), strongest first.
    pub peaks: Vec<(f64, usize, usize)>,
}

impl FirstReturns {
    /// # Errors
    /// [`TransientError::InvalidValue`] (field `first return`) when no measurement has light after the
    /// direct light.
    pub fn strongest(t: &Transient) -> Result<Self> {
        let ax = *t.time();
        let start = (((t.direct_light_end() - ax.t0) / ax.bin_width).ceil().max(0.0) as usize).min(ax.bins);
        let w = ((0.006 / ax.bin_width).round() as usize).max(1);
        let before = ((0.036 / ax.bin_width).round() as usize).max(2);
        let after = ((0.150 / ax.bin_width).round() as usize).max(4);
        let mut peaks: Vec<(f64, usize, usize)> = t
            .histograms()
            .enumerate()
            .filter_map(|(m, h)| {
                let h = &h[start..];
                if h.len() < 2 * w + 1 {
                    return None;
                }
                let mut acc: f64 = h[..w].iter().map(|&v| f64::from(v)).sum();
                let mut smooth = vec![0.0; h.len() - w + 1];
                for k in 0..smooth.len() {
                    if k > 0 {
                        acc += f64::from(h[k + w - 1]) - f64::from(h[k - 1]);
                    }
                    smooth[k] = acc / w as f64;
                }
                let top = smooth.iter().copied().fold(0.0f64, f64::max);
                let first = smooth.iter().position(|&v| v >= 0.5 * top)?;
                let peak = (first..smooth.len()).find(|&k| k + 1 == smooth.len() || smooth[k + 1] < smooth[k])?;
                // The box covers bins [peak, peak + w): its centre is the peak's bin.
                (top > 0.0).then_some((smooth[peak], m, start + peak + w / 2))
            })
            .collect();
        if peaks.is_empty() {
            return Err(invalid(
                "first return",
                format!("no measurement has light after the direct light (from bin {start})"),
            ));
        }
        peaks.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        peaks.truncate((peaks.len() / 20).max(1));
        Ok(Self { start, before, after, peaks })
    }
}
