//! Scoring against depth and normal maps (`map_metrics`): a plane against its own maps scores 0, a tilted
//! plane against a fronto-parallel truth scores its tilt, normals from a depth map recover the tilt, and
//! bad maps are typed errors.

use glam::{Quat, Vec3};
use nlos_mesh::MeshError;
use nlos_mesh::map_metrics::{MapGrid, MapLayout, Maps, evaluate_maps, mesh_maps, normals_from_depth};

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

/// A normal map without a value (NaN) where the depth map has a surface leaves that pixel out of the normal
/// error only, and says on how many pixels the error is.
#[test]
fn missing_normals_are_left_out_and_counted() {
    let truth = plate_maps(0.4, 0.0);
    let rec = mesh_maps(&plate(0.4, 0.0), &grid()).expect("maps");
    let all = evaluate_maps(&rec, &truth, 0.005).expect("scores");
    assert_eq!(all.normal_pixels, all.both_pixels);
    let mut holes = truth.clone();
    let inside: Vec<usize> = (0..holes.depth.len()).filter(|&i| !holes.depth[i].is_nan()).take(10).collect();
    inside.iter().for_each(|&i| holes.normals.as_mut().expect("normals")[i] = Vec3::NAN);
    let m = evaluate_maps(&rec, &holes, 0.005).expect("scores");
    let lost = inside.iter().filter(|&&i| !rec.depth[i].is_nan()).count();
    assert_eq!((m.both_pixels, m.normal_pixels), (all.both_pixels, all.both_pixels - lost));
    assert!(m.normal_error_mean_deg.expect("normals") < 0.05);
}

/// `MapLayout`: ours is the identity; the D-LCT depth map is our image transposed (a file of 2 rows of 3
/// is our image of 3 rows of 2), its normal map our image mirrored left to right with the vectors negated.
#[test]
fn map_layouts_place_pixels_as_documented() {
    // Stored 2 × 3, C order: (r, c) at c + 3r.
    let v: Vec<f32> = (0..6).map(|k| k as f32).collect();
    assert_eq!(MapLayout::Image.depth_to_image(&v, [2, 3]), (v.clone(), 3, 2));
    // Transposed: our image is 2 wide and 3 high; our (i, j) is stored (j, i).
    let (t, w, h) = MapLayout::Dlct.depth_to_image(&v, [2, 3]);
    assert_eq!((w, h), (2, 3));
    assert_eq!(t, vec![0.0, 3.0, 1.0, 4.0, 2.0, 5.0]);
    let n: Vec<f32> = (0..18).map(|k| k as f32).collect();
    let (ours, w, h) = MapLayout::Dlct.normals_to_image(&n, [2, 3]);
    assert_eq!((w, h), (3, 2));
    // Our (0, 0) is stored (0, 2) negated: components 6, 7, 8.
    assert_eq!(ours[0], Vec3::new(-6.0, -7.0, -8.0));
    assert_eq!(ours[3 + 2], Vec3::new(-9.0, -10.0, -11.0));
    assert_eq!(MapLayout::Image.normals_to_image(&n, [2, 3]).0[4], Vec3::new(12.0, 13.0, 14.0));
}

/// `MapGrid::spanning`: the outer pixel centres lie on the rectangle's edges (the Z-NLOS maps' 256 pixels
/// on the 256 scan points over 1 m: pixels of 1/255 m).
#[test]
fn a_spanning_grid_puts_its_outer_pixel_centres_on_the_rectangle() {
    let g = MapGrid::spanning(256, 128, [-0.5, 0.5, -0.25, 0.25]);
    let (x, y) = g.pixel_center(0, 0);
    assert!((x + 0.5).abs() < 1e-6 && (y - 0.25).abs() < 1e-6, "({x}, {y})");
    let (x, y) = g.pixel_center(127, 255);
    assert!((x - 0.5).abs() < 1e-6 && (y + 0.25).abs() < 1e-6, "({x}, {y})");
    assert!((g.x_range[1] - g.x_range[0] - 256.0 / 255.0).abs() < 1e-5);
}

#[test]
fn bad_maps_are_typed_errors() {
    let truth = plate_maps(0.4, 0.0);
    let mut short = truth.clone();
    short.depth.pop();
    assert!(
        matches!(evaluate_maps(&truth, &short, 0.005), Err(MeshError::Format { ref field, .. }) if field == "depth")
    );
    let inside = truth.depth.iter().position(|z| !z.is_nan()).expect("mask");
    let mut long = truth.clone();
    long.normals.as_mut().expect("normals")[inside] = Vec3::new(0.0, 0.0, -2.0);
    assert!(
        matches!(evaluate_maps(&truth, &long, 0.005), Err(MeshError::Format { ref field, .. }) if field == "normal")
    );
    let mut away = truth.clone();
    away.normals.as_mut().expect("normals").iter_mut().for_each(|n| *n = -*n);
    let e = evaluate_maps(&truth, &away, 0.005).expect_err("facing away");
    assert!(e.to_string().contains("face away"), "{e}");
    let empty = Maps { depth: vec![f32::NAN; grid().len()], ..truth.clone() };
    assert!(matches!(evaluate_maps(&truth, &empty, 0.005), Err(MeshError::InvalidParameter { .. })));
    assert!(matches!(evaluate_maps(&truth, &truth, f64::NAN), Err(MeshError::InvalidParameter { .. })));
}
