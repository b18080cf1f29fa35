//! Corrections for real SPAD captures: Coates' pile-up correction and background estimation.
//!
//! ## Coates' correction (Coates 1968)
//! In the synchronous first-photon model (see the [sensor docs](super)), `D_k = N − Σ_{j<k} n_j` cycles
//! are still undetected when bin `k` opens, and each is detected in bin `k` with probability
//! `1 − e^{−λ_k}`. The maximum-likelihood estimate of the per-cycle flux is therefore
//!
//! `λ̂_k = −ln(1 − n_k / D_k)`,
//!
//! and `N·λ̂_k` is what an ideal (pile-up-free) counter would have recorded on average. Background is
//! still included; subtract an [`estimate_background`] of the *corrected* histogram.
//!
//! ## Background
//! Bins before the first return hold only dark counts and ambient light, a constant `b` per bin. Its
//! estimate is the mean of those bins (unbiased for Poisson counts); the median over measurements of
//! the per-measurement means is also reported, robust to hot or stray-light pixels.

use crate::error::{Result, TransientError};
use crate::ops::median;
use crate::transient::Transient;

fn bad(name: &'static str, reason: String) -> TransientError {
    TransientError::InvalidArgument { name, reason }
}

/// Coates' correction of one histogram of counts over `cycles` laser cycles: returns
/// `N·λ̂_k = −N·ln(1 − n_k/D_k)`, `D_k = N − Σ_{j<k} n_j`.
///
/// Guard: when every remaining cycle was detected in bin `k` (`n_k = D_k`) the estimate is infinite; the
/// ratio is capped at `1 − 1/(2·D_k)` (half a cycle left undetected), and bins after all cycles are used
/// up get 0.
///
/// # Errors
/// [`TransientError::InvalidArgument`] when `cycles` is not finite and ≥ 1, a count is negative or not
/// finite, or the counts add up to more than `cycles` (the cycle count is wrong, or afterpulses dominate).
pub fn coates_histogram(counts: &[f64], cycles: f64) -> Result<Vec<f64>> {
    if !(cycles.is_finite() && cycles >= 1.0) {
        return Err(bad("cycles", format!("{cycles} must be finite and ≥ 1 (laser cycles per measurement)")));
    }
    if let Some(i) = counts.iter().position(|c| !(c.is_finite() && *c >= 0.0)) {
        return Err(bad("counts", format!("bin {i} holds {}; counts are finite and ≥ 0", counts[i])));
    }
    let total: f64 = counts.iter().sum();
    if total > cycles {
        return Err(bad(
            "cycles",
            format!("{total} counts exceed {cycles} cycles: at most one detection per cycle in this model"),
        ));
    }
    let mut remaining = cycles;
    Ok(counts
        .iter()
        .map(|&n| {
            if remaining <= 0.0 {
                return 0.0;
            }
            let ratio = (n / remaining).min(1.0 - 0.5 / remaining);
            remaining -= n;
            // −ln1p(−r) = −ln(1 − r) without cancellation at small r.
            -cycles * (-ratio).ln_1p()
        })
        .collect())
}

/// [`coates_histogram`] applied to every measurement of a count capture.
///
/// # Errors
/// As [`coates_histogram`].
pub fn coates_correction(counts: &Transient, cycles: f64) -> Result<Transient> {
    let mut data = Vec::with_capacity(counts.data().len());
    for h in counts.histograms() {
        let hd: Vec<f64> = h.iter().map(|&v| f64::from(v)).collect();
        data.extend(coates_histogram(&hd, cycles)?.into_iter().map(|v| v as f32));
    }
    Transient::new(counts.scan().clone(), *counts.time(), data)
}

/// Which bins hold background only.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum BackgroundWindow {
    /// The bins before the first return of the summed histogram (the direct light when it is on the
    /// axis, else the first hidden-scene return). The summed histogram is smoothed with a box of
    /// `w = max(1, 6 mm/Δ)` bins; the return's onset is the first bin above
    /// `min + 10 %·(max − min)` of the smoothed signal; the window is `[0, onset − 3w)`, the margin
    /// keeping the rising edge (jitter, smoothing) out. On a capture gated before it reached us
    /// ([`Transient::zero_gate`]) the window and the search start after the zeroed bins.
    BeforeFirstReturn,
    /// On a capture gated before it reached us ([`Transient::zero_gate`]): the later half of the bins from
    /// where what the gate left of the direct light's diffusion tail has fallen to within 2 % of the range
    /// above the minimum, to the first hidden return (its onset found as above, at 2 % instead of 10 %: the
    /// return's foot is not background either), when they are at least 32 — the tail's end still sits above
    /// the floor. Otherwise
    /// [`BackgroundWindow::BeforeFirstReturn`] when it holds at least 16 bins; otherwise, on a capture
    /// cropped to start inside its direct light (the Stanford LCT `.mat` files), the same later half of the
    /// quiet bins as on a gated capture, searched from where the direct light has fallen to the level of the
    /// strongest hidden return (after [`Transient::direct_light_end`]): the raw capture and its gated
    /// version read the same bins; otherwise [`BackgroundWindow::AxisEnd`], assuming the axis runs past the
    /// last return. [`BackgroundEstimate::window`] tells which was used.
    Auto,
    /// The last 10 % of the axis (at least one bin). Background only when the axis runs well past the last
    /// return; on a capture whose returns reach the end of the axis it also holds their late light, which
    /// is what the sensor fit's floor wants (`nlos_optim`'s pipeline on gated captures).
    AxisEnd,
    /// Bins `[start, end)`.
    Bins {
        /// First bin.
        start: usize,
        /// One past the last bin.
        end: usize,
    },
    /// The bins lying entirely within path lengths `[start, end)` metres (e.g. starting at
    /// [`Transient::direct_light_end`] on a capture whose hidden returns come later).
    Path {
        /// Start, metres of path.
        start: f64,
        /// End, metres of path.
        end: f64,
    },
}

