//! Tuning driver: runs the optimiser on a capture from a given initial mesh with parameters from the
//! command line, and prints the `nlos eval` metrics of the initial and final meshes against a ground truth.
//!
//! ```text
//! cargo run --release -p nlos-optim --example tune -- CAPTURE INIT.obj GT.obj OUT_DIR [key=value ...]
//! ```
//! Keys: `res`, `stages`, `blocks`, `iters`, `refl_iters`, `lr`, `lr_b`, `reg`, `rel_tol`, `growth`,
//! `max_level`, `min_level`, `bin_frac`, `collision` (0/1), `unlit` (0/1), `seed`, `rebin`, `subsample`,
//! `vis` (cached/off/live), `max_faces`, `sensor` (jitter file or `ideal`), `loss` (l2/poisson).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use nlos_optim::{Hooks, Loss, ReconstructParams, SamplingSchedule, SensorBackground, SensorFit, reconstruct_with};
use nlos_render::{DeterministicRule, Visibility};
use nlos_transient::sensor::{BackgroundWindow, BinKernel, JitterResponse};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    assert!(args.len() >= 4, "usage: tune CAPTURE INIT.obj GT.obj OUT_DIR [key=value ...]");
    let mut measured = nlos_transient::read(&args[0]).expect("capture");
    let init = nlos_mesh::io::load(&args[1]).expect("init mesh");
    let gt = nlos_mesh::metrics::load_for_eval(&args[2]).expect("gt mesh");
    let out = PathBuf::from(&args[3]);
    let mut p = ReconstructParams { out_dir: Some(out.clone()), ..ReconstructParams::default() };
    p.render.visibility = Visibility::Cached { level: 1 };
    let mut rule = DeterministicRule::default();
    let kv: Vec<(String, String)> = args[4..]
        .iter()
        .map(|a| {
            let (k, v) = a.split_once('=').expect("key=value");
            (k.to_string(), v.to_string())
        })
        .collect();
    for (k, v) in &kv {
        let f = || v.parse::<f64>().expect("number");
        let u = || v.parse::<u32>().expect("integer");
        match k.as_str() {
            "res" => p.schedule.initial_resolution = f(),
            "stages" => p.schedule.max_stages = u(),
            "blocks" => p.schedule.max_blocks_per_stage = u(),
            "iters" => p.schedule.shape_iterations = u(),
            "refl_iters" => p.schedule.reflectance_iterations = u(),
            "rel_tol" => p.schedule.rel_tol = f(),
            "growth" => p.schedule.growth = f(),
            "max_faces" => p.schedule.max_faces = u() as usize,
            "lr" => p.lr_interior = f(),
            "lr_b" => p.lr_boundary = f(),
            "reg" => p.regulariser_ratio = f(),
            "max_level" => rule.max_level = u(),
            "min_level" => rule.min_level = u(),
            "bin_frac" => rule.max_bin_fraction = v.parse().expect("number"),
            "collision" => {
                if u() == 0 {
                    p.collision = None;
                }
            }
            "unlit" => p.remove_unlit_boundary_faces = u() != 0,
            "seed" => p.seed = u64::from(u()),
            "rebin" => measured = measured.rebin(u() as usize).expect("rebin"),
            "subsample" => measured = measured.subsample(u() as usize, u() as usize).expect("subsample"),
            "vis" => {
                p.render.visibility = match v.as_str() {
                    "off" => Visibility::Off,
                    "live" => Visibility::Live,
                    _ => Visibility::Cached { level: 1 },
                }
            }
            "loss" => {
                p.data.loss = if v == "poisson" { Loss::PoissonNll { floor: 1e-12 } } else { Loss::L2 };
            }
            "sensor" => {
                let kernel = if v == "ideal" {
                    BinKernel::identity()
                } else {
                    JitterResponse::load(v).expect("jitter").to_bins(measured.time().bin_width).expect("bins")
                };
                p.sensor = Some(SensorFit { kernel, background: SensorBackground::Estimate(BackgroundWindow::Auto) });
            }
            other => panic!("unknown key {other}"),
        }
    }
    p.sampling = SamplingSchedule::Deterministic(rule);
    p.validate().expect("params");
    let eval = |m: &nlos_mesh::SurfaceMesh| {
        let r = nlos_mesh::metrics::evaluate(m, &gt, &nlos_mesh::EvalParams::default()).expect("eval");
        format!(
            "coverage {:.3} depth mean {:.2} mm median {:.2} mm rms {:.2} mm chamfer {:.2} mm normal {:.1} deg",
            r.coverage,
            r.depth_error_mean.unwrap_or(f64::NAN) * 1e3,
            r.depth_error_median.unwrap_or(f64::NAN) * 1e3,
            r.depth_error_rms.unwrap_or(f64::NAN) * 1e3,
            r.chamfer * 1e3,
            r.normal_error_mean_deg,
        )
    };
    println!("init : {} faces; {}", init.n_faces(), eval(&init));
    let t0 = std::time::Instant::now();
    let mut last_stage = u32::MAX;
    let mut progress = |pr: &nlos_optim::Progress| {
        if pr.event == nlos_optim::ProgressEvent::BlockEnd || pr.stage != last_stage {
            last_stage = pr.stage;
            eprintln!(
                "  stage {} block {} it {} loss {:.4e} faces {} t {:.0}s",
                pr.stage, pr.blocks_done, pr.iteration, pr.loss, pr.faces, pr.elapsed_s
            );
        }
        std::ops::ControlFlow::Continue(())
    };
    let hooks = Hooks { progress: Some(&mut progress), evolve: None };
    let outcome = reconstruct_with(&measured, &init, &p, hooks).expect("reconstruct");
    let secs = t0.elapsed().as_secs_f64();
    let evolve_s: f64 = outcome.evolve.iter().map(|r| r.seconds).sum();
    let adjusted: usize = outcome.evolve.iter().map(|r| r.vertices_adjusted).sum();
    println!("final: {} faces; {}", outcome.mesh.n_faces(), eval(&outcome.mesh));
    println!(
        "time {secs:.0} s (evolve {evolve_s:.1} s over {} blocks, {adjusted} vertices adjusted); scale {:.4e}; theta {:?}",
        outcome.evolve.len(),
        outcome.scale,
        outcome.reflectance.theta()
    );
}
