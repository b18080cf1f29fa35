//! Time of one forward + adjoint with the optimiser's renderer settings at Tsai et al. 2019's setup (confocal
//! 64 × 64 over [−0.25, 0.25]² m, 1200 bins of 1.2 mm, tent kernel, cached visibility), on the LCT start of
//! the shared bunny (`fixtures/bunny_lct_start.obj`) remeshed to a target edge length, for each rule:
//! `cargo run --release -p nlos-render --example loop_cost -- [EDGE_MM] [reps] [rules]`
//! (rules: comma-separated of `splat`, `splat@D` (`max_deviation` D bins), `splat2` (level 2), `adaptive8` (the former default), `fixed1`, `fixed2`,
//! `fixed4`; default `splat,adaptive8`; visibility off with `VIS=off` in the environment).
#![allow(missing_docs)]

use std::time::Instant;

use nlos_brdf::Lambertian;
use nlos_mesh::remeshing::{BoundaryMode, RemeshParams, uniform_remeshing};
use nlos_render::{DeterministicRule, Kernel, Loss, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let edge_mm: f32 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(7.8125);
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let rules = args.get(3).map_or("splat,adaptive8", String::as_str);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/bunny_lct_start.obj");
    let mut mesh = nlos_mesh::io::load(path).expect("fixture");
    let t = Instant::now();
    let rp = RemeshParams { boundary: BoundaryMode::Remesh, ..RemeshParams::fast() };
    uniform_remeshing(&mut mesh, edge_mm * 1e-3, &rp).expect("remesh");
    let (v, f) = mesh.to_triangles();
    eprintln!("{} faces, {} vertices (remeshed in {:.1} s)", f.len(), v.len(), t.elapsed().as_secs_f64());
    let scan = Scan::confocal(PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    for rule in rules.split(',') {
        let sampling = match rule {
            "splat" => Sampling::Splat(SplatRule::default()),
            "splat2" => Sampling::Splat(SplatRule { max_deviation: 1e-6, max_level: 2 }),
            "adaptive8" => Sampling::Deterministic(DeterministicRule { max_level: 8, ..DeterministicRule::default() }),
            "fixed1" => Sampling::Deterministic(DeterministicRule::fixed(1)),
            "fixed2" => Sampling::Deterministic(DeterministicRule::fixed(2)),
            "fixed4" => Sampling::Deterministic(DeterministicRule::fixed(4)),
            other => match other.strip_prefix("splat@").and_then(|d| d.parse().ok()) {
                Some(max_deviation) => Sampling::Splat(SplatRule { max_deviation, ..SplatRule::default() }),
                None => panic!("unknown rule {other}"),
            },
        };
        let visibility = if std::env::var("VIS").as_deref() == Ok("off") {
            Visibility::Off
        } else {
            Visibility::Cached { level: 1 }
        };
        let params = RenderParams { kernel: Kernel::Tent, sampling, visibility, two_sided: false };
        let t = Instant::now();
        let r = Renderer::new(&v, &f, &scan, &time, params).expect("valid");
        let setup = t.elapsed().as_secs_f64();
        let measured: Vec<f32> = r.forward(&brdf).iter().map(|x| 0.8 * x).collect();
        let mut best = f64::INFINITY;
        for _ in 0..reps {
            let t = Instant::now();
            let out = r.loss_and_gradient(&brdf, &measured, Loss::L2, None).expect("ok");
            best = best.min(t.elapsed().as_secs_f64());
            std::hint::black_box(out);
        }
        let t = Instant::now();
        std::hint::black_box(r.forward(&brdf));
        let fwd = t.elapsed().as_secs_f64();
        println!("{rule:10} setup {setup:.2} s, forward {fwd:.3} s, forward + adjoint {best:.3} s (best of {reps})");
    }
}
