//! **Front-view detail**: how much of the lateral detail a volume shows the mesh keeps — the holes, the gaps
//! between bars, the strokes of letters and the print a reconstruction should show as well as the blurry
//! volume it started from.
//!
//! Given the volume's front view `F` (its maximum over depth, [`Volume::max_projection`], on the volume's
//! columns: `nlos init --volume`, LCT on confocal grids, the phasor field on other scans) and the mesh's front
//! view `M` on the same grid (the first hit of the `+z` ray from each column's centre on the wall, valued at the
//! surface's albedo there, 1 without an albedo; a miss 0):
//! - the object's region `R`: the pixels of `F` above its Otsu threshold ([`otsu_threshold`], 256 bins), closed by
//!   two pixels (dilated then eroded, 8-neighbourhood) and with its holes filled, so that the gaps between
//!   bars lie inside `R` and count against a mesh that covers them;
//! - `r`: Pearson's correlation of `F` and `M` over `R` — 1 when the mesh is bright exactly where the volume
//!   is; a binary mask at `F`'s own threshold scores about 0.85 on a bar chart;
//! - coverage: the share of `F`'s above-threshold pixels the mesh is hit on.

use glam::Vec3;
use nlos_mesh::TriangleBvh;
use nlos_mesh::bvh::RayHit;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{InitError, Result};
use crate::surface::otsu_threshold;
use crate::volume::Volume;

/// The front-view detail of a mesh against a volume's front view (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrontViewDetail {
    /// Pearson's r of the two front views over the object's region (0 when either is constant there, NaN
    /// for a region of fewer than two pixels).
    pub r: f64,
    /// Share of the front view's above-threshold pixels where the mesh is hit.
    pub coverage: f64,
    /// Pixels in the object's region.
    pub region_pixels: usize,
    /// The front view's Otsu threshold.
    pub threshold: f32,
}

/// Scores the mesh `positions`/`triangles` against the front view of `volume` (module docs). A hit counts the
/// `albedo` of the hit triangle's corner with the largest barycentric weight where one is given (one value per
/// position), else 1.
///
/// # Errors
/// [`InitError::BadVolume`] for an invalid volume or one of constant front view (no object to score),
/// [`InitError::Mesh`] for a mesh the ray tracer refuses, [`InitError::InvalidParameter`] for an `albedo` not one
/// finite value ≥ 0 per position.
pub fn front_view_detail(
    volume: &Volume,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    albedo: Option<&[f32]>,
) -> Result<FrontViewDetail> {
    volume.validate()?;
    if let Some(a) = albedo
        && (a.len() != positions.len() || a.iter().any(|v| !(v.is_finite() && *v >= 0.0)))
    {
        return Err(InitError::InvalidParameter {
            name: "albedo",
            value: a.len() as f64,
            reason: "one finite value >= 0 per vertex",
        });
    }
    let bvh = TriangleBvh::from_triangles(positions, triangles)?;
    let (nx, ny) = (volume.nx, volume.ny);
    let value = volume.max_projection();
    let threshold = otsu_threshold(&value, 256).ok_or_else(|| InitError::BadVolume {
        reason: "the front view is constant: there is no object to score against".into(),
    })?;
    let above: Vec<bool> = value.iter().map(|&v| v > threshold).collect();
    let region = fill_holes(&erode(&dilate(&above, nx, ny, 2), nx, ny, 2), nx, ny);
    let hit_value = |hit: &RayHit| match albedo {
        Some(a) => a[triangles[hit.triangle as usize][nearest_corner(hit)] as usize],
        None => 1.0,
    };
    let mesh: Vec<Option<f32>> = (0..nx * ny)
        .into_par_iter()
        .map(|i| {
            let origin = Vec3::new(volume.x.at(i % nx) as f32, volume.y.at(i / nx) as f32, 0.0);
            bvh.ray_first_hit(origin, Vec3::Z, f32::INFINITY).map(|hit| hit_value(&hit))
        })
        .collect();
    let pairs: Vec<(f64, f64)> =
        (0..nx * ny).filter(|&i| region[i]).map(|i| (f64::from(value[i]), f64::from(mesh[i].unwrap_or(0.0)))).collect();
    let n_above = above.iter().filter(|&&a| a).count();
    let covered = above.iter().zip(&mesh).filter(|(a, m)| **a && m.is_some()).count();
    Ok(FrontViewDetail {
        r: pearson(&pairs),
        coverage: if n_above == 0 { 0.0 } else { covered as f64 / n_above as f64 },
        region_pixels: pairs.len(),
        threshold,
    })
}

