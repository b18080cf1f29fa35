//! A timing response from a capture's first returns with the scene's own spread taken out.
//!
//! ## Why
//! A capture gated before it reached us has no direct reflection to take its sensor's response from.
//! [`JitterResponse::from_first_return`] aligns its strongest first hidden returns, which hold the surface's
//! spread in path besides the sensor's blur: on Tsai et al.'s gated S and U their half width is about 54 mm
//! of path where the raw file's direct reflection gives about 10 mm, and a fit through that response puts
//! the letters 5 mm nearer than the raw file's fit does (through the raw file's own response the gated file
//! gives the raw file's depths within 2 mm).
//!
//! ## Model
//! With `g_m` a rendering of a surface close to the scene's (the start surface) for measurement `m`,
//! without sensor blur (box kernel), the measured counts around the first return are
//! ```text
//! n_m[k] ≈ Σ_j r[j] · g_m[k − j] + b,      j ∈ [−J₋, J₊]
//! ```
//! with `r` the response on the capture's bins and `b` the background per bin. `r` is the regularised least
//! squares solution (Tikhonov with a second-difference operator `D₂`; Hansen, *Rank-Deficient and Discrete
//! Ill-Posed Problems*, SIAM 1998, §5.1):
//! ```text
//! r = argmin Σ_m Σ_{k ∈ W_m} (n_m[k] − b − (r ⊛ g_m)[k])² + λ ‖D₂ r‖²,   λ = 10⁻² · tr(AᵀA) / (6 L)
//! ```
//! over the windows `W_m = [p_m − J₋, p_m + J₊]` around the strongest measurements' first peaks `p_m`
//! (picked as [`JitterResponse::from_first_return`] picks them), `L = J₋ + J₊ + 1` unknowns, solved
//! through the normal equations `(AᵀA + λ D₂ᵀD₂) r = Aᵀ(n − b)` by Cholesky. (`D₂ᵀD₂` has the trace
//! `6 (L − 2) ≈ 6 L`, so `λ` weighs the
//! smoothness at a hundredth of the data.) Negative samples are set to zero and zero delay is put at the
//! peak (the convention of [`crate::sensor::jitter`]): a start surface that lies a little off the scene
//! shifts `r` as a whole, and the shift is dropped with it. `J₋` is twice the 36 mm of path the aligned
//! response keeps before its peak, so that such a shift stays inside the support.

use crate::error::{Result, TransientError};
use crate::sensor::jitter::FirstReturns;
use crate::sensor::{BackgroundWindow, JitterResponse, estimate_background};
use crate::transient::Transient;

/// Relative weight of the second-difference penalty (module docs).
const SMOOTHNESS: f64 = 1e-2;

fn invalid(field: &str, reason: String) -> TransientError {
    TransientError::InvalidValue { file: crate::error::MEMORY.into(), field: field.into(), reason }
}

