//! Sampling tests in the style of pbrt's `Chi2Test`: bin (θ, φ) on the sphere, integrate the stated pdf over each
//! bin by quadrature, compare with the histogram of 10⁶ samples by Pearson's χ² (cells with expected count < 5
//! pooled) at significance 1% with Šidák's correction over all runs, fixed seeds. Plus: every pdf integrates to 1.

mod common;

use common::{Pcg32, composite_gl};
use glam::DVec3;
use nlos_brdf::sampling::{
    Frame, pdf_cosine_hemisphere, pdf_vndf, pdf_vndf_reflection, sample_cosine_hemisphere, sample_vndf,
    sample_vndf_reflection,
};
use nlos_brdf::{Brdf, Fresnel, Ggx, Lambertian, Lobe, Masking};
use std::f64::consts::PI;

const THETA_RES: usize = 20;
const PHI_RES: usize = 40;
const SAMPLES: usize = 1_000_000;
const MIN_EXPECTED: f64 = 5.0;
/// Number of χ² runs in this file, for Šidák's correction.
const RUNS: usize = 18;

fn ln_gamma(x: f64) -> f64 {
    // Lanczos (g = 7, n = 9).
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x) (series for x < a + 1, Lentz continued fraction otherwise).
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut sum, mut del) = (a, 1.0 / a, 1.0 / a);
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

fn bin_of(w: DVec3) -> usize {
    let theta = w.z.clamp(-1.0, 1.0).acos();
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let it = ((theta / PI * THETA_RES as f64) as usize).min(THETA_RES - 1);
    let ip = ((phi / (2.0 * PI) * PHI_RES as f64) as usize).min(PHI_RES - 1);
    it * PHI_RES + ip
}

/// Integral of `pdf` over each (θ, φ) bin, 12×12 Gauss–Legendre panels of 4×4 nodes per bin; a bin containing
/// one of `theta_breaks` (a circle θ = const across which the pdf jumps) is split there.
fn integrate_bins(pdf: &impl Fn(DVec3) -> f64, theta_breaks: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; THETA_RES * PHI_RES];
    for it in 0..THETA_RES {
        let (t0, t1) = (PI * it as f64 / THETA_RES as f64, PI * (it + 1) as f64 / THETA_RES as f64);
        let mut thetas = Vec::new();
        let mut edges = vec![t0];
        edges.extend(theta_breaks.iter().copied().filter(|&b| b > t0 && b < t1));
        edges.push(t1);
        for w in edges.windows(2) {
            thetas.extend(composite_gl(w[0], w[1], 12, 4));
        }
        for ip in 0..PHI_RES {
            let (p0, p1) = (2.0 * PI * ip as f64 / PHI_RES as f64, 2.0 * PI * (ip + 1) as f64 / PHI_RES as f64);
            let phis = composite_gl(p0, p1, 12, 4);
            let mut sum = 0.0;
            for &(th, wt) in &thetas {
                let (st, ct) = th.sin_cos();
                for &(phi, wp) in &phis {
                    sum += wt * wp * st * pdf(DVec3::new(st * phi.cos(), st * phi.sin(), ct));
                }
            }
            out[it * PHI_RES + ip] = sum;
        }
    }
    out
}

