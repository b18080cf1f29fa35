//! Coarse to fine in time (`Schedule::rebin_fraction`): a stage fits the capture with bins summed up to a
//! fraction of its edge length — exactly the run on the rebinned capture, with a sensor fit through the
//! response of the summed bins; a bad fraction is a typed error naming the setting. The schedule sized to
//! the capture's spacing and bins (`Schedule::sized_to`).
#![allow(clippy::unwrap_used)]

mod common;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::SurfaceMesh;
use nlos_optim::{OptimError, Plan, ReconstructParams, Schedule, SensorBackground, SensorFit, StopReason, reconstruct};
use nlos_render::{RenderParams, Renderer, Visibility};
use nlos_transient::sensor::BinKernel;
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

#[test]
fn stages_sum_bins_up_to_half_their_edge_length() {
    let d = Schedule::default();
    // Tsai et al. 2019's 1.2 mm bins (4 ps): edges 10.4, 6.9, 4.6 mm → 4, 2, 1 bins; then 1.
    assert_eq!((0..4).map(|k| d.rebin(k, 0.0012)).collect::<Vec<_>>(), [4, 2, 1, 1]);
    // The independent renderer's 4 mm bins are already coarser than half an edge: never summed.
    assert_eq!((0..3).map(|k| d.rebin(k, 0.004)).collect::<Vec<_>>(), [1, 1, 1]);
    let off = Schedule { rebin_fraction: 0.0, ..d };
    assert_eq!(off.rebin(0, 0.0012), 1);
    assert_eq!(d.rebin(0, 0.0), usize::MAX, "a zero bin width saturates (the run clamps to the bins)");
}

/// `Schedule::sized_to`: the shared captures (spacing at most 11.1 mm, bins at most 4 mm, 4,096
/// measurements) keep the default schedule; a coarser scan starts at 0.9 spacings, coarse bins at 1.5 bins;
/// fewer measurements lower the face cap. What it catches: a 32 × 32 capture over 1 m run at the 64 × 64
/// seed's edges (the 32 × 32 Z-NLOS bunny ended at 56,692 faces, longer than a 64 × 64 run).
#[test]
fn the_schedule_follows_the_scan_spacing_and_the_bins() {
    let d = Schedule::default();
    for (spacing, bin) in [(0.5 / 63.0, 0.0012), (0.7 / 63.0, 0.0012), (0.4 / 63.0, 0.0012), (0.49 / 63.0, 0.004)] {
        let (s, note) = d.sized_to(spacing, bin, 4096);
        assert_eq!((s, note), (d, None), "spacing {spacing}, bins {bin}");
    }
    let edge = |n: usize| d.sized_to(1.0 / (n - 1) as f64, 0.006, n * n).0;
    let (e32, e64, e8) = (edge(32), edge(64), edge(8));
    assert!((e32.target_edge_length(0) - 0.9 / 31.0).abs() < 1e-12);
    assert!(e32.target_edge_length(0) > e64.target_edge_length(0) && e8.target_edge_length(0) > 0.1);
    assert_eq!((e32.max_faces, e8.max_faces, e64.max_faces), (15 * 1024, 15 * 64, d.max_faces));
    // Coarse bins (f-k's 32 ps: 9.6 mm of path) at a fine spacing.
    let (s, note) = d.sized_to(0.004, 0.0096, 4096);
    assert!((s.target_edge_length(0) - 1.5 * 0.0096).abs() < 1e-12, "{note:?}");
    assert!(note.expect("said").contains("bins"));
}

/// A tilted 6 × 6-cell patch rendered on an 8 × 8 confocal grid (60 bins of 3 mm), and a start 1 cm behind it.
fn capture_and_start() -> (Transient, SurfaceMesh) {
    let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.25, 0.25).unwrap());
    let time = TimeAxis::new(0.72, 0.003, 60).unwrap();
    let render = RenderParams { visibility: Visibility::Off, ..RenderParams::default() };
    let (tp, tt) = common::height_field(6, 0.025, 0.0, 0.0, |x, y| 0.4 + 0.04 * x - 0.02 * y);
    let lambert = Lambertian::new(1.0f32).unwrap();
    let data = Renderer::new(&tp, &tt, &scan, &time, render).unwrap().forward(&lambert);
    // Photon counts, as the fit's noise handling expects of a capture.
    let counts: Vec<f32> = data.iter().map(|x| (x * 2e4).round()).collect();
    let measured = Transient::new(scan, time, counts).unwrap();
    let (sp, st) = common::height_field(6, 0.025, 0.0, 0.0, |x, y| 0.41 + 0.04 * x - 0.02 * y);
    (measured, SurfaceMesh::from_triangles(&sp, &st).unwrap())
}

