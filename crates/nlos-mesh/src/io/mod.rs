//! Mesh files: OBJ (read through `tobj`, written here), PLY (ASCII and binary, read and written here) and
//! GLB export (glTF 2.0 binary container, written here).
//!
//! Readers take bytes plus a file name (used only in messages) so they can be fuzzed; writers return
//! bytes. [`load`] and [`save`] add the file system: `load` detects the format from the content (PLY and
//! GLB by their magic, anything else is parsed as OBJ), `save` picks it from the extension and writes
//! atomically (temporary file + rename). Every reader returns a [`MeshError`] on malformed input and
//! never panics; allocations are bounded by the input size.

mod glb;
mod obj;
mod ply;

use std::path::Path;

pub use glb::{read_glb, write_glb};
pub use obj::{read_obj, write_obj};
pub use ply::{PlyEncoding, PlyVertexFields, read_ply, write_ply, write_ply_with, write_ply_with_albedo};

use crate::build::BuildOptions;
use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

/// Indexed triangles as read from a file, before half-edge construction (so that callers can repair
/// them, e.g. with [`crate::orient_triangles`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleSoup {
    /// Vertex positions.
    pub positions: Vec<glam::Vec3>,
    /// Triangles (polygons are fan-triangulated by the readers).
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex albedo, where the file has it (PLY's vertex property `albedo`, as
    /// [`write_ply_with_albedo`] writes it).
    pub albedo: Option<Vec<f32>>,
    /// Per-vertex support (how much of their light the data confirm), where the file has it (PLY's vertex
    /// property `support`, as [`write_ply_with`] writes it).
    pub support: Option<Vec<f32>>,
}

impl TriangleSoup {
    /// Builds the half-edge mesh (see [`SurfaceMesh::from_triangles_with`]).
    pub fn into_mesh(self, options: BuildOptions) -> Result<SurfaceMesh, MeshError> {
        SurfaceMesh::from_triangles_with(&self.positions, &self.triangles, options)
    }
}

/// Reads a mesh file of any supported format, detected from its content, and builds the half-edge mesh
/// with default [`BuildOptions`].
pub fn load(path: impl AsRef<Path>) -> Result<SurfaceMesh, MeshError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| MeshError::Io { file: path.to_owned(), source })?;
    read_any(&bytes, &path.display().to_string())?.into_mesh(BuildOptions::default())
}

/// Parses bytes of any supported format (detected from the content) into a triangle soup.
pub fn read_any(bytes: &[u8], file: &str) -> Result<TriangleSoup, MeshError> {
    if bytes.starts_with(b"ply") {
        read_ply(bytes, file)
    } else if bytes.starts_with(b"glTF") {
        read_glb(bytes, file)
    } else {
        read_obj(bytes, file)
    }
}

/// The lower-case extension of `path` when [`save`] can write it: `obj`, `ply` (binary little-endian PLY) or
/// `glb`. Check it before the work that makes the mesh.
///
/// # Errors
/// [`MeshError::Format`] naming the file for any other extension.
pub fn check_save_extension(path: &Path) -> Result<String, MeshError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    if matches!(ext.as_str(), "obj" | "ply" | "glb") {
        Ok(ext)
    } else {
        Err(MeshError::format(
            &path.display().to_string(),
            "extension",
            "unknown mesh extension; use .obj, .ply or .glb",
        ))
    }
}

/// Writes `mesh` to `path` in the format named by the extension ([`check_save_extension`]), atomically.
///
/// # Errors
/// As [`check_save_extension`]; [`MeshError::Io`] when the file cannot be written.
pub fn save(mesh: &SurfaceMesh, path: impl AsRef<Path>) -> Result<(), MeshError> {
    let path = path.as_ref();
    let ext = check_save_extension(path)?;
    let bytes = match ext.as_str() {
        "ply" => write_ply(mesh, PlyEncoding::BinaryLittleEndian),
        "glb" => write_glb(mesh),
        _ => write_obj(mesh),
    };
    write_atomically(path, &bytes)
}

/// Writes `mesh` with a per-vertex albedo to the binary PLY file `path`, atomically ([`write_ply_with_albedo`]:
/// the float property `albedo` and grey vertex colours for viewers).
///
/// # Errors
/// [`MeshError::Format`] for a path not ending in `.ply`, [`MeshError::InvalidParameter`] for an `albedo` not
/// one finite value ≥ 0 per vertex of `mesh.to_triangles()`, [`MeshError::Io`] when the file cannot be written.
pub fn save_ply_with_albedo(mesh: &SurfaceMesh, albedo: &[f32], path: impl AsRef<Path>) -> Result<(), MeshError> {
    save_ply_with(mesh, &PlyVertexFields { albedo: Some(albedo), support: None }, path)
}

/// Writes `mesh` with the per-vertex values of `fields` to the binary PLY file `path`, atomically
/// ([`write_ply_with`]); without any, as [`save`] writes a `.ply`.
///
/// # Errors
/// [`MeshError::Format`] for a path not ending in `.ply`, [`MeshError::InvalidParameter`] for a field not
/// one valid value per vertex of `mesh.to_triangles()`, [`MeshError::Io`] when the file cannot be written.
pub fn save_ply_with(
    mesh: &SurfaceMesh,
    fields: &PlyVertexFields<'_>,
    path: impl AsRef<Path>,
) -> Result<(), MeshError> {
    let path = path.as_ref();
    let ext = check_save_extension(path)?;
    if ext != "ply" {
        return Err(MeshError::format(
            &path.display().to_string(),
            "extension",
            "vertex fields are written to .ply only",
        ));
    }
    let bytes = write_ply_with(mesh, fields, PlyEncoding::BinaryLittleEndian)?;
    write_atomically(path, &bytes)
}

/// Writes `bytes` to `path` atomically through `atomic_write_file` (as every crate of the workspace: a uniquely
/// named temporary file beside it, synced, renamed over `path`; two writers of one file no longer share a
/// temporary name).
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), MeshError> {
    use std::io::Write as _;
    let io = |source| MeshError::Io { file: path.to_owned(), source };
    let mut file = atomic_write_file::AtomicWriteFile::open(path).map_err(io)?;
    file.write_all(bytes).map_err(io)?;
    file.commit().map_err(io)
}
