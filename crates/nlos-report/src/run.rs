//! [`ReportOptions::for_run`]: the report's options for a run of [`nlos_optim::pipeline`] — its renderer
//! settings, data term and sensor fit, the settings listed on the page, and the wall rectangle of the whole
//! capture — so that `nlos reconstruct`, `nlos report` and any other caller show a run the same way.

use std::path::Path;

use nlos_init::{InitMethod, Method};
use nlos_optim::pipeline::{Config, Prepared};
use nlos_optim::{ReconstructParams, SamplingSchedule};
use nlos_render::Sampling;

use crate::{DepthView, ReportOptions};

impl ReportOptions {
    /// The options of the report of a run of the capture at `data`, prepared as `prepared` with settings
    /// `config` and `params` (`resumed`: whether the run was continued from its checkpoint).
    ///
    /// The depth maps and metrics cover the bounding rectangle of the whole capture's sensor points, before
    /// subsampling (Tsai et al. 2019's setup's [−0.25, 0.25]², as `nlos eval`); where they span no rectangle
    /// the report tries the fitted grid's, and says why it cannot.
    pub fn for_run(
        data: &Path,
        config: &Config,
        prepared: &Prepared,
        params: &ReconstructParams,
        resumed: bool,
    ) -> ReportOptions {
        let sampling = match params.sampling {
            SamplingSchedule::Splat(rule) => Sampling::Splat(rule),
            SamplingSchedule::Deterministic(rule) => Sampling::Deterministic(rule),
            SamplingSchedule::Stratified { initial_samples, .. } => {
                Sampling::Stratified { samples_per_measurement: initial_samples, seed: params.seed }
            }
        };
        let name = data.file_name().map_or_else(|| data.display().to_string(), |n| n.to_string_lossy().into());
        ReportOptions {
            title: format!("nlos reconstruct {name}"),
            parameters: parameters(data, config, prepared, params, resumed),
            render: params.render.with_sampling(sampling),
            loss: params.data.loss,
            sensor: params.sensor.clone(),
            area: DepthView::over_scan(&prepared.full, 1).ok().map(|v| (v.x_range, v.y_range)),
            // The start's method, as `Prepared::start_candidates` resolves it (a mesh start: the scan's).
            backprojection: Some(match &config.init {
                InitMethod::Volume(method) => *method,
                InitMethod::Auto | InitMethod::Mesh(_) => Method::for_scan(prepared.full.scan()).0,
            }),
            ..ReportOptions::default()
        }
    }
}

/// The settings the page lists, in order.
fn parameters(
    data: &Path,
    c: &Config,
    prepared: &Prepared,
    params: &ReconstructParams,
    resumed: bool,
) -> Vec<(String, String)> {
    let s = &params.schedule;
    let parameters = [
        ("data", data.display().to_string()),
        ("initial surface", c.init.to_string()),
        ("reflectance", format!("{}, alpha0 {}", c.reflectance.model, c.reflectance.alpha)),
        ("seed", c.seed.to_string()),
        (
            "schedule",
            format!(
                "{} stages from resolution {} (first edge {:.1} mm), {} blocks of {} steps",
                s.max_stages,
                s.initial_resolution,
                1e3 * s.target_edge_length(0),
                s.max_blocks_per_stage,
                s.shape_iterations
            ),
        ),
        ("rebin, subsample", format!("{}, {}", c.capture.rebin, c.capture.subsample)),
        ("gate, max depth", format!("{}, {}", c.capture.gate, c.capture.max_depth)),
        ("visibility, splat max level", format!("{:?}, {}", c.render.visibility, c.render.max_level).to_lowercase()),
        ("sensor", format!("{} ({})", c.sensor.response, prepared.describe_sensor(c, params))),
        ("albedo", c.albedo.to_string()),
        ("resumed", resumed.to_string()),
    ];
    parameters.into_iter().map(|(k, v)| (k.to_string(), v)).collect()
}
