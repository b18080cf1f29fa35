//! Evaluation of a reconstructed surface against the ground truth (`nlos eval`).
//!
//! **Depth maps.** Rays are cast along +z, from the relay wall (z = 0) into the hidden scene, through the
//! centres of an `n × n` grid of pixels over the wall's scan area (default 128 × 128 over
//! [−0.25, 0.25]² m, Tsai et al. 2019's scan area). Pixel `(ix, iy)` has its centre at
//! `x = x₀ + (ix + ½)·(x₁ − x₀)/n`, `y = y₀ + (iy + ½)·(y₁ − y₀)/n` and is stored at `ix + n·iy` (x fastest,
//! the workspace convention). Each ray's first hit on each mesh is found through a [`TriangleBvh`] with
//! the Möller–Trumbore test [`crate::bvh::ray_triangle`] (both faces count; edge tolerance
//! [`crate::bvh::RAY_BARYCENTRIC_EPSILON`]); its depth is the hit's z. Geometry at z < 0 is never hit.
//!
//! **Coverage** = (pixels hit on both meshes) / (pixels hit on the ground truth); **coverage within 5 mm**
//! counts only the pixels whose depths also agree within [`EvalParams::coverage_threshold`]. **Depth error** =
//! |z_rec − z_gt| over the pixels hit on both: mean, median, root mean square and maximum, in metres.
//!
//! **Interior and silhouette band.** Near the ground truth's silhouette the surface turns edge-on, its depth
//! changes by centimetres within one pixel, and a reconstruction's depth there is off by far more than
//! inside (the bunny at Tsai et al. 2019's setup at 1000 photons, default fit: 5.1 mm mean over the band's 355 pixels hit on
//! both, 0.54 mm over the 1,734 interior ones; the band, a sixth of the pixels, carries two thirds of the
//! 1.32 mm mean; docs/accuracy.md). The mean depth error is therefore also given apart
//! for the *interior* pixels — ground-truth pixels whose `(2·SILHOUETTE_BAND + 1)²` neighbourhood
//! ([`SILHOUETTE_BAND`] pixels each way) lies wholly on the ground truth and inside the grid — and for the
//! rest of the ground truth's pixels, the silhouette band.
//!
//! **Surface distances** reuse [`crate::distance`]: the symmetric Chamfer distance and the Hausdorff
//! distance of [`mesh_distance`] (sampling [`EvalParams::sampling`]), and the normal angular error of
//! [`normal_angular_error`] of the reconstruction (estimate) against the ground truth (reference).
//!
//! ```
//! use glam::Vec3;
//! use nlos_mesh::metrics::{EvalParams, evaluate};
//! let mut gt = nlos_mesh::shapes::plane_grid(0.6, 0.6, 4, 4);
//! for p in gt.positions_mut() {
//!     *p += Vec3::new(-0.3, -0.3, 0.4);
//! }
//! let m = evaluate(&gt, &gt, &EvalParams::default())?;
//! assert_eq!(m.coverage, 1.0);
//! assert_eq!(m.depth_error_mean, Some(0.0));
//! # Ok::<(), nlos_mesh::MeshError>(())
//! ```

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bvh::TriangleBvh;
use crate::distance::{Sampling, mesh_distance, normal_angular_error};
use crate::error::MeshError;
use crate::surface_mesh::SurfaceMesh;

/// Largest accepted [`EvalParams::grid`].
pub const MAX_GRID: usize = 4096;

/// Width, in pixels, of the ground truth's silhouette band (module docs): a pixel is interior when every pixel
/// within this many rows and columns of it is hit by the ground truth.
pub const SILHOUETTE_BAND: usize = 2;

