//! Tests of the sensor model. Statistical tests use fixed seeds (deterministic) and state their
//! significance: a two-sided z bound of 4.5 has level 6.8e-6 per check; χ² bounds are at level 1e-4.

#![allow(clippy::unwrap_used)]

use super::*;
use crate::rng;
use crate::{PointSet, Scan, TimeAxis};

/// A transient of `m` measurements (a 1×m grid) of `bins` bins of 1.2 mm, each a Gaussian pulse
/// (different centres) on zero.
fn pulses(m: usize, bins: usize, centre: f64, sigma: f64) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(m, 1, 0.25, 0.25).unwrap());
    let mut data = Vec::new();
    for i in 0..m {
        let c = centre + 3.0 * i as f64;
        data.extend((0..bins).map(|k| (-0.5 * ((k as f64 + 0.5 - c) / sigma).powi(2)).exp() as f32));
    }
    Transient::new(scan, TimeAxis::new(0.0, 0.0012, bins).unwrap(), data).unwrap()
}

/// Upper χ² quantile with `k` degrees of freedom (Wilson–Hilferty), for z the normal quantile.
fn chi2_upper(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}
/// Normal quantile for the level 1e-4 (one-sided).
const Z_1E4: f64 = 3.719;

fn moments(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var)
}

#[test]
fn poisson_sampler_mean_and_variance() {
    let n = 200_000;
    for (i, &lam) in [0.3, 4.0, 9.9, 10.0, 57.3, 2500.0, 1.0e7].iter().enumerate() {
        let mut g = Pcg32::new(42, i as u64);
        let x: Vec<f64> = (0..n).map(|_| g.poisson(lam) as f64).collect();
        let (mean, var) = moments(&x);
        let z_mean = (mean - lam) / (lam / n as f64).sqrt();
        let z_var = (var - lam) / ((lam + 2.0 * lam * lam) / n as f64).sqrt();
        eprintln!("Poisson λ={lam}: mean {mean:.5} (z {z_mean:.2}), variance {var:.5} (z {z_var:.2})");
        assert!(z_mean.abs() < 4.5 && z_var.abs() < 4.5, "λ={lam}: z_mean {z_mean}, z_var {z_var}");
    }
}

/// χ² goodness of fit of a discrete sampler against its pmf, cells with expected count ≥ 20 (the tails
/// pooled into the neighbouring cells).
fn chi2_fit(samples: &[u64], pmf: impl Fn(u64) -> f64, lo: u64, hi: u64) -> (f64, f64) {
    let n = samples.len() as f64;
    let mut obs = vec![0.0; (hi - lo + 1) as usize];
    for &s in samples {
        let i = s.clamp(lo, hi) - lo;
        obs[i as usize] += 1.0;
    }
    let mut exp: Vec<f64> = (lo..=hi).map(|k| n * pmf(k)).collect();
    let inner: f64 = exp.iter().sum();
    // Pool the tails into the end cells.
    let below: f64 = (0..lo).map(|k| n * pmf(k)).sum();
    exp[0] += below;
    let last = exp.len() - 1;
    exp[last] += n - inner - below;
    let stat: f64 = obs.iter().zip(&exp).map(|(o, e)| (o - e).powi(2) / e).sum();
    (stat, (exp.len() - 1) as f64)
}

#[test]
fn poisson_ptrs_chi_square() {
    let lam = 37.0f64;
    let mut g = Pcg32::new(7, 0);
    let s: Vec<u64> = (0..300_000).map(|_| g.poisson(lam)).collect();
    let pmf = |k: u64| (-lam + k as f64 * lam.ln() - rng::ln_factorial(k as f64)).exp();
    let (stat, dof) = chi2_fit(&s, pmf, 18, 60);
    eprintln!("PTRS λ=37: χ² = {stat:.1} on {dof} dof (bound {:.1})", chi2_upper(dof, Z_1E4));
    assert!(stat < chi2_upper(dof, Z_1E4));
}

#[test]
fn binomial_sampler_mean_variance_and_chi_square() {
    let n_s = 200_000;
    for (i, &(n, p)) in [(20u64, 0.3), (1000, 0.3), (100_000_000, 0.01), (50, 0.9), (3, 0.5)].iter().enumerate() {
        let mut g = Pcg32::new(11, i as u64);
        let x: Vec<f64> = (0..n_s).map(|_| g.binomial(n, p) as f64).collect();
        let (mean, var) = moments(&x);
        let (nf, q) = (n as f64, 1.0 - p);
        let (mu, s2) = (nf * p, nf * p * q);
        // Var of the sample variance ≈ (μ₄ − σ⁴)/n with the exact μ₄ = σ²(1 + 3(n−2)pq).
        let mu4 = s2 * (1.0 + 3.0 * (nf - 2.0) * p * q);
        let z_mean = (mean - mu) / (s2 / n_s as f64).sqrt();
        let z_var = (var - s2) / ((mu4 - s2 * s2) / n_s as f64).sqrt();
        eprintln!("Binomial({n}, {p}): mean {mean:.3} (z {z_mean:.2}), variance {var:.3} (z {z_var:.2})");
        assert!(z_mean.abs() < 4.5 && z_var.abs() < 4.5, "({n},{p}): z_mean {z_mean}, z_var {z_var}");
    }
    let (n, p) = (1000u64, 0.3f64);
    let mut g = Pcg32::new(5, 0);
    let s: Vec<u64> = (0..300_000).map(|_| g.binomial(n, p)).collect();
    let lf = rng::ln_factorial;
    let pmf = |k: u64| {
        let k = k as f64;
        (lf(1000.0) - lf(k) - lf(1000.0 - k) + k * p.ln() + (1000.0 - k) * (1.0 - p).ln()).exp()
    };
    let (stat, dof) = chi2_fit(&s, pmf, 255, 345);
    eprintln!("BTRS (1000, 0.3): χ² = {stat:.1} on {dof} dof (bound {:.1})", chi2_upper(dof, Z_1E4));
    assert!(stat < chi2_upper(dof, Z_1E4));
}

