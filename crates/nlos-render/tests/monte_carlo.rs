//! Test 3: the stratified Monte Carlo mode is unbiased — the mean over many seeds converges to the
//! deterministic transient (and its gradient to the deterministic gradient).

use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx};
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

#[test]
fn mean_over_seeds_converges_to_deterministic() {
    let p = vec![
        Vec3::new(-0.1, -0.1, 0.4),
        Vec3::new(0.1, 0.1, 0.45),
        Vec3::new(0.1, -0.1, 0.4),
        Vec3::new(-0.1, 0.1, 0.42),
        Vec3::new(0.0, 0.0, 0.3),
        Vec3::new(0.05, 0.0, 0.3),
        Vec3::new(0.0, -0.03, 0.32),
    ];
    let f = vec![[0, 1, 2], [0, 3, 1], [4, 5, 6]];
    let scan = Scan::confocal(PointSet::wall_grid(3, 3, 0.2, 0.2).expect("grid"));
    let time = TimeAxis::new(0.55, 0.02, 30).expect("axis");
    let brdf = Ggx::new(0.3f32, 0.6, 0.4, Fresnel::One).expect("valid");
    let base = RenderParams { kernel: Kernel::Tent, visibility: Visibility::Live, ..Default::default() };
    let exact_params = RenderParams {
        sampling: Sampling::Deterministic(DeterministicRule { max_bin_fraction: 0.05, min_level: 1, max_level: 256 }),
        ..base
    };
    let exact_r = Renderer::new(&p, &f, &scan, &time, exact_params).expect("ok");
    let exact = exact_r.forward(&brdf);
    let adj = vec![1.0f32; exact.len()];
    let exact_g = exact_r.adjoint(&brdf, &adj).expect("ok");
    let seeds = 400;
    let mut mean = vec![0.0f64; exact.len()];
    let mut mean_g = vec![0.0f64; p.len() * 3];
    let mut single_err = 0.0;
    for seed in 0..seeds {
        let params = RenderParams { sampling: Sampling::Stratified { samples_per_measurement: 64, seed }, ..base };
        let r = Renderer::new(&p, &f, &scan, &time, params).expect("ok");
        let one = r.forward(&brdf);
        let g = r.adjoint(&brdf, &adj).expect("ok");
        if seed == 0 {
            single_err = rel(&one.iter().map(|v| f64::from(*v)).collect::<Vec<_>>(), &exact);
        }
        for (m, v) in mean.iter_mut().zip(&one) {
            *m += f64::from(*v) / seeds as f64;
        }
        for (i, v) in g.vertices.iter().enumerate() {
            for c in 0..3 {
                mean_g[3 * i + c] += f64::from(v[c]) / seeds as f64;
            }
        }
    }
    let err = rel(&mean, &exact);
    let exact_gf: Vec<f32> = exact_g.vertices.iter().flat_map(|v| v.to_array()).collect();
    let err_g = rel(&mean_g, &exact_gf);
    eprintln!("single-seed rel-L2 {single_err:.3e}, mean of {seeds} seeds {err:.3e}, gradient mean {err_g:.3e}");
    // Unbiased: the error of the mean shrinks like 1/√seeds (20× here); allow 2.5× that.
    assert!(err < 2.5 * single_err / (seeds as f64).sqrt(), "mean rel-L2 {err} vs single {single_err}");
    assert!(err < 0.01, "{err}");
    assert!(err_g < 0.02, "gradient mean rel-L2 {err_g}");
}

fn rel(a: &[f64], b: &[f32]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - f64::from(*y)).powi(2)).sum();
    let den: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
    (num / den).sqrt()
}
