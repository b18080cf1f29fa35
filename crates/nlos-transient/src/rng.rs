//! The workspace's random number generators: one module, so that every
//! library and test draws from the same two documented generators, and the exact discrete samplers the
//! sensor model needs.
//!
//! The crate adds no `rand` dependency: the sensor model needs one uniform generator and two discrete
//! distributions, and writing them here keeps the stream of numbers fixed across dependency upgrades (a
//! seed names the same simulated capture forever).
//!
//! - [`SplitMix64`] (Steele, Lea & Flood 2014): one `u64` of state, for seeds derived from seeds (the
//!   optimiser's per-block sampling seeds, stored in its checkpoints) and, keyed by (seed, measurement,
//!   triangle), for the renderer's Monte Carlo samples, which then do not depend on thread scheduling.
//! - [`Pcg32`]: O'Neill's PCG-XSH-RR 64/32 generator (2014), 2⁶⁴ period per stream, 2⁶³ streams. The
//!   simulator gives every measurement its own stream (`stream = measurement index`), so a histogram does
//!   not depend on the order in which measurements are processed.
//! - [`Pcg32::poisson`]: exact Poisson variates. Sequential inversion (Knuth, TAOCP vol. 2, §3.4.1; also
//!   Devroye 1986, §X.3) for `λ < 10`; Hörmann's PTRS transformed rejection with squeeze for `λ ≥ 10`
//!   (W. Hörmann, "The transformed rejection method for generating Poisson random variables",
//!   Insurance: Mathematics and Economics 12, 1993).
//! - [`Pcg32::binomial`]: exact binomial variates. Inversion (Kachitvichyanukul & Schmeiser's BINV, 1988)
//!   when `n·min(p, 1−p) < 10`, Hörmann's BTRS otherwise (W. Hörmann, "The generation of binomial random
//!   variates", J. Statist. Comput. Simul. 46, 1993). Used for the multinomial of first-photon detections.

/// SplitMix64 (Steele, Lea & Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014):
/// `state += φ·2⁶⁴`, output the state through two xor-shift-multiply rounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// The generator whose state is `state` (a stored [`Self::state`] continues the stream exactly).
    pub fn new(state: u64) -> Self {
        Self(state)
    }

    /// A generator keyed by `(seed, m, t)` (the renderer's per measurement and triangle streams): the key
    /// mixed through the generator itself, so neighbouring keys give unrelated streams.
    #[inline(always)]
    pub fn keyed(seed: u64, m: u64, t: u64) -> Self {
        let mut s = Self(seed ^ 0x9E37_79B9_7F4A_7C15);
        s.0 ^= s.next_u64().wrapping_add(m.wrapping_mul(0xD1B5_4A32_D192_ED03));
        s.0 ^= s.next_u64().wrapping_add(t.wrapping_mul(0xAEF1_7502_108E_F2D9));
        Self(s.next_u64())
    }

    /// The state, to store and continue from ([`Self::new`]).
    pub fn state(&self) -> u64 {
        self.0
    }

    /// The next 64 uniformly distributed bits.
    #[inline(always)]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` with 24 random bits (so never 1.0).
    #[inline(always)]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in `[lo, hi)`.
    pub fn range_f32(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next_f32()
    }

    /// Uniform in `0..n`, and 0 for `n = 0` (the modulo bias, below `n / 2⁶⁴`, is negligible for test sizes).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
}

/// PCG-XSH-RR 64/32 (O'Neill 2014): `state ← state·6364136223846793005 + inc`, output
/// `rotr((state ⊕ state≫18)≫27, state≫59)` of the old state.
#[derive(Debug, Clone)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const PCG_MULT: u64 = 6_364_136_223_846_793_005;

