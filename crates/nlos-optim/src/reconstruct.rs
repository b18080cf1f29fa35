//! The analysis-by-synthesis loop (Tsai et al. 2019, Sec. 4.2 and 5), its checkpoints and its run log.
//!
//! Per block (see [`crate::Schedule`]):
//! 1. **Topology.** Boundary faces no measurement can see are deleted (optional), the mesh is remeshed
//!    isotropically at the stage's target length (`nlos_mesh::remeshing::uniform_remeshing`), the Adam
//!    moments are carried to the new vertices (barycentric interpolation on the closest old face) and a new
//!    [`Renderer`] is built. (This is "remesh after every shape block", plus once on the initial mesh.)
//! 2. **Shape block.** Each step: forward render, data term with the closed-form scale ([`crate::loss`]),
//!    adjoint (Proposition 1, `nlos_render`), plus `λ ·` the normal-smoothing regulariser
//!    ([`crate::regularizer`]; λ set automatically at the first step of the block, against the data term
//!    above its noise floor for photon counts, [`crate::sensor`]), per-vertex isotropic
//!    Adam step ([`crate::adam`]), and the displacement goes through the [`Evolve`] hook.
//! 3. **Reflectance block.** Adam steps on θ with the shape fixed (and on the albedo map's log-albedo,
//!    [`crate::albedo`], when there is one).
//! 4. **Pruning** (optional, [`crate::ReconstructParams::prune`]): boundary faces whose deletion lowers the
//!    data term are deleted ([`crate::prune`]). At the end of the first stages
//!    ([`crate::ReconstructParams::residual`]), patches from the LCT of the fit's residual join the mesh
//!    where they lower it ([`crate::residual`]); the stage's saved mesh is the one before they join.
//! 5. **Bookkeeping.** Relative-decrease test, stage advance, checkpoint and run log (atomic writes), the
//!    progress callback.
//!
//! **Collision-aware evolution** (El Topo, issue 7; Tsai et al. 2019, Sec. 5): within a shape block every
//! Adam displacement goes through the [`Evolve`] hook (default [`DirectEvolve`]: applied as is). At the end
//! of the block, the displacement accumulated over it is replayed from the block's starting positions by
//! `nlos_mesh::evolve::evolve` (continuous collision detection, impulses, impact zones, fail-safe), so the
//! surface that is remeshed next has no self-intersection the block would have introduced
//! ([`crate::ReconstructParams::collision`]; [`Outcome::evolve`] records its cost per block).
//!
//! **Robustness.** A non-finite loss, gradient, θ or position restores the state before the last step,
//! halves every learning rate for the rest of the run, and retries ([`crate::ReconstructParams::max_rollbacks`]).
//!
//! **Determinism.** Given the same inputs, parameters and seed, a run is a deterministic function of them
//! *when rayon's reductions are*: the renderer's adjoint sums per-thread partial gradients in f64 in an
//! order rayon may vary between runs with several threads (differences near 1e-16 relative, rarely
//! visible after rounding to f32). Run inside a one-thread pool for bit-exact reproducibility. A resumed
//! run continues from the exact state of the checkpoint (f32/f64 values are stored exactly).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use nlos_mesh::evolve::{EvolveParams, evolve};
use nlos_mesh::intersect::triangle_self_intersections;
use nlos_mesh::{MeshError, SurfaceMesh, TriangleBvh, remeshing::uniform_remeshing};
use nlos_render::{RenderParams, Renderer, Sampling};
use nlos_transient::{Scan, TimeAxis, Transient};
use serde::{Deserialize, Serialize};

use crate::adam::{VectorAdam, VertexAdam};
use crate::albedo::AlbedoMap;
use crate::boundary_smoothing::BoundarySmoothing;
use crate::error::{OptimError, Result};
use crate::params::{ReconstructParams, SamplingSchedule};
use crate::prune::{PruneRecord, prune_boundary};
use crate::reflectance::Reflectance;
use crate::regularizer::{NormalSmoothing, auto_weight};
use crate::residual::{ResidualRecord, residual_patches};

/// File name of the checkpoint inside the output directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";
/// File name of the run log inside the output directory.
pub const RUN_LOG_FILE: &str = "run_log.json";
const CHECKPOINT_VERSION: u32 = 2;

/// The collision-handling hook: turns the current positions and an Adam displacement into new positions.
/// The default [`DirectEvolve`] adds the displacement; El Topo (issue 7) will implement this trait.
pub trait Evolve {
    /// New positions (same length as `positions`).
    ///
    /// # Errors
    /// Any failure: the hook's own error boxed in [`OptimError::Evolve`], or another variant.
    fn evolve(&mut self, positions: &[Vec3], triangles: &[[u32; 3]], displacement: &[Vec3]) -> Result<Vec<Vec3>>;
}

/// Applies displacements directly, without collision handling (the default [`Evolve`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct DirectEvolve;

impl Evolve for DirectEvolve {
    fn evolve(&mut self, positions: &[Vec3], _triangles: &[[u32; 3]], displacement: &[Vec3]) -> Result<Vec<Vec3>> {
        if displacement.len() != positions.len() {
            return Err(OptimError::LengthMismatch {
                what: "displacement",
                expected: positions.len(),
                got: displacement.len(),
            });
        }
        Ok(positions.iter().zip(displacement).map(|(p, d)| *p + *d).collect())
    }
}

/// What a progress callback is told about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ProgressEvent {
    /// An iteration (shape or reflectance step) was evaluated.
    Iteration,
    /// A block ended and its checkpoint was written. Returning `Break` here stops the run.
    BlockEnd,
}

/// The state reported to the progress callback.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// What happened.
    pub event: ProgressEvent,
    /// Current stage (0-based) and the number of stages planned.
    pub stage: u32,
    /// Stages planned at most.
    pub max_stages: u32,
    /// Blocks finished in the whole run.
    pub blocks_done: u64,
    /// Global iteration count.
    pub iteration: u64,
    /// An upper bound of the total iterations (for an ETA).
    pub iterations_planned: u64,
    /// Latest total loss (normalised data term + λ R).
    pub loss: f64,
    /// Faces of the current mesh.
    pub faces: usize,
    /// Target edge length of the stage (m).
    pub target_edge_length: f64,
    /// Wall-clock seconds of the run (summed over resumes).
    pub elapsed_s: f64,
}

/// The progress callback: called after every iteration and block; `ControlFlow::Break` is honoured at
/// [`ProgressEvent::BlockEnd`] (the run stops after that block's checkpoint, [`StopReason::Interrupted`]).
pub type ProgressFn<'a> = dyn FnMut(&Progress) -> ControlFlow<()> + 'a;

/// Optional hooks of a run.
#[derive(Default)]
pub struct Hooks<'a> {
    /// Progress callback.
    pub progress: Option<&'a mut ProgressFn<'a>>,
    /// Evolution hook (default [`DirectEvolve`]).
    pub evolve: Option<&'a mut dyn Evolve>,
}

