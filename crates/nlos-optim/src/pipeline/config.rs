//! The settings users give a reconstruction ([`Config`]): every field with its default, read and written as
//! TOML with a comment above each field ([`FIELD_DOCS`]).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use nlos_brdf::Model;
pub use nlos_init::{InitMethod, Method};
use serde::{Deserialize, Serialize};

use crate::error::{OptimError, Result};
use nlos_render::{Device, SplatRule};

use crate::{PruneParams, ReconstructParams, ResidualParams, Schedule};

/// `"auto"` or `"off"` where a setting also takes a number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Word {
    /// Decided from the capture.
    Auto,
    /// Not applied.
    Off,
}

/// A setting that is `"auto"`, `"off"` or a number (its unit is the field's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Setting {
    /// `"auto"` or `"off"`.
    Word(Word),
    /// A number.
    Value(f64),
}

impl Setting {
    /// `"auto"`.
    pub const AUTO: Self = Self::Word(Word::Auto);
    /// `"off"`.
    pub const OFF: Self = Self::Word(Word::Off);
}

impl fmt::Display for Setting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Word(Word::Auto) => f.write_str("auto"),
            Self::Word(Word::Off) => f.write_str("off"),
            Self::Value(v) => write!(f, "{v}"),
        }
    }
}

/// The sensor's timing response the counts are fitted through ([`crate::SensorFit`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum SensorChoice {
    /// `direct` for photon counts that hold a direct reflection (real captures), `off` otherwise.
    Auto,
    /// An L2 fit of intensities.
    Off,
    /// A sensor without jitter.
    Ideal,
    /// The capture's own response, taken from its direct reflection off the wall
    /// ([`nlos_transient::sensor::JitterResponse::from_direct_return`]).
    Direct,
    /// A jitter file ([`nlos_transient::sensor::JitterResponse::load`]).
    File(PathBuf),
}

impl FromStr for SensorChoice {
    type Err = std::convert::Infallible;
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Ok(match s {
            "auto" => Self::Auto,
            "off" => Self::Off,
            "ideal" => Self::Ideal,
            "direct" => Self::Direct,
            path => Self::File(path.into()),
        })
    }
}

impl From<String> for SensorChoice {
    fn from(s: String) -> Self {
        match s.parse() {
            Ok(m) => m,
            Err(e) => match e {},
        }
    }
}

impl From<SensorChoice> for String {
    fn from(m: SensorChoice) -> Self {
        m.to_string()
    }
}

impl fmt::Display for SensorChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Auto => f.write_str("auto"),
            Self::Off => f.write_str("off"),
            Self::Ideal => f.write_str("ideal"),
            Self::Direct => f.write_str("direct"),
            Self::File(p) => write!(f, "{}", p.display()),
        }
    }
}

/// The noise model of the smoothing weight ([`crate::DataTerm::counts`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Noise {
    /// `counts` when every value is a non-negative integer.
    #[default]
    Auto,
    /// Poisson photon counts: λ is set against the misfit above the noise floor.
    Counts,
    /// λ against the whole data term (Tsai et al. 2019's rule).
    None,
}

/// How the surface's visibility from the wall is computed ([`nlos_render::Visibility`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VisibilityChoice {
    /// One shadow ray per face and measurement, recomputed after every remeshing.
    #[default]
    Cached,
    /// Per sample: exact, slow.
    Live,
    /// No occlusion: right for height fields only.
    Off,
}

/// How the start's rim gets its depth: the dim columns around the bright core of the volume, which the
/// lateral blur spreads around an object and puts at the depth of its brighter neighbours
/// ([`nlos_init::SurfaceParams::core_fraction`]). A convex object's rim recedes from the wall; a concave
/// one's (a dish with its inside toward the wall) comes toward it; one laser's volume does not tell which.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StartRim {
    /// `choose` for the phasor field's start of a capture lit from one spot (one laser seen by many sensor
    /// spots, or the reverse), `receding` for the others: with several lasers or paired spots (the 4 × 4
    /// lasers, the curved wall's bunny, the general-NLOS capture) the receding start won every time, and
    /// running the other cost the general-NLOS capture 41 % of its run (339 → 478 s on 2 cores).
    #[default]
    Auto,
    /// Behind the nearest core column, receding as a smooth convex silhouette does
    /// ([`nlos_init::SurfaceParams::object`]).
    Receding,
    /// Each column at the depth of its own maximum, and each part of the volume grown down its own flanks
    /// ([`nlos_init::GrowReference::Region`]): the volume as measured, without a convex object's priors.
    Measured,
    /// Both: the first stage runs from each, and the run goes on from the one that leaves less of the data
    /// unexplained at the next stage's first step ([`crate::pipeline::StartChoice`]).
    Choose,
}