#[test]
fn simulated_counts_are_poisson_over_many_seeds() {
    // Ideal counter with jitter and background: n_k ~ Poisson(μ_k + b) independently.
    let t = pulses(2, 48, 20.0, 3.0);
    let model = SpadModel {
        jitter: Some(JitterResponse::gaussian(0.009).unwrap()),
        // 5e4 /s × 4.0 ps × 1e7 Hz × 1 s = 2.0 counts per bin: every bin's mean is ≥ 2, so the variance test
        // is sharp.
        background_rate: 5.0e4,
        exposure: 1.0,
        ..SpadModel::ideal(PhotonBudget::PerMeasurement(300.0))
    };
    let mean = model.expected_counts(&t).unwrap();
    let seeds = 4000u64;
    let len = mean.data().len();
    let (mut s1, mut s2) = (vec![0.0f64; len], vec![0.0f64; len]);
    for seed in 0..seeds {
        let c = model.simulate(&t, seed).unwrap();
        for (i, &v) in c.data().iter().enumerate() {
            assert_eq!(v.fract(), 0.0);
            s1[i] += f64::from(v);
            s2[i] += f64::from(v).powi(2);
        }
    }
    let s = seeds as f64;
    let (mut chi2, mut disp, mut disp_var) = (0.0, 0.0, 0.0);
    for i in 0..len {
        let mu = f64::from(mean.data()[i]);
        let m = s1[i] / s;
        let var = (s2[i] - s * m * m) / (s - 1.0);
        chi2 += (m - mu).powi(2) / (mu / s);
        disp += var / mu;
        disp_var += (2.0 + 1.0 / mu) / s;
    }
    let k = len as f64;
    let (disp, disp_se) = (disp / k, disp_var.sqrt() / k);
    let total: f64 = mean.data().iter().map(|&v| f64::from(v)).sum();
    eprintln!(
        "{seeds} seeds, {len} bins (expected total {total:.1}): mean χ² = {chi2:.1} on {k} dof (bound {:.1}); \
         variance/mean = {disp:.4} ± {disp_se:.4}",
        chi2_upper(k, Z_1E4)
    );
    assert!(chi2 < chi2_upper(k, Z_1E4));
    assert!((disp - 1.0).abs() < 4.5 * disp_se);
    // Background per bin: R·Δt·f_rep·T = 5e4 /s · 4.003 ps · 1e7 Hz · 1 s.
    let b = model.background_per_bin(0.0012);
    assert!((b - 5.0e4 * 0.0012 / crate::SPEED_OF_LIGHT * 1.0e7).abs() < 1e-12);
}

#[test]
fn pile_up_counts_match_expected_counts() {
    // First-photon model: the mean of the multinomial chain over seeds equals N·p_k.
    let t = pulses(1, 64, 30.0, 5.0);
    let model = SpadModel {
        afterpulse_probability: 0.0,
        rep_rate: 1.0e6,
        exposure: 0.01,
        ..SpadModel::ideal(PhotonBudget::PerMeasurement(8000.0))
    };
    let model = SpadModel { pile_up: true, dead_time: 50e-9, background_rate: 10.0, ..model };
    let mean = model.expected_counts(&t).unwrap();
    let seeds = 2000u64;
    let mut s1 = vec![0.0f64; 64];
    for seed in 0..seeds {
        for (a, &v) in s1.iter_mut().zip(model.simulate(&t, seed).unwrap().data()) {
            *a += f64::from(v);
        }
    }
    let s = seeds as f64;
    // Binomial-chain variance per bin ≤ mean, so the Poisson-variance χ² is conservative.
    let chi2: f64 =
        s1.iter().zip(mean.data()).map(|(a, &mu)| (a / s - f64::from(mu)).powi(2) / (f64::from(mu) / s)).sum();
    eprintln!("pile-up mean: χ² = {chi2:.1} on 64 dof (bound {:.1})", chi2_upper(64.0, Z_1E4));
    assert!(chi2 < chi2_upper(64.0, Z_1E4));
}

