//! Volume → surface: a depth map, a mask, a wall-facing triangle mesh.
//!
//! Per (x, y) column the depth of the maximum value is taken (the "front view" of the volumetric
//! methods); the columns whose maximum passes a threshold form the mask; optionally only the largest
//! 4-connected region is kept; every grid cell whose four corners are kept becomes two triangles at the
//! depths of its corners, wound so that their normals face the wall (negative z); the depths may be
//! smoothed, and the mesh remeshed isotropically (Botsch & Kobbelt 2004, through `nlos-mesh`).

use glam::Vec3;
use nlos_mesh::remeshing::{RemeshParams, uniform_remeshing};
use nlos_mesh::{BuildOptions, SurfaceMesh};

use crate::error::{InitError, Result};
use crate::volume::Volume;

/// How the mask threshold on the per-column maximum is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Threshold {
    /// Otsu's method (Otsu 1979) on a 256-bin histogram of the per-column maxima: the threshold that
    /// maximises the between-class variance of "object" and "background" columns.
    #[default]
    Otsu,
    /// This fraction (0–1) of the largest column maximum.
    Relative(f32),
    /// This absolute value.
    Absolute(f32),
}

/// Parameters of [`volume_to_surface`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// Mask threshold. Default [`Threshold::Otsu`].
    pub threshold: Threshold,
    /// Only voxels at least this deep are considered (metres; default `None`).
    pub min_depth: Option<f64>,
    /// Only voxels at most this deep are considered (metres; default `None`).
    pub max_depth: Option<f64>,
    /// Keep only the largest 4-connected region of the mask. Default `true`.
    pub largest_component: bool,
    /// Neighbouring columns whose depths differ by more than this (metres) are not connected, neither
    /// for the connected regions nor in the triangulation, so that objects at different depths that
    /// overlap in the front view stay apart. Default `Some(0.05)`; `None` connects by the mask only.
    pub max_depth_jump: Option<f64>,
    /// Jacobi passes averaging each kept depth with its kept 4-neighbours. Default 0.
    pub smoothing_iterations: usize,
    /// Remesh isotropically to this target edge length (metres) with `nlos-mesh`'s uniform remeshing
    /// (pmp settings, fixed boundary). Default `None` (the grid triangulation is returned).
    pub target_edge_length: Option<f64>,
}

impl Default for SurfaceParams {
    fn default() -> Self {
        Self {
            threshold: Threshold::Otsu,
            min_depth: None,
            max_depth: None,
            largest_component: true,
            max_depth_jump: Some(0.05),
            smoothing_iterations: 0,
            target_edge_length: None,
        }
    }
}

/// The surface extracted from a volume.
#[derive(Debug, Clone)]
pub struct Surface {
    /// Columns along x.
    pub nx: usize,
    /// Columns along y.
    pub ny: usize,
    /// Depth of each column's maximum (metres), `nx × ny`, x fastest (smoothed where kept).
    pub depth: Vec<f32>,
    /// Each column's maximum, `nx × ny`.
    pub albedo: Vec<f32>,
    /// The threshold that was applied.
    pub threshold: f32,
    /// Kept columns, `nx × ny`.
    pub mask: Vec<bool>,
    /// Vertex positions (metres).
    pub positions: Vec<Vec3>,
    /// Triangles, normals facing the wall (`(v1 − v0) × (v2 − v0)` has negative z before remeshing).
    pub triangles: Vec<[u32; 3]>,
    /// The same surface as a half-edge mesh (after remeshing when requested).
    pub mesh: SurfaceMesh,
}

impl Surface {
    /// Median depth over the kept columns (metres); `None` when nothing is kept.
    pub fn median_depth(&self) -> Option<f64> {
        let mut d: Vec<f32> = self.depth.iter().zip(&self.mask).filter(|&(_, &k)| k).map(|(&d, _)| d).collect();
        if d.is_empty() {
            return None;
        }
        d.sort_by(f32::total_cmp);
        Some(d[d.len() / 2] as f64)
    }
}

