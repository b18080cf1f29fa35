//! The analysis-by-synthesis loop (Tsai et al. 2019, Sec. 4.2 and 5), its checkpoints and its run log.
//!
//! Each stage fits the capture with [`crate::Schedule::rebin`] bins summed (coarse to fine in time as in
//! space: 4, 2, 1 for Tsai et al. 2019's 1.2 mm bins; a sensor fit through the response of the summed bins,
//! [`crate::data_term::response`]; the capture's own bins with per-bin weights), made once at its first block; the data term's normaliser is that capture's, so the data terms of
//! different stages are not comparable.
//!
//! Per block (see [`crate::Schedule`]):
//! 1. **Topology.** Boundary faces no measurement can see are deleted (optional), the mesh is remeshed
//!    isotropically at the stage's target length (`nlos_mesh::remeshing::uniform_remeshing`), the Adam
//!    moments are carried to the new vertices (barycentric interpolation on the closest old face) and a new
//!    [`Renderer`] is built. (This is "remesh after every shape block", plus once on the initial mesh.)
//! 2. **Shape block.** Each step: forward render, data term with the closed-form scale ([`crate::data_term::intensities`]),
//!    adjoint (Proposition 1, `nlos_render`), plus `λ ·` the normal-smoothing regulariser
//!    ([`crate::regularizer`]; λ set automatically at the first step of the block, against the data term
//!    above its noise floor for photon counts, [`crate::data_term::counts`]), per-vertex isotropic
//!    Adam step ([`crate::adam`]), and the displacement goes through the [`Evolve`] hook.
//!    The same rendering steps the per-vertex albedo ([`crate::albedo`], on by default).
//! 3. **Reflectance block.** Adam steps on θ (and the per-vertex albedo) with the shape fixed, where the
//!    BRDF has parameters beyond the scale.
//! 4. **Pruning** (optional, [`crate::ReconstructParams::prune`]): boundary faces whose deletion lowers the
//!    data term are deleted ([`crate::prune`]); dark regions whose light the data do not detect are deleted
//!    ([`crate::regions`]). At the end of the first stages
//!    ([`crate::ReconstructParams::residual`]), patches from the LCT of the fit's residual join the mesh
//!    where they lower it ([`crate::residual`]); the stage's saved mesh is the one before they join.
//! 5. **Bookkeeping.** Relative-decrease test, stage advance, checkpoint and run log (atomic writes), the
//!    progress callback.
//!
//! **The surface never intersects itself** (El Topo, Brochu & Bridson 2009; Tsai et al. 2019, Sec. 5), per
//! operation: every shape step's displacement (after the caller's [`Evolve`] hook, if any) is applied by
//! `nlos_mesh::evolve::evolve` (continuous collision detection, impulses, impact zones, fail-safe, exact
//! static check), so no step passes the surface through itself
//! ([`crate::ReconstructParams::collision`]); every operation of the remeshing is tested before it is
//! applied (`nlos_mesh::remeshing::RemeshParams::avoid_intersections`); residual patches leave out the
//! faces that would cross the surface ([`crate::residual`]). The start's own intersections are repaired
//! before the first block by deleting faces; checks after every remeshing and at every block's end then find
//! nothing. Should one find pairs, the faces are deleted as at the start and the run goes on, or, with
//! `NLOS_REQUIRE_NO_INTERSECTIONS=1` in the environment (the test suite's strictness), the run stops with
//! [`OptimError::SelfIntersecting`]. [`RunLog::collisions`] records per block what was refused and limited.
//!
//! **Robustness.** A non-finite loss, gradient, θ or position restores the state before the last step,
//! halves every learning rate for the rest of the run, and retries ([`crate::ReconstructParams::max_rollbacks`]).
//!
//! **Determinism.** Given the same inputs, parameters and seed, a run is a deterministic function of them,
//! whatever the thread count: the renderer's reductions run over fixed chunks summed in chunk order
//! (`nlos_render`, its `tests/determinism.rs`), and the loop's own sums are sequential
//! (`tests/end_to_end.rs`, `a_run_does_not_depend_on_the_thread_count`: pools of 1 and 3 threads). A resumed
//! run continues from the exact state of the checkpoint (f32/f64 values are stored exactly).