/// Settings of [`evaluate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvalParams {
    /// Pixels per side of the ray grid (`1..=`[`MAX_GRID`]; default 128).
    pub grid: usize,
    /// Extent of the grid along x on the wall, metres (default [−0.25, 0.25], Tsai et al. 2019's scan area).
    pub x_range: [f32; 2],
    /// Extent of the grid along y on the wall, metres (default [−0.25, 0.25]).
    pub y_range: [f32; 2],
    /// Points of each surface measured by the Chamfer/Hausdorff distances (default: the vertices).
    pub sampling: Sampling,
    /// Depth tolerance of [`Metrics::coverage_within`], metres (default 0.005: "coverage within 5 mm").
    pub coverage_threshold: f64,
}

impl Default for EvalParams {
    fn default() -> Self {
        Self {
            grid: 128,
            x_range: [-0.25, 0.25],
            y_range: [-0.25, 0.25],
            sampling: Sampling::Vertices,
            coverage_threshold: 0.005,
        }
    }
}

impl EvalParams {
    /// The wall position `(x, y)` of the centre of pixel `(ix, iy)` (see the module documentation).
    pub fn pixel_center(&self, ix: usize, iy: usize) -> (f32, f32) {
        let n = self.grid.max(1) as f64;
        let at = |r: [f32; 2], i: usize| (r[0] as f64 + (i as f64 + 0.5) * (r[1] as f64 - r[0] as f64) / n) as f32;
        (at(self.x_range, ix), at(self.y_range, iy))
    }

    fn validate(&self) -> Result<(), MeshError> {
        if self.grid == 0 || self.grid > MAX_GRID {
            return Err(MeshError::InvalidParameter {
                name: "grid",
                value: self.grid as f64,
                reason: "the ray grid needs 1 to 4096 pixels per side",
            });
        }
        for (name, r) in [("x_range", self.x_range), ("y_range", self.y_range)] {
            if !(r[0].is_finite() && r[1].is_finite() && r[0] < r[1]) {
                return Err(MeshError::InvalidParameter {
                    name,
                    value: (r[1] - r[0]) as f64,
                    reason: "the grid extent needs finite bounds with min < max",
                });
            }
        }
        if !(self.coverage_threshold.is_finite() && self.coverage_threshold > 0.0) {
            return Err(MeshError::InvalidParameter {
                name: "coverage_threshold",
                value: self.coverage_threshold,
                reason: "the coverage threshold is a depth in metres, finite and > 0",
            });
        }
        Ok(())
    }
}