/// Otsu's threshold of `values` on a `bins`-bin histogram; `None` when the values are not finite or all
/// equal.
pub fn otsu_threshold(values: &[f32], bins: usize) -> Option<f32> {
    let (lo, hi) = values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo || bins < 2 {
        return None;
    }
    let mut hist = vec![0.0f64; bins];
    let w = (hi - lo) as f64 / bins as f64;
    for &v in values {
        let b = (((v - lo) as f64 / w) as usize).min(bins - 1);
        hist[b] += 1.0;
    }
    let total: f64 = hist.iter().sum();
    let sum_all: f64 = hist.iter().enumerate().map(|(i, h)| i as f64 * h).sum();
    let (mut w0, mut sum0, mut best, mut best_i) = (0.0, 0.0, -1.0, 0);
    for (i, h) in hist.iter().enumerate().take(bins - 1) {
        w0 += h;
        sum0 += i as f64 * h;
        let w1 = total - w0;
        if w0 == 0.0 || w1 == 0.0 {
            continue;
        }
        let (m0, m1) = (sum0 / w0, (sum_all - sum0) / w1);
        let between = w0 * w1 * (m0 - m1) * (m0 - m1);
        if between > best {
            best = between;
            best_i = i;
        }
    }
    Some(lo + ((best_i + 1) as f64 * w) as f32)
}

