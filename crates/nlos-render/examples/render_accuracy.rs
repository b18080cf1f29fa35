//! What `nlos render` simulates, against a converged reference: the shared bunny at Tsai et al. 2019's setup
//! (1200 bins of 1.2 mm, **box** kernel, as a bin holds the integral over it), every `stride`-th scan point per
//! axis: `cargo run --release -p nlos-render --example render_accuracy -- [stride]`.
//!
//! Part 1, visibility off: the adaptive quadrature (`DeterministicRule`, the former `--mode exact`) and the
//! box splat (`Sampling::Splat` with `Kernel::Box`) at several `max_deviation`s, against the quadrature at
//! sub-triangles of at most 0.05 bins. Part 2, visibility on: the cached visible fractions at levels 1, 2 and 4
//! against level 8 (the box splat at its default). Part 3: the former and the new `nlos render` defaults against
//! the quadrature at 0.05 bins with visibility at level 8.
#![allow(missing_docs)]

use std::time::Instant;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

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
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let render = |sampling, visibility| {
        let t = Instant::now();
        let p = RenderParams { kernel: Kernel::Box, sampling, visibility, two_sided: false };
        let r = Renderer::new(&v, &f, &scan, &time, p).expect("valid");
        let d: Vec<f64> = r.forward(&brdf).iter().map(|x| f64::from(*x)).collect();
        (d, t.elapsed().as_secs_f64())
    };
    let quadrature =
        |frac| Sampling::Deterministic(DeterministicRule { max_bin_fraction: frac, min_level: 1, max_level: 64 });
    let splat = |max_deviation| Sampling::Splat(SplatRule { max_deviation, max_level: 64 });
    let pool = |d: &[f64], k: usize| d.chunks(k).map(|h| h.iter().sum::<f64>()).collect::<Vec<_>>();
    let report = |label: &str, d: &[f64], reference: &[f64], t: f64| {
        println!(
            "  {label:44} bin rel-L2 {:.2e}  pooled-8 {:.2e}  total {:.6}  ({t:.2} s)",
            rel_l2(d, reference),
            rel_l2(&pool(d, 8), &pool(reference, 8)),
            d.iter().sum::<f64>() / reference.iter().sum::<f64>(),
        );
    };
    println!("{} faces, {} measurements, box kernel", f.len(), scan.measurements());
    let (reference, tr) = render(quadrature(0.05), Visibility::Off);
    println!("visibility off; reference: quadrature at 0.05 bins ({tr:.1} s)");
    for (label, s) in [
        ("quadrature, 0.5 bins (the former --mode exact)", quadrature(0.5)),
        ("box splat, max_deviation 0.09", splat(0.09)),
        ("box splat, max_deviation 0.03", splat(0.03)),
        ("box splat, max_deviation 0.01", splat(0.01)),
    ] {
        let (d, t) = render(s, Visibility::Off);
        report(label, &d, &reference, t);
    }
    let (reference, tr) = render(quadrature(0.05), Visibility::Cached { level: 8 });
    println!("both; reference: quadrature at 0.05 bins, visibility level 8 ({tr:.1} s)");
    for (label, s, level) in [
        ("quadrature, 0.5 bins, visibility level 2 (former)", quadrature(0.5), 2),
        ("box splat 0.09, visibility level 1 (default)", splat(0.09), 1),
        ("box splat 0.09, visibility level 2", splat(0.09), 2),
    ] {
        let (d, t) = render(s, Visibility::Cached { level });
        report(label, &d, &reference, t);
    }
    let (reference, tr) = render(splat(0.03), Visibility::Cached { level: 8 });
    println!("visibility cached; reference: level 8 ({tr:.1} s)");
    for level in [1, 2, 4] {
        let (d, t) = render(splat(0.03), Visibility::Cached { level });
        report(&format!("box splat, visibility level {level}"), &d, &reference, t);
    }
}
