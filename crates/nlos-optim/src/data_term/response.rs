//! The sensor's timing response applied to a whole capture at the cost it needs, and the response of
//! summed bins.
//!
//! ## Why an FFT
//! A real capture's own response ([`nlos_transient::sensor::JitterResponse::from_direct_return`]) is short at
//! its core and long in its tail: the 40 cm chart's falls to half in 11 mm of path but keeps 15 % of its
//! mass beyond 100 bins of 1.2 mm and spans 652 bins in all. The sensor fit applies it (`J I`) and its
//! adjoint (`Jᵀ r`) to every histogram at every step: directly, `bins × taps` multiply-adds per histogram
//! (1,073 × 652 on the chart), which made a real capture's step about 25 times a simulated one's. The
//! convolution theorem gives the same linear convolution for `O(N log N)` per histogram with
//! `N ≥ bins + taps − 1` (realfft, zero-padded, f64): exact up to rounding, whatever the tail's shape
//! (fitting the tail with exponentials for a recursive filter would change the response). Short kernels
//! (an ideal sensor, a narrow jitter) keep the direct sum, which is cheaper below
//! [`FFT_MIN_TAPS`] taps. Rows are independent, so rayon splits them and the result does not depend on the
//! number of threads.
//!
//! ## Summed bins
//! Coarse to fine in time ([`crate::Schedule::rebin`]) sums `k` consecutive bins of the counts. With fine
//! input bins `j`, output bins `l` and `(J I)_l = Σ_j K[l − j] I_j`, the expected count of the coarse bin
//! `L` (fine bins `kL + a`, `a < k`) is `Σ_a (J I)_{kL+a}`. Taking the flux as constant inside each coarse
//! input bin `J'` (`I_{kJ'+b} = I'_{J'}/k`, which is what a rendering at the coarse bins integrates),
//! ```text
//! μ'_L = Σ_{J'} K'[L − J'] I'_{J'},   K'[D] = (1/k) Σ_{a<k} Σ_{b<k} K[kD + a − b]
//! ```
//! with `Σ K' = Σ K = 1`, and the background of a summed bin is `k·b`. The relation is exact when the flux
//! is constant inside each coarse bin and otherwise moves light by less than a coarse bin
//! (`tests::summed_response_*` measure it).

use rayon::prelude::*;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::sync::Arc;

use nlos_transient::sensor::BinKernel;

use crate::error::{OptimError, Result};

/// Below this many taps the direct sum is cheaper than the FFT (measured on 1,073-bin rows: equal cost
/// near 40 taps).
pub const FFT_MIN_TAPS: usize = 48;

/// The response `K'` of `k` summed bins for the response `kernel` on the fine bins (module docs):
/// `K'[D] = (1/k) Σ_{a<k} Σ_{b<k} K[kD + a − b]`.
///
/// # Errors
/// [`OptimError::InvalidParameter`] for `k = 0`.
pub fn summed_response(kernel: &BinKernel, k: usize) -> Result<BinKernel> {
    if k == 0 {
        return Err(OptimError::InvalidParameter {
            name: "rebin",
            value: 0.0,
            reason: "bins are summed in groups of at least one",
        });
    }
    if k == 1 {
        return Ok(kernel.clone());
    }
    let (first, w) = (kernel.first(), kernel.weights());
    let ki = k as i64;
    // Fine offset d = kD + a − b reaches D from floor((d − (k−1))/k) to floor((d + k − 1)/k).
    let d_lo = (first - (ki - 1)).div_euclid(ki);
    let d_hi = (first + w.len() as i64 - 1 + ki - 1).div_euclid(ki);
    let mut out = vec![0.0f64; (d_hi - d_lo + 1) as usize];
    for (i, &wi) in w.iter().enumerate() {
        let d = first + i as i64;
        // Pairs (a, b) with a − b = d − kD: for each D, the number of pairs with a − b = e (|e| < k) is k − |e|.
        for (slot, big_d) in out.iter_mut().zip(d_lo..=d_hi) {
            let e = d - ki * big_d;
            if e.abs() < ki {
                *slot += wi * (ki - e.abs()) as f64;
            }
        }
    }
    let inv = 1.0 / k as f64;
    let lo = out.iter().position(|&v| v > 0.0).unwrap_or(0);
    let hi = out.iter().rposition(|&v| v > 0.0).unwrap_or(lo);
    let weights = out[lo..=hi].iter().map(|v| v * inv).collect();
    BinKernel::new(d_lo + lo as i64, weights).map_err(OptimError::Sensor)
}

