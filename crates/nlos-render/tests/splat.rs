//! The splat rule (`Sampling::Splat`, the optimiser's default): closer to the exact quadrature than the
//! adaptive rule it replaced, and sound on the triangles that stress a closed form — slivers, faces whose
//! corners are equidistant from the spot (a point mass in time), faces spanning more bins than the fast path
//! holds — where its adjoint still matches finite differences.

mod common;

use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx, Lambertian};
use nlos_render::{DeterministicRule, FittedBrdf, Kernel, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

fn rel_l2(a: &[f32], b: &[f32]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
    (num / den).sqrt()
}

fn params(sampling: Sampling) -> RenderParams {
    RenderParams { kernel: Kernel::Tent, sampling, visibility: Visibility::Off, two_sided: false }
}

/// The exact quadrature: adaptive sub-triangles spanning at most 0.05 bins (level ≤ 64).
fn exact() -> Sampling {
    Sampling::Deterministic(DeterministicRule { max_bin_fraction: 0.05, min_level: 1, max_level: 64 })
}

/// At Tsai et al. 2019's bins (1.2 mm) on faces of the optimiser's first stage (8 mm edges, a bumpy surface 0.4 m
/// from the wall), against the exact quadrature: the splat is 30× closer than a point sample per face and
/// measurement and closer than the adaptive rule the optimiser ran before (up to 64 samples); at level 2 it
/// is well below the adaptive rule.
#[test]
fn splat_error_against_the_exact_quadrature() {
    let (mut p, mut f) = common::bumpy_surface_with_occluder(50);
    // Drop the occluder (visibility is off here): only the surface.
    p.truncate(51 * 51);
    f.pop();
    let scan = Scan::confocal(PointSet::wall_grid(5, 5, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.6, 0.0012, 600).expect("axis");
    let brdf = Ggx::new(0.5f32, 0.5, 0.3, Fresnel::One).expect("valid");
    let render = |s| Renderer::new(&p, &f, &scan, &time, params(s)).expect("valid").forward(&brdf);
    let reference = render(exact());
    let splat = rel_l2(&render(Sampling::Splat(SplatRule::default())), &reference);
    let splat2 = rel_l2(&render(Sampling::Splat(SplatRule { max_deviation: 1e-6, max_level: 2 })), &reference);
    let adaptive = rel_l2(
        &render(Sampling::Deterministic(DeterministicRule { max_bin_fraction: 0.5, min_level: 1, max_level: 8 })),
        &reference,
    );
    let fixed1 = rel_l2(&render(Sampling::Deterministic(DeterministicRule::fixed(1))), &reference);
    eprintln!(
        "rel-L2 against the exact quadrature: splat {splat:.2e}, level 2 {splat2:.2e}, adaptive ≤ 8 {adaptive:.2e}, fixed(1) {fixed1:.2e}"
    );
    assert!(splat < fixed1 / 30.0, "splat {splat} vs fixed(1) {fixed1}");
    assert!(splat < adaptive, "splat {splat} vs adaptive {adaptive}");
    assert!(splat2 < 0.5 * adaptive, "splat level 2 {splat2} vs adaptive {adaptive}");
}

/// A finer level (smaller allowed departure of τ from linear) converges to the exact quadrature, on large
/// faces (5 cm) that need it.
#[test]
fn finer_levels_converge_on_large_faces() {
    let (p, f) = common::bumpy_surface_with_occluder(8);
    let scan = Scan::confocal(PointSet::wall_grid(3, 3, 0.2, 0.2).expect("grid"));
    let time = TimeAxis::new(0.6, 0.004, 200).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let render = |s| Renderer::new(&p, &f, &scan, &time, params(s)).expect("valid").forward(&brdf);
    let reference = render(exact());
    let errors: Vec<f64> = [1.0f32, 0.2, 0.02]
        .iter()
        .map(|&d| rel_l2(&render(Sampling::Splat(SplatRule { max_deviation: d, max_level: 64 })), &reference))
        .collect();
    eprintln!("rel-L2 at max_deviation 1, 0.2, 0.02 bins: {errors:?}");
    assert!(errors[1] < errors[0] && errors[2] < errors[1], "{errors:?}");
    assert!(errors[2] < 2e-3, "{errors:?}");
}

/// Σ adj·I in f64.
fn energy<B: FittedBrdf>(r: &Renderer, brdf: &B, adj: &[f32]) -> f64 {
    r.forward(brdf).iter().zip(adj).map(|(i, a)| f64::from(*i) * f64::from(*a)).sum()
}

/// The adjoint of `p, f` against five-point central differences; returns the worst relative component error
/// (the gradient's largest component as the floor for near-zero entries).
fn gradient_error<B: FittedBrdf>(
    p: &[Vec3],
    f: &[[u32; 3]],
    scan: &Scan,
    time: &TimeAxis,
    brdf: &B,
    h: f32,
    rule: SplatRule,
) -> f64 {
    let mut r = Renderer::new(p, f, scan, time, params(Sampling::Splat(rule))).expect("valid");
    let adj: Vec<f32> = (0..r.len()).map(|i| (i as f32 * 0.093).cos() + 0.3).collect();
    let g = r.adjoint(brdf, &adj).expect("adjoint");
    assert!(g.vertices.iter().all(|v| v.is_finite()), "finite gradient");
    let scale = g.vertices.iter().map(|v| v.abs().max_element()).fold(0.0, f32::max);
    assert!(scale > 0.0);
    let mut worst = 0.0f64;
    for vi in 0..p.len() {
        for c in 0..3 {
            let mut e = |d: f32| {
                let mut q = p.to_vec();
                q[vi][c] += d;
                r.set_positions(&q).expect("finite");
                energy(&r, brdf, &adj)
            };
            let fd = (-e(2.0 * h) + 8.0 * e(h) - 8.0 * e(-h) + e(-2.0 * h)) / (12.0 * f64::from(h));
            let an = f64::from(g.vertices[vi][c]);
            worst = worst.max((fd - an).abs() / an.abs().max(0.1 * f64::from(scale)));
        }
    }
    worst
}

/// A sliver (area 10⁻⁹ of its edge squared) and a face whose three corners lie at the same distance from
/// the spot (all of its light in one instant): finite, equal to the exact quadrature in total, and a face
/// spanning about 200 bins (beyond the fast path's buffer) matches it bin by bin; gradients match finite
/// differences on the long face.
#[test]
fn degenerate_and_long_faces() {
    let scan = Scan::confocal(PointSet::list(vec![Vec3::ZERO]));
    let time = TimeAxis::new(0.6, 0.001, 400).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    // Corners on the sphere of radius 0.4 about the spot, facing it (normal toward −z-ish).
    let on_sphere = |x: f32, y: f32| Vec3::new(x, y, (0.16 - x * x - y * y).sqrt());
    let iso = vec![on_sphere(0.0, 0.0), on_sphere(0.02, 0.0), on_sphere(0.0, 0.02)];
    let sliver = vec![Vec3::new(0.0, 0.0, 0.4), Vec3::new(0.0, 0.02, 0.41), Vec3::new(0.01, 0.01 + 1e-9, 0.405)];
    for (name, p) in [("iso-distance", iso), ("sliver", sliver)] {
        // Orient the face toward the spot.
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let f = if n.dot(-p[0]) > 0.0 { vec![[0u32, 1, 2]] } else { vec![[0u32, 2, 1]] };
        let splat = Renderer::new(&p, &f, &scan, &time, params(Sampling::Splat(SplatRule::default())))
            .expect("valid")
            .forward(&brdf);
        let reference = Renderer::new(&p, &f, &scan, &time, params(exact())).expect("valid").forward(&brdf);
        assert!(splat.iter().all(|x| x.is_finite()), "{name}: finite");
        let (s, r): (f32, f32) = (splat.iter().sum(), reference.iter().sum());
        assert!(r > 0.0 && (s - r).abs() <= 1e-3 * r, "{name}: total {s} vs {r}");
        let adj: Vec<f32> = (0..splat.len()).map(|i| (i as f32 * 0.093).cos()).collect();
        let g = Renderer::new(&p, &f, &scan, &time, params(Sampling::Splat(SplatRule::default())))
            .expect("valid")
            .adjoint(&brdf, &adj)
            .expect("adjoint");
        assert!(g.vertices.iter().all(|v| v.is_finite()), "{name}: finite gradient");
    }
    // A 20 cm face tilted toward the spot: its path lengths span about 200 one-millimetre bins.
    let long = vec![Vec3::new(-0.02, 0.0, 0.35), Vec3::new(0.02, 0.0, 0.35), Vec3::new(0.0, 0.2, 0.45)];
    let f = vec![[0u32, 2, 1]];
    let render = |s| Renderer::new(&long, &f, &scan, &time, params(s)).expect("valid").forward(&brdf);
    // Level 20 resolves the curvature of τ (and of the integrand) over 20 cm at 0.35 m.
    let fine = Sampling::Splat(SplatRule { max_deviation: 0.2, max_level: 20 });
    // The reference needs sub-triangles far below a bin (the adaptive rule stops at level 64, 3 bins here).
    let (splat, reference) = (render(fine), render(Sampling::Deterministic(DeterministicRule::fixed(1500))));
    let first = reference.iter().position(|x| *x > 0.0).expect("lit");
    let last = reference.iter().rposition(|x| *x > 0.0).expect("lit");
    assert!(last - first > 150, "the face spans {} bins", last - first);
    let e = rel_l2(&splat, &reference);
    // Point samples at the same level alias against 1 mm bins (each sub-triangle spans 10 of them).
    let points = rel_l2(&render(Sampling::Deterministic(DeterministicRule::fixed(20))), &reference);
    assert!(e < 0.04 && e < points / 20.0, "long face rel-L2 {e} (point samples {points})");
    let worst = gradient_error(&long, &f, &scan, &time, &brdf, 5e-4, SplatRule::default());
    assert!(worst < 2e-3, "long face: worst gradient component error {worst}");
}

/// The vector kernels take pairs spanning up to 4, 8 or 16 bins (per block, as its pairs need) and leave
/// longer ones to a scalar loop. On the bumpy surface (5 cm faces) at bin
/// widths where most pairs span 1–4, 5–8, 9–16 and more bins, the forward pass equals the sum of the triangles'
/// shares (which run the scalar loop alone) and the adjoint matches finite differences.
#[test]
fn every_span_class_matches_the_scalar_loop() {
    let (p, f) = common::bumpy_surface_with_occluder(8);
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.2, 0.2).expect("grid"));
    let brdf = Lambertian::new(0.8f32).expect("valid");
    // Whole faces (no sub-triangles), so that a triangle's share spans what its pairs span.
    let rule = SplatRule { max_level: 1, ..SplatRule::default() };
    for (dt, lo, hi) in [(0.03f64, 1, 4), (0.01, 5, 8), (0.005, 9, 16), (0.0015, 17, 64)] {
        let time = TimeAxis::new(0.6, dt, (0.6 / dt) as usize).expect("axis");
        let r = Renderer::new(&p, &f, &scan, &time, params(Sampling::Splat(rule))).expect("valid");
        let full = r.forward(&brdf);
        let mut sum = vec![0.0f64; full.len()];
        let (mut rows, mut in_class) = (0usize, 0usize);
        for t in 0..f.len() {
            for row in r.forward_triangle(&brdf, t).expect("triangle") {
                rows += 1;
                in_class += usize::from((lo..=hi).contains(&row.values.len()));
                for (k, v) in row.values.iter().enumerate() {
                    sum[row.measurement * time.bins + row.first_bin + k] += f64::from(*v);
                }
            }
        }
        assert!(in_class * 2 > rows, "dt {dt}: {in_class} of {rows} pairs span {lo}..={hi} bins");
        let scale = full.iter().fold(0.0f32, |a, x| a.max(x.abs()));
        for (i, (a, b)) in full.iter().zip(&sum).enumerate() {
            assert!((f64::from(*a) - b).abs() <= 3e-6 * f64::from(scale), "dt {dt} value {i}: {a} vs {b}");
        }
        // A 1 mm step: the energy is f32, and smaller steps see its rounding on these large faces.
        let worst = gradient_error(&p, &f, &scan, &time, &brdf, 1e-3, rule);
        assert!(worst < 4e-3, "dt {dt}: worst gradient component error {worst}");
    }
}