/// The metrics of a reconstruction against the ground truth (module documentation: how each is computed).
///
/// Serialises with serde to one flat record (the `nlos eval` JSON line); the depth maps are left out of
/// serialisation (2·grid² numbers: write them as images) and deserialise empty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Pixels per side of the ray grid.
    pub grid: usize,
    /// Extent of the grid along x, metres.
    pub x_range: [f32; 2],
    /// Extent of the grid along y, metres.
    pub y_range: [f32; 2],
    /// Pixels whose ray hits the ground truth.
    pub gt_pixels: usize,
    /// Pixels whose ray hits the reconstruction.
    pub reconstruction_pixels: usize,
    /// Pixels whose ray hits both.
    pub both_pixels: usize,
    /// `both_pixels / gt_pixels`, in [0, 1]: plain coverage (any hit), reported, not judged — an
    /// overhanging surface wins it for free.
    pub coverage: f64,
    /// Share of the ground-truth pixels hit by the reconstruction within `coverage_threshold` of the ground
    /// truth's depth: "coverage within 5 mm" at the default threshold. 0 when read from a record written
    /// before it existed.
    #[serde(default)]
    pub coverage_within: f64,
    /// The depth tolerance of `coverage_within`, metres.
    #[serde(default)]
    pub coverage_threshold: f64,
    /// Mean of |z_rec − z_gt| over the pixels hit on both, metres; `None` (JSON `null`) when there are none.
    pub depth_error_mean: Option<f64>,
    /// Median of |z_rec − z_gt| (mean of the two middle values for an even count), metres.
    pub depth_error_median: Option<f64>,
    /// Root mean square of z_rec − z_gt, metres.
    pub depth_error_rms: Option<f64>,
    /// Largest |z_rec − z_gt|, metres.
    pub depth_error_max: Option<f64>,
    /// Ground-truth pixels that are interior (module docs, [`SILHOUETTE_BAND`]). 0 when read from a record
    /// written before it existed (as the two means below are then `None`).
    #[serde(default)]
    pub interior_pixels: usize,
    /// Mean of |z_rec − z_gt| over the interior pixels hit on both, metres; `None` when there are none.
    pub depth_error_mean_interior: Option<f64>,
    /// Mean of |z_rec − z_gt| over the pixels of the silhouette band hit on both, metres; `None` when there
    /// are none.
    pub depth_error_mean_silhouette: Option<f64>,
    /// Symmetric Chamfer distance, metres: mean distance from the reconstruction's samples to the ground-truth
    /// surface plus the mean the other way ([`crate::distance::MeshDistance::chamfer`]).
    pub chamfer: f64,
    /// Mean distance from the reconstruction's samples to the ground-truth surface, metres.
    pub mean_reconstruction_to_gt: f64,
    /// Mean distance from the ground truth's samples to the reconstruction's surface, metres.
    pub mean_gt_to_reconstruction: f64,
    /// Symmetric Hausdorff distance over the samples, metres ([`crate::distance::MeshDistance::hausdorff`]).
    pub hausdorff: f32,
    /// Mean angle, degrees, between each reconstruction vertex normal and the normal of the closest
    /// ground-truth face ([`crate::distance::NormalError::mean`]; orientation matters: flipped is 180°).
    pub normal_error_mean_deg: f64,
    /// Root mean square of those angles, degrees.
    pub normal_error_rms_deg: f64,
    /// The mean angle over the vertices within [`crate::distance::FAR_FROM_REFERENCE`] (1 cm) of the ground
    /// truth only ([`crate::distance::NormalError::split`]): the surface's normals without the rims that hang
    /// back along the line of sight. `None` when no vertex is that close, or in a record written before it
    /// existed.
    #[serde(default)]
    pub normal_error_near_deg: Option<f64>,
    /// Fraction of the reconstruction's vertices farther than that from the ground truth.
    #[serde(default)]
    pub far_vertex_fraction: Option<f64>,
    /// Depth map of the reconstruction: z (metres) of the first hit of pixel `ix + grid·iy`, `NaN` where
    /// the ray hits nothing. Not serialised.
    #[serde(skip)]
    pub depth_reconstruction: Vec<f32>,
    /// Depth map of the ground truth, same layout. Not serialised.
    #[serde(skip)]
    pub depth_ground_truth: Vec<f32>,
}

/// A [`SurfaceMesh`] of any indexed triangle list, for use as ground truth: every triangle gets its own
/// three vertices (no shared vertices or edges), so non-manifold edges or vertices and inconsistent
/// orientation — common in scanned or exported models, e.g. the shared soap bar — cannot fail the
/// half-edge construction. Rays, closest points and face normals see exactly the input triangles; the
/// vertex samples of [`crate::distance::sample_points`] count each corner once per triangle. Triangles that
/// repeat a vertex index (zero area, never hit) are dropped. Errors on an out-of-range index.
pub fn unwelded_mesh(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<SurfaceMesh, MeshError> {
    let mut pos = Vec::with_capacity(3 * triangles.len());
    let mut tris = Vec::with_capacity(triangles.len());
    for (face, t) in triangles.iter().enumerate() {
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            continue;
        }
        let base = pos.len() as u32;
        for &i in t {
            let p = positions.get(i as usize).ok_or(MeshError::IndexOutOfRange {
                face,
                index: i as u64,
                vertex_count: positions.len(),
            })?;
            pos.push(*p);
        }
        tris.push([base, base + 1, base + 2]);
    }
    SurfaceMesh::from_triangles(&pos, &tris)
}

