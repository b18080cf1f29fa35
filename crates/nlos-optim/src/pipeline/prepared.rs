//! A capture prepared as the optimiser fits it ([`Prepared`]), and everything decided from it:
//! - the capture itself ([`Prepared::new`]: rebin, gate, max depth, subsample, in that order);
//! - the optimiser's parameters ([`Prepared::params`]): the settings resolved against the capture — noise
//!   model, sensor fit and its background, renderer, schedule — and the sensor fit's description for the run
//!   log;
//! - the start ([`Prepared::initial_surface`], [`Prepared::start_candidates`]): the volume of the method the
//!   settings name or `auto` chooses ([`nlos_init::Method`]), on the capture every start shares
//!   ([`Prepared::full`]), and its surface, extracted no deeper than [`Prepared::surface_depth`] and with
//!   steps between columns allowed by the scan's spacing;
//! - the timing response of a capture gated before it reached us, with the start surface's spread taken out
//!   ([`Prepared::with_start_response`]). Such a capture has no direct reflection; [`Prepared::params`] fits
//!   it through its strongest first hidden returns aligned ([`JitterResponse::from_first_return`]), which
//!   hold the scene's spread in path besides the sensor's blur (on Tsai et al.'s gated S and U about 54 mm of
//!   path at half height where the raw file's direct reflection gives about 10 mm; the letters came out 5 mm
//!   nearer than from the raw file). Once the start surface exists, it is rendered without blur and its
//!   spread taken out of those returns ([`JitterResponse::from_first_return_deconvolved`]).

use std::path::{Path, PathBuf};

use nlos_init::{Gate, GrowReference, Model, PfParams, SurfaceParams, Volume, pf, volume_to_surface};
use nlos_mesh::SurfaceMesh;
use nlos_render::{Device, Kernel, RenderParams, Renderer, SplatRule, Visibility};
use nlos_transient::Transient;
use nlos_transient::sensor::{BackgroundWindow, BinKernel, JitterResponse};

use super::config::{
    AlbedoChoice, Config, InitMethod, Method, Noise, SensorChoice, Setting, StartRim, VisibilityChoice, Word,
    config_error,
};
use crate::error::{OptimError, Result};
use crate::{PruneParams, ReconstructParams, Reflectance, ResidualParams, SamplingSchedule};
use crate::{Schedule, SensorBackground, SensorFit};

/// A capture prepared as the optimiser fits it ([`Prepared::new`]), with the intermediate forms the sensor
/// fit and the initial surface need.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// As read and rebinned, before the gate and the max depth: it still holds the direct reflection off the
    /// wall (the capture's own response) and the background-only bins at the end of the axis.
    pub read: Transient,
    /// Whether the gate zeroed the direct light.
    pub gated: bool,
    /// After the gate and an explicit max depth: what the initial surface is reconstructed from (the whole
    /// scan grid: a volume from a subsampled grid is blurred twice as wide).
    pub full: Transient,
    /// `full` cut after the last return (`max_depth = "auto"`) and subsampled: what the optimiser fits.
    pub measured: Transient,
    /// The depth beyond which the initial surface takes no voxel (`max_depth = "auto"`).
    pub surface_depth: Option<f64>,
    /// What the `auto` settings decided, one sentence each, for the user.
    pub notes: Vec<String>,
    /// The configuration's schedule sized to the fitted capture ([`Schedule::sized_to`]).
    pub schedule: Schedule,
}

impl Prepared {
    /// Reads the capture at `path` (any format [`nlos_transient::read`] knows) and prepares it.
    ///
    /// # Errors
    /// [`OptimError::Capture`] naming the file when it cannot be read, and those of [`Prepared::new`].
    pub fn load(path: &Path, config: &Config) -> Result<Self> {
        let read = nlos_transient::read_with(path, &config.capture.read_options()?)
            .map_err(|source| OptimError::Capture { path: path.to_owned(), source: Box::new(source) })?;
        Self::new(read, config)
    }