impl StartRim {
    /// The rim of a start by `method` on `scan`: `auto` resolved, the others as they are.
    pub fn resolve(self, method: Method, scan: &nlos_transient::Scan) -> Self {
        let one_spot = matches!(scan.pattern, nlos_transient::ScanPattern::Exhaustive { ref lasers, ref sensors }
            if lasers.len() == 1 || sensors.len() == 1);
        match (self, method) {
            (Self::Auto, Method::Pf) if one_spot => Self::Choose,
            (Self::Auto, _) => Self::Receding,
            (rim, _) => rim,
        }
    }
}

impl fmt::Display for StartRim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Auto => "auto",
            Self::Receding => "receding",
            Self::Measured => "measured",
            Self::Choose => "choose",
        })
    }
}

/// Reflectance on the surface ([`crate::albedo`], [`crate::regions`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AlbedoChoice {
    /// An albedo per vertex, fitted with the shape; dark regions whose light the data do not detect are
    /// deleted. For objects with print or holes.
    Vertex,
    /// One albedo for the whole surface (Tsai et al. 2019).
    #[default]
    Off,
}

impl fmt::Display for AlbedoChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Vertex => "vertex",
            Self::Off => "off",
        })
    }
}

/// How the capture is prepared before anything else.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CaptureConfig {
    /// Sum this many consecutive bins (1: as captured).
    pub rebin: usize,
    /// Keep every k-th scan row and column of the fitted data (1: all; the initial surface always sees all).
    pub subsample: usize,
    /// Zero the bins before this path length (metres): the direct reflection off the wall is in no
    /// three-bounce rendering. `"auto"`: where the direct light ends in the summed histogram (a capture
    /// without direct light is left as it is); `"off"`: keep every bin.
    pub gate: Setting,
    /// Fit no bin whose path exceeds twice this depth (metres). `"auto"`: not the bins after the last
    /// return, where the summed histogram holds only background (plus 5 %), and the initial surface takes no
    /// voxel beyond that depth; `"off"`: the whole axis.
    pub max_depth: Setting,
    /// The bin width in picoseconds for a capture whose files do not store it (general-NLOS `data.mat` +
    /// `setup.mat`: 32 ps in the published experiment). `"auto"`: as the file says (an error for a file that
    /// says nothing).
    pub bin_width_ps: Setting,
}

impl Default for CaptureConfig {
    fn default() -> Self {
        Self { rebin: 1, subsample: 1, gate: Setting::AUTO, max_depth: Setting::AUTO, bin_width_ps: Setting::AUTO }
    }
}

impl CaptureConfig {
    /// What the reader is told that the file may not say ([`nlos_transient::ReadOptions`]).
    ///
    /// # Errors
    /// [`OptimError::Config`] for `bin_width_ps = "off"`.
    pub fn read_options(&self) -> Result<nlos_transient::ReadOptions> {
        match self.bin_width_ps {
            Setting::Word(Word::Auto) => Ok(nlos_transient::ReadOptions::default()),
            Setting::Value(ps) => Ok(nlos_transient::ReadOptions::with_bin_width_ps(Some(ps))),
            Setting::Word(Word::Off) => {
                Err(config_error("capture.bin_width_ps", "\"off\": give the bin width in ps, or \"auto\" (the file's)"))
            }
        }
    }
}

/// The reflectance model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReflectanceConfig {
    /// `"lambert"` (also `"lambertian"`), `"ggx"` or `"retroreflective"` ([`Model`]): the model fitted
    /// alongside the shape, starting at albedo 1 (GGX: its specular lobe alone, α below); the volumetric
    /// start is weighted for it.
    pub model: Model,
    /// Initial GGX roughness α, in [0.001, 1] (with `"ggx"`).
    pub alpha: f32,
}

impl Default for ReflectanceConfig {
    fn default() -> Self {
        Self { model: Model::Lambert, alpha: 0.3 }
    }
}

