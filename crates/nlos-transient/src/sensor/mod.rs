//! A single-photon avalanche diode (SPAD) sensor model: realistic simulated captures from rendered
//! transients, corrections for real captures, and the pieces a noise-aware fit needs.
//!
//! ## Forward model, in the physical order of effects
//! For each measurement (histogram) `x_k` (expected flux, any unit, bin `k` of width `Δ` metres of path,
//! `Δt = Δ/c` seconds), [`SpadModel::simulate`] applies:
//!
//! 1. **Photon budget** — `μ⁰_k = s·x_k`, with `s` chosen so that the expected number of detected signal
//!    photons (before pile-up losses) is the budget ([`PhotonBudget`]); or `s = η·f` for a known incident
//!    flux scale `f` and photon detection probability `η`.
//! 2. **Timing jitter** — `μ = K ⊛ μ⁰` with the response resampled onto the bins
//!    ([`jitter::BinKernel`], `Σ_d K[d] = 1`). The measured response bundles laser pulse width, SPAD jitter
//!    and electronics; it is applied to the flux, before detection, as in Hernández et al. 2017. (Strictly,
//!    SPAD and electronics jitter act after the first-photon competition; the difference is second order
//!    in the pile-up and vanishes at low flux.)
//! 3. **Background** — dark counts and ambient light arrive uniformly in time; each laser period puts
//!    `R_bg·Δt` of them into every bin, so over the exposure's `f_rep·T_exp` periods every bin gains
//!    `b = R_bg·Δt·f_rep·T_exp` expected counts (`R_bg` in detected counts per second, `Δt` the bin width
//!    in seconds, `f_rep` the laser repetition rate, `T_exp` the exposure per measurement).
//! 4. **Detection with dead time and pile-up** (synchronous, first-photon model; Coates 1968, Heide et
//!    al. 2018, Rapp et al. 2019). Over `N = round(f_rep·T_exp)` laser cycles, cycle-wise expected
//!    photons are `λ_k = (μ_k + b)/N`, photon arrivals in a cycle are Poisson, and the detector registers
//!    only the first one (the dead time holds it off for the rest of the window). The probability that
//!    a cycle's detection falls in bin `k` is
//!
//!    `p_k = (1 − e^{−λ_k}) · e^{−Σ_{j<k} λ_j}`,
//!
//!    and the histogram is multinomial over the armed cycles. It is sampled exactly as a chain of
//!    binomials: given the cycles still undetected before bin `k`, each is detected in bin `k` with
//!    probability `1 − e^{−λ_k}`. High flux therefore **skews the histogram early**.
//!
//!    *Hold-off across cycles*: a detection at `t_k` (time from the laser pulse, taken as the bin's path
//!    length over `c`) keeps the detector dead until `t_k + τ_d`. When that reaches past the start of the
//!    next window (`t_0 + T`, `T = 1/f_rep`), the next `L_k = max(0, ⌈(t_k + τ_d − t_0)/T⌉ − 1)` cycles are
//!    counted as lost (a cycle blind at its window start is treated as blind throughout — exact when the
//!    detector cannot recover mid-window, conservative otherwise). In expectation each armed cycle then
//!    consumes `1 + Σ_k p_k L_k` cycles, so the number of armed cycles is
//!    `N_armed = round(N / (1 + Σ_k p_k L_k))` (a renewal-reward mean; its fluctuation is neglected).
//!    When `τ_d + t_end ≤ T + t_0` (the common case, e.g. 50 ns hold-off at 10 MHz) no cycle is lost and the
//!    model is exact. A dead time shorter than the window (multi-stop TCSPC) is not modelled: at most
//!    one detection per cycle is recorded.
//!
//!    With `pile_up = false` the detector is ideal (the low-flux limit `λ ≪ 1`): `n_k ~ Poisson(μ_k + b)`.
//! 5. **Afterpulsing** — each detection triggers, with probability `P_ap`, one afterpulse after the hold-off:
//!    `t_ap = t_det + τ_d + E`, `E ~ Exp(τ_ap)`, registered at its phase in the laser period
//!    (`(t_ap − t_0) mod T`) when that falls inside the window (Hernández et al. 2017, Sec. 3). Afterpulses
//!    of afterpulses (order `P_ap²`) and the hold-off caused by an afterpulse are neglected.
//!
//! [`SpadModel::expected_counts`] returns the mean of this process. Counts are returned as `f32`
//! histograms of integers (exact up to 2²⁴ per bin).
//!
//! ## Submodules
//! - [`jitter`]: the timing response (load, Gaussian, FWHM, resample) and the convolution operator `A`
//!   with its adjoint.
//! - [`correct`]: Coates' pile-up correction and background estimation for real captures.
//! - [`likelihood`]: the Poisson negative log-likelihood with background and its gradients.
//! - [`crate::rng`] (the crate's, shared by the workspace's tests): the seeded generators and the exact
//!   Poisson/binomial samplers the simulation draws from.
//!
//! ## References
//! - Q. Hernández, D. Gutierrez, A. Jarabo, "A Computational Model of a Single-Photon Avalanche Diode
//!   Sensor for Transient Imaging", arXiv:1703.02635, 2017.
//! - P. B. Coates, "The correction for photon 'pile-up' in the measurement of radiative lifetimes",
//!   J. Phys. E 1, 1968.
//! - F. Heide, S. Diamond, D. B. Lindell, G. Wetzstein, "Sub-picosecond photon-efficient 3D imaging using
//!   single-photon sensors", Sci. Rep. 8, 2018.
//! - J. Rapp, Y. Ma, R. M. A. Dawson, V. K. Goyal, "Dead time compensation for high-flux ranging",
//!   IEEE Trans. Signal Process. 67, 2019.
//! - C.-Y. Tsai, A. C. Sankaranarayanan, I. Gkioulekas, "Beyond Volumetric Albedo", CVPR 2019, Sec. 6.1, 7.

