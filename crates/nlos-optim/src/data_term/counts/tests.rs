use super::*;
use nlos_transient::sensor::poisson_nll;

const BINS: usize = 30;

fn setup() -> (SensorFit, Vec<f32>, Vec<f32>) {
    let kernel = BinKernel::new(-1, vec![0.2, 0.5, 0.2, 0.1]).expect("kernel");
    let fit = SensorFit { kernel, background: SensorBackground::Fixed(0.7) };
    // Two histograms of a bump plus zeros; counts from a different bump (the fit is not exact).
    let rendered: Vec<f32> =
        (0..2 * BINS).map(|i| ((i % BINS) as f32 - 12.0).abs().max(0.0).mul_add(-0.1, 1.0).max(0.0)).collect();
    let counts: Vec<f32> =
        (0..2 * BINS).map(|i| ((i * 7 + 3) % 11) as f32 + if i % BINS > 8 { 4.0 } else { 0.0 }).collect();
    (fit, rendered, counts)
}

/// The share path of [`SensorRows`] (one convolution of the share, `J I` cached or not) gives the changes
/// that convolving each shifted row gives ([`crate::data_term::RowTerm`]'s default), for responses that reach before and
/// after a bin and shares at either end of the row.
#[test]
fn sensor_rows_changes_match_the_shifted_rows() {
    use crate::data_term::RowTerm;
    let (_, rendered, counts) = setup();
    for (first, weights) in [(-1, vec![0.2, 0.5, 0.2, 0.1]), (2, vec![0.6, 0.3, 0.1]), (-6, vec![0.1; 10])] {
        let fit = SensorFit {
            kernel: BinKernel::new(first, weights).expect("kernel"),
            background: SensorBackground::Fixed(0.7),
        };
        let rows = SensorRows { fit: &fit, counts: &counts, bins: BINS, background: 0.7, scale: 3.0, response: None };
        let generic = |m: usize, row: &[f32], w: std::ops::Range<usize>| rows.value(m, row, w);
        for (first_bin, len) in [(0, 4), (10, 6), (26, 4), (27, 9)] {
            let values: Vec<f32> = (0..len).map(|i| 0.05 + 0.03 * i as f32).collect();
            let share = nlos_render::RowSpan { measurement: 1, first_bin, values };
            // A row that holds the share (a deletion leaves it ≥ 0, as the generic path's clamp assumes).
            let mut row = rendered[BINS..2 * BINS].to_vec();
            for (x, v) in row[first_bin..].iter_mut().zip(&share.values) {
                *x += v;
            }
            let ks = [-1.0, 1.0, 2.0];
            let fast = rows.changes(1, &row, &share, &ks).expect("fast");
            let slow = generic.changes(1, &row, &share, &ks).expect("slow");
            // The generic path rounds the shifted row to f32 (relative 6e-8 per bin); the share path does not.
            for (a, b) in fast.iter().zip(&slow) {
                assert!(a != &0.0 && (a - b).abs() <= 1e-6 * b.abs(), "{first} {first_bin}: {a} vs {b}");
            }
            // With `J I` cached (as pruning runs it): the same changes; after `applied` takes the share away,
            // the cache is `J` of the row without it, and the changes are those of that row.
            let mut both = rendered.clone();
            both[BINS..].copy_from_slice(&row);
            let lock = RwLock::new(fit.jitter(&both, BINS).expect("J I"));
            let cached = SensorRows { response: Some(&lock), ..rows };
            let with_cache = cached.changes(1, &row, &share, &ks).expect("cached");
            for (a, b) in with_cache.iter().zip(&fast) {
                assert!((a - b).abs() <= 1e-9 * b.abs(), "cached {first} {first_bin}: {a} vs {b}");
            }
            cached.applied(std::slice::from_ref(&share), false).expect("applied");
            let mut without = both.clone();
            for (x, v) in without[BINS + first_bin..].iter_mut().zip(&share.values) {
                *x -= v;
            }
            let want = fit.jitter(&without, BINS).expect("J I");
            let got = lock.read().expect("lock");
            for (a, b) in got.iter().zip(&want) {
                assert!((a - b).abs() <= 1e-6 * (1.0 + b.abs()), "applied {first} {first_bin}: {a} vs {b}");
            }
            drop(got);
            let after = cached.changes(1, &without[BINS..], &share, &ks).expect("after");
            let plain = rows.changes(1, &without[BINS..], &share, &ks).expect("plain");
            for (a, b) in after.iter().zip(&plain) {
                assert!((a - b).abs() <= 1e-6 * (1.0 + b.abs()), "after {first} {first_bin}: {a} vs {b}");
            }
        }
    }
}

