//! Collision-aware evolution (issue 7): narrow-phase CCD against hand-built cases and brute force, and
//! `evolve` on sheets, spheres and folded grids checked with the exact static intersection test.

use glam::{DVec3, Vec3};
use nlos_mesh::evolve::ccd::{
    Moving, edge_edge_ccd, point_triangle_distance, segment_segment_distance, vertex_triangle_ccd,
};
use nlos_mesh::evolve::{EvolveError, EvolveParams, evolve};
use nlos_mesh::intersect::self_intersections;
use nlos_mesh::{MeshError, SurfaceMesh, shapes};

/// SplitMix64: deterministic, dependency-free.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.uniform()
    }
    fn vec(&mut self, s: f32) -> Vec3 {
        Vec3::new(self.range(-s, s), self.range(-s, s), self.range(-s, s))
    }
}

fn mv(x0: [f32; 3], x1: [f32; 3]) -> Moving {
    Moving::new(Vec3::from(x0), Vec3::from(x1))
}

fn still(x: [f32; 3]) -> Moving {
    mv(x, x)
}

const TOL: f64 = 1e-6;

// ------------------------------------------------------------------------------------------------------
// narrow phase, hand-built
// ------------------------------------------------------------------------------------------------------

#[test]
fn vertex_through_face_at_half() {
    let (a, b, c) = (still([0.0, 0.0, 0.0]), still([1.0, 0.0, 0.0]), still([0.0, 1.0, 0.0]));
    let p = mv([0.25, 0.25, 1.0], [0.25, 0.25, -1.0]);
    let t = vertex_triangle_ccd(&p, &a, &b, &c, TOL).expect("collides");
    assert!((t - 0.5).abs() < 1e-12, "t = {t}");
    // moving triangle, static point: same relative motion
    let (a2, b2, c2) = (
        mv([0.0, 0.0, -1.0], [0.0, 0.0, 1.0]),
        mv([1.0, 0.0, -1.0], [1.0, 0.0, 1.0]),
        mv([0.0, 1.0, -1.0], [0.0, 1.0, 1.0]),
    );
    let t = vertex_triangle_ccd(&still([0.25, 0.25, 0.0]), &a2, &b2, &c2, TOL).expect("collides");
    assert!((t - 0.5).abs() < 1e-12, "t = {t}");
    // passes the plane outside the triangle: no collision
    let q = mv([2.0, 2.0, 1.0], [2.0, 2.0, -1.0]);
    assert_eq!(vertex_triangle_ccd(&q, &a, &b, &c, TOL), None);
    // stops short of the plane
    let r = mv([0.25, 0.25, 1.0], [0.25, 0.25, 0.01]);
    assert_eq!(vertex_triangle_ccd(&r, &a, &b, &c, TOL), None);
}

#[test]
fn vertex_touching_at_end_and_start() {
    let (a, b, c) = (still([0.0, 0.0, 0.0]), still([1.0, 0.0, 0.0]), still([0.0, 1.0, 0.0]));
    let p = mv([0.2, 0.2, 1.0], [0.2, 0.2, 0.0]);
    let t = vertex_triangle_ccd(&p, &a, &b, &c, TOL).expect("touches at the end");
    assert!((1.0 - t) < 1e-9, "t = {t}");
    let q = mv([0.2, 0.2, 0.0], [0.2, 0.2, 1.0]);
    assert_eq!(vertex_triangle_ccd(&q, &a, &b, &c, TOL), Some(0.0));
}

#[test]
fn grazing_vertex_touches_the_edge_tangentially() {
    // the point moves on a parabola-free line that just touches edge ab's line at x = 0.5 while the
    // triangle rotates... simplest tangential case: a point sliding in the plane z = 0 into the triangle
    let (a, b, c) = (still([0.0, 0.0, 0.0]), still([1.0, 0.0, 0.0]), still([0.0, 1.0, 0.0]));
    // coplanar throughout: the cubic vanishes identically; the in-plane quadratics find the edge crossing
    let p = mv([0.25, -1.0, 0.0], [0.25, 1.0, 0.0]);
    let t = vertex_triangle_ccd(&p, &a, &b, &c, TOL).expect("in-plane entry");
    assert!((t - 0.5).abs() < 1e-9, "t = {t}");
    // coplanar, missing the triangle
    let q = mv([2.0, -1.0, 0.0], [2.0, 1.0, 0.0]);
    assert_eq!(vertex_triangle_ccd(&q, &a, &b, &c, TOL), None);
    // a double root: corner c swings the triangle's plane through z = 0 while the point moves so that the
    // signed volume is ∝ (t − ½)²: it touches the triangle at t = ½ without crossing
    let c_swing = mv([0.0, 1.0, 1.0], [0.0, 1.0, -1.0]);
    let p2 = mv([0.25, 0.2, 0.4], [0.25, 0.6, -0.4]);
    let t = vertex_triangle_ccd(&p2, &a, &b, &c_swing, TOL).expect("tangential contact");
    assert!((t - 0.5).abs() < 1e-5, "t = {t}");
    // the same, lifted by 1 mm: the volume never vanishes, no contact
    let p3 = mv([0.25, 0.2, 0.401], [0.25, 0.6, -0.399]);
    assert_eq!(vertex_triangle_ccd(&p3, &a, &b, &c_swing, TOL), None);
}

