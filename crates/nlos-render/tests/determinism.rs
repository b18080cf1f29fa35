//! Determinism: the forward pass, the adjoint and the fused loss-and-gradient give bit-identical results
//! whatever the number of rayon threads (the optimiser's resume-after-SIGKILL test relies on it). Every
//! reduction runs over fixed chunks (chosen from the mesh and scan only) and sums the chunks' partials in
//! chunk order.

mod common;

use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx, Lambertian};
use nlos_render::{
    DeterministicRule, FittedBrdf, Kernel, Loss, RenderParams, Renderer, Sampling, SplatRule, Visibility,
};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// The shared bumpy height field with an occluder; enough triangles for several adjoint tasks (256-triangle
/// blocks).
fn surface(n: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    common::bumpy_surface_with_occluder(n)
}

/// Forward, adjoint and loss-and-gradient of one configuration in a pool of `threads` threads.
fn run<B: FittedBrdf + Sync>(
    threads: usize,
    p: &[Vec3],
    f: &[[u32; 3]],
    scan: &Scan,
    time: &TimeAxis,
    params: RenderParams,
    brdf: &B,
) -> (Vec<f32>, Vec<Vec3>, Vec<f32>, f64, Vec<Vec3>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
    pool.install(|| {
        let r = Renderer::new(p, f, scan, time, params).expect("valid");
        let data = r.forward(brdf);
        // A non-trivial adjoint: a smooth oscillation per bin, different per measurement.
        let bins = time.bins;
        let adj: Vec<f32> =
            (0..data.len()).map(|i| ((i % bins) as f32 * 0.13 + (i / bins) as f32 * 0.7).cos() + 0.2).collect();
        let g = r.adjoint(brdf, &adj).expect("adjoint");
        let measured: Vec<f32> = data.iter().enumerate().map(|(i, x)| x * (0.7 + 0.001 * (i % 13) as f32)).collect();
        let lg = r.loss_and_gradient(brdf, &measured, Loss::L2, None).expect("loss");
        (data, g.vertices, g.brdf, lg.loss, lg.gradient.vertices)
    })
}

fn bits(v: &[Vec3]) -> Vec<u32> {
    v.iter().flat_map(|x| x.to_array()).map(f32::to_bits).collect()
}

fn fbits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn check<B: FittedBrdf + Sync>(params: RenderParams, brdf: &B, exhaustive: bool) {
    let (p, f) = surface(24);
    assert!(f.len() > 4 * 256, "several adjoint tasks");
    let scan = if exhaustive {
        Scan::exhaustive(
            PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"),
            PointSet::wall_grid(2, 3, 0.15, 0.1).expect("grid"),
        )
    } else {
        Scan::confocal(PointSet::wall_grid(4, 4, 0.2, 0.2).expect("grid"))
    };
    let time = TimeAxis::new(0.6, 0.004, 200).expect("axis");
    let one = run(1, &p, &f, &scan, &time, params, brdf);
    assert!(one.0.iter().any(|x| *x > 0.0), "non-trivial render");
    assert!(one.1.iter().any(|g| g.length() > 0.0), "non-trivial gradient");
    for threads in [2, 3] {
        let other = run(threads, &p, &f, &scan, &time, params, brdf);
        assert_eq!(fbits(&one.0), fbits(&other.0), "forward differs with {threads} threads ({params:?})");
        assert_eq!(bits(&one.1), bits(&other.1), "adjoint differs with {threads} threads ({params:?})");
        assert_eq!(fbits(&one.2), fbits(&other.2), "BRDF gradient differs with {threads} threads ({params:?})");
        assert_eq!(one.3.to_bits(), other.3.to_bits(), "loss differs with {threads} threads ({params:?})");
        assert_eq!(bits(&one.4), bits(&other.4), "loss gradient differs with {threads} threads ({params:?})");
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let lambert = Lambertian::new(0.7f32).expect("valid");
    let ggx = Ggx::new(0.2f32, 0.8, 0.3, Fresnel::Schlick { f0: 0.5 }).expect("valid");
    let fixed = RenderParams {
        kernel: Kernel::Tent,
        sampling: Sampling::Deterministic(DeterministicRule::fixed(2)),
        visibility: Visibility::Cached { level: 2 },
        two_sided: false,
    };
    check(fixed, &lambert, false);
    check(fixed, &ggx, true);
    // The optimiser's rule: closed-form time integration, levels per block.
    let splat = RenderParams { sampling: Sampling::Splat(SplatRule::default()), ..fixed };
    check(splat, &lambert, false);
    check(splat, &ggx, true);
    let fine = RenderParams { sampling: Sampling::Splat(SplatRule { max_deviation: 0.005, max_level: 3 }), ..fixed };
    check(fine, &ggx, false);
    // Live shadow rays, adaptive rule (the pair-by-pair path), Gaussian kernel.
    let adaptive = RenderParams {
        kernel: Kernel::Gaussian { fwhm_bins: 2.0 },
        sampling: Sampling::Deterministic(DeterministicRule { max_bin_fraction: 1.0, min_level: 1, max_level: 4 }),
        visibility: Visibility::Live,
        two_sided: true,
    };
    check(adaptive, &ggx, false);
    // Tsai et al. 2019's stratified Monte Carlo mode.
    let mc = RenderParams {
        sampling: Sampling::Stratified { samples_per_measurement: 3000, seed: 9 },
        visibility: Visibility::Live,
        ..Default::default()
    };
    check(mc, &lambert, false);
}