/// The data term's noise model and sensor fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// `"auto"`, `"off"`, `"ideal"`, `"direct"` or a jitter file ([`SensorChoice`]).
    pub response: SensorChoice,
    /// Background of the sensor fit in counts per bin, or `"auto"`: estimated from the bins before the first
    /// return of the capture as read.
    pub background: Setting,
    /// `"auto"`, `"counts"` or `"none"` ([`Noise`]).
    pub noise: Noise,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self { response: SensorChoice::Auto, background: Setting::AUTO, noise: Noise::Auto }
    }
}

/// The optimiser's steps and regularisers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OptimiserConfig {
    /// Learning rate of interior vertices, as a fraction of the stage's target edge length per Adam step.
    pub lr_interior: f64,
    /// Learning rate of boundary vertices, same unit.
    pub lr_boundary: f64,
    /// Learning rate of the reflectance parameters.
    pub lr_reflectance: f64,
    /// β of the automatic normal-smoothing weight λ = β·E_data/R at the start of each block.
    pub smoothing: f64,
    /// Weight of boundary smoothing relative to normal smoothing (0: off).
    pub boundary_smoothing: f64,
}

impl Default for OptimiserConfig {
    fn default() -> Self {
        let p = ReconstructParams::default();
        Self {
            lr_interior: p.lr_interior,
            lr_boundary: p.lr_boundary,
            lr_reflectance: p.lr_reflectance,
            smoothing: p.regulariser_ratio,
            boundary_smoothing: p.boundary_smoothing,
        }
    }
}

/// The renderer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {
    /// `"cached"`, `"live"` or `"off"` ([`VisibilityChoice`]).
    pub visibility: VisibilityChoice,
    /// Largest subdivision level of the closed-form time integration ([`SplatRule::max_level`], 1 to 64).
    pub max_level: u32,
    /// `"auto"` (a hardware GPU where one is found, else the CPU), `"gpu"` (any adapter, software ones
    /// included; an error without one) or `"cpu"` ([`nlos_render::Device`]).
    pub device: Device,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            visibility: VisibilityChoice::Cached,
            max_level: SplatRule::default().max_level,
            device: ReconstructParams::default().device,
        }
    }
}

/// The boundary steps after every block: pruning, and the residual's new patches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BoundaryConfig {
    /// Rounds of boundary pruning ([`crate::prune`]; 0: none).
    pub prune_rounds: u32,
    /// Margin κ of the pruning test (a face goes when ΔE < −κ·½c).
    pub prune_margin: f64,
    /// Residual back-projection after the first `residual_stages` stages ([`crate::residual`]; 0: none).
    pub residual_stages: u32,
    /// Residual columns closer than this to the mesh are left to the shape steps (metres).
    pub residual_separation: f64,
    /// Margin κ of the residual patches' test.
    pub residual_margin: f64,
    /// Tilts (degrees) of the residual patches' normals away from the wall normal.
    pub residual_tilts: Vec<f64>,
    /// Rounds of residual patches at a stage's end, at most (each after the last's patches; ≥ 1).
    pub residual_rounds: usize,
    /// The least share of the data term a round must explain for another to follow.
    pub residual_round_gain: f64,
}

impl Default for BoundaryConfig {
    fn default() -> Self {
        let (prune, residual) = (PruneParams::default(), ResidualParams::default());
        Self {
            prune_rounds: prune.rounds,
            prune_margin: prune.margin,
            residual_stages: residual.stages.unwrap_or(u32::MAX),
            residual_separation: residual.separation,
            residual_margin: residual.margin,
            residual_tilts: residual.tilts,
            residual_rounds: residual.rounds,
            residual_round_gain: residual.round_gain,
        }
    }
}