/// Which corner (0, 1 or 2) of the hit triangle lies nearest the hit: the one of largest barycentric weight.
fn nearest_corner(hit: &RayHit) -> usize {
    let b = hit.barycentric.to_array();
    (0..3).fold(0, |best, k| if b[k] > b[best] { k } else { best })
}

/// Whether any pixel within `radius` (Chebyshev) of each pixel is set.
fn dilate(mask: &[bool], nx: usize, ny: usize, radius: usize) -> Vec<bool> {
    morph(mask, nx, ny, radius, true)
}

/// Whether every pixel within `radius` (Chebyshev, inside the image) of each pixel is set.
fn erode(mask: &[bool], nx: usize, ny: usize, radius: usize) -> Vec<bool> {
    morph(mask, nx, ny, radius, false)
}

fn morph(mask: &[bool], nx: usize, ny: usize, radius: usize, any: bool) -> Vec<bool> {
    (0..nx * ny)
        .map(|i| {
            let (x, y) = (i % nx, i / nx);
            let xs = x.saturating_sub(radius)..=(x + radius).min(nx - 1);
            let mut window = (y.saturating_sub(radius)..=(y + radius).min(ny - 1))
                .flat_map(|yy| xs.clone().map(move |xx| mask[xx + nx * yy]));
            if any { window.any(|m| m) } else { window.all(|m| m) }
        })
        .collect()
}

/// `mask` with every unset region that does not reach the image's border set (4-neighbourhood flood fill
/// of the background from the border).
fn fill_holes(mask: &[bool], nx: usize, ny: usize) -> Vec<bool> {
    let mut outside = vec![false; nx * ny];
    let mut stack: Vec<usize> = (0..nx * ny)
        .filter(|&i| !mask[i] && (i % nx == 0 || i % nx == nx - 1 || i / nx == 0 || i / nx == ny - 1))
        .collect();
    for &i in &stack {
        outside[i] = true;
    }
    while let Some(i) = stack.pop() {
        let (x, y) = (i % nx, i / nx);
        let neighbours = [
            (x > 0).then(|| i - 1),
            (x + 1 < nx).then(|| i + 1),
            (y > 0).then(|| i - nx),
            (y + 1 < ny).then(|| i + nx),
        ];
        for j in neighbours.into_iter().flatten() {
            if !mask[j] && !outside[j] {
                outside[j] = true;
                stack.push(j);
            }
        }
    }
    outside.iter().map(|&o| !o).collect()
}

/// Pearson's correlation of the pairs; 0 when either side is constant (a mesh that shows no detail), NaN for
/// fewer than two pairs.
fn pearson(pairs: &[(f64, f64)]) -> f64 {
    let n = pairs.len() as f64;
    if pairs.len() < 2 {
        return f64::NAN;
    }
    let (sa, sb) = pairs.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (ma, mb) = (sa / n, sb / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in pairs {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa == 0.0 || sbb == 0.0 {
        return 0.0;
    }
    sab / (saa * sbb).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_region_closes_gaps_and_fills_holes() {
        // A ring with a one-pixel gap in a 13 × 13 image: closing bridges the gap, and the hole fills.
        let (nx, ny) = (13, 13);
        let ring: Vec<bool> = (0..nx * ny)
            .map(|i| {
                let (x, y) = (i % nx, i / nx);
                let on = (4..=8).contains(&x) && (4..=8).contains(&y) && (x == 4 || x == 8 || y == 4 || y == 8);
                on && !(x == 6 && y == 4)
            })
            .collect();
        let closed = erode(&dilate(&ring, nx, ny, 2), nx, ny, 2);
        assert!(closed[6 + nx * 4], "the gap is bridged");
        let region = fill_holes(&closed, nx, ny);
        assert!(region[6 + nx * 6], "the hole is filled");
        assert!(!region[0] && !region[12 + nx * 12] && !region[2 + nx * 6]);
        assert!((pearson(&[(0.0, 1.0), (1.0, 3.0), (2.0, 5.0)]) - 1.0).abs() < 1e-12);
        assert_eq!(pearson(&[(0.0, 1.0), (1.0, 1.0)]), 0.0);
        assert!(pearson(&[(0.0, 1.0)]).is_nan());
    }
}