use glam::Vec3;
use nlos_mesh::SurfaceMesh;
use nlos_mesh::io::PlyVertexFields;
use nlos_render::{RenderParams, Renderer, Sampling};
use nlos_transient::Transient;
use serde::{Deserialize, Serialize};
use std::ops::ControlFlow;

use crate::adam::{Moments, VectorAdam, VertexAdam};
use crate::albedo::{ALBEDO, face_weights};
use crate::boundary_smoothing::BoundarySmoothing;
use crate::error::{OptimError, Result};
use crate::params::{ReconstructParams, SamplingSchedule};
use crate::prune::PruneRecord;
use crate::reflectance::Reflectance;
use crate::regularizer::NormalSmoothing;
use crate::residual::ResidualRecord;
use crate::support::SUPPORT;
use crate::surface::{Surface, VertexField};

mod block;
mod evaluation;
mod log;
mod plan;
pub(crate) mod record;
mod rollback;
mod topology;

use block::{Block, RunCtx};
use evaluation::{Fit, StageData, data_normaliser};
pub use log::{
    EvolveRecord, FIT_DETECTION, FitQuality, IntersectionCheck, IntersectionRecord, IterationRecord, RunLog,
    StageRecord, StartRecord, StepKind, StopReason,
};
pub use plan::{BLOCK_COST_L2_S, BLOCK_COST_SENSOR_S, Plan};
pub use record::RunRecord;
use record::{SettingsRecord, fingerprint, first_difference, next_u64};
use topology::{prepare_topology, untangle};

/// The shape's Adam moments, a field of the loop's surface ([`Surface`]): carried to the new vertices by
/// every change of topology (interpolated on the closest old face after a remeshing), zero for appended
/// patches.
pub const SHAPE_MOMENTS: VertexField<Moments> = VertexField::new("shape_adam", Moments::ZERO);

/// File name of the checkpoint inside the output directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";
/// File name of the run log inside the output directory.
pub const RUN_LOG_FILE: &str = "run_log.json";

/// A caller's own per-step rule: turns the current positions and an Adam displacement into new positions.
/// Without one, the displacement is used as it is ([`DirectEvolve`] does the same). Collision handling,
/// [`crate::ReconstructParams::collision`], applies after the hook, to the motion it proposes.
pub trait Evolve {
    /// New positions (same length as `positions`).
    ///
    /// # Errors
    /// Any failure: the hook's own error boxed in [`OptimError::Evolve`], or another variant.
    fn evolve(&mut self, positions: &[Vec3], triangles: &[[u32; 3]], displacement: &[Vec3]) -> Result<Vec<Vec3>>;
}

/// Applies displacements as they are: the same as giving no [`Evolve`] hook (collision handling,
/// [`crate::ReconstructParams::collision`], still applies after it).
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
    /// The stage (0-based) of the iteration or of the block that ended.
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
    /// The fitted relative albedo of each vertex of `mesh` ([`ReconstructParams::albedo`]; None without).
    pub albedo: Option<Vec<f32>>,
    /// How much of their light the data confirm, per vertex of `mesh` ([`crate::support`]: the area-weighted
    /// mean of its faces' support, in [−1, 1]); None for a run that did not finish.
    pub support: Option<Vec<f32>>,
    /// One record per block's region tests ([`crate::regions`]; empty without them).
    pub regions: Vec<crate::regions::RegionRecord>,
}

/// The least share of its start's area a finished run must keep ([`Outcome::check_surface_kept`]).
pub const MIN_SURFACE_KEPT: f64 = 0.05;

