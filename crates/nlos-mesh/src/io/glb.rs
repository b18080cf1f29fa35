//! glTF 2.0 binary (GLB) export, and a reader for the files this module writes.
//!
//! The container is small enough to write directly (12-byte header, a JSON chunk and a BIN chunk, each
//! padded to 4 bytes), which avoids a JSON dependency; the tests check the output with the `gltf` crate.

use glam::Vec3;

use super::TriangleSoup;
use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

const MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Writes the live mesh as a GLB: one node, one triangle primitive with `POSITION` (f32 VEC3 with min/max)
/// and `u32` indices. Positions and indices are stored exactly.
pub fn write_glb(mesh: &SurfaceMesh) -> Vec<u8> {
    let (pos, tris) = mesh.to_triangles();
    let (lo, hi) = pos
        .iter()
        .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(l, h), p| (l.min(*p), h.max(*p)));
    let (lo, hi) = if pos.is_empty() { (Vec3::ZERO, Vec3::ZERO) } else { (lo, hi) };
    let pos_bytes = pos.len() * 12;
    let idx_bytes = tris.len() * 12;
    let mut json = format!(
        concat!(
            r#"{{"asset":{{"version":"2.0","generator":"nlos-mesh"}},"scene":0,"scenes":[{{"nodes":[0]}}],"#,
            r#""nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"#,
            r#""indices":1,"mode":4}}]}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":{},"#,
            r#""type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}},{{"bufferView":1,"componentType":5125,"#,
            r#""count":{},"type":"SCALAR"}}],"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{},"#,
            r#""target":34962}},{{"buffer":0,"byteOffset":{},"byteLength":{},"target":34963}}],"#,
            r#""buffers":[{{"byteLength":{}}}]}}"#
        ),
        pos.len(),
        lo.x,
        lo.y,
        lo.z,
        hi.x,
        hi.y,
        hi.z,
        tris.len() * 3,
        pos_bytes,
        pos_bytes,
        idx_bytes,
        pos_bytes + idx_bytes
    )
    .into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let bin_len = pos_bytes + idx_bytes; // already a multiple of 4
    let total = 12 + 8 + json.len() + 8 + bin_len;
    let mut out = Vec::with_capacity(total);
    for w in [MAGIC, 2, total as u32, json.len() as u32, CHUNK_JSON] {
        out.extend_from_slice(&w.to_le_bytes());
    }
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin_len as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    for p in &pos {
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &tris {
        for &i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}

/// Reads a GLB written by [`write_glb`] (or any GLB whose first accessor holds f32 VEC3 positions and
/// second accessor u32 triangle indices, tightly packed, in the BIN chunk). Not a general glTF importer:
/// it locates the two buffer views by reading the numbers that follow `"byteOffset":` and `"count":` in
/// the JSON chunk, in the order [`write_glb`] emits them.
pub fn read_glb(bytes: &[u8], file: &str) -> Result<TriangleSoup, MeshError> {
    let err = |field: &str, msg: &str| MeshError::format(file, field, msg);
    let word = |o: usize| -> Option<u32> { bytes.get(o..o + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])) };
    if word(0) != Some(MAGIC) || word(4) != Some(2) {
        return Err(err("header", "not a glTF 2.0 binary (magic `glTF`, version 2)"));
    }
    let json_len = word(12).ok_or_else(|| err("JSON chunk", "truncated"))? as usize;
    if word(16) != Some(CHUNK_JSON) {
        return Err(err("JSON chunk", "first chunk must be JSON"));
    }
    let json = bytes.get(20..20usize.saturating_add(json_len)).ok_or_else(|| err("JSON chunk", "truncated"))?;
    let json = std::str::from_utf8(json).map_err(|_| err("JSON chunk", "not UTF-8"))?;
    let bin_at = 20 + json_len;
    let bin_len = word(bin_at).ok_or_else(|| err("BIN chunk", "missing"))? as usize;
    if word(bin_at + 4) != Some(CHUNK_BIN) {
        return Err(err("BIN chunk", "second chunk must be BIN"));
    }
    let bin =
        bytes.get(bin_at + 8..(bin_at + 8).saturating_add(bin_len)).ok_or_else(|| err("BIN chunk", "truncated"))?;
    let numbers_after = |key: &str| -> Vec<usize> {
        json.match_indices(key)
            .filter_map(|(i, _)| {
                let rest = &json[i + key.len()..];
                let end = rest.find(|c: char| !c.is_ascii_digit()).unwrap_or(rest.len());
                rest[..end].parse().ok()
            })
            .collect()
    };
    let counts = numbers_after("\"count\":");
    let offsets = numbers_after("\"byteOffset\":");
    if counts.len() < 2 || offsets.len() < 2 || !json.contains("\"componentType\":5125") {
        return Err(err("accessors", "expected f32 VEC3 positions then u32 indices (as written by write_glb)"));
    }
    let (nv, ni) = (counts[0], counts[1]);
    if ni % 3 != 0 {
        return Err(err("accessors[1].count", "index count is not a multiple of 3"));
    }
    let pos_bytes = nv.checked_mul(12).and_then(|n| offsets[0].checked_add(n));
    let idx_bytes = ni.checked_mul(4).and_then(|n| offsets[1].checked_add(n));
    match (pos_bytes, idx_bytes) {
        (Some(p), Some(i)) if p <= bin.len() && i <= bin.len() => {}
        _ => return Err(err("bufferViews", "accessor data lies outside the BIN chunk")),
    }
    let f = |o: usize| f32::from_le_bytes([bin[o], bin[o + 1], bin[o + 2], bin[o + 3]]);
    let u = |o: usize| u32::from_le_bytes([bin[o], bin[o + 1], bin[o + 2], bin[o + 3]]);
    let mut soup = TriangleSoup::default();
    for k in 0..nv {
        let o = offsets[0] + 12 * k;
        let p = Vec3::new(f(o), f(o + 4), f(o + 8));
        if !p.is_finite() {
            return Err(err(&format!("POSITION[{k}]"), "non-finite coordinate"));
        }
        soup.positions.push(p);
    }
    for k in 0..ni / 3 {
        let o = offsets[1] + 12 * k;
        let t = [u(o), u(o + 4), u(o + 8)];
        if t.iter().any(|&i| i as usize >= nv) {
            return Err(err(&format!("indices[{}]", 3 * k), "vertex index out of range"));
        }
        soup.triangles.push(t);
    }
    Ok(soup)
}
