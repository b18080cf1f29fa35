//! The renderer as the optimiser runs it (`nlos_optim::ReconstructParams::default()`): one forward + adjoint
//! (`loss_and_gradient`, L2) at Tsai et al. 2019's setup — confocal 64 × 64 over [−0.25, 0.25]² m, 1200 bins of
//! 1.2 mm, summed as the stage of each mesh sums them (`nlos_optim::Schedule::rebin`: 3 at 7.8 mm edges) — with the tent kernel, `Sampling::Splat(SplatRule::default())` and cached visibility (level 1,
//! built outside the timed loop, as the optimiser does once per remeshing), on the LCT start of the shared
//! bunny (`fixtures/bunny_lct_start.obj`, from `cargo xtask fixtures`) remeshed isotropically as the
//! optimiser's stages do: (a) 7.8 mm edges (stage 0, about 3.2k faces), (b) about 20k faces, (c) about 200k
//! faces (100k vertices, Tsai et al. 2019's scale; visibility off there: its cache takes minutes to build). The
//! former rule and the others are compared by `crates/nlos-render/examples/loop_cost.rs` (the adaptive quadrature the
//! optimiser ran before takes 20 s an iteration, too long for a benchmark). Figures: docs/performance.md.
#![allow(missing_docs)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nlos_brdf::Lambertian;
use nlos_render::{Loss, Renderer};

mod common;

fn bench(c: &mut Criterion) {
    let (scan, _) = common::seed_setup();
    let brdf = Lambertian::new(1.0f32).expect("valid");
    for (name, edge, visibility) in common::CASES {
        let (v, f) = common::remeshed_start(edge);
        let time = common::stage_axis(edge);
        let params = common::loop_params(visibility);
        let r = Renderer::new(&v, &f, &scan, &time, params).expect("valid");
        eprintln!("{name}: {} faces, {} vertices, {} bins", f.len(), v.len(), time.bins);
        // A measurement that differs from the render, so the adjoint is non-zero wherever the signal is.
        let measured: Vec<f32> = r.forward(&brdf).iter().map(|x| 0.8 * x).collect();
        let mut g = c.benchmark_group(name);
        g.sample_size(10).measurement_time(std::time::Duration::from_secs(if name.contains("200k") {
            150
        } else {
            20
        }));
        g.throughput(Throughput::Elements((f.len() * scan.measurements()) as u64));
        g.bench_function("forward+adjoint", |b| {
            b.iter(|| r.loss_and_gradient(&brdf, &measured, Loss::L2, None).expect("ok"))
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