/// The response `J` on histograms of a fixed length, applied row by row: by FFT for long kernels, by the
/// direct sum for short ones (module docs).
#[derive(Clone)]
pub struct ResponseOp {
    kernel: BinKernel,
    bins: usize,
    fft: Option<Fft>,
}

impl std::fmt::Debug for ResponseOp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ResponseOp")
            .field("taps", &self.kernel.weights().len())
            .field("bins", &self.bins)
            .field("fft", &self.fft.as_ref().map(|f| f.n))
            .finish()
    }
}

#[derive(Clone)]
struct Fft {
    n: usize,
    forward: Arc<dyn RealToComplex<f64>>,
    inverse: Arc<dyn ComplexToReal<f64>>,
    /// The kernel's spectrum (taps from index 0), divided by `n` (realfft does not normalise).
    spectrum: Vec<Complex<f64>>,
}

/// The smallest `2^a·3^b ≥ n` (sizes realfft transforms fastest).
fn fft_size(n: usize) -> usize {
    let mut best = n.next_power_of_two();
    let mut p3 = 1usize;
    while p3 < best {
        let mut m = p3;
        while m < n {
            m *= 2;
        }
        best = best.min(m);
        p3 *= 3;
    }
    best
}

impl ResponseOp {
    /// The operator of `kernel` on histograms of `bins` bins.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for `bins = 0`.
    pub fn new(kernel: &BinKernel, bins: usize) -> Result<Self> {
        if bins == 0 {
            return Err(OptimError::InvalidParameter {
                name: "bins",
                value: 0.0,
                reason: "a histogram has at least one bin",
            });
        }
        let taps = kernel.weights().len();
        let fft = (taps >= FFT_MIN_TAPS).then(|| {
            let n = fft_size(bins + taps - 1);
            let mut planner = RealFftPlanner::<f64>::new();
            let forward = planner.plan_fft_forward(n);
            let inverse = planner.plan_fft_inverse(n);
            let mut h = forward.make_input_vec();
            let inv_n = 1.0 / n as f64;
            for (x, &w) in h.iter_mut().zip(kernel.weights()) {
                *x = w * inv_n;
            }
            let mut spectrum = forward.make_output_vec();
            // Guard: lengths come from the plan itself, so the transform cannot fail.
            let _ = forward.process(&mut h, &mut spectrum);
            Fft { n, forward, inverse, spectrum }
        });
        Ok(Self { kernel: kernel.clone(), bins, fft })
    }

    /// The kernel.
    pub fn kernel(&self) -> &BinKernel {
        &self.kernel
    }

    fn check(&self, len: usize, out: usize) -> Result<()> {
        if !len.is_multiple_of(self.bins) || out != len {
            return Err(OptimError::LengthMismatch { what: "response rows", expected: len, got: out });
        }
        Ok(())
    }

    /// `out = J x` per histogram: `(J x)[k] = Σ_i w[i]·x[k − first − i]`, as
    /// [`BinKernel::apply_f64`] up to rounding.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] when `x` does not split into histograms or `out` differs in length.
    pub fn apply(&self, x: &[f64], out: &mut [f64]) -> Result<()> {
        self.run(x, out, false)
    }

