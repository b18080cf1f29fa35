//! The albedo's anchor: an estimate of each surface point's albedo that the surface's tilt cannot fake.
//!
//! In a confocal capture a face's tilt and its albedo trade against each other: a patch can be darker or
//! turned away, and a free albedo per vertex lets the fit pick the wrong one (docs/experiments.md, 14 rows).
//! The anchor is the ratio of two volumes made by the start's own method ([`nlos_init::Method::for_scan`]:
//! the LCT on confocal grids, the phasor field otherwise), read at the point `x`:
//! ```text
//! a(x) = V_capture(x) / V_model(x)
//! ```
//! `V_capture` is the method's volume of the capture, `V_model` the same method's volume of the current
//! surface rendered at albedo 1 with the run's BRDF. Where the surface is right and of one albedo the ratio
//! is about 1; over print it falls to the print's share, over a slot to the noise. It varies only at the
//! volume's resolution, so it cannot follow a face's tilt from vertex to vertex, and the shape steps see it
//! fixed: the tilt must then explain how a patch's light changes from spot to spot (Choi et al. 2023 fit a
//! residual of ±0.2 around the volume's intensity with total variation; the band is
//! [`crate::AlbedoParams::band`]).
//!
//! **Reading.** Each volume is read at `x`'s column (bilinear between the four nearest columns) as its
//! largest value within [`WINDOW`] of `x`'s depth, so that a surface a few millimetres off its depth reads
//! its own peak. A point whose model reading is below [`DEFINED`] of the surface's 90th percentile is
//! not anchored (the model sends it too little light to judge): it gets the mean, 1.
//!
//! **Gauge.** The ratio's scale is the capture's, unknown; the anchors are divided by their area-weighted
//! median over the anchored points, so that the surface's typical albedo is 1, the relative albedo's
//! mean ([`crate::albedo`], "Gauge").

use glam::Vec3;
use nlos_brdf::AnyBrdf;
use nlos_init::{Method, Model, Volume};
use nlos_render::{RenderParams, Renderer};
use nlos_transient::Transient;

use crate::error::{OptimError, Result};
use crate::surface::VertexField;

/// The anchor of each vertex's albedo (module docs), recomputed at every stage's start.
pub const ANCHOR: VertexField<f64> = VertexField::new("albedo_anchor", 1.0);

/// Half-width of the depth window a volume is read in around a point (m).
pub const WINDOW: f64 = 0.01;

/// Voxels on either side of the model's peak that a reading sums.
pub const SPAN: usize = 2;

/// Share of the 90th percentile of the model's readings below which a point is not anchored.
pub const DEFINED: f64 = 0.1;

/// The capture's volume by the start's method, made once per run (module docs).
#[derive(Debug, Clone)]
pub struct CaptureVolume {
    method: Method,
    model: Model,
    volume: Volume,
}