/// Every setting of a reconstruction, as `nlos reconstruct --config` reads it (TOML; every field optional,
/// defaults as [`Config::default`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Seed of the run (a run is a deterministic function of its inputs and seed).
    pub seed: u64,
    /// Where the optimisation starts: `"auto"`, `"lct"`, `"fk"`, `"pf"`, `"carve"` or a mesh file
    /// ([`InitMethod`]).
    pub init: InitMethod,
    /// The depth of the start's rim ([`StartRim`]): `"auto"`, `"receding"`, `"measured"` or `"choose"`.
    pub init_rim: StartRim,
    /// Reflectance on the surface ([`AlbedoChoice`]): `"vertex"` (an albedo per vertex, with the region
    /// tests that make dark regions holes or print) or `"off"` (one albedo).
    pub albedo: AlbedoChoice,
    /// Capture preparation.
    pub capture: CaptureConfig,
    /// Reflectance model.
    pub reflectance: ReflectanceConfig,
    /// Noise model and sensor fit.
    pub sensor: SensorConfig,
    /// The coarse-to-fine schedule ([`Schedule`]).
    pub schedule: Schedule,
    /// Learning rates and regularisers.
    pub optimiser: OptimiserConfig,
    /// Renderer.
    pub render: RenderConfig,
    /// Boundary steps.
    pub boundary: BoundaryConfig,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            seed: 0,
            init: InitMethod::Auto,
            init_rim: StartRim::Auto,
            albedo: AlbedoChoice::Off,
            capture: CaptureConfig::default(),
            reflectance: ReflectanceConfig::default(),
            sensor: SensorConfig::default(),
            schedule: Schedule::default(),
            optimiser: OptimiserConfig::default(),
            render: RenderConfig::default(),
            boundary: BoundaryConfig::default(),
        }
    }
}

pub(super) fn config_error(field: &str, reason: impl Into<String>) -> OptimError {
    OptimError::Config { field: field.to_owned(), reason: reason.into() }
}

/// Settings a file may still name that no longer exist, and what replaced each: such a file gets this error
/// (naming the key) rather than an unknown field's.
const REPLACED: [(&str, &str); 1] = [(
    "schedule.time_budget",
    "renamed schedule.reference_seconds: the same number, the budget in seconds of the 2-core reference \
     machine as predicted from face counts (not wall-clock time)",
)];

/// Whether `table` sets the dotted `key`.
fn names(table: &toml::Table, key: &str) -> bool {
    let mut node = table;
    let mut parts = key.split('.').peekable();
    while let Some(part) = parts.next() {
        match (node.get(part), parts.peek()) {
            (Some(_), None) => return true,
            (Some(toml::Value::Table(t)), Some(_)) => node = t,
            _ => return false,
        }
    }
    false
}

impl Config {
    /// Reads a configuration from TOML text; absent fields keep their defaults.
    ///
    /// # Errors
    /// [`OptimError::Config`] for malformed TOML, an unknown field or a value of the wrong type (the
    /// message names the line and the field), or a setting that was renamed or removed (naming what
    /// replaced it).
    pub fn from_toml(text: &str) -> Result<Self> {
        let table: toml::Table =
            text.parse().map_err(|e: toml::de::Error| config_error("config", e.to_string().trim_end().to_owned()))?;
        if let Some((key, what)) = REPLACED.iter().find(|(key, _)| names(&table, key)) {
            return Err(config_error(key, format!("{key} is no longer a setting: {what}")));
        }
        toml::from_str(text).map_err(|e| config_error("config", e.to_string().trim_end().to_owned()))
    }

    /// These settings with `overrides` written over them field by field: a table in `overrides` changes only
    /// the fields it names (how `nlos reconstruct --set` and the Python package's keyword settings change a
    /// configuration, or a run's saved one on resume).
    ///
    /// # Errors
    /// Those of [`Config::from_toml`] for the result (an unknown field, a value of the wrong type, naming it).
    pub fn overridden(&self, overrides: toml::Table) -> Result<Self> {
        let mut table: toml::Table =
            self.to_toml()?.parse().map_err(|e: toml::de::Error| config_error("config", e.to_string()))?;
        // Each changed setting is checked on its own, so that an error names it rather than a line of a TOML
        // document the user never wrote.
        if let Some((key, what)) = REPLACED.iter().find(|(key, _)| names(&overrides, key)) {
            return Err(config_error(key, format!("{key} is no longer a setting: {what}")));
        }
        for (key, value) in leaves(&overrides, "") {
            if !names(&table, &key) {
                let known = leaves(&table, "").into_iter().map(|(k, _)| k).collect::<Vec<_>>();
                return Err(config_error(&key, unknown_setting(&key, &known)));
            }
            let mut one = table.clone();
            overlay(&mut one, nested(&key, value));
            let text = toml::to_string(&one).map_err(|e| config_error(&key, e.to_string()))?;
            if let Err(e) = toml::from_str::<Config>(&text) {
                return Err(config_error(&key, e.message().trim_end().to_owned()));
            }
        }
        overlay(&mut table, overrides);
        let text = toml::to_string(&table).map_err(|e| config_error("config", e.to_string()))?;
        Self::from_toml(&text)
    }