/// The change of one bin's deviance equals the difference of the deviances, on both sides of the series'
/// switch and without counts (where the difference would cancel in f64, the series is the more exact);
/// and a row's change is the sum of its bins'.
#[test]
fn deviance_change_is_the_difference_of_deviances() {
    let cases =
        [(0.4, 0.3, 2.0), (0.4, 3e-4, 1.0), (5.0, 4.9e-3, 7.0), (5.0, -2.0, 3.0), (1.0, 0.5, 0.0), (0.3, 40.0, 9.0)];
    let mut sum = 0.0;
    for (mu, delta, n) in cases {
        let want = half_deviance(mu + delta, n) - half_deviance(mu, n);
        let got = deviance_changes(&[mu], &[delta], &[n], 1.0);
        assert!((got - want).abs() <= 1e-12 * (1.0 + want.abs()), "{mu} {delta} {n}: {got} vs {want}");
        sum += want;
    }
    let mu: Vec<f64> = cases.iter().map(|c| c.0).collect();
    let moved: Vec<f64> = cases.iter().map(|c| 0.5 * c.1).collect();
    let n: Vec<f64> = cases.iter().map(|c| c.2).collect();
    let row = deviance_changes(&mu, &moved, &n, 2.0);
    assert!((row - sum).abs() <= 1e-12 * (1.0 + sum.abs()), "{row} vs {sum}");
}

#[test]
fn newton_scale_minimises_and_matches_the_transient_crate_nll() {
    let (fit, r, n) = setup();
    let ev = fit.evaluate(&r, &n, BINS, 0.7, true, 1.0).expect("ok");
    let e = |s: f64| poisson_nll(&r, &n, BINS, &fit.kernel, s, 0.7).expect("nll").value;
    assert!((e(ev.scale) - ev.value).abs() <= 1e-9 * ev.value.abs(), "{} vs {}", e(ev.scale), ev.value);
    assert!(e(ev.scale) < e(ev.scale * 1.001) && e(ev.scale) < e(ev.scale * 0.999));
    // ∂E/∂α = 0 at the optimum, by the transient crate's own gradient.
    let g = poisson_nll(&r, &n, BINS, &fit.kernel, ev.scale, 0.7).expect("nll");
    assert!(g.grad_scale.abs() < 1e-8 * (1.0 + ev.value), "{}", g.grad_scale);
    // Without background: closed form Σn/ΣJI.
    let a = fit.jitter(&r, BINS).expect("a");
    let s0 = SensorFit::optimal_scale_jittered(&a, &n, 0.0).expect("s0");
    let want = n.iter().map(|&v| f64::from(v)).sum::<f64>() / a.iter().sum::<f64>();
    assert!((s0 - want).abs() < 1e-12 * want);
}

#[test]
fn whole_data_term_gradient_matches_finite_differences() {
    let (fit, r, n) = setup();
    // b = 0 only with counts where J I > 0 (elsewhere μ meets its floor, where E is not differentiable).
    let a = fit.jitter(&r, BINS).expect("a");
    let n0: Vec<f32> = n.iter().zip(&a).map(|(&c, &ak)| if ak > 0.0 { c } else { 0.0 }).collect();
    for (b, solve, n) in [(0.7, true, &n), (0.0, true, &n0), (0.7, false, &n)] {
        let ev = fit.evaluate(&r, n, BINS, b, solve, 1.0).expect("ok");
        let e_star = |i: usize, h: f32| {
            let mut rr = r.clone();
            rr[i] += h;
            fit.evaluate(&rr, n, BINS, b, solve, 1.0).expect("ok").value
        };
        // Interior bins, histogram edges (the kernel's truncation), zero-flux bins.
        for i in [0, 1, 5, 12, 13, 29, 30, 44, 59] {
            // A rendered transient is >= 0: at zero flux with b = 0, E has a kink at I = 0 (μ meets its
            // floor below it), so the difference there is one-sided, from above.
            let fd = if b == 0.0 && r[i] == 0.0 {
                let h = 1e-4f32;
                (e_star(i, h) - e_star(i, 0.0)) / f64::from(h)
            } else {
                let h = 1e-3f32;
                (e_star(i, h) - e_star(i, -h)) / (2.0 * f64::from(h))
            };
            let an = f64::from(ev.d_rendered[i]);
            assert!((fd - an).abs() <= 1e-3 * (1.0 + an.abs()), "b {b} solve {solve} bin {i}: fd {fd} vs {an}");
        }
    }
}

