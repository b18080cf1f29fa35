//! The whole reconstruction as users run it: a capture file in, a mesh out, every `auto` decided here.
//!
//! [`Config`] holds every setting a user may change, each with its default ([`Config::default`] takes them
//! from [`ReconstructParams::default`] and the initialisers' defaults: one source). It reads and writes TOML
//! ([`Config::from_toml`], [`Config::to_toml`]; `nlos reconstruct --print-config` prints the defaults).
//! [`Prepared::new`] prepares the capture (rebin, gate, max depth, subsample), [`Prepared::params`] decides
//! the optimiser's parameters (noise model, sensor fit, background) and [`Prepared::initial_surface`]
//! extracts the start. `nlos reconstruct`, `cargo xtask reconstruct` and the Python package all go through
//! here, so a Rust caller gets the same run as the command line:
//!
//! [`run`] then owns the run directory: it writes the settings and the start surface and starts the
//! optimisation, or resumes it ([`Start`]).
//!
//! ```no_run
//! # fn demo() -> nlos_optim::Result<()> {
//! use nlos_optim::pipeline::{self, Config, Prepared, Start};
//! let config = Config::default();
//! let prepared = Prepared::load("capture.hdf5".as_ref(), &config)?;
//! let params = prepared.params(&config, Some("run".into()))?;
//! let outcome = pipeline::run(&prepared, &config, &params, Start::New, nlos_optim::Hooks::default())?;
//! println!("{} faces", outcome.mesh.n_faces());
//! # Ok(()) }
//! ```

use std::path::{Path, PathBuf};

use nlos_init::{Gate, Model, PfParams, SurfaceParams, Volume, pf, volume_to_surface};
use nlos_mesh::SurfaceMesh;
use nlos_render::{Device, SplatRule, Visibility};
use nlos_transient::Transient;
use nlos_transient::sensor::{BackgroundWindow, BinKernel, JitterResponse};

use crate::error::{OptimError, Result};

mod run_dir;
mod start_response;
use crate::{AlbedoMapParams, PruneParams, ReconstructParams, Reflectance, ResidualParams, SamplingSchedule};
use crate::{Schedule, SensorBackground, SensorFit};
pub use run_dir::{INIT_FILE, SETTINGS_FILE, Start, check_resumable, run, saved_config};