impl std::fmt::Debug for Hooks<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Hooks")
            .field("progress", &self.progress.is_some())
            .field("evolve", &self.evolve.is_some())
            .finish()
    }
}

/// Which block an iteration belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StepKind {
    /// A vertex step.
    Shape,
    /// A reflectance (θ) step.
    Reflectance,
}

/// One line of the run log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// Global iteration number.
    pub iteration: u64,
    /// Stage.
    pub stage: u32,
    /// Block within the stage.
    pub block: u32,
    /// Shape or reflectance step.
    pub kind: StepKind,
    /// Total loss `E_data/E_0 + λ R` (E_0: [`crate::DataTerm::normaliser`]).
    pub loss: f64,
    /// Normalised data term `E_data/E_0`.
    pub data: f64,
    /// Regulariser `R + w R_∂` (normal plus boundary smoothing, [`ReconstructParams::boundary_smoothing`]), before λ.
    pub regulariser: f64,
    /// Regulariser weight λ.
    pub reg_weight: f64,
    /// Intensity scale s.
    pub scale: f64,
    /// Learning rate of the step (metres for shape steps, θ units for reflectance steps), rollbacks
    /// included.
    pub step_size: f64,
    /// Faces.
    pub faces: usize,
    /// Vertices.
    pub vertices: usize,
    /// Wall-clock seconds since the start of the run (summed over resumes; the only non-deterministic
    /// field).
    pub time_s: f64,
    /// Shape steps of a fit to photon counts (a sensor fit, or [`crate::DataTerm::counts`]): the normalised
    /// noise floor of the data term ([`crate::SensorFit::noise_floor`], [`crate::DataTerm::noise_floor`]),
    /// what `data` would be if the expected counts were exact. `data − noise_floor` is the misfit left; the
    /// regulariser weight is set against it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_floor: Option<f64>,
}

/// The JSON run log (`run_log.json`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RunLog {
    /// One record per iteration.
    pub iterations: Vec<IterationRecord>,
    /// Rollbacks performed.
    pub rollbacks: u32,
    /// Self-intersection checks: of the start, after every remeshing and at the end of every block.
    #[serde(default)]
    pub intersections: Vec<IntersectionRecord>,
}

/// When the surface is checked for self-intersections ([`IntersectionRecord`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntersectionCheck {
    /// The initial surface, before the loop.
    Start,
    /// After a block's remeshing (remeshing moves vertices without collision handling).
    Remeshed,
    /// At the end of a block: after the collision-aware evolution of its shape steps, pruning and residual
    /// patches (which are added where the data want them, whatever they cross).
    BlockEnd,
}

/// One self-intersection check of the surface. Faces found intersecting are deleted (the smaller face of
/// each pair, both where that leaves a non-manifold mesh), so that collision-aware evolution starts every
/// block from an intersection-free surface: `pairs_left` is 0 unless no deletion kept the mesh manifold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct IntersectionRecord {
    /// Stage.
    pub stage: u32,
    /// Block within the stage.
    pub block: u32,
    /// When.
    pub check: IntersectionCheck,
    /// Intersecting face pairs found.
    pub pairs: usize,
    /// Faces deleted.
    pub faces_removed: usize,
    /// Intersecting face pairs left.
    pub pairs_left: usize,
}

/// Why a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// All stages ran.
    MaxStages,
    /// The next stage would exceed the face limit.
    FaceLimit,
    /// The progress callback asked to stop (resume continues).
    Interrupted,
}

/// What the collision-aware evolution did at the end of one shape block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvolveRecord {
    /// Stage.
    pub stage: u32,
    /// Block within the stage.
    pub block: u32,
    /// Wall-clock seconds of the `evolve` call (the only non-deterministic field).
    pub seconds: f64,
    /// Vertices whose end position differs from `x₀ + d` (collisions resolved).
    pub vertices_adjusted: usize,
    /// Share of the requested motion applied (`nlos_mesh::evolve::EvolveReport::motion_fraction`).
    pub motion_fraction: f64,
    /// Whether the block's starting mesh already self-intersected (evolved with `check_input: false`).
    pub input_intersected: bool,
}

/// The result of [`reconstruct`] / [`resume`].
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The final mesh.
    pub mesh: SurfaceMesh,
    /// The final reflectance.
    pub reflectance: Reflectance,
    /// The final intensity scale s (measured ≈ s · rendered).
    pub scale: f64,
    /// The run log.
    pub log: RunLog,
    /// Why the run ended.
    pub stop: StopReason,
    /// Stage reached (0-based).
    pub stage: u32,
    /// Blocks run.
    pub blocks_done: u64,
    /// One record per collision-aware evolution (per shape block; empty when
    /// [`ReconstructParams::collision`] is `None`).
    pub evolve: Vec<EvolveRecord>,
    /// One record per boundary pruning (per block; empty when [`ReconstructParams::prune`] is `None`).
    pub prune: Vec<PruneRecord>,
    /// One record per residual back-projection (per stage that proposes, [`crate::ResidualParams::stages`];
    /// empty when [`ReconstructParams::residual`] is `None`).
    pub residual: Vec<ResidualRecord>,
    /// The fitted albedo map ([`ReconstructParams::albedo_map`]; None without one).
    pub albedo: Option<AlbedoMap>,
}

/// Everything needed to continue a run (written as the checkpoint).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct State {
    version: u32,
    fingerprint: u64,
    /// The settings the run was started with ([`SettingsRecord`]).
    settings: SettingsRecord,
    #[serde(with = "exact_vec3")]
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    reflectance: Reflectance,
    shape_adam: VertexAdam,
    reflectance_adam: VectorAdam,
    stage: u32,
    block_in_stage: u32,
    blocks_done: u64,
    iteration: u64,
    rng: u64,
    lr_scale: f64,
    scale: f64,
    reg_weight: f64,
    elapsed_s: f64,
    finished: Option<StopReason>,
    log: RunLog,
    /// Stages planned (for progress reports only).
    #[serde(default)]
    max_stages_hint: u32,
    /// Collision-aware evolution per block.
    #[serde(default)]
    evolve_log: Vec<EvolveRecord>,
    /// Boundary pruning per block.
    #[serde(default)]
    prune_log: Vec<PruneRecord>,
    /// Residual back-projection per stage.
    #[serde(default)]
    residual_log: Vec<ResidualRecord>,
    /// The albedo map ([`crate::albedo`]; None without one).
    #[serde(default)]
    albedo: Option<AlbedoMap>,
    /// Adam state of the albedo map's θ.
    #[serde(default)]
    albedo_adam: VectorAdam,
}

