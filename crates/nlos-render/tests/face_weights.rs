//! Per-triangle reflectance factors (`Renderer::set_face_weights`): the forward pass scales each triangle's
//! share, the adjoint's `Gradient::faces` is dE/dw_t (checked against finite differences, for Lambertian and
//! GGX, confocal and exhaustive scans, fixed rule and random sampling), the vertex gradient stays exact with
//! factors set, and bad factors are typed errors.

use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx, Lambertian};
use nlos_render::{DeterministicRule, FittedBrdf, Kernel, RenderError, RenderParams, Renderer, Sampling, Visibility};
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

/// Five random triangles around z = 0.4 facing the wall.
fn mesh(seed: u64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut r = Draws::new(seed);
    let (mut p, mut f) = (Vec::new(), Vec::new());
    for t in 0..5u32 {
        let c = Vec3::new(r.next() * 0.3 - 0.15, r.next() * 0.3 - 0.15, 0.35 + 0.1 * r.next());
        let a = c + Vec3::new(0.05 + 0.03 * r.next(), 0.02 * r.next(), 0.03 * (r.next() - 0.5));
        let b = c + Vec3::new(0.02 * r.next(), 0.05 + 0.03 * r.next(), 0.03 * (r.next() - 0.5));
        p.extend([c, b, a]);
        f.push([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    (p, f)
}

fn scan(exhaustive: bool) -> Scan {
    if exhaustive {
        Scan::exhaustive(
            PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"),
            PointSet::wall_grid(3, 2, 0.15, 0.1).expect("grid"),
        )
    } else {
        Scan::confocal(PointSet::wall_grid(3, 3, 0.2, 0.2).expect("grid"))
    }
}

fn energy<B: FittedBrdf>(r: &Renderer, brdf: &B, adj: &[f32]) -> f64 {
    r.forward(brdf).iter().zip(adj).map(|(i, a)| f64::from(*i) * f64::from(*a)).sum()
}

/// `vertices`: also check the vertex gradient (only meaningful for a fixed rule, smooth in the vertices).
fn check<B: FittedBrdf>(brdf: &B, exhaustive: bool, sampling: Sampling, seed: u64, vertices: bool) {
    let (p, f) = mesh(seed);
    let time = TimeAxis::new(0.3, 0.01, 150).expect("axis");
    let params = RenderParams {
        kernel: Kernel::Gaussian { fwhm_bins: 2.0 },
        sampling,
        visibility: Visibility::Off,
        two_sided: false,
    };
    let mut r = Renderer::new(&p, &f, &scan(exhaustive), &time, params).expect("valid");
    let bins = time.bins;
    let adj: Vec<f32> =
        (0..r.len()).map(|i| ((i % bins) as f32 * 0.21 + (i / bins) as f32 * 1.3).cos() + 0.3).collect();
    let mut rng = Draws::new(seed + 7);
    let w: Vec<f32> = (0..f.len()).map(|_| 0.5 + rng.next()).collect();

    // Analytic special cases: factors all c scale the transient by c; each triangle's share by its own.
    let plain = r.forward(brdf);
    r.set_face_weights(Some(&vec![2.5; f.len()])).expect("valid");
    for (a, b) in r.forward(brdf).iter().zip(&plain) {
        assert!((a - 2.5 * b).abs() <= 1e-5 * b.abs().max(1e-3 * plain.iter().fold(0.0f32, |m, x| m.max(*x))));
    }
    r.set_face_weights(Some(&w)).expect("valid");
    let g = r.adjoint(brdf, &adj).expect("adjoint");
    assert_eq!(g.faces.len(), f.len());
    let mut checked = 0;
    for t in 0..f.len() {
        // E is linear in w_t: the central difference is exact up to rounding.
        let h = 0.1 * w[t];
        let mut e = |d: f32| {
            let mut q = w.clone();
            q[t] += d;
            r.set_face_weights(Some(&q)).expect("valid");
            energy(&r, brdf, &adj)
        };
        let fd = (e(h) - e(-h)) / (2.0 * f64::from(h));
        let an = f64::from(g.faces[t]);
        if fd.abs() > 0.0 {
            checked += 1;
        }
        assert!((fd - an).abs() <= 1e-3 * fd.abs().max(1e-9), "face {t}: fd {fd} adjoint {an}");
    }
    assert!(checked >= 3, "only {checked} faces reflect: the check says little");
    if !vertices {
        return;
    }
    // The vertex gradient with factors set against central differences.
    r.set_face_weights(Some(&w)).expect("valid");
    let scale = g.vertices.iter().map(|v| v.abs().max_element()).fold(0.0, f32::max);
    let h = 5e-4f32;
    for vi in 0..p.len() {
        for c in 0..3 {
            let mut e = |d: f32| {
                let mut q = p.clone();
                q[vi][c] += d;
                r.set_positions(&q).expect("finite");
                energy(&r, brdf, &adj)
            };
            let fd = (-e(2.0 * h) + 8.0 * e(h) - 8.0 * e(-h) + e(-2.0 * h)) / (12.0 * f64::from(h));
            let an = f64::from(g.vertices[vi][c]);
            let err = (fd - an).abs() / an.abs().max(0.1 * f64::from(scale));
            assert!(err < 2e-3, "vertex {vi} axis {c}: fd {fd} adjoint {an} (rel {err})");
        }
    }
}

#[test]
fn face_weight_gradient_matches_finite_differences_lambertian() {
    let brdf = Lambertian::new(0.7f32).expect("valid");
    check(&brdf, false, Sampling::Deterministic(DeterministicRule::fixed(6)), 1, true);
    check(&brdf, true, Sampling::Deterministic(DeterministicRule::fixed(5)), 2, true);
    check(
        &brdf,
        false,
        Sampling::Deterministic(DeterministicRule { min_level: 2, max_level: 6, ..DeterministicRule::fixed(6) }),
        3,
        false,
    );
}

#[test]
fn face_weight_gradient_matches_finite_differences_ggx() {
    let brdf = Ggx::new(0.2f32, 0.8, 0.35, Fresnel::Schlick { f0: 0.6 }).expect("valid");
    check(&brdf, false, Sampling::Deterministic(DeterministicRule::fixed(6)), 4, true);
    check(&brdf, true, Sampling::Deterministic(DeterministicRule::fixed(5)), 5, true);
}

/// Without factors, Σ_t dE/dw_t is the derivative along a common scale of every triangle — for a Lambertian
/// BRDF exactly albedo · dE/d(albedo).
#[test]
fn face_weight_gradients_sum_to_the_albedo_derivative() {
    let (p, f) = mesh(9);
    let time = TimeAxis::new(0.3, 0.01, 150).expect("axis");
    let r = Renderer::new(&p, &f, &scan(false), &time, RenderParams::default()).expect("valid");
    let brdf = Lambertian::new(0.7f32).expect("valid");
    let adj: Vec<f32> = (0..r.len()).map(|i| ((i % 150) as f32 * 0.17).sin() + 0.5).collect();
    let g = r.adjoint(&brdf, &adj).expect("adjoint");
    let sum: f64 = g.faces.iter().map(|x| f64::from(*x)).sum();
    let albedo = 0.7 * f64::from(g.brdf[0]);
    assert!((sum - albedo).abs() <= 1e-4 * albedo.abs(), "Σ dE/dw {sum} vs albedo·dE/dalbedo {albedo}");
}

#[test]
fn bad_face_weights_are_typed_errors() {
    let (p, f) = mesh(3);
    let time = TimeAxis::new(0.3, 0.01, 150).expect("axis");
    let mut r = Renderer::new(&p, &f, &scan(false), &time, RenderParams::default()).expect("valid");
    assert!(matches!(
        r.set_face_weights(Some(&[1.0; 2])),
        Err(RenderError::LengthMismatch { expected: 5, got: 2, .. })
    ));
    let mut w = vec![1.0f32; 5];
    w[2] = f32::NAN;
    assert!(matches!(r.set_face_weights(Some(&w)), Err(RenderError::InvalidParameter { name: "face weight", .. })));
    w[2] = -0.5;
    assert!(matches!(r.set_face_weights(Some(&w)), Err(RenderError::InvalidParameter { .. })));
    // A zero factor makes the triangle black: without occlusion (it still casts shadows) the transient
    // equals the render of the mesh without it.
    let off = RenderParams { visibility: Visibility::Off, ..RenderParams::default() };
    let mut r = Renderer::new(&p, &f, &scan(false), &time, off).expect("valid");
    w[2] = 0.0;
    r.set_face_weights(Some(&w)).expect("valid");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let with_zero = r.forward(&brdf);
    let mut f4 = f.clone();
    f4.remove(2);
    let without = Renderer::new(&p, &f4, &scan(false), &time, off).expect("valid").forward(&brdf);
    let peak = without.iter().fold(0.0f32, |m, x| m.max(*x));
    assert!(peak > 0.0);
    for (a, b) in with_zero.iter().zip(&without) {
        assert!((a - b).abs() <= 1e-5 * peak);
    }
}
