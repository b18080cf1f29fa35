//! # nlos-mesh
//!
//! The surface representation of the `nlos` reconstruction (Tsai, Sankaranarayanan & Gkioulekas,
//! CVPR 2019): a half-edge triangle mesh with boundary in the design of pmp-library's `SurfaceMesh`
//! (Sieger & Botsch), with construction from indexed triangles, procedural shapes and topological
//! operations that keep it manifold.
//!
//! ```
//! use glam::Vec3;
//! use nlos_mesh::{shapes, SurfaceMesh};
//! let mut mesh = shapes::icosphere(Vec3::ZERO, 1.0, 2);
//! assert_eq!(mesh.n_faces(), 320);
//! let e = mesh.edges().next().expect("has edges");
//! let mid = (mesh.position(mesh.edge_vertices(e)[0]) + mesh.position(mesh.edge_vertices(e)[1])) * 0.5;
//! mesh.split_edge(e, mid);
//! mesh.validate()?;
//! let (positions, triangles) = mesh.to_triangles();
//! let again = SurfaceMesh::from_triangles(&positions, &triangles)?;
//! assert_eq!(again.n_faces(), 322);
//! # Ok::<(), nlos_mesh::MeshError>(())
//! ```
//!
//! ## Conventions
//! Triangles are counter-clockwise seen from the side their normal points to. Positions are `f32`
//! metres (the workspace convention). Handles are `u32` indices with an invalid sentinel; deletion marks
//! and [`SurfaceMesh::garbage_collect`] compacts.
#![warn(missing_docs)]

mod analysis;
mod build;
pub mod bvh;
pub mod curvature;
pub mod distance;
mod error;
mod handles;
pub mod intersect;
pub mod io;
mod property;
pub mod quality;
pub mod remeshing;
pub mod shapes;
mod surface_mesh;

pub use analysis::triangle_normal_raw;
pub use build::{BuildOptions, orient_triangles};
pub use bvh::{ClosestPoint, TriangleBvh};
pub use error::MeshError;
pub use handles::{EdgeId, FaceId, HalfedgeId, VertexId};
pub use property::{EdgeProperty, FaceProperty, VertexProperty};
pub use surface_mesh::{IndexRemap, SurfaceMesh, VertexHalfedges};
