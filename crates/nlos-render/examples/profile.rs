//! Manual timing at Tsai et al. 2019's setup (the criterion benchmark's scenes), for profiling:
//! `cargo run --release -p nlos-render --example profile -- [10k|70k|both|strat10k|strat70k] [reps]`
//! (`strat*`: Tsai et al. 2019's stratified sampling at 20,000 samples per measurement with live shadow rays).
#![allow(missing_docs)]

use std::time::Instant;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{DeterministicRule, Kernel, Loss, RenderParams, Renderer, Sampling, Visibility};
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

/// CPU seconds (user + system) of this process so far, from /proc (0 where unavailable).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return 0.0 };
    // Fields after the parenthesised command name; utime and stime are the 14th and 15th fields overall.
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = rest.split_whitespace().skip(11).take(2).filter_map(|x| x.parse().ok()).collect();
    f.iter().sum::<f64>() / 100.0
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map_or("both", String::as_str);
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let Some((v, f)) = load() else {
        eprintln!("bunny absent");
        return;
    };
    let scan = Scan::confocal(PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let small: Vec<[u32; 3]> = f.iter().step_by(7).copied().collect();
    let fixed = Sampling::Deterministic(DeterministicRule::fixed(1));
    let strat = Sampling::Stratified { samples_per_measurement: 20_000, seed: 1 };
    let mut cases = Vec::new();
    match which {
        "strat10k" => cases.push(("bunny10k stratified 20k, live", &small, Visibility::Live, strat)),
        "strat70k" => cases.push(("bunny70k stratified 20k, live", &f, Visibility::Live, strat)),
        _ => {
            if which != "70k" {
                cases.push(("bunny10k", &small, Visibility::Cached { level: 1 }, fixed));
            }
            if which != "10k" {
                cases.push(("bunny70k", &f, Visibility::Cached { level: 1 }, fixed));
            }
        }
    }
    for (name, faces, vis, sampling) in cases {
        let params = RenderParams { kernel: Kernel::Tent, sampling, visibility: vis, two_sided: false };
        let t = Instant::now();
        let r = Renderer::new(&v, faces, &scan, &time, params).expect("valid");
        println!("{name}: {} faces, setup {:.2} s", faces.len(), t.elapsed().as_secs_f64());
        let pairs = (faces.len() * scan.measurements()) as f64;
        let measured: Vec<f32> = r.forward(&brdf).iter().map(|x| 0.8 * x).collect();
        for _ in 0..reps {
            let (t, c) = (Instant::now(), cpu_seconds());
            let d = r.forward(&brdf);
            let (tf, cf) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
            let (t, c) = (Instant::now(), cpu_seconds());
            let lg = r.loss_and_gradient(&brdf, &measured, Loss::L2, None).expect("ok");
            let (tg, cg) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
            println!(
                "  forward {tf:.3} s ({:.1} M pairs/s; cpu {cf:.2} s), forward+adjoint {tg:.3} s ({:.1} M pairs/s; \
                 cpu {cg:.2} s)  [sum {:.6e}, loss {:.6e}]",
                pairs / tf * 1e-6,
                pairs / tg * 1e-6,
                d.iter().map(|x| f64::from(*x)).sum::<f64>(),
                lg.loss
            );
            let g: f64 = lg.gradient.vertices.iter().map(|g| f64::from(g.length())).sum();
            println!("    Σ|dE/dv| {g:.6e}, dE/dρ {:?}", lg.gradient.brdf);
        }
    }
}
