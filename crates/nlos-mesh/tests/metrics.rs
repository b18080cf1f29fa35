//! Evaluation metrics (`nlos_mesh::metrics`): exact cases on planes, ray queries against brute force,
//! and the typed errors on empty or degenerate input.

use glam::Vec3;
use nlos_mesh::bvh::ray_triangle;
use nlos_mesh::metrics::{EvalParams, SILHOUETTE_BAND, depth_map, evaluate, interior_mask};
use nlos_mesh::{MeshError, SurfaceMesh, TriangleBvh, shapes};

/// The workspace's SplitMix64 (`nlos_transient::rng`), with the draws these tests use.
struct Rng(nlos_transient::rng::SplitMix64);
impl Rng {
    fn new(seed: u64) -> Self {
        Self(nlos_transient::rng::SplitMix64::new(seed))
    }
    fn f(&mut self) -> f32 {
        self.0.next_f32()
    }
    fn v(&mut self, s: f32) -> Vec3 {
        Vec3::new(self.f() - 0.5, self.f() - 0.5, self.f() - 0.5) * s
    }
}

/// A square grid plane of side `size` centred on the z axis at depth `z`, normals +z.
fn plane(size: f32, quads: usize, z: f32) -> SurfaceMesh {
    let mut m = shapes::plane_grid(size, size, quads, quads);
    for p in m.positions_mut() {
        *p += Vec3::new(-0.5 * size, -0.5 * size, z);
    }
    m
}

/// First hit over all triangles (no BVH).
fn brute_first_hit(m: &SurfaceMesh, o: Vec3, d: Vec3) -> Option<f32> {
    m.faces().filter_map(|f| ray_triangle(o, d, m.face_points(f), f32::INFINITY).map(|h| h.0)).reduce(f32::min)
}

#[test]
fn identical_meshes_have_full_coverage_and_zero_errors() {
    let bumpy = shapes::height_field(0.6, 0.6, 24, 24, |x, y| 0.4 + 0.05 * (9.0 * x).sin() * (7.0 * y).cos())
        .expect("height field");
    let mut bumpy = bumpy;
    for p in bumpy.positions_mut() {
        *p += Vec3::new(-0.3, -0.3, 0.0);
    }
    let m = evaluate(&bumpy, &bumpy, &EvalParams::default()).expect("evaluate");
    assert_eq!(m.gt_pixels, 128 * 128);
    assert_eq!(m.both_pixels, 128 * 128);
    assert_eq!(m.coverage, 1.0);
    assert_eq!(m.depth_error_mean, Some(0.0));
    assert_eq!(m.depth_error_median, Some(0.0));
    assert_eq!(m.depth_error_rms, Some(0.0));
    assert_eq!(m.depth_error_max, Some(0.0));
    assert_eq!(m.chamfer, 0.0);
    assert_eq!(m.hausdorff, 0.0);
    assert_eq!(m.depth_reconstruction.len(), 128 * 128);
    assert!(m.depth_reconstruction.iter().all(|z| (0.34..=0.46).contains(z)));

    let flat = plane(0.6, 6, 0.4);
    let m = evaluate(&flat, &flat, &EvalParams::default()).expect("evaluate");
    assert_eq!(m.coverage, 1.0);
    // acos of an f32 cosine near 1 resolves ≈ 0.02°
    assert!(m.normal_error_mean_deg.abs() < 0.05, "{}", m.normal_error_mean_deg);
}

#[test]
fn planes_one_centimetre_apart_have_ten_millimetre_depth_error() {
    let gt = plane(0.6, 5, 0.40);
    let rec = plane(0.6, 7, 0.41);
    let m = evaluate(&rec, &gt, &EvalParams::default()).expect("evaluate");
    assert_eq!(m.coverage, 1.0);
    for e in [m.depth_error_mean, m.depth_error_median, m.depth_error_rms, m.depth_error_max] {
        let e = e.expect("pixels hit by both");
        assert!((e - 0.01).abs() < 1e-6, "depth error {e}");
    }
    assert!((m.chamfer - 0.02).abs() < 1e-6, "chamfer {}", m.chamfer);
    assert!((m.hausdorff as f64 - 0.01).abs() < 1e-6);
    assert!(m.normal_error_mean_deg < 0.05);
    assert!(m.depth_ground_truth.iter().all(|&z| z == 0.40));
    assert!(m.depth_reconstruction.iter().all(|&z| z == 0.41));
}