impl JitterResponse {
    /// The timing response of a capture gated before it reached us, from its strongest first hidden
    /// returns with the spread of `geometry` taken out: `geometry` renders a surface close to the scene's on
    /// the capture's scan and time axis, without sensor blur (module docs of
    /// [`crate::sensor::deconvolve`]).
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] (`geometry`) when `geometry` has another number of measurements or
    /// another time axis than `t`; [`TransientError::InvalidValue`] (field `first return`) as
    /// [`JitterResponse::from_first_return`], or when `geometry` renders no light where the strongest
    /// returns are, or the solved response holds nothing positive.
    pub fn from_first_return_deconvolved(t: &Transient, geometry: &Transient) -> Result<Self> {
        let ax = *t.time();
        if geometry.measurements() != t.measurements() || *geometry.time() != ax {
            return Err(TransientError::InvalidArgument {
                name: "geometry",
                reason: format!(
                    "{} measurements on {:?}: the capture has {} on {ax:?}; render the start on the capture's own \
                     scan and time axis",
                    geometry.measurements(),
                    geometry.time(),
                    t.measurements()
                ),
            });
        }
        let FirstReturns { start, before, after, peaks } = FirstReturns::strongest(t)?;
        let before = 2 * before;
        let n = before + 1 + after;
        let background = estimate_background(t, BackgroundWindow::Auto).map_or(0.0, |e| e.per_bin);
        // Normal equations: AᵀA (n × n, row-major) and Aᵀy.
        let (mut ata, mut aty) = (vec![0.0f64; n * n], vec![0.0f64; n]);
        let mut row = vec![0.0f64; n];
        for &(_, m, p) in &peaks {
            let (h, g) = (t.histogram(m), geometry.histogram(m));
            let (lo, hi) = (p.saturating_sub(before).max(start), (p + after + 1).min(ax.bins));
            for (k, &count) in h.iter().enumerate().take(hi).skip(lo) {
                // Row k of A: a[i] = g[k − j] with j = i − before, the delay of sample i.
                for (i, a) in row.iter_mut().enumerate() {
                    *a = (k + before).checked_sub(i).filter(|&q| q < ax.bins).map_or(0.0, |q| f64::from(g[q]));
                }
                let y = f64::from(count) - background;
                for i in 0..n {
                    if row[i] == 0.0 {
                        continue;
                    }
                    aty[i] += row[i] * y;
                    for j in i..n {
                        ata[i * n + j] += row[i] * row[j];
                    }
                }
            }
        }
        let trace: f64 = (0..n).map(|i| ata[i * n + i]).sum();
        if trace.is_nan() || trace <= 0.0 {
            return Err(invalid(
                "first return",
                "the start surface renders no light around the strongest first returns: nothing to take its spread \
                 out of"
                    .into(),
            ));
        }
        // λ D₂ᵀD₂ (second differences of r over its support).
        let lambda = SMOOTHNESS * trace / (6.0 * n as f64);
        for c in 0..n.saturating_sub(2) {
            let d = [(c, 1.0), (c + 1, -2.0), (c + 2, 1.0)];
            for &(i, a) in &d {
                for &(j, b) in &d {
                    if j >= i {
                        ata[i * n + j] += lambda * a * b;
                    }
                }
            }
        }
        let r = cholesky_solve(&mut ata, n, aty)
            .ok_or_else(|| invalid("first return", "the normal equations are not positive definite".into()))?;
        let r: Vec<f64> = r.into_iter().map(|v| v.max(0.0)).collect();
        let peak = r.iter().enumerate().fold(0, |b, (i, &v)| if v > r[b] { i } else { b });
        if r[peak] <= 0.0 {
            return Err(invalid("first return", "the deconvolved response holds nothing positive".into()));
        }
        Self::from_histogram(-(peak as f64) * ax.bin_width, ax.bin_width, &r, false)
    }
}

