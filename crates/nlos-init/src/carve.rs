//! Space carving from first-returning photons (Tsai, Xia, Sankaranarayanan & Gkioulekas, "The geometry
//! of first-returning photons for non-line-of-sight imaging", CVPR 2017).
//!
//! A measurement with laser spot `l` and sensor spot `s` whose first photon arrives at path length `t₁`
//! proves that the open ellipsoid `|x − l| + |x − s| < t₁` (a ball of radius `t₁/2` around the spot when
//! confocal) holds no surface. Every such region is carved; what faces the wall is the boundary of the
//! union. Because each region is convex, symmetric about the wall plane and contains its foci, its
//! intersection with the vertical line above a wall point `(x, y)` is an interval `[0, z(x, y))`, so the
//! carved depth of a column is the maximum of these `z` over all measurements (closed form for a ball,
//! bisection for an ellipsoid). No voxel grid is needed for the carving itself.
//!
//! Where the carved boundary is real surface, many measurements' regions touch it (their first photons
//! come from there); over empty space it is the cap of a single region. The returned [`Volume`] holds, at
//! the carved depth of each column, the number of regions whose boundary lies within one depth bin of
//! it, and zero elsewhere; [`crate::volume_to_surface`] then keeps the well-supported columns.
//!
//! First returns: after gating and bin merging, the first bin whose value exceeds
//! `max(median + k·1.4826·MAD, fraction·max)` of its histogram (defaults `k = 5`, `fraction = 0.2`); a
//! histogram without such a bin carves nothing.

use rayon::prelude::*;

use nlos_transient::{Layout, Transient};

use crate::error::{InitError, Result};
use crate::prep::Gate;
use crate::volume::{Axis, Volume};

/// Parameters of [`carve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CarveParams {
    /// Removal of the direct light. Default [`Gate::Auto`].
    pub gate: Gate,
    /// Sum this many consecutive bins first (≥ 1; default 1).
    pub bin_merge: usize,
    /// Noise threshold in robust standard deviations above the median. Default 5.
    pub noise_sigmas: f32,
    /// Minimum first-return level as a fraction of the histogram's maximum. Default 0.2.
    pub peak_fraction: f32,
}

impl Default for CarveParams {
    fn default() -> Self {
        Self { gate: Gate::Auto, bin_merge: 1, noise_sigmas: 5.0, peak_fraction: 0.2 }
    }
}

