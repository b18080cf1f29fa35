//! Stanford PLY: ASCII, binary little-endian and binary big-endian reading; ASCII and binary
//! little-endian writing. Written here (no dependency): the subset a triangle mesh needs, parsed with
//! bounded allocations.

use std::fmt::Write as _;

use glam::Vec3;

use super::TriangleSoup;
use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

/// PLY body encoding for [`write_ply`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyEncoding {
    /// Human-readable; floats written with the shortest decimal that reads back exactly.
    Ascii,
    /// `binary_little_endian 1.0`: `float` x, y, z and `list uchar int vertex_indices`.
    BinaryLittleEndian,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar(String, Scalar),
    List(String, Scalar, Scalar),
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Le,
    Be,
}

/// Parses PLY bytes. Needs a `vertex` element with `x`, `y`, `z` (any numeric type) and reads a `face`
/// element's `vertex_indices` (or `vertex_index`) list, fan-triangulating polygons; other elements and
/// properties are skipped.
pub fn read_ply(bytes: &[u8], file: &str) -> Result<TriangleSoup, MeshError> {
    let err = |field: &str, msg: &str| MeshError::format(file, field, msg);
    // --- header --------------------------------------------------------------------------------------------
    let end = find(bytes, b"end_header").ok_or_else(|| err("header", "no `end_header` line; not a PLY file?"))?;
    let mut body = end + b"end_header".len();
    // the header ends with "\n" or "\r\n"
    if bytes.get(body) == Some(&b'\r') {
        body += 1;
    }
    if bytes.get(body) == Some(&b'\n') {
        body += 1;
    } else if body < bytes.len() {
        return Err(err("end_header", "must be followed by a newline"));
    }
    let header = std::str::from_utf8(&bytes[..end]).map_err(|_| err("header", "header is not ASCII text"))?;
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err(err("magic", "the file must start with a `ply` line"));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            [] => {}
            ["comment" | "obj_info", ..] => {}
            ["format", f, v] => {
                if *v != "1.0" {
                    return Err(err("format", "only PLY version 1.0 is supported"));
                }
                encoding = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Le,
                    "binary_big_endian" => Encoding::Be,
                    _ => return Err(err("format", "unknown encoding; use ascii or binary_little_endian")),
                });
            }
            ["element", name, count] => {
                let count: usize =
                    count.parse().map_err(|_| err(&format!("element {name}"), "count is not a number"))?;
                elements.push(Element { name: (*name).to_owned(), count, props: Vec::new() });
            }
            ["property", "list", ct, it, name] => {
                let el = elements.last_mut().ok_or_else(|| err("property", "property before any element"))?;
                let field = format!("element {} property {name}", el.name);
                let ct = Scalar::parse(ct).ok_or_else(|| err(&field, "unknown list count type"))?;
                let it = Scalar::parse(it).ok_or_else(|| err(&field, "unknown list item type"))?;
                if matches!(ct, Scalar::F32 | Scalar::F64) {
                    return Err(err(&field, "list count type must be an integer type"));
                }
                el.props.push(Property::List((*name).to_owned(), ct, it));
            }
            ["property", ty, name] => {
                let el = elements.last_mut().ok_or_else(|| err("property", "property before any element"))?;
                let field = format!("element {} property {name}", el.name);
                let ty = Scalar::parse(ty).ok_or_else(|| err(&field, "unknown property type"))?;
                el.props.push(Property::Scalar((*name).to_owned(), ty));
            }
            _ => return Err(err("header", &format!("cannot parse header line {line:?}"))),
        }
    }
    let encoding = encoding.ok_or_else(|| err("format", "missing `format` line"))?;
    if !elements.iter().any(|e| e.name == "vertex") {
        return Err(err("element vertex", "missing; a mesh needs vertices"));
    }
    let data = &bytes[body..];
    // Bound every count by the data size: each element takes at least one byte (ASCII: one digit; binary:
    // its fixed-size part, or one byte for an empty property list).
    for el in &elements {
        let min = match encoding {
            Encoding::Ascii => 1,
            _ => el
                .props
                .iter()
                .map(|p| match p {
                    Property::Scalar(_, t) => t.size(),
                    Property::List(_, c, _) => c.size(),
                })
                .sum::<usize>()
                .max(1),
        };
        if el.count > data.len() / min {
            return Err(err(
                &format!("element {}", el.name),
                &format!("count {} exceeds what the {} data bytes can hold; file truncated?", el.count, data.len()),
            ));
        }
    }

    let mut cur = Cursor { data, pos: 0, encoding, file };
    let mut soup = TriangleSoup::default();
    for el in &elements {
        if el.name == "vertex" {
            let idx = |n: &str| el.props.iter().position(|p| matches!(p, Property::Scalar(m, _) if m == n));
            let (Some(ix), Some(iy), Some(iz)) = (idx("x"), idx("y"), idx("z")) else {
                return Err(err("element vertex", "needs scalar properties x, y and z"));
            };
            let (ia, is) = (idx("albedo"), idx("support"));
            soup.positions.reserve(el.count);
            let mut albedo = Vec::with_capacity(if ia.is_some() { el.count } else { 0 });
            let mut support = Vec::with_capacity(if is.is_some() { el.count } else { 0 });
            let mut vals = vec![0f64; el.props.len()];
            for vi in 0..el.count {
                for (k, p) in el.props.iter().enumerate() {
                    match p {
                        Property::Scalar(_, t) => vals[k] = cur.scalar(*t, "vertex")?,
                        Property::List(_, c, t) => {
                            cur.skip_list(*c, *t, "vertex")?;
                        }
                    }
                }
                let p = Vec3::new(vals[ix] as f32, vals[iy] as f32, vals[iz] as f32);
                if !p.is_finite() {
                    return Err(err(&format!("vertex {vi}"), "non-finite coordinate"));
                }
                soup.positions.push(p);
                if let Some(ia) = ia {
                    let a = vals[ia] as f32;
                    if !(a.is_finite() && a >= 0.0) {
                        return Err(err(&format!("vertex {vi} albedo"), "not a finite value >= 0"));
                    }
                    albedo.push(a);
                }
                if let Some(is) = is {
                    let v = vals[is] as f32;
                    if !v.is_finite() {
                        return Err(err(&format!("vertex {vi} support"), "not a finite value"));
                    }
                    support.push(v);
                }
            }
            soup.albedo = ia.map(|_| albedo);
            soup.support = is.map(|_| support);
        } else if el.name == "face" {
            let list = el
                .props
                .iter()
                .position(|p| matches!(p, Property::List(n, _, _) if n == "vertex_indices" || n == "vertex_index"));
            let Some(list) = list else {
                return Err(err("element face", "needs a `vertex_indices` list property"));
            };
            soup.triangles.reserve(el.count);
            let mut poly: Vec<u32> = Vec::new();
            for fi in 0..el.count {
                for (k, p) in el.props.iter().enumerate() {
                    match p {
                        Property::List(_, c, t) if k == list => {
                            let n = cur.count(*c, "face")?;
                            poly.clear();
                            for _ in 0..n {
                                let x = cur.scalar(*t, "face")?;
                                if !(x >= 0.0 && x < u32::MAX as f64 && x.fract() == 0.0) {
                                    return Err(err(&format!("face {fi}"), "vertex index is not a valid integer"));
                                }
                                poly.push(x as u32);
                            }
                        }
                        Property::List(_, c, t) => cur.skip_list(*c, *t, "face")?,
                        Property::Scalar(_, t) => {
                            cur.scalar(*t, "face")?;
                        }
                    }
                }
                if poly.len() < 3 {
                    return Err(err(&format!("face {fi}"), "has fewer than 3 vertices"));
                }
                for k in 1..poly.len() - 1 {
                    soup.triangles.push([poly[0], poly[k], poly[k + 1]]);
                }
            }
        } else {
            for _ in 0..el.count {
                for p in &el.props {
                    match p {
                        Property::Scalar(_, t) => {
                            cur.scalar(*t, &el.name)?;
                        }
                        Property::List(_, c, t) => cur.skip_list(*c, *t, &el.name)?,
                    }
                }
            }
        }
    }
    let n = soup.positions.len();
    for (fi, t) in soup.triangles.iter().enumerate() {
        if t.iter().any(|&i| i as usize >= n) {
            return Err(err(&format!("face {fi}"), &format!("vertex index out of range (there are {n} vertices)")));
        }
    }
    Ok(soup)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
    encoding: Encoding,
    file: &'a str,
}