/// 4-connected components of a `nx × ny` mask: a label per cell (`u32::MAX` outside the mask) and the
/// size of each component. With `depth_jump = Some((depth, max_jump))`, neighbours whose depths differ
/// by more than `max_jump` are not connected.
///
/// # Panics
/// When `mask` (or `depth`) holds fewer than `nx × ny` values.
pub fn connected_components(
    mask: &[bool],
    nx: usize,
    ny: usize,
    depth_jump: Option<(&[f32], f32)>,
) -> (Vec<u32>, Vec<usize>) {
    let linked = |a: usize, b: usize| depth_jump.is_none_or(|(d, j)| (d[a] - d[b]).abs() <= j);
    let mut label = vec![u32::MAX; nx * ny];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..nx * ny {
        if !mask[start] || label[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let mut size = 0;
        label[start] = id;
        stack.push(start);
        while let Some(c) = stack.pop() {
            size += 1;
            let (ix, iy) = (c % nx, c / nx);
            let mut visit = |n: usize| {
                if mask[n] && label[n] == u32::MAX && linked(c, n) {
                    label[n] = id;
                    stack.push(n);
                }
            };
            if ix > 0 {
                visit(c - 1);
            }
            if ix + 1 < nx {
                visit(c + 1);
            }
            if iy > 0 {
                visit(c - nx);
            }
            if iy + 1 < ny {
                visit(c + nx);
            }
        }
        sizes.push(size);
    }
    (label, sizes)
}

/// Extracts the wall-facing surface of a volume (see the module docs).
///
/// # Errors
/// [`InitError::BadVolume`] / [`InitError::NonFinite`] for an invalid volume,
/// [`InitError::InvalidParameter`] for a bad threshold or edge length, [`InitError::Empty`] when no
/// column passes the threshold or no grid cell has four kept corners, [`InitError::Mesh`] when
/// remeshing fails.
pub fn volume_to_surface(vol: &Volume, params: &SurfaceParams) -> Result<Surface> {
    vol.validate()?;
    let (nx, ny) = (vol.nx, vol.ny);
    let (mut depth, albedo) = vol.depth_map(params.min_depth, params.max_depth)?;
    let max = albedo.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let threshold = match params.threshold {
        Threshold::Otsu => otsu_threshold(&albedo, 256).unwrap_or(max),
        Threshold::Relative(r) if (0.0..=1.0).contains(&r) => r * max,
        Threshold::Absolute(a) if a.is_finite() => a,
        Threshold::Relative(r) | Threshold::Absolute(r) => {
            return Err(InitError::InvalidParameter {
                name: "threshold",
                value: r as f64,
                reason: "a relative threshold lies in [0, 1]; an absolute one must be finite",
            });
        }
    };
    if max.is_nan() || max <= 0.0 {
        return Err(InitError::Empty {
            what: "the volume is zero everywhere: nothing to extract (check the gate and the data)".into(),
        });
    }
    let mut mask: Vec<bool> = albedo.iter().map(|&a| a >= threshold && a > 0.0).collect();
    if params.largest_component {
        let jump = params.max_depth_jump.map(|j| (depth.as_slice(), j as f32));
        let (label, sizes) = connected_components(&mask, nx, ny, jump);
        if let Some(best) = (0..sizes.len()).max_by_key(|&i| sizes[i]) {
            for (m, l) in mask.iter_mut().zip(&label) {
                *m = *l == best as u32;
            }
        }
    }
    for _ in 0..params.smoothing_iterations {
        let prev = depth.clone();
        for iy in 0..ny {
            for ix in 0..nx {
                let c = ix + nx * iy;
                if !mask[c] {
                    continue;
                }
                let (mut s, mut n) = (prev[c] as f64, 1.0);
                let nbs = [
                    (ix > 0).then(|| c - 1),
                    (ix + 1 < nx).then(|| c + 1),
                    (iy > 0).then(|| c - nx),
                    (iy + 1 < ny).then(|| c + nx),
                ];
                for nb in nbs.into_iter().flatten() {
                    if mask[nb] {
                        s += prev[nb] as f64;
                        n += 1.0;
                    }
                }
                depth[c] = (s / n) as f32;
            }
        }
    }
    if let Some(j) = params.max_depth_jump
        && !(j.is_finite() && j > 0.0)
    {
        return Err(InitError::InvalidParameter {
            name: "max_depth_jump",
            value: j,
            reason: "must be a positive length (m)",
        });
    }
    let max_jump = params.max_depth_jump.unwrap_or(f64::INFINITY) as f32;
    let (positions, triangles) = grid_triangles(vol, &depth, &mask, max_jump);
    if triangles.is_empty() {
        return Err(InitError::Empty {
            what: format!(
                "{} column(s) pass the threshold {threshold} but no 2 × 2 block of them does, so there is no surface; \
                 lower the threshold",
                mask.iter().filter(|&&k| k).count()
            ),
        });
    }
    let mut mesh =
        SurfaceMesh::from_triangles_with(&positions, &triangles, BuildOptions { split_non_manifold_vertices: true })?;
    let (positions, triangles) = if let Some(l) = params.target_edge_length {
        if !(l.is_finite() && l > 0.0) {
            return Err(InitError::InvalidParameter {
                name: "target_edge_length",
                value: l,
                reason: "must be a positive length in metres",
            });
        }
        uniform_remeshing(&mut mesh, l as f32, &RemeshParams::pmp())?;
        mesh.to_triangles()
    } else {
        (positions, triangles)
    };
    Ok(Surface { nx, ny, depth, albedo, threshold, mask, positions, triangles, mesh })
}

/// One vertex per kept column that belongs to a complete cell; two triangles per cell whose corner
/// depths span at most `max_jump`, facing −z.
fn grid_triangles(vol: &Volume, depth: &[f32], mask: &[bool], max_jump: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (nx, ny) = (vol.nx, vol.ny);
    let mut vertex_of = vec![u32::MAX; nx * ny];
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut vid = |c: usize, positions: &mut Vec<Vec3>| {
        if vertex_of[c] == u32::MAX {
            vertex_of[c] = positions.len() as u32;
            let (ix, iy) = (c % nx, c / nx);
            positions.push(Vec3::new(vol.x.at(ix) as f32, vol.y.at(iy) as f32, depth[c]));
        }
        vertex_of[c]
    };
    for iy in 0..ny.saturating_sub(1) {
        for ix in 0..nx.saturating_sub(1) {
            let c00 = ix + nx * iy;
            let (c10, c01, c11) = (c00 + 1, c00 + nx, c00 + nx + 1);
            if !(mask[c00] && mask[c10] && mask[c01] && mask[c11]) {
                continue;
            }
            let ds = [c00, c10, c01, c11].map(|c| depth[c]);
            let spread =
                ds.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) - ds.iter().fold(f32::INFINITY, |a, &b| a.min(b));
            if spread > max_jump {
                continue;
            }
            let [a, b, c, d] = [c00, c10, c01, c11].map(|c| vid(c, &mut positions));
            // With x and y increasing to the right and up (the usual case) (00, 11, 10) and (00, 01, 11)
            // are clockwise seen from +z, i.e. their normals point to −z, toward the wall. A decreasing
            // axis mirrors the grid, so the winding flips once per decreasing axis.
            let mirrored = (vol.x.step < 0.0) != (vol.y.step < 0.0);
            if mirrored {
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            } else {
                triangles.push([a, d, b]);
                triangles.push([a, c, d]);
            }
        }
    }
    (positions, triangles)
}