/// f32 vectors stored as f64 triples: an f32 widened to f64 prints and parses back exactly (serde_json's
/// `float_roundtrip`), whereas f32 parsing goes through f64 and could round twice.
mod exact_vec3 {
    use glam::Vec3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(super) fn serialize<S: Serializer>(v: &[Vec3], s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|p| p.as_dvec3().to_array()).collect::<Vec<[f64; 3]>>().serialize(s)
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec3>, D::Error> {
        Ok(Vec::<[f64; 3]>::deserialize(d)?
            .into_iter()
            .map(|a| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32))
            .collect())
    }
}

/// SplitMix64 (Steele, Lea & Flood 2014): the run's RNG, one u64 of state.
fn next_u64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// FNV-1a over the measurement's shape and bits: ties a checkpoint to its measurement.
fn fingerprint(measured: &Transient) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |x: u64| {
        for b in x.to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(measured.measurements() as u64);
    eat(measured.bins() as u64);
    for v in measured.data() {
        eat(u64::from(v.to_bits()));
    }
    h
}

/// The settings a run was started with, in its checkpoint: every field of [`ReconstructParams`] but
/// `out_dir`, as serde writes them. `resume` compares it field by field with the parameters it is given and
/// names the first that differs ([`OptimError::SettingsChanged`]). `version` changes when a field changes
/// meaning; a record of another version is refused rather than compared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct SettingsRecord {
    version: u32,
    params: serde_json::Value,
}

/// The version of [`SettingsRecord`] this build writes.
const SETTINGS_VERSION: u32 = 1;

impl SettingsRecord {
    fn of(params: &ReconstructParams) -> Result<Self> {
        // Serialising plain data into a `Value` fails only for maps with non-string keys, which the
        // parameters do not hold.
        let params = serde_json::to_value(params).map_err(|_| OptimError::InvalidParameter {
            name: "params",
            value: 0.0,
            reason: "the parameters cannot be recorded in the checkpoint",
        })?;
        Ok(Self { version: SETTINGS_VERSION, params })
    }
}

/// The first difference between two settings records' values, depth first in field order: its dotted path
/// and the two values (compact JSON).
fn first_difference(was: &serde_json::Value, now: &serde_json::Value, path: &str) -> Option<(String, String, String)> {
    use serde_json::Value;
    let join = |key: &str| if path.is_empty() { key.to_owned() } else { format!("{path}.{key}") };
    match (was, now) {
        (Value::Object(a), Value::Object(b)) => {
            for (key, va) in a {
                let vb = b.get(key).unwrap_or(&Value::Null);
                if let Some(d) = first_difference(va, vb, &join(key)) {
                    return Some(d);
                }
            }
            b.iter()
                .find(|(key, vb)| !a.contains_key(*key) && !vb.is_null())
                .map(|(key, vb)| (join(key), "(absent)".to_owned(), vb.to_string()))
        }
        (Value::Array(a), Value::Array(b)) if a.len() == b.len() => {
            a.iter().zip(b).enumerate().find_map(|(i, (va, vb))| first_difference(va, vb, &format!("{path}[{i}]")))
        }
        _ if was == now => None,
        _ => {
            // Long values (a sensor's response) are cut: the path names the setting.
            let short = |v: &Value| {
                let s = v.to_string();
                if s.chars().count() > 60 { format!("{}…", s.chars().take(57).collect::<String>()) } else { s }
            };
            Some((path.to_owned(), short(was), short(now)))
        }
    }
}

/// Writes `bytes` to `path` atomically (temporary file in the same directory + rename).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    let io = |source| OptimError::Io { path: path.to_owned(), source };
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
}

fn json_bytes<T: Serialize>(v: &T, path: &Path) -> Result<Vec<u8>> {
    serde_json::to_vec(v).map_err(|e| OptimError::Checkpoint { path: path.to_owned(), message: e.to_string() })
}

/// Reconstructs a surface from `measured`, starting from `init` (faces must face the wall, see
/// `nlos_render`'s one-sided convention), with default hooks.
///
/// # Errors
/// Invalid parameters or measurement, renderer/mesh failures, divergence, I/O in the output directory.
pub fn reconstruct(measured: &Transient, init: &SurfaceMesh, params: &ReconstructParams) -> Result<Outcome> {
    reconstruct_with(measured, init, params, Hooks::default())
}

/// [`reconstruct`] with a progress callback and/or an evolution hook.
///
/// # Errors
/// As [`reconstruct`].
pub fn reconstruct_with(
    measured: &Transient,
    init: &SurfaceMesh,
    params: &ReconstructParams,
    hooks: Hooks<'_>,
) -> Result<Outcome> {
    params.validate()?;
    let (positions, triangles) = init.to_triangles();
    if triangles.is_empty() {
        return Err(OptimError::EmptyMesh { context: "initial mesh" });
    }
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(OptimError::InvalidParameter {
            name: "init",
            value: i as f64,
            reason: "the initial mesh has a non-finite vertex (value = its index)",
        });
    }
    let n = positions.len();
    // The map covers the initial surface with two cells to spare; points beyond take the edge's value.
    let albedo = match &params.albedo_map {
        Some(a) => Some(AlbedoMap::covering(&positions, a.cell, 2.0 * a.cell)?),
        None => None,
    };
    let albedo_adam = VectorAdam::new(albedo.as_ref().map_or(0, |m| m.log_albedo.len()));
    let mut state = State {
        version: CHECKPOINT_VERSION,
        fingerprint: fingerprint(measured),
        settings: SettingsRecord::of(params)?,
        positions,
        triangles,
        reflectance: params.reflectance.clone(),
        shape_adam: VertexAdam::new(n),
        reflectance_adam: VectorAdam::new(params.reflectance.theta().len()),
        stage: 0,
        block_in_stage: 0,
        blocks_done: 0,
        iteration: 0,
        rng: params.seed,
        lr_scale: 1.0,
        scale: 1.0,
        reg_weight: 0.0,
        elapsed_s: 0.0,
        finished: None,
        log: RunLog::default(),
        max_stages_hint: params.schedule.max_stages,
        evolve_log: Vec::new(),
        prune_log: Vec::new(),
        residual_log: Vec::new(),
        albedo,
        albedo_adam,
    };
    // A start that intersects itself would leave collision-aware evolution nothing to guarantee.
    untangle(&mut state, IntersectionCheck::Start)?;
    if let Some(dir) = &params.out_dir {
        std::fs::create_dir_all(dir).map_err(|source| OptimError::Io { path: dir.clone(), source })?;
    }
    run(measured, state, params, hooks)
}

