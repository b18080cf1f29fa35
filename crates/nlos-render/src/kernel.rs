//! Temporal kernels: how a path of length τ is spread over the histogram bins.
//!
//! Bin `k` covers `[t0 + kΔ, t0 + (k+1)Δ)` and holds an integral over the bin (workspace convention). A
//! kernel gives the weights `K_k(τ)` with `Σ_k K_k(τ) = 1` away from the ends of the axis, so the time sum
//! of a transient is the steady-state value whatever the kernel. The forward pass splats `g·K_k(τ)`; the
//! adjoint gathers `Σ_k a_k K_k(τ)` and `Σ_k a_k dK_k/dτ` from the SAME kernel (the original code used
//! different kernels in the two passes; here the splats and the gather of the crate-private evaluator all
//! go through one weight routine).

/// A temporal kernel `K_k(τ)`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub enum Kernel {
    /// The box of eq. (3) of Tsai et al. 2019: `K_k(τ) = 1` for τ in bin k (floor assignment). Exact for
    /// simulating measurements; its τ-derivative is 0 almost everywhere, so with it the adjoint carries no
    /// time-shift term (use [`Kernel::Tent`] or [`Kernel::Gaussian`] to optimise).
    Box,
    /// Linear interpolation between bin centres: `K_k(τ) = max(0, 1 − |u − k − ½|)`, `u = (τ − t0)/Δ`.
    /// Continuous, piecewise linear, derivative `∓1/Δ`; keeps the mean arrival bin of the box. The default.
    #[default]
    Tent,
    /// A Gaussian of the given full width at half maximum (in bins) sampled at bin centres:
    /// `K_k(τ) = exp(−z²/2)/(σ√(2π))`, `z = (k + ½ − u)/σ`, `σ = FWHM/(2√(2 ln 2))`, truncated at `|z| ≤ 5`
    /// (the truncation jump is below 4e-6 of the peak). Smooth; needs FWHM ≳ 1 bin for `Σ_k K_k ≈ 1`.
    Gaussian {
        /// Full width at half maximum, in bins (> 0).
        fwhm_bins: f32,
    },
}

/// Precomputed constants of a kernel on a given time axis (f32, in bins).
#[derive(Debug, Clone, Copy)]
pub(crate) struct KernelEval {
    kind: Kernel,
    t0: f32,
    inv_dt: f32,
    bins: usize,
    inv_sigma: f32,
    norm: f32,
    radius: f32,
    /// The steady-state "kernel" ([`KernelEval::steady`]): a box, but never a time axis for the splat.
    steady: bool,
}

impl KernelEval {
    pub(crate) fn new(kind: Kernel, t0: f64, dt: f64, bins: usize) -> Self {
        let (sigma, radius) = match kind {
            Kernel::Gaussian { fwhm_bins } => {
                let s = fwhm_bins / (2.0 * (2.0 * std::f32::consts::LN_2).sqrt());
                (s, 5.0 * s)
            }
            _ => (1.0, 1.0),
        };
        Self {
            kind,
            t0: t0 as f32,
            inv_dt: (1.0 / dt) as f32,
            bins,
            inv_sigma: 1.0 / sigma,
            norm: 1.0 / (sigma * (2.0 * std::f32::consts::PI).sqrt()),
            radius,
            steady: false,
        }
    }

    /// The tent kernel's constants for the block kernels (None for the other kernels).
    pub(crate) fn tent(&self) -> Option<TentAxis> {
        (self.kind == Kernel::Tent).then_some(TentAxis {
            t0: self.t0,
            inv_dt: self.inv_dt,
            last: self.bins as f32 - 1.0,
            box_kernel: false,
        })
    }

    /// The splat's time axis for the box kernel (None for the other kernels and the steady state): the
    /// tent's constants with the origin moved back half a bin, so that the splat's node units
    /// `(τ − t0')/Δ − ½` are the box's bin units `(τ − t0)/Δ` (bin k is `[k, k + 1)`).
    pub(crate) fn box_axis(&self) -> Option<TentAxis> {
        (self.kind == Kernel::Box && !self.steady).then_some(TentAxis {
            t0: self.t0 - 0.5 / self.inv_dt,
            inv_dt: self.inv_dt,
            last: self.bins as f32 - 1.0,
            box_kernel: true,
        })
    }

    /// `1/Δ`.
    pub(crate) fn inv_dt(&self) -> f32 {
        self.inv_dt
    }

    /// Number of bins.
    pub(crate) fn bins(&self) -> usize {
        self.bins
    }

    /// The steady-state (time-integrated) "kernel": one bin that holds every path length, `K_0(τ) = 1`, no
    /// τ-derivative (a box of width 10³⁰ m starting at τ = 0; path lengths are ≥ 0).
    pub(crate) fn steady() -> Self {
        Self { steady: true, ..Self::new(Kernel::Box, 0.0, 1e30, 1) }
    }

