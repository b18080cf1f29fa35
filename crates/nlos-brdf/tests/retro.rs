//! The retroreflector (`Retroreflective`): gradients against central finite differences of an independent f64
//! reference (as GGX's in `gradients.rs`), the confocal path against the general path, the f32 build against
//! the f64 build, and its special cases: the confocal 1/r² falloff, reciprocity, the lobe's width, the back side.

mod common;

use common::{Pcg32, dir_with_cos, random_mu, tangents};
use glam::{DVec3, Vec3};
use nlos_brdf::{Brdf, BrdfError, Lambertian, RETRO_LOBE_WIDTH, Retroreflective};
use std::f64::consts::PI;

/// Textbook reference, written from the model's statement: `ρ/π · |l||s| · exp(−(1 − cos θ)/σ²)` with θ the
/// angle between l and s (from atan2, not from a normalised dot product), on the front side.
fn reference(l: DVec3, s: DVec3, n: DVec3, rho: f64, sigma: f64) -> f64 {
    if n.dot(l) <= 0.0 || n.dot(s) <= 0.0 {
        return 0.0;
    }
    let theta = l.cross(s).length().atan2(l.dot(s));
    rho / PI * l.length() * s.length() * (-(1.0 - theta.cos()) / (sigma * sigma)).exp()
}

fn fd4(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
    (-f(x + 2.0 * h) + 8.0 * f(x + h) - 8.0 * f(x - h) + f(x - 2.0 * h)) / (12.0 * h)
}

fn fd_vec(v: DVec3, h: f64, f: impl Fn(DVec3) -> f64) -> DVec3 {
    let mut g = DVec3::ZERO;
    for k in 0..3 {
        g[k] = fd4(
            |t| {
                let mut x = v;
                x[k] = t;
                f(x)
            },
            v[k],
            h,
        );
    }
    g
}

/// A random front-facing configuration whose sensor direction lies within about 2σ of the laser direction
/// (outside it the value underflows to nothing), lengths in metres of an NLOS scene.
fn config(rng: &mut Pcg32, sigma: f64) -> (DVec3, DVec3, DVec3) {
    let n = rng.unit();
    let l = dir_with_cos(n, random_mu(rng).max(0.2), rng.range(0.0, 2.0 * PI));
    let (t, b) = tangents(l);
    let phi = rng.range(0.0, 2.0 * PI);
    let theta = sigma * rng.range(0.0, 2.0);
    let s = (l * theta.cos() + (t * phi.cos() + b * phi.sin()) * theta.sin()).normalize();
    let s = if s.dot(n) > 0.05 { s } else { l };
    (l * rng.range(0.2, 2.0), s * rng.range(0.2, 2.0), n * rng.range(0.3, 3.0))
}

#[test]
fn gradients_match_central_differences_of_the_reference() {
    let mut rng = Pcg32::new(0x5eed_0007, 3);
    let mut worst = [0.0f64; 5];
    for i in 0..4000 {
        let sigma = if i % 2 == 0 { RETRO_LOBE_WIDTH } else { rng.range(0.01, 0.8) };
        let rho = rng.range(0.05, 3.0);
        let brdf = Retroreflective::with_lobe_width(rho, sigma).expect("valid");
        let (l, s, n) = config(&mut rng, sigma);
        let f = reference(l, s, n, rho, sigma);
        assert!(f > 0.0, "config {i}: {l} {s} {n}");
        let g = brdf.eval_grad(l, s, n);
        assert!((g.value - brdf.eval(l, s, n)).abs() <= 1e-13 * f, "eval and eval_grad disagree");
        worst[0] = worst[0].max((g.value - f).abs() / f);
        // The step resolves the lobe: a fraction of σ in angle at each vector's length.
        let h = |v: DVec3| 2e-3 * sigma.min(0.2) * v.length();
        let fd_l = fd_vec(l, h(l), |x| reference(x, s, n, rho, sigma));
        let fd_s = fd_vec(s, h(s), |x| reference(l, x, n, rho, sigma));
        let fd_rho = fd4(|p| reference(l, s, n, p, sigma), rho, 1e-2);
        // Relative to the gradient's natural scale f/|v| (the length term alone has that size).
        worst[1] = worst[1].max((g.d_omega_l - fd_l).length() / (f / l.length()));
        worst[2] = worst[2].max((g.d_omega_s - fd_s).length() / (f / s.length()));
        worst[3] = worst[3].max(g.d_n.length());
        worst[4] = worst[4].max((g.d_params.albedo - fd_rho).abs() / (f / rho));
    }
    println!("max relative errors (value, d_omega_l, d_omega_s, |d_n|, albedo): {worst:?}");
    assert!(worst[0] < 1e-9, "value: {}", worst[0]);
    for (name, e) in [("d_omega_l", worst[1]), ("d_omega_s", worst[2]), ("albedo", worst[4])] {
        assert!(e < 1e-5, "{name}: relative error {e}");
    }
    assert_eq!(worst[3], 0.0, "the normal enters through the front-side test only");
}