impl Cursor<'_> {
    fn truncated(&self, what: &str) -> MeshError {
        MeshError::format(self.file, format!("element {what}"), "data ends early; the file is truncated")
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], MeshError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len()).ok_or_else(|| self.truncated(what))?;
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn token(&mut self, what: &str) -> Result<&str, MeshError> {
        while self.pos < self.data.len() && self.data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < self.data.len() && !self.data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(self.truncated(what));
        }
        std::str::from_utf8(&self.data[start..self.pos])
            .map_err(|_| MeshError::format(self.file, format!("element {what}"), "non-ASCII number"))
    }

    fn scalar(&mut self, t: Scalar, what: &str) -> Result<f64, MeshError> {
        if self.encoding == Encoding::Ascii {
            let file = self.file;
            let tok = self.token(what)?;
            return tok
                .parse::<f64>()
                .map_err(|_| MeshError::format(file, format!("element {what}"), format!("{tok:?} is not a number")));
        }
        let le = self.encoding == Encoding::Le;
        let b = self.take(t.size(), what)?;
        macro_rules! rd {
            ($ty:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(b);
                if le { <$ty>::from_le_bytes(a) as f64 } else { <$ty>::from_be_bytes(a) as f64 }
            }};
        }
        Ok(match t {
            Scalar::I8 => rd!(i8, 1),
            Scalar::U8 => rd!(u8, 1),
            Scalar::I16 => rd!(i16, 2),
            Scalar::U16 => rd!(u16, 2),
            Scalar::I32 => rd!(i32, 4),
            Scalar::U32 => rd!(u32, 4),
            Scalar::F32 => rd!(f32, 4),
            Scalar::F64 => rd!(f64, 8),
        })
    }

    fn count(&mut self, t: Scalar, what: &str) -> Result<usize, MeshError> {
        let x = self.scalar(t, what)?;
        // Bound: a list cannot have more items than there are bytes left.
        if !(x >= 0.0 && x.fract() == 0.0 && x <= (self.data.len() - self.pos) as f64) {
            return Err(MeshError::format(self.file, format!("element {what}"), "invalid list length"));
        }
        Ok(x as usize)
    }

    fn skip_list(&mut self, c: Scalar, t: Scalar, what: &str) -> Result<(), MeshError> {
        let n = self.count(c, what)?;
        for _ in 0..n {
            self.scalar(t, what)?;
        }
        Ok(())
    }
}