/// One stage of 3 steps at 15 mm edges, whose bins are summed by `k` (3 mm bins: fraction k · 3 / 15).
fn one_stage(k: u32) -> ReconstructParams {
    ReconstructParams {
        schedule: Schedule {
            initial_resolution: 10.0,
            extent: 0.15,
            max_stages: 1,
            max_blocks_per_stage: 1,
            shape_iterations: 3,
            // Half a bin above k bins, clear of rounding in the floor.
            rebin_fraction: (f64::from(k) + 0.5) * 0.003 / 0.015,
            ..Schedule::default()
        },
        prune: None,
        residual: None,
        ..ReconstructParams::default()
    }
}

/// The time budget (`Schedule::reference_seconds`): predicted from face counts, so a budget that holds two blocks
/// of the patch's mesh but not three ends the run after two, with the stop reason saying why, and a run
/// with the same budget again ends at the same mesh (deterministic, whatever the machine's speed).
/// What it catches: a budget read from the wall clock (different stops on different machines) or one that
/// lets a block start past it.
#[test]
fn the_time_budget_stops_blocks_deterministically() {
    let (measured, start) = capture_and_start();
    let mut params = one_stage(1);
    params.schedule.max_stages = 3;
    params.schedule.max_blocks_per_stage = 4;
    params.schedule.rel_tol = 0.0;
    let free = reconstruct(&measured, &start, &params).unwrap();
    assert_eq!(free.stop, StopReason::MaxStages);
    // What two blocks of the first stage cost, predicted: their logged face counts.
    let first: Vec<usize> = free.log.iterations.iter().take(6).map(|r| r.faces).collect();
    let plan = Plan::new(params.schedule, measured.measurements(), false);
    let two = plan.predicted_seconds(first.iter().sum::<usize>() as f64);
    let three = two + plan.predicted_seconds(3.0 * first[5] as f64);
    params.schedule.reference_seconds = 0.5 * (two + three);
    let cut = reconstruct(&measured, &start, &params).unwrap();
    assert_eq!(cut.stop, StopReason::TimeBudget);
    assert_eq!((cut.blocks_done, cut.log.iterations.len()), (2, 6), "two blocks of three steps");
    let again = reconstruct(&measured, &start, &params).unwrap();
    assert_eq!(positions(&again.mesh), positions(&cut.mesh));
    let plan = Plan::new(Schedule::default(), 4096, true);
    assert!(plan.block_fits(0.0, 1e4), "a 10k-face block fits an empty budget");
}

fn positions(mesh: &SurfaceMesh) -> Vec<Vec3> {
    mesh.to_triangles().0
}

#[test]
fn a_coarse_stage_fits_the_rebinned_capture() {
    let (measured, start) = capture_and_start();
    let coarse = reconstruct(&measured, &start, &one_stage(3)).unwrap();
    let by_hand = reconstruct(&measured.rebin(3).unwrap(), &start, &one_stage(1)).unwrap();
    let full = reconstruct(&measured, &start, &one_stage(1)).unwrap();
    assert_eq!(positions(&coarse.mesh), positions(&by_hand.mesh), "stage 0 fits the capture summed over 3 bins");
    assert_ne!(positions(&coarse.mesh), positions(&full.mesh), "and not the capture itself");
    assert!(coarse.mesh.n_faces() > 0);
}