impl CaptureVolume {
    /// The start's method's volume of `measured`, weighted for `model`; None when the method cannot take
    /// the scan (the albedo is then not anchored).
    ///
    /// # Errors
    /// Those of the method other than a scan it cannot take.
    pub fn new(measured: &Transient, model: Model) -> Result<Option<Self>> {
        let method = Method::for_scan(measured.scan()).0;
        match method.volume(measured, model, None) {
            Ok(volume) => Ok(Some(Self { method, model, volume })),
            Err(
                nlos_init::InitError::NotConfocal { .. }
                | nlos_init::InitError::NotGrid { .. }
                | nlos_init::InitError::BadGrid { .. }
                | nlos_init::InitError::DeviceLegs
                | nlos_init::InitError::TimeOrigin { .. },
            ) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// The anchor of each vertex of the surface `positions`/`triangles` (module docs): the surface is
    /// rendered at albedo 1 with `brdf` on `measured`'s scan and time axis, its volume made as the
    /// capture's, and both read at each vertex.
    ///
    /// # Errors
    /// Those of the renderer and of the method.
    pub fn anchors(
        &self,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        measured: &Transient,
        brdf: &AnyBrdf,
        render: RenderParams,
    ) -> Result<Vec<f64>> {
        let renderer = Renderer::new(positions, triangles, measured.scan(), measured.time(), render)?;
        let rendered = Transient::new(measured.scan().clone(), *measured.time(), renderer.forward_any(brdf))
            .map_err(|source| OptimError::Transient { context: "the anchor's rendering", source })?;
        let model = self.method.volume(&rendered, self.model, None)?;
        if (model.nx, model.ny, model.nz) != (self.volume.nx, self.volume.ny, self.volume.nz) {
            return Err(OptimError::LengthMismatch {
                what: "the anchor's model volume",
                expected: self.volume.data.len(),
                got: model.data.len(),
            });
        }
        let (cap, mdl): (Vec<f64>, Vec<f64>) = positions.iter().map(|p| read(&self.volume, &model, *p)).unzip();
        Ok(ratios(&cap, &mdl, &vertex_areas(positions, triangles)))
    }
}

/// The ratio of the capture's reading to the model's at each point, with the module's rules for points the
/// model sends too little light and for the gauge; `area` weighs each point in the median.
pub fn ratios(capture: &[f64], model: &[f64], area: &[f64]) -> Vec<f64> {
    let mut sorted: Vec<f64> = model.iter().copied().filter(|m| m.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let p90 = sorted.get(sorted.len() * 9 / 10).copied().unwrap_or(0.0);
    let floor = DEFINED * p90;
    let raw: Vec<Option<f64>> = capture
        .iter()
        .zip(model)
        .map(|(&c, &m)| (m > floor && m > 0.0 && c.is_finite()).then(|| c.max(0.0) / m))
        .collect();
    let mut weighted: Vec<(f64, f64)> = raw.iter().zip(area).filter_map(|(r, &a)| r.map(|r| (r, a))).collect();
    weighted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = weighted.iter().map(|w| w.1).sum();
    let mut acc = 0.0;
    let median = weighted.iter().find(|w| {
        acc += w.1;
        acc >= 0.5 * total
    });
    let Some(&(median, _)) = median.filter(|m| m.0 > 0.0) else {
        return vec![1.0; capture.len()];
    };
    raw.iter().map(|r| r.map_or(1.0, |r| r / median)).collect()
}

/// One third of the area of every face around each vertex.
fn vertex_areas(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<f64> {
    let mut area = vec![0.0; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let third = f64::from((b - a).cross(c - a).length()) / 6.0;
        t.iter().for_each(|&v| area[v as usize] += third);
    }
    area
}

/// Both volumes at `p` (`capture`, `model`): in each of the four nearest columns, the model's peak within
/// [`WINDOW`] of `p`'s depth and the capture's sum over the same [`SPAN`] voxels around it, both summed
/// over [`SPAN`]; bilinear between the columns (0 outside the volume). The capture is read where the model
/// has its surface, so that the noise of one reading is that of a few voxels, not the largest of a window.
pub fn read(capture: &Volume, model: &Volume, p: Vec3) -> (f64, f64) {
    let v = model;
    let (fx, fy) = ((f64::from(p.x) - v.x.start) / v.x.step, (f64::from(p.y) - v.y.start) / v.y.step);
    if !(fx.is_finite() && fy.is_finite()) {
        return (0.0, 0.0);
    }
    let (z0, z1) = (f64::from(p.z) - WINDOW, f64::from(p.z) + WINDOW);
    let (za, zb) = ((z0 - v.z.start) / v.z.step, (z1 - v.z.start) / v.z.step);
    let (lo, hi) = (za.min(zb).ceil().max(0.0), za.max(zb).floor().min(v.nz as f64 - 1.0));
    if hi < lo {
        return (0.0, 0.0);
    }
    let (lo, hi) = (lo as usize, hi as usize);
    let column = |ix: f64, iy: f64| -> (f64, f64) {
        if ix < 0.0 || iy < 0.0 || ix >= v.nx as f64 || iy >= v.ny as f64 {
            return (0.0, 0.0);
        }
        let (ix, iy) = (ix as usize, iy as usize);
        let m = model.column(ix, iy);
        let c = capture.column(ix, iy);
        let peak = (lo..=hi).max_by(|&a, &b| m[a].total_cmp(&m[b])).unwrap_or(lo);
        let (a, b) = (peak.saturating_sub(SPAN), (peak + SPAN).min(v.nz - 1));
        let sum = |col: &[f32]| col[a..=b].iter().map(|&x| f64::from(x)).sum::<f64>();
        (sum(c), sum(m))
    };
    let (x0, y0) = (fx.floor(), fy.floor());
    let (wx, wy) = (fx - x0, fy - y0);
    let mut out = (0.0, 0.0);
    for (dx, dy, w) in [(0.0, 0.0, (1.0 - wx) * (1.0 - wy)), (1.0, 0.0, wx * (1.0 - wy)), (0.0, 1.0, (1.0 - wx) * wy), (1.0, 1.0, wx * wy)] {
        let (c, m) = column(x0 + dx, y0 + dy);
        out.0 += w * c;
        out.1 += w * m;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nlos_init::Axis;

    #[test]
    fn ratios_are_relative_to_the_area_weighted_median_and_unanchored_points_get_the_mean() {
        // Four points: three of one albedo, one at a quarter; one the model sends almost nothing.
        let cap = [2.0, 2.0, 2.0, 0.5, 7.0];
        let mdl = [1.0, 1.0, 1.0, 1.0, 0.01];
        let a = ratios(&cap, &mdl, &[1.0; 5]);
        assert_eq!(a, vec![1.0, 1.0, 1.0, 0.25, 1.0]);
    }

    #[test]
    fn a_capture_is_read_where_the_model_peaks_and_between_columns() {
        let (nx, ny, nz) = (2, 1, 100);
        let step = |start, step| Axis { start, step };
        let volume = |data| Volume { nx, ny, nz, x: step(0.0, 0.1), y: step(0.0, 0.1), z: step(0.5, 0.001), data };
        let (mut m, mut c) = (vec![0.0; nx * nz], vec![0.0; nx * nz]);
        m[50] = 4.0; // column 0, depth 0.5 + 50 · 0.001
        m[nz + 50] = 2.0;
        c[50] = 1.0;
        c[80] = 9.0; // a noise peak the window holds but the model's peak does not
        c[nz + 51] = 1.0;
        let (cap, model) = (volume(c), volume(m));
        assert_eq!(read(&cap, &model, Vec3::new(0.0, 0.0, 0.545)), (1.0, 4.0));
        let (a, b) = read(&cap, &model, Vec3::new(0.05, 0.0, 0.555));
        assert!((a - 1.0).abs() < 1e-6 && (b - 3.0).abs() < 1e-6, "{a} {b}");
        assert_eq!(read(&cap, &model, Vec3::new(0.0, 0.0, 0.52)), (0.0, 0.0));
    }
}