#[test]
fn edge_edge_cases() {
    // crossing edges: ab along x at z = 1 moving to z = −1, cd along y at z = 0
    let (a, b) = (mv([-1.0, 0.0, 1.0], [-1.0, 0.0, -1.0]), mv([1.0, 0.0, 1.0], [1.0, 0.0, -1.0]));
    let (c, d) = (still([0.0, -1.0, 0.0]), still([0.0, 1.0, 0.0]));
    let t = edge_edge_ccd(&a, &b, &c, &d, TOL).expect("collides");
    assert!((t - 0.5).abs() < 1e-12);
    // parallel edges passing each other at distance 0.5: no collision
    let (c2, d2) = (still([-1.0, 0.5, 0.0]), still([1.0, 0.5, 0.0]));
    assert_eq!(edge_edge_ccd(&a, &b, &c2, &d2, TOL), None);
    // parallel edges meeting: the cubic is identically zero (always coplanar), in-plane tests find it
    let (c3, d3) = (still([-1.0, 0.0, 0.0]), still([1.0, 0.0, 0.0]));
    let t = edge_edge_ccd(&a, &b, &c3, &d3, TOL).expect("parallel collision");
    assert!((t - 0.5).abs() < 1e-9, "t = {t}");
    // skew edges whose lines cross but the segments miss
    let (c4, d4) = (still([3.0, -1.0, 0.0]), still([3.0, 1.0, 0.0]));
    assert_eq!(edge_edge_ccd(&a, &b, &c4, &d4, TOL), None);
}

#[test]
fn distances() {
    let z = DVec3::ZERO;
    let (d, bary) = point_triangle_distance(DVec3::new(0.25, 0.25, 2.0), z, DVec3::X, DVec3::Y);
    assert!((d - 2.0).abs() < 1e-15 && (bary[0] - 0.5).abs() < 1e-15);
    // degenerate triangle (collinear): distance to the segment
    let (d, _) = point_triangle_distance(DVec3::new(0.5, 1.0, 0.0), z, DVec3::X, DVec3::X * 2.0);
    assert!((d - 1.0).abs() < 1e-15, "{d}");
    let (d, s, u) = segment_segment_distance(z, DVec3::X, DVec3::new(0.0, 1.0, 0.0), DVec3::new(1.0, 1.0, 0.0));
    assert!((d - 1.0).abs() < 1e-15 && (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&u));
    let (d, _, _) = segment_segment_distance(z, z, DVec3::Y, DVec3::Y);
    assert!((d - 1.0).abs() < 1e-15);
}

// ------------------------------------------------------------------------------------------------------
// narrow phase against brute force
// ------------------------------------------------------------------------------------------------------

/// Brute force: sample the signed volume at `n` steps; at every sign change (or zero) interpolate the
/// crossing and test the distance there. Returns the earliest hit and the smallest crossing distance.
fn brute(ms: &[Moving; 4], edge: bool, n: usize) -> (Option<f64>, f64) {
    let vol = |t: f64| {
        let x = ms.map(|m| m.at(t));
        (x[1] - x[0]).cross(x[2] - x[0]).dot(x[3] - x[0])
    };
    let dist = |t: f64| {
        let x = ms.map(|m| m.at(t));
        if edge {
            segment_segment_distance(x[0], x[1], x[2], x[3]).0
        } else {
            point_triangle_distance(x[3], x[0], x[1], x[2]).0
        }
    };
    let mut best = f64::INFINITY;
    let mut prev = vol(0.0);
    for k in 1..=n {
        let t = k as f64 / n as f64;
        let cur = vol(t);
        if prev == 0.0 || prev.signum() != cur.signum() || cur == 0.0 {
            // linear interpolation of the crossing within the step
            let t0 = (k - 1) as f64 / n as f64;
            let tc = if cur != prev { t0 + (t - t0) * prev / (prev - cur) } else { t0 };
            let d = dist(tc);
            best = best.min(d);
            if d <= 1e-3 {
                return (Some(tc), best);
            }
        }
        prev = cur;
    }
    (None, best)
}

#[test]
fn ccd_matches_brute_force_sampling() {
    let mut rng = Rng(7);
    let (mut hits, mut misses, mut skipped) = (0, 0, 0);
    for case in 0..3000 {
        let edge = case % 2 == 1;
        let pts: [Moving; 4] = std::array::from_fn(|_| {
            let x0 = rng.vec(1.0);
            Moving::new(x0, x0 + rng.vec(1.0))
        });
        let tol = 1e-3;
        let ccd = if edge {
            edge_edge_ccd(&pts[0], &pts[1], &pts[2], &pts[3], tol)
        } else {
            vertex_triangle_ccd(&pts[3], &pts[0], &pts[1], &pts[2], tol)
        };
        let (bf, closest) = brute(&pts, edge, 20_000);
        // borderline cases (crossing distance within the sampling error of the tolerance) are not decided
        if (closest - tol).abs() < 2e-4 {
            skipped += 1;
            continue;
        }
        match (ccd, bf) {
            (Some(t), Some(tb)) => {
                assert!((t - tb).abs() < 1e-3, "case {case}: ccd {t} vs brute {tb}");
                hits += 1;
            }
            (None, None) => misses += 1,
            (a, b) => {
                panic!("case {case} ({}): ccd {a:?} vs brute {b:?} (closest {closest})", if edge { "ee" } else { "vt" })
            }
        }
    }
    assert!(hits > 100 && misses > 100, "hits {hits} misses {misses} skipped {skipped}");
}
