//! The optimiser's parameters of a prepared capture ([`Prepared::params`]): the settings resolved against
//! the capture — noise model, sensor fit and its background, renderer, schedule — and the sensor fit's
//! description for the run log.

use std::path::PathBuf;

use super::*;

impl Prepared {
    /// The optimiser's parameters: `config` resolved against this capture (noise model, sensor fit,
    /// background), writing into `out_dir`.
    ///
    /// # Errors
    /// [`OptimError::Config`] for a value outside its domain (naming the field), and those of
    /// [`ReconstructParams::validate`].
    pub fn params(&self, config: &Config, out_dir: Option<PathBuf>) -> Result<ReconstructParams> {
        let mut p = ReconstructParams { seed: config.seed, out_dir, ..ReconstructParams::default() };
        let r = &config.reflectance;
        // Checked whatever the model, so a typo never silently runs a long reconstruction with another α.
        if !(1e-3..=1.0).contains(&r.alpha) {
            return Err(config_error("reflectance.alpha", format!("{}: GGX roughness lies in [0.001, 1]", r.alpha)));
        }
        p.reflectance = Reflectance::start(r.model, r.alpha)?;
        p.render.visibility = match config.render.visibility {
            VisibilityChoice::Cached => Visibility::Cached { level: 1 },
            VisibilityChoice::Live => Visibility::Live,
            VisibilityChoice::Off => Visibility::Off,
        };
        let max_level = config.render.max_level;
        if !(1..=64).contains(&max_level) {
            return Err(config_error("render.max_level", format!("{max_level}: from 1 to 64")));
        }
        let rule = SplatRule { max_level, ..SplatRule::default() };
        p.sampling = SamplingSchedule::Splat(rule);
        p.device = config.render.device;
        if p.device == Device::Gpu {
            let why = nlos_render::gpu_support(r.model, &p.render.with_sampling(nlos_render::Sampling::Splat(rule)));
            why.map_err(|why| config_error("render.device", format!("\"gpu\": {why}; use \"auto\" or \"cpu\"")))?;
        }
        p.schedule = self.schedule;
        let o = &config.optimiser;
        (p.lr_interior, p.lr_boundary, p.lr_reflectance) = (o.lr_interior, o.lr_boundary, o.lr_reflectance);
        (p.regulariser_ratio, p.boundary_smoothing) = (o.smoothing, o.boundary_smoothing);
        p.data.counts = match config.sensor.noise {
            Noise::Auto => nlos_transient::sensor::is_integer_counts(self.measured.data()),
            Noise::Counts => true,
            Noise::None => false,
        };
        let b = &config.boundary;
        p.prune = (b.prune_rounds > 0).then_some(PruneParams {
            rounds: b.prune_rounds,
            margin: b.prune_margin,
            ..PruneParams::default()
        });
        p.residual = (b.residual_stages > 0).then(|| ResidualParams {
            separation: b.residual_separation,
            stages: Some(b.residual_stages),
            margin: b.residual_margin,
            tilts: b.residual_tilts.clone(),
            rounds: b.residual_rounds,
            round_gain: b.residual_round_gain,
            ..ResidualParams::default()
        });
        p.sensor = self.sensor_fit(config)?;
        p.albedo_map = match config.albedo_map {
            Setting::Word(Word::Off) => None,
            Setting::Value(cell) => Some(AlbedoMapParams { cell, ..AlbedoMapParams::default() }),
            Setting::Word(Word::Auto) => {
                return Err(config_error("albedo_map", "\"auto\": give a cell size in metres or \"off\""));
            }
        };
        p.validate()?;
        Ok(p)
    }

