//! Scoring against depth and normal maps (`map_metrics`): a plane against its own maps scores 0, a tilted
//! plane against a fronto-parallel truth scores its tilt, normals from a depth map recover the tilt, and
//! bad maps are typed errors.

use glam::{Quat, Vec3};
use nlos_mesh::MeshError;
use nlos_mesh::map_metrics::{MapGrid, Maps, evaluate_maps, mesh_maps, normals_from_depth};

fn grid() -> MapGrid {
    MapGrid { width: 48, height: 40, x_range: [-0.25, 0.25], y_range: [-0.2, 0.2] }
}

/// A 0.3 m square plate centred at (0, 0, depth), tilted by `tilt` degrees about y, facing the wall.
fn plate(depth: f32, tilt: f32) -> nlos_mesh::SurfaceMesh {
    let mut m = nlos_mesh::shapes::plane_grid(0.3, 0.3, 12, 12);
    let q = Quat::from_rotation_y(tilt.to_radians());
    for p in m.positions_mut() {
        *p = q * (*p - Vec3::new(0.15, 0.15, 0.0)) + Vec3::new(0.0, 0.0, depth);
    }
    m
}

/// The truth's analytic maps of the plate: depth and the normal facing the wall.
fn plate_maps(depth: f32, tilt: f32) -> Maps {
    let g = grid();
    let q = Quat::from_rotation_y(tilt.to_radians());
    let n = q * Vec3::NEG_Z;
    let (mut d, mut normals) = (vec![f32::NAN; g.len()], vec![Vec3::ZERO; g.len()]);
    for i in 0..g.len() {
        let (x, y) = g.pixel_center(i / g.width, i % g.width);
        // The plane through (0, 0, depth) with normal n: z where n·(p − c) = 0.
        let z = depth - n.x * x / n.z - n.y * y / n.z;
        let local = q.inverse() * (Vec3::new(x, y, z) - Vec3::new(0.0, 0.0, depth));
        if local.x.abs() < 0.15 && local.y.abs() < 0.15 {
            d[i] = z;
            normals[i] = n;
        }
    }
    Maps { grid: g, depth: d, normals: Some(normals) }
}

#[test]
fn a_plane_scores_zero_against_its_own_maps() {
    for tilt in [0.0, 20.0] {
        let truth = plate_maps(0.4, tilt);
        let rec = mesh_maps(&plate(0.4, tilt), &grid()).expect("maps");
        let m = evaluate_maps(&rec, &truth, 0.005).expect("scores");
        eprintln!("tilt {tilt}: {m:?}");
        // Pixels on the plate's edge may fall either side: all but the rim agree.
        assert!(m.coverage > 0.97 && m.coverage_within > 0.97, "{m:?}");
        assert!(m.depth_error_mean.expect("pixels") < 1e-6, "{m:?}");
        assert!(m.depth_error_mean_interior.expect("interior") < 1e-6);
        assert!(m.normal_error_mean_deg.expect("normals") < 0.05, "{m:?}");
    }
}

#[test]
fn a_tilted_plane_against_a_flat_truth_scores_its_tilt() {
    let truth = plate_maps(0.4, 0.0);
    let rec = mesh_maps(&plate(0.4, 15.0), &grid()).expect("maps");
    let m = evaluate_maps(&rec, &truth, 0.005).expect("scores");
    assert!((m.normal_error_mean_deg.expect("normals") - 15.0).abs() < 0.05, "{m:?}");
    // |Δz| = |x| tan 15° over the plate: within 5 mm only near x = 0.
    assert!(m.coverage > 0.9 && m.coverage_within < 0.25, "{m:?}");
    // Normals from the depth map (a volume's arg-max map has no others) give the tilt too.
    let from_depth = normals_from_depth(&rec.depth, &grid());
    let inner: Vec<f64> = (0..grid().len())
        .filter(|&i| !truth.depth[i].is_nan() && !rec.depth[i].is_nan())
        .map(|i| f64::from(from_depth[i].dot(Vec3::NEG_Z)).acos().to_degrees())
        .collect();
    let mean = inner.iter().sum::<f64>() / inner.len() as f64;
    assert!((mean - 15.0).abs() < 0.1, "{mean}");
}

#[test]
fn bad_maps_are_typed_errors() {
    let truth = plate_maps(0.4, 0.0);
    let mut short = truth.clone();
    short.depth.pop();
    assert!(
        matches!(evaluate_maps(&truth, &short, 0.005), Err(MeshError::Format { ref field, .. }) if field == "depth")
    );
    let mut nan = truth.clone();
    let inside = nan.depth.iter().position(|z| !z.is_nan()).expect("mask");
    nan.normals.as_mut().expect("normals")[inside] = Vec3::NAN;
    assert!(
        matches!(evaluate_maps(&truth, &nan, 0.005), Err(MeshError::Format { ref field, .. }) if field == "normal")
    );
    let mut away = truth.clone();
    away.normals.as_mut().expect("normals").iter_mut().for_each(|n| *n = -*n);
    let e = evaluate_maps(&truth, &away, 0.005).expect_err("facing away");
    assert!(e.to_string().contains("face away"), "{e}");
    let empty = Maps { depth: vec![f32::NAN; grid().len()], ..truth.clone() };
    assert!(matches!(evaluate_maps(&truth, &empty, 0.005), Err(MeshError::InvalidParameter { .. })));
    assert!(matches!(evaluate_maps(&truth, &truth, f64::NAN), Err(MeshError::InvalidParameter { .. })));
}
