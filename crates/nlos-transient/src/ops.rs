//! Operations on transients: cropping, rebinning, leg removal, gating, subsampling, summaries.

use crate::error::{Result, TransientError};
use crate::scan::{Scan, ScanPattern};
use crate::time_axis::TimeAxis;
use crate::transient::Transient;

/// How far past path 0 (metres) an axis may start and still hold the direct light off the wall, or where it was
/// before a gate removed it ([`Transient::zero_gate`]): the general-NLOS files start half a bin before path 0,
/// the Stanford ones at 0; a few centimetres allow for a laser spot's size and calibration.
pub const DIRECT_LIGHT_REACH: f64 = 0.05;

impl Transient {
    /// Keeps bins `start..end` (end exclusive); `t0` moves to the start of bin `start`.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when the range is empty or exceeds the axis.
    pub fn crop_bins(&self, start: usize, end: usize) -> Result<Self> {
        let bins = self.bins();
        if start >= end || end > bins {
            return Err(TransientError::InvalidArgument {
                name: "range",
                reason: format!("bins {start}..{end} is empty or outside 0..{bins}"),
            });
        }
        let data = self.histograms().flat_map(|h| h[start..end].iter().copied()).collect();
        let time = TimeAxis { t0: self.time().bin_start(start), bins: end - start, ..*self.time() };
        Ok(Self::from_parts_unchecked(self.scan().clone(), time, data))
    }

    /// Keeps the bins that overlap the path-length window `[t_start, t_end)` (metres).
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when the window is not finite, is empty, or misses the axis.
    pub fn crop_path(&self, t_start: f64, t_end: f64) -> Result<Self> {
        if !(t_start.is_finite() && t_end.is_finite() && t_start < t_end) {
            return Err(TransientError::InvalidArgument {
                name: "window",
                reason: format!("[{t_start}, {t_end}) is not a finite, non-empty path-length window"),
            });
        }
        let ax = self.time();
        let to_bin = |t: f64| ((t - ax.t0) / ax.bin_width).clamp(0.0, ax.bins as f64);
        let start = to_bin(t_start).floor() as usize;
        let end = to_bin(t_end).ceil() as usize;
        self.crop_bins(start, end)
    }

    /// Sums every `k` consecutive bins into one (bin width × k). A trailing group of fewer than `k` bins
    /// is dropped, so every output bin has the same width.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when `k == 0` or `k > bins`.
    pub fn rebin(&self, k: usize) -> Result<Self> {
        let bins = self.bins();
        if k == 0 || k > bins {
            return Err(TransientError::InvalidArgument {
                name: "k",
                reason: format!("rebin factor {k} must be in 1..={bins} (the number of bins)"),
            });
        }
        let out_bins = bins / k;
        let mut data = Vec::with_capacity(self.measurements() * out_bins);
        for h in self.histograms() {
            data.extend(h[..out_bins * k].chunks_exact(k).map(|c| c.iter().map(|&v| f64::from(v)).sum::<f64>() as f32));
        }
        let time = TimeAxis { bins: out_bins, bin_width: self.time().bin_width * k as f64, ..*self.time() };
        Ok(Self::from_parts_unchecked(self.scan().clone(), time, data))
    }

    /// Removes the device legs from the times: each measurement's histogram is shifted earlier by
    /// `|laser_device − l| + |s − sensor_device|`, so that times become the path length of `l → x → s`.
    ///
    /// The shift is exact for histograms: the signal is taken as constant inside each bin and each new
    /// bin receives the integral of that piecewise-constant density over its (shifted) interval, so the
    /// total is conserved except for what moves off either end of the axis.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when the time axis does not include the legs, or when the
    /// device positions are unknown.
    pub fn remove_device_legs(&self) -> Result<Self> {
        if !self.time().includes_device_legs {
            return Err(TransientError::InvalidArgument {
                name: "time",
                reason: "times already exclude the device legs (includes_device_legs = false)".into(),
            });
        }
        let (Some(laser), Some(sensor)) = (self.scan().laser_device, self.scan().sensor_device) else {
            return Err(TransientError::InvalidArgument {
                name: "scan",
                reason: "laser and sensor device positions are needed to remove the legs; set scan.laser_device \
                         and scan.sensor_device"
                    .into(),
            });
        };
        let mut out = self.clone();
        for m in 0..self.measurements() {
            let g = self.scan().measurement(m);
            let d = f64::from(laser.distance(g.laser)) + f64::from(g.sensor.distance(sensor));
            shift_histogram(self.histogram(m), d / self.time().bin_width, out.histogram_mut(m));
        }
        out.time_mut().includes_device_legs = false;
        Ok(out)
    }

