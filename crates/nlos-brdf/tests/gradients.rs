//! Analytic gradients against central finite differences of an independent f64 reference, the f32 build against
//! the f64 build, the confocal fast path against the general path, and the reparametrisation's chain rule.

mod common;

use common::{Pcg32, random_alpha, random_config, reference_ggx};
use glam::{DVec3, Vec3};
use nlos_brdf::{Brdf, Fresnel, Ggx, GgxTheta, Lambertian, Masking};

/// Relative error of a gradient vector, with a floor below which a gradient is "zero at this scale": the
/// fourth-order difference's round-off is ≈ 3e-16 |f| / (h_rel |v|), so gradients below 1e-12 |f| / (h_rel |v|)
/// are not resolvable by the reference and are compared in absolute terms at that scale (noise ≤ 3e-4 of it).
fn vec_err(analytic: DVec3, fd: DVec3, value: f64, len: f64, h_rel: f64) -> f64 {
    (analytic - fd).length() / fd.length().max(1e-12 * value.abs() / (h_rel * len))
}

fn scalar_err(analytic: f64, fd: f64, floor: f64) -> f64 {
    (analytic - fd).abs() / fd.abs().max(floor)
}

/// Fourth-order central difference `(−f(x+2h) + 8f(x+h) − 8f(x−h) + f(x−2h)) / 12h` (truncation O(h⁴)).
fn fd4(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
    (-f(x + 2.0 * h) + 8.0 * f(x + h) - 8.0 * f(x - h) + f(x - 2.0 * h)) / (12.0 * h)
}

