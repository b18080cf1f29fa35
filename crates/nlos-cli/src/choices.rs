//! Choices shared by several commands, as clap value enums and parsers.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use nlos_brdf::Model;
use nlos_init::{InitMethod, Method};

/// `--brdf`: the reflectance model, by the names and aliases of [`Model`] (its `FromStr`).
pub(crate) fn brdf_parser() -> impl TypedValueParser<Value = Model> {
    let value = |m: Model| {
        Model::ALIASES
            .iter()
            .filter(|(_, a)| *a == m)
            .fold(PossibleValue::new(m.name()), |v, (alias, _)| v.alias(alias))
    };
    PossibleValuesParser::new(Model::ALL.map(value)).try_map(|s| s.parse::<Model>())
}

/// `nlos eval --method`: a start method by name, each listed with its summary ([`Method::ALL`]).
pub(crate) fn method_parser() -> impl TypedValueParser<Value = Method> {
    PossibleValuesParser::new(Method::ALL.map(|m| PossibleValue::new(m.name()).help(m.summary())))
        .try_map(|s| s.parse::<Method>())
}

/// `nlos init --method`: `auto` or a start method by name ([`method_parser`]).
pub(crate) fn start_parser() -> impl TypedValueParser<Value = InitMethod> {
    let auto = PossibleValue::new("auto").help(
        "LCT on a confocal scan over a regular grid, the phasor field on every other scan (as `nlos reconstruct`)",
    );
    let named = Method::ALL.map(|m| PossibleValue::new(m.name()).help(m.summary()));
    PossibleValuesParser::new(std::iter::once(auto).chain(named)).map(InitMethod::from)
}

/// `--visibility`: how occlusion between the surface and the wall is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum VisibilityArg {
    /// One visible fraction per triangle and measurement (fast, exact away from shadow boundaries).
    Cached,
    /// A shadow ray per sample (exact, slow on large meshes).
    Live,
    /// No occlusion.
    Off,
}

/// `nlos render --mode`: how the surface integral is evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ModeArg {
    /// Noise-free closed-form time integration against the box kernel (`Sampling::Splat` with
    /// `Kernel::Box`): each face's path-length density integrated over each bin exactly.
    Exact,
    /// Noise-free adaptive point quadrature (sub-triangles of at most half a bin, each assigned to one bin):
    /// `--mode exact` before the closed form, 13× less accurate and 30× slower.
    Quadrature,
    /// Tsai et al. 2019's stratified area sampling.
    Mc,
    /// The optimiser's rule: closed-form time integration against the tent kernel (`nlos_render::SplatRule`);
    /// the one `--device gpu` runs.
    Splat,
}

/// `--device`: where the renderer runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum DeviceArg {
    /// The CPU.
    Cpu,
    /// A GPU (wgpu; software adapters such as Mesa's lavapipe too); an error without one.
    Gpu,
    /// A hardware GPU where one is found, else the CPU.
    Auto,
}

impl From<DeviceArg> for nlos_render::Device {
    fn from(d: DeviceArg) -> Self {
        match d {
            DeviceArg::Cpu => Self::Cpu,
            DeviceArg::Gpu => Self::Gpu,
            DeviceArg::Auto => Self::Auto,
        }
    }
}

/// What a reader is told that some capture files do not say, shared by every command that reads one.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub(crate) struct ReadArgs {
    /// Bin width in picoseconds, for captures whose files do not store it: general-NLOS `data.mat` +
    /// `setup.mat` (32 ps in the published experiment). Refused for files that have their own.
    #[arg(long, value_name = "PS")]
    pub(crate) bin_width_ps: Option<f64>,
}

impl ReadArgs {
    /// The reader's options.
    pub(crate) fn options(self) -> nlos_transient::ReadOptions {
        nlos_transient::ReadOptions::with_bin_width_ps(self.bin_width_ps)
    }

    /// Reads `file` (any format) with these options.
    pub(crate) fn read(self, file: &std::path::Path) -> Result<nlos_transient::Transient, crate::CliError> {
        nlos_transient::read_with(file, &self.options()).map_err(crate::CliError::input)
    }
}
