//! Distances between meshes: point-to-mesh, symmetric Chamfer and Hausdorff, normal angular error.
//!
//! Both directions are measured from sample points of one surface to the other *surface* (closest point
//! on any triangle, through [`TriangleBvh`]), not to its vertices. The samples are the vertices plus,
//! optionally, a regular barycentric lattice on every face ([`Sampling`]), so the reported Hausdorff
//! distance is a lower bound of the true one that tightens as the lattice refines.

use glam::Vec3;

use crate::bvh::TriangleBvh;
use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

/// Which points of a surface are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sampling {
    /// The live vertices only.
    #[default]
    Vertices,
    /// The vertices plus the interior and edge points of the `n`-th barycentric lattice on each face
    /// (`n ≥ 1`; `n = 1` adds nothing, `n = 2` adds edge midpoints, `n = 3` adds face centroids …).
    Lattice(u32),
}

/// Distances between surfaces `a` and `b` (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshDistance {
    /// Mean distance from the samples of `a` to surface `b`.
    pub mean_a_to_b: f64,
    /// Mean distance from the samples of `b` to surface `a`.
    pub mean_b_to_a: f64,
    /// Largest distance from a sample of `a` to surface `b`.
    pub max_a_to_b: f32,
    /// Largest distance from a sample of `b` to surface `a`.
    pub max_b_to_a: f32,
    /// Symmetric Chamfer distance: `mean_a_to_b + mean_b_to_a`.
    pub chamfer: f64,
    /// Symmetric Hausdorff distance: `max(max_a_to_b, max_b_to_a)`.
    pub hausdorff: f32,
}

/// Sample points of `mesh` per [`Sampling`].
pub fn sample_points(mesh: &SurfaceMesh, sampling: Sampling) -> Vec<Vec3> {
    let mut pts: Vec<Vec3> = mesh.vertices().map(|v| mesh.position(v)).collect();
    if let Sampling::Lattice(n) = sampling {
        let n = n.clamp(1, 64);
        for f in mesh.faces() {
            let [a, b, c] = mesh.face_points(f);
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let k = n - i - j;
                    // corners are vertices, already included; edge points are shared by two faces but
                    // including them twice only repeats a sample.
                    if i == n || j == n || k == n {
                        continue;
                    }
                    pts.push((a * i as f32 + b * j as f32 + c * k as f32) / n as f32);
                }
            }
        }
    }
    pts
}

/// Distance from every point to the surface in `target`.
pub fn point_distances(points: &[Vec3], target: &TriangleBvh) -> Vec<f32> {
    points.iter().map(|&p| target.closest_point(p).distance()).collect()
}

/// Distance from `p` to the surface of `mesh` (builds a BVH; reuse a [`TriangleBvh`] for many queries).
pub fn point_to_mesh_distance(p: Vec3, mesh: &SurfaceMesh) -> Result<f32, MeshError> {
    Ok(TriangleBvh::from_mesh(mesh)?.closest_point(p).distance())
}

/// Symmetric Chamfer and Hausdorff distances between the surfaces of `a` and `b`. Errors if either mesh
/// has no faces.
pub fn mesh_distance(a: &SurfaceMesh, b: &SurfaceMesh, sampling: Sampling) -> Result<MeshDistance, MeshError> {
    let ba = TriangleBvh::from_mesh(a)?;
    let bb = TriangleBvh::from_mesh(b)?;
    let da = point_distances(&sample_points(a, sampling), &bb);
    let db = point_distances(&sample_points(b, sampling), &ba);
    let mean = |d: &[f32]| d.iter().map(|&x| x as f64).sum::<f64>() / d.len().max(1) as f64;
    let max = |d: &[f32]| d.iter().copied().fold(0.0f32, f32::max);
    let (mean_a_to_b, mean_b_to_a) = (mean(&da), mean(&db));
    let (max_a_to_b, max_b_to_a) = (max(&da), max(&db));
    Ok(MeshDistance {
        mean_a_to_b,
        mean_b_to_a,
        max_a_to_b,
        max_b_to_a,
        chamfer: mean_a_to_b + mean_b_to_a,
        hausdorff: max_a_to_b.max(max_b_to_a),
    })
}

/// Angular normal error of `estimate` against `reference`, in degrees.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalError {
    /// Per live vertex of `estimate` (in `vertices()` order): angle between its vertex normal and the
    /// normal of the closest reference face.
    pub per_vertex: Vec<f32>,
    /// Mean of `per_vertex`.
    pub mean: f64,
    /// Root mean square of `per_vertex`.
    pub rms: f64,
    /// Largest entry of `per_vertex`.
    pub max: f32,
}

/// For each vertex of `estimate`, the angle (degrees) between its angle-weighted normal and the normal of
/// the closest face of `reference`. Orientation matters (a flipped surface gives 180°). Vertices with a
/// zero normal are skipped.
pub fn normal_angular_error(estimate: &SurfaceMesh, reference: &SurfaceMesh) -> Result<NormalError, MeshError> {
    let bvh = TriangleBvh::from_mesh(reference)?;
    let mut per_vertex = Vec::with_capacity(estimate.n_vertices());
    for v in estimate.vertices() {
        let n = estimate.vertex_normal(v);
        if n == Vec3::ZERO {
            continue;
        }
        let cp = bvh.closest_point(estimate.position(v));
        let nr = reference.face_normal(bvh.face_id(cp.triangle));
        // clamp: rounding can push the cosine of unit vectors slightly outside [-1, 1]
        per_vertex.push(n.dot(nr).clamp(-1.0, 1.0).acos().to_degrees());
    }
    let k = per_vertex.len().max(1) as f64;
    let mean = per_vertex.iter().map(|&x| x as f64).sum::<f64>() / k;
    let rms = (per_vertex.iter().map(|&x| (x as f64).powi(2)).sum::<f64>() / k).sqrt();
    let max = per_vertex.iter().copied().fold(0.0f32, f32::max);
    Ok(NormalError { per_vertex, mean, rms, max })
}
