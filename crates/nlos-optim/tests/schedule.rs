//! Coarse to fine in time (`Schedule::rebin_fraction`): a stage fits the capture with bins summed up to a
//! fraction of its edge length — exactly the run on the rebinned capture, with a sensor fit through the
//! response of the summed bins; a bad fraction is a typed error naming the setting.
#![allow(clippy::unwrap_used)]

mod common;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::SurfaceMesh;
use nlos_optim::{OptimError, ReconstructParams, Schedule, SensorBackground, SensorFit, reconstruct};
use nlos_render::{RenderParams, Renderer, Visibility};
use nlos_transient::sensor::BinKernel;
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

#[test]
fn stages_sum_bins_up_to_half_their_edge_length() {
    let d = Schedule::default();
    // The seed's 1.2 mm bins (4 ps): edges 10.4, 6.9, 4.6 mm → 4, 2, 1 bins; then 1.
    assert_eq!((0..4).map(|k| d.rebin(k, 0.0012)).collect::<Vec<_>>(), [4, 2, 1, 1]);
    // The independent renderer's 4 mm bins are already coarser than half an edge: never summed.
    assert_eq!((0..3).map(|k| d.rebin(k, 0.004)).collect::<Vec<_>>(), [1, 1, 1]);
    let off = Schedule { rebin_fraction: 0.0, ..d };
    assert_eq!(off.rebin(0, 0.0012), 1);
    assert_eq!(d.rebin(0, 0.0), usize::MAX, "a zero bin width saturates (the run clamps to the bins)");
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
/// (`nlos_optim::response::summed_response`) with the background of a summed bin, and not the fit at the
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
    let summed = nlos_optim::response::summed_response(&kernel, 2).unwrap();
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
