//! Parameters of a reconstruction, with documented defaults (the schedule's in [`crate::schedule`]).

use std::path::PathBuf;

use nlos_mesh::evolve::EvolveParams;
use nlos_mesh::remeshing::{BoundaryMode, RemeshParams};
use nlos_render::{DeterministicRule, Device, Kernel, RenderParams, Sampling, SplatRule, Visibility};

use crate::adam::AdamParams;
use crate::albedo::AlbedoParams;
use crate::data_term::counts::SensorFit;
use crate::data_term::intensities::DataTerm;
use crate::error::{OptimError, Result};
use crate::prune::PruneParams;
use crate::reflectance::Reflectance;
use crate::regions::RegionParams;
use crate::residual::ResidualParams;
use crate::schedule::Schedule;

/// How the renderer samples the surface, stage by stage ("the sample budget grows").
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum SamplingSchedule {
    /// Closed-form time integration of each (sub-)triangle against the tent kernel
    /// (`nlos_render::Sampling::Splat`): noise-free, exact in time whatever the bins a face spans. The
    /// default (`SplatRule::default()`): at Tsai et al. 2019's setup one forward + adjoint on the bunny's 3.2k-face
    /// first stage takes under a second on 2 cores, against 20 s for the adaptive quadrature below at
    /// `max_level` 8, at a bin-level error against the exact quadrature of 1.46e-3 against its 1.52e-3
    /// (docs/performance.md).
    Splat(SplatRule),
    /// Noise-free quadrature with an adaptive level per (triangle, measurement) (`DeterministicRule`).
    Deterministic(DeterministicRule),
    /// Tsai et al. 2019's stratified area sampling, `initial_samples · growthᵏ` samples per measurement in stage k;
    /// the sampling seed is drawn once per block from the run's RNG (so a run is reproducible).
    Stratified {
        /// Samples per measurement in stage 0.
        initial_samples: u32,
        /// Growth factor per stage (≥ 1).
        growth: f64,
    },
}

impl Default for SamplingSchedule {
    fn default() -> Self {
        SamplingSchedule::Splat(SplatRule::default())
    }
}

/// A [`RenderParams`] without its sampling rule: the renderer's settings of a run, whose sampling
/// [`ReconstructParams::sampling`] gives stage by stage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RenderSettings {
    /// Temporal kernel, used in both passes ([`RenderParams::kernel`]).
    pub kernel: Kernel,
    /// Visibility ([`RenderParams::visibility`]).
    pub visibility: Visibility,
    /// Whether back faces reflect too ([`RenderParams::two_sided`]).
    pub two_sided: bool,
}

impl Default for RenderSettings {
    /// [`RenderParams`]'s defaults.
    fn default() -> Self {
        let RenderParams { kernel, visibility, two_sided, .. } = RenderParams::default();
        Self { kernel, visibility, two_sided }
    }
}

impl RenderSettings {
    /// The renderer's parameters with this sampling rule.
    pub fn with_sampling(self, sampling: Sampling) -> RenderParams {
        RenderParams { kernel: self.kernel, sampling, visibility: self.visibility, two_sided: self.two_sided }
    }
}