    /// Reads a configuration file ([`Config::from_toml`]).
    ///
    /// # Errors
    /// [`OptimError::Io`] when the file cannot be read, and those of [`Config::from_toml`] (naming the file).
    pub fn load(path: &Path) -> Result<Self> {
        let fix = "check the path of the settings file (TOML, as `nlos reconstruct --print-config` writes it)";
        let text =
            std::fs::read_to_string(path).map_err(|source| OptimError::Io { path: path.to_owned(), fix, source })?;
        Self::from_toml(&text).map_err(|e| match e {
            OptimError::Config { reason, .. } => config_error(&path.display().to_string(), reason),
            e => e,
        })
    }

    /// The configuration as TOML: every field, each under a comment that says what it is ([`FIELD_DOCS`]),
    /// so that `--print-config` documents the defaults.
    ///
    /// # Errors
    /// [`OptimError::Config`] when a value has no TOML form (a non-finite number).
    pub fn to_toml(&self) -> Result<String> {
        // Serialised by `toml` (its number formats: an f32 setting prints as written), then commented through
        // the document model of `toml_edit`.
        let plain = toml::to_string(self).map_err(|e| config_error("config", e.to_string()))?;
        let mut doc: toml_edit::DocumentMut = plain.parse().map_err(|e| config_error("config", format!("{e}")))?;
        doc.decor_mut()
            .set_prefix("# nlos reconstruct settings (`--config FILE`); absent fields keep their defaults.\n");
        for (path, text) in FIELD_DOCS {
            let (table, key) = match path.split_once('.') {
                Some((section, key)) => (doc.get_mut(section).and_then(toml_edit::Item::as_table_like_mut), key),
                None => (Some(doc.as_table_mut() as &mut dyn toml_edit::TableLike), *path),
            };
            if let Some(mut key) = table.and_then(|t| t.key_mut(key)) {
                key.leaf_decor_mut().set_prefix(format!("# {text}\n"));
            }
        }
        Ok(doc.to_string())
    }
}