/// Writes the live vertices and faces as PLY (`float` x, y, z; `list uchar int vertex_indices`).
/// Reading it back gives bit-identical positions and the same triangles.
pub fn write_ply(mesh: &SurfaceMesh, encoding: PlyEncoding) -> Vec<u8> {
    let (pos, tris) = mesh.to_triangles();
    ply_bytes(&pos, &tris, &PlyVertexFields::default(), encoding)
}

/// Per-vertex values that [`write_ply_with`] writes beside the positions, each one value per vertex of
/// `mesh.to_triangles()`, in its order.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PlyVertexFields<'a> {
    /// The `float` property `albedo` (finite, ≥ 0), with `uchar` red, green and blue: the albedo as grey
    /// scaled so that the largest is white (what MeshLab and Blender show). Read back by [`read_ply`] into
    /// [`super::TriangleSoup::albedo`].
    pub albedo: Option<&'a [f32]>,
    /// The `float` property `support` (finite, in [−1, 1]): how much of their light the data confirm
    /// (`nlos_optim::support`). Read back into [`super::TriangleSoup::support`].
    pub support: Option<&'a [f32]>,
}

/// [`write_ply`] with a per-vertex albedo ([`write_ply_with`] with [`PlyVertexFields::albedo`] alone).
///
/// # Errors
/// As [`write_ply_with`].
pub fn write_ply_with_albedo(mesh: &SurfaceMesh, albedo: &[f32], encoding: PlyEncoding) -> Result<Vec<u8>, MeshError> {
    write_ply_with(mesh, &PlyVertexFields { albedo: Some(albedo), support: None }, encoding)
}

