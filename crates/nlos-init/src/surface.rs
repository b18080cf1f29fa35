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

/// What the hysteresis of [`SurfaceParams::grow_threshold`] is relative to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GrowReference {
    /// The largest column maximum of the volume.
    #[default]
    Volume,
    /// The largest column maximum of each connected region of the starting mask: a dim part apart from a
    /// bright one grows as far down its own flanks as the bright one does.
    Region,
}

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
///
/// The defaults are the plain extraction (Otsu's threshold, largest region, arg-max voxel depth); see
/// [`SurfaceParams::object`] for the settings tuned for compact objects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// Mask threshold: where the mask starts before it grows. Default [`Threshold::Otsu`].
    pub threshold: Threshold,
    /// Hysteresis (Canny 1986): columns whose maximum reaches this fraction (0–1) of the largest column
    /// maximum join the mask when they connect (4-neighbours, within [`Self::max_depth_jump`]) to a column
    /// that passes [`Self::threshold`]. The LCT albedo of grazing or distant parts of an object (a rabbit's
    /// ears, the flanks) falls well below Otsu's threshold while a bright halo surrounds the object, so one
    /// threshold either loses the parts or keeps the halo. `None` or a value above the threshold's own
    /// fraction grows nothing. Default `None` ([`SurfaceParams::object`]: `Some(0.1)`).
    pub grow_threshold: Option<f32>,
    /// Noise floor of the growth: a column joins the mask by hysteresis only when its maximum is also at
    /// least `median + k · 1.4826 · MAD` of all column maxima (a robust noise level: the empty columns are
    /// the majority for a compact object; never above the starting threshold). With a background in the
    /// capture (ambient light, dark counts) every column's maximum rises, and growing down to
    /// [`Self::grow_threshold`] alone took half the wall (the bunny at 100 photons per measurement with
    /// 0.01 background counts per bin: 8,667 of 16,384 evaluation pixels, Chamfer 156 mm; with k = 1: 4,177
    /// pixels, coverage 95 %). k = 1 leaves the clean 1,000-photon bunny capture unchanged; k = 2 trimmed
    /// it too (initial coverage 94.6 → 91.2 %, final 85.7 %). Default `None` ([`SurfaceParams::object`]:
    /// `Some(1.0)`).
    pub grow_noise_sigmas: Option<f32>,
    /// What [`Self::grow_threshold`] is a fraction of. Default [`GrowReference::Volume`].
    pub grow_reference: GrowReference,
    /// Only voxels at least this deep are considered (metres; default `None`).
    pub min_depth: Option<f64>,
    /// Only voxels at most this deep are considered (metres; default `None`).
    pub max_depth: Option<f64>,
    /// Keep only the largest 4-connected region of the mask and those of at least
    /// [`Self::min_region_fraction`] of its size. Default `true`.
    pub largest_component: bool,
    /// With [`Self::largest_component`], also keep every region with at least this fraction (0–1) of the
    /// largest region's columns (parts that the depth-jump rule separates from the body, e.g. ears behind
    /// a head). Default 1: only the largest ([`SurfaceParams::object`]: 0.05).
    pub min_region_fraction: f64,
    /// Neighbouring columns whose depths differ by more than this (metres) are not connected, neither
    /// for the connected regions nor in the triangulation, so that objects at different depths that
    /// overlap in the front view stay apart. Default `Some(0.05)`; `None` connects by the mask only.
    pub max_depth_jump: Option<f64>,
    /// Refine each column's depth to the vertex of the parabola through the maximum voxel and its two
    /// neighbours (a sub-voxel peak; the LCT blurs a surface over several voxels in depth). Default `false`
    /// ([`SurfaceParams::object`]: `true`).
    pub subvoxel: bool,
    /// Rings of columns added around the mask (4-neighbours of the mask, then of the first ring, …) where
    /// the column maximum is still positive; the mesh otherwise ends at the centres of the outermost kept
    /// columns, half a column inside the silhouette. Default 0.
    pub rim_rings: usize,
    /// How fast the columns outside the core ([`Self::core_fraction`]) and the rim rings recede, as a
    /// multiple of the column spacing: a column `k` columns from the nearest core column lies
    /// `rim_recession · k² · spacing` behind it, like the silhouette of a smooth closed object (where the
    /// surface turns parallel to the line of sight). The LCT depth of the dim outer columns is itself too
    /// shallow there: the lateral blur mixes in the brighter, nearer interior. Default 1; 0 extrapolates
    /// flat.
    pub rim_recession: f64,
    /// The core of the mask: kept columns whose maximum reaches this fraction (0–1) of the largest column
    /// maximum (or the starting threshold, when lower). Every other kept column (the dim rim the lateral blur
    /// spreads around an object, and the rim rings) takes the depth of the nearest core column plus
    /// `rim_recession · spacing · k²`, `k` its distance to that column in columns. Default `None`: every
    /// kept column is core (only the rim rings recede) ([`SurfaceParams::object`]: `Some(0.2)`).
    pub core_fraction: Option<f32>,
    /// Turn the mesh back toward its boundary: every vertex within this distance (metres) of the boundary
    /// recedes along +z by a quarter circle of this radius ([`crate::rim::round_rim`]; the per-column
    /// [`Surface::depth`] is not changed). Default `None`: on the bunny at Tsai et al. 2019's setup it trades mean depth error
    /// for coverage (docs/accuracy.md).
    pub rim_radius: Option<f64>,
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
            grow_threshold: None,
            grow_noise_sigmas: None,
            grow_reference: GrowReference::Volume,
            min_depth: None,
            max_depth: None,
            largest_component: true,
            min_region_fraction: 1.0,
            max_depth_jump: Some(0.05),
            subvoxel: false,
            rim_rings: 0,
            rim_recession: 1.0,
            core_fraction: None,
            rim_radius: None,
            smoothing_iterations: 0,
            target_edge_length: None,
        }
    }
}

