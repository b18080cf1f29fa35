//! Throughput of value+gradient evaluation, general and confocal, in f32 (the renderer's precision).
//!
//! Each iteration evaluates a batch of 4096 pre-generated random front-facing configurations (unnormalised
//! vectors, as the renderer passes them), so the reported element throughput is evaluations per second.

use criterion::{Criterion, Throughput, black_box, criterion_group, criterion_main};
use glam::Vec3;
use nlos_brdf::{Brdf, Fresnel, Ggx, Lambertian, Masking};

const BATCH: usize = 4096;

/// Reproducible inputs from the workspace's SplitMix64 (`nlos_transient::rng`).
struct Inputs(nlos_transient::rng::SplitMix64);
impl Inputs {
    fn f32(&mut self) -> f32 {
        self.0.next_f32()
    }
    fn upper(&mut self) -> Vec3 {
        // Random direction with positive z, random length in [0.5, 2].
        let v = Vec3::new(self.f32() * 2.0 - 1.0, self.f32() * 2.0 - 1.0, 0.05 + self.f32());
        v.normalize() * (0.5 + 1.5 * self.f32())
    }
}

fn configs() -> Vec<(Vec3, Vec3, Vec3)> {
    let mut rng = Inputs(nlos_transient::rng::SplitMix64::new(0x9e37_79b9));
    (0..BATCH)
        .map(|_| {
            let n = Vec3::new(0.1 * (rng.f32() - 0.5), 0.1 * (rng.f32() - 0.5), 1.0);
            (rng.upper(), rng.upper(), n)
        })
        .collect()
}

fn bench_brdf<B: Brdf<Scalar = f32>>(c: &mut Criterion, name: &str, brdf: B) {
    let cfg = configs();
    let mut group = c.benchmark_group(name);
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("eval_grad general", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for &(l, s, n) in &cfg {
                let g = brdf.eval_grad(black_box(l), black_box(s), black_box(n));
                acc += g.value + g.d_omega_l.x + g.d_omega_s.y + g.d_n.z;
            }
            acc
        })
    });
    group.bench_function("eval_grad confocal", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for &(l, _, n) in &cfg {
                let g = brdf.eval_grad_confocal(black_box(l), black_box(n));
                acc += g.value + g.d_omega.x + g.d_n.z;
            }
            acc
        })
    });
    group.bench_function("eval general", |b| {
        b.iter(|| cfg.iter().map(|&(l, s, n)| brdf.eval(black_box(l), black_box(s), black_box(n))).sum::<f32>())
    });
    group.bench_function("eval confocal", |b| {
        b.iter(|| cfg.iter().map(|&(l, _, n)| brdf.eval_confocal(black_box(l), black_box(n))).sum::<f32>())
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    let ggx = Ggx::new(0.3f32, 1.0, 0.2, Fresnel::One).expect("valid parameters");
    bench_brdf(c, "ggx separable F=1", ggx);
    let ggx_hc = Ggx::new(0.3f32, 1.0, 0.2, Fresnel::Schlick { f0: 0.04 })
        .expect("valid parameters")
        .with_masking(Masking::HeightCorrelated);
    bench_brdf(c, "ggx height-correlated schlick", ggx_hc);
    bench_brdf(c, "lambertian", Lambertian::new(0.5f32).expect("valid parameters"));
}

criterion_group!(brdf, benches);
criterion_main!(brdf);
