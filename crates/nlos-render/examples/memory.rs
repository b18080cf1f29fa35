//! Peak memory at Tsai et al. 2019's scale: a 100k-vertex mesh (a 317 × 317 height field, 200k faces, facing the
//! wall), confocal 64 × 64 scan, 1200 bins of 1.2 mm, fixed(1) rule, tent kernel; renderer construction,
//! forward pass and fused loss-and-gradient. Prints the peak resident set size (VmHWM from /proc) after each
//! step: `cargo run --release -p nlos-render --example memory -- [off|cached]`. With `cached` the
//! visibility cache (one byte per (triangle, measurement), 0.8 GB here) is built too: 8e8 shadow rays,
//! minutes on two cores.
#![allow(missing_docs)]

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_render::{DeterministicRule, Kernel, Loss, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// Peak resident set size in MiB (VmHWM of /proc/self/status), 0 where unavailable.
fn peak_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kib = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(0.0);
    kib / 1024.0
}

fn main() {
    let cached = std::env::args().nth(1).is_some_and(|a| a == "cached");
    // (n)² ≈ 100k vertices, 200k faces.
    let (p, f) = nlos_testdata::scenes::height_field(317);
    let p: Vec<Vec3> = p.into_iter().map(Vec3::from_array).collect();
    println!("mesh: {} vertices, {} faces; baseline peak RSS {:.0} MiB", p.len(), f.len(), peak_mib());
    let scan = Scan::confocal(PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
    let params = RenderParams {
        kernel: Kernel::Tent,
        sampling: Sampling::Deterministic(DeterministicRule::fixed(1)),
        visibility: if cached { Visibility::Cached { level: 1 } } else { Visibility::Off },
        two_sided: false,
    };
    let t = std::time::Instant::now();
    let r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
    println!("renderer ({:?}): peak RSS {:.0} MiB ({:.1} s)", params.visibility, peak_mib(), t.elapsed().as_secs_f64());
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let t = std::time::Instant::now();
    let data = r.forward(&brdf);
    println!("forward ({} values): peak RSS {:.0} MiB ({:.1} s)", data.len(), peak_mib(), t.elapsed().as_secs_f64());
    let measured: Vec<f32> = data.iter().map(|v| 0.9 * v).collect();
    drop(data);
    let t = std::time::Instant::now();
    let lg = r.loss_and_gradient(&brdf, &measured, Loss::L2, None).expect("ok");
    println!(
        "forward + loss + adjoint: peak RSS {:.0} MiB ({:.1} s; loss {:.4e})",
        peak_mib(),
        t.elapsed().as_secs_f64(),
        lg.loss
    );
}