pub mod correct;
pub mod deconvolve;
pub mod jitter;
pub mod likelihood;
#[cfg(test)]
mod tests;

use crate::rng::Pcg32;
pub use correct::{
    BackgroundEstimate, BackgroundWindow, CountSummary, coates_correction, coates_histogram, count_summary,
    estimate_background, is_integer_counts,
};
pub use jitter::{BinKernel, JitterResponse};
pub use likelihood::{PoissonNll, poisson_nll};

use crate::SPEED_OF_LIGHT;
use crate::error::{Result, TransientError};
use crate::transient::Transient;

/// How bright the simulated capture is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PhotonBudget {
    /// Expected detected signal photons per measurement, averaged over measurements (before pile-up
    /// losses, background excluded): `s = N·M / Σ_{m,k} x_{m,k}`. Absorbs the detection probability.
    PerMeasurement(f64),
    /// Expected detected signal photons over the whole capture: `s = N / Σ_{m,k} x_{m,k}`.
    Total(f64),
    /// The transient is in incident photons per exposure up to this factor: `s = η·f` with `η` the
    /// [`SpadModel::detection_probability`].
    IncidentScale(f64),
}

/// The parameters of a SPAD sensor (see the [module docs](self) for the equations).
///
/// Defaults describe a typical NLOS setup of the CVPR 2019 era (thin-junction SPAD, 10 MHz picosecond
/// laser, TCSPC): see each field. Call [`SpadModel::validate`] (the simulation does) to get typed errors
/// for values outside their domain.
#[derive(Debug, Clone, PartialEq)]
pub struct SpadModel {
    /// Photon budget. Default: 1000 detected signal photons per measurement.
    pub photons: PhotonBudget,
    /// Photon detection probability `η ∈ (0, 1]` (used by [`PhotonBudget::IncidentScale`]).
    /// Default 0.3 (thin-junction SPAD in the red).
    pub detection_probability: f64,
    /// Timing response; `None` is an ideal (jitter-free) detector. Default `None`; use
    /// [`JitterResponse::gaussian`] or [`JitterResponse::load`].
    pub jitter: Option<JitterResponse>,
    /// Dark-count plus ambient background rate `R_bg`, detected counts per second. Default 1000 /s.
    pub background_rate: f64,
    /// Afterpulsing probability per detection `P_ap ∈ [0, 1)`. Default 0.01.
    pub afterpulse_probability: f64,
    /// Mean afterpulse delay after the hold-off, `τ_ap` seconds (> 0 when `P_ap > 0`). Default 20 ns.
    pub afterpulse_time_constant: f64,
    /// Dead time (hold-off) `τ_d`, seconds, ≥ 0. Default 50 ns.
    pub dead_time: f64,
    /// Laser repetition rate `f_rep`, Hz; must be > 0 with pile-up or a dead time. Default 10 MHz.
    pub rep_rate: f64,
    /// Exposure (acquisition time) per measurement `T_exp`, seconds, > 0. Default 0.1 s (10⁶ cycles).
    pub exposure: f64,
    /// Whether detection follows the first-photon (pile-up) model; `false` is an ideal photon counter.
    /// Default `true`.
    pub pile_up: bool,
    /// The TCSPC bin width, metres of path; `None` keeps the transient's. Must be an integer multiple of the
    /// transient's bin width (bins are summed). Default `None`.
    pub bin_width: Option<f64>,
}

