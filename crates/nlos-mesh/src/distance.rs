//! Distances between meshes: point-to-mesh, symmetric Chamfer and Hausdorff, normal angular error.
//!
//! Both directions are measured from sample points of one surface to the other *surface* (closest point
//! on any triangle, through [`TriangleBvh`]), not to its vertices. The samples are the vertices plus,
//! optionally, a regular barycentric lattice on every face ([`Sampling`]), so the reported Hausdorff
//! distance is a lower bound of the true one that tightens as the lattice refines. With
//! [`Sampling::Spacing`]`(s)` every point of either surface lies within `s/√3` of a sample (each lattice
//! cell is a triangle with sides at most `s`, and a triangle with longest side `s` is covered by the
//! discs of radius `s/√3` around its corners), and the distance to a surface is 1-Lipschitz, so the true
//! Hausdorff distance lies in `[hausdorff, hausdorff + s/√3]` (Metro's argument, Cignoni et al. 1998).

use glam::Vec3;
use rayon::prelude::*;

use crate::bvh::TriangleBvh;
use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

/// Which points of a surface are measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Sampling {
    /// The live vertices only.
    #[default]
    Vertices,
    /// The vertices plus the interior and edge points of the `n`-th barycentric lattice on each face
    /// (`n ≥ 1`; `n = 1` adds nothing, `n = 2` adds edge midpoints, `n = 3` adds face centroids …).
    Lattice(u32),
    /// Dense surface sampling: the vertices plus, on each face, the barycentric lattice of the smallest
    /// order `n` whose step (longest edge / `n`, capped at `n = 256`) is at most this length (metres).
    /// Surface-to-surface distances measured this way are within `spacing/√3` of the true ones (module
    /// documentation). A non-positive or non-finite spacing samples the vertices only.
    Spacing(f32),
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

/// Lattice order used on a face with corners `t` (0: no points besides the corners).
fn lattice_order(sampling: Sampling, [a, b, c]: [Vec3; 3]) -> u32 {
    match sampling {
        Sampling::Vertices => 0,
        Sampling::Lattice(n) => n.clamp(1, 64),
        Sampling::Spacing(s) if s.is_finite() && s > 0.0 => {
            let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
            // Guard: NaN (non-finite positions) saturates to 0 and is clamped to 1.
            ((longest / s).ceil() as u32).clamp(1, 256)
        }
        Sampling::Spacing(_) => 0,
    }
}

/// Calls `f` on the lattice points of order `n` of triangle `(a, b, c)` that are not corners.
#[inline]
fn for_each_lattice_point([a, b, c]: [Vec3; 3], n: u32, mut f: impl FnMut(Vec3)) {
    for i in 0..=n {
        for j in 0..=(n - i) {
            let k = n - i - j;
            // corners are vertices, already included; edge points are shared by two faces but including
            // them twice only repeats a sample.
            if i == n || j == n || k == n {
                continue;
            }
            f((a * i as f32 + b * j as f32 + c * k as f32) / n as f32);
        }
    }
}

/// Sample points of `mesh` per [`Sampling`]: the live vertices, then the lattice points face by face.
pub fn sample_points(mesh: &SurfaceMesh, sampling: Sampling) -> Vec<Vec3> {
    let mut pts: Vec<Vec3> = mesh.vertices().map(|v| mesh.position(v)).collect();
    for f in mesh.faces() {
        let t = mesh.face_points(f);
        for_each_lattice_point(t, lattice_order(sampling, t), |p| pts.push(p));
    }
    pts
}

