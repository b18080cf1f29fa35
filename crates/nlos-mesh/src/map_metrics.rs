//! Scoring against ground-truth **depth and normal maps** on a wall grid — the protocol of the NLOS methods
//! that compare on the Z-NLOS scenes (D-LCT, Young et al. 2020; NeTF; NLOS-NeuS): depth per wall pixel,
//! mean absolute depth error in the ground truth's mask, mean normal angle error in the mask.
//!
//! **Grid.** A map is `height × width` pixels over the wall rectangle `x_range × y_range`, seen from the
//! wall into the hidden scene as an image: pixel `(row r, column c)` has its centre at
//! `x = x₀ + (c + ½)(x₁ − x₀)/width`, `y = y₁ − (r + ½)(y₁ − y₀)/height` (row 0 at the top, largest y) and is
//! stored at `c + width·r`. Depths are metres along +z (the distance from the wall, our frame: wall z = 0,
//! scene at z > 0); a pixel without surface is `NaN` (readers map 0 and negative depths to `NaN`). Normals
//! are unit 3-vectors in the same frame, facing the wall (`n_z < 0` where the surface is seen).
//!
//! **Metrics** ([`MapMetrics`]), with the names of [`crate::metrics::Metrics`] where they mean the same:
//! coverage (ground-truth pixels the reconstruction also has), coverage within the threshold (5 mm: also
//! within it in depth), mean/median |Δz| over the pixels both have (the D-LCT mean absolute depth error in
//! the mask, missing pixels left to coverage), the interior and silhouette split of
//! [`crate::metrics::interior_mask`], and the mean angle between the normals over the pixels both have.
//!
//! A mesh gives its maps by [`mesh_maps`] (first hit of a +z ray per pixel, the hit face's normal); a
//! volume's arg-max depth map gives normals by [`normals_from_depth`] (central differences).
//!
//! **Files.** [`MapLayout`] says how a map file's pixels and vectors relate to this grid: ours, or the
//! Z-NLOS ground truth as D-LCT published it. A pixel whose normal is missing (NaN) while its depth is not
//! is left out of the normal error only; [`MapMetrics::normal_pixels`] says on how many pixels it is.

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bvh::TriangleBvh;
use crate::error::MeshError;
use crate::metrics::{SILHOUETTE_BAND, interior_mask, median_of_sorted};
use crate::surface_mesh::SurfaceMesh;

/// The wall grid of a map (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MapGrid {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Extent along x on the wall, metres.
    pub x_range: [f32; 2],
    /// Extent along y on the wall, metres.
    pub y_range: [f32; 2],
}

impl MapGrid {
    /// The wall position `(x, y)` of the centre of pixel `(row, col)` (module docs).
    pub fn pixel_center(&self, row: usize, col: usize) -> (f32, f32) {
        let at =
            |r: [f32; 2], i: usize, n: usize| f64::from(r[0]) + (i as f64 + 0.5) * f64::from(r[1] - r[0]) / n as f64;
        let x = at(self.x_range, col, self.width);
        let y = f64::from(self.y_range[1]) - (at(self.y_range, row, self.height) - f64::from(self.y_range[0]));
        (x as f32, y as f32)
    }

    /// The grid of `width × height` pixels whose first and last pixel centres lie on the edges of the
    /// rectangle `[x0, x1, y0, y1]` (a map of the scan points themselves, as the Z-NLOS maps are of their
    /// 256 × 256 scan grid): the pixels reach half a pixel beyond it. A side of one pixel spans the
    /// rectangle's side (at least 1 cm).
    pub fn spanning(width: usize, height: usize, centres: [f32; 4]) -> Self {
        let [x0, x1, y0, y1] = centres;
        let half = |lo: f32, hi: f32, n: usize| {
            if n > 1 { 0.5 * (hi - lo) / (n - 1) as f32 } else { 0.5 * (hi - lo).max(0.01) }
        };
        let (hx, hy) = (half(x0, x1, width), half(y0, y1, height));
        Self { width, height, x_range: [x0 - hx, x1 + hx], y_range: [y0 - hy, y1 + hy] }
    }

