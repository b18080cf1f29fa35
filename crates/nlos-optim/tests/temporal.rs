//! Coarse-to-fine in time (`nlos_optim::temporal`): a start whose light arrives far (tens of bins) from the
//! measured return feels no pull with the unblurred data term, and is brought to the truth when the first
//! stages fit blurred histograms.
#![allow(clippy::unwrap_used)]

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::{SurfaceMesh, shapes};
use nlos_optim::{OptimError, ReconstructParams, SamplingSchedule, Schedule, reconstruct};
use nlos_render::{DeterministicRule, RenderParams, Renderer, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// A flat 0.1 m square at depth `z`, facing the wall.
fn square(z: f32, n: usize) -> SurfaceMesh {
    let m = shapes::height_field(0.1, 0.1, n, n, |_, _| z).unwrap();
    let (mut p, t) = m.to_triangles();
    for q in &mut p {
        q.x -= 0.05;
        q.y -= 0.05;
    }
    let t: Vec<[u32; 3]> = t.iter().map(|f| [f[0], f[2], f[1]]).collect();
    SurfaceMesh::from_triangles(&p, &t).unwrap()
}

fn render() -> RenderParams {
    RenderParams { visibility: Visibility::Off, ..RenderParams::default() }
}

/// The truth at 0.43 m on an 8 × 8 confocal scan over ±0.05 m (under the square: every spot's histogram
/// spans at most 45 mm of path), 2.4 mm bins from 0.6 m of path.
fn measurement() -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.05, 0.05).unwrap());
    let time = TimeAxis::new(0.6, 0.0024, 300).unwrap();
    let (p, t) = square(0.43, 8).to_triangles();
    let data = Renderer::new(&p, &t, &scan, &time, render()).unwrap().forward(&Lambertian::new(1.0f32).unwrap());
    Transient::new(scan, time, data).unwrap()
}

/// Mean depth of the mesh's vertices.
fn mean_depth(m: &SurfaceMesh) -> f64 {
    let (p, _) = m.to_triangles();
    p.iter().map(|v: &Vec3| f64::from(v.z)).sum::<f64>() / p.len() as f64
}

fn params(blur: Vec<f64>) -> ReconstructParams {
    ReconstructParams {
        schedule: Schedule {
            initial_resolution: 20.0,
            growth: 1.0,
            max_stages: 4,
            max_blocks_per_stage: 2,
            shape_iterations: 40,
            reflectance_iterations: 0,
            rel_tol: 0.0,
            ..Schedule::default()
        },
        // The start is a plane too: only the depth is in question.
        lr_interior: 0.15,
        lr_boundary: 0.15,
        render: render(),
        sampling: SamplingSchedule::Deterministic(DeterministicRule {
            max_bin_fraction: 1.5,
            min_level: 1,
            max_level: 6,
        }),
        prune: None,
        residual: None,
        temporal_blur: blur,
        seed: 3,
        ..ReconstructParams::default()
    }
}

#[test]
fn a_start_many_bins_off_reaches_the_truth_only_through_the_blur() {
    let measured = measurement();
    // 7 cm in front of the truth: its light arrives ~140 mm of path (~58 bins) early, where the measured
    // histograms are empty.
    let init = square(0.36, 6);
    let sharp = reconstruct(&measured, &init, &params(Vec::new())).unwrap();
    let blurred = reconstruct(&measured, &init, &params(vec![0.3, 0.1, 0.03])).unwrap();
    let (ds, db) = (mean_depth(&sharp.mesh), mean_depth(&blurred.mesh));
    println!("mean depth: start 0.360 m, unblurred {ds:.4} m, blurred first stages {db:.4} m, truth 0.430 m");
    assert!((db - 0.43).abs() < 0.004, "with the blur the plane should reach 0.43 m, got {db}");
    assert!((ds - 0.43).abs() > 0.02, "without the blur the plane should stay put, got {ds}");
}

#[test]
fn bad_blur_widths_are_typed_errors() {
    let measured = measurement();
    let init = square(0.36, 4);
    for w in [-0.01, f64::NAN, f64::INFINITY] {
        let r = reconstruct(&measured, &init, &params(vec![w]));
        assert!(matches!(r, Err(OptimError::InvalidParameter { name: "temporal_blur", .. })), "{w}: {r:?}");
    }
    // Wider than 1000 bins (2.4 m of path here): refused when the stage starts.
    let r = reconstruct(&measured, &init, &params(vec![3.0]));
    assert!(matches!(r, Err(OptimError::InvalidParameter { name: "temporal_blur", .. })), "{r:?}");
}