impl Outcome {
    /// Whether the run kept a surface: at least [`MIN_SURFACE_KEPT`] of its start's area ([`RunLog::start`]).
    /// Why: pruning deletes the faces the data do not support, and a start the data do not support at all
    /// ends as a few slivers that look like a result — the shared general-NLOS capture thinned to every 4th
    /// spot each way ended with 2 faces of 0.006 cm² from a start of 0.43 m², and the command said nothing.
    /// An interrupted run, or one whose log has no start, is not judged.
    ///
    /// # Errors
    /// [`OptimError::SurfaceLost`]: what was kept, what deleted the rest, and what to look at.
    pub fn check_surface_kept(&self) -> Result<()> {
        let Some(start) = self.log.start else { return Ok(()) };
        let area = self.mesh.surface_area();
        if self.stop == StopReason::Interrupted || !(start.area > 0.0) || area >= MIN_SURFACE_KEPT * start.area {
            return Ok(());
        }
        let pruned: usize = self.prune.iter().map(|r| r.removed).sum();
        let why = if pruned > 0 {
            format!("boundary pruning deleted {pruned} faces, block by block, because the data did not support them")
        } else {
            "the faces were deleted as self-intersecting or degenerate".to_string()
        };
        Err(OptimError::SurfaceLost {
            faces: self.mesh.n_faces(),
            area,
            start_faces: start.faces,
            start_area: start.area,
            why,
        })
    }

    /// Whether the finished surface explains more of its capture than an empty scene would, by more than the
    /// noise ([`RunLog::fit`], [`FitQuality::explains_anything`]): its data term below the empty scene's (no
    /// surface, the background alone) and, for photon counts, its light detected at 3σ. A run whose
    /// surface only spreads light over the background — what a capture of noise alone gives — has not found a
    /// scene, whatever its mesh looks like. An interrupted run, or one without the record, is not judged.
    ///
    /// # Errors
    /// [`OptimError::ExplainsNothing`], with the verdict's figures.
    pub fn check_explains(&self) -> Result<()> {
        match &self.log.fit {
            Some(fit) if self.stop != StopReason::Interrupted && !fit.explains_anything() => {
                Err(OptimError::ExplainsNothing { verdict: fit.describe() })
            }
            _ => Ok(()),
        }
    }
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
    let mut surface = Surface::new(positions, triangles)?;
    if params.albedo.is_some() {
        // Created at its initial value, the mean (1), so that every later change of topology carries it.
        surface.vertex_mut(ALBEDO)?;
    }
    let mut state = RunRecord {
        version: RunRecord::VERSION,
        fingerprint: fingerprint(measured),
        settings: SettingsRecord::of(params)?,
        surface,
        reflectance: params.reflectance.clone(),
        shape_adam: VertexAdam::default(),
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
        prune_log: Vec::new(),
        residual_log: Vec::new(),
        region_log: Vec::new(),
        albedo_steps: 0,
    };
    // A start that intersects itself would leave collision-aware evolution nothing to guarantee.
    untangle(&mut state, IntersectionCheck::Start)?;
    state.log.start = Some(StartRecord { faces: state.surface.n_faces(), area: state.surface.area() });
    if let Some(dir) = &params.out_dir {
        std::fs::create_dir_all(dir).map_err(|source| OptimError::Io {
            path: dir.clone(),
            fix: OptimError::WRITE_FIX,
            source,
        })?;
    }
    run(measured, state, params, hooks)
}

/// Why a checkpoint could not be read, in words: a missing one means no run was started in the directory.
pub(crate) fn checkpoint_unreadable(e: &std::io::Error) -> String {
    if e.kind() == std::io::ErrorKind::NotFound {
        "not found: no run was started in this directory, so there is nothing to resume".into()
    } else {
        format!("cannot be read: {e}")
    }
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
    let ck = |message: String| OptimError::Checkpoint { path: path.clone(), message };
    let state = RunRecord::read(dir)?;
    if state.fingerprint != fingerprint(measured) {
        return Err(ck("it was written for a different measurement".into()));
    }
    if state.settings.version != record::SETTINGS_VERSION {
        return Err(ck(format!(
            "settings record version {} (this build writes {}); start the run afresh",
            state.settings.version,
            record::SETTINGS_VERSION
        )));
    }
    let now = SettingsRecord::of(params)?;
    if let Some((field, was, now)) = first_difference(&state.settings.params, &now.params, "") {
        return Err(OptimError::SettingsChanged { path: path.clone(), field, was, now });
    }
    if state.surface.vertex(SHAPE_MOMENTS).is_err()
        || state.surface.n_faces() == 0
        || state.surface.vertex(ALBEDO).is_ok() != params.albedo.is_some()
    {
        return Err(ck("inconsistent mesh and optimiser state".into()));
    }
    run(measured, state, params, hooks)
}