#[test]
fn confocal_path_is_the_general_path_at_equal_directions() {
    let mut rng = Pcg32::new(0x5eed_0008, 1);
    for _ in 0..500 {
        let n = rng.unit();
        let w = dir_with_cos(n, random_mu(&mut rng).max(0.05), rng.range(0.0, 2.0 * PI)) * rng.range(0.1, 3.0);
        let brdf = Retroreflective::new(rng.range(0.1, 2.0)).expect("valid");
        let c = brdf.eval_grad_confocal(w, n);
        let g = brdf.eval_grad(w, w, n);
        assert!((c.value - g.value).abs() <= 1e-12 * g.value, "{} vs {}", c.value, g.value);
        assert!((brdf.eval_confocal(w, n) - c.value).abs() <= 1e-12 * g.value);
        let sum = g.d_omega_l + g.d_omega_s;
        assert!((c.d_omega - sum).length() <= 1e-9 * sum.length(), "{} vs {}", c.d_omega, sum);
        assert!((c.d_params.albedo - g.d_params.albedo).abs() <= 1e-12 * g.d_params.albedo);
        // Finite differences along the shared direction.
        let fd = fd_vec(w, 1e-4 * w.length(), |x| brdf.eval_confocal(x, n));
        assert!((c.d_omega - fd).length() <= 1e-7 * c.d_omega.length());
    }
}

#[test]
fn f32_build_agrees_with_f64_build() {
    let mut rng = Pcg32::new(0x5eed_0009, 2);
    for _ in 0..1000 {
        let (l, s, n) = config(&mut rng, RETRO_LOBE_WIDTH);
        let (b64, b32) = (Retroreflective::new(0.7f64).expect("valid"), Retroreflective::new(0.7f32).expect("valid"));
        let (g64, g32) = (b64.eval_grad(l, s, n), b32.eval_grad(l.as_vec3(), s.as_vec3(), n.as_vec3()));
        assert!((f64::from(g32.value) - g64.value).abs() <= 1e-4 * g64.value);
        let scale = g64.value / l.length().min(s.length());
        assert!((g32.d_omega_l.as_dvec3() - g64.d_omega_l).length() <= 2e-3 * scale);
        assert!((g32.d_omega_s.as_dvec3() - g64.d_omega_s).length() <= 2e-3 * scale);
    }
}

#[test]
fn confocal_return_falls_as_one_over_r_squared() {
    let retro = Retroreflective::new(1.0f64).expect("valid");
    let lambert = Lambertian::new(1.0f64).expect("valid");
    // The measurement's distance factor 1/(|a|²|b|²) = 1/r⁴ times f: Lambertian 1/r⁴, retroreflector 1/r².
    let measured = |f: f64, r: f64| f / r.powi(4);
    for r in [0.25, 0.5, 1.0, 2.0] {
        let w = DVec3::new(0.0, 0.0, r);
        let (fr, fl) = (retro.eval_confocal(w, DVec3::Z), lambert.eval_confocal(w, DVec3::Z));
        assert!((measured(fr, r) * r * r - 1.0 / PI).abs() < 1e-12, "retro at {r}");
        assert!((measured(fl, r) * r.powi(4) - 1.0 / PI).abs() < 1e-12, "lambert at {r}");
    }
    // Equal at d₀ = 1 m.
    let w = DVec3::new(0.3, 0.4, (1.0f64 - 0.25).sqrt());
    assert!((retro.eval_confocal(w, DVec3::Z) - lambert.eval_confocal(w, DVec3::Z)).abs() < 1e-15);
}

#[test]
fn special_cases() {
    let b = Retroreflective::new(1.0f64).expect("valid");
    let (l, s, n) = (DVec3::new(0.1, 0.0, 0.5), DVec3::new(0.1, 0.004, 0.5), DVec3::Z);
    // Reciprocal.
    assert!((b.eval(l, s, n) - b.eval(s, l, n)).abs() <= 1e-15 * b.eval(l, s, n));
    // The lobe: at observation angle θ the value is the confocal one times exp(−(1 − cos θ)/σ²).
    let theta = l.angle_between(s);
    let expect = b.eval(l, l * (s.length() / l.length()), n) * (-(1.0 - theta.cos()) / RETRO_LOBE_WIDTH.powi(2)).exp();
    assert!((b.eval(l, s, n) - expect).abs() <= 1e-12 * expect);
    // At θ = σ: about exp(−1/2) of the peak.
    let rot = DVec3::new(0.0, RETRO_LOBE_WIDTH.sin(), RETRO_LOBE_WIDTH.cos()) * 0.5;
    let ratio = b.eval(DVec3::Z * 0.5, rot, n) / b.eval(DVec3::Z * 0.5, DVec3::Z * 0.5, n);
    assert!((ratio - (-0.5f64).exp()).abs() < 1e-4, "{ratio}");
    // Back side, degenerate input: 0 and zero gradients.
    assert_eq!(b.eval(-l, s, n), 0.0);
    assert_eq!(b.eval_grad(l, -s, n).d_omega_l, DVec3::ZERO);
    assert_eq!(b.eval_confocal(DVec3::ZERO, n), 0.0);
    assert_eq!(b.eval_grad_confocal(DVec3::new(0.0, 0.0, f64::NAN), n).value, 0.0);
    // Bad parameters are typed errors.
    assert!(matches!(Retroreflective::new(-1.0f32), Err(BrdfError::InvalidAlbedo { .. })));
    assert!(matches!(Retroreflective::with_lobe_width(1.0f32, 0.0), Err(BrdfError::InvalidLobeWidth { .. })));
    assert!(matches!(Retroreflective::with_lobe_width(1.0f32, f32::NAN), Err(BrdfError::InvalidLobeWidth { .. })));
    // Sampling is the cosine hemisphere's (area sampling reaches the lobe).
    let r32 = Retroreflective::new(1.0f32).expect("valid");
    let smp = r32.sample(Vec3::Z, Vec3::Z, [0.5, 0.3, 0.7]).expect("front-facing");
    assert!((r32.pdf(Vec3::Z, smp.omega, Vec3::Z) - smp.pdf).abs() < 1e-6);
}
