//! Front-view detail (`nlos_mesh::front_view`): a mesh with the volume's slot scores higher than one that
//! covers it, a dark print lowers the score of a uniform albedo, and bad input is a typed error.

use glam::Vec3;
use nlos_mesh::TriangleBvh;
use nlos_mesh::bvh::RayHit;
use nlos_mesh::front_view::{FrontView, front_view_detail};

/// 32 × 32 pixels over [−0.16, 0.16]² m; the plate covers |x|, |y| < 0.1 m, the slot 0 ≤ x < 0.03 m.
const N: usize = 32;

fn axis() -> Vec<f64> {
    (0..N).map(|i| -0.16 + 0.01 * (i as f64 + 0.5)).collect()
}

fn in_plate(x: f64, y: f64) -> bool {
    x.abs() < 0.1 && y.abs() < 0.1
}

fn in_slot(x: f64, y: f64) -> bool {
    (0.0..0.03).contains(&x) && y.abs() < 0.07
}

/// A plate of 1 cm squares at z = 0.4 m, leaving out the squares whose centre `skip` says.
fn plate(skip: impl Fn(f64, f64) -> bool) -> TriangleBvh {
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for j in 0..20 {
        for i in 0..20 {
            let (x0, y0) = (-0.1 + 0.01 * i as f32, -0.1 + 0.01 * j as f32);
            if skip(f64::from(x0) + 0.005, f64::from(y0) + 0.005) {
                continue;
            }
            let b = positions.len() as u32;
            for (dx, dy) in [(0.0, 0.0), (0.01, 0.0), (0.0, 0.01), (0.01, 0.01)] {
                positions.push(Vec3::new(x0 + dx, y0 + dy, 0.4));
            }
            triangles.extend([[b, b + 1, b + 2], [b + 1, b + 3, b + 2]]);
        }
    }
    TriangleBvh::from_triangles(&positions, &triangles).expect("a valid plate")
}

#[test]
fn the_slot_counts_and_so_does_the_print() {
    let (x, y) = (axis(), axis());
    // The volume: the plate bright, the slot and the outside dark, a little blur-free noise.
    let value: Vec<f32> = (0..N * N)
        .map(|i| {
            let (px, py) = (x[i % N], y[i / N]);
            let base = if in_plate(px, py) && !in_slot(px, py) { 1.0 } else { 0.05 };
            base + 0.01 * ((i * 7 % 5) as f32)
        })
        .collect();
    let view = FrontView { x: &x, y: &y, value: &value };
    let uniform = |_: &RayHit| 1.0f32;
    let with_slot = front_view_detail(view, &plate(in_slot), &uniform).expect("valid");
    let covered = front_view_detail(view, &plate(|_, _| false), &uniform).expect("valid");
    eprintln!("with the slot: {with_slot:?}\nwithout: {covered:?}");
    assert!(with_slot.r > 0.95, "{with_slot:?}");
    assert!(covered.r < 0.7, "{covered:?}");
    assert!(with_slot.coverage > 0.99 && covered.coverage > 0.99);
    // The slot lies inside the region (holes filled), the outside does not.
    assert_eq!(with_slot.region_pixels, 400);
    // The same slot as dark print on a whole plate scores like the hole.
    let printed = front_view_detail(view, &plate(|_, _| false), &|hit: &RayHit| {
        if in_slot(f64::from(hit.point.x), f64::from(hit.point.y)) { 0.05 } else { 1.0 }
    })
    .expect("valid");
    assert!(printed.r > 0.95, "{printed:?}");
    // Bad input.
    assert!(front_view_detail(FrontView { x: &x, y: &y, value: &value[1..] }, &plate(in_slot), &uniform).is_err());
    let mut nan = value.clone();
    nan[3] = f32::NAN;
    assert!(front_view_detail(FrontView { x: &x, y: &y, value: &nan }, &plate(in_slot), &uniform).is_err());
}