/// Continues the run whose checkpoint is in `params.out_dir` (same measurement and parameters as the
/// interrupted run). A finished run returns its outcome at once.
///
/// # Errors
/// [`OptimError::Checkpoint`] for a missing, malformed or foreign checkpoint, plus those of [`reconstruct`].
pub fn resume(measured: &Transient, params: &ReconstructParams, hooks: Hooks<'_>) -> Result<Outcome> {
    params.validate()?;
    let Some(dir) = &params.out_dir else {
        return Err(OptimError::InvalidParameter {
            name: "out_dir",
            value: 0.0,
            reason: "resume needs the output directory that holds checkpoint.json",
        });
    };
    let path = dir.join(CHECKPOINT_FILE);
    let bytes = std::fs::read(&path).map_err(|source| OptimError::Io { path: path.clone(), source })?;
    let ck = |message: String| OptimError::Checkpoint { path: path.clone(), message };
    let state: State = serde_json::from_slice(&bytes).map_err(|e| ck(e.to_string()))?;
    if state.version != CHECKPOINT_VERSION {
        return Err(ck(format!(
            "written by another version of nlos (checkpoint version {}, this build reads {CHECKPOINT_VERSION}); \
             start the run afresh",
            state.version
        )));
    }
    if state.fingerprint != fingerprint(measured) {
        return Err(ck("it was written for a different measurement".into()));
    }
    if state.settings.version != SETTINGS_VERSION {
        return Err(ck(format!(
            "settings record version {} (this build writes {SETTINGS_VERSION}); start the run afresh",
            state.settings.version
        )));
    }
    let now = SettingsRecord::of(params)?;
    if let Some((field, was, now)) = first_difference(&state.settings.params, &now.params, "") {
        return Err(OptimError::SettingsChanged { path: path.clone(), field, was, now });
    }
    if state.shape_adam.len() != state.positions.len()
        || state.triangles.is_empty()
        || state.albedo.is_some() != params.albedo_map.is_some()
        || state.albedo.as_ref().is_some_and(|m| {
            m.validate().is_err()
                || state.albedo_adam.m.len() != m.log_albedo.len()
                || state.albedo_adam.v.len() != m.log_albedo.len()
        })
    {
        return Err(ck("inconsistent mesh and optimiser state".into()));
    }
    run(measured, state, params, hooks)
}

/// Render parameters of a block.
fn render_params(params: &ReconstructParams, stage: u32, rng: &mut u64) -> RenderParams {
    let sampling = match params.sampling {
        SamplingSchedule::Splat(rule) => Sampling::Splat(rule),
        SamplingSchedule::Deterministic(rule) => Sampling::Deterministic(rule),
        SamplingSchedule::Stratified { initial_samples, growth } => {
            let n = (f64::from(initial_samples) * growth.powi(stage as i32)).min(f64::from(u32::MAX / 2));
            Sampling::Stratified { samples_per_measurement: n as u32, seed: next_u64(rng) }
        }
    };
    RenderParams { sampling, ..params.render }
}

/// Whether a face with corners `p` can receive light in some measurement (one-sided faces, positive wall
/// cosines, path length inside the time window) — tested at the centroid.
fn face_lit(p: [Vec3; 3], scan: &Scan, time: &TimeAxis, two_sided: bool) -> bool {
    let c = (p[0] + p[1] + p[2]) / 3.0;
    let n = (p[1] - p[0]).cross(p[2] - p[0]);
    let (t0, t1) = (time.t0 as f32, time.end() as f32);
    (0..scan.measurements()).any(|m| {
        let g = scan.measurement(m);
        let (a, b) = (g.laser - c, g.sensor - c);
        let (dl, ds) = (n.dot(a), n.dot(b));
        let facing = (dl > 0.0 && ds > 0.0) || (two_sided && dl < 0.0 && ds < 0.0);
        let tau = a.length() + b.length();
        facing && -g.laser_normal.dot(a) > 0.0 && -g.sensor_normal.dot(b) > 0.0 && tau >= t0 && tau <= t1
    })
}

/// Step 1 of a block: unlit boundary faces, remeshing, Adam transfer. Returns the boundary flags.
fn prepare_topology(
    st: &mut State,
    target: f32,
    params: &ReconstructParams,
    measured: &Transient,
) -> Result<Vec<bool>> {
    let (old_pos, old_tris) = (st.positions.clone(), st.triangles.clone());
    let mut mesh = SurfaceMesh::from_triangles(&st.positions, &st.triangles)?;
    // Boundary faces no measurement can see carry no signal and no gradient: they go before remeshing.
    let dark: Vec<_> = mesh
        .faces()
        .filter(|&f| {
            mesh.is_boundary_face(f)
                && !face_lit(mesh.face_points(f), measured.scan(), measured.time(), params.render.two_sided)
        })
        .collect();
    // Guard: never delete everything (a mesh entirely out of view keeps its faces and its zero signal).
    if !dark.is_empty() && dark.len() < mesh.n_faces() {
        let mut pruned = mesh.clone();
        for f in dark {
            pruned.delete_face(f);
        }
        pruned.garbage_collect();
        // Deleting faces can pinch a vertex between two boundary loops (a non-manifold "bow tie" that
        // the half-edge builder rejects): keep the faces for this block rather than fail the run.
        if is_manifold(&pruned) {
            mesh = pruned;
        }
    }
    if mesh.n_faces() == 0 {
        return Err(OptimError::EmptyMesh { context: "after removing unlit faces" });
    }
    let mut remeshed = mesh.clone();
    uniform_remeshing(&mut remeshed, target, &params.remesh)?;
    // Guard against a remeshing result that is not a valid manifold mesh: keep the unremeshed mesh.
    if is_manifold(&remeshed) {
        mesh = remeshed;
    }
    let (pos, tris) = mesh.to_triangles();
    if tris.is_empty() {
        return Err(OptimError::EmptyMesh { context: "after remeshing" });
    }
    let boundary: Vec<bool> = mesh.vertices().map(|v| mesh.is_boundary_vertex(v)).collect();
    let bvh = TriangleBvh::from_triangles(&old_pos, &old_tris)?;
    let weights: Vec<[(u32, f32); 3]> = pos
        .iter()
        .map(|p| {
            let cp = bvh.closest_point(*p);
            let t = old_tris[cp.triangle as usize];
            let b = cp.barycentric;
            [(t[0], b.x.max(0.0)), (t[1], b.y.max(0.0)), (t[2], b.z.max(0.0))]
        })
        .collect();
    st.shape_adam = st.shape_adam.transfer(&weights);
    st.positions = pos;
    st.triangles = tris;
    let faces = st.triangles.len();
    untangle(st, IntersectionCheck::Remeshed)?;
    if st.triangles.len() == faces {
        return Ok(boundary);
    }
    // Faces went: the boundary flags of the mesh as it now is.
    let mesh = mesh_of(st)?;
    Ok(mesh.vertices().map(|v| mesh.is_boundary_vertex(v)).collect())
}

