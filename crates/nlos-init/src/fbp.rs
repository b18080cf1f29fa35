//! Filtered backprojection for confocal and exhaustive scans.
//!
//! Backprojection is the adjoint of the light-cone forward model: the LCT pipeline with `conj(Ĥ)` in
//! place of the Wiener filter (O'Toole et al. 2018, Sec. "Reconstruction"; `isbackprop` in their
//! `cnlos_reconstruction.m`). Its blur is sharpened, as in Velten et al. (Nat. Commun. 2012) and the
//! FBP of Lindell et al.'s f-k code (`filterLaplacian`), by a negative second derivative, here along
//! depth only and taken in the LCT's `u = t²` domain before resampling back: `(2v(u) − v(u − 2) −
//! v(u + 2)) / 4`, the square of the central difference (0 within two bins of either end), then clamped
//! at 0. The three-point rule `2v(u) − v(u − 1) − v(u + 1)` would amplify the Nyquist component
//! fourfold, and the backprojection's discretisation ripple then becomes a comb of spurious peaks in
//! front of the surface (seen on rendered planes, `tests/rendered.rs`); the five-point rule passes none. The lateral terms of the full 3-D
//! Laplacian erase the interior of a flat surface wider than the blur (a plane's backprojection is
//! laterally constant) and leave only its outline; the depth term alone turns the backprojection's
//! ramp at the surface into a peak. Taking it in `u`, where the backprojection is smooth, avoids the
//! staircase that resampling to `t` creates near the wall (every early time bin comes from the first
//! u-bin).
//!
//! **Exhaustive scans** (laser and sensor grids apart) take the direct path, `O(voxels × measurements)`:
//! every voxel `x` of a grid over the sensor points (their `nx × ny` grid in x and y, depth step half the
//! merged bin width, as the confocal volume) sums, over all measurements `(l, s)`, the histogram value at
//! its path length `τ = |x − l| + |x − s|` (linear interpolation between bin centres: the ellipsoidal
//! backprojection of Velten et al. 2012, Eq. 1 there), weighted by `(|x − l|·|x − s|)²` for
//! [`Model::Lambert`] and `|x − l|·|x − s|` for [`Model::Retroreflective`] (the inverse of the
//! radiometric fall-off, as the confocal path's `t⁴` and `t²`); then the same five-point depth filter,
//! here along z, and the clamp. Parallel over columns with rayon. A confocal scan always takes the fast
//! path.

use glam::DVec3;
use rayon::prelude::*;

use nlos_transient::{Layout, Transient};

use crate::error::{InitError, Result};
use nlos_brdf::Model;

use crate::lct::{LctParams, lct_grid, volume_from_grid};
use crate::prep;
use crate::prep::Gate;
use crate::volume::{Axis, Volume};

/// Parameters of [`fbp`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FbpParams {
    /// The reflectance model the back-projection is weighted for (each leg's distance to half its
    /// [`Model::distance_power`]). Default [`Model::Lambert`].
    pub reflectance: Model,
    /// Sum this many consecutive bins before reconstructing (≥ 1; default 1 = none).
    pub bin_merge: usize,
    /// Removal of the direct light. Default [`Gate::Auto`].
    pub gate: Gate,
    /// Ignore path lengths beyond `2 × max_depth` (metres; default `None`).
    pub max_depth: Option<f64>,
}

impl Default for FbpParams {
    fn default() -> Self {
        Self { reflectance: Model::Lambert, bin_merge: 1, gate: Gate::Auto, max_depth: None }
    }
}

/// Laplacian-filtered backprojection of a confocal grid capture (through the LCT pipeline) or of an
/// exhaustive capture whose sensor points form a grid (direct ellipsoidal backprojection; see the
/// [module docs](self)).
///
/// # Errors
/// Confocal: as [`crate::lct()`] (`snr` aside). Exhaustive: [`InitError::NotGrid`] / [`InitError::BadGrid`]
/// for sensor points that are not a regular `≥ 2 × 2` grid, [`InitError::DeviceLegs`],
/// [`InitError::InvalidParameter`] (bin_merge, gate, max_depth), [`InitError::Empty`],
/// [`InitError::NonFinite`].
pub fn fbp(t: &Transient, params: &FbpParams) -> Result<Volume> {
    if !t.scan().is_confocal() {
        return fbp_exhaustive(t, params);
    }
    let p = LctParams {
        reflectance: params.reflectance,
        bin_merge: params.bin_merge,
        gate: params.gate,
        max_depth: params.max_depth,
        backprojection: true,
        ..LctParams::default()
    };
    let g = prep::prepare(t, "filtered backprojection", params.gate, params.max_depth, params.bin_merge)?;
    let data = lct_grid(&g, &p, true);
    Ok(volume_from_grid(&g, data))
}

