//! Transient error of the sampling rules at Tsai et al. 2019's setup (full bunny, 1200 bins of 1.2 mm, tent kernel,
//! visibility off) on a subset of measurements, against a fine deterministic reference:
//! `cargo run --release -p nlos-render --example accuracy -- [stride]`.
#![allow(missing_docs)]

use std::time::Instant;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// The shared bunny as positions + triangles, read with `nlos-mesh` (a dev-dependency only: the renderer
/// itself takes plain arrays); `None`, with the reason printed, when the file is absent or unreadable.
fn load() -> Option<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/meshes/bunny_centered.obj");
    match nlos_mesh::io::load(path) {
        Ok(mesh) => Some(mesh.to_triangles()),
        Err(e) => {
            eprintln!("skipping: {e}");
            None
        }
    }
}

fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

fn main() {
    let stride: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(8);
    let Some((v, f)) = load() else { return };
    let all = PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid");
    let mut pts = Vec::new();
    for iy in (stride / 2..64).step_by(stride) {
        for ix in (stride / 2..64).step_by(stride) {
            pts.push(all.points[ix + 64 * iy]);
        }
    }
    let scan = Scan::confocal(PointSet::list(pts));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let bins = time.bins;
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let small: Vec<[u32; 3]> = f.iter().step_by(7).copied().collect();
    for (name, faces) in [("bunny70k", &f), ("bunny10k", &small)] {
        let render = |sampling| {
            let p = RenderParams { kernel: Kernel::Tent, sampling, visibility: Visibility::Off, two_sided: false };
            let r = Renderer::new(&v, faces, &scan, &time, p).expect("valid");
            let t = Instant::now();
            let d: Vec<f64> = r.forward(&brdf).iter().map(|x| f64::from(*x)).collect();
            (d, t.elapsed().as_secs_f64())
        };
        let fine =
            |frac| Sampling::Deterministic(DeterministicRule { max_bin_fraction: frac, min_level: 1, max_level: 64 });
        let (reference, tr) = render(fine(0.1));
        println!("{name}: {} measurements, reference (fraction 0.1) {tr:.1} s", scan.measurements());
        let pool = |d: &[f64], k: usize| d.chunks(k).map(|h| h.iter().sum::<f64>()).collect::<Vec<_>>();
        let img = |d: &[f64]| d.chunks(bins).map(|h| h.iter().sum::<f64>()).collect::<Vec<_>>();
        let mut cases: Vec<(String, Sampling)> = vec![
            ("fraction 0.2".into(), fine(0.2)),
            ("fraction 0.5 (default)".into(), fine(0.5)),
            ("fraction 1".into(), fine(1.0)),
            ("fraction 2".into(), fine(2.0)),
            ("fixed(1)".into(), Sampling::Deterministic(DeterministicRule::fixed(1))),
            ("fixed(2)".into(), Sampling::Deterministic(DeterministicRule::fixed(2))),
        ];
        for seed in 0..2 {
            cases.push((
                format!("stratified 20000 spp seed {seed}"),
                Sampling::Stratified { samples_per_measurement: 20_000, seed },
            ));
        }
        for (label, s) in cases {
            let (d, t) = render(s);
            println!(
                "  {label:32} voxel rel-L2 {:.4}  pooled-8 {:.4}  image {:.5}  total {:.5}  ({t:.2} s)",
                rel_l2(&d, &reference),
                rel_l2(&pool(&d, 8), &pool(&reference, 8)),
                rel_l2(&img(&d), &img(&reference)),
                d.iter().sum::<f64>() / reference.iter().sum::<f64>(),
            );
        }
    }
}
