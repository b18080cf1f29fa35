//! Choices shared by several commands, as clap value enums.

/// `--brdf`: the reflectance model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum BrdfArg {
    /// One albedo.
    Lambert,
    /// GGX microfacet lobe.
    Ggx,
    /// A retroreflector: the confocal return falls as 1/r² (`nlos_brdf::Retroreflective`).
    Retroreflective,
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
    /// Noise-free adaptive quadrature.
    Exact,
    /// Tsai et al. 2019's stratified area sampling.
    Mc,
}