/// Fourth-order central differences of `f` along each axis of `v`, step `h_rel |v|`.
fn fd_vec(v: DVec3, h_rel: f64, f: impl Fn(DVec3) -> f64) -> DVec3 {
    let h = h_rel * v.length();
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

/// Relative finite-difference step: 2e-3 of the smallest angular scale on which f varies — the lobe width α seen
/// through the half vector (α |ω̂_l + ω̂_s|), the grazing cosines, and 1 — so that the O(h⁴) truncation error
/// stays ≲ 1e-9 relative even for nearly opposite directions and α = 1e-3, and the step never crosses the horizon.
fn fd_step(l: DVec3, s: DVec3, n: DVec3, alpha: f64) -> f64 {
    let (l, s, n) = (l.normalize(), s.normalize(), n.normalize());
    let m = (l + s).length();
    2e-3 * (alpha * m).min(n.dot(l)).min(n.dot(s)).min(1.0)
}

#[derive(Default, Debug)]
struct MaxErr {
    value: f64,
    omega_l: f64,
    omega_s: f64,
    n: f64,
    alpha: f64,
    specular: f64,
    albedo_diffuse: f64,
    f0: f64,
}

#[test]
fn ggx_gradients_match_central_differences_of_the_reference() {
    let mut rng = Pcg32::new(0x5eed_0001, 7);
    let configs_per_model = 3000;
    for masking in [Masking::Separable, Masking::HeightCorrelated] {
        for schlick in [false, true] {
            let mut worst = MaxErr::default();
            for _ in 0..configs_per_model {
                let alpha = random_alpha(&mut rng);
                let rho_d = if rng.f64() < 0.3 { 0.0 } else { rng.range(0.0, 1.0) };
                let rho_s = rng.range(0.05, 2.0);
                let f0 = if schlick { Some(rng.range(0.0, 1.0)) } else { None };
                let fresnel = f0.map_or(Fresnel::One, |f0| Fresnel::Schlick { f0 });
                let brdf = Ggx::new(rho_d, rho_s, alpha, fresnel).expect("valid").with_masking(masking);
                let hc = masking == Masking::HeightCorrelated;
                let (l, s, n) = random_config(&mut rng, alpha);
                let r = |l, s, n, rho_d, rho_s, alpha, f0| reference_ggx(l, s, n, rho_d, rho_s, alpha, f0, hc);
                let g = brdf.eval_grad(l, s, n);
                let f_ref = r(l, s, n, rho_d, rho_s, alpha, f0);
                assert!(f_ref > 0.0);
                worst.value = worst.value.max((g.value - f_ref).abs() / f_ref);
                let v = brdf.eval(l, s, n);
                assert!((g.value - v).abs() <= 1e-13 * v, "eval {v} and eval_grad {} disagree", g.value);

                let h_rel = fd_step(l, s, n, alpha);
                // The diffuse term is constant on the front side: differencing the specular part alone keeps the
                // constant ρ_d/π out of the round-off.
                let f_spec = r(l, s, n, 0.0, rho_s, alpha, f0);
                let fd_l = fd_vec(l, h_rel, |x| r(x, s, n, 0.0, rho_s, alpha, f0));
                let fd_s = fd_vec(s, h_rel, |x| r(l, x, n, 0.0, rho_s, alpha, f0));
                let fd_n = fd_vec(n, h_rel, |x| r(l, s, x, 0.0, rho_s, alpha, f0));
                let errs = [
                    vec_err(g.d_omega_l, fd_l, f_spec, l.length(), h_rel),
                    vec_err(g.d_omega_s, fd_s, f_spec, s.length(), h_rel),
                    vec_err(g.d_n, fd_n, f_spec, n.length(), h_rel),
                ];
                worst.omega_l = worst.omega_l.max(errs[0]);
                worst.omega_s = worst.omega_s.max(errs[1]);
                worst.n = worst.n.max(errs[2]);

                let h = h_rel * alpha;
                let fd_alpha = fd4(|a| r(l, s, n, 0.0, rho_s, a, f0), alpha, h);
                // f is linear in ρ_s, ρ_d, F0: any step is exact up to round-off; each parameter is differenced in
                // the only term that depends on it (the other term is a constant that would only add round-off).
                let fd_rho_s = fd4(|p| r(l, s, n, 0.0, p, alpha, f0), rho_s, 1e-2);
                let fd_rho_d = fd4(|p| r(l, s, n, p, 0.0, alpha, f0), rho_d, 1e-2);
                worst.alpha = worst.alpha.max(scalar_err(g.d_params.alpha, fd_alpha, 1e-12 * f_spec / h));
                worst.specular = worst.specular.max(scalar_err(g.d_params.specular, fd_rho_s, 1e-11 * f_spec));
                worst.albedo_diffuse = worst.albedo_diffuse.max(scalar_err(g.d_params.albedo_diffuse, fd_rho_d, 1e-11));
                if let Some(f0) = f0 {
                    let fd_f0 = fd4(|p| r(l, s, n, 0.0, rho_s, alpha, Some(p)), f0, 1e-2);
                    worst.f0 = worst.f0.max(scalar_err(g.d_params.f0, fd_f0, 1e-11 * f_spec));
                } else {
                    assert_eq!(g.d_params.f0, 0.0);
                }
                if errs.iter().any(|&e| e > 1e-3) {
                    panic!("{masking:?} schlick={schlick} alpha={alpha} l={l} s={s} n={n}: errors {errs:?}");
                }
            }
            println!("{masking:?} schlick={schlick}: max relative errors over {configs_per_model} configs: {worst:?}");
            for (name, e) in [
                ("value", worst.value),
                ("d_omega_l", worst.omega_l),
                ("d_omega_s", worst.omega_s),
                ("d_n", worst.n),
                ("alpha", worst.alpha),
                ("specular", worst.specular),
                ("albedo_diffuse", worst.albedo_diffuse),
                ("f0", worst.f0),
            ] {
                let tol = if name == "value" { 1e-9 } else { 1e-3 };
                assert!(e < tol, "{masking:?} schlick={schlick}: {name} relative error {e} ≥ {tol}");
            }
        }
    }
}

#[test]
fn gradients_are_tangent_and_scale_like_one_over_length() {
    // F(λv) = F(v) ⇒ ∇F(v)·v = 0 and ∇F(λv) = ∇F(v)/λ.
    let brdf = Ggx::new(0.2f64, 1.0, 0.25, Fresnel::Schlick { f0: 0.3 }).expect("valid");
    let mut rng = Pcg32::new(3, 3);
    for _ in 0..500 {
        let (l, s, n) = random_config(&mut rng, 0.25);
        let g = brdf.eval_grad(l, s, n);
        let g2 = brdf.eval_grad(l * 2.0, s * 3.0, n * 0.5);
        for (gv, v) in [(g.d_omega_l, l), (g.d_omega_s, s), (g.d_n, n)] {
            assert!(gv.dot(v).abs() <= 1e-9 * gv.length() * v.length() + 1e-300);
        }
        assert!((g2.d_omega_l * 2.0 - g.d_omega_l).length() <= 1e-9 * g.d_omega_l.length() + 1e-300);
        assert!((g2.d_omega_s * 3.0 - g.d_omega_s).length() <= 1e-9 * g.d_omega_s.length() + 1e-300);
        assert!((g2.d_n * 0.5 - g.d_n).length() <= 1e-9 * g.d_n.length() + 1e-300);
    }
}

#[test]
fn lambertian_gradients() {
    let brdf = Lambertian::new(0.7f64).expect("valid");
    let g = brdf.eval_grad(DVec3::new(0.3, 0.2, 1.0), DVec3::new(-1.0, 0.0, 0.1), DVec3::Z * 3.0);
    assert_eq!(g.value, 0.7 / std::f64::consts::PI);
    assert_eq!(g.d_params.albedo, 1.0 / std::f64::consts::PI);
    assert_eq!((g.d_omega_l, g.d_omega_s, g.d_n), (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO));
    let c = brdf.eval_grad_confocal(DVec3::new(0.3, 0.2, 1.0), DVec3::Z);
    assert_eq!((c.value, c.d_params.albedo), (g.value, g.d_params.albedo));
}

/// Componentwise comparison of two gradient records, relative to a per-vector scale.
fn assert_close(a: DVec3, b: DVec3, scale: f64, tol: f64, what: &str) {
    assert!((a - b).length() <= tol * scale, "{what}: {a} vs {b} (scale {scale})");
}

#[test]
fn confocal_fast_path_equals_general_path() {
    let mut rng = Pcg32::new(11, 1);
    for masking in [Masking::Separable, Masking::HeightCorrelated] {
        for i in 0..4000 {
            let alpha = random_alpha(&mut rng);
            let fresnel = if i % 2 == 0 { Fresnel::One } else { Fresnel::Schlick { f0: rng.range(0.0, 1.0) } };
            let brdf = Ggx::new(rng.range(0.0, 1.0), rng.range(0.0, 2.0), alpha, fresnel)
                .expect("valid")
                .with_masking(masking);
            let (w, _, n) = random_config(&mut rng, alpha);
            let c = brdf.eval_grad_confocal(w, n);
            let g = brdf.eval_grad(w, w, n);
            assert!((c.value - brdf.eval_confocal(w, n)).abs() <= 1e-13 * c.value);
            assert!((c.value - g.value).abs() <= 1e-12 * g.value, "value {} vs {}", c.value, g.value);
            let p = (c.d_params, g.d_params);
            for (a, b) in [
                (p.0.alpha, p.1.alpha),
                (p.0.specular, p.1.specular),
                (p.0.albedo_diffuse, p.1.albedo_diffuse),
                (p.0.f0, p.1.f0),
            ] {
                assert!((a - b).abs() <= 1e-10 * b.abs().max(1e-3 * g.value), "param {a} vs {b}");
            }
            let sum = g.d_omega_l + g.d_omega_s;
            let scale = g.d_omega_l.length() + g.d_omega_s.length() + 1e-300;
            assert_close(c.d_omega, sum, scale, 1e-9, "d_omega");
            assert_close(c.d_n, g.d_n, g.d_n.length() + 1e-300, 1e-9, "d_n");

            // f32 build: same check with an f32 tolerance.
            let b32 = Ggx::new(
                brdf.albedo_diffuse() as f32,
                brdf.specular() as f32,
                alpha as f32,
                match fresnel {
                    Fresnel::One => Fresnel::One,
                    Fresnel::Schlick { f0 } => Fresnel::Schlick { f0: f0 as f32 },
                },
            )
            .expect("valid")
            .with_masking(masking);
            let (w32, n32) = (w.as_vec3(), n.as_vec3());
            let c = b32.eval_grad_confocal(w32, n32);
            let g = b32.eval_grad(w32, w32, n32);
            assert!((c.value - g.value).abs() <= 1e-5 * g.value);
            let sum: Vec3 = g.d_omega_l + g.d_omega_s;
            let scale = g.d_omega_l.length() + g.d_omega_s.length() + 1e-30;
            assert!((c.d_omega - sum).length() <= 1e-3 * scale, "f32 d_omega {} vs {sum}", c.d_omega);
            assert!((c.d_n - g.d_n).length() <= 1e-3 * (g.d_n.length() + 1e-30));
        }
    }
}

/// The f32 instantiation against the f64 one at the same (f32-rounded) inputs.
///
/// Documented f32 tolerance: with κ = max(1, 1/(α |ω̂_l + ω̂_s|)) the condition number of the specular lobe with
/// respect to the input directions (f32 inputs are only known to ε ≈ 6e-8 rad, which moves the half vector by
/// ε/|ω̂_l + ω̂_s| against a lobe of width α), the relative error is ≤ 1e-3 + 3e-6 κ
/// * on the value;
/// * on each gradient vector, measured against max(|∇f|, κ |f| / |v|): near the peak the gradient passes through
///   0 on the lobe's natural scale |f| κ/|v|, and rounding of the inputs alone moves it by ≈ ε κ² |f|/|v|;
/// * on ∂f/∂α against max(|∂f/∂α|, κ|f|/α), likewise; on ∂f/∂ρ_s, ∂f/∂F0 against their own size.
///
/// Away from nearly opposite directions and mirror-like α this is the plain 1e-3 relative bound.
#[test]
fn f32_build_agrees_with_f64_build() {
    let mut rng = Pcg32::new(99, 5);
    let mut worst = [0.0f64; 2];
    let mut worst_scaled = 0.0f64;
    for masking in [Masking::Separable, Masking::HeightCorrelated] {
        for i in 0..5000 {
            let alpha = random_alpha(&mut rng) as f32;
            let fresnel = if i % 2 == 0 { Fresnel::One } else { Fresnel::Schlick { f0: rng.f32() } };
            let b32 = Ggx::new(rng.f32(), 0.05 + rng.f32(), alpha, fresnel).expect("valid").with_masking(masking);
            let f64_fresnel = match fresnel {
                Fresnel::One => Fresnel::One,
                Fresnel::Schlick { f0 } => Fresnel::Schlick { f0: f64::from(f0) },
            };
            let b64 =
                Ggx::new(f64::from(b32.albedo_diffuse()), f64::from(b32.specular()), f64::from(alpha), f64_fresnel)
                    .expect("valid")
                    .with_masking(masking);
            let (l, s, n) = random_config(&mut rng, f64::from(alpha));
            let (l, s, n) = (l.as_vec3(), s.as_vec3(), n.as_vec3());
            let g32 = b32.eval_grad(l, s, n);
            let g64 = b64.eval_grad(l.as_dvec3(), s.as_dvec3(), n.as_dvec3());
            if g64.value == 0.0 {
                continue; // rounding to f32 made it back-facing
            }
            let f = g64.value;
            let m = (l.as_dvec3().normalize() + s.as_dvec3().normalize()).length();
            let kappa = (1.0 / (f64::from(alpha) * m)).max(1.0);
            let mut e = (f64::from(g32.value) - f).abs() / f;
            for (a, b, v) in
                [(g32.d_omega_l, g64.d_omega_l, l), (g32.d_omega_s, g64.d_omega_s, s), (g32.d_n, g64.d_n, n)]
            {
                let len = f64::from(v.length());
                e = e.max((a.as_dvec3() - b).length() / b.length().max(kappa * f / len));
            }
            let pa = (g32.d_params, g64.d_params);
            e = e.max(scalar_err(f64::from(pa.0.alpha), pa.1.alpha, kappa * f / f64::from(alpha)));
            e = e.max(scalar_err(f64::from(pa.0.specular), pa.1.specular, 1e-4 * f));
            e = e.max(scalar_err(f64::from(pa.0.f0), pa.1.f0, 1e-4 * f));
            let tol = 1e-3 + 3e-6 * kappa;
            let k = usize::from(kappa > 100.0);
            worst[k] = worst[k].max(e);
            worst_scaled = worst_scaled.max(e / tol);
            assert!(e < tol, "alpha {alpha} kappa {kappa} {masking:?} l={l} s={s} n={n}: f32 relative error {e}");
        }
    }
    println!(
        "f32 vs f64 max relative error: kappa <= 100: {:.2e}, kappa > 100: {:.2e}; max error/tolerance {:.2}",
        worst[0], worst[1], worst_scaled
    );
}

#[test]
fn reparametrisation_chain_rule_matches_finite_differences() {
    let mut rng = Pcg32::new(5, 9);
    for _ in 0..1000 {
        let theta = GgxTheta {
            albedo_diffuse: rng.range(-6.0, 3.0),
            specular: rng.range(-6.0, 3.0),
            alpha: rng.range(-8.0, 8.0),
            f0: rng.range(-6.0, 6.0),
        };
        let brdf = theta.to_ggx(true, Masking::HeightCorrelated).expect("finite theta");
        let (l, s, n) = random_config(&mut rng, brdf.alpha());
        let g = brdf.eval_grad(l, s, n);
        let d = theta.chain(&g.d_params);
        let f = |t: GgxTheta<f64>| t.to_ggx(true, Masking::HeightCorrelated).expect("finite").eval(l, s, n);
        let h = 1e-6;
        let mut worst = 0.0f64;
        for (k, analytic) in [d.albedo_diffuse, d.specular, d.alpha, d.f0].into_iter().enumerate() {
            let (mut tp, mut tm) = (theta, theta);
            let (p, m) = match k {
                0 => (&mut tp.albedo_diffuse, &mut tm.albedo_diffuse),
                1 => (&mut tp.specular, &mut tm.specular),
                2 => (&mut tp.alpha, &mut tm.alpha),
                _ => (&mut tp.f0, &mut tm.f0),
            };
            *p += h;
            *m -= h;
            let fd = (f(tp) - f(tm)) / (2.0 * h);
            worst = worst.max(scalar_err(analytic, fd, 1e-7 * g.value));
        }
        assert!(worst < 1e-3, "theta {theta:?}: chain-rule error {worst}");
    }
}