/// The five-point negative second difference `(2v[i] − v[i−2] − v[i+2]) / 4` of one lane (0 within two
/// samples of either end), clamped at 0.
fn depth_filter(v: &[f32], out: &mut [f32]) {
    let n = v.len();
    out.fill(0.0);
    for i in 2..n.saturating_sub(2) {
        out[i] = (0.25 * (2.0 * v[i] - v[i - 2] - v[i + 2])).max(0.0);
    }
}

/// Direct ellipsoidal backprojection of an exhaustive capture (module docs).
fn fbp_exhaustive(t: &Transient, params: &FbpParams) -> Result<Volume> {
    const METHOD: &str = "filtered backprojection";
    let sensors = t.scan().sensors();
    let Layout::Grid { nx, ny } = sensors.layout else {
        return Err(InitError::NotGrid { method: METHOD });
    };
    let p = &sensors.points;
    if nx < 2 || ny < 2 || p.len() != nx * ny {
        return Err(InitError::BadGrid {
            method: METHOD, reason: format!("{nx} × {ny} grid with {} points", p.len())
        });
    }
    if t.time().includes_device_legs {
        return Err(InitError::DeviceLegs);
    }
    let merge = params.bin_merge;
    if merge == 0 {
        return Err(InitError::InvalidParameter { name: "bin_merge", value: 0.0, reason: "must be at least 1" });
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
    let bins = time.bins / merge;
    let delta = time.bin_width * merge as f64;
    // Deepest voxel: half the last path, or max_depth.
    let mut z_max = 0.5 * (time.t0 + bins as f64 * delta);
    if let Some(d) = params.max_depth {
        if !(d.is_finite() && d > 0.0) {
            return Err(InitError::InvalidParameter {
                name: "max_depth",
                value: d,
                reason: "must be a positive depth (m)",
            });
        }
        z_max = z_max.min(d);
    }
    let dz = 0.5 * delta;
    let nz = (z_max / dz).floor().min(1e7) as usize;
    if bins < 2 || nz < 5 {
        return Err(InitError::Empty {
            what: format!(
                "{bins} merged bin(s) and {nz} depth voxel(s) after merging {merge} bins and capping at max_depth \
                 {:?} m; raise max_depth or lower bin_merge",
                params.max_depth
            ),
        });
    }
    // Gated, merged histograms.
    let first = (0..time.bins).find(|&k| time.bin_start(k) >= gate).unwrap_or(time.bins);
    let mut data = vec![0.0f32; t.measurements() * bins];
    for (m, out) in data.chunks_exact_mut(bins).enumerate() {
        let h = t.histogram(m);
        for (j, o) in out.iter_mut().enumerate() {
            *o = (j * merge..(j + 1) * merge).filter(|&k| k >= first).map(|k| h[k]).sum();
        }
    }
    if let Some(index) = data.iter().position(|v| !v.is_finite()) {
        return Err(InitError::NonFinite { what: "transient data", index });
    }
    let pairs: Vec<(DVec3, DVec3)> = (0..t.measurements())
        .map(|m| {
            let me = t.scan().measurement(m);
            (me.laser.as_dvec3(), me.sensor.as_dvec3())
        })
        .collect();
    let (x0, y0) = (p[0].x as f64, p[0].y as f64);
    let dx = (p[nx - 1].x as f64 - x0) / (nx - 1) as f64;
    let dy = (p[nx * (ny - 1)].y as f64 - y0) / (ny - 1) as f64;
    let power = params.reflectance.distance_power() as i32 / 2;
    let mut out = vec![0.0f32; nx * ny * nz];
    out.par_chunks_mut(nz).enumerate().for_each_init(
        || vec![0.0f32; nz],
        |acc, (c, col)| {
            let (x, y) = (x0 + (c % nx) as f64 * dx, y0 + (c / nx) as f64 * dy);
            acc.fill(0.0);
            for (iz, a) in acc.iter_mut().enumerate() {
                let v = DVec3::new(x, y, (iz as f64 + 0.5) * dz);
                let mut sum = 0.0f64;
                for (m, &(l, s)) in pairs.iter().enumerate() {
                    let (rl, rs) = ((v - l).length(), (v - s).length());
                    // Fractional bin index, bin centres at integers.
                    let u = (rl + rs - time.t0) / delta - 0.5;
                    if u < 0.0 || u >= (bins - 1) as f64 {
                        continue;
                    }
                    let k = u as usize;
                    let f = u - k as f64;
                    let h = &data[m * bins + k..m * bins + k + 2];
                    sum += (h[0] as f64 * (1.0 - f) + h[1] as f64 * f) * (rl * rs).powi(power);
                }
                *a = sum as f32;
            }
            depth_filter(acc, col);
        },
    );
    Ok(Volume {
        nx,
        ny,
        nz,
        x: Axis { start: x0, step: dx },
        y: Axis { start: y0, step: dy },
        z: Axis { start: 0.5 * dz, step: dz },
        data: out,
    })
}