#[test]
fn half_size_reconstruction_covers_a_quarter() {
    // Pixel centres at (i + ½)/256 − 0.25: exactly i = 32..=95 lie within ±0.125 on each axis (none on the edge).
    let gt = plane(0.6, 4, 0.4);
    let rec = plane(0.25, 3, 0.4);
    let m = evaluate(&rec, &gt, &EvalParams::default()).expect("evaluate");
    assert_eq!(m.gt_pixels, 16384);
    assert_eq!(m.reconstruction_pixels, 4096);
    assert_eq!(m.both_pixels, 4096);
    assert_eq!(m.coverage, 0.25);
    assert_eq!(m.depth_error_max, Some(0.0));
    let (nan, hit) = (m.depth_reconstruction[0], m.depth_reconstruction[64 + 128 * 64]);
    assert!(nan.is_nan() && hit == 0.4);
    // other grid sizes: the same count in closed form
    let params = EvalParams { grid: 40, ..EvalParams::default() };
    let m = evaluate(&rec, &gt, &params).expect("evaluate");
    let inside = (0..40).filter(|&i| params.pixel_center(i, 0).0.abs() <= 0.125).count();
    assert_eq!(m.both_pixels, inside * inside);
    assert_eq!(m.coverage, (inside * inside) as f64 / 1600.0);
}

#[test]
fn rays_through_shared_edges_and_vertices_do_not_leak() {
    // 256 quads over ±0.25: every pixel centre of the 128 grid lies exactly on a grid vertex.
    let gt = plane(0.5, 256, 0.3);
    let m = evaluate(&gt, &gt, &EvalParams::default()).expect("evaluate");
    assert_eq!(m.gt_pixels, 128 * 128);
    // and on edges (odd pixel count over the same plane: centres on vertical edges)
    let m = evaluate(&gt, &gt, &EvalParams { grid: 256, ..EvalParams::default() }).expect("evaluate");
    assert_eq!(m.gt_pixels, 256 * 256);
}

#[test]
fn ray_hits_agree_with_brute_force() {
    let mut rng = Rng::new(17);
    // a jittered height field in front of the wall, and a jittered closed sphere (rays hit both faces)
    let mut field =
        shapes::height_field(0.5, 0.5, 9, 9, |x, y| 0.35 + 0.04 * (11.0 * x + 5.0 * y).sin()).expect("height field");
    for p in field.positions_mut() {
        *p += Vec3::new(-0.25, -0.25, 0.0) + rng.v(0.02);
    }
    let grid = EvalParams { grid: 48, ..EvalParams::default() };
    let depth = depth_map(&field, &grid).expect("depth map");
    let mut hits = 0;
    for iy in 0..48 {
        for ix in 0..48 {
            let (x, y) = grid.pixel_center(ix, iy);
            let bf = brute_first_hit(&field, Vec3::new(x, y, 0.0), Vec3::Z);
            let z = depth[ix + 48 * iy];
            match bf {
                Some(t) => {
                    hits += 1;
                    assert!((z - t).abs() < 1e-6, "pixel ({ix}, {iy}): bvh {z} vs brute {t}");
                }
                None => assert!(z.is_nan(), "pixel ({ix}, {iy}): bvh {z}, brute force misses"),
            }
        }
    }
    assert!(hits > 1000, "{hits}");

    let mut sphere = shapes::icosphere(Vec3::new(0.0, 0.0, 0.4), 0.1, 2);
    for p in sphere.positions_mut() {
        *p += rng.v(0.01);
    }
    let bvh = TriangleBvh::from_mesh(&sphere).expect("bvh");
    let (mut inside, mut outside, mut missed) = (0, 0, 0);
    for k in 0..3000 {
        let o = if k % 2 == 0 { Vec3::new(0.0, 0.0, 0.4) + rng.v(0.05) } else { Vec3::new(0.0, 0.0, 0.4) + rng.v(0.6) };
        let d = rng.v(2.0);
        let h = bvh.ray_first_hit(o, d, f32::INFINITY);
        match (h, brute_first_hit(&sphere, o, d)) {
            (Some(h), Some(t)) => {
                assert!((h.t - t).abs() <= 1e-6 * t.max(1.0), "bvh {} vs brute {t}", h.t);
                let [a, b, c] = bvh.triangle(h.triangle);
                let q = a * h.barycentric.x + b * h.barycentric.y + c * h.barycentric.z;
                assert!(q.distance(h.point) < 1e-5);
                if k % 2 == 0 { inside += 1 } else { outside += 1 }
            }
            (None, None) => missed += 1,
            (h, t) => panic!("bvh {h:?} vs brute {t:?} for ray {o} + t·{d}"),
        }
    }
    assert!(inside == 1500 && outside > 50 && missed > 100, "{inside} {outside} {missed}");
    // t_max bounds the search
    let h = bvh.ray_first_hit(Vec3::new(0.0, 0.0, 0.0), Vec3::Z, 0.25);
    assert!(h.is_none());
    assert!(bvh.ray_first_hit(Vec3::ZERO, Vec3::Z, 1.0).is_some_and(|h| (h.t - 0.3).abs() < 0.02));
    // no panic on bad rays
    assert!(bvh.ray_first_hit(Vec3::ZERO, Vec3::ZERO, 1.0).is_none());
    assert!(bvh.ray_first_hit(Vec3::splat(f32::NAN), Vec3::Z, 1.0).is_none());
    assert!(bvh.ray_first_hit(Vec3::ZERO, Vec3::Z, f32::NAN).is_none());
}

