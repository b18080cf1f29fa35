//! `Renderer::forward_triangle`: the triangles' shares add up to the forward pass, for every sampling and
//! visibility mode (the occluder's shadow included), and bad indices are typed errors.

mod common;

use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx, Lambertian};
use nlos_render::{
    DeterministicRule, FittedBrdf, Kernel, RenderError, RenderParams, Renderer, Sampling, SplatRule, Visibility,
};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// A bumpy 8 × 8 height field at z ≈ 0.4 facing the wall, and a small occluder in front of it.
fn scene() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    common::bumpy_surface_with_occluder(8)
}

fn check<B: FittedBrdf>(params: RenderParams, brdf: &B) {
    let (p, f) = scene();
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.2, 0.2).expect("grid"));
    let time = TimeAxis::new(0.6, 0.004, 200).expect("axis");
    let r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
    let full = r.forward(brdf);
    let mut sum = vec![0.0f64; full.len()];
    for t in 0..f.len() {
        let rows = r.forward_triangle(brdf, t).expect("triangle");
        for row in &rows {
            assert!(row.values.first().is_some_and(|x| *x != 0.0) && row.values.last().is_some_and(|x| *x != 0.0));
            for (k, v) in row.values.iter().enumerate() {
                sum[row.measurement * time.bins + row.first_bin + k] += f64::from(*v);
            }
        }
    }
    let scale = full.iter().fold(0.0f32, |a, x| a.max(x.abs()));
    assert!(scale > 0.0, "non-trivial render");
    // The forward pass accumulates the 129 triangles' shares of a bin in f32 (ε = 6·10⁻⁸ per addition); the
    // shares are summed here in f64. 1e-6 of the peak is that rounding (1e-7 fails; 1e-4 was 100× loose).
    // The splat rule spreads each triangle over every bin its path lengths span (here up to about 15 of
    // them, against 2 for a point sample with the tent kernel): several times more f32 additions per bin.
    let tol = if matches!(params.sampling, Sampling::Splat(_)) { 3e-6 } else { 1e-6 };
    for (i, (a, b)) in full.iter().zip(&sum).enumerate() {
        assert!(
            (f64::from(*a) - b).abs() <= tol * f64::from(scale),
            "{params:?} value {i}: forward {a}, sum of triangles {b}"
        );
    }
}

#[test]
fn triangle_shares_sum_to_the_forward_pass() {
    let lambert = Lambertian::new(0.8f32).expect("valid");
    let ggx = Ggx::new(0.2f32, 0.8, 0.3, Fresnel::Schlick { f0: 0.5 }).expect("valid");
    for visibility in [Visibility::Off, Visibility::Cached { level: 2 }, Visibility::Live] {
        for sampling in [
            Sampling::Deterministic(DeterministicRule { min_level: 3, max_level: 3, ..DeterministicRule::default() }),
            Sampling::Deterministic(DeterministicRule::default()),
            Sampling::Stratified { samples_per_measurement: 4000, seed: 5 },
            Sampling::Splat(SplatRule::default()),
            Sampling::Splat(SplatRule { max_deviation: 0.01, max_level: 4 }),
        ] {
            for kernel in [Kernel::Tent, Kernel::Box] {
                if kernel == Kernel::Box && matches!(sampling, Sampling::Splat(_)) {
                    continue; // the splat rule integrates the tent kernel only (a typed error otherwise)
                }
                let params = RenderParams { visibility, sampling, kernel, ..RenderParams::default() };
                check(params, &lambert);
                check(params, &ggx);
            }
        }
    }
}

#[test]
fn the_occluder_shadows_a_triangles_share() {
    // With visibility, a triangle behind the occluder gives less than without.
    let (p, f) = scene();
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.2, 0.2).expect("grid"));
    let time = TimeAxis::new(0.6, 0.004, 200).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let total = |visibility| -> Vec<f64> {
        let r =
            Renderer::new(&p, &f, &scan, &time, RenderParams { visibility, ..RenderParams::default() }).expect("valid");
        (0..f.len() - 1)
            .map(|t| {
                r.forward_triangle(&brdf, t)
                    .expect("ok")
                    .iter()
                    .flat_map(|s| s.values.iter())
                    .map(|x| f64::from(*x))
                    .sum()
            })
            .collect()
    };
    let (open, shadowed) = (total(Visibility::Off), total(Visibility::Cached { level: 2 }));
    assert!(open.iter().zip(&shadowed).all(|(a, b)| *b <= *a * (1.0 + 1e-5)));
    assert!(open.iter().zip(&shadowed).any(|(a, b)| *b < 0.9 * *a), "some triangle is in the occluder's shadow");
}

#[test]
fn a_bad_triangle_index_is_a_typed_error() {
    let (p, f) = scene();
    let scan = Scan::confocal(PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"));
    let time = TimeAxis::new(0.6, 0.004, 200).expect("axis");
    let r = Renderer::new(&p, &f, &scan, &time, RenderParams::default()).expect("valid");
    assert!(matches!(
        r.forward_triangle(&Lambertian::new(1.0f32).expect("valid"), f.len()),
        Err(RenderError::InvalidParameter { name: "triangle", .. })
    ));
}