    /// Pixels in the map.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Whether the grid has no pixel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn validate(&self) -> Result<(), MeshError> {
        if self.width == 0 || self.height == 0 || self.width > 4096 || self.height > 4096 {
            return Err(MeshError::InvalidParameter {
                name: "map size",
                value: self.len() as f64,
                reason: "a map needs 1 to 4096 pixels per side",
            });
        }
        for (name, r) in [("x_range", self.x_range), ("y_range", self.y_range)] {
            if !(r[0].is_finite() && r[1].is_finite() && r[0] < r[1]) {
                return Err(MeshError::InvalidParameter {
                    name,
                    value: f64::from(r[1] - r[0]),
                    reason: "the map's wall extent needs finite bounds with min < max",
                });
            }
        }
        Ok(())
    }
}

/// How a map file lays out its pixels (and its normals' components) against [`MapGrid`]'s image.
///
/// Decided from the published files, not from files written here: `tests/znlos_published.rs` checks each
/// against the Z-NLOS bunny's capture (its first returns against the depth map's nearest surface) and the
/// two maps against each other (masks, normals against the depth map's slopes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MapLayout {
    /// This crate's (module docs): row 0 at the top (largest y), column 0 at the smallest x; normals in our
    /// frame, facing the wall.
    #[default]
    Image,
    /// The Z-NLOS ground truth of the directional LCT (Young et al., CVPR 2020; `zaragoza/*_depth.mat`,
    /// `*_normal.mat`, used by NeTF and the surface methods after it), in our frame (the wall's
    /// x, and its y = Z-NLOS z, the reader's axes). The depth map is the transpose of our image: its element
    /// `(r, c)` is at our pixel `(c, r)`, so its rows run along +x and its columns down from the top. The
    /// normal map is our image mirrored left to right, and its vectors point away from the wall: element
    /// `(r, c)` holds `−n` of our pixel `(r, W − 1 − c)`. (As stored, the two masks overlap on 16,844 of
    /// the bunny's 26,706 pixels; so read, on all of them.)
    Dlct,
}

impl MapLayout {
    /// A depth map stored `shape = [rows, cols]` in C order, as our image: `(values, width, height)`.
    /// Values missing from a short `values` are NaN (no surface).
    pub fn depth_to_image(self, values: &[f32], shape: [usize; 2]) -> (Vec<f32>, usize, usize) {
        let [rows, cols] = shape;
        let at = |i: usize| values.get(i).copied().unwrap_or(f32::NAN);
        let n = rows.saturating_mul(cols);
        match self {
            MapLayout::Image => ((0..n).map(at).collect(), cols, rows),
            // Our (i, j) = stored (j, i): width = rows, height = cols.
            MapLayout::Dlct => ((0..n).map(|k| at((k / rows) + cols * (k % rows))).collect(), rows, cols),
        }
    }

    /// A normal map stored `shape = [rows, cols, 3]` in C order, as our image of vectors in our frame:
    /// `(normals, width, height)`; missing values are NaN (no normal).
    pub fn normals_to_image(self, values: &[f32], shape: [usize; 2]) -> (Vec<Vec3>, usize, usize) {
        let [rows, cols] = shape;
        let get = |i: usize| values.get(i).copied().unwrap_or(f32::NAN);
        let at = |r: usize, c: usize| {
            let k = 3 * (c + cols * r);
            Vec3::new(get(k), get(k + 1), get(k + 2))
        };
        let image = (0..rows.saturating_mul(cols)).map(|k| {
            let (r, c) = (k / cols, k % cols);
            match self {
                MapLayout::Image => at(r, c),
                MapLayout::Dlct => -at(r, cols - 1 - c),
            }
        });
        (image.collect(), cols, rows)
    }
}