    /// Zeroes every bin that begins before path length `t` (metres) — e.g. to gate out the direct
    /// reflection off the wall. Bins that begin at or after `t` are untouched.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when `t` is not finite.
    pub fn gate(&self, t: f64) -> Result<Self> {
        if !t.is_finite() {
            return Err(TransientError::InvalidArgument { name: "t", reason: format!("{t} is not finite") });
        }
        let ax = self.time();
        let n = (0..ax.bins).take_while(|&k| ax.bin_start(k) < t).count();
        let mut out = self.clone();
        for m in 0..self.measurements() {
            out.histogram_mut(m)[..n].fill(0.0);
        }
        Ok(out)
    }

    /// The same capture with every point list that forms a regular grid ([`PointSet::regular_grid`]) laid out
    /// as one ([`Layout::Grid`], x fastest): a list in row order is relabelled; a confocal list in column
    /// order is reordered (points and histograms) into row order. Anything else is returned unchanged.
    /// [`crate::read`] applies this to every format, so that the grid methods (LCT, f-k, subsampling)
    /// accept a grid written as a list.
    ///
    /// [`PointSet::regular_grid`]: crate::PointSet::regular_grid
    /// [`Layout::Grid`]: crate::Layout::Grid
    pub fn with_grid_layout(self) -> Self {
        let as_grid = |set: &mut crate::PointSet| {
            if let Some((nx, ny, true)) = set.regular_grid() {
                set.layout = crate::Layout::Grid { nx, ny };
            }
        };
        let (mut scan, time, data) = self.into_parts();
        match &mut scan.pattern {
            ScanPattern::Confocal(p) => {
                if let (crate::Layout::List, Some((nx, ny, false))) = (p.layout, p.regular_grid()) {
                    // Column order: measurement iy + ny·ix goes to ix + nx·iy.
                    let order: Vec<usize> = (0..nx * ny).map(|m| (m / nx) + ny * (m % nx)).collect();
                    let bins = time.bins;
                    let data = order.iter().flat_map(|&m| data[m * bins..(m + 1) * bins].iter().copied()).collect();
                    p.points = order.iter().map(|&m| p.points[m]).collect();
                    p.normals = order.iter().map(|&m| p.normals[m]).collect();
                    p.layout = crate::Layout::Grid { nx, ny };
                    return Self::from_parts_unchecked(scan, time, data);
                }
                as_grid(p);
            }
            ScanPattern::Exhaustive { lasers, sensors } | ScanPattern::Paired { lasers, sensors } => {
                as_grid(lasers);
                as_grid(sensors);
            }
        }
        Self::from_parts_unchecked(scan, time, data)
    }

