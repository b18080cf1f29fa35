//! Shared preprocessing of confocal grid captures for the volumetric methods.

use nlos_transient::{Layout, Transient};

use crate::error::{InitError, Result};

/// How the direct reflection off the wall (and anything before the hidden scene) is removed.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Gate {
    /// Keep every bin.
    None,
    /// Zero the bins that begin before [`Transient::direct_light_end`] (a documented heuristic on the
    /// summed histogram).
    #[default]
    Auto,
    /// Zero the bins that begin before this path length (metres; `2 × depth` for a confocal scan).
    Path(f64),
}

impl Gate {
    /// The path length (metres) before which this gate zeroes the bins of `t`: `None` for [`Gate::None`],
    /// [`Transient::direct_light_end`] for [`Gate::Auto`], the given length for [`Gate::Path`].
    ///
    /// # Errors
    /// [`InitError::InvalidParameter`] for a non-finite [`Gate::Path`].
    pub fn path(self, t: &Transient) -> Result<Option<f64>> {
        match self {
            Gate::None => Ok(None),
            Gate::Auto => Ok(Some(t.direct_light_end())),
            Gate::Path(g) if g.is_finite() => Ok(Some(g)),
            Gate::Path(g) => Err(InitError::InvalidParameter {
                name: "gate",
                value: g,
                reason: "the gate must be a finite path length",
            }),
        }
    }
}

/// A confocal grid capture ready for the FFT methods: times start at path length 0, bins merged.
#[derive(Debug, Clone)]
pub(crate) struct ConfocalGrid {
    pub nx: usize,
    pub ny: usize,
    pub x0: f64,
    pub dx: f64,
    pub y0: f64,
    pub dy: f64,
    /// Bins per histogram; bin `k` covers path `[k·delta, (k+1)·delta)`.
    pub bins: usize,
    /// Bin width after merging, metres of path.
    pub delta: f64,
    /// `data[(ix + nx·iy)·bins + k]`.
    pub data: Vec<f32>,
}

/// Checks that `t` is a confocal regular grid with times from the wall, gates, crops to `max_depth` and
/// merges `merge` bins into one.
pub(crate) fn prepare(
    t: &Transient,
    method: &'static str,
    gate: Gate,
    max_depth: Option<f64>,
    merge: usize,
) -> Result<ConfocalGrid> {
    if !t.scan().is_confocal() {
        return Err(InitError::NotConfocal { method, scan: t.scan().kind() });
    }
    let pts = t.scan().sensors();
    let Layout::Grid { nx, ny } = pts.layout else {
        return Err(InitError::NotGrid { method });
    };
    let bad = |reason: String| InitError::BadGrid { method, reason };
    if nx < 2 || ny < 2 || pts.points.len() != nx * ny {
        return Err(bad(format!("{nx} × {ny} grid with {} points", pts.points.len())));
    }
    let p = &pts.points;
    let (x0, y0) = (p[0].x as f64, p[0].y as f64);
    let dx = (p[nx - 1].x as f64 - x0) / (nx - 1) as f64;
    let dy = (p[nx * (ny - 1)].y as f64 - y0) / (ny - 1) as f64;
    if !(dx.is_finite() && dy.is_finite() && dx.abs() > 0.0 && dy.abs() > 0.0) {
        return Err(bad(format!("grid spacing ({dx}, {dy}) m is zero or not finite")));
    }
    // Regularity within 1 % of a spacing (f32 positions carry ~1e-7 relative rounding).
    let tol = 0.01 * dx.abs().min(dy.abs());
    for iy in 0..ny {
        for ix in 0..nx {
            let q = p[ix + nx * iy];
            let (ex, ey) = (x0 + ix as f64 * dx, y0 + iy as f64 * dy);
            if (q.x as f64 - ex).abs() > tol || (q.y as f64 - ey).abs() > tol || (q.z as f64).abs() > tol {
                return Err(bad(format!(
                    "point ({ix}, {iy}) is at {q:?}, expected ({ex:.5}, {ey:.5}, 0): not a regular grid on z = 0"
                )));
            }
        }
    }
    let time = *t.time();
    if time.includes_device_legs {
        return Err(InitError::DeviceLegs);
    }
    if merge == 0 {
        return Err(InitError::InvalidParameter {
            name: "bin_merge",
            value: 0.0,
            reason: "the bin merging factor must be at least 1 (1 = no merging)",
        });
    }
    let delta0 = time.bin_width;
    let k0f = time.t0 / delta0;
    let k0 = k0f.round();
    // Bins must sit on the grid k·Δ from path 0 (tolerance 1e-3 bin for decimal rounding of t0).
    if !(k0 >= 0.0 && (k0f - k0).abs() <= 1e-3) || k0 > 1e7 {
        return Err(InitError::TimeOrigin { t0: time.t0, bin_width: delta0 });
    }
    let k0 = k0 as usize;
    let gate_path = gate.path(t)?.unwrap_or(f64::NEG_INFINITY);
    let mut total = k0 + time.bins;
    if let Some(d) = max_depth {
        if !(d.is_finite() && d > 0.0) {
            return Err(InitError::InvalidParameter {
                name: "max_depth",
                value: d,
                reason: "must be a positive depth (m)",
            });
        }
        // Guard: the cap is at most the axis, so the float → usize conversion cannot overflow.
        total = total.min(((2.0 * d / delta0).ceil()).min(total as f64) as usize);
    }
    let bins = total / merge;
    if bins < 2 {
        return Err(InitError::Empty {
            what: format!(
                "only {bins} time bin(s) left after cropping to max_depth {max_depth:?} m and merging {merge} bins; \
                 raise max_depth or lower bin_merge"
            ),
        });
    }
    let src_bins = time.bins;
    let first_kept = (0..src_bins).find(|&k| time.bin_start(k) >= gate_path).unwrap_or(src_bins);
    let m_count = nx * ny;
    let mut data = vec![0.0f32; m_count * bins];
    for (m, out) in data.chunks_exact_mut(bins).enumerate() {
        let h = t.histogram(m);
        for (j, o) in out.iter_mut().enumerate() {
            let mut s = 0.0f32;
            for r in 0..merge {
                let k = j * merge + r;
                if k >= k0 && k - k0 >= first_kept && k - k0 < src_bins {
                    s += h[k - k0];
                }
            }
            *o = s;
        }
    }
    if let Some(index) = data.iter().position(|v| !v.is_finite()) {
        return Err(InitError::NonFinite { what: "transient data", index });
    }
    Ok(ConfocalGrid { nx, ny, x0, dx, y0, dy, bins, delta: delta0 * merge as f64, data })
}

/// The smallest `n' >= n` whose only prime factors are 2, 3 and 5 (fast FFT sizes).
pub(crate) fn next_fast_len(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for p in [2, 3, 5] {
            while r.is_multiple_of(p) {
                r /= p;
            }
        }
        if r == 1 {
            return m;
        }
        m += 1;
    }
}