/// Where the run's shape and reflectance steps render and why, in words for its log
/// ([`nlos_render::describe_device`] for the first stage's renderer settings and [`ReconstructParams::device`]).
pub fn describe_device(params: &ReconstructParams) -> String {
    nlos_render::describe_device(params.device, &render_params(params, 0, &mut 0))
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
    params.render.with_sampling(sampling)
}

/// The loop over blocks, from `st` (a new run's first state or a checkpoint's) to the end of the schedule;
/// each block's steps are in [`block`].
fn run(measured: &Transient, mut st: RunRecord, params: &ReconstructParams, mut hooks: Hooks<'_>) -> Result<Outcome> {
    let data = measured.data();
    if let Some(i) = data.iter().position(|x| !x.is_finite()) {
        return Err(OptimError::NonFiniteMeasurement { index: i, value: data[i] });
    }
    params.data.validate(data.len())?;
    let background = match &params.sensor {
        Some(sensor) => sensor.resolve_background(measured)?,
        None => 0.0,
    };
    // An all-zero capture is refused before any work (each stage's own normaliser is taken in the loop).
    data_normaliser(params, data)?;
    st.max_stages_hint = params.schedule.max_stages;
    let mut evolve: Option<&mut dyn Evolve> = hooks.evolve.take();
    let ctx = RunCtx::new(&st, params, Plan::new(params.schedule, measured.measurements(), params.sensor.is_some()));

    // The capture of the current stage (coarse to fine in time, crate::Schedule): made at a stage's first block.
    let mut stage_data: Option<StageData> = None;
    while st.finished.is_none() {
        let target = ctx.plan.stage_edge(&mut st, |edge| StageData::bins_summed(measured, params, edge));
        let sd: &StageData = match stage_data.take() {
            Some(d) if d.stage == st.stage => stage_data.insert(d),
            _ => stage_data.insert(StageData::new(measured, params, st.stage, target, background)?),
        };
        let stage_capture: &Transient = sd.capture.as_ref().unwrap_or(measured);
        let norm = data_normaliser(params, stage_capture.data())?;
        // Step 1: topology (remeshing at the stage's edge), then the block's renderer and regularisers.
        let (boundary, remesh_refused) = prepare_topology(&mut st, target as f32, params, stage_capture)?;
        let mut renderer = Renderer::new(
            st.surface.positions(),
            st.surface.triangles(),
            stage_capture.scan(),
            stage_capture.time(),
            render_params(params, st.stage, &mut st.rng),
        )?;
        renderer.set_device(params.device)?;
        // The albedo's face factors (crate::albedo); every shape step updates them.
        set_albedo_weights(&st, &mut renderer)?;
        let mut b = Block {
            target,
            measured: stage_capture,
            fit: Fit { params, measured: stage_capture.data(), sensor: sd.sensor.as_ref(), norm },
            renderer,
            reg: NormalSmoothing::new(st.surface.n_vertices(), st.surface.triangles())?,
            edge_reg: BoundarySmoothing::new(st.surface.n_vertices(), st.surface.triangles())?,
            boundary,
            collisions: EvolveRecord {
                stage: st.stage,
                block: st.block_in_stage,
                seconds: 0.0,
                steps: 0,
                steps_limited: 0,
                vertices_adjusted: 0,
                motion_fraction: 1.0,
                input_intersected: st.log.intersections.last().is_some_and(|r| r.pairs_left > 0),
                remesh_refused,
            },
            first: f64::NAN,
            last: f64::NAN,
            tv_weight: 0.0,
        };
        let block_stage = st.stage;
        block::shape_block(&mut st, &ctx, &mut b, &mut hooks, evolve.as_deref_mut())?;
        if ctx.refl_iters > 0 {
            block::reflectance_block(&mut st, &ctx, &mut b, &mut hooks)?;
        }
        let end = ctx.plan.block_end(&st, target, b.first, b.last);
        let stage_mesh = block::prune_and_patch(&mut st, &ctx, &b, &end)?;
        block::bookkeeping(&mut st, &ctx, &b, &end, stage_mesh)?;
        if end.stage_ends {
            // What the stage's last surface explains of its capture (the final surface's, after the last stage),
            // in the record before its next write.
            let mut rng = st.rng;
            let render = render_params(params, block_stage, &mut rng);
            let mut surface = Renderer::new(
                st.surface.positions(),
                st.surface.triangles(),
                b.measured.scan(),
                b.measured.time(),
                render,
            )?;
            surface.set_device(params.device)?;
            set_albedo_weights(&st, &mut surface)?;
            let fit = evaluation::fit_quality(&st, &surface, &b.fit)?;
            if let Some(r) = st.log.stages.iter_mut().rev().find(|r| r.stage == block_stage) {
                r.fit = Some(fit);
            }
            if st.finished.is_some() {
                st.log.fit = Some(fit);
                // How much of each final face's light the data confirm (mesh.ply, the report's 3-D view).
                let support = evaluation::face_support(&st, &surface, &b.fit)?;
                st.surface.face_mut(SUPPORT)?.copy_from_slice(&support);
            }
            if let Some(dir) = &params.out_dir {
                st.write(dir)?;
            }
        }
        // The block's stage: `bookkeeping` has moved `st` to the next stage when this block ended one.
        let end = progress(&st, ProgressEvent::BlockEnd, ctx.planned, b.last, target, st.elapsed_s);
        let flow = report(&mut hooks, &Progress { stage: block_stage, ..end });
        if flow.is_break() && st.finished.is_none() {
            return Ok(outcome(&st, st.surface.mesh()?, StopReason::Interrupted));
        }
    }
    let mesh = st.surface.mesh()?;
    if let Some(dir) = &params.out_dir {
        nlos_mesh::io::save(&mesh, dir.join("mesh.obj"))?;
        // The relative albedo (area mean 1 over the surface) at each vertex, for viewers, `nlos render` and
        // `nlos eval --front-view`; the support of the faces around each vertex.
        let (albedo, support) = (vertex_albedo(&st), st.vertex_support());
        let fields = PlyVertexFields { albedo: albedo.as_deref(), support: support.as_deref() };
        nlos_mesh::io::save_ply_with(&mesh, &fields, dir.join("mesh.ply"))?;
    }
    Ok(outcome(&st, mesh, st.finished.unwrap_or(StopReason::MaxStages)))
}

