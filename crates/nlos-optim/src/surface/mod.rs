//! The loop's surface ([`Surface`]): positions, triangles and named per-vertex and per-face fields (the
//! shape's Adam moments, and whatever a step adds), which follow every change of topology.
//!
//! **One map per change.** Every operation that changes the topology — remeshing, deleting faces (unlit,
//! pruned, self-intersecting), appending patches — produces one [`Remap`]: the new positions and triangles,
//! and for each new vertex and face where its values come from ([`Source`]: kept, interpolated from old
//! elements, or appended). [`Surface::apply`] applies it once to every field, so a field declared anywhere
//! follows every change without the operations knowing it (pmp-library's property arrays, which follow
//! `garbage_collection`; here the interpolation is part of the map because remeshing moves vertices).
//!
//! **Adding a field** is its declaration, a [`VertexField`] (or [`FaceField`]) constant with its name and
//! initial value, and its use: [`Surface::vertex_mut`] creates it on first write; values are carried by
//! [`FieldValue::blend`] of their type, stored in the checkpoint by name ([`Column`]).

use std::collections::BTreeMap;

use glam::Vec3;
use nlos_mesh::{SurfaceMesh, TriangleBvh};
use serde::{Deserialize, Serialize};

use crate::error::{OptimError, Result};

mod field;

pub use field::{Column, ColumnOf, FaceField, FieldValue, VertexField};

/// Where a new element's values come from ([`Remap`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Source {
    /// The old element of this index (renumbered).
    Kept(u32),
    /// Interpolated from old elements: `(index, weight)` pairs, the weights barycentric (≥ 0, summing to 1).
    Interpolated([(u32, f32); 3]),
    /// New: the field's initial value.
    Appended,
}

impl Source {
    /// The new element's value from `old` values; an index out of range counts as absent.
    fn value<T: FieldValue>(&self, old: &[T], initial: T) -> T {
        match *self {
            Source::Kept(j) => old.get(j as usize).copied().unwrap_or(initial),
            Source::Interpolated(w) => {
                let parts: Vec<(T, f32)> =
                    w.iter().filter_map(|&(j, wj)| old.get(j as usize).map(|&x| (x, wj))).collect();
                T::blend(&parts)
            }
            Source::Appended => initial,
        }
    }
}

/// One change of topology: the new surface's positions and triangles and, per new vertex and face, its
/// [`Source`] in the surface it was made from.
#[derive(Debug, Clone, PartialEq)]
pub struct Remap {
    /// The new positions.
    pub positions: Vec<Vec3>,
    /// The new triangles (indices into `positions`).
    pub triangles: Vec<[u32; 3]>,
    /// Where each new vertex comes from.
    pub vertices: Vec<Source>,
    /// Where each new face comes from.
    pub faces: Vec<Source>,
}

impl Remap {
    /// Keeps the triangles flagged in `keep` (in order) and the vertices they use, renumbered in order of
    /// first use.
    pub fn keep_faces(surface: &Surface, keep: &[bool]) -> Self {
        let mut new_index = vec![u32::MAX; surface.positions.len()];
        let mut vertices: Vec<Source> = Vec::new();
        let mut positions = Vec::new();
        let mut triangles = Vec::with_capacity(surface.triangles.len());
        let mut faces = Vec::with_capacity(surface.triangles.len());
        for (f, (t, _)) in surface.triangles.iter().zip(keep).enumerate().filter(|(_, (_, k))| **k) {
            let mut out = [0u32; 3];
            for (o, &v) in out.iter_mut().zip(t) {
                if new_index[v as usize] == u32::MAX {
                    new_index[v as usize] = vertices.len() as u32;
                    vertices.push(Source::Kept(v));
                    positions.push(surface.positions[v as usize]);
                }
                *o = new_index[v as usize];
            }
            triangles.push(out);
            faces.push(Source::Kept(f as u32));
        }
        Self { positions, triangles, vertices, faces }
    }

    /// Appends vertices (numbered from the current count on) and triangles (indices into the appended
    /// surface); the old elements are kept as they are, the new ones start at each field's initial value.
    pub fn append(surface: &Surface, positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let kept = |n: usize| (0..n as u32).map(Source::Kept);
        let appended = |n: usize| std::iter::repeat_n(Source::Appended, n);
        Self {
            positions: surface.positions.iter().chain(positions).copied().collect(),
            triangles: surface.triangles.iter().chain(triangles).copied().collect(),
            vertices: kept(surface.positions.len()).chain(appended(positions.len())).collect(),
            faces: kept(surface.triangles.len()).chain(appended(triangles.len())).collect(),
        }
    }

