//! Closest point, distances, self-intersection and quality, checked against brute force and exact cases.

use glam::Vec3;
use nlos_mesh::distance::{self, Sampling};
use nlos_mesh::intersect::{self, triangles_intersect};
use nlos_mesh::quality::mesh_quality;
use nlos_mesh::{FaceId, SurfaceMesh, TriangleBvh, shapes};

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

/// Brute-force distance to a point set's closest triangle, by dense barycentric search refinement-free:
/// exact closest points computed per triangle by projecting onto the plane and clamping to edges.
fn brute_distance(p: Vec3, m: &SurfaceMesh) -> f32 {
    let mut best = f32::INFINITY;
    for f in m.faces() {
        let [a, b, c] = m.face_points(f);
        let n = (b - a).cross(c - a).normalize();
        let q = p - n * n.dot(p - a);
        let inside = [(a, b), (b, c), (c, a)].iter().all(|&(x, y)| (y - x).cross(q - x).dot(n) >= 0.0);
        let d = if inside {
            p.distance(q)
        } else {
            [(a, b), (b, c), (c, a)]
                .iter()
                .map(|&(x, y)| {
                    let t = ((p - x).dot(y - x) / (y - x).length_squared()).clamp(0.0, 1.0);
                    p.distance(x + (y - x) * t)
                })
                .fold(f32::INFINITY, f32::min)
        };
        best = best.min(d);
    }
    best
}

#[test]
fn closest_point_matches_brute_force() {
    let m = shapes::icosphere(Vec3::new(0.1, 0.2, 0.3), 1.0, 2);
    let bvh = TriangleBvh::from_mesh(&m).expect("bvh");
    let mut rng = Rng::new(5);
    for _ in 0..2000 {
        let p = rng.v(4.0);
        let cp = bvh.closest_point(p);
        let bf = brute_distance(p, &m);
        assert!((cp.distance() - bf).abs() < 1e-5, "bvh {} vs brute {bf} at {p}", cp.distance());
        // the point lies on the reported triangle at the reported barycentrics
        let [a, b, c] = bvh.triangle(cp.triangle);
        let q = a * cp.barycentric.x + b * cp.barycentric.y + c * cp.barycentric.z;
        assert!(q.distance(cp.point) < 1e-5);
    }
    assert!(bvh.closest_point_within(Vec3::splat(10.0), 1.0).is_none());
    assert!(TriangleBvh::from_triangles(&[], &[]).is_err());
}

#[test]
fn chamfer_and_hausdorff_match_brute_force() {
    let a = shapes::icosphere(Vec3::ZERO, 1.0, 1);
    let b = shapes::height_field(2.0, 2.0, 5, 4, |x, y| 0.3 * (x * 2.0).sin() + 0.1 * y).expect("finite");
    let d = distance::mesh_distance(&a, &b, Sampling::Vertices).expect("non-empty");
    let ab: Vec<f32> = a.vertices().map(|v| brute_distance(a.position(v), &b)).collect();
    let ba: Vec<f32> = b.vertices().map(|v| brute_distance(b.position(v), &a)).collect();
    let mean = |x: &[f32]| x.iter().map(|&v| v as f64).sum::<f64>() / x.len() as f64;
    let max = |x: &[f32]| x.iter().copied().fold(0.0, f32::max);
    assert!((d.mean_a_to_b - mean(&ab)).abs() < 1e-5);
    assert!((d.mean_b_to_a - mean(&ba)).abs() < 1e-5);
    assert!((d.chamfer - mean(&ab) - mean(&ba)).abs() < 1e-5);
    assert!((d.hausdorff - max(&ab).max(max(&ba))).abs() < 1e-5);
    // a mesh against itself is at distance zero; a translated copy at the translation (along the normal)
    let same = distance::mesh_distance(&b, &b, Sampling::Lattice(3)).expect("non-empty");
    assert!(same.hausdorff < 1e-6 && same.chamfer < 1e-6);
    let flat = shapes::plane_grid(1.0, 1.0, 4, 4);
    let mut up = flat.clone();
    for p in up.positions_mut() {
        p.z += 0.25;
    }
    let d = distance::mesh_distance(&flat, &up, Sampling::Lattice(4)).expect("non-empty");
    assert!((d.hausdorff - 0.25).abs() < 1e-6 && (d.chamfer - 0.5).abs() < 1e-6);
    assert!((distance::point_to_mesh_distance(Vec3::new(0.5, 0.5, -2.0), &flat).expect("ok") - 2.0).abs() < 1e-6);
}

