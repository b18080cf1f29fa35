//! Discrete curvature (Meyer, Desbrun, Schröder & Barr 2003): cotangent-Laplacian mean curvature and
//! angle-deficit Gaussian curvature over mixed Voronoi areas, combined into principal curvatures.

use glam::Vec3;

use crate::surface_mesh::SurfaceMesh;

/// Per-vertex curvatures, indexed by `VertexId::idx` (zero for deleted, isolated and boundary vertices,
/// where the discrete estimators are undefined; see [`max_abs_curvature`] for a version that fills those
/// in from their neighbours).
#[derive(Debug, Clone, PartialEq)]
pub struct Curvature {
    /// Mean curvature `H` (unsigned magnitude of the mean-curvature normal, 1/m).
    pub mean: Vec<f32>,
    /// Gaussian curvature `K` (1/m²).
    pub gauss: Vec<f32>,
}

/// Computes [`Curvature`] for every vertex.
pub fn curvature(mesh: &SurfaceMesh) -> Curvature {
    let n = mesh.vertices_size();
    let mut mean = vec![0.0f32; n];
    let mut gauss = vec![0.0f32; n];
    for v in mesh.vertices() {
        if mesh.is_boundary_vertex(v) {
            continue;
        }
        let p = mesh.position(v);
        let mut lap = Vec3::ZERO;
        let mut area = 0.0f32;
        let mut angle_sum = 0.0f32;
        for h in mesh.vertex_halfedges(v) {
            let q = mesh.position(mesh.to_vertex(h));
            let r = mesh.position(mesh.to_vertex(mesh.next(h)));
            // triangle (p, q, r), corner at p
            let (a, b, c) = (q - p, r - p, r - q);
            let cross = a.cross(b).length();
            // Guard: degenerate triangles contribute nothing.
            if cross <= f32::MIN_POSITIVE {
                continue;
            }
            let cot_q = (-a).dot(c) / cross; // angle at q (opposite edge p-r)
            let cot_r = (-b).dot(-c) / cross; // angle at r (opposite edge p-q)
            lap += b * cot_q + a * cot_r;
            angle_sum += cross.atan2(a.dot(b));
            // mixed area (Meyer et al. Fig. 4)
            let tri_area = 0.5 * cross;
            let obtuse_p = a.dot(b) < 0.0;
            let obtuse_q = (-a).dot(c) < 0.0;
            let obtuse_r = (-b).dot(-c) < 0.0;
            area += if obtuse_p {
                tri_area / 2.0
            } else if obtuse_q || obtuse_r {
                tri_area / 4.0
            } else {
                (a.length_squared() * cot_r + b.length_squared() * cot_q) / 8.0
            };
        }
        if area > f32::MIN_POSITIVE {
            mean[v.idx()] = 0.25 * lap.length() / area;
            gauss[v.idx()] = (std::f32::consts::TAU - angle_sum) / area;
        }
    }
    Curvature { mean, gauss }
}

/// Largest absolute principal curvature `|H| + √max(H² − K, 0)` per vertex, with boundary and
/// degenerate vertices given the mean of their interior neighbours, then smoothed by `smoothing` passes
/// of one-ring averaging (pmp smooths its curvature the same way before deriving edge lengths).
pub fn max_abs_curvature(mesh: &SurfaceMesh, smoothing: u32) -> Vec<f32> {
    let c = curvature(mesh);
    let n = mesh.vertices_size();
    let mut k = vec![0.0f32; n];
    for v in mesh.vertices() {
        let (h, g) = (c.mean[v.idx()], c.gauss[v.idx()]);
        k[v.idx()] = h.abs() + (h * h - g).max(0.0).sqrt();
    }
    let fill: Vec<_> = mesh.vertices().filter(|&v| mesh.is_boundary_vertex(v)).collect();
    for v in fill {
        let (s, m) = mesh
            .vertex_vertices(v)
            .filter(|&w| !mesh.is_boundary_vertex(w))
            .fold((0.0, 0), |(s, m), w| (s + k[w.idx()], m + 1));
        if m > 0 {
            k[v.idx()] = s / m as f32;
        }
    }
    for _ in 0..smoothing {
        let prev = k.clone();
        for v in mesh.vertices() {
            let (s, m) = mesh.vertex_vertices(v).fold((prev[v.idx()], 1), |(s, m), w| (s + prev[w.idx()], m + 1));
            k[v.idx()] = s / m as f32;
        }
    }
    k
}