mod config;
use config::config_error;
pub use config::*;

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
        p.sampling = SamplingSchedule::Splat(SplatRule { max_level, ..SplatRule::default() });
        p.device = config.render.device;
        if p.device == Device::Gpu && !nlos_render::gpu_supports(r.model) {
            return Err(config_error(
                "render.device",
                format!("\"gpu\": the reflectance model \"{}\" has no GPU version; use \"auto\" or \"cpu\"", r.model),
            ));
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
    /// [`OptimError::Init`] for parameters out of range or an empty volume ([`nlos_init::pf`]).
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
    /// ([`Prepared::volume`], [`Prepared::surface_params`]), or the mesh file of [`InitMethod::Mesh`].
    ///
    /// # Errors
    /// [`OptimError::Init`] when the volume or its surface fails, [`OptimError::Mesh`] for an unreadable mesh.
    pub fn initial_surface(&self, config: &Config) -> Result<SurfaceMesh> {
        let method = match &config.init {
            InitMethod::Auto => Method::for_scan(self.full.scan()).0,
            InitMethod::Volume(method) => *method,
            InitMethod::Mesh(file) => return Ok(nlos_mesh::io::load(file)?),
        };
        let volume = self.volume(method, config.reflectance.model, None)?;
        Ok(volume_to_surface(&volume, &self.surface_params(method))?.mesh)
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
fn wall_spacing(scan: &nlos_transient::Scan) -> f64 {
    scan.dense_points().spacing().unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every setting printed has its comment, and every comment names a setting.
    #[test]
    fn every_setting_is_documented() {
        let text = Config::default().to_toml().expect("toml");
        let mut section = String::new();
        let mut keys = Vec::new();
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                section = format!("{name}.");
            } else if let Some((key, _)) = line.split_once(" = ") {
                keys.push(format!("{section}{key}"));
            }
        }
        for key in &keys {
            assert!(FIELD_DOCS.iter().any(|(k, _)| k == key), "{key} has no comment");
        }
        for (k, _) in FIELD_DOCS {
            assert!(keys.iter().any(|key| key == k), "comment for {k}, which is not a setting");
        }
    }

    /// A raw capture holding its direct light and the same capture gated before it reached us (bins 0..600
    /// zeroed, as Tsai et al.'s files are) get the same sensor-fit floor: the level of the axis's last 10 %,
    /// bins both hold, here above the quiet bins' background because a late return reaches the axis's end;
    /// the gated capture scaled by a constant (not integers) gets the Poisson fit too, its floor scaled.
    #[test]
    fn a_raw_capture_and_its_gated_version_get_the_same_floor() {
        use nlos_transient::sensor::estimate_background;
        use nlos_transient::{PointSet, Scan, TimeAxis};
        let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.25, 0.25).expect("grid"));
        let bins = 1600;
        // A Gaussian rise (σ = 4 bins), then 90 % Gaussian fall and a 10 % diffusion tail (τ = 60 bins).
        let response = |j: f64| {
            let g = (-0.5 * (j / 4.0).powi(2)).exp();
            if j < 0.0 { g } else { 0.9 * g + 0.1 * (-j / 60.0).exp() }
        };
        let mut data = Vec::with_capacity(64 * bins);
        for m in 0..64 {
            let first = 1100.0 + (m / 4) as f64;
            data.extend((0..bins).map(|k| {
                let k = k as f64;
                let mean = 2.0e4 * response(k) + 40.0 * response(k - first) + 20.0 * response(k - 1500.0) + 1.0;
                mean.round() as f32
            }));
        }
        let raw = Transient::new(scan, TimeAxis::new(0.0, 0.0012, bins).expect("axis"), data).expect("capture");
        let mut gated = raw.clone();
        for m in 0..64 {
            gated.histogram_mut(m)[..600].fill(0.0);
        }
        assert_eq!((raw.zero_gate(), gated.zero_gate()), (None, Some(600)));
        let config = Config::default();
        let floor = |t: Transient| {
            let prepared = Prepared::new(t, &config).expect("prepare");
            assert!(prepared.gated);
            match prepared.params(&config, None).expect("params").sensor {
                Some(SensorFit { background: SensorBackground::Fixed(b), .. }) => b,
                other => panic!("{other:?}"),
            }
        };
        // The gated capture scaled by a constant (values no longer integers) is fitted alike, its floor scaled.
        let mut scaled = gated.clone();
        for m in 0..64 {
            scaled.histogram_mut(m).iter_mut().for_each(|v| *v *= 0.37);
        }
        let from_scaled = floor(scaled);
        let (from_raw, from_gated) = (floor(raw.clone()), floor(gated));
        assert!((from_scaled - 0.37 * from_gated).abs() < 1e-6 * from_gated, "{from_scaled} against {from_gated}");
        assert_eq!(from_raw, from_gated);
        let axis_end = estimate_background(&raw, BackgroundWindow::AxisEnd).expect("estimate");
        assert_eq!(from_raw, axis_end.per_bin);
        // The quiet bins between the direct light and the first return hold the background (1 per bin).
        let quiet = estimate_background(&raw, BackgroundWindow::Auto).expect("estimate");
        assert_eq!(quiet.per_bin, 1.0, "{quiet:?}");
        assert!(from_raw > 1.5, "the floor {from_raw} holds the late return");
    }

    /// The settings file spells the start as `nlos init --method` and `nlos reconstruct --init` do.
    #[test]
    fn init_is_written_by_name() {
        assert_eq!(Config::default().init, InitMethod::Auto);
        for (text, want) in [
            ("auto", InitMethod::Auto),
            ("pf", InitMethod::Volume(Method::Pf)),
            ("fbp", InitMethod::Volume(Method::Fbp)),
            ("start.obj", InitMethod::Mesh("start.obj".into())),
        ] {
            let c = Config::from_toml(&format!("init = \"{text}\"\n")).expect("parse");
            assert_eq!(c.init, want);
            assert_eq!(c.init.to_string(), text);
        }
    }

    #[test]
    fn overrides_change_only_the_fields_they_name() {
        let base = Config { seed: 7, ..Config::default() };
        let mut schedule = toml::Table::new();
        schedule.insert("max_stages".into(), toml::Value::Integer(2));
        let mut overrides = toml::Table::new();
        overrides.insert("schedule".into(), toml::Value::Table(schedule));
        let c = base.overridden(overrides).expect("valid");
        assert_eq!(c.schedule.max_stages, 2);
        assert_eq!(c.seed, 7, "a field not named keeps the base's value");
        assert_eq!(c.schedule.shape_iterations, base.schedule.shape_iterations);
        let mut bad = toml::Table::new();
        bad.insert("no_such_section".into(), toml::Value::Integer(1));
        assert!(matches!(base.overridden(bad), Err(OptimError::Config { .. })));
    }

    #[test]
    fn settings_round_trip_through_toml() {
        assert_eq!(Config::from_toml(&Config::default().to_toml().expect("toml")).expect("parse"), Config::default());
        let mut c = Config { seed: 9, init: InitMethod::Mesh("start.obj".into()), ..Config::default() };
        c.capture.gate = Setting::Value(0.3);
        c.capture.max_depth = Setting::OFF;
        c.sensor.response = SensorChoice::File("jitter.mat".into());
        c.reflectance.model = Model::Ggx;
        c.schedule.max_stages = 2;
        c.boundary.residual_tilts = vec![30.0];
        assert_eq!(Config::from_toml(&c.to_toml().expect("toml")).expect("parse"), c);
        // Absent fields keep their defaults; integers are numbers too.
        let partial = Config::from_toml("[capture]\ngate = 1\n").expect("parse");
        assert_eq!(
            partial,
            Config {
                capture: CaptureConfig { gate: Setting::Value(1.0), ..CaptureConfig::default() },
                ..Config::default()
            }
        );
    }

    #[test]
    fn bad_settings_are_typed_errors_naming_the_field() {
        for (text, field) in [
            ("[capture]\ngate = \"lots\"\n", "gate"),
            ("[schedule]\nmax_stages = -1\n", "max_stages"),
            ("[render]\nvisibility = \"sometimes\"\n", "visibility"),
            ("no_such_setting = 1\n", "no_such_setting"),
            ("[capture\n", "capture"),
        ] {
            match Config::from_toml(text) {
                Err(OptimError::Config { reason, .. }) => assert!(reason.contains(field), "{text}: {reason}"),
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    #[test]
    fn a_renamed_setting_says_what_replaced_it() {
        let from_file = Config::from_toml("[schedule]\ntime_budget = 300\n");
        let mut set = toml::Table::new();
        set.insert("schedule".into(), toml::Value::Table(toml::toml! { time_budget = 300 }));
        for result in [from_file, Config::default().overridden(set)] {
            match result {
                Err(OptimError::Config { field, reason }) => {
                    assert_eq!(field, "schedule.time_budget");
                    assert!(reason.contains("renamed schedule.reference_seconds"), "{reason}");
                }
                other => panic!("{other:?}"),
            }
        }
        let renamed = Config::from_toml("[schedule]\nreference_seconds = 300\n").expect("the new name");
        assert_eq!(renamed.schedule.reference_seconds, 300.0);
    }
}
