//! Synthetic scenes the benchmarks and examples share.

/// A height field of `n × n` vertices (`2 (n − 1)²` triangles) over [−0.3, 0.3]² m at z = 0.5 + 0.05 sin(13x)
/// cos(9y), facing the wall (normals toward −z): every face is lit by every spot of a confocal scan of the
/// wall's centre, the renderer's worst case. Positions as `[x, y, z]`.
///
/// # Panics
/// If `n < 2`.
pub fn height_field(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    assert!(n >= 2, "a height field needs at least 2 × 2 vertices");
    let mut p = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (-0.3 + 0.6 * i as f32 / (n - 1) as f32, -0.3 + 0.6 * j as f32 / (n - 1) as f32);
            p.push([x, y, 0.5 + 0.05 * (13.0 * x).sin() * (9.0 * y).cos()]);
        }
    }
    let id = |i: usize, j: usize| (i * n + j) as u32;
    let mut f = Vec::with_capacity(2 * (n - 1) * (n - 1));
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            f.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            f.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    (p, f)
}
