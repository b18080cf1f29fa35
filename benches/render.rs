//! Criterion benchmarks at Tsai et al. 2019's setup: confocal 64 × 64 over [−0.25, 0.25]² of the wall, 1200 bins of
//! 1.2 mm, the shared bunny (`shared/data/meshes/bunny_centered.obj`, 69,630 faces) and a naive 10k-face
//! version (every 7th face). Deterministic mode, one sample per (triangle, measurement) (`fixed(1)`: at this
//! mesh density a face spans a few bins, and Tsai et al. 2019's 20,000 samples per measurement are 0.3 per face),
//! tent kernel. Visibility: cached (level 1: one shadow ray per triangle and measurement at setup; the full
//! bunny's cache build, 2.9e8 shadow rays, takes about 34 s and is outside the timed loop). Throughput =
//! (triangle × measurement) pairs per second.
//!
//! The `bunny10k_stratified20k_live` group times Tsai et al. 2019's own scheme for comparison with the original renderer:
//! stratified area sampling at 20,000 samples per measurement, a live shadow ray per sample (throughput there: samples per second).
#![allow(missing_docs)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// The shared bunny as positions + triangles, read with `nlos-mesh` (a dev-dependency only: the renderer
/// itself takes plain arrays); `None`, with the reason printed, when the file is absent or unreadable.
fn load() -> Option<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let path = nlos_testdata::shared("meshes/bunny_centered.obj")?;
    match nlos_mesh::io::load(&path) {
        Ok(mesh) => Some(mesh.to_triangles()),
        Err(e) => {
            eprintln!("skipping: {e}");
            None
        }
    }
}

fn bench(c: &mut Criterion) {
    let Some((v, f)) = load() else { return };
    let scan = Scan::confocal(PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let small: Vec<[u32; 3]> = f.iter().step_by(7).copied().collect();
    for (name, faces, vis) in
        [("bunny10k", &small, Visibility::Cached { level: 1 }), ("bunny70k", &f, Visibility::Cached { level: 1 })]
    {
        let params = RenderParams {
            kernel: Kernel::Tent,
            sampling: Sampling::Deterministic(DeterministicRule::fixed(1)),
            visibility: vis,
            two_sided: false,
        };
        let t = std::time::Instant::now();
        let r = Renderer::new(&v, faces, &scan, &time, params).expect("valid");
        eprintln!("{name}: {} faces, setup (BVH + visibility cache) {:.1} s", faces.len(), t.elapsed().as_secs_f64());
        // A measurement that differs from the render, so the adjoint is non-zero everywhere the signal is.
        let measured: Vec<f32> = r.forward(&brdf).iter().map(|x| 0.8 * x).collect();
        let mut g = c.benchmark_group(name);
        g.sample_size(10).measurement_time(std::time::Duration::from_secs(8));
        g.throughput(Throughput::Elements((faces.len() * scan.measurements()) as u64));
        g.bench_function("forward", |b| b.iter(|| r.forward(&brdf)));
        g.bench_function("forward+adjoint", |b| {
            b.iter(|| r.loss_and_gradient(&brdf, &measured, nlos_render::Loss::L2, None).expect("ok"))
        });
        g.finish();
        if name == "bunny10k" {
            // The same with per-triangle reflectance factors (an albedo map, `set_face_weights`): the cost of
            // reading one factor per (measurement, triangle) pair.
            let mut rw = Renderer::new(&v, faces, &scan, &time, params).expect("valid");
            let w: Vec<f32> = (0..faces.len()).map(|i| 0.5 + (i % 7) as f32 / 7.0).collect();
            rw.set_face_weights(Some(&w)).expect("valid");
            let mut g = c.benchmark_group("bunny10k_face_weights");
            g.sample_size(10).measurement_time(std::time::Duration::from_secs(8));
            g.throughput(Throughput::Elements((faces.len() * scan.measurements()) as u64));
            g.bench_function("forward", |b| b.iter(|| rw.forward(&brdf)));
            g.bench_function("forward+adjoint", |b| {
                b.iter(|| rw.loss_and_gradient(&brdf, &measured, nlos_render::Loss::L2, None).expect("ok"))
            });
            g.finish();
        }
    }
    {
        let (name, faces) = ("bunny10k_stratified20k_live", &small);
        let params = RenderParams {
            kernel: Kernel::Tent,
            sampling: Sampling::Stratified { samples_per_measurement: 20_000, seed: 1 },
            visibility: Visibility::Live,
            two_sided: false,
        };
        let r = Renderer::new(&v, faces, &scan, &time, params).expect("valid");
        let measured: Vec<f32> = r.forward(&brdf).iter().map(|x| 0.8 * x).collect();
        let mut g = c.benchmark_group(name);
        g.sample_size(10).measurement_time(std::time::Duration::from_secs(8));
        g.throughput(Throughput::Elements(20_000 * scan.measurements() as u64));
        g.bench_function("forward", |b| b.iter(|| r.forward(&brdf)));
        g.bench_function("forward+adjoint", |b| {
            b.iter(|| r.loss_and_gradient(&brdf, &measured, nlos_render::Loss::L2, None).expect("ok"))
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