/// Everything a reconstruction needs besides the measurement and the initial mesh.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ReconstructParams {
    /// Data term: loss (default L2, eq. 7), weights (none), scale solving (on).
    pub data: DataTerm,
    /// Noise-aware fit of photon counts ([`crate::data_term::counts`]): when set, the data term is the Poisson
    /// NLL of `scale·J(I) + b` against the counts, replacing `data.loss` (`data.solve_scale` still applies;
    /// per-bin weights are not supported with it). Default None.
    pub sensor: Option<SensorFit>,
    /// Initial reflectance (default Lambertian, albedo 1). Fitted in reflectance blocks of
    /// [`Schedule::reflectance_iterations`] steps (0: none) where the model has free parameters beyond the scale
    /// ([`Reflectance`]: none for a Lambertian or retroreflective model with the scale solved) or an albedo map
    /// is fitted.
    pub reflectance: Reflectance,
    /// Coarse-to-fine schedule.
    pub schedule: Schedule,
    /// Adam hyper-parameters for the vertices (default Kingma & Ba's).
    pub shape_adam: AdamParams,
    /// Learning rate of interior vertices, as a fraction of the stage's target edge length (default 0.05:
    /// an Adam step moves a vertex by about 5% of an edge).
    pub lr_interior: f64,
    /// Learning rate of boundary vertices, same unit (default 0.02: boundaries are poorly constrained).
    pub lr_boundary: f64,
    /// Adam hyper-parameters for θ.
    pub reflectance_adam: AdamParams,
    /// Learning rate for θ (default 0.05).
    pub lr_reflectance: f64,
    /// β of the automatic regulariser weight `λ = β E_data/R` (default 0.1), see
    /// [`crate::regularizer::auto_weight`]. With [`ReconstructParams::sensor`] or [`DataTerm::counts`],
    /// `E_data` is the data term above its Poisson noise floor (`crate::data_term::counts`, "Noise floor"), at least
    /// 1 % of the data term.
    pub regulariser_ratio: f64,
    /// A fixed regulariser weight λ instead of the automatic one (default None).
    pub regulariser_weight: Option<f64>,
    /// Weight of the boundary-smoothing term relative to the normal-smoothing one: the regulariser is
    /// `λ (R + w R_∂)` ([`crate::boundary_smoothing`]; λ is still set against `R` alone; on a patch that is mostly
    /// rim its step holds the boundary loop's enclosed area). 0 turns it off; default 1.
    pub boundary_smoothing: f64,
    /// Reflectance on the surface ([`crate::albedo`]): a relative albedo per vertex, fitted in every shape
    /// step with the vertices and in the reflectance blocks, with a total-variation prior (default `None`:
    /// one albedo for the whole surface, as in Tsai et al. 2019). For objects with print or holes; not the
    /// default yet, because it moves the bunny, the reference bunny and the 40 cm chart (docs/accuracy.md).
    pub albedo: Option<AlbedoParams>,
    /// Region tests after every block ([`crate::regions`]; they run only with [`ReconstructParams::albedo`]): dark regions
    /// whose light the data do not detect are deleted — holes — and the others kept darker — print (default
    /// `Some(RegionParams::default())`).
    pub regions: Option<RegionParams>,
    /// Renderer settings besides the sampling rule, which [`ReconstructParams::sampling`] gives stage by stage
    /// (default: [`RenderParams`]'s — tent kernel, needed for the time-shift gradient; live visibility;
    /// one-sided faces).
    pub render: RenderSettings,
    /// Where the shape and reflectance steps render ([`nlos_render::Renderer::set_device`]; default
    /// [`Device::Auto`]: a hardware GPU where the build has the feature `gpu` and one is found, else the CPU).
    /// Not in a checkpoint's settings record: the device changes the results only by f32 rounding, so a run
    /// may resume on another one.
    #[serde(skip)]
    pub device: Device,
    /// Sampling schedule.
    pub sampling: SamplingSchedule,
    /// Remeshing after every shape block (default: `RemeshParams::fast()` with the boundary remeshed along
    /// itself, so boundary edges follow the target length too, and every operation tested for collisions,
    /// `avoid_intersections`).
    pub remesh: RemeshParams,
    /// Collision-aware evolution (El Topo, [`nlos_mesh::evolve::evolve`]) of every shape step's
    /// displacement, so that no step makes the surface intersect itself (default `Some` with
    /// `edge_length: None` → the stage's target length; `None` applies the displacements as they are).
    /// `improve` and `check_input` are always treated as false: the remeshing that follows improves the mesh,
    /// the Adam state needs fixed connectivity, and the block's mesh was checked where it started. The loop
    /// deletes the faces of any self-intersection found in the start, after a remeshing or at the end of a
    /// block (`RunLog::intersections`; after the start, with the default settings, there are none); should
    /// that repair fail (no deletion keeps the mesh manifold), the old intersections stay and only new ones
    /// are prevented.
    pub collision: Option<EvolveParams>,
    /// Loss-driven boundary pruning after every block ([`crate::prune`]): boundary faces whose deletion
    /// lowers the data term by more than the margin are deleted (default `Some(PruneParams::default())`:
    /// 3 rounds, margin 0.5). It removes the start's rim and the surface the fit grows where no light
    /// comes from: on the shared bunnies it cuts the mean depth error by a quarter to a half and the
    /// normal error by 2–7°, for 2–3 points of coverage (docs/accuracy.md).
    pub prune: Option<PruneParams>,
    /// Residual back-projection at the end of the first stage ([`crate::residual`]): the LCT of the fit's
    /// residual (the phasor field's on scans that are not confocal grids) proposes surface patches away from
    /// the mesh, added where they lower the data term (default `Some(ResidualParams::default())`): it finds parts
    /// the start lacks, as far as the data show them ([`crate::residual`]).
    pub residual: Option<ResidualParams>,
    /// Seed of the run's RNG (default 0). A run is a deterministic function of its inputs and this seed.
    pub seed: u64,
    /// Rollbacks (non-finite loss, gradient or positions → restore the last good state, halve the step)
    /// allowed per run before giving up (default 10).
    pub max_rollbacks: u32,
    /// Output directory for the checkpoint, the run log and the meshes (default None: nothing written,
    /// and [`crate::resume`] is impossible). Not a setting of the run: the settings record leaves it out.
    #[serde(skip)]
    pub out_dir: Option<PathBuf>,
}