    /// `out = Jᵀ y` per histogram: `(Jᵀ y)[j] = Σ_i w[i]·y[j + first + i]`, as [`BinKernel::adjoint_f64`]
    /// up to rounding.
    ///
    /// # Errors
    /// As [`ResponseOp::apply`].
    pub fn adjoint(&self, y: &[f64], out: &mut [f64]) -> Result<()> {
        self.run(y, out, true)
    }

    fn run(&self, x: &[f64], out: &mut [f64], adjoint: bool) -> Result<()> {
        self.check(x.len(), out.len())?;
        let bins = self.bins;
        let Some(f) = &self.fft else {
            let k = &self.kernel;
            let r = if adjoint { k.adjoint_f64(x, bins, out) } else { k.apply_f64(x, bins, out) };
            return r.map_err(OptimError::Sensor);
        };
        let first = self.kernel.first();
        let (n, nb) = (f.n as i64, bins as i64);
        x.par_chunks(bins).zip(out.par_chunks_mut(bins)).for_each_init(
            || (f.forward.make_input_vec(), f.forward.make_output_vec(), f.forward.make_scratch_vec()),
            |(buf, spec, scratch), (xr, or)| {
                buf.fill(0.0);
                if adjoint {
                    // (Jᵀ y)[j] = Σ_i w[i] z[j + i] with z[t] = y[t + first]: a correlation, conj(H).
                    for (t, slot) in buf.iter_mut().enumerate() {
                        let src = t as i64 + first;
                        if (0..nb).contains(&src) {
                            *slot = xr[src as usize];
                        }
                    }
                } else {
                    buf[..bins].copy_from_slice(xr);
                }
                let _ = f.forward.process_with_scratch(buf, spec, scratch);
                for (s, h) in spec.iter_mut().zip(&f.spectrum) {
                    *s *= if adjoint { h.conj() } else { *h };
                }
                // The DC and Nyquist terms of a real signal's spectrum are real; rounding cannot make them
                // otherwise here, but realfft checks.
                spec[0].im = 0.0;
                if let Some(last) = spec.last_mut().filter(|_| f.n.is_multiple_of(2)) {
                    last.im = 0.0;
                }
                let _ = f.inverse.process_with_scratch(spec, buf, scratch);
                if adjoint {
                    or.copy_from_slice(&buf[..bins]);
                } else {
                    // (J x)[k] = c[k − first], c the linear convolution (indices 0 .. bins + taps − 1 < n).
                    for (k, o) in or.iter_mut().enumerate() {
                        let u = k as i64 - first;
                        *o = if (0..n).contains(&u) && u < nb + self.kernel.weights().len() as i64 - 1 {
                            buf[u as usize]
                        } else {
                            0.0
                        };
                    }
                }
            },
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kernel(first: i64, taps: usize) -> BinKernel {
        // A sharp rise and a long, slowly falling tail, as a real capture's own response.
        let w: Vec<f64> =
            (0..taps).map(|i| if i < 3 { 0.2 * (i + 1) as f64 } else { (-(i as f64) / 40.0).exp() }).collect();
        let s: f64 = w.iter().sum();
        BinKernel::new(first, w.iter().map(|v| v / s).collect()).expect("kernel")
    }

    fn rows(m: usize, bins: usize) -> Vec<f64> {
        (0..m * bins)
            .map(|i| ((i * 37 % 101) as f64 / 101.0) * if (i % bins).is_multiple_of(7) { 3.0 } else { 1.0 })
            .collect()
    }

    /// The FFT path equals the direct sum, for kernels that start before, at and after the bin, and for
    /// both the operator and its adjoint (a kernel reaching past the row's end included).
    #[test]
    fn fft_matches_the_direct_sum() {
        let bins = 150;
        for (first, taps) in [(-1, 200), (0, 60), (5, 90), (-30, 64)] {
            let k = kernel(first, taps);
            let op = ResponseOp::new(&k, bins).expect("op");
            assert!(op.fft.is_some());
            let x = rows(3, bins);
            let (mut fast, mut slow) = (vec![0.0; x.len()], vec![0.0; x.len()]);
            op.apply(&x, &mut fast).expect("apply");
            k.apply_f64(&x, bins, &mut slow).expect("direct");
            let scale = slow.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (a, b) in fast.iter().zip(&slow) {
                assert!((a - b).abs() <= 1e-12 * scale, "apply {first} {taps}: {a} vs {b}");
            }
            op.adjoint(&x, &mut fast).expect("adjoint");
            k.adjoint_f64(&x, bins, &mut slow).expect("direct");
            for (a, b) in fast.iter().zip(&slow) {
                assert!((a - b).abs() <= 1e-12 * scale, "adjoint {first} {taps}: {a} vs {b}");
            }
        }
        assert!(matches!(
            ResponseOp::new(&kernel(0, 60), 150).expect("op").apply(&[0.0; 7], &mut [0.0; 7]),
            Err(OptimError::LengthMismatch { .. })
        ));
    }

    /// Summed bins: where the flux is constant inside each coarse bin, the coarse response of the summed
    /// flux is exactly the sum of the fine response's output (module docs); the kernel keeps unit mass.
    #[test]
    fn summed_response_is_exact_for_flux_constant_in_each_coarse_bin() {
        let (fine_bins, k) = (240, 4);
        for (first, taps) in [(-1, 70), (0, 9), (3, 13), (-6, 30)] {
            let fine = kernel(first, taps);
            let coarse = summed_response(&fine, k).expect("coarse");
            assert!((coarse.weights().iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let coarse_in: Vec<f64> = (0..fine_bins / k).map(|i| ((i * 13 % 17) as f64).powi(2)).collect();
            let fine_in: Vec<f64> = (0..fine_bins).map(|j| coarse_in[j / k] / k as f64).collect();
            let mut fine_out = vec![0.0; fine_bins];
            fine.apply_f64(&fine_in, fine_bins, &mut fine_out).expect("fine");
            let mut coarse_out = vec![0.0; fine_bins / k];
            coarse.apply_f64(&coarse_in, fine_bins / k, &mut coarse_out).expect("coarse");
            // Away from the row's ends (where the fine output spills past the axis).
            let reach = (taps as i64 + first.abs()) as usize / k + 2;
            for l in reach..fine_bins / k - reach {
                let summed: f64 = fine_out[l * k..(l + 1) * k].iter().sum();
                assert!((summed - coarse_out[l]).abs() < 1e-12 * (1.0 + summed), "{first} {taps} bin {l}");
            }
        }
        assert!(summed_response(&kernel(0, 5), 0).is_err());
    }

    /// For a flux that varies inside the coarse bins (a narrow pulse), the summed response moves light by
    /// less than a coarse bin: the coarse model's relative L2 error against the summed fine model.
    #[test]
    fn summed_response_error_on_a_pulse_is_small() {
        let (fine_bins, k) = (400, 4);
        let fine = kernel(-1, 300);
        let coarse = summed_response(&fine, k).expect("coarse");
        let fine_in: Vec<f64> = (0..fine_bins).map(|j| (-((j as f64 - 101.3) / 6.0).powi(2)).exp()).collect();
        let coarse_in: Vec<f64> = fine_in.chunks(k).map(|c| c.iter().sum()).collect();
        let mut fine_out = vec![0.0; fine_bins];
        fine.apply_f64(&fine_in, fine_bins, &mut fine_out).expect("fine");
        let mut coarse_out = vec![0.0; fine_bins / k];
        coarse.apply_f64(&coarse_in, fine_bins / k, &mut coarse_out).expect("coarse");
        let summed: Vec<f64> = fine_out.chunks(k).map(|c| c.iter().sum()).collect();
        let err: f64 = summed.iter().zip(&coarse_out).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        let norm: f64 = summed.iter().map(|a| a * a).sum::<f64>().sqrt();
        assert!(err / norm < 0.05, "relative error {}", err / norm);
    }
}