/// Reads a mesh file for [`evaluate`] (any format of [`crate::io::read_any`]): the half-edge mesh when the
/// triangles are manifold and consistently oriented, otherwise [`unwelded_mesh`] of the same triangles (then
/// the vertex normals of [`normal_angular_error`] are the face normals). Errors on an unreadable or
/// malformed file, non-finite positions or out-of-range indices.
pub fn load_for_eval(path: impl AsRef<std::path::Path>) -> Result<SurfaceMesh, MeshError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| MeshError::Io { file: path.to_owned(), source })?;
    let soup = crate::io::read_any(&bytes, &path.display().to_string())?;
    match SurfaceMesh::from_triangles(&soup.positions, &soup.triangles) {
        Err(
            MeshError::NonManifoldEdge { .. }
            | MeshError::NonManifoldVertex { .. }
            | MeshError::InconsistentOrientation { .. }
            | MeshError::DegenerateFace { .. },
        ) => unwelded_mesh(&soup.positions, &soup.triangles),
        other => other,
    }
}

/// Depth map of `mesh` over the grid of `params`: z of the first hit of the +z ray from each pixel centre
/// on the wall, `NaN` for no hit; layout `ix + grid·iy`. Errors on invalid `params`, a mesh without faces
/// or with non-finite positions.
pub fn depth_map(mesh: &SurfaceMesh, params: &EvalParams) -> Result<Vec<f32>, MeshError> {
    params.validate()?;
    Ok(depth_map_bvh(&TriangleBvh::from_mesh(mesh)?, params))
}

fn depth_map_bvh(bvh: &TriangleBvh, params: &EvalParams) -> Vec<f32> {
    let n = params.grid;
    let mut depth = vec![f32::NAN; n * n];
    depth.par_chunks_mut(n).enumerate().for_each(|(iy, row)| {
        for (ix, z) in row.iter_mut().enumerate() {
            let (x, y) = params.pixel_center(ix, iy);
            if let Some(hit) = bvh.ray_first_hit(Vec3::new(x, y, 0.0), Vec3::Z, f32::INFINITY) {
                *z = hit.point.z;
            }
        }
    });
    depth
}

