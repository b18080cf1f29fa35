//! The retroreflective model in the renderer: a retroreflective plane's confocal transient falls as `1/r²`
//! where a Lambertian one falls as `1/r⁴` (the light-cone transform's two image formation models), and the
//! splat rule (with its fall-off correction at `FittedBrdf::DISTANCE_POWER`) is as close to the exact
//! quadrature for it as for the Lambertian model.

use glam::Vec3;
use nlos_brdf::{Lambertian, Retroreflective};
use nlos_render::{DeterministicRule, FittedBrdf, Kernel, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

fn params(sampling: Sampling) -> RenderParams {
    RenderParams { kernel: Kernel::Tent, sampling, visibility: Visibility::Off, two_sided: false }
}

/// A `side`-metre square centred on the z axis at depth z, facing the wall, cut into 2·k² triangles.
fn square(z: f32, side: f32, k: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for j in 0..=k {
        for i in 0..=k {
            let t = |q: usize| side * (q as f32 / k as f32 - 0.5);
            p.push(Vec3::new(t(i), t(j), z));
        }
    }
    let idx = |i: usize, j: usize| (j * (k + 1) + i) as u32;
    let mut f = Vec::new();
    for j in 0..k {
        for i in 0..k {
            // Normal (v1 − v0) × (v2 − v0) = −z: facing the wall.
            f.push([idx(i, j), idx(i, j + 1), idx(i + 1, j)]);
            f.push([idx(i + 1, j), idx(i, j + 1), idx(i + 1, j + 1)]);
        }
    }
    (p, f)
}

/// Time-integrated confocal return of the square at depth z, seen from the wall's origin.
fn total<B: FittedBrdf>(brdf: &B, z: f32) -> f64 {
    let (p, f) = square(z, 0.01, 4);
    let scan = Scan::confocal(PointSet::wall_grid(1, 1, 0.0, 0.0).expect("grid"));
    let time = TimeAxis::new(0.0, 0.002, 2000).expect("axis");
    let r = Renderer::new(&p, &f, &scan, &time, params(Sampling::Splat(SplatRule::default()))).expect("valid");
    r.forward(brdf).iter().map(|v| f64::from(*v)).sum()
}

#[test]
fn retroreflective_plane_falls_as_one_over_r_squared() {
    let retro = Retroreflective::new(1.0f32).expect("valid");
    let lambert = Lambertian::new(1.0f32).expect("valid");
    let (r1, r2) = (total(&retro, 0.4), total(&retro, 0.8));
    let (l1, l2) = (total(&lambert, 0.4), total(&lambert, 0.8));
    eprintln!("retro {r1:.4e} → {r2:.4e} (×{:.3}), lambert {l1:.4e} → {l2:.4e} (×{:.3})", r1 / r2, l1 / l2);
    // A 1 cm square: the cosines differ from 1 by < 2e-4 at 0.4 m.
    assert!((r1 / r2 - 4.0).abs() < 4.0 * 2e-3, "retroreflective ratio {}", r1 / r2);
    assert!((l1 / l2 - 16.0).abs() < 16.0 * 2e-3, "lambertian ratio {}", l1 / l2);
    // At 1 m the two models agree (ρ is the return relative to a Lambertian surface at d₀ = 1 m).
    let (r, l) = (total(&retro, 1.0), total(&lambert, 1.0));
    assert!((r / l - 1.0).abs() < 1e-3, "at 1 m: {r} vs {l}");
}

fn rel_l2(a: &[f32], b: &[f32]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
    (num / den).sqrt()
}

/// On 8 mm faces 0.4 m from the wall at 1.2 mm bins (the optimiser's first stage), the splat rule is as
/// close to the exact quadrature for the retroreflector as for the Lambertian model (the fall-off
/// correction's power matters little here: with the Lambertian 4 the retroreflector's error grows by < 1 %).
#[test]
fn splat_rule_is_as_accurate_for_the_retroreflector() {
    let (p, f) = {
        let (mut p, f) = square(0.4, 0.2, 25);
        // A gentle bump, so that faces are tilted and span several bins.
        for v in &mut p {
            v.z += 0.02 * (-(v.x * v.x + v.y * v.y) / 0.004).exp();
        }
        (p, f)
    };
    let scan = Scan::confocal(PointSet::wall_grid(5, 5, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.7, 0.0012, 300).expect("axis");
    let exact = Sampling::Deterministic(DeterministicRule { max_bin_fraction: 0.05, min_level: 1, max_level: 64 });
    let err = |b: &dyn Fn(Sampling) -> Vec<f32>| rel_l2(&b(Sampling::Splat(SplatRule::default())), &b(exact));
    let retro = Retroreflective::new(1.0f32).expect("valid");
    let lambert = Lambertian::new(1.0f32).expect("valid");
    let render_r = |s| Renderer::new(&p, &f, &scan, &time, params(s)).expect("valid").forward(&retro);
    let render_l = |s| Renderer::new(&p, &f, &scan, &time, params(s)).expect("valid").forward(&lambert);
    let (er, el) = (err(&render_r), err(&render_l));
    eprintln!("splat against the exact quadrature: retroreflective {er:.2e}, lambertian {el:.2e}");
    assert!(er < 1.5 * el && er < 5e-3, "retroreflective {er} vs lambertian {el}");
}
