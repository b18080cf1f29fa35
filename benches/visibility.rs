//! The visibility cache as the optimiser rebuilds it after every remeshing (`Renderer::refresh_visibility`:
//! the BVH and one visible share per face and measurement, `Visibility::Cached { level: 1 }`), at Tsai et al.
//! 2019's setup (confocal 64 × 64 over [−0.25, 0.25]² m), on the LCT start of the shared bunny
//! (`fixtures/bunny_lct_start.obj`) remeshed as the optimiser's stages do: 7.8 mm edges (stage 0, about 3.2k
//! faces) and about 20k faces. The cache answers each face's view of the whole wall at once
//! (`nlos_render`'s `visibility::bundle`); the tests hold it to one shadow ray per face and spot, entry by
//! entry. Figures: docs/performance.md.
#![allow(missing_docs)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nlos_render::{Renderer, Visibility};

mod common;

fn bench(c: &mut Criterion) {
    let (scan, _) = common::seed_setup();
    for (name, edge, visibility) in common::CASES {
        if visibility == Visibility::Off {
            continue;
        }
        let (v, f) = common::remeshed_start(edge);
        let time = common::stage_axis(edge);
        let mut r = Renderer::new(&v, &f, &scan, &time, common::loop_params(visibility)).expect("valid");
        eprintln!("{name}: {} faces × {} measurements", f.len(), scan.measurements());
        let mut g = c.benchmark_group(name);
        g.sample_size(10).measurement_time(std::time::Duration::from_secs(30));
        g.throughput(Throughput::Elements((f.len() * scan.measurements()) as u64));
        g.bench_function("visibility_cache", |b| b.iter(|| r.refresh_visibility()));
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
