//! Sweeps `SurfaceParams` on LCT volumes of captures with ground truth (development aid):
//! `surface_tune DATA GT [DATA GT …]`, parameter sets from stdin, one per line:
//! `grow region subvoxel rings recession smooth otsu|REL`.
use nlos_init::{LctParams, SurfaceParams, Threshold, lct, volume_to_surface};
use nlos_mesh::metrics::{EvalParams, evaluate, load_for_eval};
use std::io::BufRead;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cases: Vec<_> = args
        .chunks(2)
        .map(|p| {
            let t = nlos_transient::read(&p[0]).expect("capture");
            (lct(&t, &LctParams::default()).expect("lct"), load_for_eval(&p[1]).expect("gt"), p[0].clone())
        })
        .collect();
    for line in std::io::stdin().lock().lines() {
        let line = line.expect("line");
        let w: Vec<&str> = line.split_whitespace().collect();
        if w.len() < 7 {
            continue;
        }
        let g: f32 = w[0].parse().expect("grow");
        let params = SurfaceParams {
            grow_threshold: (g > 0.0).then_some(g),
            min_region_fraction: w[1].parse().expect("region"),
            subvoxel: w[2] == "1",
            rim_rings: w[3].parse().expect("rings"),
            rim_recession: w[4].parse().expect("rec"),
            smoothing_iterations: w[5].parse().expect("smooth"),
            threshold: if w[6] == "otsu" { Threshold::Otsu } else { Threshold::Relative(w[6].parse().expect("th")) },
            core_fraction: w.get(7).and_then(|c| c.parse::<f32>().ok()).filter(|&c| c > 0.0),
            ..SurfaceParams::default()
        };
        for (vol, gt, name) in &cases {
            let s = volume_to_surface(vol, &params).expect("surface");
            let m = evaluate(&s.mesh, gt, &EvalParams::default()).expect("eval");
            if let Ok(dir) = std::env::var("DUMP") {
                let b: Vec<u8> =
                    m.depth_reconstruction.iter().chain(&m.depth_ground_truth).flat_map(|v| v.to_le_bytes()).collect();
                std::fs::write(format!("{dir}/{}.px", &name[name.len() - 12..]), b).expect("dump");
            }
            println!(
                "{line:40} | {:>12} cov {:.3} mean {:.2} med {:.2} rms {:.2} chamfer {:.2} normal {:.1}",
                &name[name.len() - 12..],
                m.coverage,
                1e3 * m.depth_error_mean.unwrap_or(f64::NAN),
                1e3 * m.depth_error_median.unwrap_or(f64::NAN),
                1e3 * m.depth_error_rms.unwrap_or(f64::NAN),
                1e3 * m.chamfer,
                m.normal_error_mean_deg
            );
        }
    }
}
