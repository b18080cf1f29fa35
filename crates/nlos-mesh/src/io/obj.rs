//! Wavefront OBJ: positions and faces, read and written here.
//!
//! Why not `tobj`: it renumbers vertices per object in order of first use and drops unused ones, so a
//! file's vertex `i` is not the mesh's vertex `i` and round trips are not exact. This reader keeps the
//! file's numbering.

use std::fmt::Write as _;

use glam::Vec3;

use super::TriangleSoup;
use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

/// Parses OBJ bytes: `v x y z [w | r g b]` records and `f` records (`i`, `i/t`, `i//n`, `i/t/n`, negative
/// indices relative to the vertices read so far; polygons are fan-triangulated). Vertex `i` of the file
/// (1-based) is vertex `i − 1` of the soup, groups and objects share one vertex list. Texture
/// coordinates, normals, groups, materials, lines and points are ignored.
pub fn read_obj(bytes: &[u8], file: &str) -> Result<TriangleSoup, MeshError> {
    let mut soup = TriangleSoup::default();
    let mut poly: Vec<u32> = Vec::new();
    for (ln, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = ln + 1;
        let field = || format!("line {line_no}");
        let line = std::str::from_utf8(raw).map_err(|_| MeshError::format(file, field(), "not UTF-8 text"))?;
        let line = line.split('#').next().unwrap_or("");
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut c = [0f32; 3];
                for x in c.iter_mut() {
                    let tok = it.next().ok_or_else(|| {
                        MeshError::format(file, field(), "`v` needs three coordinates; fix the vertex line")
                    })?;
                    *x = tok.parse().map_err(|_| {
                        MeshError::format(file, field(), format!("{tok:?} is not a number; fix the vertex line"))
                    })?;
                }
                let p = Vec3::from_array(c);
                if !p.is_finite() {
                    return Err(MeshError::format(file, field(), "non-finite coordinate; fix the vertex line"));
                }
                soup.positions.push(p);
            }
            Some("f") => {
                poly.clear();
                for tok in it {
                    let first = tok.split('/').next().unwrap_or("");
                    let i: i64 = first.parse().map_err(|_| {
                        MeshError::format(file, field(), format!("{tok:?} is not a vertex index; fix the face line"))
                    })?;
                    let n = soup.positions.len() as i64;
                    let idx = if i > 0 { i - 1 } else { n + i };
                    if i == 0 || idx < 0 || idx >= n {
                        return Err(MeshError::format(
                            file,
                            field(),
                            format!("vertex index {i} out of range (only {n} vertices defined so far)"),
                        ));
                    }
                    poly.push(idx as u32);
                }
                if poly.len() < 3 {
                    return Err(MeshError::format(file, field(), "a face needs at least 3 vertices"));
                }
                for k in 1..poly.len() - 1 {
                    soup.triangles.push([poly[0], poly[k], poly[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(soup)
}

/// Writes the live vertices and faces as OBJ (`v x y z` with the shortest decimal that reads back to the
/// same `f32`, then `f a b c`, 1-based). Reading it back gives bit-identical positions and the same
/// triangles.
pub fn write_obj(mesh: &SurfaceMesh) -> Vec<u8> {
    let (pos, tris) = mesh.to_triangles();
    let mut s = String::with_capacity(pos.len() * 40 + tris.len() * 24);
    s.push_str("# nlos-mesh\n");
    for p in &pos {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for t in &tris {
        let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s.into_bytes()
}