/// Keeps the triangles flagged in `keep` and the vertices they use (renumbered in order), with their Adam
/// moments.
fn drop_faces(st: &mut State, keep: &[bool]) {
    let mut new_index = vec![u32::MAX; st.positions.len()];
    let mut old_of_new: Vec<u32> = Vec::new();
    let mut triangles = Vec::with_capacity(st.triangles.len());
    for (t, _) in st.triangles.iter().zip(keep).filter(|(_, k)| **k) {
        let mut out = [0u32; 3];
        for (o, &v) in out.iter_mut().zip(t) {
            if new_index[v as usize] == u32::MAX {
                new_index[v as usize] = old_of_new.len() as u32;
                old_of_new.push(v);
            }
            *o = new_index[v as usize];
        }
        triangles.push(out);
    }
    let source: Vec<Option<u32>> = old_of_new.iter().map(|&v| Some(v)).collect();
    st.shape_adam = st.shape_adam.select(&source);
    st.positions = old_of_new.iter().map(|&v| st.positions[v as usize]).collect();
    st.triangles = triangles;
}

/// Checks the surface for self-intersections and deletes the faces that cause them ([`IntersectionRecord`]),
/// with their vertices' Adam state; the check is logged.
fn untangle(st: &mut State, check: IntersectionCheck) -> Result<()> {
    let pairs = triangle_self_intersections(&st.positions, &st.triangles)?;
    let mut record = IntersectionRecord {
        stage: st.stage,
        block: st.block_in_stage,
        check,
        pairs: pairs.len(),
        faces_removed: 0,
        pairs_left: pairs.len(),
    };
    if !pairs.is_empty() {
        let area = |f: u32| {
            let t = st.triangles[f as usize].map(|v| st.positions[v as usize]);
            (t[1] - t[0]).cross(t[2] - t[0]).length()
        };
        let smaller: Vec<u32> = pairs.iter().map(|&(f, g)| if area(f) <= area(g) { f } else { g }).collect();
        let both: Vec<u32> = pairs.iter().flat_map(|&(f, g)| [f, g]).collect();
        for doomed in [smaller, both] {
            let mut keep = vec![true; st.triangles.len()];
            for f in doomed {
                keep[f as usize] = false;
            }
            let kept: Vec<[u32; 3]> = st.triangles.iter().zip(&keep).filter(|(_, k)| **k).map(|(t, _)| *t).collect();
            // Guard: deleting faces can pinch a vertex into a bow tie, or delete everything.
            if kept.is_empty() || SurfaceMesh::from_triangles(&st.positions, &kept).is_err() {
                continue;
            }
            record.faces_removed = st.triangles.len() - kept.len();
            drop_faces(st, &keep);
            record.pairs_left = triangle_self_intersections(&st.positions, &st.triangles)?.len();
            break;
        }
    }
    st.log.intersections.push(record);
    Ok(())
}

/// Whether the mesh's triangles rebuild into a valid half-edge mesh (no non-manifold vertex or edge).
fn is_manifold(mesh: &SurfaceMesh) -> bool {
    let (p, t) = mesh.to_triangles();
    !t.is_empty() && SurfaceMesh::from_triangles(&p, &t).is_ok()
}

fn surface_area(p: &[Vec3], t: &[[u32; 3]]) -> f64 {
    t.iter()
        .map(|f| {
            let (a, b, c) = (p[f[0] as usize], p[f[1] as usize], p[f[2] as usize]);
            0.5 * f64::from((b - a).cross(c - a).length())
        })
        .sum()
}

/// Loss pieces at the current state.
struct Eval {
    data: f64,
    /// The normalised noise floor of the data term ([`crate::SensorFit::noise_floor`],
    /// [`crate::DataTerm::noise_floor`]) when asked for and the data are counts; 0 otherwise.
    floor: f64,
    scale: f64,
    grad_vertices: Vec<Vec3>,
    grad_theta: Vec<f64>,
    /// dE/dw_t per triangle (`nlos_render::Gradient::faces`), for the albedo map.
    grad_faces: Vec<f32>,
}

/// The data term of a run: the plain [`crate::DataTerm`], or the sensor fit with its resolved background.
struct Fit<'a> {
    params: &'a ReconstructParams,
    measured: &'a [f32],
    bins: usize,
    /// Background per bin of the sensor fit (unused without one).
    background: f64,
    /// Normaliser of the data term.
    norm: f64,
}

/// The data term, its scale and gradients at the current state; with `want_floor`, also the data term's
/// noise floor (for the automatic regulariser weight).
fn evaluate(st: &State, r: &Renderer, fit: &Fit<'_>, want_floor: bool) -> Result<Eval> {
    let (params, measured, norm) = (fit.params, fit.measured, fit.norm);
    let brdf = st.reflectance.brdf()?;
    let rendered = brdf.forward(r);
    let mut floor = 0.0;
    let ev = match &params.sensor {
        Some(sensor) => {
            let ev =
                sensor.evaluate(&rendered, measured, fit.bins, fit.background, params.data.solve_scale, st.scale)?;
            if want_floor {
                floor = sensor.noise_floor(&rendered, fit.bins, fit.background, ev.scale)? / norm;
            }
            ev
        }
        None => {
            let ev = params.data.evaluate(&rendered, measured, st.scale)?;
            if want_floor && params.data.counts {
                floor = params.data.noise_floor(&rendered, measured, ev.scale)? / norm;
            }
            ev
        }
    };
    let inv = (1.0 / norm) as f32;
    let d: Vec<f32> = ev.d_rendered.iter().map(|x| x * inv).collect();
    let g = brdf.adjoint(r, &d)?;
    Ok(Eval {
        data: ev.value / norm,
        floor,
        scale: ev.scale,
        grad_theta: st.reflectance.chain(&g.brdf),
        grad_vertices: g.vertices,
        grad_faces: g.faces,
    })
}

fn write_outputs(dir: &Path, st: &State) -> Result<()> {
    let ck = dir.join(CHECKPOINT_FILE);
    write_atomic(&ck, &json_bytes(st, &ck)?)?;
    let lg = dir.join(RUN_LOG_FILE);
    write_atomic(&lg, &json_bytes(&st.log, &lg)?)
}

/// Appends new vertices (numbered from the current count on) and faces; old vertices keep their Adam
/// moments, the new ones start at zero.
fn append(st: &mut State, positions: &[Vec3], triangles: &[[u32; 3]]) {
    let source: Vec<Option<u32>> =
        (0..st.positions.len() as u32).map(Some).chain(positions.iter().map(|_| None)).collect();
    st.shape_adam = st.shape_adam.select(&source);
    st.positions.extend(positions);
    st.triangles.extend(triangles);
}

fn mesh_of(st: &State) -> Result<SurfaceMesh> {
    Ok(SurfaceMesh::from_triangles(&st.positions, &st.triangles)?)
}

/// A shape step's evaluation: data term and gradient, the regulariser (normal + boundary smoothing), the
/// normal-smoothing part alone (what λ is set against), the regulariser's gradient.
type Attempt = (Eval, f64, f64, Vec<Vec3>);

