//! The one error type of the crate.

use std::path::PathBuf;

use thiserror::Error;

/// Everything that can go wrong in a reconstruction. Each variant says the cause and the fix.
#[derive(Debug, Error)]
pub enum OptimError {
    /// The renderer rejected the mesh, the scan or a buffer.
    #[error("renderer: {0}; the mesh or the measurement's scan/time axis is unusable (see nlos_render)")]
    Render(#[from] nlos_render::RenderError),
    /// A mesh operation (construction, remeshing, I/O) failed.
    #[error("mesh: {0}; repair the initial mesh (manifold, finite, non-empty) or check the output directory")]
    Mesh(#[from] nlos_mesh::MeshError),
    /// Reflectance parameters could not be turned into a BRDF.
    #[error("BRDF: {0}; start from parameters inside the model's domain")]
    Brdf(#[from] nlos_brdf::BrdfError),
    /// A field of the loop's surface ([`crate::surface::Surface`]) was read before it was written, or under a
    /// name that holds another type.
    #[error(
        "surface {kind} field {name:?}: {reason}; a field is written (created with its initial value) before it is \
         read, and each name holds one type"
    )]
    Field {
        /// The field's name.
        name: String,
        /// "vertex" or "face".
        kind: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A parameter is outside its domain.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name (as spelled in [`crate::ReconstructParams`]).
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// Two buffers that must match in length do not.
    #[error("{what} has {got} values but {expected} were expected; pass one value per (measurement, bin)")]
    LengthMismatch {
        /// Which buffer.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Supplied length.
        got: usize,
    },
    /// The measurement contains NaN or infinite values.
    #[error("measured value {index} is not finite ({value}); clean the capture (e.g. zero dead pixels) first")]
    NonFiniteMeasurement {
        /// Index into the measurement (measurement-major).
        index: usize,
        /// The value.
        value: f32,
    },
    /// A finished run explains no more of its capture than an empty scene would ([`crate::Outcome::check_explains`]).
    #[error(
        "the surface {verdict}: it is no evidence of a scene. The capture may hold no return from the hidden \
         volume (look at its time-summed image and at `nlos init --volume`), or the start missed it (look at \
         `init.obj` beside the mesh, or give your own with `nlos reconstruct --init MESH`)"
    )]
    ExplainsNothing {
        /// The verdict in words ([`crate::FitQuality::describe`]).
        verdict: String,
    },
    /// A finished run kept almost no surface ([`crate::Outcome::check_surface_kept`]).
    #[error(
        "the run kept almost no surface: {faces} faces, {:.3} cm², {:.1} % of the {start_faces} faces and {:.0} cm² \
         it started from; {why}. The start does not match the capture: look at the start (`init.obj` beside the \
         mesh) and at its volume (`nlos init --volume`), \
         or give your own start (`nlos reconstruct --init MESH`)",
        1e4 * .area, 100.0 * .area / .start_area, 1e4 * .start_area
    )]
    SurfaceLost {
        /// Faces of the final mesh.
        faces: usize,
        /// Its area (m²).
        area: f64,
        /// Faces of the start.
        start_faces: usize,
        /// Its area (m²).
        start_area: f64,
        /// What deleted the rest, in words.
        why: String,
    },
    /// The mesh has no faces (initially, or after removing unlit faces).
    #[error("the mesh has no faces ({context}); start from a larger initial surface in front of the wall")]
    EmptyMesh {
        /// Where it happened.
        context: &'static str,
    },
    /// Non-finite loss, gradient or positions persisted after every allowed step halving.
    #[error(
        "optimisation diverged at iteration {iteration}: non-finite {what} after {rollbacks} rollbacks with \
         halved steps; lower the learning rates, raise the regulariser ratio or check the measurement"
    )]
    Diverged {
        /// Global iteration number.
        iteration: u64,
        /// What was not finite.
        what: &'static str,
        /// Rollbacks performed.
        rollbacks: u32,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}; {fix}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What to check, for this file ([`OptimError::WRITE_FIX`] for the run's outputs).
        fix: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A checkpoint is missing, malformed or from an incompatible run.
    #[error(
        "checkpoint {}: {message}; start a fresh run (without resume) or pass the matching measurement",
        path.display()
    )]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// `resume` found a checkpoint written with other reconstruction settings than the ones given: continuing
    /// would silently mix two different runs. `field` is the first setting that differs, as a path into
    /// [`crate::ReconstructParams`] (`schedule.shape_iterations`), with its value in the checkpoint and now.
    #[error(
        "checkpoint {}: the run was started with {field} = {was}, not {now}; resume with the settings of the \
         original run (`nlos reconstruct` keeps them in settings.toml beside the checkpoint), or start afresh in \
         another directory",
        path.display()
    )]
    SettingsChanged {
        /// The checkpoint file.
        path: PathBuf,
        /// The first setting that differs (a dotted path into the parameters).
        field: String,
        /// Its value in the checkpoint (JSON).
        was: String,
        /// Its value now (JSON).
        now: String,
    },
    /// The sensor model of the noise-aware fit (jitter kernel, background window, histogram layout) is
    /// unusable.
    #[error("sensor fit: {0}; check the jitter response, the background window and the capture's bins")]
    Sensor(#[source] nlos_transient::TransientError),
    /// A transient built inside the loop (the residual's histograms) is invalid: non-finite values.
    #[error("{context}: {source}; the fit diverged or the measurement holds non-finite values")]
    Transient {
        /// Which transient.
        context: &'static str,
        /// What the transient crate found.
        #[source]
        source: nlos_transient::TransientError,
    },
    /// A volumetric reconstruction failed: the initial surface ([`crate::pipeline`]) or the residual's
    /// back-projection ([`crate::residual`]).
    #[error("volumetric reconstruction: {0}; for the residual patches switch them off (boundary.residual_stages = 0)")]
    Init(#[from] nlos_init::InitError),
    /// A setting of the pipeline's configuration ([`crate::pipeline::Config`]) is malformed or outside its
    /// domain for this capture.
    #[error("setting {field}: {reason}")]
    Config {
        /// The field, as spelled in the configuration file (`capture.rebin`), or the file.
        field: String,
        /// What is wrong and what is allowed.
        reason: String,
    },
    /// The capture file cannot be read.
    #[error("{}", capture_message(path, source))]
    Capture {
        /// The capture file.
        path: PathBuf,
        /// What the reader found (boxed: it is large, and every `Result` of the crate would carry it).
        #[source]
        source: Box<nlos_transient::TransientError>,
    },
    /// An evolution hook ([`crate::Evolve`]) failed with its own error.
    #[error("evolution hook: {0}; fall back to DirectEvolve or fix the hook")]
    Evolve(#[source] Box<dyn std::error::Error + Send + Sync>),
    /// Collision-aware evolution returned positions that do not fit the mesh: another vertex count, or
    /// non-finite positions (then `got == expected`).
    #[error(
        "collision-aware evolution returned {got} positions for {expected} vertices, or non-finite ones; \
         lower the learning rates or switch it off (ReconstructParams::collision = None)"
    )]
    EvolveOutput {
        /// Vertices of the mesh.
        expected: usize,
        /// Positions returned.
        got: usize,
    },
    /// A self-intersection check after the start found intersecting faces, and the environment asks for
    /// none (`NLOS_REQUIRE_NO_INTERSECTIONS=1`, the test suite's strictness). Without it the faces are
    /// deleted and the run goes on.
    #[error(
        "the surface intersects itself at the {check} check of stage {stage}, block {block}: {pairs} face pairs \
         (NLOS_REQUIRE_NO_INTERSECTIONS=1 makes this an error; collision handling should have prevented it: \
         please report it with the run's run_log.json)"
    )]
    SelfIntersecting {
        /// Stage.
        stage: u32,
        /// Block within the stage.
        block: u32,
        /// Which check (`remeshed`, `block_end`).
        check: &'static str,
        /// Intersecting face pairs found.
        pairs: usize,
    },
}

/// The reader's message, with the file in front when the message does not name it already (most do: a path
/// said twice reads as two files).
fn capture_message(path: &std::path::Path, source: &nlos_transient::TransientError) -> String {
    let (file, message) = (path.display().to_string(), source.to_string());
    if message.contains(&file) { message } else { format!("{file}: {message}") }
}

impl OptimError {
    /// What to check when an output of the run cannot be written ([`OptimError::Io`]).
    pub const WRITE_FIX: &'static str = "check that the output directory exists and is writable";
}

/// Result alias of the crate.
pub type Result<T> = std::result::Result<T, OptimError>;
