//! Procedural shapes for tests and demos. All are consistently oriented (outward / +z normals) and
//! manifold; they return a [`SurfaceMesh`] directly.

use std::collections::HashMap;

use glam::Vec3;

use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

fn build(positions: &[Vec3], tris: &[[u32; 3]]) -> SurfaceMesh {
    // The shapes below are manifold by construction; an error would be a bug in this file.
    match SurfaceMesh::from_triangles(positions, tris) {
        Ok(m) => m,
        Err(e) => unreachable!("procedural shape is not manifold: {e}"),
    }
}

/// Icosphere of radius `radius` around `center`: an icosahedron whose faces are split `subdivisions`
/// times into four (20·4ⁿ faces, 10·4ⁿ + 2 vertices), vertices projected onto the sphere.
/// `subdivisions` above 7 is clamped to 7 (327,680 faces).
pub fn icosphere(center: Vec3, radius: f32, subdivisions: u32) -> SurfaceMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut pos: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from_array(*p).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions.min(7) {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, pos: &mut Vec<Vec3>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                pos.push(((pos[a as usize] + pos[b as usize]) * 0.5).normalize());
                (pos.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for &[a, b, c] in &tris {
            let ab = midpoint(a, b, &mut pos);
            let bc = midpoint(b, c, &mut pos);
            let ca = midpoint(c, a, &mut pos);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let pos: Vec<Vec3> = pos.into_iter().map(|p| center + p * radius).collect();
    build(&pos, &tris)
}

/// Regular grid on the plane z = 0 covering `[0, size_x] × [0, size_y]` with `nx × ny` quads, each split
/// into two triangles along alternating diagonals; normals +z. An open mesh with one boundary loop.
/// `nx`, `ny` are clamped to `[1, 4096]`.
pub fn plane_grid(size_x: f32, size_y: f32, nx: usize, ny: usize) -> SurfaceMesh {
    height_field_impl(size_x, size_y, nx, ny, |_, _| 0.0)
}

/// Height field `z = f(x, y)` sampled on the grid of [`plane_grid`]. Errors if `f` returns a non-finite
/// value.
pub fn height_field(
    size_x: f32,
    size_y: f32,
    nx: usize,
    ny: usize,
    f: impl Fn(f32, f32) -> f32,
) -> Result<SurfaceMesh, MeshError> {
    let m = height_field_impl(size_x, size_y, nx, ny, f);
    for v in m.vertices() {
        let p = m.position(v);
        if !p.is_finite() {
            return Err(MeshError::NonFinitePosition { vertex: v.idx(), position: p.to_array() });
        }
    }
    Ok(m)
}

fn height_field_impl(size_x: f32, size_y: f32, nx: usize, ny: usize, f: impl Fn(f32, f32) -> f32) -> SurfaceMesh {
    let nx = nx.clamp(1, 4096);
    let ny = ny.clamp(1, 4096);
    let mut pos = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            let x = size_x * i as f32 / nx as f32;
            let y = size_y * j as f32 / ny as f32;
            pos.push(Vec3::new(x, y, f(x, y)));
        }
    }
    let id = |i: usize, j: usize| (i + (nx + 1) * j) as u32;
    let mut tris = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            } else {
                tris.push([a, b, d]);
                tris.push([b, c, d]);
            }
        }
    }
    // Non-finite heights are reported by `height_field`; build without the finiteness check here.
    let safe: Vec<Vec3> = pos.iter().map(|p| if p.is_finite() { *p } else { Vec3::ZERO }).collect();
    let mut m = build(&safe, &tris);
    for (i, p) in pos.iter().enumerate() {
        m.positions_mut()[i] = *p;
    }
    m
}

/// Open cone (no base disk): apex at `apex_height` above the origin on +z, base circle of `radius` in
/// z = 0 with `segments` vertices, `rings` rings of vertices between base and apex. Normals point outward.
/// `segments` is clamped to `[3, 65536]`, `rings` to `[1, 65536]`.
pub fn open_cone(radius: f32, apex_height: f32, segments: usize, rings: usize) -> SurfaceMesh {
    let s = segments.clamp(3, 65536);
    let r = rings.clamp(1, 65536);
    let mut pos = Vec::with_capacity(s * r + 1);
    for k in 0..r {
        let t = k as f32 / r as f32; // 0 at the base
        for i in 0..s {
            let a = std::f32::consts::TAU * (i as f32 + 0.5 * k as f32) / s as f32;
            pos.push(Vec3::new(radius * (1.0 - t) * a.cos(), radius * (1.0 - t) * a.sin(), apex_height * t));
        }
    }
    pos.push(Vec3::new(0.0, 0.0, apex_height));
    let apex = (s * r) as u32;
    let id = |k: usize, i: usize| (k * s + i % s) as u32;
    let mut tris = Vec::new();
    for k in 0..r - 1 {
        for i in 0..s {
            tris.push([id(k, i), id(k, i + 1), id(k + 1, i)]);
            tris.push([id(k, i + 1), id(k + 1, i + 1), id(k + 1, i)]);
        }
    }
    for i in 0..s {
        tris.push([id(r - 1, i), id(r - 1, i + 1), apex]);
    }
    build(&pos, &tris)
}
