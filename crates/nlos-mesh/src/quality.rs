//! Mesh quality statistics: angles, aspect ratios, valences, edge lengths.

use crate::surface_mesh::SurfaceMesh;

/// A histogram over `[lo, hi)` with equal bins; values outside go to the first/last bin.
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram {
    /// Lower edge of the first bin.
    pub lo: f32,
    /// Upper edge of the last bin.
    pub hi: f32,
    /// Counts per bin.
    pub counts: Vec<usize>,
}

impl Histogram {
    fn new(lo: f32, hi: f32, bins: usize, values: impl Iterator<Item = f32>) -> Self {
        let bins = bins.max(1);
        let mut counts = vec![0; bins];
        let w = hi - lo;
        for v in values {
            // Guard: a zero-width range (all values equal) puts everything in bin 0.
            let k = if w > 0.0 { (((v - lo) / w) * bins as f32).floor() } else { 0.0 };
            counts[(k.max(0.0) as usize).min(bins - 1)] += 1;
        }
        Self { lo, hi, counts }
    }
}

/// Quality statistics of a triangle mesh (angles in degrees).
#[derive(Debug, Clone, PartialEq)]
pub struct MeshQuality {
    /// Smallest interior angle over all faces.
    pub min_angle: f32,
    /// Largest interior angle over all faces.
    pub max_angle: f32,
    /// Per face, its smallest angle (in `faces()` order).
    pub face_min_angles: Vec<f32>,
    /// Largest aspect ratio (longest edge over the shortest altitude · √3/2, 1 for equilateral triangles,
    /// infinite for degenerate ones).
    pub max_aspect_ratio: f32,
    /// Mean aspect ratio.
    pub mean_aspect_ratio: f64,
    /// Number of zero-area faces.
    pub degenerate_faces: usize,
    /// `valence_histogram[k]` = number of vertices with `k` edges (the last entry collects ≥ its index).
    pub valence_histogram: Vec<usize>,
    /// Edge-length histogram over `[0, 2·mean)` in 20 bins.
    pub edge_length_histogram: Histogram,
    /// Shortest edge.
    pub min_edge_length: f32,
    /// Longest edge.
    pub max_edge_length: f32,
    /// Mean edge length.
    pub mean_edge_length: f32,
}

impl MeshQuality {
    /// Fraction of faces whose smallest angle is at least `degrees`.
    pub fn fraction_min_angle_at_least(&self, degrees: f32) -> f64 {
        let n = self.face_min_angles.len().max(1);
        self.face_min_angles.iter().filter(|&&a| a >= degrees).count() as f64 / n as f64
    }
}

/// Interior angles (degrees) of the triangle `(a, b, c)`.
pub fn triangle_angles(a: glam::Vec3, b: glam::Vec3, c: glam::Vec3) -> [f32; 3] {
    let ang = |p: glam::Vec3, q: glam::Vec3, r: glam::Vec3| {
        let (u, v) = ((q - p).as_dvec3(), (r - p).as_dvec3());
        // atan2 of |u×v| and u·v is accurate for small and large angles alike
        u.cross(v).length().atan2(u.dot(v)).to_degrees() as f32
    };
    [ang(a, b, c), ang(b, c, a), ang(c, a, b)]
}

/// Computes [`MeshQuality`] over the live elements.
pub fn mesh_quality(mesh: &SurfaceMesh) -> MeshQuality {
    let mut min_angle = f32::INFINITY;
    let mut max_angle = 0.0f32;
    let mut face_min_angles = Vec::with_capacity(mesh.n_faces());
    let mut max_ar = 0.0f32;
    let mut sum_ar = 0.0f64;
    let mut degenerate = 0;
    for f in mesh.faces() {
        let [a, b, c] = mesh.face_points(f);
        let ang = triangle_angles(a, b, c);
        let mn = ang[0].min(ang[1]).min(ang[2]);
        let mx = ang[0].max(ang[1]).max(ang[2]);
        min_angle = min_angle.min(mn);
        max_angle = max_angle.max(mx);
        face_min_angles.push(mn);
        let lmax = a.distance(b).max(b.distance(c)).max(c.distance(a));
        let area2 = (b - a).cross(c - a).length();
        let ar = if area2 > 0.0 {
            // shortest altitude = 2·area / longest edge; normalised so equilateral = 1
            let h = area2 / lmax;
            lmax / h * (3f32.sqrt() / 2.0)
        } else {
            degenerate += 1;
            f32::INFINITY
        };
        max_ar = max_ar.max(ar);
        if ar.is_finite() {
            sum_ar += ar as f64;
        }
    }
    let mut valence_histogram = vec![0usize; 16];
    for v in mesh.vertices() {
        let k = mesh.valence(v).min(15);
        valence_histogram[k] += 1;
    }
    let lengths: Vec<f32> = mesh.edges().map(|e| mesh.edge_length(e)).collect();
    let mean = if lengths.is_empty() { 0.0 } else { lengths.iter().sum::<f32>() / lengths.len() as f32 };
    let edge_length_histogram = Histogram::new(0.0, 2.0 * mean, 20, lengths.iter().copied());
    let nf = (mesh.n_faces() - degenerate).max(1);
    MeshQuality {
        min_angle: if min_angle.is_finite() { min_angle } else { 0.0 },
        max_angle,
        face_min_angles,
        max_aspect_ratio: max_ar,
        mean_aspect_ratio: sum_ar / nf as f64,
        degenerate_faces: degenerate,
        valence_histogram,
        edge_length_histogram,
        min_edge_length: lengths.iter().copied().fold(f32::INFINITY, f32::min),
        max_edge_length: lengths.iter().copied().fold(0.0, f32::max),
        mean_edge_length: mean,
    }
}