/// Evaluates `reconstruction` against `ground_truth`: coverage and depth error from the +z ray grid of
/// `params`, symmetric Chamfer and Hausdorff distances, and normal angular error (module documentation).
///
/// Errors ([`MeshError`]): invalid `params` (`InvalidParameter`: grid outside `1..=4096`, empty or
/// non-finite extent), either mesh without faces (`EmptyMesh`), non-finite positions
/// (`NonFinitePosition`), and a ground truth that no ray of the grid hits (`InvalidParameter` on the
/// extent: coverage would be 0/0 — move the grid over the object or check that it lies at z > 0).
/// A reconstruction that no ray hits is valid: coverage 0 and depth errors `None`.
pub fn evaluate(
    reconstruction: &SurfaceMesh,
    ground_truth: &SurfaceMesh,
    params: &EvalParams,
) -> Result<Metrics, MeshError> {
    params.validate()?;
    if reconstruction.n_faces() == 0 {
        return Err(MeshError::EmptyMesh { what: "evaluating the reconstruction" });
    }
    if ground_truth.n_faces() == 0 {
        return Err(MeshError::EmptyMesh { what: "evaluating against the ground truth" });
    }
    let rec_bvh = TriangleBvh::from_mesh(reconstruction)?;
    let gt_bvh = TriangleBvh::from_mesh(ground_truth)?;
    let depth_reconstruction = depth_map_bvh(&rec_bvh, params);
    let depth_ground_truth = depth_map_bvh(&gt_bvh, params);

    let gt_pixels = depth_ground_truth.iter().filter(|z| !z.is_nan()).count();
    if gt_pixels == 0 {
        return Err(MeshError::InvalidParameter {
            name: "x_range/y_range",
            value: (params.x_range[1] - params.x_range[0]) as f64,
            reason: "no ray of the evaluation grid hits the ground truth, so coverage is undefined; \
                     make the grid cover the object and check that the object lies at z > 0",
        });
    }
    let reconstruction_pixels = depth_reconstruction.iter().filter(|z| !z.is_nan()).count();
    let mut errors: Vec<f64> = depth_reconstruction
        .iter()
        .zip(&depth_ground_truth)
        .filter(|(r, g)| !r.is_nan() && !g.is_nan())
        .map(|(&r, &g)| (r as f64 - g as f64).abs())
        .collect();
    let both_pixels = errors.len();
    let within = errors.iter().filter(|&&e| e <= params.coverage_threshold).count();
    let (mean, median, rms, max) = if errors.is_empty() {
        (None, None, None, None)
    } else {
        let k = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / k;
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / k).sqrt();
        errors.sort_by(f64::total_cmp);
        (Some(mean), median_of_sorted(&errors), Some(rms), errors.last().copied())
    };

    let interior = interior_mask(&depth_ground_truth, params.grid, SILHOUETTE_BAND);
    let interior_pixels = interior.iter().filter(|&&k| k).count();
    let band_mean = |want: bool| {
        let (sum, k) = depth_reconstruction
            .iter()
            .zip(&depth_ground_truth)
            .zip(&interior)
            .filter(|((r, g), i)| !r.is_nan() && !g.is_nan() && **i == want)
            .fold((0.0, 0usize), |(s, k), ((&r, &g), _)| (s + (r as f64 - g as f64).abs(), k + 1));
        (k > 0).then(|| sum / k as f64)
    };

    let dist = mesh_distance(reconstruction, ground_truth, params.sampling)?;
    let normals = normal_angular_error(reconstruction, ground_truth)?;
    let (near_deg, far) = normals.split(crate::distance::FAR_FROM_REFERENCE);
    Ok(Metrics {
        grid: params.grid,
        x_range: params.x_range,
        y_range: params.y_range,
        gt_pixels,
        reconstruction_pixels,
        both_pixels,
        coverage: both_pixels as f64 / gt_pixels as f64,
        coverage_within: within as f64 / gt_pixels as f64,
        coverage_threshold: params.coverage_threshold,
        depth_error_mean: mean,
        depth_error_median: median,
        depth_error_rms: rms,
        depth_error_max: max,
        interior_pixels,
        depth_error_mean_interior: band_mean(true),
        depth_error_mean_silhouette: band_mean(false),
        chamfer: dist.chamfer,
        mean_reconstruction_to_gt: dist.mean_a_to_b,
        mean_gt_to_reconstruction: dist.mean_b_to_a,
        hausdorff: dist.hausdorff,
        normal_error_mean_deg: normals.mean,
        normal_error_rms_deg: normals.rms,
        normal_error_near_deg: near_deg,
        far_vertex_fraction: Some(far),
        depth_reconstruction,
        depth_ground_truth,
    })
}

/// The median of ascending `sorted` values (the mean of the two middle ones for an even count); None when
/// empty.
pub(crate) fn median_of_sorted(sorted: &[f64]) -> Option<f64> {
    let m = sorted.len() / 2;
    match sorted.len() {
        0 => None,
        n if n % 2 == 1 => Some(sorted[m]),
        _ => Some(0.5 * (sorted[m - 1] + sorted[m])),
    }
}

/// Per pixel of an `n × n` depth map (`NaN`: no hit): whether every pixel within `band` rows and columns of
/// it is a hit and inside the grid (module docs, "Interior and silhouette band"). `band = 0` marks the hits.
///
/// # Panics
/// When `depth.len() != n * n`.
pub fn interior_mask(depth: &[f32], n: usize, band: usize) -> Vec<bool> {
    assert_eq!(depth.len(), n * n, "interior_mask: a depth map of {n} × {n} pixels");
    // Separable erosion: runs of hits along x, then along y.
    let erode = |hit: &[bool], step: usize, stride: usize| -> Vec<bool> {
        let mut out = vec![false; n * n];
        for line in 0..n {
            let at = |i: usize| line * stride + i * step;
            for i in 0..n {
                out[at(i)] = i >= band && i + band < n && (i - band..=i + band).all(|j| hit[at(j)]);
            }
        }
        out
    };
    let hits: Vec<bool> = depth.iter().map(|z| !z.is_nan()).collect();
    erode(&erode(&hits, 1, n), n, 1)
}