#[test]
fn dense_sampling_matches_brute_force_and_its_bound() {
    // a coarse sphere against a fine one: the largest gaps are inside the coarse faces, which vertex
    // sampling misses
    let coarse = shapes::icosphere(Vec3::ZERO, 1.0, 1);
    let fine = shapes::icosphere(Vec3::ZERO, 1.0, 3);
    let s = 0.05;
    let d = distance::mesh_distance(&coarse, &fine, Sampling::Spacing(s)).expect("non-empty");
    let brute_max = |a: &SurfaceMesh, b: &SurfaceMesh| {
        distance::sample_points(a, Sampling::Spacing(s)).iter().map(|&p| brute_distance(p, b)).fold(0.0, f32::max)
    };
    let (ab, ba) = (brute_max(&coarse, &fine), brute_max(&fine, &coarse));
    assert!((d.max_a_to_b - ab).abs() < 1e-5 && (d.max_b_to_a - ba).abs() < 1e-5, "{d:?} vs {ab} {ba}");
    // the sample count per face follows the spacing
    let longest = coarse.edges().map(|e| coarse.edge_length(e)).fold(0.0, f32::max);
    assert!(distance::sample_points(&coarse, Sampling::Spacing(s)).len() > coarse.n_faces() * 10);
    assert!(longest / s > 10.0);
    // vertices only: the coarse vertices are vertices of the fine sphere too, so coarse-to-fine measured at
    // vertices is zero while the dense one finds the gaps inside the coarse faces; a much finer lattice
    // moves the dense value by at most s/√3
    let v = distance::mesh_distance(&coarse, &fine, Sampling::Vertices).expect("non-empty");
    let finer = distance::mesh_distance(&coarse, &fine, Sampling::Lattice(64)).expect("non-empty");
    assert!(v.max_a_to_b < 1e-5 && d.max_a_to_b > 0.03, "vertices {} vs dense {}", v.max_a_to_b, d.max_a_to_b);
    assert!((finer.hausdorff - d.hausdorff).abs() <= s / 3f32.sqrt(), "{} vs {}", finer.hausdorff, d.hausdorff);
    // the deepest face centroid of the coarse sphere (below the unit sphere) bounds the answer
    let depth = coarse.faces().map(|f| 1.0 - (coarse.face_points(f).iter().sum::<Vec3>() / 3.0).length());
    let deepest = depth.fold(0.0, f32::max);
    assert!(d.max_a_to_b <= deepest + 1e-3 && d.max_a_to_b >= deepest - 0.02, "{} vs {deepest}", d.max_a_to_b);
    // non-positive spacing: vertices only
    assert_eq!(distance::sample_points(&coarse, Sampling::Spacing(0.0)).len(), coarse.n_vertices());
}

#[test]
fn any_within_agrees_with_closest_point() {
    let m = shapes::icosphere(Vec3::new(0.1, 0.2, 0.3), 1.0, 2);
    let bvh = TriangleBvh::from_mesh(&m).expect("bvh");
    let mut rng = Rng::new(9);
    for _ in 0..2000 {
        let p = rng.v(3.0);
        let r = rng.f() * 0.5;
        let d = brute_distance(p, &m);
        if (d - r).abs() > 1e-5 {
            assert_eq!(bvh.any_within(p, r), d <= r, "{p} r {r} d {d}");
        }
    }
}