/// The outcome of a run in state `st` with its mesh.
fn outcome(st: &RunRecord, mesh: SurfaceMesh, stop: StopReason) -> Outcome {
    Outcome {
        mesh,
        reflectance: st.reflectance.clone(),
        scale: st.scale,
        log: st.log.clone(),
        stop,
        stage: st.stage,
        blocks_done: st.blocks_done,
        evolve: st.log.collisions.clone(),
        prune: st.prune_log.clone(),
        residual: st.residual_log.clone(),
        albedo: vertex_albedo(st),
        support: st.vertex_support(),
        regions: st.region_log.clone(),
    }
}

/// The per-vertex albedo of `st`'s surface in f32 (None: the run fits none).
fn vertex_albedo(st: &RunRecord) -> Option<Vec<f32>> {
    st.surface.vertex(ALBEDO).ok().map(|a| a.iter().map(|&x| x as f32).collect())
}

/// What the progress hook is told of `st` now.
fn progress(st: &RunRecord, event: ProgressEvent, planned: u64, loss: f64, target: f64, elapsed_s: f64) -> Progress {
    Progress {
        event,
        stage: st.stage,
        max_stages: st.max_stages_hint,
        blocks_done: st.blocks_done,
        iteration: st.iteration,
        iterations_planned: planned,
        loss,
        faces: st.surface.n_faces(),
        target_edge_length: target,
        elapsed_s,
    }
}

