//! Bin-level error of the renderer's rules against the exact quadrature at the optimiser's configuration:
//! Tsai et al. 2019's setup (confocal over [−0.25, 0.25]² m, 1200 bins of 1.2 mm, tent kernel, visibility off) on
//! the LCT start of the shared bunny (`fixtures/bunny_lct_start.obj`) remeshed to the first stage's 7.8 mm
//! edges (or EDGE_MM), every `stride`-th scan point per axis:
//! `cargo run --release -p nlos-render --example loop_accuracy -- [stride] [EDGE_MM]`.
#![allow(missing_docs)]

use std::time::Instant;

use nlos_brdf::Lambertian;
use nlos_mesh::remeshing::{BoundaryMode, RemeshParams, uniform_remeshing};
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

fn main() {
    let stride: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(8);
    let edge_mm: f32 = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(7.8125);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/bunny_lct_start.obj");
    let mut mesh = nlos_mesh::io::load(path).expect("fixture");
    let rp = RemeshParams { boundary: BoundaryMode::Remesh, ..RemeshParams::fast() };
    uniform_remeshing(&mut mesh, edge_mm * 1e-3, &rp).expect("remesh");
    let (v, f) = mesh.to_triangles();
    let all = PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid");
    let mut pts = Vec::new();
    for iy in (stride / 2..64).step_by(stride) {
        for ix in (stride / 2..64).step_by(stride) {
            pts.push(all.points[ix + 64 * iy]);
        }
    }
    let scan = Scan::confocal(PointSet::list(pts));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let render = |sampling| {
        let p = RenderParams { kernel: Kernel::Tent, sampling, visibility: Visibility::Off, two_sided: false };
        let r = Renderer::new(&v, &f, &scan, &time, p).expect("valid");
        let t = Instant::now();
        let d: Vec<f64> = r.forward(&brdf).iter().map(|x| f64::from(*x)).collect();
        (d, t.elapsed().as_secs_f64())
    };
    let fine =
        |frac| Sampling::Deterministic(DeterministicRule { max_bin_fraction: frac, min_level: 1, max_level: 64 });
    let (reference, tr) = render(fine(0.05));
    println!(
        "{} faces, {} measurements; reference (fraction 0.05, level ≤ 64) {tr:.1} s",
        f.len(),
        scan.measurements()
    );
    let pool = |d: &[f64], k: usize| d.chunks(k).map(|h| h.iter().sum::<f64>()).collect::<Vec<_>>();
    let cases: Vec<(&str, Sampling)> = vec![
        (
            "adaptive, half a bin, level ≤ 8 (former default)",
            Sampling::Deterministic(DeterministicRule { max_level: 8, ..DeterministicRule::default() }),
        ),
        ("adaptive, half a bin, level ≤ 64", fine(0.5)),
        ("fixed(1)", Sampling::Deterministic(DeterministicRule::fixed(1))),
        ("fixed(2)", Sampling::Deterministic(DeterministicRule::fixed(2))),
        ("fixed(4)", Sampling::Deterministic(DeterministicRule::fixed(4))),
        ("splat (default)", Sampling::Splat(SplatRule::default())),
        ("splat, level 2", Sampling::Splat(SplatRule { max_deviation: 1e-6, max_level: 2 })),
    ];
    for (label, s) in cases {
        let (d, t) = render(s);
        println!(
            "  {label:50} bin rel-L2 {:.2e}  pooled-8 {:.2e}  total {:.5}  ({t:.2} s)",
            rel_l2(&d, &reference),
            rel_l2(&pool(&d, 8), &pool(&reference, 8)),
            d.iter().sum::<f64>() / reference.iter().sum::<f64>(),
        );
    }
}