#[test]
fn empty_degenerate_and_out_of_range_inputs_are_typed_errors() {
    let gt = plane(0.6, 4, 0.4);
    let empty = SurfaceMesh::new();
    let p = EvalParams::default();
    assert!(matches!(evaluate(&empty, &gt, &p), Err(MeshError::EmptyMesh { .. })));
    assert!(matches!(evaluate(&gt, &empty, &p), Err(MeshError::EmptyMesh { .. })));
    // zero-area triangles are never hit: a degenerate ground truth has no pixel
    let flat = SurfaceMesh::from_triangles(
        &[Vec3::new(0.0, 0.0, 0.4), Vec3::new(0.1, 0.0, 0.4), Vec3::new(0.2, 0.0, 0.4)],
        &[[0, 1, 2]],
    )
    .expect("collinear triangle is still a valid connectivity");
    assert!(matches!(evaluate(&gt, &flat, &p), Err(MeshError::InvalidParameter { .. })));
    // ground truth behind the wall or outside the grid
    assert!(matches!(evaluate(&gt, &plane(0.6, 2, -0.4), &p), Err(MeshError::InvalidParameter { .. })));
    let mut far = plane(0.1, 2, 0.4);
    for q in far.positions_mut() {
        q.x += 1.0;
    }
    assert!(matches!(evaluate(&gt, &far, &p), Err(MeshError::InvalidParameter { .. })));
    // a reconstruction that no ray hits is valid: zero coverage, no depth error
    let m = evaluate(&far, &gt, &p).expect("evaluate");
    assert_eq!((m.coverage, m.both_pixels, m.depth_error_mean), (0.0, 0, None));
    assert!(m.depth_reconstruction.iter().all(|z| z.is_nan()));
    // bad parameters
    for bad in [
        EvalParams { grid: 0, ..p },
        EvalParams { grid: 5000, ..p },
        EvalParams { x_range: [0.1, 0.1], ..p },
        EvalParams { y_range: [f32::NAN, 0.1], ..p },
    ] {
        assert!(matches!(evaluate(&gt, &gt, &bad), Err(MeshError::InvalidParameter { .. })), "{bad:?}");
    }
    // non-finite positions
    let mut nan = plane(0.6, 2, 0.4);
    nan.positions_mut()[3] = Vec3::NAN;
    assert!(matches!(evaluate(&nan, &gt, &p), Err(MeshError::NonFinitePosition { .. })));
    assert!(matches!(evaluate(&gt, &nan, &p), Err(MeshError::NonFinitePosition { .. })));
}

