//! The timing response of a capture gated before it reached us, with the start surface's spread taken out.
//!
//! Such a capture has no direct reflection; [`Prepared::params`] fits it through its strongest first
//! hidden returns aligned ([`JitterResponse::from_first_return`]), which hold the scene's spread in path
//! besides the sensor's blur (on Tsai et al.'s gated S and U about 54 mm of path at half height where the
//! raw file's direct reflection gives about 10 mm; the letters came out 5 mm nearer than from the raw file).
//! Once the start surface exists, [`Prepared::with_start_response`] renders it without blur and takes its
//! spread out of those returns ([`JitterResponse::from_first_return_deconvolved`]).

use nlos_mesh::SurfaceMesh;
use nlos_render::{Kernel, RenderParams, Renderer};
use nlos_transient::Transient;
use nlos_transient::sensor::JitterResponse;

use super::config::SensorChoice;
use super::{Config, Prepared};
use crate::error::{OptimError, Result};
use crate::{ReconstructParams, SensorFit};

impl Prepared {
    /// Whether [`Prepared::with_start_response`] changes `params`: a sensor fit with `sensor.response =
    /// "auto"` on a capture gated before it reached us.
    pub fn takes_response_from_start(&self, config: &Config, params: &ReconstructParams) -> bool {
        params.sensor.is_some()
            && matches!(config.sensor.response, SensorChoice::Auto)
            && self.read.zero_gate().is_some()
    }

