//! The starts: LCT and f-k on a 64 × 64 × 1024 confocal capture (target: ≤ 1 s each on a 2-core machine),
//! space carving on 64 × 64 × 1200, the phasor field on a one-laser capture of 64 × 64 sensors × 1200 bins
//! (the shared `bunny_single_mc`'s setup) with a voxel at every bin's depth (target: ≤ 10 s on a 2-core
//! machine). `cargo bench --bench init`; figures in docs/performance.md.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use nlos_init::{CarveParams, FkParams, Gate, LctParams, PfParams, carve, fk, lct, pf};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

fn capture(bins: usize) -> Transient {
    noise(Scan::confocal(PointSet::wall_grid(64, 64, 0.4, 0.4).expect("grid")), bins)
}

fn noise(scan: Scan, bins: usize) -> Transient {
    let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.0024, bins).expect("axis")).expect("zeros");
    // Deterministic pseudo-random counts (the cost does not depend on the values).
    let mut s = 0x2545_f491_4f6c_dd1du64;
    for v in t.data_mut() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        *v = (s >> 40) as f32 / (1u64 << 24) as f32;
    }
    t
}

/// [`capture`] plus the return of a plane at 0.4 m (5× the noise's maximum at path `2r`), so that
/// carving finds first returns and carves (on noise alone it stops early with `InitError::Empty`).
fn capture_with_plane(bins: usize) -> Transient {
    let mut t = capture(bins);
    for m in 0..t.measurements() {
        let p = t.scan().measurement(m).laser;
        let r = (0.16 + (p.x * p.x + p.y * p.y) as f64).sqrt();
        let k = (2.0 * r / 0.0024) as usize;
        if k < bins {
            t.histogram_mut(m)[k] += 5.0;
        }
    }
    t
}

fn bench(c: &mut Criterion) {
    let t = capture(1024);
    let mut g = c.benchmark_group("init_64x64x1024");
    g.sample_size(10);
    g.bench_function("lct", |b| {
        b.iter(|| lct(&t, &LctParams { gate: Gate::None, ..LctParams::default() }).expect("lct"))
    });
    g.bench_function("fk", |b| b.iter(|| fk(&t, &FkParams { gate: Gate::None, ..FkParams::default() }).expect("fk")));
    g.finish();
    let t = capture_with_plane(1200);
    let mut g = c.benchmark_group("init_64x64x1200");
    g.sample_size(10);
    g.bench_function("carve", |b| {
        b.iter(|| carve(&t, &CarveParams { gate: Gate::None, ..CarveParams::default() }).expect("carve"))
    });
    g.finish();
    // One laser, 64 × 64 sensors over [−0.25, 0.25]², 1200 bins of 1.2 mm: `bunny_single_mc`'s setup.
    let one = PointSet::list(vec![glam::Vec3::new(0.05, -0.05, 0.0)]);
    let t = noise(Scan::exhaustive(one, PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid")), 1200);
    let mut g = c.benchmark_group("pf_1x4096x1200");
    g.sample_size(10);
    // A voxel at every bin's depth (depth step = half a bin of path: 1,200 depths), and the default step.
    let every_bin = PfParams { gate: Gate::None, depth_step: Some(0.0006), ..PfParams::default() };
    g.bench_function("every_bin", |b| b.iter(|| pf(&t, &every_bin).expect("pf")));
    g.bench_function("default", |b| {
        b.iter(|| pf(&t, &PfParams { gate: Gate::None, ..PfParams::default() }).expect("pf"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
