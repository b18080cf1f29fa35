//! Two starts, the data choose (`init_rim = "choose"`, `nlos_optim::pipeline::StartChoice`): the run goes on
//! from the candidate with the lower misfit at stage 1's first step, its result is the result of a run
//! started from that candidate alone, and an interruption while the candidates run resumes. Which rim wins
//! on which capture is measured on the `nonconfocal` acceptance scenario (docs/accuracy.md).
#![allow(clippy::unwrap_used)]

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_optim::pipeline::{self, CANDIDATES_DIR, Config, Prepared, Start, StartRim};
use nlos_optim::{Hooks, Outcome, Progress, ProgressEvent, StopReason};
use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

mod common;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join("nlos-optim-tests").join("start_choice").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A dish: a spherical cap of radius `r` and half-angle 55° about +z as a height field facing the wall, its
/// rim 0.4 m from the wall and its inside toward it. The two starts of its phasor field differ at the rim.
fn dish(r: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let rim = r * 55f32.to_radians().sin();
    let n = 40;
    let (mut p, t) = common::height_field(n, 2.0 * rim / n as f32, 0.0, 0.0, |x, y| {
        0.4 + (r * r - (x * x + y * y).min(rim * rim)).sqrt() - r * 55f32.to_radians().cos()
    });
    // The square's corners beyond the rim fold onto it: pull them in to the circle.
    for q in &mut p {
        let d = (q.x * q.x + q.y * q.y).sqrt();
        if d > rim {
            q.x *= rim / d;
            q.y *= rim / d;
        }
    }
    (p, t)
}

/// `mesh` seen by one laser at the wall's centre and 24 × 24 sensors over 0.5 m, 300 bins of 4 mm.
fn one_laser(mesh: &(Vec<Vec3>, Vec<[u32; 3]>)) -> Transient {
    let scan = Scan::exhaustive(PointSet::list(vec![Vec3::ZERO]), PointSet::wall_grid(24, 24, 0.25, 0.25).unwrap());
    let time = TimeAxis::new(0.0, 0.004, 300).unwrap();
    let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
    let r = Renderer::new(&mesh.0, &mesh.1, &scan, &time, params).unwrap();
    r.forward_transient(&Lambertian::new(1.0f32).unwrap()).unwrap()
}

/// Two short stages.
fn config(rim: StartRim) -> Config {
    let text = "[schedule]\nmax_stages = 2\ninitial_resolution = 16\nmax_blocks_per_stage = 2\nshape_iterations = 4\n";
    Config { init_rim: rim, ..Config::from_toml(text).unwrap() }
}

fn run(capture: &Transient, rim: StartRim, dir: &Path, start: Start, hooks: Hooks<'_>) -> Outcome {
    let config = config(rim);
    let prepared = Prepared::new(capture.clone(), &config).unwrap();
    let params = prepared.params(&config, Some(dir.to_owned())).unwrap();
    pipeline::run(&prepared, &config, &params, start, hooks).unwrap()
}

fn positions(o: &Outcome) -> Vec<Vec3> {
    o.mesh.to_triangles().0
}

/// The run goes on from the candidate with the lower misfit, and ends where a run from that candidate alone
/// ends, bit for bit; the other candidate's start and first stage stay beside it. Interrupted while the
/// candidates run, it resumes to the same end.
#[test]
fn the_chosen_start_runs_on_as_if_it_had_been_the_only_one() {
    let capture = one_laser(&dish(0.11));
    let dir = scratch("chosen");
    let chosen = run(&capture, StartRim::Choose, &dir.join("choose"), Start::New, Hooks::default());
    let choice = pipeline::saved_choice(&dir.join("choose")).unwrap().expect("a choice is recorded");
    assert_eq!(choice.candidates.len(), 2, "{choice:?}");
    assert_eq!(choice.candidates.iter().map(|c| c.rim).collect::<Vec<_>>(), [StartRim::Receding, StartRim::Measured]);
    assert!(choice.candidates.iter().all(|c| c.stage == 1 && c.misfit.is_finite()), "{choice:?}");
    let best = choice.candidates.iter().min_by(|a, b| a.misfit.total_cmp(&b.misfit)).unwrap();
    assert_eq!(choice.chosen, best.rim);
    let other = choice.candidates.iter().find(|c| c.rim != choice.chosen).unwrap();
    assert_ne!(best.misfit, other.misfit, "the two starts differ");
    let kept = dir.join("choose").join(CANDIDATES_DIR).join(other.rim.to_string());
    assert!(kept.join("init.obj").is_file() && kept.join("stage_00.obj").is_file(), "{}", kept.display());

    let alone = run(&capture, choice.chosen, &dir.join("alone"), Start::New, Hooks::default());
    assert_eq!(alone.stop, StopReason::MaxStages);
    assert_eq!(positions(&chosen), positions(&alone));
    let strip = |o: &Outcome| o.log.iterations.iter().map(|r| (r.iteration, r.data.to_bits())).collect::<Vec<_>>();
    assert_eq!(strip(&chosen), strip(&alone));
    assert!(pipeline::saved_choice(&dir.join("alone")).unwrap().is_none(), "one start: no choice");

    // Without a run directory the candidates run in a temporary one, removed at the end; the same result.
    let config = config(StartRim::Choose);
    let prepared = Prepared::new(capture.clone(), &config).unwrap();
    let params = prepared.params(&config, None).unwrap();
    let in_memory = pipeline::run(&prepared, &config, &params, Start::New, Hooks::default()).unwrap();
    assert_eq!(positions(&in_memory), positions(&chosen));

    // Stopped at the first candidate's first block, then resumed.
    let mut stop = |p: &Progress| {
        if p.event == ProgressEvent::BlockEnd { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
    };
    let hooks = Hooks { progress: Some(&mut stop), evolve: None };
    let cut = run(&capture, StartRim::Choose, &dir.join("cut"), Start::New, hooks);
    assert_eq!(cut.stop, StopReason::Interrupted);
    pipeline::check_resumable(&dir.join("cut")).expect("the candidates resume");
    let resumed = run(&capture, StartRim::Choose, &dir.join("cut"), Start::Resume, Hooks::default());
    assert_eq!(positions(&resumed), positions(&chosen));
}