#[test]
fn jitter_convolution_conserves_flux_and_centroid() {
    let j = JitterResponse::gaussian(0.0108).unwrap(); // 36 ps
    assert!((j.fwhm() - 0.0108).abs() < 1e-3 * 0.0108, "fwhm {}", j.fwhm());
    for bw in [0.0012, 0.0005, 0.004, 0.0301] {
        let k = j.to_bins(bw).unwrap();
        let sum: f64 = k.weights().iter().sum();
        assert!((sum - 1.0).abs() < 1e-12);
        let centroid: f64 = k.weights().iter().enumerate().map(|(i, w)| w * (k.first() + i as i64) as f64).sum();
        assert!(centroid.abs() < 1e-9, "bw {bw}: centroid {centroid} bins");
    }
    let t = pulses(3, 400, 150.0, 4.0);
    let k = j.to_bins(0.0012).unwrap();
    let out = k.apply(t.data(), 400).unwrap();
    for (a, b) in t.histograms().zip(out.chunks_exact(400)) {
        let (sa, sb): (f64, f64) = (a.iter().map(|&v| f64::from(v)).sum(), b.iter().map(|&v| f64::from(v)).sum());
        assert!((sa - sb).abs() < 1e-5 * sa, "{sa} vs {sb}");
    }
}

#[test]
fn jitter_adjoint_passes_dot_product_test() {
    let j = JitterResponse::gaussian(0.02).unwrap();
    let mut k = j.to_bins(0.0012).unwrap();
    // Also an asymmetric kernel reaching beyond both ends of a short axis.
    let asym = BinKernel::new(-3, vec![0.1, 0.5, 0.2, 0.0, 0.7, 0.3, 0.05]).unwrap();
    let mut g = Pcg32::new(3, 0);
    for bins in [5usize, 64] {
        for kern in [&mut k, &mut asym.clone()] {
            let x: Vec<f64> = (0..3 * bins).map(|_| g.uniform() - 0.3).collect();
            let y: Vec<f64> = (0..3 * bins).map(|_| g.uniform() - 0.6).collect();
            let (mut ax, mut aty) = (vec![0.0; x.len()], vec![0.0; y.len()]);
            kern.apply_f64(&x, bins, &mut ax).unwrap();
            kern.adjoint_f64(&y, bins, &mut aty).unwrap();
            let lhs: f64 = ax.iter().zip(&y).map(|(a, b)| a * b).sum();
            let rhs: f64 = x.iter().zip(&aty).map(|(a, b)| a * b).sum();
            assert!((lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0), "{lhs} vs {rhs}");
        }
    }
}

/// A high-flux capture: pile-up skews the histogram early; Coates' correction recovers the shape.
#[test]
fn pile_up_skews_early_and_coates_recovers_shape() {
    let bins = 200;
    let t = pulses(1, bins, 100.0, 15.0);
    let cycles = 1.0e8;
    // Σ_k λ_k = 1.5 photons per cycle: strong pile-up (only 1 − e^{−1.5} = 78 % of cycles detect).
    let model = SpadModel {
        pile_up: true,
        dead_time: 50e-9,
        rep_rate: 10e6,
        exposure: cycles / 10e6,
        ..SpadModel::ideal(PhotonBudget::PerMeasurement(1.5 * cycles))
    };
    let counts = model.simulate(&t, 2024).unwrap();
    let truth: Vec<f64> = t.data().iter().map(|&v| f64::from(v)).collect();
    let n: Vec<f64> = counts.data().iter().map(|&v| f64::from(v)).collect();
    let centroid = |h: &[f64]| {
        let s: f64 = h.iter().sum();
        h.iter().enumerate().map(|(k, v)| (k as f64 + 0.5) * v).sum::<f64>() / s
    };
    // Theory: p_k = (1 − e^{−λ_k}) e^{−Σ_{j<k} λ_j}.
    let s_truth: f64 = truth.iter().sum();
    let lam: Vec<f64> = truth.iter().map(|v| 1.5 * v / s_truth).collect();
    let mut acc = 0.0f64;
    let p: Vec<f64> = lam
        .iter()
        .map(|&l| {
            let p = (1.0 - (-l).exp()) * (-acc).exp();
            acc += l;
            p
        })
        .collect();
    let (c_true, c_sim, c_theory) = (centroid(&truth), centroid(&n), centroid(&p));
    eprintln!(
        "pile-up (Σλ = 1.5/cycle): centroid truth {c_true:.3} bins, simulated {c_sim:.3}, theory {c_theory:.3}; \
         detected {:.4} of cycles (theory {:.4})",
        n.iter().sum::<f64>() / cycles,
        1.0 - (-1.5f64).exp()
    );
    assert!(c_sim < c_true - 5.0, "no early skew");
    assert!((c_sim - c_theory).abs() < 0.01);
    let corrected = coates_correction(&counts, cycles).unwrap();
    let c: Vec<f64> = corrected.data().iter().map(|&v| f64::from(v)).collect();
    let s_c: f64 = c.iter().sum();
    let peak = truth.iter().copied().fold(0.0, f64::max);
    let (mut worst_raw, mut worst_cor) = (0.0f64, 0.0f64);
    let s_n: f64 = n.iter().sum();
    for k in 0..bins {
        if truth[k] > 0.05 * peak {
            let tr = truth[k] / s_truth;
            worst_cor = worst_cor.max((c[k] / s_c - tr).abs() / tr);
            worst_raw = worst_raw.max((n[k] / s_n - tr).abs() / tr);
        }
    }
    eprintln!(
        "shape error over bins above 5 % of peak: raw {:.1} %, Coates-corrected {:.3} %",
        100.0 * worst_raw,
        100.0 * worst_cor
    );
    assert!(worst_raw > 0.2);
    assert!(worst_cor < 0.02);
    // Coates recovers the absolute flux too: Σ N·λ̂ ≈ 1.5·N.
    assert!((s_c / (1.5 * cycles) - 1.0).abs() < 0.01);
}