/// Runs one χ² test; `sample` returns `None` for a failed sample (counted in its own cell, expected
/// `1 − ∫ pdf`). Returns the total integral of the pdf over the sphere.
fn chi2_test(
    name: &str,
    seed: u64,
    theta_breaks: &[f64],
    mut sample: impl FnMut(&mut Pcg32) -> Option<DVec3>,
    pdf: impl Fn(DVec3) -> f64,
) -> f64 {
    let mut rng = Pcg32::new(seed, 0x0c12);
    let mut observed = vec![0.0f64; THETA_RES * PHI_RES + 1];
    for _ in 0..SAMPLES {
        match sample(&mut rng) {
            Some(w) => {
                assert!((w.length() - 1.0).abs() < 1e-9 && w.is_finite(), "{name}: non-unit sample {w}");
                observed[bin_of(w)] += 1.0;
            }
            None => observed[THETA_RES * PHI_RES] += 1.0,
        }
    }
    let mut integrals = integrate_bins(&pdf, theta_breaks);
    let total: f64 = integrals.iter().sum();
    integrals.push((1.0 - total).max(0.0));
    let mut cells: Vec<(f64, f64)> = integrals.iter().zip(&observed).map(|(&p, &o)| (p * SAMPLES as f64, o)).collect();
    cells.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut pooled_exp, mut pooled_obs, mut chi2, mut dof) = (0.0, 0.0, 0.0, 0i64);
    for &(e, o) in &cells {
        if e < 1e-12 * SAMPLES as f64 && o > 0.0 {
            panic!("{name}: {o} samples in a cell of zero probability");
        }
        if e < MIN_EXPECTED {
            pooled_exp += e;
            pooled_obs += o;
        } else if pooled_exp > 0.0 && pooled_exp < MIN_EXPECTED {
            // Merge the pool into this cell (as pbrt does when the pool stays too small).
            let (e, o) = (e + pooled_exp, o + pooled_obs);
            pooled_exp = 0.0;
            pooled_obs = 0.0;
            chi2 += (o - e) * (o - e) / e;
            dof += 1;
        } else {
            chi2 += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pooled_exp >= MIN_EXPECTED {
        chi2 += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        dof += 1;
    }
    dof -= 1;
    let p_value = gamma_q(dof as f64 / 2.0, chi2 / 2.0);
    let level = 1.0 - (1.0f64 - 0.01).powf(1.0 / RUNS as f64);
    println!("{name}: chi2 = {chi2:.1}, dof = {dof}, p = {p_value:.3}, integral = {total:.6}");
    assert!(dof > 0, "{name}: no degrees of freedom");
    assert!(p_value > level, "{name}: rejected, chi2 = {chi2}, dof = {dof}, p = {p_value} < {level}");
    total
}

fn local_wi(theta_deg: f64) -> DVec3 {
    let t = theta_deg.to_radians();
    DVec3::new(t.sin(), 0.0, t.cos())
}

#[test]
fn gamma_q_is_right() {
    // χ² with 2 dof: Q(1, x/2) = e^{−x/2}; with 10 dof the 1% critical value is 23.209.
    assert!((gamma_q(1.0, 1.5) - (-1.5f64).exp()).abs() < 1e-12);
    assert!((gamma_q(5.0, 23.209 / 2.0) - 0.01).abs() < 1e-4);
    assert!((gamma_q(50.0, 124.342 / 2.0) - 0.05).abs() < 1e-4); // χ²(100 dof) 95% quantile.
}

#[test]
fn vndf_reflection_chi2_and_normalisation() {
    let mut seed = 1;
    for &alpha in &[0.1, 0.3, 0.6, 1.0] {
        for &theta in &[0.0, 45.0, 80.0] {
            let wi = local_wi(theta);
            seed += 1;
            // The reflection pdf jumps where h = (ω_i + ω_o)/|ω_i + ω_o| crosses the horizon: ω_o.z = −ω_i.z.
            let total = chi2_test(
                &format!("VNDF reflection alpha {alpha} theta_i {theta}"),
                seed,
                &[PI - f64::to_radians(theta)],
                |rng| Some(sample_vndf_reflection(wi, alpha, rng.f64(), rng.f64())),
                |wo| pdf_vndf_reflection(wi, wo, alpha),
            );
            assert!((total - 1.0).abs() < 1e-3, "pdf integrates to {total}");
        }
    }
}

#[test]
fn vndf_normals_chi2_and_normalisation() {
    for (k, &(alpha, theta)) in [(0.2, 60.0), (0.7, 20.0)].iter().enumerate() {
        let wi = local_wi(theta);
        let total = chi2_test(
            &format!("VNDF normals alpha {alpha} theta_i {theta}"),
            100 + k as u64,
            &[],
            |rng| Some(sample_vndf(wi, alpha, rng.f64(), rng.f64())),
            |m| pdf_vndf(wi, m, alpha),
        );
        assert!((total - 1.0).abs() < 1e-3, "pdf integrates to {total}");
    }
}

#[test]
fn cosine_sampling_chi2_and_normalisation() {
    let total = chi2_test(
        "cosine hemisphere",
        200,
        &[],
        |rng| Some(sample_cosine_hemisphere(rng.f64(), rng.f64())),
        |w| pdf_cosine_hemisphere(w.z),
    );
    assert!((total - 1.0).abs() < 1e-4);
    // Through the Brdf interface and a tilted frame.
    let n = DVec3::new(0.3, -0.4, 0.8).normalize();
    let lambert = Lambertian::new(0.5f64).expect("valid");
    let wi = DVec3::new(0.0, 0.0, 1.0);
    let total = chi2_test(
        "Lambertian::sample tilted",
        201,
        &[],
        |rng| lambert.sample(wi, n, [rng.f64(), rng.f64(), rng.f64()]).map(|s| s.omega),
        |w| lambert.pdf(wi, w, n),
    );
    assert!((total - 1.0).abs() < 1e-4);
}

#[test]
fn combined_ggx_sampler_chi2_and_mixture_pdf() {
    let n = DVec3::new(-0.2, 0.1, 1.0).normalize();
    let frame = Frame::<f64>::from_normal(n);
    let cases = [
        (Ggx::new(0.5, 1.0, 0.3, Fresnel::One).expect("valid"), 30.0),
        (
            Ggx::new(0.2, 0.8, 0.15, Fresnel::Schlick { f0: 0.3 })
                .expect("valid")
                .with_masking(Masking::HeightCorrelated),
            70.0,
        ),
        (Ggx::new(0.0, 1.0, 0.5, Fresnel::One).expect("valid"), 85.0),
    ];
    // Binned in the local frame of the tilted normal, so that the horizon is a bin boundary (θ = π/2).
    for (k, (brdf, theta)) in cases.iter().enumerate() {
        let wi = frame.to_world(local_wi(*theta));
        let total = chi2_test(
            &format!("Ggx::sample alpha {} theta_i {theta}", brdf.alpha()),
            300 + k as u64,
            &[],
            |rng| {
                let s = brdf.sample(wi, n, [rng.f64(), rng.f64(), rng.f64()])?;
                // The returned pdf is the one `pdf` reports, and the sample is front-facing.
                assert!((s.pdf - brdf.pdf(wi, s.omega, n)).abs() <= 1e-9 * s.pdf);
                assert!(s.omega.dot(n) > 0.0);
                Some(frame.to_local(s.omega))
            },
            |w| brdf.pdf(wi, frame.to_world(w), n),
        );
        assert!(total <= 1.0 + 1e-6, "mixture pdf integrates to {total} > 1");
    }
    // Lobe selection follows the stated probability (diffuse samples never fail, specular ones may go below).
    let brdf = cases[0].0;
    let mut rng = Pcg32::new(9, 9);
    let wi = frame.to_world(local_wi(30.0));
    let diffuse = (0..100_000)
        .filter(|_| brdf.sample(wi, n, [rng.f64(), rng.f64(), rng.f64()]).is_some_and(|s| s.lobe == Lobe::Diffuse))
        .count() as f64
        / 100_000.0;
    let expected = 1.0 - brdf.specular_probability();
    assert!((diffuse - expected).abs() < 0.01, "{diffuse} vs {expected}");
}

/// The sampler and the evaluator agree: the MC estimate of E(μ) = ∫ f cos dω with VNDF samples (weight f cos/pdf)
/// equals the directional albedo by quadrature (printed by the `properties` tests) within 4σ.
#[test]
fn vndf_estimator_of_directional_albedo() {
    let brdf = Ggx::new(0.0f64, 1.0, 0.5, Fresnel::One).expect("valid");
    let wi = local_wi(60.0); // μ = 0.5; quadrature: E = 0.686007 (separable)
    let mut rng = Pcg32::new(77, 1);
    let n = 400_000;
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..n {
        let w = match brdf.sample(wi, DVec3::Z, [0.0, rng.f64(), rng.f64()]) {
            Some(s) => brdf.eval(wi, s.omega, DVec3::Z) * s.omega.z / s.pdf,
            None => 0.0,
        };
        sum += w;
        sum2 += w * w;
    }
    let mean = sum / n as f64;
    let sigma = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
    assert!((mean - 0.686007).abs() < 4.0 * sigma + 1e-6, "MC {mean} ± {sigma} vs 0.686007");
}