#[allow(clippy::too_many_lines)]
fn run(measured: &Transient, mut st: State, params: &ReconstructParams, mut hooks: Hooks<'_>) -> Result<Outcome> {
    let data = measured.data();
    if let Some(i) = data.iter().position(|x| !x.is_finite()) {
        return Err(OptimError::NonFiniteMeasurement { index: i, value: data[i] });
    }
    params.data.validate(data.len())?;
    let background = match &params.sensor {
        Some(sensor) => sensor.resolve_background(measured)?,
        None => 0.0,
    };
    let norm = match &params.sensor {
        Some(_) => crate::sensor::SensorFit::normaliser(data),
        None => params.data.normaliser(data),
    };
    let norm = norm.ok_or(OptimError::InvalidParameter {
        name: "measured",
        value: 0.0,
        reason: "the (weighted) measurement is zero everywhere: there is nothing to fit",
    })?;
    // Photon counts (a sensor fit, or a data term told so): the regulariser weight discounts the noise floor.
    let counts = params.sensor.is_some() || params.data.counts;
    let sch = params.schedule;
    st.max_stages_hint = sch.max_stages;
    let mut direct = DirectEvolve;
    let evolve: &mut dyn Evolve = match hooks.evolve.take() {
        Some(e) => e,
        None => &mut direct,
    };
    let start = Instant::now();
    let t_base = st.elapsed_s;
    let elapsed = || t_base + start.elapsed().as_secs_f64();
    // A Lambertian albedo is a pure scale factor: with the scale solved in closed form its gradient is zero,
    // and a reflectance block would spend full forward/adjoint renders to leave θ where it is.
    let scale_only = matches!(st.reflectance, Reflectance::Lambertian { .. }) && params.data.solve_scale;
    let fit_brdf = params.optimise_reflectance && !scale_only && !st.reflectance.theta().is_empty();
    // The albedo map (crate::albedo) is fitted in the reflectance blocks too, whatever the BRDF.
    let fit_albedo = params.optimise_reflectance && st.albedo.is_some();
    let refl_iters = if fit_brdf || fit_albedo { sch.reflectance_iterations } else { 0 };
    let planned =
        u64::from(sch.max_stages) * u64::from(sch.max_blocks_per_stage) * u64::from(sch.shape_iterations + refl_iters);
    let out_dir: Option<PathBuf> = params.out_dir.clone();

    while st.finished.is_none() {
        let target = sch.target_edge_length(st.stage);
        let boundary = prepare_topology(&mut st, target as f32, params, measured)?;
        let fit = Fit { params, measured: data, bins: measured.bins(), background, norm };
        let mut renderer = Renderer::new(
            &st.positions,
            &st.triangles,
            measured.scan(),
            measured.time(),
            render_params(params, st.stage, &mut st.rng),
        )?;
        // The albedo map's factors, held fixed through the shape block (crate::albedo, "Gradient").
        set_albedo_weights(&st, &mut renderer)?;
        let reg = NormalSmoothing::new(st.positions.len(), &st.triangles)?;
        let edge_reg = BoundarySmoothing::new(st.positions.len(), &st.triangles)?;
        let w_edge = params.boundary_smoothing;
        let (mut block_first, mut block_last) = (f64::NAN, f64::NAN);
        let block_start = st.positions.clone();

        // ---- shape block ----
        let mut good: Option<(Vec<Vec3>, VertexAdam)> = None;
        let mut it = 0;
        while it < sch.shape_iterations {
            let attempt = (|| -> Result<Option<Attempt>> {
                let ev = evaluate(&st, &renderer, &fit, counts)?;
                let (r_n, mut rg) = reg.evaluate(&st.positions, &st.triangles)?;
                let mut r = r_n;
                if w_edge > 0.0 {
                    let (r_e, eg) = edge_reg.evaluate(&st.positions)?;
                    r += w_edge * r_e;
                    for (g, e) in rg.iter_mut().zip(&eg) {
                        *g += w_edge as f32 * *e;
                    }
                }
                let ok = ev.data.is_finite() && r.is_finite() && ev.grad_vertices.iter().all(|g| g.is_finite());
                Ok(ok.then_some((ev, r, r_n, rg)))
            })()?;
            let Some((ev, r, r_n, rg)) = attempt else {
                rollback(&mut st, &mut good, &mut renderer, params, "loss or gradient")?;
                continue;
            };
            if it == 0 {
                let area = surface_area(&st.positions, &st.triangles);
                // With counts, the regulariser is weighed against the part of the data term above its noise
                // floor (crate::sensor, "Noise floor"; DataTerm::noise_floor); at least 1 % of the data term,
                // so a fit that has reached the floor keeps some smoothing.
                let excess = if counts { (ev.data - ev.floor).max(0.01 * ev.data) } else { ev.data };
                st.reg_weight = params
                    .regulariser_weight
                    .unwrap_or_else(|| auto_weight(params.regulariser_ratio, excess, r_n, area));
            }
            let lam = st.reg_weight;
            let loss = ev.data + lam * r;
            if it == 0 {
                block_first = loss;
            }
            block_last = loss;
            st.scale = ev.scale;
            let step = params.lr_interior * target * st.lr_scale;
            st.log.iterations.push(IterationRecord {
                iteration: st.iteration,
                stage: st.stage,
                block: st.block_in_stage,
                kind: StepKind::Shape,
                loss,
                data: ev.data,
                regulariser: r,
                reg_weight: lam,
                scale: ev.scale,
                step_size: step,
                faces: st.triangles.len(),
                vertices: st.positions.len(),
                time_s: elapsed(),
                noise_floor: counts.then_some(ev.floor),
            });
            let _ = report(&mut hooks, &st, ProgressEvent::Iteration, planned, loss, target, elapsed());
            let grad: Vec<Vec3> = ev.grad_vertices.iter().zip(&rg).map(|(g, q)| *g + lam as f32 * *q).collect();
            good = Some((st.positions.clone(), st.shape_adam.clone()));
            let (li, lb) = (params.lr_interior * target * st.lr_scale, params.lr_boundary * target * st.lr_scale);
            let disp = st.shape_adam.step(&params.shape_adam, &grad, |i| if boundary[i] { lb } else { li });
            let new = evolve.evolve(&st.positions, &st.triangles, &disp)?;
            if new.len() != st.positions.len() || new.iter().any(|p| !p.is_finite()) {
                rollback(&mut st, &mut good, &mut renderer, params, "positions")?;
                continue;
            }
            st.positions = new;
            renderer.set_positions(&st.positions)?;
            st.iteration += 1;
            it += 1;
        }

        // ---- collision-aware evolution of the block's accumulated displacement ----
        if let Some(ep) = params.collision {
            let rec = evolve_block(&mut st, &block_start, target as f32, ep)?;
            st.evolve_log.push(rec);
            renderer.set_positions(&st.positions)?;
        }

        // ---- reflectance block ----
        if refl_iters > 0 {
            // The map's factors at the faces' current centroids (the shape block moved them), so that the
            // renderer's dE/dw_t and the map's chain rule see the same w_t.
            set_albedo_weights(&st, &mut renderer)?;
            let (mut r, _) = reg.evaluate(&st.positions, &st.triangles)?;
            if w_edge > 0.0 {
                r += w_edge * edge_reg.evaluate(&st.positions)?.0;
            }
            let mut good_refl: Option<GoodReflectance> = None;
            let mut it = 0;
            while it < refl_iters {
                let ev = evaluate(&st, &renderer, &fit, false);
                let ev = match ev {
                    Ok(ev)
                        if ev.data.is_finite()
                            && ev.grad_theta.iter().all(|g| g.is_finite())
                            && ev.grad_faces.iter().all(|g| g.is_finite()) =>
                    {
                        ev
                    }
                    Ok(_) | Err(OptimError::Brdf(_)) => {
                        rollback_refl(&mut st, &mut good_refl, &mut renderer, params, "reflectance loss or gradient")?;
                        continue;
                    }
                    Err(e) => return Err(e),
                };
                let loss = ev.data + st.reg_weight * r;
                block_last = loss;
                st.scale = ev.scale;
                let lr = params.lr_reflectance * st.lr_scale;
                st.log.iterations.push(IterationRecord {
                    iteration: st.iteration,
                    stage: st.stage,
                    block: st.block_in_stage,
                    kind: StepKind::Reflectance,
                    loss,
                    data: ev.data,
                    regulariser: r,
                    reg_weight: st.reg_weight,
                    scale: ev.scale,
                    step_size: lr,
                    faces: st.triangles.len(),
                    vertices: st.positions.len(),
                    time_s: elapsed(),
                    noise_floor: None,
                });
                let _ = report(&mut hooks, &st, ProgressEvent::Iteration, planned, loss, target, elapsed());
                good_refl = Some((
                    st.reflectance.clone(),
                    st.reflectance_adam.clone(),
                    st.albedo.clone(),
                    st.albedo_adam.clone(),
                ));
                if fit_brdf {
                    let delta = st.reflectance_adam.step(&params.reflectance_adam, &ev.grad_theta, lr);
                    st.reflectance.add_theta(&delta);
                }
                if let (Some(map), Some(ap)) = (st.albedo.as_mut(), params.albedo_map.as_ref()) {
                    let g = map.chain(&st.positions, &st.triangles, &ev.grad_faces);
                    let delta = st.albedo_adam.step(&params.reflectance_adam, &g, ap.lr * st.lr_scale);
                    map.add(&delta, ap.max_log);
                    map.recentre(&st.positions, &st.triangles);
                    set_albedo_weights(&st, &mut renderer)?;
                }
                st.iteration += 1;
                it += 1;
            }
        }

        let rel = (block_first - block_last) / block_first.abs().max(f64::MIN_POSITIVE);
        // NaN-safe: a NaN `rel` counts as converged (the rollback logic has already run out otherwise).
        let converged = !(rel >= sch.rel_tol);
        let stage_ends = converged || st.block_in_stage + 1 >= sch.max_blocks_per_stage;
        let last_block = stage_ends && st.stage + 1 >= sch.max_stages;

        // ---- boundary pruning,
        // residual back-projection at the end of a stage but the last ----
        let residual =
            params.residual.as_ref().filter(|r| stage_ends && !last_block && r.stages.is_none_or(|n| st.stage < n));
        // The stage's mesh as fitted (before residual patches join it).
        let mut stage_mesh: Option<(Vec<Vec3>, Vec<[u32; 3]>)> = None;
        if params.prune.is_some() || residual.is_some() {
            let brdf = st.reflectance.brdf()?;
            let mut rendered = brdf.forward(&renderer);
            let (bins, scale) = (measured.bins(), st.scale);
            let row_loss = |m: usize, row: &[f32], window: std::ops::Range<usize>| -> Result<f64> {
                let measured_row = &data[m * bins..(m + 1) * bins];
                match &params.sensor {
                    Some(sensor) => sensor.row_value_in(row, measured_row, background, scale, window),
                    None => params.data.row_value_in(row, measured_row, m * bins, scale, window),
                }
            };
            if let Some(pp) = &params.prune {
                let p = prune_boundary(&st.triangles, &renderer, &brdf, &mut rendered, bins, &row_loss, pp)?;
                if p.removed > 0 {
                    drop_faces(&mut st, &p.keep);
                }
                st.prune_log.push(PruneRecord {
                    stage: st.stage,
                    block: st.block_in_stage,
                    tested: p.tested,
                    removed: p.removed,
                    data_change: p.data_change / norm,
                });
            }
            if let Some(rp) = residual {
                let model: Vec<f64> = match &params.sensor {
                    Some(sensor) => sensor.expected(&rendered, bins, background, scale)?,
                    None => rendered.iter().map(|&r| scale * f64::from(r)).collect(),
                };
                let res: Vec<f32> = data.iter().zip(&model).map(|(&m, &e)| (f64::from(m) - e) as f32).collect();
                let p = residual_patches(
                    &st.positions,
                    &st.triangles,
                    measured,
                    res,
                    *renderer.params(),
                    &brdf,
                    &mut rendered,
                    &row_loss,
                    rp,
                )?;
                if !p.triangles.is_empty() {
                    stage_mesh = Some((st.positions.clone(), st.triangles.clone()));
                }
                append(&mut st, &p.positions, &p.triangles);
                st.residual_log.push(ResidualRecord {
                    stage: st.stage,
                    columns: p.columns,
                    regions: p.regions,
                    accepted: p.accepted,
                    faces: p.triangles.len(),
                    data_change: p.data_change / norm,
                });
            }
        }

        // ---- bookkeeping: self-intersections, relative decrease, stage advance, checkpoint ----
        untangle(&mut st, IntersectionCheck::BlockEnd)?;
        st.blocks_done += 1;
        if stage_ends {
            if let Some(dir) = &out_dir {
                let m = match &stage_mesh {
                    Some((p, t)) => SurfaceMesh::from_triangles(p, t)?,
                    None => mesh_of(&st)?,
                };
                nlos_mesh::io::save(&m, dir.join(format!("stage_{:02}.obj", st.stage)))?;
            }
            st.stage += 1;
            st.block_in_stage = 0;
            if st.stage >= sch.max_stages {
                st.finished = Some(StopReason::MaxStages);
            } else {
                let l = sch.target_edge_length(st.stage);
                let est = surface_area(&st.positions, &st.triangles) / (3f64.sqrt() / 4.0 * l * l);
                if est > sch.max_faces as f64 {
                    st.finished = Some(StopReason::FaceLimit);
                }
            }
        } else {
            st.block_in_stage += 1;
        }
        st.elapsed_s = elapsed();
        if let Some(dir) = &out_dir {
            write_outputs(dir, &st)?;
        }
        let flow = report(&mut hooks, &st, ProgressEvent::BlockEnd, planned, block_last, target, st.elapsed_s);
        if flow.is_break() && st.finished.is_none() {
            return Ok(Outcome {
                mesh: mesh_of(&st)?,
                reflectance: st.reflectance.clone(),
                scale: st.scale,
                log: st.log.clone(),
                stop: StopReason::Interrupted,
                stage: st.stage,
                blocks_done: st.blocks_done,
                evolve: st.evolve_log.clone(),
                prune: st.prune_log.clone(),
                residual: st.residual_log.clone(),
                albedo: st.albedo.clone(),
            });
        }
    }
    let mesh = mesh_of(&st)?;
    if let Some(dir) = &out_dir {
        nlos_mesh::io::save(&mesh, dir.join("mesh.obj"))?;
        nlos_mesh::io::save(&mesh, dir.join("mesh.ply"))?;
    }
    Ok(Outcome {
        mesh,
        reflectance: st.reflectance.clone(),
        scale: st.scale,
        log: st.log.clone(),
        stop: st.finished.unwrap_or(StopReason::MaxStages),
        stage: st.stage,
        blocks_done: st.blocks_done,
        evolve: st.evolve_log.clone(),
        prune: st.prune_log.clone(),
        residual: st.residual_log.clone(),
        albedo: st.albedo.clone(),
    })
}

