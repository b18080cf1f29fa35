//! # nlos-optim
//!
//! The analysis-by-synthesis loop of Tsai, Sankaranarayanan & Gkioulekas, "Beyond Volumetric Albedo — A
//! Surface Optimization Framework for Non-Line-of-Sight Imaging", CVPR 2019 (equation numbers are theirs):
//! render the transient of a candidate mesh (`nlos_render`), compare it with the measurement, differentiate,
//! step with Adam, remesh, repeat — coarse to fine.
//!
//! Building blocks:
//! - [`data_term`]: the data term — L2 of eq. (7) or Poisson NLL of intensities (`nlos_render::Loss`), per-bin
//!   weights and an unknown global intensity scale solved in closed form at every step; or the noise-aware
//!   Poisson NLL of photon counts through the SPAD's jitter response with a background level,
//!   `scale·J(I) + b` (set [`ReconstructParams::sensor`]); and both one histogram at a time;
//! - [`regularizer`]: the normal-smoothing term of Delaunoy & Prados (IJCV 2011) with its exact gradient and
//!   the automatic weight;
//! - [`prune`]: loss-driven boundary pruning — boundary faces whose deletion lowers the data term go;
//! - [`residual`]: residual back-projection — new surface patches where the LCT of the fit's residual
//!   finds light away from the mesh, added where they lower the data term;
//! - [`albedo`]: reflectance on the surface — an albedo per vertex, fitted with the shape under a
//!   total-variation prior, so that dark print is darker surface, not relief;
//! - [`regions`]: region tests — dark regions whose light the data do not detect are deleted (holes);
//! - [`pipeline`]: the reconstruction as users run it — settings ([`pipeline::Config`], TOML), capture
//!   preparation, every `auto` decision and the initial surface;
//! - [`surface`]: the loop's surface — positions, triangles and named per-vertex and per-face fields (the
//!   shape's Adam moments) that every change of topology carries through one map ([`Remap`]);
//! - [`adam`]: Adam (Kingma & Ba 2015), per-vertex isotropic for positions, plain for reflectance θ;
//! - [`reconstruct()`](crate::reconstruct()): the loop — coarse-to-fine schedule, remeshing, rollback on
//!   non-finite values, checkpoints and [`resume`], the JSON run log, collision-aware evolution of each
//!   shape block (`nlos_mesh::evolve`, after El Topo) and a per-step [`Evolve`] hook.
//!
//! ```no_run
//! use nlos_optim::{ReconstructParams, reconstruct};
//! # fn demo(measured: &nlos_transient::Transient, init: &nlos_mesh::SurfaceMesh) -> nlos_optim::Result<()> {
//! let params = ReconstructParams { out_dir: Some("out".into()), seed: 7, ..ReconstructParams::default() };
//! let outcome = reconstruct(measured, init, &params)?;
//! println!("{} faces, final loss {:?}", outcome.mesh.n_faces(), outcome.log.iterations.last().map(|r| r.loss));
//! # Ok(()) }
//! ```
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate: it is also true for NaN, which is how non-finite values reach the guards.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod adam;
pub mod albedo;
pub mod boundary_smoothing;
pub mod builtin;
pub mod data_term;
pub mod error;
pub mod params;
pub mod pipeline;
pub mod prune;
pub mod reconstruct;
pub mod reflectance;
pub mod regions;
pub mod regularizer;
pub mod residual;
pub mod schedule;
pub mod support;
pub mod surface;

pub use adam::{AdamParams, Moments, ScalarMoments, VectorAdam, VertexAdam};
pub use albedo::{ALBEDO, ALBEDO_MOMENTS, AlbedoParams};
pub use boundary_smoothing::BoundarySmoothing;
pub use data_term::{
    DataEval, DataTerm, RowLoss, RowTerm, SensorBackground, SensorFit, SensorModel, SensorRows, expected_half_deviance,
};
pub use error::{OptimError, Result};
pub use nlos_render::Loss;
pub use params::{ReconstructParams, RenderSettings, SamplingSchedule};
pub use prune::{PruneParams, PruneRecord, Pruned, prune_boundary};
pub use reconstruct::{
    BLOCK_COST_L2_S, BLOCK_COST_SENSOR_S, CHECKPOINT_FILE, DirectEvolve, Evolve, EvolveRecord, FIT_DETECTION,
    FitQuality, Hooks, IntersectionCheck, IntersectionRecord, IterationRecord, MIN_SURFACE_KEPT, Outcome, Plan,
    Progress, ProgressEvent, ProgressFn, RUN_LOG_FILE, RunLog, RunRecord, SHAPE_MOMENTS, StageRecord, StartRecord,
    StepKind, StopReason, describe_device, reconstruct, reconstruct_with, resume,
};
pub use reflectance::Reflectance;
pub use regions::{RegionFit, RegionNoise, RegionParams, RegionRecord, Regions, dark_regions};
pub use regularizer::{NormalSmoothing, auto_weight};
pub use residual::{
    LOCALISATION_SHIFT, LOCALISED_CONTRAST, PatchFit, PatchNote, Patches, ResidualParams, ResidualRecord, localisation,
    residual_patches, residual_rounds,
};
pub use schedule::{PHASOR_START_BLOCKS, Schedule, faces_at};
pub use support::{SUPPORT, face_support, vertex_support};
pub use surface::{Remap, Source, Surface};