    /// Keeps every `step_x`-th column and `step_y`-th row of a grid scan (both laser and sensor grids of
    /// an exhaustive scan; the laser grid of a paired scan, each kept measurement with its sensor spot).
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when a step is zero or a point set is not a grid.
    pub fn subsample(&self, step_x: usize, step_y: usize) -> Result<Self> {
        if step_x == 0 || step_y == 0 {
            return Err(TransientError::InvalidArgument { name: "step", reason: "steps must be >= 1".into() });
        }
        let not_grid =
            || TransientError::InvalidArgument { name: "scan", reason: "subsampling needs a grid scan".into() };
        let (pattern, kept): (ScanPattern, Vec<usize>) = match &self.scan().pattern {
            ScanPattern::Confocal(p) => {
                let (sub, kept) = p.subsample(step_x, step_y).ok_or_else(not_grid)?;
                (ScanPattern::Confocal(sub), kept)
            }
            ScanPattern::Exhaustive { lasers, sensors } => {
                let (ls, lk) = lasers.subsample(step_x, step_y).ok_or_else(not_grid)?;
                let (ss, sk) = sensors.subsample(step_x, step_y).ok_or_else(not_grid)?;
                let ns = sensors.len();
                let kept = lk.iter().flat_map(|&l| sk.iter().map(move |&s| l * ns + s)).collect();
                (ScanPattern::Exhaustive { lasers: ls, sensors: ss }, kept)
            }
            ScanPattern::Paired { lasers, sensors } => {
                // The laser grid indexes the measurements; each kept measurement keeps its sensor spot.
                let (ls, kept) = lasers.subsample(step_x, step_y).ok_or_else(not_grid)?;
                let ss = match sensors.subsample(step_x, step_y) {
                    Some((ss, sk)) if sk == kept => ss,
                    _ => sensors.pick(&kept),
                };
                (ScanPattern::Paired { lasers: ls, sensors: ss }, kept)
            }
        };
        let data = kept.iter().flat_map(|&m| self.histogram(m).iter().copied()).collect();
        let scan = Scan { pattern, ..self.scan().clone() };
        Ok(Self::from_parts_unchecked(scan, *self.time(), data))
    }

    /// Keeps the measurements `kept` (in that order) of a confocal or paired scan, each with its spot (or its
    /// laser and sensor spots), as a list of points: a sparser or irregular spot set drawn from a dense capture
    /// on any wall, where [`Transient::subsample`] needs a grid.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] for an exhaustive scan (its measurements are laser × sensor pairs:
    /// subsample its grids), an empty `kept`, or an index past the last measurement.
    pub fn select(&self, kept: &[usize]) -> Result<Self> {
        let n = self.scan().measurements();
        let bad = |reason: String| TransientError::InvalidArgument { name: "kept", reason };
        if kept.is_empty() {
            return Err(bad("keep at least one measurement".into()));
        }
        if let Some(&m) = kept.iter().find(|&&m| m >= n) {
            return Err(bad(format!("measurement {m} is past the last of {n}")));
        }
        let pattern = match &self.scan().pattern {
            ScanPattern::Confocal(p) => ScanPattern::Confocal(p.pick(kept)),
            ScanPattern::Paired { lasers, sensors } => {
                ScanPattern::Paired { lasers: lasers.pick(kept), sensors: sensors.pick(kept) }
            }
            ScanPattern::Exhaustive { .. } => {
                return Err(bad(
                    "an exhaustive scan's measurements are laser × sensor pairs: subsample its grids".into()
                ));
            }
        };
        let data = kept.iter().flat_map(|&m| self.histogram(m).iter().copied()).collect();
        let scan = Scan { pattern, ..self.scan().clone() };
        Ok(Self::from_parts_unchecked(scan, *self.time(), data))
    }

    /// The time-summed (steady-state) value of each measurement; for a confocal grid, an `nx × ny` image
    /// with x fastest.
    pub fn time_summed(&self) -> Vec<f32> {
        self.histograms().map(|h| h.iter().map(|&v| f64::from(v)).sum::<f64>() as f32).collect()
    }

    /// The bin of the maximum of each histogram (the first one on ties).
    pub fn peak_bins(&self) -> Vec<usize> {
        self.histograms()
            .map(|h| h.iter().enumerate().fold((0, f32::NEG_INFINITY), |b, (k, &v)| if v > b.1 { (k, v) } else { b }).0)
            .collect()
    }

    /// The histogram summed over all measurements, accumulated in `f64`.
    pub fn summed_histogram(&self) -> Vec<f64> {
        let mut acc = vec![0.0f64; self.bins()];
        for h in self.histograms() {
            for (a, &v) in acc.iter_mut().zip(h) {
                *a += f64::from(v);
            }
        }
        acc
    }