/// Moves the mesh from `start` by the displacement accumulated over the block (`st.positions − start`)
/// with collision-aware evolution (`nlos_mesh::evolve`), improvement off.
fn evolve_block(st: &mut State, start: &[Vec3], target: f32, ep: EvolveParams) -> Result<EvolveRecord> {
    let t0 = Instant::now();
    let disp: Vec<Vec3> = st.positions.iter().zip(start).map(|(p, q)| *p - *q).collect();
    let mut mesh = SurfaceMesh::from_triangles(start, &st.triangles)?;
    let ep = EvolveParams { improve: false, edge_length: ep.edge_length.or(Some(target)), ..ep };
    let (report, input_intersected) = match evolve(&mut mesh, &disp, &ep) {
        Ok(r) => (r, false),
        Err(MeshError::InputSelfIntersects { .. }) => {
            (evolve(&mut mesh, &disp, &EvolveParams { check_input: false, ..ep })?, true)
        }
        Err(e) => return Err(e.into()),
    };
    let pos = mesh.positions();
    if pos.len() != st.positions.len() || pos.iter().any(|p| !p.is_finite()) {
        return Err(OptimError::EvolveOutput { expected: st.positions.len(), got: pos.len() });
    }
    st.positions = pos.to_vec();
    Ok(EvolveRecord {
        stage: st.stage,
        block: st.block_in_stage,
        seconds: t0.elapsed().as_secs_f64(),
        vertices_adjusted: report.vertices_adjusted,
        motion_fraction: report.motion_fraction,
        input_intersected,
    })
}