/// (sum, count, max) of the distances from the samples of `mesh` to `target`, streamed face by face in
/// parallel so that dense samplings need no memory.
fn one_sided(mesh: &SurfaceMesh, sampling: Sampling, target: &TriangleBvh) -> (f64, usize, f32) {
    let verts: Vec<Vec3> = mesh.vertices().map(|v| mesh.position(v)).collect();
    let d = point_distances(&verts, target);
    let mut acc = (d.iter().map(|&x| x as f64).sum::<f64>(), d.len(), d.iter().copied().fold(0.0f32, f32::max));
    if sampling != Sampling::Vertices {
        let faces: Vec<[Vec3; 3]> = mesh.faces().map(|f| mesh.face_points(f)).collect();
        let lattice = faces
            .par_iter()
            .with_min_len(64)
            .map(|&t| {
                let mut a = (0.0f64, 0usize, 0.0f32);
                // The distance to a surface is 1-Lipschitz: d(p) <= d(q) + |p - q| bounds the search
                // radius around each sample by the previous one, which prunes most of the tree (the
                // result is the exact closest point either way).
                let mut prev = (t[0], target.closest_point(t[0]).distance());
                for_each_lattice_point(t, lattice_order(sampling, t), |p| {
                    let bound = (prev.1 + p.distance(prev.0)) * (1.0 + 1e-5) + 1e-12;
                    let d = target.closest_point_near(p, bound).distance();
                    prev = (p, d);
                    a = (a.0 + d as f64, a.1 + 1, a.2.max(d));
                });
                a
            })
            .reduce(|| (0.0, 0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1, x.2.max(y.2)));
        acc = (acc.0 + lattice.0, acc.1 + lattice.1, acc.2.max(lattice.2));
    }
    acc
}

/// Distance from every point to the surface in `target` (queries run in parallel).
pub fn point_distances(points: &[Vec3], target: &TriangleBvh) -> Vec<f32> {
    points.par_iter().with_min_len(1024).map(|&p| target.closest_point(p).distance()).collect()
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
    let (sa, na, max_a_to_b) = one_sided(a, sampling, &bb);
    let (sb, nb, max_b_to_a) = one_sided(b, sampling, &ba);
    let (mean_a_to_b, mean_b_to_a) = (sa / na.max(1) as f64, sb / nb.max(1) as f64);
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
    /// Per entry of `per_vertex`: the vertex's distance to the closest reference face (metres).
    pub distance: Vec<f32>,
}

/// Vertices farther than this from the reference (metres) are *far* for [`NormalError::split`]: on the
/// bunny at Tsai et al. 2019's setup they are the rims that hang back along the line of sight (up to 10 cm
/// behind the truth, off by 67° on average) and small pieces apart from the surface, while the vertices
/// within 1–3 mm are off by 7–17° (docs/accuracy.md).
pub const FAR_FROM_REFERENCE: f32 = 0.01;

impl NormalError {
    /// The mean angle (degrees) over the vertices within `within` metres of the reference and the fraction of
    /// vertices farther than that: the surface's own normals counted apart from the rims and pieces that
    /// lie off it. `None` for the mean when no vertex is that close.
    pub fn split(&self, within: f32) -> (Option<f64>, f64) {
        let (sum, near) = self
            .per_vertex
            .iter()
            .zip(&self.distance)
            .filter(|&(_, &d)| d <= within)
            .fold((0.0f64, 0usize), |(s, k), (&a, _)| (s + f64::from(a), k + 1));
        let far = (self.per_vertex.len() - near) as f64 / self.per_vertex.len().max(1) as f64;
        ((near > 0).then(|| sum / near as f64), far)
    }
}

/// For each vertex of `estimate`, the angle (degrees) between its angle-weighted normal and the normal of
/// the closest face of `reference`. Orientation matters (a flipped surface gives 180°). Vertices with a
/// zero normal are skipped.
pub fn normal_angular_error(estimate: &SurfaceMesh, reference: &SurfaceMesh) -> Result<NormalError, MeshError> {
    let bvh = TriangleBvh::from_mesh(reference)?;
    let mut per_vertex = Vec::with_capacity(estimate.n_vertices());
    let mut distance = Vec::with_capacity(estimate.n_vertices());
    for v in estimate.vertices() {
        let n = estimate.vertex_normal(v);
        if n == Vec3::ZERO {
            continue;
        }
        let cp = bvh.closest_point(estimate.position(v));
        let nr = reference.face_normal(bvh.face_id(cp.triangle));
        // clamp: rounding can push the cosine of unit vectors slightly outside [-1, 1]
        per_vertex.push(n.dot(nr).clamp(-1.0, 1.0).acos().to_degrees());
        distance.push(cp.distance_squared.sqrt());
    }
    let k = per_vertex.len().max(1) as f64;
    let mean = per_vertex.iter().map(|&x| x as f64).sum::<f64>() / k;
    let rms = (per_vertex.iter().map(|&x| (x as f64).powi(2)).sum::<f64>() / k).sqrt();
    let max = per_vertex.iter().copied().fold(0.0f32, f32::max);
    Ok(NormalError { per_vertex, mean, rms, max, distance })
}