    /// Estimates where the direct reflection off the wall ends, as a path length (metres).
    ///
    /// Heuristic, documented here because it is a choice: the summed histogram is smoothed with a box of
    /// `max(1, 6 mm / bin_width)` bins; from its maximum among the first 10 % of the axis (the direct
    /// light, which decays monotonically apart from noise) the running minimum is tracked, and the first
    /// place where the smoothed signal rises above twice that minimum marks the first return from the
    /// hidden scene; the running minimum's position is returned. When no such rise exists (no direct light
    /// on the axis, or it was already gated), the start of the axis is returned.
    ///
    /// A capture gated before it reached us ([`Transient::zero_gate`]) is searched from the end of its zeroed
    /// bins on: what its gate left of the direct light's tail ends where the raw capture's would. When no
    /// falling tail follows the zeros (a capture gated at the direct light's end already, as
    /// `nlos reconstruct` prepares one), the end of the zeros is returned.
    pub fn direct_light_end(&self) -> f64 {
        let ax = self.time();
        let h = self.summed_histogram();
        let w = ((0.006 / ax.bin_width).round() as usize).max(1);
        let smooth = box_smooth(&h, w);
        let z = self.zero_gate().unwrap_or(0);
        let head = (ax.bins / 10).max(1);
        let start = if z == 0 { (0..head).fold(0, |b, k| if smooth[k] > smooth[b] { k } else { b }) } else { z };
        let (mut min_k, mut min_v) = (start, smooth[start]);
        for (k, &v) in smooth.iter().enumerate().skip(start) {
            if v < min_v {
                (min_k, min_v) = (k, v);
            } else if v > 2.0 * min_v && min_v > 0.0 && k > start {
                // Guard: after a gate, light that does not fall to the floor first is no direct light's tail
                // (a capture this crate gated itself: its first hidden return follows the zeros); the gate
                // ends the direct light.
                let after = h[z..(z + w).min(ax.bins)].iter().sum::<f64>() / w as f64;
                if z > 0 && after <= 2.0 * min_v {
                    return ax.bin_start(z);
                }
                return ax.bin_start(min_k);
            }
        }
        ax.t0
    }

    /// The number of leading bins that are zero in every measurement.
    pub fn leading_zero_bins(&self) -> usize {
        self.histograms().map(|h| h.iter().position(|&v| v != 0.0).unwrap_or(h.len())).min().unwrap_or(0)
    }

    /// The bins a preprocessing step zeroed before the capture reached us (Tsai et al. 2019's `transient.mat`
    /// zeroes bins 1–600, as the Stanford reference code does before LCT, to remove the direct reflection):
    /// `Some(z)` when the first `z ≥ 1` bins are zero in every measurement ([`Transient::leading_zero_bins`])
    /// and the light that follows them does not rise — the summed histogram's mean over the 8 bins after
    /// them is positive and at least half its mean over the next 8 — and the summed histogram is positive in
    /// every bin after them. What a gate leaves is the direct light's falling tail, background or a flat
    /// stretch, and the background goes on after it; a simulation without background also starts with zero
    /// bins, but what follows them is its first return's rising edge, and bins without a return are zero
    /// there too (a flat face's abrupt first return passed the first test: the soap bar's 1,000-photon
    /// capture was taken for gated and fitted through a response estimated from its own first return, 6 mm
    /// off), so it has no gate. Neither has a capture without zero bins.
    ///
    /// A gate removed a direct light, so the axis must reach back to where the direct light was: path 0, the
    /// wall (within `DIRECT_LIGHT_REACH`, 5 cm), or an axis whose times include the device legs. A capture cut
    /// from later bins (`nlos convert --crop-bins 500..900` of a simulation: its axis starts 0.6 m in, and its
    /// zeros are the darkness before the first return) has none, however its first return rises: a flat
    /// face's abrupt return, cut before its end, passed every other test.
    ///
    /// Estimates that need bins without signal (the background, [`crate::sensor::BackgroundWindow`]) and
    /// the direct light's end start after the gate: its zeros are neither background nor signal.
    pub fn zero_gate(&self) -> Option<usize> {
        let ax = self.time();
        // Guard: no direct light could have been on an axis that starts past the wall.
        if !ax.includes_device_legs && ax.t0 > DIRECT_LIGHT_REACH {
            return None;
        }
        let z = self.leading_zero_bins();
        if z == 0 || z + 16 > self.bins() {
            return None;
        }
        let h = self.summed_histogram();
        let (first, next) = (h[z..z + 8].iter().sum::<f64>(), h[z + 8..z + 16].iter().sum::<f64>());
        // Guard: background everywhere after the zeros, or they are darkness, not a gate.
        let background_after = h[z..].iter().all(|&v| v > 0.0);
        (first > 0.0 && first >= 0.5 * next && background_after).then_some(z)
    }

