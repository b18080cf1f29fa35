//! Time of one forward + adjoint of the splat rule on the GPU (feature `gpu`) against the CPU, at the sizes the GPU
//! backend is judged on: a height field facing the wall (every face seen by every spot; visibility off) of about
//! F faces at z ≈ 0.5 m, a confocal G × G scan over [−0.25, 0.25]² m and B bins of 1.2 mm:
//! `cargo run --release -p nlos-render --features gpu --example gpu_cost -- [F:G:B ...] [--reps N] [--cpu]`
//! (default `3000:64:1200 20000:64:1200 200000:64:1200 20000:256:512`). Prints, per size, the GPU's first call
//! (pipelines, uploads) and its best of N calls, the CPU's time with `--cpu`, and the largest difference between
//! the two transients and gradients.
#![allow(missing_docs)]

use std::time::Instant;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{GpuRenderer, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// A height field of about `faces` triangles (`nlos_testdata::scenes::height_field`).
fn height_field(faces: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let n = ((faces as f64 / 2.0).sqrt().round() as usize + 1).max(2);
    let (p, f) = nlos_testdata::scenes::height_field(n);
    (p.into_iter().map(Vec3::from_array).collect(), f)
}

fn max_abs(v: impl IntoIterator<Item = f32>) -> f32 {
    v.into_iter().fold(0.0, |m, x| m.max(x.abs()))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cpu = args.iter().any(|a| a == "--cpu");
    let reps: usize =
        args.iter().position(|a| a == "--reps").and_then(|i| args.get(i + 1)).and_then(|s| s.parse().ok()).unwrap_or(3);
    let mut sizes: Vec<(usize, usize, usize)> = args
        .iter()
        .filter_map(|a| {
            let v: Vec<usize> = a.split(':').filter_map(|x| x.parse().ok()).collect();
            (v.len() == 3).then(|| (v[0], v[1], v[2]))
        })
        .collect();
    if sizes.is_empty() {
        sizes = vec![(3000, 64, 1200), (20_000, 64, 1200), (200_000, 64, 1200), (20_000, 256, 512)];
    }
    let mut gpu = match GpuRenderer::new() {
        Ok(g) => g,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    println!("adapter: {}; CPU threads: {}", gpu.adapter(), rayon::current_num_threads());
    let brdf = Lambertian::new(1.0f32).expect("albedo");
    for (faces, grid, bins) in sizes {
        let (p, f) = height_field(faces);
        let scan = Scan::confocal(PointSet::wall_grid(grid, grid, 0.25, 0.25).expect("grid"));
        // Paths of 1.0–1.3 m: 1200 bins from 0 (the loop's axis) or 512 from 0.8 m.
        let t0 = if bins >= 1200 { 0.0 } else { 0.8 };
        let time = TimeAxis::new(t0, 0.0012, bins).expect("axis");
        let params = RenderParams {
            sampling: Sampling::Splat(SplatRule::default()),
            visibility: Visibility::Off,
            ..RenderParams::default()
        };
        let r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
        let adj: Vec<f32> = (0..r.len()).map(|i| ((i % bins) as f32 * 0.13 + (i / bins) as f32 * 0.7).cos()).collect();
        let t = Instant::now();
        let fw = gpu.forward(&r, &brdf).expect("GPU forward");
        let gd = gpu.adjoint(&r, &brdf, &adj).expect("GPU adjoint");
        let first = t.elapsed().as_secs_f64();
        let (mut best_f, mut best_a) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..reps {
            let t = Instant::now();
            let again = gpu.forward(&r, &brdf).expect("GPU forward");
            best_f = best_f.min(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let _ = gpu.adjoint(&r, &brdf, &adj).expect("GPU adjoint");
            best_a = best_a.min(t.elapsed().as_secs_f64());
            assert!(again.iter().zip(&fw).all(|(a, b)| a.to_bits() == b.to_bits()), "GPU forward not repeatable");
        }
        print!(
            "{} faces × {} measurements × {bins} bins: GPU forward {:.3} s + adjoint {:.3} s = {:.3} s (first call {:.2} s)",
            f.len(),
            grid * grid,
            best_f,
            best_a,
            best_f + best_a,
            first
        );
        if cpu {
            let t = Instant::now();
            let fc = r.forward(&brdf);
            let tf = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let gc = r.adjoint(&brdf, &adj).expect("CPU adjoint");
            let ta = t.elapsed().as_secs_f64();
            let peak = max_abs(fc.iter().copied());
            let ferr = max_abs(fc.iter().zip(&fw).map(|(a, b)| a - b)) / peak;
            let top = max_abs(gc.vertices.iter().flat_map(|v| v.to_array()));
            let gerr = max_abs(gc.vertices.iter().zip(&gd.vertices).flat_map(|(a, b)| (*a - *b).to_array())) / top;
            print!(
                "; CPU forward {tf:.2} s + adjoint {ta:.2} s = {:.2} s ({:.0}×); |GPU − CPU|: transient {ferr:.1e} of peak, gradient {gerr:.1e} of largest",
                tf + ta,
                (tf + ta) / (best_f + best_a)
            );
        }
        println!();
    }
}