/// [`write_ply`] with the per-vertex values of `fields` as vertex properties.
///
/// # Errors
/// [`MeshError::InvalidParameter`] naming the field when it is not one value per vertex, or holds a value
/// outside its range (its value: the length, or the first bad value).
pub fn write_ply_with(
    mesh: &SurfaceMesh,
    fields: &PlyVertexFields<'_>,
    encoding: PlyEncoding,
) -> Result<Vec<u8>, MeshError> {
    let (pos, tris) = mesh.to_triangles();
    type Valid = fn(f32) -> bool;
    let checks: [(&'static str, Option<&[f32]>, Valid, &'static str); 2] = [
        ("albedo", fields.albedo, |a| a.is_finite() && a >= 0.0, "an albedo is a finite value >= 0"),
        ("support", fields.support, |s| (-1.0..=1.0).contains(&s), "a support is a value in [-1, 1]"),
    ];
    for (name, values, valid, range) in checks {
        let Some(values) = values else { continue };
        let bad = |value: f64, reason| Err(MeshError::InvalidParameter { name, value, reason });
        if values.len() != pos.len() {
            return bad(values.len() as f64, "one value per vertex of the mesh, in the order of its triangles' list");
        }
        if let Some(v) = values.iter().find(|&&v| !valid(v)) {
            return bad(f64::from(*v), range);
        }
    }
    Ok(ply_bytes(&pos, &tris, fields, encoding))
}

/// The PLY file of `pos` and `tris`, with `fields` (checked by the caller) as properties, the albedo also as
/// grey colours.
fn ply_bytes(pos: &[Vec3], tris: &[[u32; 3]], fields: &PlyVertexFields<'_>, encoding: PlyEncoding) -> Vec<u8> {
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
    };
    let (albedo, support) = (fields.albedo, fields.support);
    let mut extra = String::new();
    if albedo.is_some() {
        extra.push_str("property float albedo\n");
    }
    if support.is_some() {
        extra.push_str("property float support\n");
    }
    if albedo.is_some() {
        extra.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment nlos-mesh\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\n{extra}element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        pos.len(),
        tris.len()
    )
    .into_bytes();
    let top = albedo.map_or(0.0, |a| a.iter().fold(0.0f32, |m, &x| m.max(x)));
    let grey = |a: f32| if top > 0.0 { (255.0 * a / top).round().clamp(0.0, 255.0) as u8 } else { 0 };
    match encoding {
        PlyEncoding::Ascii => {
            let mut s = String::with_capacity(pos.len() * 36 + tris.len() * 24);
            for (i, p) in pos.iter().enumerate() {
                let _ = write!(s, "{} {} {}", p.x, p.y, p.z);
                if let Some(a) = albedo {
                    let _ = write!(s, " {}", a[i]);
                }
                if let Some(v) = support {
                    let _ = write!(s, " {}", v[i]);
                }
                if let Some(a) = albedo {
                    let g = grey(a[i]);
                    let _ = write!(s, " {g} {g} {g}");
                }
                s.push('\n');
            }
            for t in tris {
                let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
            }
            out.extend_from_slice(s.as_bytes());
        }
        PlyEncoding::BinaryLittleEndian => {
            out.reserve(pos.len() * 19 + tris.len() * 13);
            for (i, p) in pos.iter().enumerate() {
                for c in p.to_array() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
                if let Some(a) = albedo {
                    out.extend_from_slice(&a[i].to_le_bytes());
                }
                if let Some(v) = support {
                    out.extend_from_slice(&v[i].to_le_bytes());
                }
                if let Some(a) = albedo {
                    out.extend_from_slice(&[grey(a[i]); 3]);
                }
            }
            for t in tris {
                out.push(3);
                for &i in t {
                    out.extend_from_slice(&(i as i32).to_le_bytes());
                }
            }
        }
    }
    out
}
