//! # nlos-mesh
//!
//! The surface representation of the `nlos` reconstruction (Tsai, Sankaranarayanan & Gkioulekas,
//! CVPR 2019): a half-edge triangle mesh with boundary in the design of pmp-library's `SurfaceMesh`
//! (Sieger & Botsch), and what the pipeline does with it: read and write it, remesh it isotropically
//! (Botsch & Kobbelt 2004) after the optimiser has moved its vertices, and measure it.
//!
//! | module | what |
//! |---|---|
//! | [`SurfaceMesh`] | connectivity, check/mutate operations, deletion, validation, construction |
//! | | ([`SurfaceMesh::from_triangles_with`], [`orient_triangles`]), normals, boundary loops, components |
//! | [`shapes`] | icosphere, open cone, plane grid, height field |
//! | [`io`] | OBJ and PLY read/write, GLB export, content-based [`io::load`], atomic [`io::save`] |
//! | [`remeshing`] | [`remeshing::uniform_remeshing`], [`remeshing::adaptive_remeshing`], presets |
//! | [`bvh`], [`distance`] | closest point on a mesh, point-to-mesh, Chamfer/Hausdorff, normal angular error |
//! | [`intersect`] | exact triangle–triangle test, [`intersect::self_intersections`] |
//! | [`quality`], [`curvature`] | angle/aspect/valence/edge-length statistics; discrete curvatures |
//!
//! ```
//! use glam::Vec3;
//! use nlos_mesh::{SurfaceMesh, remeshing, shapes};
//! let mut mesh = shapes::icosphere(Vec3::ZERO, 1.0, 2);
//! assert_eq!(mesh.n_faces(), 320);
//! let e = mesh.edges().next().expect("has edges");
//! let mid = (mesh.position(mesh.edge_vertices(e)[0]) + mesh.position(mesh.edge_vertices(e)[1])) * 0.5;
//! mesh.split_edge(e, mid);
//! mesh.validate()?;
//! remeshing::uniform_remeshing(&mut mesh, 0.3, &remeshing::RemeshParams::pmp())?;
//! mesh.validate()?;
//! let (positions, triangles) = mesh.to_triangles();
//! let again = SurfaceMesh::from_triangles(&positions, &triangles)?;
//! assert_eq!(again.n_faces(), mesh.n_faces());
//! # Ok::<(), nlos_mesh::MeshError>(())
//! ```
//!
//! ## Conventions
//! Triangles are counter-clockwise seen from the side their normal points to. Positions are `f32`
//! metres (the workspace convention). Handles are `u32` indices with an invalid sentinel; deletion marks
//! and [`SurfaceMesh::garbage_collect`] compacts. Every fallible function returns [`MeshError`]; no
//! function panics on bad input (non-manifold or NaN input is rejected at construction or by
//! [`SurfaceMesh::validate`]).
//!
//! ## Why these dependencies
//! `obvhs` builds the BVH (PLOC; the renderer uses it too), `robust` gives exact orientation predicates
//! for the self-intersection test, `rayon` parallelises the remesher's projection queries. OBJ and PLY
//! are parsed here (`tobj` renumbers vertices, which breaks exact round trips) and GLB is written here;
//! `gltf` is a dev-dependency that checks the exported files.
#![warn(missing_docs)]

mod analysis;
mod build;
pub mod bvh;
pub mod curvature;
pub mod distance;
mod error;
pub mod evolve;
mod handles;
pub mod intersect;
pub mod io;
pub mod map_metrics;
pub mod metrics;
pub mod quality;
pub mod remeshing;
pub mod shapes;
mod surface_mesh;
mod union_find;

pub use analysis::triangle_normal_raw;
pub use build::{BuildOptions, orient_triangles};
pub use bvh::{ClosestPoint, TriangleBvh};
pub use error::MeshError;
pub use handles::{EdgeId, FaceId, HalfedgeId, VertexId};
pub use metrics::{EvalParams, Metrics, evaluate};
pub use surface_mesh::{IndexRemap, SurfaceMesh, VertexHalfedges};
pub use union_find::UnionFind;