#[test]
fn hold_off_across_cycles_loses_cycles() {
    let t = pulses(1, 100, 50.0, 5.0);
    let base = SpadModel {
        pile_up: true,
        rep_rate: 10e6,
        exposure: 0.01,
        ..SpadModel::ideal(PhotonBudget::PerMeasurement(5.0e4))
    };
    let short = base.expected_counts(&t).unwrap();
    // 150 ns hold-off at 100 ns period: every detection costs the next cycle, N_armed = N/(1 + P_det).
    let long = SpadModel { dead_time: 150e-9, ..base.clone() }.expected_counts(&t).unwrap();
    let (ss, sl): (f64, f64) =
        (short.data().iter().map(|&v| f64::from(v)).sum(), long.data().iter().map(|&v| f64::from(v)).sum());
    let n = 1.0e5;
    let p_det = ss / n;
    assert!((sl - (n / (1.0 + p_det)).round() * p_det).abs() < 1e-3 * sl, "{sl} vs {}", n / (1.0 + p_det) * p_det);
}

#[test]
fn afterpulses_match_expected_counts() {
    let t = pulses(1, 300, 60.0, 4.0);
    let model = SpadModel {
        afterpulse_probability: 0.05,
        afterpulse_time_constant: 0.2e-9,
        dead_time: 0.1e-9,
        rep_rate: 10e6,
        pile_up: false,
        ..SpadModel::ideal(PhotonBudget::PerMeasurement(2000.0))
    };
    let mean = model.expected_counts(&t).unwrap();
    let plain = SpadModel { afterpulse_probability: 0.0, ..model.clone() }.expected_counts(&t).unwrap();
    let ap_mean: f64 = mean.data().iter().zip(plain.data()).map(|(a, b)| f64::from(a - b)).sum();
    let seeds = 400;
    let mut total = 0.0;
    for seed in 0..seeds {
        total += model.simulate(&t, seed).unwrap().data().iter().map(|&v| f64::from(v)).sum::<f64>();
    }
    let sim_mean = total / seeds as f64;
    let expected: f64 = mean.data().iter().map(|&v| f64::from(v)).sum();
    eprintln!("afterpulses: expected {ap_mean:.2} per measurement; total counts sim {sim_mean:.2} vs {expected:.2}");
    assert!(ap_mean > 0.03 * 2000.0);
    assert!((sim_mean - expected).abs() < 4.5 * (expected / seeds as f64).sqrt());
}