    /// Prepares a capture: rebin, gate, max depth, subsample (in that order).
    ///
    /// `max_depth = "auto"` drops the late bins from the fitted data only: the initial volume is reconstructed
    /// from the whole axis and its surface cut at the depth instead. The LCT's volume depends on the length
    /// of the axis it resamples (a simulation of the bunny with 0.01 background counts per bin, cut after its
    /// last return at 0.57 m, gave an initial surface with a mean depth error of 9.6 mm against 8.5 mm from
    /// the whole axis, and a fit of 7.3 against 5.8 mm).
    ///
    /// # Errors
    /// [`OptimError::Config`] for a rebin or subsample factor of 0 or one the capture does not allow, a
    /// non-finite gate, a depth that is not positive or leaves no bin.
    pub fn new(capture: Transient, config: &Config) -> Result<Self> {
        let c = &config.capture;
        let mut notes = Vec::new();
        let mut read = capture;
        if c.rebin > 1 {
            read = read.rebin(c.rebin).map_err(|e| config_error("capture.rebin", e.to_string()))?;
        } else if c.rebin == 0 {
            return Err(config_error("capture.rebin", "0 bins: give 1 to keep the capture's bins"));
        }
        let gate = match c.gate {
            Setting::Word(Word::Auto) => Gate::Auto,
            Setting::Word(Word::Off) => Gate::None,
            Setting::Value(g) => Gate::Path(g),
        };
        let gate = gate.path(&read).map_err(|e| config_error("capture.gate", e.to_string()))?;
        let gate = gate.filter(|g| *g > read.time().t0);
        let mut full = match gate {
            Some(g) => read.gate(g).map_err(|e| config_error("capture.gate", e.to_string()))?,
            None => read.clone(),
        };
        let (fitted, surface_depth) = match c.max_depth {
            Setting::Word(Word::Off) => (None, None),
            Setting::Value(d) => {
                if !(d.is_finite() && d > 0.0) {
                    return Err(config_error("capture.max_depth", format!("{d}: a depth in metres (finite, > 0)")));
                }
                let t0 = full.time().t0;
                full = full.crop_path(t0, 2.0 * d).map_err(|e| config_error("capture.max_depth", e.to_string()))?;
                (None, None)
            }
            Setting::Word(Word::Auto) => {
                let ax = *full.time();
                let end = full.signal_end_path(gate.unwrap_or(ax.t0));
                if end < ax.end() {
                    // Each leg of a path is at least the depth of its point, so no surface lies deeper than
                    // half the last return's path, whatever the scan.
                    let depth = format!(" (depth at most {:.4} m)", end / 2.0);
                    notes.push(format!(
                        "max_depth auto: the last return ends at {end:.4} m of path{depth}; the {} later bins hold \
                         only background and are not fitted (capture.max_depth = \"off\" keeps them)",
                        ax.bins - ((end - ax.t0) / ax.bin_width).ceil() as usize,
                    ));
                    let cut =
                        full.crop_path(ax.t0, end).map_err(|e| config_error("capture.max_depth", e.to_string()))?;
                    (Some(cut), Some(end / 2.0))
                } else {
                    (None, None)
                }
            }
        };
        let fitted = fitted.unwrap_or_else(|| full.clone());
        let measured = match c.subsample {
            0 => return Err(config_error("capture.subsample", "0: give 1 to keep every scan point")),
            1 => fitted,
            k => fitted.subsample(k, k).map_err(|e| config_error("capture.subsample", e.to_string()))?,
        };
        let (schedule, note) =
            config.schedule.sized_to(wall_spacing(measured.scan()), measured.time().bin_width, measured.measurements());
        notes.extend(note);
        let (method, why) = config.init.resolve(full.scan());
        if config.init == InitMethod::Auto {
            notes.push(format!("init auto: {why} (\"{method}\"; init = \"lct\", \"pf\", … chooses another)"));
        }
        let (schedule, note) = schedule.for_start(method == InitMethod::Volume(Method::Pf));
        notes.extend(note);
        Ok(Self { read, gated: gate.is_some(), full, measured, surface_depth, notes, schedule })
    }
}

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
        p.albedo = (config.albedo == AlbedoChoice::Vertex).then(crate::AlbedoParams::default);
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

impl Prepared {
    /// The volume of `method` on [`Prepared::full`] (gated, rebinned, cut at an explicit max depth: the
    /// preparation every start shares), weighted for `reflectance` ([`Method::volume`]; `snr` replaces the
    /// LCT's Wiener SNR). `nlos reconstruct`, `nlos init`,
    /// `nlos eval --volume` and the Python package take their volumes here.
    ///
    /// # Errors
    /// [`OptimError::Init`] when the method fails (not a confocal grid, an empty volume).
    pub fn volume(&self, method: Method, reflectance: Model, snr: Option<f64>) -> Result<Volume> {
        Ok(method.volume(&self.full, reflectance, snr)?)
    }

    /// The phasor field's volume of [`Prepared::full`] with `params` (its gate and max depth are the
    /// preparation's: those of `params` are ignored).
    ///
    /// # Errors
    /// [`OptimError::Init`] for parameters out of range or an empty volume ([`nlos_init::pf()`]).
    pub fn pf_volume(&self, params: &PfParams) -> Result<Volume> {
        Ok(pf(&self.full, &PfParams { gate: Gate::None, max_depth: None, ..*params })?)
    }