/// Depth and (optionally) normal maps on one grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Maps {
    /// The grid.
    pub grid: MapGrid,
    /// Depth per pixel, metres; `NaN` where there is no surface.
    pub depth: Vec<f32>,
    /// Unit normal per pixel facing the wall (ignored where the depth is `NaN`; `NaN` where the normal map
    /// has no value).
    pub normals: Option<Vec<Vec3>>,
}

impl Maps {
    /// Checks the sizes, and that every normal inside the depth's mask is a unit vector facing the wall or
    /// missing (a NaN component).
    ///
    /// # Errors
    /// [`MeshError::Format`] naming `what` (e.g. the file) and the problem: sizes that differ from the grid,
    /// a non-finite or non-unit normal, normals facing away from the wall (the map's axes are not ours).
    pub fn validate(&self, what: &str) -> Result<(), MeshError> {
        let bad = |field: &str, message: String| MeshError::Format { file: what.into(), field: field.into(), message };
        self.grid.validate()?;
        if self.depth.len() != self.grid.len() {
            return Err(bad(
                "depth",
                format!("{} values for a {} × {} grid", self.depth.len(), self.grid.height, self.grid.width),
            ));
        }
        let Some(normals) = &self.normals else { return Ok(()) };
        if normals.len() != self.grid.len() {
            return Err(bad(
                "normal",
                format!(
                    "{} normals for a {} × {} depth map: the normal map must be height × width × 3 on the depth's grid",
                    normals.len(),
                    self.grid.height,
                    self.grid.width
                ),
            ));
        }
        let inside = || normals.iter().zip(&self.depth).filter(|(n, z)| !z.is_nan() && !n.is_nan()).map(|(n, _)| *n);
        if let Some((i, n)) = inside().enumerate().find(|(_, n)| !(n.is_finite() && (n.length() - 1.0).abs() < 1e-2)) {
            return Err(bad(
                "normal",
                format!(
                    "the {i}-th normal inside the mask is {n}, not a finite unit vector (is the last axis x, y, z?)"
                ),
            ));
        }
        let facing = inside().filter(|n| n.z < 0.0).count();
        let count = inside().count();
        if count > 0 && 2 * facing < count {
            return Err(bad(
                "normal",
                format!(
                    "{} of {count} normals face away from the wall (n_z ≥ 0): the map's axes differ from ours (wall \
                     z = 0, scene at z > 0, normals toward the wall); flip or convert them",
                    count - facing
                ),
            ));
        }
        Ok(())
    }
}

/// The scores of [`evaluate_maps`] (module docs). Fields named as in [`crate::metrics::Metrics`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapMetrics {
    /// Pixels per row of the maps.
    pub width: usize,
    /// Rows of the maps.
    pub height: usize,
    /// Ground-truth pixels (the mask).
    pub gt_pixels: usize,
    /// Pixels the reconstruction has.
    pub reconstruction_pixels: usize,
    /// Pixels both have.
    pub both_pixels: usize,
    /// `both_pixels / gt_pixels`.
    pub coverage: f64,
    /// The depth threshold of `coverage_within`, metres.
    pub coverage_threshold: f64,
    /// Share of the ground-truth pixels that the reconstruction has within `coverage_threshold` in depth.
    pub coverage_within: f64,
    /// Mean |Δz| over the pixels both have (the mean absolute depth error in the mask), metres.
    pub depth_error_mean: Option<f64>,
    /// Median |Δz| over the pixels both have, metres.
    pub depth_error_median: Option<f64>,
    /// Ground-truth pixels at least `SILHOUETTE_BAND + 1` pixels inside the mask.
    pub interior_pixels: usize,
    /// Mean |Δz| over the interior pixels both have, metres.
    pub depth_error_mean_interior: Option<f64>,
    /// Mean |Δz| over the rest of the mask both have, metres.
    pub depth_error_mean_silhouette: Option<f64>,
    /// Mean angle between the normals over the pixels both have where the truth has a normal, degrees
    /// (None without normal maps).
    pub normal_error_mean_deg: Option<f64>,
    /// Pixels the normal error is computed on: both have a surface and the truth's normal map a value.
    pub normal_pixels: usize,
}