#[test]
fn normal_error_of_identical_and_flipped_meshes() {
    let s = shapes::icosphere(Vec3::ZERO, 1.0, 3);
    let e = distance::normal_angular_error(&s, &s).expect("ok");
    assert!(e.mean < 8.0, "vertex vs face normals differ only by discretisation: {}", e.mean);
    let (p, t) = s.to_triangles();
    let flipped: Vec<[u32; 3]> = t.iter().map(|x| [x[0], x[2], x[1]]).collect();
    let f = SurfaceMesh::from_triangles(&p, &flipped).expect("valid");
    let e = distance::normal_angular_error(&f, &s).expect("ok");
    assert!(e.mean > 170.0);
}

#[test]
fn normal_error_counts_the_far_vertices_apart() {
    // The reference sphere and, 4 radii away, a flipped copy: half the vertices lie on the reference, half
    // at least 2 radii off it.
    let s = shapes::icosphere(Vec3::ZERO, 1.0, 3);
    let (p, t) = s.to_triangles();
    let n = p.len() as u32;
    let mut pos = p.clone();
    pos.extend(p.iter().map(|&x| x + Vec3::new(4.0, 0.0, 0.0)));
    let mut tri = t.clone();
    tri.extend(t.iter().map(|x| [x[0] + n, x[2] + n, x[1] + n]));
    let both = SurfaceMesh::from_triangles(&pos, &tri).expect("valid");
    let e = distance::normal_angular_error(&both, &s).expect("ok");
    assert_eq!(e.distance.len(), e.per_vertex.len());
    let (near, far) = e.split(distance::FAR_FROM_REFERENCE);
    assert!((far - 0.5).abs() < 1e-12, "far fraction {far}");
    let near = near.expect("half the vertices are on the reference");
    // The far half (normals against the closest face of a sphere 2–6 radii away) averages about 100°.
    assert!(near < 8.0 && 2.0 * e.mean - near > 80.0, "near {near}°, all {}°", e.mean);
    // Nothing near: no mean; everything near: the whole mean.
    let (none, all_far) = e.split(-1.0);
    assert_eq!((none, all_far), (None, 1.0));
    let (all, no_far) = e.split(f32::INFINITY);
    assert!((all.expect("every vertex") - e.mean).abs() < 1e-9 && no_far == 0.0);
}

#[test]
fn triangle_triangle_exact_cases() {
    let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
    // crossing
    assert!(triangles_intersect(t, [Vec3::new(0.2, 0.2, -1.0), Vec3::new(0.2, 0.2, 1.0), Vec3::new(2.0, 2.0, 0.5)]));
    // separated
    assert!(!triangles_intersect(t, [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)]));
    // touching at a vertex exactly
    assert!(triangles_intersect(t, [Vec3::new(0.5, 0.5, 0.0), Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, 0.5, 1.0)]));
    // just missing the hypotenuse by one ulp
    let off = 0.5f32 + f32::EPSILON;
    assert!(!triangles_intersect(t, [Vec3::new(off, off, 0.0), Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, 0.6, 1.0)]));
    // coplanar overlapping / disjoint / contained
    assert!(triangles_intersect(t, [Vec3::new(0.5, 0.5, 0.0), Vec3::new(-0.5, 0.5, 0.0), Vec3::new(0.5, -0.5, 0.0)]));
    assert!(!triangles_intersect(t, [Vec3::new(2.0, 2.0, 0.0), Vec3::new(3.0, 2.0, 0.0), Vec3::new(2.0, 3.0, 0.0)]));
    assert!(triangles_intersect(t, [Vec3::new(0.1, 0.1, 0.0), Vec3::new(0.2, 0.1, 0.0), Vec3::new(0.1, 0.2, 0.0)]));
}

#[test]
fn closed_and_open_shapes_have_no_self_intersections() {
    for m in [
        shapes::icosphere(Vec3::ZERO, 1.0, 3),
        shapes::open_cone(1.0, 1.0, 32, 8),
        shapes::plane_grid(1.0, 1.0, 16, 16),
        shapes::height_field(1.0, 1.0, 20, 20, |x, y| (x * 9.0).sin() * (y * 7.0).cos() * 0.05).expect("finite"),
    ] {
        assert_eq!(intersect::self_intersections(&m).expect("non-empty"), vec![]);
    }
}