/// A background estimate: expected counts per bin.
#[derive(Debug, Clone, PartialEq)]
pub struct BackgroundEstimate {
    /// Mean of all window bins over all measurements (unbiased for Poisson counts).
    pub per_bin: f64,
    /// Standard error of `per_bin` (sample standard deviation of the window bins over √count).
    pub std_error: f64,
    /// Median over measurements of the per-measurement means (robust to hot pixels).
    pub per_bin_median: f64,
    /// Per-measurement mean of the window bins.
    pub per_measurement: Vec<f64>,
    /// The window used, bins `[start, end)`.
    pub window: (usize, usize),
}

fn window_bins(t: &Transient, window: BackgroundWindow) -> Result<(usize, usize)> {
    let ax = t.time();
    let (s, e) = match window {
        BackgroundWindow::Bins { start, end } => (start, end),
        BackgroundWindow::Path { start, end } => {
            if !(start.is_finite() && end.is_finite()) {
                return Err(bad("window", format!("[{start}, {end}) is not finite")));
            }
            let s = ((start - ax.t0) / ax.bin_width).ceil().max(0.0);
            let e = ((end - ax.t0) / ax.bin_width).floor().clamp(0.0, ax.bins as f64);
            (s.min(ax.bins as f64) as usize, e as usize)
        }
        BackgroundWindow::Auto => {
            // A capture gated before it reached us: the later half of the bins between its gate and the first
            // hidden return (the first half holds what the gate left of the direct light's tail).
            let later_half = |start: usize| {
                let (s, e) = quiet_bins(t, start, 0.02, true);
                (e >= s + 32).then_some((s + (e - s) / 2, e))
            };
            if let Some(window) = t.zero_gate().and_then(later_half) {
                return Ok(window);
            }
            return match window_bins(t, BackgroundWindow::BeforeFirstReturn) {
                Ok((s, e)) if e - s >= 16 => Ok((s, e)),
                _ => match direct_tail_start(t).and_then(later_half) {
                    Some(window) => Ok(window),
                    None => window_bins(t, BackgroundWindow::AxisEnd),
                },
            };
        }
        BackgroundWindow::AxisEnd => (ax.bins - (ax.bins / 10).max(1), ax.bins),
        BackgroundWindow::BeforeFirstReturn => quiet_bins(t, t.zero_gate().unwrap_or(0), 0.1, false),
    };
    if s >= e || e > ax.bins {
        return Err(bad(
            "window",
            format!(
                "background window [{s}, {e}) of {} bins is empty or outside the axis; pass an explicit \
                 window of bins that hold background only",
                ax.bins
            ),
        ));
    }
    Ok((s, e))
}

/// On a capture without a gate whose direct light is on the axis: the first bin after the direct light's
/// peak (the smoothed summed histogram's maximum in the first 10 % of the axis) at which the smoothed
/// histogram has fallen to the strongest hidden return's level (its maximum after
/// [`Transient::direct_light_end`]). From there on the direct light's tail is no stronger than the hidden
/// returns, so [`quiet_bins`] can skip the rest of it as it does after a gate. `None` without direct light.
fn direct_tail_start(t: &Transient) -> Option<usize> {
    let ax = t.time();
    let end = ((t.direct_light_end() - ax.t0) / ax.bin_width).round();
    // Guard: `direct_light_end` returns the axis start when it finds no direct light (a NaN is none either).
    if t.zero_gate().is_some() || end.is_nan() || end < 1.0 {
        return None;
    }
    let end = (end as usize).min(ax.bins - 1);
    let h = t.summed_histogram();
    let w = ((0.006 / ax.bin_width).round() as usize).clamp(1, ax.bins);
    // The smoothing `direct_light_end` applies, so that both read the same curve.
    let smooth = crate::ops::box_smooth(&h, w);
    let hidden = smooth[end..].iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let head = (ax.bins / 10).max(1).min(end);
    let peak = (0..head).fold(0, |b, k| if smooth[k] > smooth[b] { k } else { b });
    (peak..end).find(|&k| smooth[k] <= hidden)
}

