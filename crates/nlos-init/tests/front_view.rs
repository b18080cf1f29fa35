//! Front-view detail (`nlos_init::front_view`): a mesh with the volume's slot scores higher than one that
//! covers it, a dark print lowers the score of a uniform albedo, and bad input is a typed error.

use glam::Vec3;
use nlos_init::{Axis, Volume, front_view_detail};

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
fn plate(skip: impl Fn(f64, f64) -> bool) -> (Vec<Vec3>, Vec<[u32; 3]>) {
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
    (positions, triangles)
}

#[test]
fn the_slot_counts_and_so_does_the_print() {
    let (x, y) = (axis(), axis());
    // The volume: one depth voxel per column, the plate bright, the slot and the outside dark, a little noise.
    let value: Vec<f32> = (0..N * N)
        .map(|i| {
            let (px, py) = (x[i % N], y[i / N]);
            let base = if in_plate(px, py) && !in_slot(px, py) { 1.0 } else { 0.05 };
            base + 0.01 * ((i * 7 % 5) as f32)
        })
        .collect();
    let volume = |data: Vec<f32>| Volume {
        nx: N,
        ny: N,
        nz: 1,
        x: Axis { start: x[0], step: 0.01 },
        y: Axis { start: y[0], step: 0.01 },
        z: Axis { start: 0.4, step: 0.01 },
        data,
    };
    let vol = volume(value.clone());
    let score = |skip: &dyn Fn(f64, f64) -> bool, albedo: Option<&dyn Fn(Vec3) -> f32>| {
        let (p, t) = plate(skip);
        let a: Option<Vec<f32>> = albedo.map(|f| p.iter().map(|&q| f(q)).collect());
        front_view_detail(&vol, &p, &t, a.as_deref()).expect("valid")
    };
    let with_slot = score(&in_slot, None);
    let covered = score(&|_, _| false, None);
    eprintln!("with the slot: {with_slot:?}\nwithout: {covered:?}");
    assert!(with_slot.r > 0.95, "{with_slot:?}");
    assert!(covered.r < 0.7, "{covered:?}");
    assert!(with_slot.coverage > 0.99 && covered.coverage > 0.99);
    // The slot lies inside the region (holes filled), the outside does not.
    assert_eq!(with_slot.region_pixels, 400);
    // The same slot as dark print on a whole plate (each square's corners dark) scores like the hole.
    let dark = |q: Vec3| {
        let inside = |dx: f64, dy: f64| in_slot(f64::from(q.x) + dx, f64::from(q.y) + dy);
        if inside(0.005, 0.005) && inside(-0.005, -0.005) { 0.05 } else { 1.0 }
    };
    let printed = score(&|_, _| false, Some(&dark));
    eprintln!("printed: {printed:?}");
    // Below the hole's 0.998: a hit takes its nearest corner's albedo, so the print's edges move by up to half
    // a square (0.82 here).
    assert!(printed.r > 0.8 && printed.r > covered.r + 0.5, "{printed:?}");
    // Bad input: typed errors.
    let (p, t) = plate(in_slot);
    let mut nan = value.clone();
    nan[3] = f32::NAN;
    assert!(front_view_detail(&volume(nan), &p, &t, None).is_err());
    assert!(front_view_detail(&volume(value[1..].to_vec()), &p, &t, None).is_err());
    assert!(front_view_detail(&volume(vec![1.0; N * N]), &p, &t, None).is_err(), "a constant front view");
    assert!(front_view_detail(&vol, &p, &t, Some(&[1.0])).is_err(), "one albedo per vertex");
}