impl SurfaceParams {
    /// Settings for a compact object seen through the LCT (`nlos init --method lct` without
    /// `--threshold`): seeded at Otsu's threshold and grown (hysteresis) down to 10 % of the largest
    /// column maximum, every region of at least 5 % of the largest's size kept, sub-voxel peaks, and the
    /// columns below 20 % of the maximum receding from the core (`rim_recession` 1). Tuned on two
    /// renderings of the Stanford bunny 0.4 m behind the wall (Tsai et al. 2019's setup at 1,000 photons per
    /// measurement and the independent path tracer's `reference/bunny_mc.hdf5`, 64 × 64 confocal over
    /// 0.5 m), where against Otsu's threshold alone it doubles the coverage, and against a plain 10 %
    /// threshold (the same coverage) it lowers the mean depth error by 6–13 %, the Chamfer distance by
    /// a third and the normal error by a quarter (`tests/reference_bunny.rs`). Not for flat, letter-like
    /// scenes: growing reaches into the noise of the measured Stanford captures.
    pub fn object() -> Self {
        Self {
            grow_threshold: Some(0.1),
            grow_noise_sigmas: Some(1.0),
            min_region_fraction: 0.05,
            subvoxel: true,
            core_fraction: Some(0.2),
            ..Self::default()
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
/// [`InitError::InvalidParameter`] for a bad threshold, grow threshold, region fraction, rim recession,
/// depth jump or edge length, [`InitError::Empty`] when no column passes the threshold or no grid cell
/// has four kept corners, [`InitError::Mesh`] when remeshing fails.
pub fn volume_to_surface(vol: &Volume, params: &SurfaceParams) -> Result<Surface> {
    volume_to_surface_where(vol, params, &|_| true)
}

/// [`volume_to_surface`] restricted to the columns whose point `(x, y, depth)` (metres, before any rim
/// recession or smoothing) passes `admit`: the others leave the mask right after the threshold and the
/// hysteresis, before the connected regions are formed. `nlos_optim` uses it to extract only the parts of
/// a residual volume away from the surface it already has.
///
/// # Errors
/// As [`volume_to_surface`]; [`InitError::Empty`] also when `admit` rejects every column that could form
/// a surface.
pub fn volume_to_surface_where(vol: &Volume, params: &SurfaceParams, admit: &dyn Fn(Vec3) -> bool) -> Result<Surface> {
    vol.validate()?;
    validate(params)?;
    let (nx, ny) = (vol.nx, vol.ny);
    let (mut depth, albedo) = vol.depth_map(params.min_depth, params.max_depth)?;
    if params.subvoxel {
        refine_peaks(vol, &mut depth);
    }
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
    let max_jump = params.max_depth_jump.unwrap_or(f64::INFINITY) as f32;
    let mut mask: Vec<bool> = albedo.iter().map(|&a| a >= threshold && a > 0.0).collect();
    if let Some(g) = params.grow_threshold {
        let floor = params.grow_noise_sigmas.map_or(0.0, |k| noise_floor(&albedo, k));
        let low = |peak: f32| (g * peak).max(floor).min(threshold);
        let seeds: Vec<(usize, f32)> = match params.grow_reference {
            GrowReference::Volume => (0..mask.len()).filter(|&c| mask[c]).map(|c| (c, low(max))).collect(),
            GrowReference::Region => {
                let (label, sizes) = connected_components(&mask, nx, ny, Some((&depth, max_jump)));
                let mut peak = vec![0f32; sizes.len()];
                for (c, &l) in label.iter().enumerate().filter(|(_, l)| **l != u32::MAX) {
                    peak[l as usize] = peak[l as usize].max(albedo[c]);
                }
                (0..mask.len()).filter(|&c| mask[c]).map(|c| (c, low(peak[label[c] as usize]))).collect()
            }
        };
        grow(&mut mask, nx, ny, seeds, &albedo, &depth, max_jump);
    }
    for (c, m) in mask.iter_mut().enumerate() {
        if *m {
            let (ix, iy) = (c % nx, c / nx);
            *m = admit(Vec3::new(vol.x.at(ix) as f32, vol.y.at(iy) as f32, depth[c]));
        }
    }
    if params.largest_component {
        let jump = params.max_depth_jump.map(|j| (depth.as_slice(), j as f32));
        let (label, sizes) = connected_components(&mask, nx, ny, jump);
        if let Some(best) = (0..sizes.len()).max_by_key(|&i| sizes[i]) {
            // A fraction of 1 keeps exactly one region, as before, even when two tie.
            let min_size = (params.min_region_fraction * sizes[best] as f64).ceil() as usize;
            let keep = |l: u32| l as usize == best || params.min_region_fraction < 1.0 && sizes[l as usize] >= min_size;
            for (m, &l) in mask.iter_mut().zip(&label) {
                *m = l != u32::MAX && keep(l);
            }
        }
    }
    let spacing = vol.x.step.abs().min(vol.y.step.abs());
    let core: Vec<bool> = match params.core_fraction {
        Some(f) => {
            let t = (f * max).min(threshold);
            mask.iter().zip(&albedo).map(|(&m, &a)| m && a >= t).collect()
        }
        None => mask.clone(),
    };
    for _ in 0..params.rim_rings {
        add_rim_ring(&mut mask, &albedo, nx, ny);
    }
    recede_rim(&mask, &core, &mut depth, nx, params.rim_recession * spacing);
    for _ in 0..params.smoothing_iterations {
        let prev = depth.clone();
        for iy in 0..ny {
            for ix in 0..nx {
                let c = ix + nx * iy;
                if !mask[c] {
                    continue;
                }
                let (mut s, mut n) = (prev[c] as f64, 1.0);
                for nb in neighbours(c, nx, ny).into_iter().flatten() {
                    if mask[nb] {
                        s += prev[nb] as f64;
                        n += 1.0;
                    }
                }
                depth[c] = (s / n) as f32;
            }
        }
    }
    let (mut positions, triangles) = grid_triangles(vol, &depth, &mask, &core, max_jump);
    if let Some(r) = params.rim_radius {
        crate::rim::round_rim(&mut positions, &triangles, r)?;
    }
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
        uniform_remeshing(&mut mesh, l as f32, &RemeshParams::pmp())?;
        mesh.to_triangles()
    } else {
        (positions, triangles)
    };
    Ok(Surface { nx, ny, depth, albedo, threshold, mask, positions, triangles, mesh })
}

fn validate(params: &SurfaceParams) -> Result<()> {
    let bad = |name, value: f64, reason| Err(InitError::InvalidParameter { name, value, reason });
    if let Some(j) = params.max_depth_jump
        && !(j.is_finite() && j > 0.0)
    {
        return bad("max_depth_jump", j, "must be a positive length (m)");
    }
    if let Some(g) = params.grow_threshold
        && !(0.0..=1.0).contains(&g)
    {
        return bad("grow_threshold", g as f64, "a fraction of the largest column maximum lies in [0, 1]");
    }
    if let Some(k) = params.grow_noise_sigmas
        && !(k.is_finite() && k >= 0.0)
    {
        return bad("grow_noise_sigmas", k as f64, "a number of robust standard deviations: finite and >= 0");
    }
    if !(0.0..=1.0).contains(&params.min_region_fraction) {
        return bad(
            "min_region_fraction",
            params.min_region_fraction,
            "a fraction of the largest region lies in [0, 1]",
        );
    }
    if !(params.rim_recession.is_finite() && params.rim_recession >= 0.0) {
        return bad("rim_recession", params.rim_recession, "a multiple of the column spacing, finite and ≥ 0");
    }
    if let Some(r) = params.rim_radius
        && !(r.is_finite() && r > 0.0)
    {
        return bad("rim_radius", r, "the rounding radius is a length in metres, finite and > 0");
    }
    if let Some(l) = params.target_edge_length
        && !(l.is_finite() && l > 0.0)
    {
        return bad("target_edge_length", l, "must be a positive length in metres");
    }
    Ok(())
}

/// The 4-neighbours of column `c` on an `nx × ny` grid.
fn neighbours(c: usize, nx: usize, ny: usize) -> [Option<usize>; 4] {
    let (ix, iy) = (c % nx, c / nx);
    [(ix > 0).then(|| c - 1), (ix + 1 < nx).then(|| c + 1), (iy > 0).then(|| c - nx), (iy + 1 < ny).then(|| c + nx)]
}

/// Moves each column's depth from its maximum voxel to the vertex of the parabola through that voxel and
/// its two neighbours (at most half a voxel; unchanged at the ends of the column or without a strict
/// maximum).
fn refine_peaks(vol: &Volume, depth: &mut [f32]) {
    let nz = vol.nz;
    for (c, d) in depth.iter_mut().enumerate() {
        let iz = ((*d as f64 - vol.z.start) / vol.z.step).round();
        if !(iz >= 1.0 && iz + 1.0 < nz as f64) {
            continue;
        }
        let iz = iz as usize;
        let col = &vol.data[c * nz..(c + 1) * nz];
        let (a, b, e) = (col[iz - 1] as f64, col[iz] as f64, col[iz + 1] as f64);
        let curvature = a - 2.0 * b + e;
        if curvature < 0.0 && b >= a && b >= e {
            let shift = (0.5 * (a - e) / curvature).clamp(-0.5, 0.5);
            *d = vol.z.at(iz) as f32 + (shift * vol.z.step) as f32;
        }
    }
}

/// `median + k · 1.4826 · MAD` of the finite values of `a` (0 when there are none): the median absolute
/// deviation scaled to estimate a Gaussian's standard deviation (Hampel 1974; Rousseeuw & Croux 1993), so
/// `k` counts robust sigmas and the floor ignores the bright minority of object columns.
fn noise_floor(a: &[f32], k: f32) -> f32 {
    let mut v: Vec<f32> = a.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let median = |v: &mut Vec<f32>| {
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    let m = median(&mut v);
    let mut dev: Vec<f32> = v.iter().map(|x| (x - m).abs()).collect();
    m + k * 1.4826 * median(&mut dev)
}

/// Hysteresis: adds to `mask` every column whose maximum reaches the level of a seed it connects to through
/// such columns (neighbours within `max_jump` in depth); `seeds` are the mask's columns, each with its level.
fn grow(
    mask: &mut [bool],
    nx: usize,
    ny: usize,
    seeds: Vec<(usize, f32)>,
    albedo: &[f32],
    depth: &[f32],
    max_jump: f32,
) {
    let mut stack = seeds;
    while let Some((c, low)) = stack.pop() {
        for n in neighbours(c, nx, ny).into_iter().flatten() {
            if !mask[n] && albedo[n] >= low && albedo[n] > 0.0 && (depth[n] - depth[c]).abs() <= max_jump {
                mask[n] = true;
                stack.push((n, low));
            }
        }
    }
}

/// Adds one ring of columns around `mask`: every column outside it with a positive maximum and a kept
/// 4-neighbour.
fn add_rim_ring(mask: &mut [bool], albedo: &[f32], nx: usize, ny: usize) {
    let ring: Vec<usize> = (0..mask.len())
        .filter(|&c| !mask[c] && albedo[c] > 0.0 && neighbours(c, nx, ny).into_iter().flatten().any(|n| mask[n]))
        .collect();
    for c in ring {
        mask[c] = true;
    }
}

/// Every kept column outside `core` takes the depth of the nearest core column (grid distance `k`
/// columns, Euclidean) plus `step · k²`; of equally near core columns the nearest to the wall counts.
fn recede_rim(mask: &[bool], core: &[bool], depth: &mut [f32], nx: usize, step: f64) {
    let cores: Vec<(i64, i64, f32)> =
        (0..core.len()).filter(|&c| core[c]).map(|c| ((c % nx) as i64, (c / nx) as i64, depth[c])).collect();
    if cores.is_empty() {
        return;
    }
    for c in 0..mask.len() {
        if !mask[c] || core[c] {
            continue;
        }
        let (x, y) = ((c % nx) as i64, (c / nx) as i64);
        let mut best = (i64::MAX, f32::INFINITY);
        for &(cx, cy, d) in &cores {
            let k2 = (cx - x).pow(2) + (cy - y).pow(2);
            if k2 < best.0 || k2 == best.0 && d < best.1 {
                best = (k2, d);
            }
        }
        depth[c] = best.1 + (step * best.0 as f64) as f32;
    }
}

/// One vertex per kept column that belongs to a complete cell; two triangles per cell whose core corner
/// depths span at most `max_jump`, facing −z.
fn grid_triangles(
    vol: &Volume,
    depth: &[f32],
    mask: &[bool],
    core: &[bool],
    max_jump: f32,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
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
            // Receded rim columns take their depth from the core, so only core corners can be torn apart.
            let ds: Vec<f32> = [c00, c10, c01, c11].into_iter().filter(|&c| core[c]).map(|c| depth[c]).collect();
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
