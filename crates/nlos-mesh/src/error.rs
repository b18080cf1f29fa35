//! The crate's single error type.

use std::path::PathBuf;

/// Everything that can go wrong in `nlos-mesh`. Each variant names the offending element, file or field
/// and says how to fix the input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// A triangle refers to a vertex index that does not exist.
    #[error("triangle {face} refers to vertex {index}, but there are only {vertex_count} vertices; fix the index list")]
    IndexOutOfRange {
        /// Triangle index in the input list.
        face: usize,
        /// The offending vertex index.
        index: u64,
        /// Number of vertices available.
        vertex_count: usize,
    },
    /// A triangle uses the same vertex twice.
    #[error("triangle {face} is degenerate (vertex {vertex} repeated); remove it from the index list")]
    DegenerateFace {
        /// Triangle index in the input list.
        face: usize,
        /// The repeated vertex.
        vertex: u32,
    },
    /// A vertex position is NaN or infinite.
    #[error("vertex {vertex} has a non-finite position {position:?}; fix or drop that vertex")]
    NonFinitePosition {
        /// Vertex index.
        vertex: usize,
        /// The position as read.
        position: [f32; 3],
    },
    /// More than two triangles share an edge.
    #[error(
        "edge ({v0}, {v1}) is shared by more than two triangles (non-manifold edge, at triangle {face}); \
         remove the extra triangles"
    )]
    NonManifoldEdge {
        /// First endpoint.
        v0: u32,
        /// Second endpoint.
        v1: u32,
        /// The triangle that made the edge non-manifold.
        face: usize,
    },
    /// Two triangles traverse a shared edge in the same direction.
    #[error(
        "triangles around edge ({v0}, {v1}) are inconsistently oriented (at triangle {face}); \
         call `orient_triangles` on the index list first"
    )]
    InconsistentOrientation {
        /// First endpoint.
        v0: u32,
        /// Second endpoint.
        v1: u32,
        /// The triangle whose orientation disagrees with an earlier one.
        face: usize,
    },
    /// The triangles around a vertex form more than one fan.
    #[error(
        "vertex {vertex} is non-manifold (its triangles form {fans} separate fans); \
         build with `BuildOptions {{ split_non_manifold_vertices: true }}` to duplicate it per fan"
    )]
    NonManifoldVertex {
        /// Vertex index.
        vertex: u32,
        /// Number of separate fans.
        fans: usize,
    },
    /// The mesh violates a half-edge invariant (reported by `validate`).
    #[error("mesh invariant violated: {0}; this is a bug in the operation that produced the mesh")]
    Invariant(String),
    /// The mesh has no faces where at least one is needed.
    #[error("the mesh has no faces; {what} needs a non-empty triangle mesh")]
    EmptyMesh {
        /// The operation that needed faces.
        what: &'static str,
    },
    /// A parameter is out of its valid range.
    #[error("parameter `{name}` = {value} is invalid: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What the valid range is.
        reason: &'static str,
    },
    /// [`crate::evolve::evolve`]: the displacement slice does not have one entry per vertex slot.
    #[error(
        "got {got} displacements for a mesh with {expected} vertex slots; pass one per `VertexId` index \
         (`mesh.vertices_size()`, deleted slots included)"
    )]
    DisplacementCount {
        /// `mesh.vertices_size()`.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// [`crate::evolve::evolve`]: a displacement of a live vertex is NaN or infinite.
    #[error("displacement of vertex {vertex} is not finite ({value:?}); fix the gradient step")]
    NonFiniteDisplacement {
        /// Vertex index.
        vertex: usize,
        /// The value given.
        value: [f32; 3],
    },
    /// [`crate::evolve::evolve`]: the input mesh already self-intersects, so no motion can be guaranteed
    /// intersection-free.
    #[error(
        "the input mesh already self-intersects ({pairs} face pairs, first {first:?}); repair it, or set \
         `check_input: false` to evolve anyway (then only new intersections are prevented)"
    )]
    InputSelfIntersects {
        /// Number of intersecting face pairs.
        pairs: usize,
        /// The first pair.
        first: (crate::FaceId, crate::FaceId),
    },
    /// A file could not be read or written.
    #[error("{}: {source}; check the path and permissions", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A malformed or unsupported file.
    #[error("{file}: {field}: {message}")]
    Format {
        /// The file name (as given by the caller).
        file: String,
        /// The header field, element or line where the problem is.
        field: String,
        /// What is wrong and how to fix it.
        message: String,
    },
}

impl MeshError {
    /// Shorthand for [`MeshError::Format`].
    pub(crate) fn format(file: &str, field: impl Into<String>, message: impl Into<String>) -> Self {
        MeshError::Format { file: file.to_owned(), field: field.into(), message: message.into() }
    }
}