/// Scores `reconstruction` against `truth` on the truth's grid (module docs); `threshold` is the depth
/// tolerance of `coverage_within` (0.005 m for "coverage within 5 mm").
///
/// # Errors
/// [`MeshError::InvalidParameter`] when the grids differ or the threshold is not finite and > 0, when the
/// truth has no pixel; those of [`Maps::validate`].
pub fn evaluate_maps(reconstruction: &Maps, truth: &Maps, threshold: f64) -> Result<MapMetrics, MeshError> {
    truth.validate("ground truth")?;
    reconstruction.validate("reconstruction")?;
    if reconstruction.grid != truth.grid {
        return Err(MeshError::InvalidParameter {
            name: "grid",
            value: reconstruction.grid.len() as f64,
            reason: "the reconstruction's maps must be on the ground truth's grid",
        });
    }
    if !(threshold.is_finite() && threshold > 0.0) {
        return Err(MeshError::InvalidParameter {
            name: "threshold",
            value: threshold,
            reason: "the coverage threshold is a depth in metres, finite and > 0",
        });
    }
    let (w, h) = (truth.grid.width, truth.grid.height);
    let gt_pixels = truth.depth.iter().filter(|z| !z.is_nan()).count();
    if gt_pixels == 0 {
        return Err(MeshError::InvalidParameter {
            name: "depth",
            value: 0.0,
            reason: "the ground-truth depth map has no surface pixel (all NaN or ≤ 0)",
        });
    }
    // interior_mask works on square maps; pad to a square of NaN.
    let n = w.max(h);
    let mut square = vec![f32::NAN; n * n];
    for r in 0..h {
        square[r * n..r * n + w].copy_from_slice(&truth.depth[r * w..(r + 1) * w]);
    }
    let interior_sq = interior_mask(&square, n, SILHOUETTE_BAND);
    let interior: Vec<bool> = (0..h).flat_map(|r| interior_sq[r * n..r * n + w].to_vec()).collect();
    let pairs: Vec<(usize, f64)> = (0..w * h)
        .filter(|&i| !truth.depth[i].is_nan() && !reconstruction.depth[i].is_nan())
        .map(|i| (i, (f64::from(reconstruction.depth[i]) - f64::from(truth.depth[i])).abs()))
        .collect();
    let mean = |it: &mut dyn Iterator<Item = f64>| {
        let (s, k) = it.fold((0.0, 0usize), |(s, k), e| (s + e, k + 1));
        (k > 0).then(|| s / k as f64)
    };
    let mut sorted: Vec<f64> = pairs.iter().map(|p| p.1).collect();
    sorted.sort_by(f64::total_cmp);
    let median = median_of_sorted(&sorted);
    let angles: Vec<f64> = match (&reconstruction.normals, &truth.normals) {
        (Some(a), Some(b)) => pairs
            .iter()
            .filter(|&&(i, _)| !a[i].is_nan() && !b[i].is_nan())
            .map(|&(i, _)| f64::from(a[i].normalize().dot(b[i].normalize()).clamp(-1.0, 1.0)).acos().to_degrees())
            .collect(),
        _ => Vec::new(),
    };
    let normal_error_mean_deg = if reconstruction.normals.is_some() && truth.normals.is_some() {
        mean(&mut angles.iter().copied())
    } else {
        None
    };
    Ok(MapMetrics {
        width: w,
        height: h,
        gt_pixels,
        reconstruction_pixels: reconstruction.depth.iter().filter(|z| !z.is_nan()).count(),
        both_pixels: pairs.len(),
        coverage: pairs.len() as f64 / gt_pixels as f64,
        coverage_threshold: threshold,
        coverage_within: pairs.iter().filter(|p| p.1 <= threshold).count() as f64 / gt_pixels as f64,
        depth_error_mean: mean(&mut pairs.iter().map(|p| p.1)),
        depth_error_median: median,
        interior_pixels: interior.iter().filter(|&&k| k).count(),
        depth_error_mean_interior: mean(&mut pairs.iter().filter(|p| interior[p.0]).map(|p| p.1)),
        depth_error_mean_silhouette: mean(&mut pairs.iter().filter(|p| !interior[p.0]).map(|p| p.1)),
        normal_error_mean_deg,
        normal_pixels: angles.len(),
    })
}