    /// `params` with the sensor fit's response taken from the capture's first returns with the spread of
    /// `start` taken out, when the capture was gated before it reached us and `sensor.response` is
    /// `"auto"` (the response [`Prepared::params`] took from the aligned returns); otherwise `params`
    /// unchanged. `start` is rendered as the fit begins (box kernel, the run's BRDF at unit albedo, no
    /// visibility) on the capture as read. Deterministic: a resumed run gets the same response from the same
    /// start.
    ///
    /// # Errors
    /// [`OptimError::Render`] for a start the renderer refuses; [`OptimError::Sensor`] when the response
    /// cannot be resampled onto the bins; [`OptimError::Transient`] when the rendering does not fit the
    /// capture's scan. A response that cannot be solved for (the start renders nothing
    /// where the strongest returns are) leaves `params` as they are.
    pub fn with_start_response(
        &self,
        config: &Config,
        params: &ReconstructParams,
        start: &SurfaceMesh,
    ) -> Result<ReconstructParams> {
        let Some(fit) = params.sensor.as_ref().filter(|_| self.takes_response_from_start(config, params)) else {
            return Ok(params.clone());
        };
        let (positions, triangles) = start.to_triangles();
        let render = RenderParams {
            kernel: Kernel::Box,
            visibility: nlos_render::Visibility::Off,
            ..params.render.with_sampling(RenderParams::default().sampling)
        };
        let renderer = Renderer::new(&positions, &triangles, self.read.scan(), self.read.time(), render)?;
        let brdf = params.reflectance.brdf()?;
        let geometry = Transient::new(self.read.scan().clone(), *self.read.time(), renderer.forward_any(&brdf))
            .map_err(|source| OptimError::Transient { context: "the start surface's rendering", source })?;
        let Ok(response) = JitterResponse::from_first_return_deconvolved(&self.read, &geometry) else {
            return Ok(params.clone());
        };
        let mut out = params.clone();
        out.sensor = Some(SensorFit::from_jitter(&response, self.measured.time().bin_width, fit.background)?);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use nlos_render::Visibility;
    use nlos_transient::{PointSet, Scan, TimeAxis};

    /// Full width at half maximum of a fit's kernel, in bins ([`JitterResponse::fwhm`]).
    fn fwhm(kernel: &[f64]) -> f64 {
        JitterResponse::from_histogram(0.0, 1.0, kernel, false).expect("kernel").fwhm()
    }

    /// A tilted plate facing the wall (z from 0.45 to 0.6 m across it), its capture seen through a sensor of
    /// 4 bins at half height with a diffusion tail, background 2 counts per bin, bins 0..600 zeroed (gated
    /// before it reached us): the aligned first returns spread over the plate's tilt; with the start (the
    /// plate itself) taken out, the response is the sensor's.
    #[test]
    fn a_gated_capture_gets_its_sensors_response_from_the_start() {
        let plate = nlos_mesh::shapes::height_field(0.3, 0.3, 12, 12, |x, _| 0.45 + 0.5 * x).expect("plate");
        let (pos, tri) = plate.to_triangles();
        let pos: Vec<Vec3> = pos.iter().map(|p| *p - Vec3::new(0.15, 0.15, 0.0)).collect();
        let tri: Vec<[u32; 3]> = tri.iter().map(|&[a, b, c]| [a, c, b]).collect();
        let start = SurfaceMesh::from_triangles(&pos, &tri).expect("mesh");
        let scan = Scan::confocal(PointSet::wall_grid(12, 12, 0.25, 0.25).expect("grid"));
        let (bins, width) = (1200, 0.0012);
        let time = TimeAxis::new(0.0, width, bins).expect("axis");
        let render = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
        let flux = nlos_brdf::Lambertian::new(1.0f32)
            .map(|b| Renderer::new(&pos, &tri, &scan, &time, render).map(|r| r.forward(&b)))
            .expect("brdf")
            .expect("render");
        // The sensor: Gaussian rise (σ = 1.5 bins), 85 % Gaussian fall and a 15 % tail (τ = 20 bins).
        let sensor: Vec<f64> = (-8..120)
            .map(|j: i32| {
                let (j, g) = (f64::from(j), (-0.5 * (f64::from(j) / 1.5).powi(2)).exp());
                if j < 0.0 { g } else { 0.85 * g + 0.15 * (-j / 20.0).exp() }
            })
            .collect();
        let truth = JitterResponse::from_histogram(-8.0 * width, width, &sensor, false).expect("response");
        let blurred = truth.to_bins(width).expect("bins").apply(&flux, bins).expect("blur");
        let top = blurred.iter().copied().fold(0.0f32, f32::max);
        let counts: Vec<f32> = blurred
            .iter()
            .enumerate()
            .map(|(i, &v)| if i % bins < 600 { 0.0 } else { (200.0 * v / top + 2.0).round() })
            .collect();
        let capture = Transient::new(scan, time, counts).expect("capture");
        assert_eq!(capture.zero_gate(), Some(600));
        let config = Config::default();
        let prepared = Prepared::new(capture, &config).expect("prepare");
        let params = prepared.params(&config, None).expect("params");
        let aligned = params.sensor.as_ref().expect("a sensor fit").kernel.weights().to_vec();
        assert!(prepared.takes_response_from_start(&config, &params));
        let out = prepared.with_start_response(&config, &params, &start).expect("response");
        let taken_out = out.sensor.as_ref().expect("a sensor fit").kernel.weights().to_vec();
        let want = fwhm(truth.to_bins(width).expect("bins").weights());
        let (w_aligned, w_out) = (fwhm(&aligned), fwhm(&taken_out));
        eprintln!(
            "FWHM in bins: sensor {want:.1}, aligned returns {w_aligned:.1}, start's spread taken out {w_out:.1}"
        );
        assert!(w_aligned >= 2.0 * want, "the aligned returns hold the plate's spread: {w_aligned} bins");
        assert!((w_out - want).abs() <= 1.0, "{w_out} bins against the sensor's {want}");
        // Everything else is as it was; with another response setting nothing changes.
        assert_eq!(ReconstructParams { sensor: params.sensor.clone(), ..out.clone() }, params);
        let ideal = Config::from_toml("[sensor]\nresponse = \"ideal\"\n").expect("parse");
        let p = prepared.params(&ideal, None).expect("params");
        assert!(!prepared.takes_response_from_start(&ideal, &p));
        assert_eq!(prepared.with_start_response(&ideal, &p, &start).expect("unchanged"), p);
    }
}