#[test]
fn non_manifold_ground_truth_is_evaluated_unwelded() {
    // a square at z = 0.4 plus a fin sharing its diagonal: three triangles on one edge
    let pos = [
        Vec3::new(-0.3, -0.3, 0.4),
        Vec3::new(0.3, -0.3, 0.4),
        Vec3::new(0.3, 0.3, 0.4),
        Vec3::new(-0.3, 0.3, 0.4),
        Vec3::new(0.0, 0.0, 0.6),
    ];
    let tris = [[0, 1, 2], [0, 2, 3], [0, 2, 4], [1, 1, 2]];
    assert!(SurfaceMesh::from_triangles(&pos, &tris).is_err());
    let gt = nlos_mesh::metrics::unwelded_mesh(&pos, &tris).expect("unwelded");
    assert_eq!((gt.n_faces(), gt.n_vertices()), (3, 9));
    let rec = plane(0.6, 3, 0.4);
    let m = evaluate(&rec, &gt, &EvalParams::default()).expect("evaluate");
    assert_eq!(m.coverage, 1.0);
    assert_eq!(m.depth_error_max, Some(0.0));
    assert!(matches!(
        nlos_mesh::metrics::unwelded_mesh(&pos, &[[0, 1, 7]]),
        Err(MeshError::IndexOutOfRange { index: 7, .. })
    ));
    // and through a file
    let dir = std::env::temp_dir().join(format!("nlos-metrics-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let file = dir.join("fin.obj");
    let mut obj = String::new();
    for p in pos {
        obj.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    obj.push_str("f 1 2 3\nf 1 3 4\nf 1 3 5\n");
    std::fs::write(&file, obj).expect("write");
    assert!(nlos_mesh::io::load(&file).is_err());
    let gt = nlos_mesh::metrics::load_for_eval(&file).expect("load as ground truth");
    assert_eq!(gt.n_faces(), 3);
    assert!(matches!(nlos_mesh::metrics::load_for_eval(dir.join("missing.obj")), Err(MeshError::Io { .. })));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn interior_mask_erodes_the_hits_by_the_band_and_at_the_grid_border() {
    // 7 × 7 map, hits in the 5 × 5 block of rows and columns 1..=5, and one lone hit at the corner (0, 0).
    let n = 7;
    let mut depth = vec![f32::NAN; n * n];
    for iy in 1..=5 {
        for ix in 1..=5 {
            depth[ix + n * iy] = 0.4;
        }
    }
    depth[0] = 0.4;
    let count = |band| interior_mask(&depth, n, band).iter().filter(|&&k| k).count();
    assert_eq!(count(0), 26, "band 0 marks the hits");
    assert_eq!(count(1), 9, "one pixel in from each side of the block: 3 × 3");
    let two = interior_mask(&depth, n, 2);
    assert_eq!(two.iter().filter(|&&k| k).count(), 1);
    assert!(two[3 + n * 3], "the block's centre is its only pixel two in from every side");
    // A full map loses only the grid's border.
    let full = vec![0.4f32; n * n];
    assert_eq!(interior_mask(&full, n, 1).iter().filter(|&&k| k).count(), 25);
    assert_eq!(interior_mask(&full, n, 3).iter().filter(|&&k| k).count(), 1);
}

#[test]
fn depth_error_splits_into_interior_and_silhouette_band() {
    // A plate of side 0.2 m at 0.4 m, seen by a reconstruction 1 cm behind it that covers the whole grid.
    let gt = plane(0.2, 4, 0.4);
    let rec = plane(0.6, 6, 0.41);
    let m = evaluate(&rec, &gt, &EvalParams::default()).expect("evaluate");
    let side = (m.gt_pixels as f64).sqrt().round() as usize;
    assert_eq!(side * side, m.gt_pixels, "the plate hits a square of pixels");
    assert_eq!(m.interior_pixels, (side - 2 * SILHOUETTE_BAND).pow(2));
    for e in [m.depth_error_mean_interior, m.depth_error_mean_silhouette] {
        assert!((e.expect("pixels on both") - 0.01).abs() < 1e-6, "{e:?}");
    }
    // The reconstruction's ring outside the plate is no error: the split covers the pixels hit on both.
    let (Some(inside), Some(band), Some(mean)) =
        (m.depth_error_mean_interior, m.depth_error_mean_silhouette, m.depth_error_mean)
    else {
        panic!("pixels on both: {m:?}")
    };
    let weighted = inside * m.interior_pixels as f64 + band * (m.both_pixels - m.interior_pixels) as f64;
    assert!((weighted / m.both_pixels as f64 - mean).abs() < 1e-9);

    // The ground truth against itself: no error on either side.
    let exact = evaluate(&gt, &gt, &EvalParams::default()).expect("evaluate");
    assert_eq!(exact.depth_error_mean_interior, Some(0.0));
    assert_eq!(exact.depth_error_mean_silhouette, Some(0.0));
    // A small plate at the centre hits interior pixels only: no silhouette band error to report.
    let small = plane(0.02, 1, 0.4);
    let inner = evaluate(&small, &gt, &EvalParams::default()).expect("evaluate");
    assert_eq!(inner.depth_error_mean_silhouette, None, "no band pixel is hit by the small plate");
    assert_eq!(inner.depth_error_mean_interior, Some(0.0));
}

/// `nlos eval` lines written before the interior/band split still read back (the new fields default).
#[test]
fn records_without_the_silhouette_split_still_deserialise() {
    let line = r#"{"grid":128,"x_range":[-0.25,0.25],"y_range":[-0.25,0.25],"gt_pixels":10,"reconstruction_pixels":9,
        "both_pixels":8,"coverage":0.8,"depth_error_mean":0.001,"depth_error_median":0.001,"depth_error_rms":0.001,
        "depth_error_max":0.002,"chamfer":0.01,"mean_reconstruction_to_gt":0.005,"mean_gt_to_reconstruction":0.005,
        "hausdorff":0.02,"normal_error_mean_deg":10.0,"normal_error_rms_deg":12.0}"#;
    let m: nlos_mesh::metrics::Metrics = serde_json::from_str(line).expect("an earlier record");
    assert_eq!(m.interior_pixels, 0);
    assert_eq!((m.depth_error_mean_interior, m.depth_error_mean_silhouette), (None, None));
    assert_eq!(m.both_pixels, 8);
    assert_eq!((m.normal_error_near_deg, m.far_vertex_fraction), (None, None));
}