/// First-return path length of each measurement (metres; `None` when nothing rises above the noise).
pub fn first_returns(t: &Transient, params: &CarveParams) -> Result<Vec<Option<f64>>> {
    if params.bin_merge == 0 {
        return Err(InitError::InvalidParameter { name: "bin_merge", value: 0.0, reason: "must be at least 1" });
    }
    if !(params.noise_sigmas.is_finite() && params.noise_sigmas >= 0.0) {
        return Err(InitError::InvalidParameter {
            name: "noise_sigmas",
            value: params.noise_sigmas as f64,
            reason: "must be finite and ≥ 0",
        });
    }
    if !(0.0..=1.0).contains(&params.peak_fraction) {
        return Err(InitError::InvalidParameter {
            name: "peak_fraction",
            value: params.peak_fraction as f64,
            reason: "must lie in [0, 1]",
        });
    }
    if t.time().includes_device_legs {
        return Err(InitError::DeviceLegs);
    }
    let time = *t.time();
    let gate = match params.gate {
        Gate::None => f64::NEG_INFINITY,
        Gate::Auto => t.direct_light_end(),
        Gate::Path(g) if g.is_finite() => g,
        Gate::Path(g) => {
            return Err(InitError::InvalidParameter { name: "gate", value: g, reason: "must be a finite path length" });
        }
    };
    let first = (0..time.bins).find(|&k| time.bin_start(k) >= gate).unwrap_or(time.bins);
    let merge = params.bin_merge;
    let n = (time.bins - first) / merge;
    let out = t
        .histograms()
        .collect::<Vec<_>>()
        .par_iter()
        .map(|h| {
            let merged: Vec<f32> = (0..n).map(|j| h[first + j * merge..first + (j + 1) * merge].iter().sum()).collect();
            if let Some(i) = merged.iter().position(|v| !v.is_finite()) {
                return Err(InitError::NonFinite { what: "transient data", index: i });
            }
            let mut sorted = merged.clone();
            sorted.sort_by(f32::total_cmp);
            let Some(&max) = sorted.last() else { return Ok(None) };
            let median = sorted[sorted.len() / 2];
            let mut dev: Vec<f32> = sorted.iter().map(|v| (v - median).abs()).collect();
            dev.sort_by(f32::total_cmp);
            let mad = dev[dev.len() / 2];
            let level = (median + params.noise_sigmas * 1.4826 * mad).max(params.peak_fraction * max);
            // A flat (e.g. all-zero) histogram has max == level: no return.
            Ok(merged.iter().position(|&v| v > level).map(|j| time.bin_start(first + j * merge)))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(out)
}

/// Space carving (see the module docs). The sensor points must form a grid (the scan points of a
/// confocal scan), which becomes the volume's x–y grid; depth bins are half the (merged) bin width.
///
/// # Errors
/// [`InitError::NotGrid`] when the sensor points are a list, [`InitError::DeviceLegs`],
/// [`InitError::InvalidParameter`], [`InitError::NonFinite`], [`InitError::Empty`] when no
/// measurement has a first return.
pub fn carve(t: &Transient, params: &CarveParams) -> Result<Volume> {
    let sensors = t.scan().sensors();
    let Layout::Grid { nx, ny } = sensors.layout else {
        return Err(InitError::NotGrid { method: "space carving" });
    };
    if nx < 2 || ny < 2 {
        return Err(InitError::BadGrid { method: "space carving", reason: format!("{nx} × {ny} grid") });
    }
    let returns = first_returns(t, params)?;
    let regions: Vec<(glam::DVec3, glam::DVec3, f64)> = returns
        .iter()
        .enumerate()
        .filter_map(|(m, r)| {
            let me = t.scan().measurement(m);
            r.map(|t1| (me.laser.as_dvec3(), me.sensor.as_dvec3(), t1))
        })
        .collect();
    let Some(t_max) = regions.iter().map(|r| r.2).reduce(f64::max) else {
        return Err(InitError::Empty {
            what: "no measurement has a first return above the noise threshold: lower noise_sigmas or \
                   peak_fraction, or check the gate"
                .into(),
        });
    };
    let dz = 0.5 * t.time().bin_width * params.bin_merge as f64;
    let nz = ((0.5 * t_max / dz).ceil() as usize + 2).max(2);
    let p = &sensors.points;
    let (x0, y0) = (p[0].x as f64, p[0].y as f64);
    let dx = (p[nx - 1].x as f64 - x0) / (nx - 1) as f64;
    let dy = (p[nx * (ny - 1)].y as f64 - y0) / (ny - 1) as f64;
    let mut data = vec![0.0f32; nx * ny * nz];
    data.par_chunks_mut(nz).enumerate().for_each(|(c, col)| {
        let q = p[c].as_dvec3();
        let depths: Vec<f64> = regions.iter().map(|&(l, s, t1)| carved_depth(q.x, q.y, l, s, t1)).collect();
        let z = depths.iter().copied().fold(0.0, f64::max);
        if z <= 0.0 {
            return;
        }
        let support = depths.iter().filter(|&&d| d > 0.0 && z - d <= dz).count();
        let iz = ((z / dz) as usize).min(nz - 1);
        col[iz] = support as f32;
    });
    Ok(Volume {
        nx,
        ny,
        nz,
        x: Axis { start: x0, step: dx },
        y: Axis { start: y0, step: dy },
        z: Axis { start: 0.5 * dz, step: dz },
        data,
    })
}

/// Depth at which the vertical line above `(x, y, 0)` leaves the region `|X − l| + |X − s| < t1`
/// (0 when `(x, y, 0)` is outside it).
fn carved_depth(x: f64, y: f64, l: glam::DVec3, s: glam::DVec3, t1: f64) -> f64 {
    let path = |z: f64| {
        let q = glam::DVec3::new(x, y, z);
        (q - l).length() + (q - s).length()
    };
    if path(0.0) >= t1 {
        return 0.0;
    }
    if (l - s).length_squared() < 1e-18 {
        // Confocal: a ball of radius t1/2 about l (the wall points have z = 0).
        let r2 = 0.25 * t1 * t1 - (x - l.x).powi(2) - (y - l.y).powi(2);
        return r2.max(0.0).sqrt();
    }
    // path(z) increases with z ≥ 0 and exceeds t1 at z = t1: bisection, 50 halvings (≪ 1 nm).
    let (mut lo, mut hi) = (0.0, t1);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if path(mid) < t1 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}