/// Analytic special cases: `d(μ) = μ ln(1/μ) + μ² ln 2 + O(μ³)` for small μ (the tolerance is tight
/// enough that dropping the μ² term fails), → ½ for large μ, continuous at the switch to the expansion.
#[test]
fn expected_half_deviance_special_cases() {
    for mu in [1e-4f64, 1e-3] {
        let want = mu * (1.0 / mu).ln() + mu * mu * 2f64.ln();
        let got = expected_half_deviance(mu);
        assert!((got - want).abs() < 1e-6 * want, "μ {mu}: {got} vs {want}");
    }
    let below = expected_half_deviance(DEVIANCE_SERIES_MAX_MU);
    let above = expected_half_deviance(DEVIANCE_SERIES_MAX_MU * (1.0 + 1e-12));
    assert!((below - above).abs() < 1e-5, "{below} vs {above}");
    assert!((expected_half_deviance(1e6) - 0.5).abs() < 1e-6);
    assert_eq!(expected_half_deviance(0.0), 0.0);
    assert_eq!(expected_half_deviance(f64::NAN), 0.0);
}

/// Statistical test: the mean half-deviance of Poisson draws matches `d(μ)` (20,000 draws per μ,
/// tolerance 5 standard errors of the sample mean).
#[test]
fn expected_half_deviance_matches_poisson_draws() {
    let mut rng = nlos_transient::rng::Pcg32::new(5, 0);
    for mu in [0.05f64, 0.7, 3.0, 20.0] {
        let draws = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..draws {
            let d = half_deviance(mu, rng.poisson(mu) as f64);
            sum += d;
            sum2 += d * d;
        }
        let mean = sum / f64::from(draws);
        let se = ((sum2 / f64::from(draws) - mean * mean) / f64::from(draws)).sqrt();
        let want = expected_half_deviance(mu);
        assert!((mean - want).abs() < 5.0 * se, "μ {mu}: sample mean {mean} ± {se} vs {want}");
    }
}

#[test]
fn noise_floor_is_the_expected_value_at_the_model() {
    let (fit, r, _) = setup();
    let a = fit.jitter(&r, BINS).expect("a");
    let want: f64 = a.iter().map(|&ak| expected_half_deviance(2.0 * ak + 0.7)).sum();
    let got = fit.noise_floor(&r, BINS, 0.7, 2.0).expect("floor");
    assert!((got - want).abs() < 1e-12 * want);
    // Bright bins add about ½ each.
    let bright = vec![1e4f32; 2 * BINS];
    let f = fit.noise_floor(&bright, BINS, 0.0, 1.0).expect("floor");
    assert!((f / (2 * BINS) as f64 - 0.5).abs() < 0.05, "{f}");
    assert!(matches!(fit.noise_floor(&r, 7, 0.7, 2.0), Err(OptimError::Sensor(_))));
}

#[test]
fn background_alone_falls_back_and_bad_input_is_an_error() {
    let (fit, r, _) = setup();
    // Counts below the background everywhere: no positive scale explains them better than α = 0.
    let n = vec![0.0f32; r.len()];
    assert!(SensorFit::optimal_scale_jittered(&fit.jitter(&r, BINS).expect("a"), &n, 0.7).is_none());
    assert_eq!(fit.evaluate(&r, &n, BINS, 0.7, true, 3.5).expect("ok").scale, 3.5);
    let mut bad = n.clone();
    bad[3] = -1.0;
    assert!(matches!(fit.evaluate(&r, &bad, BINS, 0.7, true, 1.0), Err(OptimError::InvalidParameter { .. })));
    assert!(matches!(fit.evaluate(&r, &n[1..], BINS, 0.7, true, 1.0), Err(OptimError::LengthMismatch { .. })));
    assert!(matches!(fit.evaluate(&r, &n, 7, 0.7, true, 1.0), Err(OptimError::Sensor(_))));
    assert!(matches!(fit.evaluate(&r, &n, BINS, f64::NAN, true, 1.0), Err(OptimError::InvalidParameter { .. })));
    assert_eq!(SensorFit::normaliser(&n), None);
}