/// Calls the progress hook, if any.
fn report(hooks: &mut Hooks<'_>, p: &Progress) -> ControlFlow<()> {
    hooks.progress.as_mut().map_or(ControlFlow::Continue(()), |cb| cb(p))
}

/// Gives the renderer the per-triangle factors of the surface's albedo ([`crate::albedo::face_weights`];
/// nothing when the run fits none).
fn set_albedo_weights(st: &RunRecord, renderer: &mut Renderer) -> Result<()> {
    if let Ok(albedo) = st.surface.vertex(ALBEDO) {
        renderer.set_face_weights(Some(&face_weights(albedo, st.surface.triangles())))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A finished run that kept less than `MIN_SURFACE_KEPT` of its start's area is an error saying what
    /// was kept and what deleted the rest; one that kept more, an interrupted one and one whose log predates
    /// the start record are not. What it catches: a run ending in a sliver reported as a result.
    #[test]
    fn a_run_that_kept_almost_no_surface_or_explains_nothing_is_an_error() {
        let p = [Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.01, 0.0, 0.5), Vec3::new(0.0, 0.01, 0.5)];
        let mesh = SurfaceMesh::from_triangles(&p, &[[0, 2, 1]]).expect("one face");
        let area = mesh.surface_area();
        let outcome = |start_area: f64, stop: StopReason| Outcome {
            mesh: mesh.clone(),
            reflectance: Reflectance::default(),
            scale: 1.0,
            log: RunLog { start: Some(StartRecord { faces: 86, area: start_area }), ..RunLog::default() },
            stop,
            stage: 3,
            blocks_done: 23,
            evolve: Vec::new(),
            prune: vec![PruneRecord { stage: 0, block: 0, tested: 40, removed: 84, data_change: -0.1 }],
            residual: Vec::new(),
            albedo: None,
            support: None,
            regions: Vec::new(),
        };
        let e = outcome(area / 0.01, StopReason::MaxStages).check_surface_kept().expect_err("1 % kept");
        let text = e.to_string();
        assert!(matches!(e, OptimError::SurfaceLost { faces: 1, start_faces: 86, .. }), "{e:?}");
        for part in ["almost no surface", "1.0 % of the 86 faces", "pruning deleted 84 faces", "--init MESH"] {
            assert!(text.contains(part), "{part:?} missing: {text}");
        }
        assert!(outcome(area / (2.0 * MIN_SURFACE_KEPT), StopReason::MaxStages).check_surface_kept().is_ok());
        assert!(outcome(area / 0.01, StopReason::Interrupted).check_surface_kept().is_ok());
        let mut old = outcome(area / 0.01, StopReason::TimeBudget);
        old.log.start = None;
        assert!(old.check_surface_kept().is_ok());
        // A surface no better than an empty scene is an error with the verdict's figures; a better one, an
        // interrupted run and a log without the record are not.
        let mut noise = outcome(area, StopReason::MaxStages);
        noise.log.fit = Some(FitQuality { data: 0.98, empty: 0.77, noise_floor: Some(0.07), detection: None });
        let e = noise.check_explains().expect_err("no better than empty");
        assert!(matches!(e, OptimError::ExplainsNothing { .. }), "{e:?}");
        let text = e.to_string();
        for part in ["explains no more than an empty scene would", "0.9800", "0.7700", "init.obj"] {
            assert!(text.contains(part), "{part:?} missing: {text}");
        }
        noise.log.fit = Some(FitQuality { data: 0.5, empty: 0.77, noise_floor: Some(0.07), detection: None });
        assert!(noise.check_explains().is_ok());
        noise.log.fit = Some(FitQuality { data: 0.76, empty: 0.77, noise_floor: Some(0.07), detection: Some(3.0) });
        let e = noise.check_explains().expect_err("not by more than the noise");
        assert!(e.to_string().contains("by more than the noise"), "{e}");
        noise.log.fit = Some(FitQuality { data: 0.98, empty: 0.77, noise_floor: None, detection: None });
        noise.stop = StopReason::Interrupted;
        assert!(noise.check_explains().is_ok());
        noise.log.fit = None;
        noise.stop = StopReason::MaxStages;
        assert!(noise.check_explains().is_ok());
    }
}