    /// A new surface `mesh` made over `surface` (remeshed): each new vertex interpolates the old face
    /// closest to it (barycentric weights of the closest point, clamped at 0), each new face takes the old
    /// face closest to its centroid (looked up only when the surface has face fields).
    ///
    /// # Errors
    /// [`OptimError::Mesh`] when the old surface has no faces to look up.
    pub fn closest(surface: &Surface, mesh: &SurfaceMesh) -> Result<Self> {
        let (positions, triangles) = mesh.to_triangles();
        let bvh = TriangleBvh::from_triangles(&surface.positions, &surface.triangles)?;
        let vertices = positions
            .iter()
            .map(|p| {
                let cp = bvh.closest_point(*p);
                let t = surface.triangles[cp.triangle as usize];
                let b = cp.barycentric;
                Source::Interpolated([(t[0], b.x.max(0.0)), (t[1], b.y.max(0.0)), (t[2], b.z.max(0.0))])
            })
            .collect();
        let faces = if surface.face_fields.is_empty() {
            vec![Source::Appended; triangles.len()]
        } else {
            triangles
                .iter()
                .map(|t| {
                    let c = (positions[t[0] as usize] + positions[t[1] as usize] + positions[t[2] as usize]) / 3.0;
                    Source::Kept(bvh.closest_point(c).triangle)
                })
                .collect()
        };
        Ok(Self { positions, triangles, vertices, faces })
    }
}

/// Positions, triangles and named per-vertex and per-face fields (module docs). Every vertex is used by a
/// face after any [`Remap`] of the loop; the surface is a manifold mesh wherever the loop builds one from
/// it ([`Surface::mesh`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Surface {
    #[serde(with = "exact_vec3")]
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    vertex_fields: BTreeMap<String, Column>,
    face_fields: BTreeMap<String, Column>,
}

impl Surface {
    /// A surface without fields.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a triangle index out of range or a non-finite position.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self> {
        let s = Self { positions, triangles, vertex_fields: BTreeMap::new(), face_fields: BTreeMap::new() };
        s.validate().map_err(|reason| OptimError::InvalidParameter { name: "surface", value: 0.0, reason })?;
        Ok(s)
    }

    /// The surface of a half-edge mesh (its vertices and faces in order), without fields.
    ///
    /// # Errors
    /// As [`Surface::new`].
    pub fn from_mesh(mesh: &SurfaceMesh) -> Result<Self> {
        let (p, t) = mesh.to_triangles();
        Self::new(p, t)
    }

    /// The half-edge mesh of the positions and triangles.
    ///
    /// # Errors
    /// [`OptimError::Mesh`] for triangles that do not make a manifold mesh.
    pub fn mesh(&self) -> Result<SurfaceMesh> {
        Ok(SurfaceMesh::from_triangles(&self.positions, &self.triangles)?)
    }

    /// Vertex positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Triangles (indices into [`Surface::positions`]).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces.
    pub fn n_faces(&self) -> usize {
        self.triangles.len()
    }

    /// Total area (m²), summed in f64.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|f| {
                let (a, b, c) =
                    (self.positions[f[0] as usize], self.positions[f[1] as usize], self.positions[f[2] as usize]);
                0.5 * f64::from((b - a).cross(c - a).length())
            })
            .sum()
    }

    /// Moves the vertices (the topology and the fields stay).
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] for another number of positions.
    pub fn set_positions(&mut self, positions: Vec<Vec3>) -> Result<()> {
        if positions.len() != self.positions.len() {
            return Err(OptimError::LengthMismatch {
                what: "positions",
                expected: self.positions.len(),
                got: positions.len(),
            });
        }
        self.positions = positions;
        Ok(())
    }

    /// Whether each vertex lies on the boundary: it is a corner of an edge that only one triangle has, or of
    /// no triangle at all (for a manifold mesh, `SurfaceMesh::is_boundary_vertex`). Derived from the
    /// triangles, so it follows every change of topology.
    pub fn boundary_vertices(&self) -> Vec<bool> {
        let mut edges: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        let mut boundary = vec![true; self.positions.len()];
        let mut used = vec![false; self.positions.len()];
        for t in &self.triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        for (b, u) in boundary.iter_mut().zip(&used) {
            *b = !*u;
        }
        for (&(a, b), &n) in &edges {
            if n == 1 {
                boundary[a as usize] = true;
                boundary[b as usize] = true;
            }
        }
        boundary
    }

    /// The values of a per-vertex field.
    ///
    /// # Errors
    /// [`OptimError::Field`] when the field was never written or holds another type.
    pub fn vertex<T: FieldValue>(&self, f: VertexField<T>) -> Result<&[T]> {
        column(&self.vertex_fields, f.name, VertexField::<T>::KIND).map(|c| c.values.as_slice())
    }

    /// The values of a per-vertex field, mutably; a field never written is created with its initial value.
    ///
    /// # Errors
    /// [`OptimError::Field`] when the name holds another type.
    pub fn vertex_mut<T: FieldValue>(&mut self, f: VertexField<T>) -> Result<&mut [T]> {
        let n = self.positions.len();
        column_mut(&mut self.vertex_fields, f.name, VertexField::<T>::KIND, f.initial, n)
    }

    /// The values of a per-face field.
    ///
    /// # Errors
    /// As [`Surface::vertex`].
    pub fn face<T: FieldValue>(&self, f: FaceField<T>) -> Result<&[T]> {
        column(&self.face_fields, f.name, FaceField::<T>::KIND).map(|c| c.values.as_slice())
    }

    /// The values of a per-face field, mutably, created with its initial value on first use.
    ///
    /// # Errors
    /// As [`Surface::vertex_mut`].
    pub fn face_mut<T: FieldValue>(&mut self, f: FaceField<T>) -> Result<&mut [T]> {
        let n = self.triangles.len();
        column_mut(&mut self.face_fields, f.name, FaceField::<T>::KIND, f.initial, n)
    }

    /// Names of the fields, per-vertex then per-face.
    pub fn field_names(&self) -> (Vec<&str>, Vec<&str>) {
        (self.vertex_fields.keys().map(String::as_str).collect(), self.face_fields.keys().map(String::as_str).collect())
    }

    /// Replaces the topology with `remap`'s and carries every field through it (module docs).
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a map whose sources do not match its elements or whose triangles
    /// index past its positions.
    pub fn apply(&mut self, remap: Remap) -> Result<()> {
        let bad = |reason| OptimError::InvalidParameter { name: "remap", value: 0.0, reason };
        if remap.vertices.len() != remap.positions.len() || remap.faces.len() != remap.triangles.len() {
            return Err(bad("one source per new vertex and face is needed"));
        }
        let n = remap.positions.len() as u32;
        if remap.triangles.iter().flatten().any(|&v| v >= n) {
            return Err(bad("a triangle indexes past the new positions"));
        }
        for c in self.vertex_fields.values_mut() {
            *c = c.remapped(&remap.vertices);
        }
        for c in self.face_fields.values_mut() {
            *c = c.remapped(&remap.faces);
        }
        self.positions = remap.positions;
        self.triangles = remap.triangles;
        Ok(())
    }

    /// What is wrong with a surface read back (a checkpoint): an index out of range, a non-finite position or
    /// value, a field of another length than its elements.
    ///
    /// # Errors
    /// The reason.
    pub fn validate(&self) -> std::result::Result<(), &'static str> {
        let n = self.positions.len() as u32;
        if self.triangles.iter().flatten().any(|&v| v >= n) {
            return Err("a triangle indexes past the positions");
        }
        if self.positions.iter().any(|p| !p.is_finite()) {
            return Err("a position is not finite");
        }
        if self.vertex_fields.values().any(|c| c.len() != self.positions.len())
            || self.face_fields.values().any(|c| c.len() != self.triangles.len())
        {
            return Err("a field has another number of values than its elements");
        }
        if !self.vertex_fields.values().chain(self.face_fields.values()).all(Column::is_finite) {
            return Err("a field holds a non-finite value");
        }
        Ok(())
    }
}