/// A mesh's depth and normal maps on `grid`: the first hit of the +z ray through each pixel centre, and
/// the hit face's unit normal turned toward the wall.
///
/// # Errors
/// [`MeshError::EmptyMesh`] for a mesh without faces; those of the BVH (non-finite positions) and of the grid.
pub fn mesh_maps(mesh: &SurfaceMesh, grid: &MapGrid) -> Result<Maps, MeshError> {
    grid.validate()?;
    if mesh.n_faces() == 0 {
        return Err(MeshError::EmptyMesh { what: "mapping the reconstruction's depth" });
    }
    let bvh = TriangleBvh::from_mesh(mesh)?;
    let pixels: Vec<(f32, Vec3)> = (0..grid.len())
        .into_par_iter()
        .map(|i| {
            let (x, y) = grid.pixel_center(i / grid.width, i % grid.width);
            match bvh.ray_first_hit(Vec3::new(x, y, 0.0), Vec3::Z, f32::INFINITY) {
                Some(hit) => {
                    let [a, b, c] = bvh.triangle(hit.triangle);
                    let n = (b - a).cross(c - a).normalize_or_zero();
                    (hit.point.z, if n.z > 0.0 { -n } else { n })
                }
                None => (f32::NAN, Vec3::ZERO),
            }
        })
        .collect();
    Ok(Maps {
        grid: *grid,
        depth: pixels.iter().map(|p| p.0).collect(),
        normals: Some(pixels.iter().map(|p| p.1).collect()),
    })
}

/// Unit normals of a depth map by central differences (one-sided at the mask's edge), facing the wall:
/// `n ∝ (∂z/∂x, ∂z/∂y, −1)`; a pixel without neighbours in the mask gets `(0, 0, −1)`.
pub fn normals_from_depth(depth: &[f32], grid: &MapGrid) -> Vec<Vec3> {
    let (w, h) = (grid.width, grid.height);
    let dx = f64::from(grid.x_range[1] - grid.x_range[0]) / w as f64;
    let dy = f64::from(grid.y_range[1] - grid.y_range[0]) / h as f64;
    let at = |r: usize, c: usize| depth.get(c + w * r).copied().filter(|z| !z.is_nan());
    // A derivative along one axis from whichever neighbours are in the mask (`step` metres apart).
    let slope = |lo: Option<f32>, mid: f32, hi: Option<f32>, step: f64| match (lo, hi) {
        (Some(a), Some(b)) => f64::from(b - a) / (2.0 * step),
        (Some(a), None) => f64::from(mid - a) / step,
        (None, Some(b)) => f64::from(b - mid) / step,
        (None, None) => 0.0,
    };
    (0..w * h)
        .map(|i| {
            let (r, c) = (i / w, i % w);
            let Some(z) = at(r, c) else { return Vec3::new(0.0, 0.0, -1.0) };
            let zx = slope(c.checked_sub(1).and_then(|c| at(r, c)), z, (c + 1 < w).then(|| at(r, c + 1)).flatten(), dx);
            // Rows run toward −y.
            let zy =
                -slope(r.checked_sub(1).and_then(|r| at(r, c)), z, (r + 1 < h).then(|| at(r + 1, c)).flatten(), dy);
            Vec3::new(zx as f32, zy as f32, -1.0).normalize()
        })
        .collect()
}