    /// The surface extraction of `method`'s start: the settings for compact objects for LCT and the phasor
    /// field ([`SurfaceParams::object`]: Otsu's threshold alone keeps only the brightest columns, about half
    /// the bunny's silhouette from the LCT, a fifth from the one-laser phasor field), the plain extraction
    /// otherwise; no voxel beyond [`Prepared::surface_depth`].
    ///
    /// The largest depth step between neighbouring columns that still joins them grows with the scan's
    /// spacing: at least the extraction's own (5 cm), and what a surface at [`MAX_START_SLOPE`] to the wall
    /// makes between two columns. On the 64 × 64 captures over 0.5–2 m (spacing 8–31 mm) that is the fixed
    /// 5 cm up to 18 mm and 8.6 cm at 31 mm; on the published 8 × 8 Z-NLOS bunny (12.5 cm) a fixed 5 cm tore
    /// every cell of its sloping surface apart but two.
    pub fn surface_params(&self, method: Method) -> SurfaceParams {
        let base = method.surface_params();
        let spacing = wall_spacing(self.full.scan());
        let max_depth_jump = base.max_depth_jump.map(|j| j.max(MAX_START_SLOPE * spacing));
        SurfaceParams { max_depth: base.max_depth.or(self.surface_depth), max_depth_jump, ..base }
    }

    /// The initial surface: a volumetric reconstruction of [`Prepared::full`] turned into a mesh
    /// ([`Prepared::volume`], [`Prepared::surface_params`]), or the mesh file of [`InitMethod::Mesh`]; of
    /// two candidates ([`StartRim::Choose`]), the first ([`Prepared::start_candidates`]).
    ///
    /// # Errors
    /// [`OptimError::Init`] when the volume or its surface fails, [`OptimError::Mesh`] for an unreadable mesh.
    pub fn initial_surface(&self, config: &Config) -> Result<SurfaceMesh> {
        let mut candidates = self.start_candidates(config)?;
        Ok(candidates.swap_remove(0).1)
    }

    /// The starts the run may begin from, each with the rim it was given: one, or two when
    /// [`Config::init_rim`] resolves to [`StartRim::Choose`] for a volume whose extraction sets a rim
    /// apart ([`nlos_init::SurfaceParams::core_fraction`]): the receding rim first, then the measured one
    /// (every column at its own depth, each region grown relative to its own peak:
    /// [`nlos_init::GrowReference::Region`]), both from the same volume; one when the two are the same
    /// surface (a volume without a dim rim). A method whose extraction sets no rim apart (f-k, FBP,
    /// carving) and a mesh file are one start each, as they are ([`StartRim::Measured`]).
    ///
    /// # Errors
    /// As [`Prepared::initial_surface`].
    pub fn start_candidates(&self, config: &Config) -> Result<Vec<(StartRim, SurfaceMesh)>> {
        let method = match &config.init {
            InitMethod::Auto => Method::for_scan(self.full.scan()).0,
            InitMethod::Volume(method) => *method,
            InitMethod::Mesh(file) => return Ok(vec![(StartRim::Measured, nlos_mesh::io::load(file)?)]),
        };
        let volume = self.volume(method, config.reflectance.model, None)?;
        let receding = self.surface_params(method);
        // The volume as measured, without the convex object's priors: no core, so every column stays at its
        // own depth, and each part grown down its own flanks (a ball beside a brighter dish kept a third of
        // its pixels when grown relative to the dish's peak).
        let measured = SurfaceParams { core_fraction: None, grow_reference: GrowReference::Region, ..receding };
        let rims = match (config.init_rim.resolve(method, self.full.scan()), receding.core_fraction) {
            // The method's own extraction: it has no rim to place.
            (_, None) => vec![(StartRim::Measured, receding)],
            (StartRim::Measured, _) => vec![(StartRim::Measured, measured)],
            (StartRim::Choose, Some(_)) => vec![(StartRim::Receding, receding), (StartRim::Measured, measured)],
            _ => vec![(StartRim::Receding, receding)],
        };
        let mut starts: Vec<(StartRim, SurfaceMesh)> = rims
            .into_iter()
            .map(|(rim, params)| Ok((rim, volume_to_surface(&volume, &params)?.mesh)))
            .collect::<Result<_>>()?;
        // A volume whose every kept column is core gives the same surface twice: one run is enough.
        if starts.len() == 2 && starts[0].1.to_triangles() == starts[1].1.to_triangles() {
            starts.truncate(1);
        }
        Ok(starts)
    }
}

/// The steepest slope (depth per lateral metre, 70°) of the start's surface between two neighbouring
/// columns ([`Prepared::surface_params`]).
pub const MAX_START_SLOPE: f64 = 2.75;

/// The spacing of the wall points that resolve the scene laterally (metres): the spacing of the denser of
/// the laser and sensor sets (the scan points of a confocal scan, the sensor grid of a one-laser capture, the
/// pairs of a paired scan; [`nlos_transient::PointSet::spacing`], a list's from its bounding box), 0 when
/// it has none. The general-NLOS capture's 4,096 pairs over 1.5 × 1.8 m are 26 mm apart: its first edge is
/// 23 mm, not 14 mm from its bins, and its start 3,200 faces rather than 8,600.
pub(super) fn wall_spacing(scan: &nlos_transient::Scan) -> f64 {
    scan.dense_points().spacing().unwrap_or(0.0)
}

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