/// A sensor fit's coarse stage is the fit of the summed counts through the response of summed bins
/// (`nlos_optim::data_term::response::summed_response`) with the background of a summed bin, and not the fit at the
/// capture's bins.
#[test]
fn a_sensor_fit_sums_bins_through_the_summed_response() {
    let (measured, start) = capture_and_start();
    let kernel = BinKernel::new(-1, vec![0.2, 0.5, 0.2, 0.1]).unwrap();
    let mean = measured.data().iter().map(|&c| f64::from(c)).sum::<f64>() / measured.data().len() as f64;
    let b = 0.01 * mean;
    let fit = |kernel: BinKernel, b: f64| SensorFit { kernel, background: SensorBackground::Fixed(b) };
    let with = |k, f: SensorFit| ReconstructParams { sensor: Some(f), ..one_stage(k) };
    let coarse = reconstruct(&measured, &start, &with(2, fit(kernel.clone(), b))).unwrap();
    let summed = nlos_optim::data_term::response::summed_response(&kernel, 2).unwrap();
    let by_hand = reconstruct(&measured.rebin(2).unwrap(), &start, &with(1, fit(summed, 2.0 * b))).unwrap();
    let full = reconstruct(&measured, &start, &with(1, fit(kernel, b))).unwrap();
    assert_eq!(positions(&coarse.mesh), positions(&by_hand.mesh), "stage 0 fits the counts summed over 2 bins");
    assert_ne!(positions(&coarse.mesh), positions(&full.mesh), "and not the capture itself");
}

#[test]
fn a_bad_fraction_is_a_typed_error_naming_the_setting() {
    let (measured, start) = capture_and_start();
    for bad in [-0.5, f64::NAN, f64::INFINITY] {
        let mut p = one_stage(1);
        p.schedule.rebin_fraction = bad;
        let err = reconstruct(&measured, &start, &p).unwrap_err();
        assert!(matches!(err, OptimError::InvalidParameter { name: "schedule.rebin_fraction", .. }), "{err}");
    }
}

#[test]
fn a_bad_time_budget_is_a_typed_error_naming_the_setting() {
    let (measured, start) = capture_and_start();
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let mut p = one_stage(1);
        p.schedule.reference_seconds = bad;
        let err = reconstruct(&measured, &start, &p).unwrap_err();
        assert!(matches!(err, OptimError::InvalidParameter { name: "schedule.reference_seconds", .. }), "{err}");
    }
}

/// `Plan::planned_edge`: the stages left refine by the largest common growth whose blocks fit what the
/// budget has left — the schedule's own edges when they fit, coarser ones (never finer than the schedule's,
/// never coarser than the stage before) when they do not, and the previous edge when nothing fits.
/// What it catches: a plan that overruns the budget, one that coarsens more than it must, or one that
/// refines past the schedule.
#[test]
fn later_stages_are_planned_to_fit_the_budget_whole() {
    let s = Schedule::default();
    let plan = Plan::new(s, 4096, true);
    let (e0, e1, e2) = (s.target_edge_length(0), s.target_edge_length(1), s.target_edge_length(2));
    let stage_cost = |edge: f64, area: f64| {
        let steps = f64::from(s.max_blocks_per_stage * s.shape_iterations);
        plan.predicted_seconds(nlos_optim::faces_at(area, edge) * steps)
    };
    // A small object (the chart's 0.03 m²): the schedule's own edges.
    assert_eq!(plan.planned_edge(1, e0, 0.03, 2e5), e1);
    // Without a budget, or at stage 0: the schedule's.
    let free = Plan { schedule: Schedule { reference_seconds: 0.0, ..s }, ..plan };
    assert_eq!(free.planned_edge(1, e0, 10.0, 2e5), e1);
    assert_eq!(plan.planned_edge(0, e0, 10.0, 0.0), e0);
    // A large one (the S and U's 0.14 m² after a first stage of 2.3·10⁵ face-steps): coarser, and exactly
    // what fits — stages 1 and 2 at the common growth fill what is left, a hair finer would not fit.
    let (area, done) = (0.14, 2.3e5);
    let left = s.reference_seconds - plan.predicted_seconds(done);
    let edge = plan.planned_edge(1, e0, area, done);
    assert!(edge > e1 && edge < e0, "{edge}");
    let g = e0 / edge;
    let cost = |g: f64| stage_cost((e0 / g).max(e1), area) + stage_cost((e0 / (g * g)).max(e2), area);
    assert!(cost(g) <= left * (1.0 + 1e-9), "{} > {left}", cost(g));
    assert!(cost(g * 1.001) > left, "the growth is the largest that fits");
    // Nothing left: the previous edge again (the blocks then stop at the budget).
    assert_eq!(plan.planned_edge(1, e0, area, 1e7), e0);
}