    /// Calls `f(k, K_k(τ), dK_k/dτ)` for every bin with a non-zero weight.
    #[inline(always)]
    fn weights(&self, tau: f32, mut f: impl FnMut(usize, f32, f32)) {
        let u = (tau - self.t0) * self.inv_dt;
        // Guard: NaN or far-outside τ never produces an index (the comparisons are false for NaN).
        if !(u > -self.radius - 1.0 && u < self.bins as f32 + self.radius + 1.0) {
            return;
        }
        match self.kind {
            Kernel::Box => {
                if u >= 0.0 {
                    let k = u as usize;
                    if k < self.bins {
                        f(k, 1.0, 0.0);
                    }
                }
            }
            Kernel::Tent => {
                let c = u - 0.5;
                // floor(c) without a libm call (baseline x86-64 has no rounding instruction): truncate, then
                // step down for negative non-integers. Exact: c is finite here (range check above), and every
                // f32 of magnitude ≥ 2^23 is an integer, so the i64 round trip truncates exactly.
                let tr = c as i64 as f32;
                let kf = if tr > c { tr - 1.0 } else { tr };
                let frac = c - kf;
                let k0 = kf as i64;
                if k0 >= 0 && (k0 as usize) < self.bins {
                    f(k0 as usize, 1.0 - frac, -self.inv_dt);
                }
                let k1 = k0 + 1;
                if k1 >= 0 && (k1 as usize) < self.bins {
                    f(k1 as usize, frac, self.inv_dt);
                }
            }
            Kernel::Gaussian { .. } => {
                let lo = (u - 0.5 - self.radius).ceil().max(0.0) as usize;
                let hi = ((u - 0.5 + self.radius).floor() as i64).min(self.bins as i64 - 1);
                if hi < 0 {
                    return;
                }
                for k in lo..=hi as usize {
                    let z = (k as f32 + 0.5 - u) * self.inv_sigma;
                    let w = self.norm * (-0.5 * z * z).exp();
                    // dz/dτ = −1/(σΔ), dw/dz = −z w  ⇒  dw/dτ = z w /(σΔ).
                    f(k, w, w * z * self.inv_sigma * self.inv_dt);
                }
            }
        }
    }

    /// `hist[k] += g · K_k(τ)`.
    #[inline(always)]
    pub(crate) fn splat(&self, tau: f32, g: f32, hist: &mut [f32]) {
        self.weights(tau, |k, w, _| hist[k] += g * w);
    }

    /// `hist[k] += g[i] · K_k(τ[i])` for every `i` with `g[i] ≠ 0` (the kernel dispatched once per call).
    #[inline(always)]
    pub(crate) fn splat_all(&self, tau: &[f32], g: &[f32], hist: &mut [f32]) {
        match self.kind {
            Kernel::Box => self.splat_each(Kernel::Box, tau, g, hist),
            Kernel::Tent => self.splat_each(Kernel::Tent, tau, g, hist),
            k @ Kernel::Gaussian { .. } => self.splat_each(k, tau, g, hist),
        }
    }

    #[inline(always)]
    fn splat_each(&self, kind: Kernel, tau: &[f32], g: &[f32], hist: &mut [f32]) {
        // `kind` equals `self.kind`; passing it as a constant lets each arm specialise `weights`.
        let this = Self { kind, ..*self };
        for (t, v) in tau.iter().zip(g) {
            if *v != 0.0 {
                this.weights(*t, |k, w, _| hist[k] += v * w);
            }
        }
    }

    /// `(Σ_k a_k K_k(τ), Σ_k a_k dK_k/dτ)`.
    #[inline(always)]
    pub(crate) fn gather(&self, tau: f32, adj: &[f32]) -> (f32, f32) {
        let (mut v, mut d) = (0.0f32, 0.0f32);
        self.weights(tau, |k, w, dw| {
            v += adj[k] * w;
            d += adj[k] * dw;
        });
        (v, d)
    }
}

/// The tent kernel's bin arithmetic in the block kernels (the same expressions as `KernelEval::weights`):
/// `c = (τ − t0)/Δ − ½`, lower bin `k0 = ⌊c⌋`, weights `1 − (c − k0)` and `c − k0`. Histograms and adjoint
/// rows are padded by one zero bin at each end (bin k at index k + 1), so a pair whose lower bin is in
/// `−1..bins` needs no bounds logic; other pairs have no bin in range and get weight 0.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TentAxis {
    pub(crate) t0: f32,
    pub(crate) inv_dt: f32,
    /// `bins − 1`, the largest valid lower bin.
    pub(crate) last: f32,
    /// The splat integrates the box kernel instead of the tent ([`KernelEval::box_axis`]: `t0` is then
    /// half a bin early, so that node units are bin units); never set for the point rules' tent path.
    pub(crate) box_kernel: bool,
}

impl TentAxis {
    /// `(padded index of the lower bin, fraction c − k0, whether any bin is in range)`. Branch-free and free
    /// of float → int conversions (Rust's saturating casts do not vectorise): c is clamped to
    /// `[−2, bins]` (NaN → −2, out of range), rounded with the 1.5·2²³ trick (exact round-to-nearest for
    /// |c| < 2²², no fast-math here), stepped down to the floor, and the integer read from the bits.
    #[inline(always)]
    pub(crate) fn bin(&self, tau: f32) -> (u32, f32, bool) {
        const MAGIC: f32 = 12_582_912.0; // 1.5 · 2²³: ulp 1 over [2²³, 2²⁴)
        let c = ((tau - self.t0) * self.inv_dt - 0.5).max(-2.0).min(self.last + 1.0);
        let r = (c + MAGIC) - MAGIC;
        let kf = if r > c { r - 1.0 } else { r };
        let frac = c - kf;
        let in_range = (kf >= -1.0) & (kf <= self.last);
        // kf + 1 ∈ [−1, bins + 1] is an integer: MAGIC + it has it in the low mantissa bits.
        let p = (kf.max(-1.0).min(self.last) + 1.0 + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits());
        (p, frac, in_range)
    }
}