    /// The sensor fit of `config.sensor` on this capture's bins (None: an L2 fit).
    fn sensor_fit(&self, config: &Config) -> Result<Option<SensorFit>> {
        let s = &config.sensor;
        // Photon counts, or a capture gated before it reached us whose values are counts scaled by a
        // constant (non-negative, not integers: the Poisson deviance of `c·n` against `c·μ` is `c` times that
        // of `n` against `μ`, so the fit and its floor, taken from the same bins, are the same; a background
        // subtracted from it would leave negative values and an L2 fit).
        let counts = nlos_transient::sensor::is_integer_counts(self.measured.data())
            || self.read.zero_gate().is_some() && self.measured.data().iter().all(|&v| v >= 0.0);
        // `auto`: the capture's own response when it holds one: its direct reflection, which the gate removed,
        // or, on a capture gated before it reached us, its first strong hidden return.
        let direct = match &s.response {
            SensorChoice::Off => return Ok(None),
            SensorChoice::Auto => {
                match (counts && self.gated).then(|| self.own_response()) {
                    Some(Ok(r)) => Some(r),
                    _ => {
                        // An explicit background would be silently dropped, so it is an error.
                        if let Setting::Value(b) = s.background {
                            return Err(config_error(
                                "sensor.background",
                                format!(
                                    "{b} with sensor.response = \"auto\": this capture is fitted by L2 (not photon counts \
                                 with a direct reflection), which has no background; give response = \"ideal\", \
                                 \"direct\" or a response file for a sensor fit"
                                ),
                            ));
                        }
                        return Ok(None);
                    }
                }
            }
            SensorChoice::Direct => Some(
                JitterResponse::from_direct_return(&self.read)
                    .map_err(|e| config_error("sensor.response", format!("direct: {e}")))?,
            ),
            SensorChoice::Ideal | SensorChoice::File(_) => None,
        };
        let background = match s.background {
            Setting::Word(Word::Auto) if self.gated => {
                // The fit's floor on a capture with a direct light (on the axis or gated before it reached us):
                // the level of the last 10 % of the axis as read, not the background of the quiet bins before
                // the first return. The one-bounce model leaves out what a real capture also holds there (the
                // SPAD's diffusion tail past the response's window, light of several bounces); a Poisson fit
                // with the quiet bins' background (Stanford S and U: 0.05 counts per bin against 0.67 here)
                // pulls surfaces apart to explain it: the S broke into stripes from the raw file and from its
                // gated version alike (docs/experiments.md). The raw file and its gated version share these
                // bins, so both are fitted alike.
                let est = nlos_transient::sensor::estimate_background(&self.read, BackgroundWindow::AxisEnd)
                    .map_err(|e| config_error("sensor.background", e.to_string()))?;
                SensorBackground::Fixed(est.per_bin.max(0.0))
            }
            Setting::Word(Word::Auto) => SensorBackground::Estimate(BackgroundWindow::Auto),
            Setting::Value(b) if b.is_finite() && b >= 0.0 => SensorBackground::Fixed(b),
            other => {
                return Err(config_error(
                    "sensor.background",
                    format!("{other}: counts per bin (finite, ≥ 0) or \"auto\""),
                ));
            }
        };
        let bin_width = self.measured.time().bin_width;
        Ok(Some(match (direct, &s.response) {
            (Some(response), _) => SensorFit::from_jitter(&response, bin_width, background)?,
            (None, SensorChoice::File(file)) => {
                let response = JitterResponse::load(file)
                    .map_err(|e| config_error("sensor.response", format!("{}: {e}", file.display())))?;
                SensorFit::from_jitter(&response, bin_width, background)?
            }
            (None, _) => SensorFit { kernel: BinKernel::identity(), background },
        }))
    }

    /// The capture's own timing response: its direct reflection ([`JitterResponse::from_direct_return`]), or,
    /// when a preprocessing step zeroed it ([`Transient::zero_gate`]), its first strong hidden return
    /// ([`JitterResponse::from_first_return`]).
    fn own_response(&self) -> std::result::Result<JitterResponse, nlos_transient::TransientError> {
        if self.read.zero_gate().is_some() {
            JitterResponse::from_first_return(&self.read)
        } else {
            JitterResponse::from_direct_return(&self.read)
        }
    }

    /// What the sensor settings decided, for the user: the response's shape and the background level.
    pub fn describe_sensor(&self, config: &Config, params: &ReconstructParams) -> String {
        let response = match config.sensor.response {
            SensorChoice::Auto if self.read.zero_gate().is_some() => format!(
                "the capture's own response (its first strong hidden returns with the start surface's spread \
                 taken out, or aligned as they are where the start renders no light near them: bins 0..{} are \
                 zero in every measurement, the direct light gated before it reached us)",
                self.read.zero_gate().unwrap_or(0)
            ),
            SensorChoice::Auto | SensorChoice::Direct => "the capture's own response (its direct reflection)".into(),
            SensorChoice::Ideal => "an ideal sensor's response".into(),
            SensorChoice::File(ref f) => format!("the response of {}", f.display()),
            SensorChoice::Off => String::new(),
        };
        match &params.sensor {
            None => "L2 fit of intensities (sensor.response = \"off\", or \"auto\" on data that are not photon \
                     counts with a direct reflection)"
                .into(),
            Some(fit) => {
                let background = match fit.background {
                    SensorBackground::Fixed(b) if self.gated && config.sensor.background == Setting::AUTO => format!(
                        "{b:.4} counts per bin (the last 10 % of the axis: the background with the late light the \
                         one-bounce model leaves out, a floor that keeps surfaces from explaining it)"
                    ),
                    SensorBackground::Fixed(b) => format!("{b:.4} counts per bin"),
                    SensorBackground::Estimate(_) => "estimated before the first return".into(),
                };
                format!(
                    "Poisson fit of the counts through {response} ({} bins), background {background}; \
                     sensor.response = \"off\" fits intensities by L2",
                    fit.kernel.weights().len()
                )
            }
        }
    }
}
