//! Scenes shared by the integration tests.

use glam::Vec3;

/// A height field `z(x, y)` facing the wall (normals toward −z) over `n × n` square cells of side `cell`,
/// centred at `(cx, cy)`, each cell split into two triangles. Vertices run x fastest.
pub fn height_field(n: i32, cell: f32, cx: f32, cy: f32, z: impl Fn(f32, f32) -> f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (cx + (i as f32 - n as f32 / 2.0) * cell, cy + (j as f32 - n as f32 / 2.0) * cell);
            p.push(Vec3::new(x, y, z(x, y)));
        }
    }
    let id = |i: i32, j: i32| (j * (n + 1) + i) as u32;
    let mut t = Vec::new();
    for j in 0..n {
        for i in 0..n {
            // (v1 − v0) × (v2 − v0) points to −z.
            t.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            t.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    (p, t)
}