impl Default for ReconstructParams {
    fn default() -> Self {
        Self {
            data: DataTerm::default(),
            sensor: None,
            reflectance: Reflectance::default(),
            schedule: Schedule::default(),
            shape_adam: AdamParams::default(),
            lr_interior: 0.05,
            lr_boundary: 0.02,
            reflectance_adam: AdamParams::default(),
            lr_reflectance: 0.05,
            regulariser_ratio: 0.1,
            boundary_smoothing: 1.0,
            albedo: None,
            regions: Some(RegionParams::default()),
            regulariser_weight: None,
            render: RenderSettings::default(),
            device: Device::Auto,
            sampling: SamplingSchedule::default(),
            remesh: RemeshParams { boundary: BoundaryMode::Remesh, avoid_intersections: true, ..RemeshParams::fast() },
            collision: Some(EvolveParams { improve: false, ..EvolveParams::default() }),
            prune: Some(PruneParams::default()),
            residual: Some(ResidualParams::default()),
            seed: 0,
            max_rollbacks: 10,
            out_dir: None,
        }
    }
}

impl ReconstructParams {
    /// Checks every numeric parameter.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value: f64, reason| Err(OptimError::InvalidParameter { name, value, reason });
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if let Some(r) = &self.residual {
            r.validate()?;
        }
        if let Some(p) = &self.prune {
            p.validate()?;
        }
        if let Some(a) = &self.albedo {
            a.validate()?;
        }
        if let Some(r) = &self.regions {
            r.validate()?;
        }
        let s = &self.schedule;
        if !pos(s.initial_resolution) {
            return bad("schedule.initial_resolution", s.initial_resolution, "must be finite and > 0");
        }
        if !(s.growth.is_finite() && s.growth >= 1.0) {
            return bad("schedule.growth", s.growth, "must be finite and >= 1");
        }
        if !pos(s.extent) {
            return bad("schedule.extent", s.extent, "must be finite and > 0 (metres)");
        }
        if s.max_stages == 0 || s.max_blocks_per_stage == 0 || s.shape_iterations == 0 {
            return bad("schedule", 0.0, "max_stages, max_blocks_per_stage and shape_iterations must be >= 1");
        }
        if !(s.rel_tol.is_finite() && s.rel_tol >= 0.0) {
            return bad("schedule.rel_tol", s.rel_tol, "must be finite and >= 0");
        }
        if !(s.reference_seconds.is_finite() && s.reference_seconds >= 0.0) {
            return bad(
                "schedule.reference_seconds",
                s.reference_seconds,
                "must be finite and >= 0 seconds (0: no budget)",
            );
        }
        if !(s.rebin_fraction.is_finite() && s.rebin_fraction >= 0.0) {
            return bad("schedule.rebin_fraction", s.rebin_fraction, "must be finite and >= 0 (0: no summed bins)");
        }
        for (name, x) in [
            ("lr_interior", self.lr_interior),
            ("lr_boundary", self.lr_boundary),
            ("lr_reflectance", self.lr_reflectance),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return bad(name, x, "learning rates must be finite and >= 0");
            }
        }
        if !self.shape_adam.valid() || !self.reflectance_adam.valid() {
            return bad("adam", self.shape_adam.beta1, "need 0 <= beta1, beta2 < 1 and eps > 0");
        }
        if !(self.boundary_smoothing.is_finite() && self.boundary_smoothing >= 0.0) {
            return bad("boundary_smoothing", self.boundary_smoothing, "must be finite and >= 0");
        }
        if !(self.regulariser_ratio.is_finite() && self.regulariser_ratio >= 0.0) {
            return bad("regulariser_ratio", self.regulariser_ratio, "must be finite and >= 0");
        }
        if let Some(w) = self.regulariser_weight
            && !(w.is_finite() && w >= 0.0)
        {
            return bad("regulariser_weight", w, "must be finite and >= 0");
        }
        if let SamplingSchedule::Stratified { initial_samples, growth } = self.sampling
            && (initial_samples == 0 || !(growth.is_finite() && growth >= 1.0))
        {
            return bad("sampling.growth", growth, "need initial_samples >= 1 and a finite growth >= 1");
        }
        if self.sensor.is_some() && self.data.weights.is_some() {
            return bad("data.weights", 0.0, "per-bin weights are not supported with the sensor fit");
        }
        Ok(())
    }
}