/// One line per setting, for the comments of [`Config::to_toml`] (the fields' rustdoc says more).
pub const FIELD_DOCS: &[(&str, &str)] = &[
    ("seed", "seed of the run: a run is a deterministic function of its inputs and seed"),
    (
        "init",
        "initial surface: \"auto\" (LCT on confocal grids, else the phasor field), \"lct\", \"fk\", \"pf\", \"carve\" \
         or a mesh file (OBJ/PLY/GLB) facing the wall",
    ),
    (
        "init_rim",
        "depth of the start's dim rim: \"receding\" (convex), \"measured\" (its own), \"choose\" (both run a stage, \
         the data choose) or \"auto\" (choose for the phasor field on one laser's capture, else receding)",
    ),
    (
        "albedo",
        "reflectance on the surface: \"vertex\" (an albedo per vertex; dark regions become holes or print) or \"off\" (one albedo)",
    ),
    ("capture.rebin", "sum this many consecutive bins first (1: as captured)"),
    ("capture.subsample", "fit every k-th scan row and column (the initial surface sees them all)"),
    ("capture.gate", "zero the bins before this path length (m): \"auto\" (end of the direct light) or \"off\""),
    ("capture.max_depth", "fit no bin beyond 2 × this depth (m): \"auto\" (after the last return) or \"off\""),
    ("capture.bin_width_ps", "bin width (ps) for files that do not store it (general-NLOS: 32), or \"auto\""),
    (
        "reflectance.model",
        "\"lambert\" (or \"lambertian\"), \"ggx\" or \"retroreflective\" (1/r² confocal return; start weighted for it)",
    ),
    ("reflectance.alpha", "initial GGX roughness, in [0.001, 1]"),
    ("sensor.response", "\"auto\", \"off\" (L2), \"ideal\", \"direct\" (the capture's own) or a jitter file"),
    ("sensor.background", "background counts per bin of the sensor fit, or \"auto\""),
    ("sensor.noise", "noise model of the smoothing weight: \"auto\", \"counts\" or \"none\""),
    ("schedule.initial_resolution", "first stage: target edge length extent / resolution"),
    ("schedule.growth", "resolution factor between stages"),
    ("schedule.extent", "numerator of the target edge length (m)"),
    ("schedule.max_stages", "coarse-to-fine stages at most"),
    ("schedule.max_faces", "a stage that would exceed this many faces is not started"),
    ("schedule.max_blocks_per_stage", "blocks per stage at most"),
    ("schedule.shape_iterations", "Adam steps on the vertices per block"),
    ("schedule.reflectance_iterations", "Adam steps on the reflectance per block (0: none)"),
    ("schedule.rel_tol", "a stage ends when a block lowers the loss by less than this fraction"),
    (
        "schedule.reference_seconds",
        "budget of the blocks in seconds of a 2-core reference machine, predicted from faces, not timed (0: none)",
    ),
    (
        "schedule.rebin_fraction",
        "a stage sums bins up to this fraction of its edge length (0: all at the capture's bins)",
    ),
    ("optimiser.lr_interior", "step of interior vertices, as a fraction of the stage's edge length"),
    ("optimiser.lr_boundary", "step of boundary vertices, same unit"),
    ("optimiser.lr_reflectance", "step of the reflectance parameters"),
    ("optimiser.smoothing", "β of the normal-smoothing weight λ = β·E_data/R"),
    ("optimiser.boundary_smoothing", "weight of boundary smoothing relative to normal smoothing (0: off)"),
    ("render.visibility", "\"cached\" (per face and measurement), \"live\" (exact, slow) or \"off\" (height fields)"),
    ("render.max_level", "largest subdivision level of the closed-form time integration (1 to 64)"),
    (
        "render.device",
        "\"auto\" (a hardware GPU where found, else the CPU), \"gpu\" (any adapter; error without) or \"cpu\"",
    ),
    ("boundary.prune_rounds", "rounds of boundary pruning after every block (0: none)"),
    ("boundary.prune_margin", "margin κ of the pruning test"),
    ("boundary.residual_stages", "residual patches after the first N stages (0: none)"),
    ("boundary.residual_separation", "residual columns closer than this to the mesh (m) are left to the steps"),
    ("boundary.residual_margin", "margin κ of the residual patches' test"),
    ("boundary.residual_tilts", "tilts (degrees) of the residual patches' normals"),
    ("boundary.residual_rounds", "rounds of residual patches at a stage's end at most, each after the last's patches"),
    ("boundary.residual_round_gain", "least share of the data term a round must explain for another to follow"),
];

/// Writes `top`'s fields over `base`'s, descending into the tables both have.
/// Every value of `table` that is not itself a table, with its dotted key (`capture.gate`).
fn leaves(table: &toml::Table, prefix: &str) -> Vec<(String, toml::Value)> {
    table
        .iter()
        .flat_map(|(k, v)| {
            let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
            match v {
                toml::Value::Table(t) => leaves(t, &key),
                v => vec![(key, v.clone())],
            }
        })
        .collect()
}

/// The table that sets only the dotted `key` to `value`.
fn nested(key: &str, value: toml::Value) -> toml::Table {
    let mut parts = key.rsplit('.');
    let mut table = toml::Table::new();
    table.insert(parts.next().unwrap_or(key).to_owned(), value);
    for part in parts {
        let mut outer = toml::Table::new();
        outer.insert(part.to_owned(), toml::Value::Table(table));
        table = outer;
    }
    table
}

/// Why `key` is not a setting, with up to three settings of similar names (Jaro–Winkler ≥ 0.8) to try instead.
fn unknown_setting(key: &str, known: &[String]) -> String {
    let mut near: Vec<(f64, &str)> =
        known.iter().map(|k| (strsim::jaro_winkler(key, k), k.as_str())).filter(|(s, _)| *s >= 0.8).collect();
    near.sort_by(|a, b| b.0.total_cmp(&a.0));
    let names: Vec<&str> = near.iter().take(3).map(|(_, k)| *k).collect();
    let hint = if names.is_empty() { String::new() } else { format!(" (did you mean {}?)", names.join(", ")) };
    format!("no such setting{hint}; `nlos reconstruct --print-config` lists every setting")
}

fn overlay(base: &mut toml::Table, top: toml::Table) {
    for (key, value) in top {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => overlay(b, t),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}