fn column<'a, T: FieldValue>(
    fields: &'a BTreeMap<String, Column>,
    name: &str,
    kind: &'static str,
) -> Result<&'a ColumnOf<T>> {
    let c = fields.get(name).ok_or_else(|| OptimError::Field {
        name: name.to_owned(),
        kind,
        reason: "it was never written".into(),
    })?;
    T::of(c).ok_or_else(|| mistyped::<T>(name, kind))
}

fn column_mut<'a, T: FieldValue>(
    fields: &'a mut BTreeMap<String, Column>,
    name: &str,
    kind: &'static str,
    initial: T,
    n: usize,
) -> Result<&'a mut [T]> {
    let c = fields.entry(name.to_owned()).or_insert_with(|| T::column(vec![initial; n], initial));
    T::of_mut(c).map(|c| c.values.as_mut_slice()).ok_or_else(|| mistyped::<T>(name, kind))
}

fn mistyped<T: FieldValue>(name: &str, kind: &'static str) -> OptimError {
    OptimError::Field { name: name.to_owned(), kind, reason: format!("it holds another type than {}", T::TYPE) }
}

/// f32 vectors stored as f64 triples: an f32 widened to f64 prints and parses back exactly (serde_json's
/// `float_roundtrip`), whereas f32 parsing goes through f64 and could round twice.
mod exact_vec3 {
    use glam::Vec3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(super) fn serialize<S: Serializer>(v: &[Vec3], s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|p| p.as_dvec3().to_array()).collect::<Vec<[f64; 3]>>().serialize(s)
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec3>, D::Error> {
        Ok(Vec::<[f64; 3]>::deserialize(d)?
            .into_iter()
            .map(|a| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32))
            .collect())
    }
}

#[cfg(test)]
mod tests;
