//! Steady-state (time-integrated) intensity: equals the time sum of the transient, and its adjoint matches
//! central finite differences (vertices and BRDF parameters), with and without an occluder.

use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx, Lambertian};
use nlos_render::{DeterministicRule, FittedBrdf, Kernel, Loss, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// Deterministic pseudo-random numbers in [0, 1): the workspace's SplitMix64 (`nlos_transient::rng`).
struct Draws(nlos_transient::rng::SplitMix64);
impl Draws {
    fn new(seed: u64) -> Self {
        Self(nlos_transient::rng::SplitMix64::new(seed))
    }
    fn next(&mut self) -> f32 {
        self.0.next_f32()
    }
}

/// A few random triangles around z = 0.4 facing the wall, plus optionally an occluder in front of them.
fn random_mesh(seed: u64, occluder: bool) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut r = Draws::new(seed);
    let (mut p, mut f) = (Vec::new(), Vec::new());
    for t in 0..4u32 {
        let c = Vec3::new(r.next() * 0.3 - 0.15, r.next() * 0.3 - 0.15, 0.35 + 0.1 * r.next());
        let a = c + Vec3::new(0.05 + 0.03 * r.next(), 0.02 * r.next(), 0.03 * (r.next() - 0.5));
        let b = c + Vec3::new(0.02 * r.next(), 0.05 + 0.03 * r.next(), 0.03 * (r.next() - 0.5));
        p.extend([c, b, a]);
        f.push([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    if occluder {
        let n = p.len() as u32;
        p.extend([Vec3::new(-0.05, -0.05, 0.2), Vec3::new(0.02, 0.1, 0.21), Vec3::new(0.12, -0.02, 0.19)]);
        f.push([n, n + 1, n + 2]);
    }
    (p, f)
}

fn scans() -> [Scan; 2] {
    [
        Scan::confocal(PointSet::wall_grid(3, 3, 0.2, 0.2).expect("grid")),
        Scan::exhaustive(
            PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"),
            PointSet::wall_grid(3, 2, 0.15, 0.1).expect("grid"),
        ),
    ]
}

#[test]
fn steady_state_is_the_time_sum_of_the_transient() {
    // The axis [0.3, 1.5) m holds every path (0.7–1.1 m) with margin, so no kernel weight falls off its ends.
    let time = TimeAxis::new(0.3, 0.01, 120).expect("axis");
    let brdf = Ggx::new(0.3f32, 0.7, 0.25, Fresnel::Schlick { f0: 0.5 }).expect("valid");
    for scan in scans() {
        for (kernel, sampling, visibility) in [
            (Kernel::Tent, Sampling::Deterministic(DeterministicRule::fixed(3)), Visibility::Cached { level: 2 }),
            (Kernel::Box, Sampling::Deterministic(DeterministicRule::default()), Visibility::Live),
            (
                Kernel::Gaussian { fwhm_bins: 3.0 },
                Sampling::Stratified { samples_per_measurement: 500, seed: 3 },
                Visibility::Live,
            ),
        ] {
            let (p, f) = random_mesh(5, true);
            let params = RenderParams { kernel, sampling, visibility, two_sided: false };
            let r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
            let transient = r.forward(&brdf);
            let steady = r.forward_steady(&brdf);
            assert_eq!(steady.len(), scan.measurements());
            let total: f64 = steady.iter().map(|v| f64::from(*v)).sum();
            assert!(total > 0.0);
            for (m, s) in steady.iter().enumerate() {
                let sum: f64 = transient[m * time.bins..][..time.bins].iter().map(|v| f64::from(*v)).sum();
                let err = (sum - f64::from(*s)).abs();
                assert!(err <= 1e-5 * total, "{kernel:?} measurement {m}: Σ_k I = {sum}, S = {s}");
            }
        }
    }
}

/// E = Σ_m a_m S_m in f64.
fn energy<B: FittedBrdf>(r: &Renderer, brdf: &B, adj: &[f32]) -> f64 {
    r.forward_steady(brdf).iter().zip(adj).map(|(i, a)| f64::from(*i) * f64::from(*a)).sum()
}

fn check_gradients<B: FittedBrdf>(brdf: &B, occluder: bool, scan: &Scan, seed: u64) {
    let (p, f) = random_mesh(seed, occluder);
    let time = TimeAxis::new(0.3, 0.01, 150).expect("axis");
    let params = RenderParams {
        sampling: Sampling::Deterministic(DeterministicRule::fixed(6)),
        visibility: if occluder { Visibility::Cached { level: 4 } } else { Visibility::Off },
        ..Default::default()
    };
    let mut r = Renderer::new(&p, &f, scan, &time, params).expect("valid");
    let mut rng = Draws::new(seed + 7);
    let adj: Vec<f32> = (0..scan.measurements()).map(|_| rng.next() - 0.3).collect();
    let g = r.adjoint_steady(brdf, &adj).expect("adjoint");
    assert!(r.adjoint_steady(brdf, &adj[1..]).is_err());
    let h = 2e-4f32;
    let scale = g.vertices.iter().map(|v| v.abs().max_element()).fold(0.0, f32::max);
    assert!(scale > 0.0);
    let (mut diff2, mut norm2) = (0.0f64, 0.0f64);
    for vi in 0..p.len() {
        for c in 0..3 {
            let mut q = p.clone();
            q[vi][c] += h;
            r.set_positions(&q).expect("finite");
            let ep = energy(&r, brdf, &adj);
            q[vi][c] -= 2.0 * h;
            r.set_positions(&q).expect("finite");
            let em = energy(&r, brdf, &adj);
            let fd = (ep - em) / (2.0 * f64::from(h));
            let an = f64::from(g.vertices[vi][c]);
            let err = (fd - an).abs() / an.abs().max(0.1 * f64::from(scale));
            diff2 += (fd - an) * (fd - an);
            norm2 += an * an;
            assert!(err < 3e-3, "vertex {vi} axis {c}: fd {fd} adjoint {an} (rel {err})");
        }
    }
    let vec_rel = (diff2 / norm2).sqrt();
    eprintln!("steady vertex gradient rel error {vec_rel:.2e} (occluder {occluder})");
    assert!(vec_rel < 1e-3, "vertex gradient vector rel error {vec_rel}");
    r.set_positions(&p).expect("finite");
    let theta = brdf.params();
    for (k, name) in B::PARAM_NAMES.iter().enumerate() {
        let hp = 1e-3 * theta[k].abs().max(0.1);
        let mut tp = theta.clone();
        tp[k] += hp;
        let Ok(bp) = brdf.with_params(&tp) else { continue };
        tp[k] -= 2.0 * hp;
        let Ok(bm) = brdf.with_params(&tp) else { continue };
        let fd = (energy(&r, &bp, &adj) - energy(&r, &bm, &adj)) / (2.0 * f64::from(hp));
        let an = f64::from(g.brdf[k]);
        let err = (fd - an).abs() / an.abs().max(1e-6 * fd.abs().max(1.0));
        assert!(err < 1e-3, "param {name}: fd {fd} adjoint {an} (rel {err})");
    }
}

#[test]
fn steady_state_adjoint_matches_finite_differences() {
    let [confocal, exhaustive] = scans();
    check_gradients(&Lambertian::new(0.7f32).expect("valid"), false, &confocal, 1);
    check_gradients(&Lambertian::new(0.7f32).expect("valid"), true, &exhaustive, 2);
    let ggx = Ggx::new(0.2f32, 0.8, 0.35, Fresnel::Schlick { f0: 0.6 }).expect("valid");
    check_gradients(&ggx, true, &confocal, 3);
    check_gradients(&ggx, false, &exhaustive, 4);
}

#[test]
fn steady_state_loss_and_gradient() {
    let (p, f) = random_mesh(9, false);
    let [scan, _] = scans();
    let time = TimeAxis::new(0.3, 0.01, 150).expect("axis");
    let r = Renderer::new(&p, &f, &scan, &time, RenderParams::default()).expect("valid");
    let brdf = Lambertian::new(0.5f32).expect("valid");
    let measured = r.forward_steady(&Lambertian::new(0.8f32).expect("valid"));
    let out = r.loss_and_gradient_steady(&brdf, &measured, Loss::L2, None).expect("ok");
    let (e, adj) = Loss::L2.evaluate(&out.rendered, &measured, None).expect("ok");
    assert_eq!(e, out.loss);
    assert_eq!(r.adjoint_steady(&brdf, &adj).expect("ok"), out.gradient);
    // S is linear in the albedo: E(ρ) = ½ Σ (ρ S₁ − 0.8 S₁)², dE/dρ = (ρ − 0.8) Σ S₁².
    let s1: f64 =
        r.forward_steady(&Lambertian::new(1.0f32).expect("valid")).iter().map(|v| f64::from(*v).powi(2)).sum();
    let expected = (0.5 - 0.8) * s1;
    let got = f64::from(out.gradient.brdf[0]);
    assert!((got - expected).abs() <= 1e-4 * expected.abs(), "dE/dρ {got} vs {expected}");
    assert!(r.loss_and_gradient_steady(&brdf, &measured[1..], Loss::L2, None).is_err());
}