fn report(
    hooks: &mut Hooks<'_>,
    st: &State,
    event: ProgressEvent,
    planned: u64,
    loss: f64,
    target: f64,
    elapsed_s: f64,
) -> ControlFlow<()> {
    let Some(cb) = hooks.progress.as_mut() else { return ControlFlow::Continue(()) };
    cb(&Progress {
        event,
        stage: st.stage,
        max_stages: st.max_stages_hint,
        blocks_done: st.blocks_done,
        iteration: st.iteration,
        iterations_planned: planned,
        loss,
        faces: st.triangles.len(),
        target_edge_length: target,
        elapsed_s,
    })
}

/// Counts a rollback (failing with [`OptimError::Diverged`] past `max_rollbacks`) and halves the learning
/// rates: the part shared by the shape and reflectance rollbacks.
fn count_rollback(st: &mut State, params: &ReconstructParams, what: &'static str) -> Result<()> {
    st.log.rollbacks += 1;
    if st.log.rollbacks > params.max_rollbacks {
        return Err(OptimError::Diverged { iteration: st.iteration, what, rollbacks: st.log.rollbacks - 1 });
    }
    st.lr_scale *= 0.5;
    Ok(())
}

/// Restores the vertex state before the last step and halves the learning rates.
fn rollback(
    st: &mut State,
    good: &mut Option<(Vec<Vec3>, VertexAdam)>,
    renderer: &mut Renderer,
    params: &ReconstructParams,
    what: &'static str,
) -> Result<()> {
    count_rollback(st, params, what)?;
    if let Some((p, a)) = good.take() {
        st.positions = p;
        st.shape_adam = a;
        renderer.set_positions(&st.positions)?;
    }
    Ok(())
}

/// Restores θ before the last reflectance step and halves the learning rates.
fn rollback_refl(
    st: &mut State,
    good: &mut Option<GoodReflectance>,
    renderer: &mut Renderer,
    params: &ReconstructParams,
    what: &'static str,
) -> Result<()> {
    count_rollback(st, params, what)?;
    if let Some((r, a, map, map_adam)) = good.take() {
        st.reflectance = r;
        st.reflectance_adam = a;
        st.albedo = map;
        st.albedo_adam = map_adam;
        set_albedo_weights(st, renderer)?;
    }
    Ok(())
}

/// The reflectance state a reflectance rollback restores: θ, its Adam state, the albedo map and its Adam
/// state.
type GoodReflectance = (Reflectance, VectorAdam, Option<AlbedoMap>, VectorAdam);

/// Gives the renderer the albedo map's per-triangle factors at the current positions (nothing without a
/// map).
fn set_albedo_weights(st: &State, renderer: &mut Renderer) -> Result<()> {
    if let Some(map) = &st.albedo {
        renderer.set_face_weights(Some(&map.face_weights(&st.positions, &st.triangles)))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The record names the first setting that differs, by its path, with both values.
    #[test]
    fn settings_record_names_the_changed_field() {
        let p = ReconstructParams::default();
        let a = SettingsRecord::of(&p).expect("record");
        assert_eq!(first_difference(&a.params, &a.params, ""), None);
        let q = ReconstructParams { schedule: crate::Schedule { shape_iterations: 30, ..p.schedule }, ..p.clone() };
        let b = SettingsRecord::of(&q).expect("record");
        assert_eq!(
            first_difference(&a.params, &b.params, ""),
            Some(("schedule.shape_iterations".into(), "20".into(), "30".into()))
        );
        let r = ReconstructParams { prune: None, ..p.clone() };
        let d = first_difference(&a.params, &SettingsRecord::of(&r).expect("record").params, "").expect("differs");
        assert_eq!(d.0, "prune");
        assert_eq!(d.2, "null");
        // The output directory is not a setting.
        let o = ReconstructParams { out_dir: Some("elsewhere".into()), ..p };
        assert_eq!(SettingsRecord::of(&o).expect("record"), a);
    }
}