#[test]
fn self_intersections_are_found_and_match_brute_force() {
    // a grid with one vertex pushed through the surface far enough to cross non-adjacent faces: fold a
    // strip of a flat grid over onto itself
    let mut m = shapes::plane_grid(1.0, 1.0, 6, 6);
    for p in m.positions_mut() {
        if p.x > 0.6 {
            // fold: x' = 1.2 - x lies back over the grid, slightly raised and tilted to cross it
            let x = p.x;
            p.x = 1.2 - x;
            p.z = (x - 0.6) * 0.3 - 0.04;
        }
    }
    let pairs = intersect::self_intersections(&m).expect("non-empty");
    assert!(!pairs.is_empty());
    // brute force over all non-adjacent pairs and adjacent pairs with the same rules
    let faces: Vec<_> = m.faces().collect();
    let mut brute = Vec::new();
    for (i, &f) in faces.iter().enumerate() {
        for &g in &faces[i + 1..] {
            let fv = m.face_vertices(f);
            let gv = m.face_vertices(g);
            if fv.iter().any(|v| gv.contains(v)) {
                continue;
            }
            if triangles_intersect(m.face_points(f), m.face_points(g)) {
                brute.push((f, g));
            }
        }
    }
    for p in &brute {
        assert!(pairs.contains(p), "brute-force pair {p:?} missed");
    }
    // The indexed-triangle form finds the same pairs (face i is triangle i of `to_triangles`).
    let (pos, tris) = m.to_triangles();
    let by_index: Vec<(FaceId, FaceId)> = intersect::triangle_self_intersections(&pos, &tris)
        .expect("non-empty")
        .into_iter()
        .map(|(i, j)| (faces[i as usize], faces[j as usize]))
        .collect();
    assert_eq!(by_index, pairs);
    // adjacent faces folded flat onto each other are reported
    let mut fold =
        SurfaceMesh::from_triangles(&[Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.5, 0.4, 0.0)], &[[0, 1, 2], [1, 0, 3]])
            .expect("two triangles");
    assert_eq!(intersect::self_intersections(&fold).expect("ok").len(), 1, "coplanar fold-over");
    fold.positions_mut()[3] = Vec3::new(0.5, -0.4, 0.0);
    assert!(intersect::self_intersections(&fold).expect("ok").is_empty(), "flat neighbours");
    fold.positions_mut()[3] = Vec3::new(0.5, 0.4, 1e-7);
    assert!(intersect::self_intersections(&fold).expect("ok").is_empty(), "nearly folded is not folded");
}

#[test]
fn quality_of_regular_shapes() {
    let g = shapes::plane_grid(1.0, 1.0, 4, 4);
    let q = mesh_quality(&g);
    assert!((q.min_angle - 45.0).abs() < 1e-3 && (q.max_angle - 90.0).abs() < 1e-3);
    assert_eq!(q.degenerate_faces, 0);
    assert_eq!(q.valence_histogram.iter().sum::<usize>(), 25);
    assert_eq!(q.edge_length_histogram.counts.iter().sum::<usize>(), g.n_edges());
    assert!((q.min_edge_length - 0.25).abs() < 1e-6);
    assert!((q.max_edge_length - 0.25 * 2f32.sqrt()).abs() < 1e-6);
    assert_eq!(q.fraction_min_angle_at_least(45.0 - 1e-3), 1.0);
    let eq = SurfaceMesh::from_triangles(&[Vec3::ZERO, Vec3::X, Vec3::new(0.5, 3f32.sqrt() / 2.0, 0.0)], &[[0, 1, 2]])
        .expect("one triangle");
    let q = mesh_quality(&eq);
    assert!((q.max_aspect_ratio - 1.0).abs() < 1e-5 && (q.min_angle - 60.0).abs() < 1e-3);
    let s = shapes::icosphere(Vec3::ZERO, 1.0, 2);
    let q = mesh_quality(&s);
    assert_eq!(q.valence_histogram[5], 12);
    assert_eq!(q.valence_histogram[6], 150);
}