impl Pcg32 {
    /// The generator for `seed` on stream `stream` (the reference `pcg32_srandom_r(seed, stream)`).
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut g = Self { state: 0, inc: (stream << 1) | 1 };
        g.next_u32();
        g.state = g.state.wrapping_add(seed);
        g.next_u32();
        g
    }

    /// The next 32 uniformly distributed bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform variate on the **open** interval (0, 1) with 53 random bits: `(m + ½)·2⁻⁵³`,
    /// `m ∈ [0, 2⁵³)`. Never 0, so `ln(u)` is always finite.
    pub fn uniform(&mut self) -> f64 {
        let hi = u64::from(self.next_u32());
        let lo = u64::from(self.next_u32());
        let m = ((hi << 32) | lo) >> 11;
        (m as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
    }

    /// An exponential variate with mean `mean`: `−mean·ln(u)`.
    pub fn exponential(&mut self, mean: f64) -> f64 {
        -mean * self.uniform().ln()
    }

    /// A Poisson variate with mean `lambda` (exact in distribution; see the module docs).
    ///
    /// `lambda ≤ 0` or NaN gives 0 (callers validate their means; this is the guard that keeps the
    /// sampler total). Means above 2⁵² are returned rounded (the variate's standard deviation, 2²⁶, is far
    /// above the spacing of representable counts there).
    pub fn poisson(&mut self, lambda: f64) -> u64 {
        // Guard: NaN and non-positive means have no Poisson law; 0 keeps the sampler total.
        if lambda.is_nan() || lambda <= 0.0 {
            return 0;
        }
        if lambda >= 4.5e15 {
            // Guard: beyond 2⁵² counts are not integers in f64 anyway; the normal limit is exact to
            // within the representable spacing.
            let z = self.standard_normal();
            return (lambda + z * lambda.sqrt()).max(0.0).round() as u64;
        }
        if lambda < 10.0 {
            // Sequential inversion: P(0) = e^{−λ}, P(k) = P(k−1)·λ/k. Expected λ + 1 iterations.
            let u = self.uniform();
            let mut p = (-lambda).exp();
            let mut cdf = p;
            let mut k = 0u64;
            // The tail beyond k = 200 has probability < 1e-150 for λ < 10; the bound only guards rounding.
            while u > cdf && k < 200 {
                k += 1;
                p *= lambda / k as f64;
                cdf += p;
            }
            return k;
        }
        self.poisson_ptrs(lambda)
    }

    /// Hörmann's PTRS (1993) for `λ ≥ 10`: transformed rejection from the hat
    /// `k = ⌊(2a/us + b)·u + λ + 0.43⌋`, with the squeeze `us ≥ 0.07 ∧ v ≤ v_r`, and the exact acceptance
    /// `ln v + ln(1/α) − ln(a/us² + b) ≤ −λ + k ln λ − ln k!`.
    fn poisson_ptrs(&mut self, lambda: f64) -> u64 {
        let slam = lambda.sqrt();
        let loglam = lambda.ln();
        let b = 0.931 + 2.53 * slam;
        let a = -0.059 + 0.024_83 * b;
        let inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
        let v_r = 0.9277 - 3.6224 / (b - 2.0);
        loop {
            let u = self.uniform() - 0.5;
            let v = self.uniform();
            let us = 0.5 - u.abs();
            let k = ((2.0 * a / us + b) * u + lambda + 0.43).floor();
            if us >= 0.07 && v <= v_r {
                return k as u64;
            }
            if k < 0.0 || (us < 0.013 && v > us) {
                continue;
            }
            if v.ln() + inv_alpha.ln() - (a / (us * us) + b).ln() <= -lambda + k * loglam - ln_factorial(k) {
                return k as u64;
            }
        }
    }

    /// A binomial variate: the number of successes in `n` trials of probability `p` (exact in
    /// distribution; see the module docs). `p` is clamped to `[0, 1]`; NaN gives 0.
    pub fn binomial(&mut self, n: u64, p: f64) -> u64 {
        // Guard: NaN or out-of-range probabilities (from rounding upstream) are clamped.
        if n == 0 || p.is_nan() || p <= 0.0 {
            return 0;
        }
        if p >= 1.0 {
            return n;
        }
        if p > 0.5 {
            return n - self.binomial(n, 1.0 - p);
        }
        let nf = n as f64;
        if nf * p < 10.0 { self.binomial_inversion(n, p) } else { self.binomial_btrs(nf, p) }
    }

    /// BINV (inversion): `P(0) = qⁿ`, `P(x) = P(x−1)·((n+1)s/x − s)` with `s = p/q`.
    fn binomial_inversion(&mut self, n: u64, p: f64) -> u64 {
        let q = 1.0 - p;
        let s = p / q;
        let a = (n as f64 + 1.0) * s;
        // qⁿ via exp(n·ln1p(−p)): accurate for tiny p and huge n (≥ e^{-10.6} here since n·p < 10).
        let r0 = (n as f64 * (-p).ln_1p()).exp();
        loop {
            let mut u = self.uniform();
            let mut r = r0;
            let mut x = 0u64;
            let mut ok = true;
            while u > r {
                u -= r;
                x += 1;
                if x > n {
                    // Guard: rounding left u above the total mass; draw again (probability ~1e-16).
                    ok = false;
                    break;
                }
                r *= a / x as f64 - s;
            }
            if ok {
                return x;
            }
        }
    }

    /// Hörmann's BTRS (1993) for `n·p ≥ 10`, `p ≤ ½`: hat `k = ⌊(2a/us + b)·u + c⌋`, squeeze
    /// `us ≥ 0.07 ∧ v ≤ v_r`, exact acceptance of `ln(v·α/(a/us² + b))` against
    /// `ln(P(k)/P(m))` written with Stirling tails δ(k) = ln k! − [(k+½)ln(k+1) − (k+1) + ½ln2π].
    fn binomial_btrs(&mut self, n: f64, p: f64) -> u64 {
        let q = 1.0 - p;
        let spq = (n * p * q).sqrt();
        let b = 1.15 + 2.53 * spq;
        let a = -0.0873 + 0.0248 * b + 0.01 * p;
        let c = n * p + 0.5;
        let v_r = 0.92 - 4.2 / b;
        let r = p / q;
        let alpha = (2.83 + 5.1 / b) * spq;
        let m = ((n + 1.0) * p).floor();
        loop {
            let u = self.uniform() - 0.5;
            let v = self.uniform();
            let us = 0.5 - u.abs();
            let k = ((2.0 * a / us + b) * u + c).floor();
            if k < 0.0 || k > n {
                continue;
            }
            if us >= 0.07 && v <= v_r {
                return k as u64;
            }
            let lv = (v * alpha / (a / (us * us) + b)).ln();
            let bound = (m + 0.5) * ((m + 1.0) / (r * (n - m + 1.0))).ln()
                + (n + 1.0) * ((n - m + 1.0) / (n - k + 1.0)).ln()
                + (k + 0.5) * (r * (n - k + 1.0) / (k + 1.0)).ln()
                + stirling_tail(m)
                + stirling_tail(n - m)
                - stirling_tail(k)
                - stirling_tail(n - k);
            if lv <= bound {
                return k as u64;
            }
        }
    }

    /// A standard normal variate (Box–Muller; used only for the guard of astronomically large means).
    fn standard_normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// `ln k!` for a non-negative integer-valued `k`: exact summation below 10, Stirling's series
/// `(k+½)ln(k+1) − (k+1) + ½ln2π + δ(k)` above (|error| < 1e-15 relative).
pub fn ln_factorial(k: f64) -> f64 {
    if k < 10.0 {
        let mut s = 0.0;
        let mut i = 2.0;
        while i <= k {
            s += f64::ln(i);
            i += 1.0;
        }
        return s;
    }
    (k + 0.5) * (k + 1.0).ln() - (k + 1.0) + 0.5 * (std::f64::consts::TAU).ln() + stirling_tail(k)
}

/// Stirling's correction δ(k) = ln k! − [(k+½)ln(k+1) − (k+1) + ½ln2π]: exact below 10, else the series
/// `1/(12(k+1)) − 1/(360(k+1)³) + 1/(1260(k+1)⁵)`.
fn stirling_tail(k: f64) -> f64 {
    if k < 10.0 {
        let exact = {
            let mut s = 0.0;
            let mut i = 2.0;
            while i <= k {
                s += f64::ln(i);
                i += 1.0;
            }
            s
        };
        return exact - ((k + 0.5) * (k + 1.0).ln() - (k + 1.0) + 0.5 * (std::f64::consts::TAU).ln());
    }
    let kp1 = k + 1.0;
    let kp1sq = kp1 * kp1;
    (1.0 / 12.0 - (1.0 / 360.0 - 1.0 / 1260.0 / kp1sq) / kp1sq) / kp1
}