    /// Estimates where the last return from the hidden scene ends, as a path length (metres): the end of
    /// the last bin whose summed histogram stands clearly above the background. Later bins hold only
    /// background, which an L2 fit would explain with far, large surfaces.
    ///
    /// Heuristic, documented here because it is a choice (it sets `nlos reconstruct --max-depth auto`);
    /// only the bins that begin at or after `min_path` count (pass [`Transient::direct_light_end`] for a
    /// raw capture):
    /// 1. the summed histogram `h` is smoothed with a box of `w = max(1, 6 mm / bin_width)` bins (`h̄`);
    /// 2. the background `B` is the 10th percentile of `h̄` (the bins between and around the returns; the
    ///    last bins of a capture are no guide: in `data_s_u.mat` they hold the U and a rise of the
    ///    background), and the noise `σ` of one bin is `1.4826·MAD/√2` of the first differences of `h`
    ///    (slow structure cancels in a difference, Poisson noise does not);
    /// 3. a bin holds signal when its smoothed excess `h̄ − B` exceeds both `5σ/√w` and 2 % of the largest
    ///    excess (at 1 % the diffuse S's late background bumps at 1.1 m counted as signal);
    /// 4. the end of the last such bin, plus 5 % of its path length (the faint tails of the last return),
    ///    is returned, at most the end of the axis.
    ///
    /// A capture without background (`B = 0`: a simulation, noisy or not) returns the end of the axis: its
    /// late bins hold nothing that could mislead a fit, and the faint tails of its returns are signal.
    /// So does a capture with no bin at or after `min_path`, or with no excess at all.
    pub fn signal_end_path(&self, min_path: f64) -> f64 {
        let ax = self.time();
        let h = self.summed_histogram();
        let w = ((0.006 / ax.bin_width).round() as usize).max(1);
        let smooth = box_smooth(&h, w);
        let first = (0..ax.bins).find(|&k| ax.bin_start(k) >= min_path).unwrap_or(ax.bins);
        if ax.bins - first < 2 {
            return ax.end();
        }
        let mut sorted = smooth[first..].to_vec();
        sorted.sort_by(f64::total_cmp);
        let background = sorted[(sorted.len() - 1) / 10];
        let diffs: Vec<f64> = h[first..].windows(2).map(|p| p[1] - p[0]).collect();
        let centre = median(&diffs);
        let dev: Vec<f64> = diffs.iter().map(|d| (d - centre).abs()).collect();
        // 1.4826·MAD estimates σ of a normal distribution; a difference of two bins has σ·√2.
        let sigma = 1.4826 * median(&dev) / std::f64::consts::SQRT_2;
        let peak = smooth[first..].iter().map(|v| v - background).fold(0.0f64, f64::max);
        // Guard: no background (or none measurable) means nothing to drop; no excess means no return.
        if !(background > 0.0 && peak > 0.0) {
            return ax.end();
        }
        let threshold = (5.0 * sigma / (w as f64).sqrt()).max(0.02 * peak);
        (first..ax.bins)
            .rev()
            .find(|&k| smooth[k] - background > threshold)
            .map_or(ax.end(), |k| (1.05 * (ax.bin_start(k) + ax.bin_width)).min(ax.end()))
    }