#[test]
fn jitter_files_load_and_report_fwhm() {
    for name in ["spad_jitter.mat", "spad_impulse_response.hdf5"] {
        let Some(path) = nlos_testdata::shared(&format!("sensor/{name}")) else { continue };
        let j = JitterResponse::load(&path).unwrap();
        let fwhm = j.fwhm();
        eprintln!(
            "{name}: FWHM {:.2} ps = {:.3} mm of path; mean delay {:.2} ps; {} samples of {:.4} ps; \
             on 1.2 mm bins: {} bins",
            j.fwhm_ps(),
            fwhm * 1e3,
            j.mean_delay() / crate::SPEED_OF_LIGHT * 1e12,
            j.weights().len(),
            j.spacing() / crate::SPEED_OF_LIGHT * 1e12,
            j.to_bins(0.0012).unwrap().weights().len()
        );
        assert!((15.0..80.0).contains(&j.fwhm_ps()), "implausible FWHM {} ps", j.fwhm_ps());
        let k = j.to_bins(0.0012).unwrap();
        assert!((k.weights().iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
    if let Some(path) = nlos_testdata::shared("sensor/spad_jitter.mat") {
        // The file's times are seconds: 0.814 ps spacing, so the samples are ~0.244 mm of path apart.
        let j = JitterResponse::load(&path).unwrap();
        assert!((j.spacing() / crate::SPEED_OF_LIGHT * 1e12 - 0.814).abs() < 0.01);
    }
}

#[test]
fn nll_gradient_matches_central_differences() {
    let bins = 40;
    let j = JitterResponse::gaussian(0.006).unwrap().to_bins(0.0012).unwrap();
    let mut g = Pcg32::new(9, 0);
    let flux: Vec<f32> = (0..2 * bins).map(|_| (0.2 + 2.0 * g.uniform()) as f32).collect();
    let counts: Vec<f32> = flux.iter().map(|&f| g.poisson(3.0 * f64::from(f) + 0.5) as f32).collect();
    let (alpha, b) = (2.5, 0.7);
    let r = poisson_nll(&flux, &counts, bins, &j, alpha, b).unwrap();
    let f = |x: &[f32], a: f64, bg: f64| poisson_nll(x, &counts, bins, &j, a, bg).unwrap().value;
    for i in [0usize, 7, 39, 40, 63, 79] {
        let h = 1e-2f32;
        let (mut xp, mut xm) = (flux.clone(), flux.clone());
        xp[i] += h;
        xm[i] -= h;
        let step = f64::from(xp[i]) - f64::from(xm[i]);
        let fd = (f(&xp, alpha, b) - f(&xm, alpha, b)) / step;
        assert!(
            (fd - r.grad_flux[i]).abs() < 1e-4 * r.grad_flux[i].abs().max(1.0),
            "x[{i}]: {fd} vs {}",
            r.grad_flux[i]
        );
    }
    let h = 1e-5;
    let fd_a = (f(&flux, alpha + h, b) - f(&flux, alpha - h, b)) / (2.0 * h);
    let fd_b = (f(&flux, alpha, b + h) - f(&flux, alpha, b - h)) / (2.0 * h);
    assert!((fd_a - r.grad_scale).abs() < 1e-5 * r.grad_scale.abs().max(1.0), "{fd_a} vs {}", r.grad_scale);
    assert!((fd_b - r.grad_background).abs() < 1e-5 * r.grad_background.abs().max(1.0));
    // Analytic special case: counts equal to the model ⇒ value 0 and zero gradients.
    let mut ax = vec![0.0; flux.len()];
    let xd: Vec<f64> = flux.iter().map(|&v| f64::from(v)).collect();
    j.apply_f64(&xd, bins, &mut ax).unwrap();
    let exact: Vec<f32> = ax.iter().map(|v| (alpha * v + b) as f32).collect();
    let z = poisson_nll(&flux, &exact, bins, &j, alpha, b).unwrap();
    assert!(z.value.abs() < 1e-9 && z.grad_scale.abs() < 1e-5, "{} {}", z.value, z.grad_scale);
}

#[test]
fn background_is_estimated_before_the_first_return() {
    let t = pulses(16, 300, 200.0, 5.0);
    let model =
        SpadModel { background_rate: 1.0e4, exposure: 1.0, ..SpadModel::ideal(PhotonBudget::PerMeasurement(5e4)) };
    let b_true = model.background_per_bin(0.0012);
    let c = model.simulate(&t, 1).unwrap();
    let est = estimate_background(&c, BackgroundWindow::BeforeFirstReturn).unwrap();
    eprintln!(
        "background: true {b_true:.3}/bin, estimated {:.3} ± {:.3} (median {:.3}) over bins {:?}",
        est.per_bin, est.std_error, est.per_bin_median, est.window
    );
    assert!((est.per_bin - b_true).abs() < 4.5 * est.std_error);
    assert!(est.window.1 > 100 && est.window.1 < 190);
    let path = estimate_background(&c, BackgroundWindow::Path { start: 0.0, end: 0.12 }).unwrap();
    assert_eq!(path.window, (0, 100));
    let s = count_summary(&c, BackgroundWindow::Bins { start: 0, end: 100 }).unwrap();
    assert!(s.integer_counts && (s.signal_per_measurement - 5e4).abs() < 0.01 * 5e4, "{s:?}");
    assert_eq!(estimate_background(&c, BackgroundWindow::Auto).unwrap().window, est.window);
    // A capture cropped inside its first return: Auto falls back to the last 10 % of the axis.
    let early = model.simulate(&pulses(2, 300, 2.0, 5.0), 3).unwrap();
    assert!(estimate_background(&early, BackgroundWindow::BeforeFirstReturn).is_err());
    let late = estimate_background(&early, BackgroundWindow::Auto).unwrap();
    assert_eq!(late.window, (270, 300));
    assert!((late.per_bin - b_true).abs() < 4.5 * late.std_error);
    assert!(estimate_background(&c, BackgroundWindow::Bins { start: 10, end: 10 }).is_err());
    assert!(estimate_background(&c, BackgroundWindow::Bins { start: 0, end: 301 }).is_err());
}

#[test]
fn bad_parameters_give_typed_errors() {
    let t = pulses(1, 50, 20.0, 3.0);
    let name = |m: SpadModel| match m.simulate(&t, 0) {
        Err(TransientError::InvalidArgument { name, .. }) => name,
        other => panic!("expected InvalidArgument, got {other:?}"),
    };
    let d = SpadModel::default();
    assert_eq!(name(SpadModel { background_rate: -1.0, ..d.clone() }), "background_rate");
    assert_eq!(name(SpadModel { background_rate: f64::NAN, ..d.clone() }), "background_rate");
    assert_eq!(name(SpadModel { detection_probability: f64::NAN, ..d.clone() }), "detection_probability");
    assert_eq!(name(SpadModel { detection_probability: 1.5, ..d.clone() }), "detection_probability");
    assert_eq!(name(SpadModel { dead_time: 50e-9, rep_rate: 0.0, pile_up: false, ..d.clone() }), "rep_rate");
    assert_eq!(name(SpadModel { rep_rate: 0.0, ..d.clone() }), "rep_rate");
    assert_eq!(name(SpadModel { dead_time: -1e-9, ..d.clone() }), "dead_time");
    assert_eq!(name(SpadModel { exposure: 0.0, ..d.clone() }), "exposure");
    assert_eq!(name(SpadModel { afterpulse_probability: 1.0, ..d.clone() }), "afterpulse_probability");
    assert_eq!(name(SpadModel { photons: PhotonBudget::Total(-5.0), ..d.clone() }), "photons");
    assert_eq!(name(SpadModel { photons: PhotonBudget::PerMeasurement(f64::INFINITY), ..d.clone() }), "photons");
    assert_eq!(name(SpadModel { bin_width: Some(0.0018), ..d.clone() }), "bin_width");
    assert_eq!(name(SpadModel { rep_rate: 5.0, exposure: 0.1, ..d.clone() }), "exposure");
    let mut neg = t.clone();
    neg.data_mut()[3] = -1.0;
    assert!(matches!(d.simulate(&neg, 0), Err(TransientError::InvalidArgument { name: "transient", .. })));
    assert!(JitterResponse::gaussian(f64::NAN).is_err());
    assert!(JitterResponse::gaussian(-1.0).is_err());
    assert!(JitterResponse::from_histogram(0.0, 1e-3, &[1.0, f64::NAN], false).is_err());
    assert!(JitterResponse::from_histogram(0.0, 0.0, &[1.0], false).is_err());
    assert!(JitterResponse::gaussian(0.01).unwrap().to_bins(f64::NAN).is_err());
    assert!(JitterResponse::gaussian(0.01).unwrap().to_bins(1e-12).is_err());
    assert!(coates_histogram(&[1.0, 2.0], 0.0).is_err());
    assert!(coates_histogram(&[5.0, 6.0], 10.0).is_err());
    assert!(coates_histogram(&[-1.0], 10.0).is_err());
    let k = BinKernel::identity();
    assert!(poisson_nll(&[1.0], &[-1.0], 1, &k, 1.0, 0.0).is_err());
    assert!(poisson_nll(&[1.0], &[1.0], 1, &k, f64::NAN, 0.0).is_err());
    assert!(poisson_nll(&[1.0], &[1.0, 2.0], 1, &k, 1.0, 0.0).is_err());
    assert!(poisson_nll(&[1.0], &[1.0], 1, &k, 1.0, -0.1).is_err());
    assert!(k.apply(&[1.0, 2.0, 3.0], 2).is_err());
    // Rebinning onto a coarser sensor bin works when it is an integer multiple.
    let r = SpadModel { bin_width: Some(0.0024), ..d.clone() }.simulate(&t, 0).unwrap();
    assert_eq!(r.bins(), 25);
}

/// The capture's own response from its direct return: a 4 × 4 confocal capture whose histograms hold a
/// heavy-tailed response at path 0 (peak at bin 3: a rising side on the axis), the same response around a
/// hidden return at bin 250, and a flat background. The response comes back sample for sample, zero delay at
/// its peak; a capture without direct light (or gated) is a typed error.
#[test]
fn response_from_the_direct_return_recovers_the_impulse_response() {
    let bins = 500;
    // h[d], d = −3..=120: a steep rise, then a fast and a slow exponential (a SPAD's diffusion tail).
    let h: Vec<f64> = (-3i32..=120)
        .map(|d| {
            let d = f64::from(d);
            if d < 0.0 { (-0.5 * (d / 1.5).powi(2)).exp() } else { 0.7 * (-d / 6.0).exp() + 0.3 * (-d / 40.0).exp() }
        })
        .collect();
    let background = 0.5;
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.25, 0.25).unwrap());
    let mut data = Vec::new();
    for m in 0..16 {
        let (direct, hidden) = (1e4 * (1.0 + 0.1 * m as f64), 30.0);
        let mut hist = vec![background; bins];
        for (i, &v) in h.iter().enumerate() {
            hist[i] += direct * v; // peak (d = 0) at bin 3
            hist[247 + i] += hidden * v;
        }
        data.extend(hist.iter().map(|&v| v as f32));
    }
    let t = Transient::new(scan, TimeAxis::new(0.0, 0.0012, bins).unwrap(), data).unwrap();
    let r = JitterResponse::from_direct_return(&t).unwrap();
    let total: f64 = h.iter().sum();
    assert!((r.origin() - (-3.5 * 0.0012)).abs() < 1e-12, "zero delay at the peak: origin {}", r.origin());
    assert!(r.weights().len() >= 100, "the tail is kept: {} samples", r.weights().len());
    for (i, (&w, &v)) in r.weights().iter().zip(&h).enumerate() {
        // The response is cut where the direct light ends: compare relative to the kept mass.
        let kept: f64 = h[..r.weights().len()].iter().sum();
        assert!((w - v / kept).abs() < 1e-6 * (v / total).max(1e-3), "sample {i}: {w} vs {}", v / kept);
    }
    // Without direct light (the same capture gated before the hidden return) there is nothing to take.
    let gated = t.gate(0.30).unwrap();
    let e = JitterResponse::from_direct_return(&gated).unwrap_err();
    assert!(e.to_string().contains("direct return"), "{e}");
    // Regression (error_message_of_a_capture_without_direct_light_has_no_blank_run): the message once carried
    // a run of blanks where a line continuation had been lost.
    assert!(!e.to_string().contains("  "), "{e}");
}

/// `apply_window` gives exactly (bit for bit) the whole histogram's `apply_f64` on the bins of its window,
/// for kernels that reach before and after the bin, windows at either end, and windows past the row.
#[test]
fn apply_window_is_the_whole_rows_convolution_on_its_bins() {
    let bins = 40;
    let x: Vec<f32> = (0..bins).map(|k| ((k * 37 % 11) as f32 + 0.5) * 0.1).collect();
    let xd: Vec<f64> = x.iter().map(|&v| f64::from(v)).collect();
    for (first, weights) in [(0, vec![1.0]), (-2, vec![0.1, 0.2, 0.4, 0.2, 0.1]), (3, vec![0.5, 0.3, 0.2])] {
        let kern = BinKernel::new(first, weights).unwrap();
        let mut whole = vec![0.0; bins];
        kern.apply_f64(&xd, bins, &mut whole).unwrap();
        for window in [0..bins, 0..5, 17..23, 35..bins, 38..60, 50..70] {
            let part = kern.apply_window(&x, window.clone());
            let (lo, hi) = (window.start.min(bins), window.end.min(bins));
            assert_eq!(part.len(), hi.saturating_sub(lo), "{window:?}");
            for (k, v) in (lo..hi).zip(&part) {
                assert_eq!(v.to_bits(), whole[k].to_bits(), "bin {k}, kernel from {first}");
            }
        }
    }
}

/// A direct return cut at its maximum (a pre-rectified capture) gets back the rising side its top implies:
/// a Gaussian core of σ = 5 bins with a slow tail after it, cut 1 bin after its centre, is completed with a
/// Gaussian of that width whose centre is zero delay; a return that keeps its rising side is not touched.
#[test]
fn rising_side_cut_by_the_axis_is_completed_from_the_top() {
    let sigma = 5.0;
    // The response at x bins from its centre: a Gaussian core, then a slow exponential tail after it.
    let h = |x: f64| (-0.5 * (x / sigma).powi(2)).exp() + if x > 0.0 { 0.05 * (1.0 - (-x / 3.0).exp()) } else { 0.0 };
    // Cut 1.0 bin after the centre: bin k's centre is at x = k + 0.5 + 0.5.
    let cut: Vec<f64> = (0..200).map(|k| h(k as f64 + 1.0)).collect();
    let (done, zero) = jitter::complete_rising_side(cut.clone(), 0);
    let before = done.len() - cut.len();
    assert_eq!(&done[before..], &cut[..], "the recorded bins are kept");
    // Zero delay at the Gaussian's centre, half a bin before the recorded axis's start.
    assert!(
        (zero - (before as f64 - 0.5)).abs() < 0.35,
        "zero delay at {zero} bins, the centre at {}",
        before as f64 - 0.5
    );
    // Down to about 3σ before the centre, and the filled bins follow the Gaussian.
    assert!((14..=17).contains(&before), "{before} bins put before the axis");
    for (j, &v) in done[..before].iter().enumerate() {
        let x = j as f64 + 0.5 - zero;
        let want = h(x.min(0.0));
        assert!((v - want).abs() < 0.08 * want + 1e-3, "bin {j} (x = {x:.2}): {v} vs {want}");
    }
    // A return with its rising side (maximum 4 bins in) is whole.
    let whole: Vec<f64> = (0..200).map(|k| h(k as f64 + 0.5 - 4.0)).collect();
    let (same, zero) = jitter::complete_rising_side(whole.clone(), 4);
    assert_eq!(same, whole);
    assert_eq!(zero, 4.5);
    // A flat top (no curvature to fit) is not completed.
    let (flat, zero) = jitter::complete_rising_side(vec![1.0; 50], 0);
    assert_eq!((flat.len(), zero), (50, 0.5));
}

/// A top that falls too slowly to be a peak (a plateau: its Gaussian would be wider than any sensor's) and a
/// degenerate one (all equal but the first) are left as they are, with no allocation on the width's scale.
#[test]
fn plateau_or_degenerate_top_is_not_completed() {
    let plateau: Vec<f64> = (0..100).map(|k| 1.0 - 1e-9 * (k * k) as f64).collect();
    let (out, zero) = jitter::complete_rising_side(plateau.clone(), 0);
    assert_eq!((out, zero), (plateau, 0.5));
    let flat: Vec<f64> = std::iter::once(2.0).chain(std::iter::repeat_n(1.9, 40)).collect();
    let (out, _) = jitter::complete_rising_side(flat.clone(), 0);
    assert!(out.len() <= flat.len() + 3 * 128 + 2, "{} bins", out.len());
}

/// The response of [`raw_and_gated`]: a Gaussian rise (σ = 4 bins) and, after its peak, 90 % Gaussian fall
/// and 10 % exponential diffusion tail (τ = 60 bins), at `j` bins from its peak.
fn tailed_response(j: f64) -> f64 {
    let g = (-0.5 * (j / 4.0).powi(2)).exp();
    if j < 0.0 { g } else { 0.9 * g + 0.1 * (-j / 60.0).exp() }
}

/// A raw confocal capture as the Stanford files hold them (1,600 bins of 1.2 mm, 16 × 16 spots, Poisson
/// counts): the direct reflection from bin 0 on (its rising side cut), one hidden return per spot at bins
/// 1,100–1,163 (four spots each) through the same response, `b` background counts per bin; and the same capture with bins
/// 0..600 zeroed, as Tsai et al.'s `transient.mat` zeroes bins 1–600 (the direct light's tail is left).
fn raw_and_gated(b: f64) -> (Transient, Transient) {
    let scan = Scan::confocal(PointSet::wall_grid(16, 16, 0.25, 0.25).unwrap());
    let bins = 1600;
    let mut data = Vec::with_capacity(256 * bins);
    for m in 0..256 {
        let mut rng = rng::Pcg32::new(7, m as u64);
        let centre = 1100.0 + (m / 4) as f64;
        data.extend((0..bins).map(|k| {
            let k = k as f64;
            let mean = 2.0e4 * tailed_response(k) + 40.0 * tailed_response(k - centre) + b;
            rng.poisson(mean) as f32
        }));
    }
    let raw = Transient::new(scan, TimeAxis::new(0.0, 0.0012, bins).unwrap(), data).unwrap();
    let mut gated = raw.clone();
    for m in 0..256 {
        gated.histogram_mut(m)[..600].fill(0.0);
    }
    (raw, gated)
}

#[test]
fn a_gated_capture_is_recognised_and_estimated_after_its_gate() {
    let b_true = 0.05;
    let (raw, gated) = raw_and_gated(b_true);
    assert_eq!(raw.zero_gate(), None, "the raw capture has no zeroed bins");
    assert_eq!(gated.zero_gate(), Some(600));
    // What the gate left of the direct light's tail ends where the raw capture's does.
    let (end_raw, end_gated) = (raw.direct_light_end(), gated.direct_light_end());
    assert!(end_raw > 600.0 * 0.0012 && end_raw < 1100.0 * 0.0012, "raw direct light ends at {end_raw}");
    assert_eq!(end_gated, end_raw);
    // The background comes from the bins between the gate and the first hidden return, after the direct
    // light's tail: not from the zeros (which would give nearly 0) nor from the tail.
    let est = estimate_background(&gated, BackgroundWindow::Auto).unwrap();
    assert!(est.window.0 > 700 && est.window.1 > est.window.0 + 100 && est.window.1 < 1100, "{:?}", est.window);
    assert!((est.per_bin - b_true).abs() < 4.5 * est.std_error, "background {est:?}");
    // The raw capture, cropped to start inside its direct light (as the Stanford files are), reads the
    // later half of the same quiet stretch: its direct light is followed down to the hidden return's level
    // and skipped as the gate's tail is (here the tail is quiet before bin 600, so the stretch starts a
    // little earlier than the gate; on the Stanford S and U both read bins 783..940).
    let from_raw = estimate_background(&raw, BackgroundWindow::Auto).unwrap();
    assert_eq!(from_raw.window.1, est.window.1);
    assert!(from_raw.window.0 > 700 && from_raw.window.0 <= est.window.0, "{:?}", from_raw.window);
    assert!((from_raw.per_bin - b_true).abs() < 4.5 * from_raw.std_error, "background {from_raw:?}");
    // The fit's floor (the axis's end) is the same bins in both, zeros or no zeros before it.
    let (floor_raw, floor_gated) = (
        estimate_background(&raw, BackgroundWindow::AxisEnd).unwrap(),
        estimate_background(&gated, BackgroundWindow::AxisEnd).unwrap(),
    );
    assert_eq!(floor_raw.window, (1440, 1600));
    assert_eq!(floor_raw, floor_gated);
    // A noiseless simulation starts with zeros too, but what follows them is its first return: no gate.
    let sim = pulses(4, 300, 200.0, 5.0);
    assert!(sim.leading_zero_bins() > 100);
    assert_eq!(sim.zero_gate(), None);
    // An abrupt first return (a flat face facing the wall) does not rise over the 16 bins after the zeros,
    // but without background the bins after the return are dark too: no gate (the soap bar's capture).
    let mut abrupt = sim.clone();
    for m in 0..4 {
        let h = abrupt.histogram_mut(m);
        h.fill(0.0);
        h[150..170].fill(3.0);
    }
    assert_eq!(abrupt.leading_zero_bins(), 150);
    assert_eq!(abrupt.zero_gate(), None);
    // With background after the zeros, they are a gate.
    for m in 0..4 {
        for v in &mut abrupt.histogram_mut(m)[150..] {
            *v += 0.05;
        }
    }
    assert_eq!(abrupt.zero_gate(), Some(150));
}

#[test]
fn a_gated_capture_gives_its_response_from_the_first_strong_return() {
    let (raw, gated) = raw_and_gated(0.05);
    assert!(JitterResponse::from_direct_return(&gated).is_err(), "the gate removed the direct reflection");
    let direct = JitterResponse::from_direct_return(&raw).unwrap();
    let first = JitterResponse::from_first_return(&gated).unwrap();
    // The truth: the response sampled per bin, its peak at zero delay.
    let w: Vec<f64> = (-30..=125).map(|j| tailed_response(f64::from(j))).collect();
    let truth = JitterResponse::from_histogram(-30.0 * 0.0012, 0.0012, &w, false).unwrap();
    eprintln!(
        "FWHM truth {:.4} first-return {:.4} direct {:.4}; mean delay truth {:.4} first-return {:.4}",
        truth.fwhm(),
        first.fwhm(),
        direct.fwhm(),
        truth.mean_delay(),
        first.mean_delay()
    );
    // Within two bins in width and in mean delay (its tail is cut at 150 mm and carries the noise of 3
    // spots' returns).
    assert!((first.fwhm() - truth.fwhm()).abs() < 2.0 * 0.0012, "FWHM {} against {}", first.fwhm(), truth.fwhm());
    assert!((first.mean_delay() - truth.mean_delay()).abs() < 2.0 * 0.0012);
    // No light after the gate at all: a typed error naming the field.
    let mut dark = gated.clone();
    dark.data_mut().fill(0.0);
    let e = JitterResponse::from_first_return(&dark).unwrap_err();
    assert!(e.to_string().contains("first return"), "{e}");
}