/// Bins `[start, onset − 3w)`: from `start` to the first return after it (the summed histogram smoothed with
/// a trailing box of `w = max(1, 6 mm/Δ)` bins; the onset is the first bin above `min + fraction·(max − min)`
/// of the smoothed bins from `start` on; the margin keeps the rising edge out). Empty when the return
/// comes first. With `skip_leading`, bins above the threshold at `start` (a falling tail) are skipped: the
/// window starts where the smoothed histogram first falls to the threshold, and the onset is searched after.
fn quiet_bins(t: &Transient, start: usize, fraction: f64, skip_leading: bool) -> (usize, usize) {
    let ax = t.time();
    let h = &t.summed_histogram()[start..];
    let w = ((0.006 / ax.bin_width).round() as usize).clamp(1, ax.bins);
    let mut smooth = vec![0.0; h.len()];
    let mut acc = 0.0;
    for k in 0..h.len() {
        acc += h[k];
        if k >= w {
            acc -= h[k - w];
        }
        smooth[k] = acc / (k + 1).min(w) as f64;
    }
    let lo = smooth.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = smooth.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let thr = lo + fraction * (hi - lo);
    // Light already above the threshold at `start` (what a gate left of the direct light) is not the return.
    let quiet = if skip_leading { smooth.iter().position(|&v| v <= thr).unwrap_or(0) } else { 0 };
    let onset = smooth[quiet..].iter().position(|&v| v > thr).map_or(0, |k| quiet + k);
    // The trailing box puts the smoothed rise up to w bins late relative to its centre; 3w covers it.
    (start + quiet, start + onset.saturating_sub(3 * w).max(quiet))
}

/// Estimates the background (expected counts per bin) from bins that hold no signal.
///
/// # Errors
/// [`TransientError::InvalidArgument`] when the window is empty, outside the axis, not finite, or (for
/// [`BackgroundWindow::BeforeFirstReturn`]) when no bins precede the first return.
pub fn estimate_background(t: &Transient, window: BackgroundWindow) -> Result<BackgroundEstimate> {
    let (s, e) = window_bins(t, window)?;
    let n = (e - s) as f64;
    let per_measurement: Vec<f64> =
        t.histograms().map(|h| h[s..e].iter().map(|&v| f64::from(v)).sum::<f64>() / n).collect();
    let count = n * per_measurement.len() as f64;
    let per_bin = per_measurement.iter().sum::<f64>() * n / count;
    let ss: f64 = t.histograms().flat_map(|h| h[s..e].iter()).map(|&v| (f64::from(v) - per_bin).powi(2)).sum();
    // Guard: a single window bin has no spread to estimate.
    let std_error = if count > 1.0 { (ss / (count - 1.0)).sqrt() / count.sqrt() } else { f64::NAN };
    Ok(BackgroundEstimate {
        per_bin,
        std_error,
        per_bin_median: median(&per_measurement),
        per_measurement,
        window: (s, e),
    })
}

/// Whether every value is a non-negative integer: the capture looks like raw photon counts (what
/// [`CountSummary::integer_counts`] reports and `nlos reconstruct --noise auto` detects).
pub fn is_integer_counts(data: &[f32]) -> bool {
    data.iter().all(|&v| v >= 0.0 && v.fract() == 0.0)
}

/// Photon counts of a capture, split into background and signal.
#[derive(Debug, Clone, PartialEq)]
pub struct CountSummary {
    /// Σ of all bins of all measurements.
    pub total: f64,
    /// The background estimate used.
    pub background: BackgroundEstimate,
    /// Estimated background counts over the capture: `b·bins·M`.
    pub background_total: f64,
    /// `total − background_total`.
    pub signal_total: f64,
    /// `signal_total / M`.
    pub signal_per_measurement: f64,
    /// Whether every value is a non-negative integer (the capture looks like raw photon counts).
    pub integer_counts: bool,
}

/// Counts of a capture with the background estimated over `window`.
///
/// # Errors
/// As [`estimate_background`].
pub fn count_summary(t: &Transient, window: BackgroundWindow) -> Result<CountSummary> {
    let background = estimate_background(t, window)?;
    let total: f64 = t.data().iter().map(|&v| f64::from(v)).sum();
    let background_total = background.per_bin * t.data().len() as f64;
    let signal_total = total - background_total;
    Ok(CountSummary {
        total,
        background_total,
        signal_total,
        signal_per_measurement: signal_total / t.measurements() as f64,
        integer_counts: is_integer_counts(t.data()),
        background,
    })
}