    /// Path length (metres, at the bin centre) of the maximum of the summed histogram among the bins
    /// that begin at or after `min_path`; `None` for `min_path` means [`Transient::direct_light_end`].
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when no bin begins at or after `min_path`.
    pub fn summed_peak_path(&self, min_path: Option<f64>) -> Result<f64> {
        let gate = min_path.unwrap_or_else(|| self.direct_light_end());
        let ax = self.time();
        let h = self.summed_histogram();
        let first = (0..ax.bins).find(|&k| ax.bin_start(k) >= gate).ok_or_else(|| TransientError::InvalidArgument {
            name: "min_path",
            reason: format!("no bin begins at or after {gate} m (axis ends at {} m)", ax.end()),
        })?;
        let k = (first..ax.bins).fold(first, |b, k| if h[k] > h[b] { k } else { b });
        Ok(ax.bin_center(k))
    }

    /// Depth (metres from the wall) of the summed-histogram peak: [`Transient::depth_of_path`] of its path
    /// length (half of it for a confocal scan). See [`Transient::summed_peak_path`] for `min_path`.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] for times that include the device legs, or as
    /// [`Transient::summed_peak_path`].
    pub fn summed_peak_depth(&self, min_path: Option<f64>) -> Result<f64> {
        if self.time().includes_device_legs {
            return Err(TransientError::InvalidArgument {
                name: "time",
                reason: "times include the device legs; call remove_device_legs first".into(),
            });
        }
        Ok(self.depth_of_path(self.summed_peak_path(min_path)?))
    }

    /// The depth of a point at path length `path` (metres, `l → x → s`) straight in front of the scan: on
    /// the wall normal through the midpoint of the laser spots' and the sensor spots' centroids, at distance
    /// `a` from each, `2·√(a² + z²) = path`, so `z = √((path/2)² − a²)` (0 when the path is shorter than
    /// `2a`). A confocal scan has `a = 0`: half the path.
    pub fn depth_of_path(&self, path: f64) -> f64 {
        let centroid = |p: &crate::PointSet| {
            p.points.iter().fold(glam::DVec3::ZERO, |acc, v| acc + v.as_dvec3()) / p.len().max(1) as f64
        };
        let a = if self.scan().is_confocal() {
            0.0
        } else {
            0.5 * (centroid(self.scan().lasers()) - centroid(self.scan().sensors())).length()
        };
        ((0.5 * path).powi(2) - a * a).max(0.0).sqrt()
    }
}

/// Shifts a histogram earlier by `shift` bins (fractional, may be negative), treating it as piecewise
/// constant: `out[k] = C(k + 1 + shift) − C(k + shift)` with `C` the cumulative integral.
pub(crate) fn shift_histogram(input: &[f32], shift: f64, out: &mut [f32]) {
    let n = input.len();
    let mut cum = Vec::with_capacity(n + 1);
    cum.push(0.0f64);
    for &v in input {
        cum.push(cum.last().copied().unwrap_or(0.0) + f64::from(v));
    }
    let c = |x: f64| -> f64 {
        if x <= 0.0 {
            0.0
        } else if x >= n as f64 {
            cum[n]
        } else {
            let i = x.floor() as usize;
            cum[i] + (x - i as f64) * f64::from(input[i])
        }
    };
    for (k, o) in out.iter_mut().enumerate() {
        *o = (c(k as f64 + 1.0 + shift) - c(k as f64 + shift)) as f32;
    }
}

/// `h` smoothed with a centred box of `w` bins (shorter at the ends, where it is clipped to the slice).
pub(crate) fn box_smooth(h: &[f64], w: usize) -> Vec<f64> {
    let n = h.len();
    let mut cum = vec![0.0; n + 1];
    for i in 0..n {
        cum[i + 1] = cum[i] + h[i];
    }
    (0..n)
        .map(|k| {
            let lo = k.saturating_sub(w / 2);
            let hi = (k + w - w / 2).min(n);
            (cum[hi] - cum[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// Median of a non-empty slice of finite values (upper median for even lengths is not used: the mean of
/// the two middle values).
pub(crate) fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 { s[n / 2] } else { 0.5 * (s[n / 2 - 1] + s[n / 2]) }
}