/// Solves `M x = b` for a symmetric positive definite `M` (`n × n`, row-major, upper triangle read and
/// overwritten) by Cholesky (`M = Uᵀ U`); `None` when a pivot is not positive.
fn cholesky_solve(m: &mut [f64], n: usize, mut b: Vec<f64>) -> Option<Vec<f64>> {
    for i in 0..n {
        for k in 0..i {
            let u = m[k * n + i];
            for j in i..n {
                m[i * n + j] -= u * m[k * n + j];
            }
        }
        let d = m[i * n + i];
        if !d.is_finite() || d <= 0.0 {
            return None;
        }
        let s = d.sqrt();
        for j in i..n {
            m[i * n + j] /= s;
        }
    }
    // Uᵀ z = b, then U x = z.
    for i in 0..n {
        let s: f64 = (0..i).map(|k| m[k * n + i] * b[k]).sum();
        b[i] = (b[i] - s) / m[i * n + i];
    }
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| m[i * n + k] * b[k]).sum();
        b[i] = (b[i] - s) / m[i * n + i];
    }
    Some(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;
    use crate::{PointSet, Scan, TimeAxis};

    /// The sensor of the test: a Gaussian rise (σ = 3 bins), then 85 % Gaussian fall and a 15 %
    /// exponential tail (τ = 25 bins), at `j` bins from its peak.
    fn sensor(j: f64) -> f64 {
        let g = (-0.5 * (j / 3.0).powi(2)).exp();
        if j < 0.0 { g } else { 0.85 * g + 0.15 * (-j / 25.0).exp() }
    }

    /// A gated capture (bins 0..100 zero) whose first returns spread over 20–60 bins (a surface's extent
    /// in path, different per measurement) seen through [`sensor`], with background and Poisson noise:
    /// the aligned returns are as wide as the spread; with the spread taken out, the response is the
    /// sensor's (its width within two bins, its peak at zero delay).
    #[test]
    fn the_scenes_spread_is_taken_out_of_the_first_returns() {
        let scan = Scan::confocal(PointSet::wall_grid(10, 10, 0.25, 0.25).expect("valid"));
        let bins = 700;
        let mut geometry = Vec::with_capacity(100 * bins);
        let mut counts = Vec::with_capacity(100 * bins);
        for m in 0..100 {
            let onset = 300 + m;
            let spread = 20.0 + 0.4 * m as f64;
            let g: Vec<f64> =
                (0..bins).map(|k| if k >= onset { (-((k - onset) as f64) / spread).exp() } else { 0.0 }).collect();
            let mut rng = Pcg32::new(3, m as u64);
            for k in 0..bins {
                let blurred: f64 = (-20i64..=150)
                    .filter_map(|j| {
                        usize::try_from(k as i64 - j).ok().filter(|&q| q < bins).map(|q| sensor(j as f64) * g[q])
                    })
                    .sum();
                let value = if k < 100 { 0.0 } else { rng.poisson(400.0 * blurred + 0.5) as f32 };
                counts.push(value);
            }
            geometry.extend(g.iter().map(|&v| v as f32));
        }
        let axis = TimeAxis::new(0.0, 0.0012, bins).expect("valid");
        let t = Transient::new(scan.clone(), axis, counts).expect("valid");
        assert_eq!(t.zero_gate(), Some(100));
        let geometry = Transient::new(scan, axis, geometry).expect("valid");
        let samples: Vec<f64> = (-20..=150).map(|j| sensor(f64::from(j))).collect();
        let truth = JitterResponse::from_histogram(-20.0 * 0.0012, 0.0012, &samples, false).expect("valid");
        let aligned = JitterResponse::from_first_return(&t).expect("valid");
        let taken_out = JitterResponse::from_first_return_deconvolved(&t, &geometry).expect("valid");
        let [w_truth, w_aligned, w_out] = [&truth, &aligned, &taken_out].map(|r| r.fwhm() / 0.0012);
        eprintln!("FWHM in bins: sensor {w_truth:.1}, aligned returns {w_aligned:.1}, spread taken out {w_out:.1}");
        assert!(w_aligned >= 3.0 * w_truth, "the aligned returns hold the spread: {w_aligned} bins");
        assert!((w_out - w_truth).abs() <= 2.0, "{w_out} bins against the sensor's {w_truth}");
        // Zero delay at the peak: the largest sample's centre lies within a bin of delay 0.
        let w = taken_out.weights();
        let top = (0..w.len()).fold(0, |b, i| if w[i] > w[b] { i } else { b });
        let centre = taken_out.origin() + (top as f64 + 0.5) * taken_out.spacing();
        assert!(centre.abs() <= taken_out.spacing(), "peak at {centre} m of delay");
        // A geometry on another axis is refused, naming it.
        let other = Transient::new(
            Scan::confocal(PointSet::wall_grid(10, 10, 0.25, 0.25).expect("valid")),
            TimeAxis::new(0.0, 0.0024, bins).expect("valid"),
            vec![0.0; 100 * bins],
        )
        .expect("valid");
        let e = JitterResponse::from_first_return_deconvolved(&t, &other).expect_err("refused");
        assert!(e.to_string().contains("geometry"), "{e}");
        // A start that renders nothing there has no spread to take out.
        let dark = Transient::new(other.scan().clone(), axis, vec![0.0; 100 * bins]).expect("valid");
        assert!(JitterResponse::from_first_return_deconvolved(&t, &dark).is_err());
    }

    #[test]
    fn cholesky_solves_a_small_system() {
        // M = [[4, 2], [2, 3]], b = [2, 1] → x = [0.5, 0].
        let mut m = vec![4.0, 2.0, 2.0, 3.0];
        let x = cholesky_solve(&mut m, 2, vec![2.0, 1.0]).expect("valid");
        assert!((x[0] - 0.5).abs() < 1e-12 && x[1].abs() < 1e-12, "{x:?}");
        assert!(cholesky_solve(&mut [0.0], 1, vec![1.0]).is_none());
    }
}