impl Default for SpadModel {
    fn default() -> Self {
        Self {
            photons: PhotonBudget::PerMeasurement(1000.0),
            detection_probability: 0.3,
            jitter: None,
            background_rate: 1000.0,
            afterpulse_probability: 0.01,
            afterpulse_time_constant: 20e-9,
            dead_time: 50e-9,
            rep_rate: 10e6,
            exposure: 0.1,
            pile_up: true,
            bin_width: None,
        }
    }
}

fn bad(name: &'static str, reason: String) -> TransientError {
    TransientError::InvalidArgument { name, reason }
}

/// The per-measurement quantities derived once from a model and a time axis.
struct Plan {
    kernel: BinKernel,
    scale: f64,
    background: f64,
    cycles: f64,
}

impl SpadModel {
    /// An ideal photon counter: the given budget, no jitter, background, afterpulsing, dead time or
    /// pile-up — `n_k ~ Poisson(s·x_k)`.
    pub fn ideal(photons: PhotonBudget) -> Self {
        Self {
            photons,
            background_rate: 0.0,
            afterpulse_probability: 0.0,
            dead_time: 0.0,
            pile_up: false,
            ..Self::default()
        }
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] naming the parameter: budgets, rates, times not finite or
    /// negative; `η ∉ (0, 1]`; `P_ap ∉ [0, 1)`; `τ_ap ≤ 0` with `P_ap > 0`; exposure ≤ 0; a dead time or
    /// pile-up with a zero repetition rate; pile-up with fewer than one laser cycle per exposure; a bin
    /// width that is not finite and positive.
    pub fn validate(&self) -> Result<()> {
        let finite_nonneg = |name: &'static str, v: f64, unit: &str| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(bad(name, format!("{v} must be finite and ≥ 0 {unit}")))
            }
        };
        match self.photons {
            PhotonBudget::PerMeasurement(n) | PhotonBudget::Total(n) => finite_nonneg("photons", n, "(photons)")?,
            PhotonBudget::IncidentScale(f) => finite_nonneg("photons", f, "(photons per unit of transient)")?,
        }
        let eta = self.detection_probability;
        if !(eta.is_finite() && eta > 0.0 && eta <= 1.0) {
            return Err(bad("detection_probability", format!("{eta} must lie in (0, 1]")));
        }
        finite_nonneg("background_rate", self.background_rate, "(counts per second)")?;
        let pap = self.afterpulse_probability;
        if !(pap.is_finite() && (0.0..1.0).contains(&pap)) {
            return Err(bad("afterpulse_probability", format!("{pap} must lie in [0, 1)")));
        }
        finite_nonneg("afterpulse_time_constant", self.afterpulse_time_constant, "(seconds)")?;
        if pap > 0.0 && self.afterpulse_time_constant <= 0.0 {
            return Err(bad("afterpulse_time_constant", "must be > 0 when afterpulse_probability > 0".into()));
        }
        finite_nonneg("dead_time", self.dead_time, "(seconds)")?;
        finite_nonneg("rep_rate", self.rep_rate, "(Hz)")?;
        if !(self.exposure.is_finite() && self.exposure > 0.0) {
            return Err(bad("exposure", format!("{} must be finite and > 0 (seconds)", self.exposure)));
        }
        if self.background_rate > 0.0 && self.rep_rate <= 0.0 {
            return Err(bad(
                "rep_rate",
                "must be > 0 with a background rate: background counts per bin scale with the number of laser \
                 periods"
                    .into(),
            ));
        }
        if (self.pile_up || self.dead_time > 0.0) && self.rep_rate <= 0.0 {
            return Err(bad(
                "rep_rate",
                "a dead time or pile-up needs the laser repetition rate (> 0 Hz): hold-off and first-photon \
                 detection are defined per laser cycle"
                    .into(),
            ));
        }
        if self.pile_up && self.rep_rate * self.exposure < 1.0 {
            return Err(bad(
                "exposure",
                format!(
                    "rep_rate × exposure = {} laser cycles; pile-up needs at least one",
                    self.rep_rate * self.exposure
                ),
            ));
        }
        if let Some(w) = self.bin_width
            && !(w.is_finite() && w > 0.0)
        {
            return Err(bad("bin_width", format!("{w} must be finite and > 0 (metres of path)")));
        }
        Ok(())
    }

    /// The number of laser cycles per measurement, `N = round(f_rep·T_exp)` (0 without a repetition rate).
    pub fn cycles(&self) -> f64 {
        (self.rep_rate * self.exposure).round()
    }

    /// Expected background counts per bin over one exposure, `b = R_bg·(Δ/c)·f_rep·T_exp`, for bins of
    /// `bin_width` metres of path: the histogram folds time modulo the laser period, so each of the
    /// `f_rep·T_exp` periods adds `R_bg·Δ/c` counts to every bin.
    pub fn background_per_bin(&self, bin_width: f64) -> f64 {
        self.background_rate * bin_width / SPEED_OF_LIGHT * self.rep_rate * self.exposure
    }

    /// The sensor's temporal response on bins of `bin_width` metres: the jitter kernel, or the identity.
    ///
    /// # Errors
    /// As [`JitterResponse::to_bins`].
    pub fn kernel(&self, bin_width: f64) -> Result<BinKernel> {
        self.jitter.as_ref().map_or(Ok(BinKernel::identity()), |j| j.to_bins(bin_width))
    }

    /// The transient on the sensor's bins (summing groups of bins when [`SpadModel::bin_width`] is set).
    fn on_sensor_bins(&self, t: &Transient) -> Result<Transient> {
        let Some(w) = self.bin_width else { return Ok(t.clone()) };
        let ratio = w / t.time().bin_width;
        let k = ratio.round();
        if !(k >= 1.0 && (ratio - k).abs() <= 1e-6 * k) {
            return Err(bad(
                "bin_width",
                format!("{w} m is not an integer multiple of the transient's bin width {} m", t.time().bin_width),
            ));
        }
        if k == 1.0 { Ok(t.clone()) } else { t.rebin(k as usize) }
    }

    fn plan(&self, t: &Transient) -> Result<Plan> {
        self.validate()?;
        if let Some(i) = t.data().iter().position(|&v| v < 0.0) {
            return Err(bad(
                "transient",
                format!("value {} at flat index {i} is negative; an expected photon flux is ≥ 0", t.data()[i]),
            ));
        }
        let total: f64 = t.data().iter().map(|&v| f64::from(v)).sum();
        let m = t.measurements() as f64;
        // Guard: an all-zero transient has no scale to set; it simulates background only.
        let per_total = |n: f64| if total > 0.0 { n / total } else { 0.0 };
        let scale = match self.photons {
            PhotonBudget::PerMeasurement(n) => per_total(n * m),
            PhotonBudget::Total(n) => per_total(n),
            PhotonBudget::IncidentScale(f) => f * self.detection_probability,
        };
        let bw = t.time().bin_width;
        Ok(Plan { kernel: self.kernel(bw)?, scale, background: self.background_per_bin(bw), cycles: self.cycles() })
    }

    /// Linear expected counts `μ_k + b` (budget, jitter, background) of every measurement, f64.
    fn linear_means(&self, t: &Transient, plan: &Plan) -> Result<Vec<f64>> {
        let x: Vec<f64> = t.data().iter().map(|&v| f64::from(v) * plan.scale).collect();
        let mut mu = vec![0.0; x.len()];
        plan.kernel.apply_f64(&x, t.bins(), &mut mu)?;
        for v in &mut mu {
            *v += plan.background;
        }
        Ok(mu)
    }

    /// Lost cycles `L_k` after a detection in bin `k` (see the module docs), and the armed-cycle count.
    fn armed_cycles(&self, t: &Transient, p: &[f64], cycles: f64) -> f64 {
        if self.rep_rate <= 0.0 {
            return cycles;
        }
        let period = 1.0 / self.rep_rate;
        let ax = t.time();
        let t_start = ax.t0 / SPEED_OF_LIGHT;
        let consumed: f64 = p
            .iter()
            .enumerate()
            .map(|(k, &pk)| {
                let tk = ax.bin_center(k) / SPEED_OF_LIGHT;
                let lost = (((tk + self.dead_time - t_start) / period).ceil() - 1.0).max(0.0);
                pk * lost
            })
            .sum();
        (cycles / (1.0 + consumed)).round()
    }

    /// Per-cycle first-photon probabilities `p_k = (1 − e^{−λ_k})·e^{−Σ_{j<k}λ_j}` for `λ_k = means/N`.
    fn first_photon_probabilities(means: &[f64], cycles: f64) -> Vec<f64> {
        let mut survive = 0.0f64; // Σ_{j<k} λ_j
        means
            .iter()
            .map(|&m| {
                let lam = m / cycles;
                // −expm1(−λ) is 1 − e^{−λ} without cancellation at tiny λ.
                let p = -(-lam).exp_m1() * (-survive).exp();
                survive += lam;
                p
            })
            .collect()
    }

    /// The afterpulse delay distribution in bins: `g[m]`, `m = 0 … bins−1` offsets after wrapping into
    /// the window by the laser period. Bin-centre approximation (the within-bin spread is neglected).
    fn afterpulse_kernel(&self, t: &Transient) -> Vec<(i64, f64)> {
        let ax = t.time();
        let dt = ax.bin_width_seconds();
        let tau = self.afterpulse_time_constant;
        let mut g: Vec<(i64, f64)> = Vec::new();
        // Mass of D = τ_d + E in [a, b) (seconds after the detection), E ~ Exp(τ).
        let mass = |a: f64, b: f64| {
            let a = (a - self.dead_time).max(0.0);
            let b = (b - self.dead_time).max(0.0);
            (-a / tau).exp() - (-b / tau).exp()
        };
        let period = if self.rep_rate > 0.0 { 1.0 / self.rep_rate } else { f64::INFINITY };
        let n = ax.bins as i64;
        // A detection at bin k registers an afterpulse at bin k + m (m may be negative after the wrap):
        // delay ∈ [(m − ½)Δt + qT, (m + ½)Δt + qT) for q = 0, 1, …; sum q until the tail is < 1e-12.
        for m in -(n - 1)..n {
            let mut acc = 0.0;
            let mut q = 0.0;
            loop {
                let lo = (m as f64 - 0.5) * dt + q * period;
                if !lo.is_finite() || (lo > self.dead_time && (-(lo - self.dead_time) / tau).exp() < 1e-12) {
                    break;
                }
                if lo + dt > 0.0 {
                    acc += mass(lo.max(0.0), lo + dt);
                }
                if period.is_infinite() || q > 1e6 {
                    break;
                }
                q += 1.0;
            }
            if acc > 0.0 {
                g.push((m, acc));
            }
        }
        g
    }

    /// The mean of [`SpadModel::simulate`]: expected counts per bin, on the sensor's bins.
    ///
    /// `E[n_k] = μ_k + b` (ideal counter) or `N_armed·p_k` (pile-up), plus the afterpulse term
    /// `P_ap Σ_j E[n_j] g[k − j]` with `g` the wrapped delay distribution of afterpulses.
    ///
    /// # Errors
    /// The errors of [`SpadModel::validate`]; [`TransientError::InvalidArgument`] for negative transient
    /// values or a bin width that is not a multiple of the transient's.
    pub fn expected_counts(&self, transient: &Transient) -> Result<Transient> {
        let t = self.on_sensor_bins(transient)?;
        let plan = self.plan(&t)?;
        let mut means = self.linear_means(&t, &plan)?;
        let bins = t.bins();
        if self.pile_up {
            for h in means.chunks_exact_mut(bins) {
                let p = Self::first_photon_probabilities(h, plan.cycles);
                let armed = self.armed_cycles(&t, &p, plan.cycles);
                for (v, pk) in h.iter_mut().zip(&p) {
                    *v = armed * pk;
                }
            }
        }
        if self.afterpulse_probability > 0.0 {
            let g = self.afterpulse_kernel(&t);
            for h in means.chunks_exact_mut(bins) {
                let mut ap = vec![0.0; bins];
                for &(m, w) in &g {
                    for (j, &n) in h.iter().enumerate() {
                        let k = j as i64 + m;
                        if (0..bins as i64).contains(&k) {
                            ap[k as usize] += self.afterpulse_probability * w * n;
                        }
                    }
                }
                for (v, a) in h.iter_mut().zip(ap) {
                    *v += a;
                }
            }
        }
        let (scan, time, _) = t.into_parts();
        Transient::new(scan, time, means.into_iter().map(|v| v as f32).collect())
    }

    /// Simulates a photon-count capture from a transient of expected flux, reproducibly: the same
    /// `(model, transient, seed)` gives the same counts. Measurement `m` draws from
    /// [`Pcg32::new(seed, m)`](Pcg32::new). See the [module docs](self) for the process.
    ///
    /// # Errors
    /// As [`SpadModel::expected_counts`].
    pub fn simulate(&self, transient: &Transient, seed: u64) -> Result<Transient> {
        let t = self.on_sensor_bins(transient)?;
        let plan = self.plan(&t)?;
        let means = self.linear_means(&t, &plan)?;
        let bins = t.bins();
        let ax = *t.time();
        let period = if self.rep_rate > 0.0 { 1.0 / self.rep_rate } else { f64::INFINITY };
        let t_start = ax.t0 / SPEED_OF_LIGHT;
        let dt = ax.bin_width_seconds();
        let mut out = vec![0.0f32; means.len()];
        for (m, (h, o)) in means.chunks_exact(bins).zip(out.chunks_exact_mut(bins)).enumerate() {
            let mut rng = Pcg32::new(seed, m as u64);
            let mut counts = vec![0u64; bins];
            if self.pile_up {
                let p = Self::first_photon_probabilities(h, plan.cycles);
                let mut remaining = self.armed_cycles(&t, &p, plan.cycles) as u64;
                for (c, &mk) in counts.iter_mut().zip(h) {
                    if remaining == 0 {
                        break;
                    }
                    // Conditional on no detection before bin k: P(detect in k) = 1 − e^{−λ_k}.
                    let q = -(-mk / plan.cycles).exp_m1();
                    *c = rng.binomial(remaining, q);
                    remaining -= *c;
                }
            } else {
                for (c, &mk) in counts.iter_mut().zip(h) {
                    *c = rng.poisson(mk);
                }
            }
            if self.afterpulse_probability > 0.0 {
                let mut extra = vec![0u64; bins];
                for (k, &n) in counts.iter().enumerate() {
                    let a = rng.binomial(n, self.afterpulse_probability);
                    for _ in 0..a {
                        let t_det = t_start + (k as f64 + rng.uniform()) * dt;
                        let t_ap = t_det + self.dead_time + rng.exponential(self.afterpulse_time_constant);
                        let phase =
                            if period.is_finite() { (t_ap - t_start).rem_euclid(period) } else { t_ap - t_start };
                        let bin = (phase / dt).floor();
                        if bin >= 0.0 && bin < bins as f64 {
                            extra[bin as usize] += 1;
                        }
                    }
                }
                for (c, e) in counts.iter_mut().zip(extra) {
                    *c += e;
                }
            }
            for (v, c) in o.iter_mut().zip(counts) {
                *v = c as f32;
            }
        }
        let (scan, time, _) = t.into_parts();
        Transient::new(scan, time, out)
    }
}
