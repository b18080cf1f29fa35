//! The run log (`run_log.json`): one record per iteration, per collision-aware evolution and per
//! self-intersection check, and why the run ended.

use serde::{Deserialize, Serialize};

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
    /// Regulariser `R + w R_∂` (normal plus boundary smoothing, [`ReconstructParams::boundary_smoothing`](crate::ReconstructParams::boundary_smoothing)), before λ.
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
    /// The stages started: the edge each was run at ([`crate::Plan::planned_edge`]).
    #[serde(default)]
    pub stages: Vec<StageRecord>,
    /// Residual back-projection at the end of each stage that proposes patches: every candidate that passed
    /// the data test, with its depth, what it explained, its contrast and whether it was kept.
    #[serde(default)]
    pub residual: Vec<crate::ResidualRecord>,
    /// Collision handling per block: the remeshing's refused operations and the shape steps' limited motion.
    #[serde(default)]
    pub collisions: Vec<EvolveRecord>,
    /// The start the run was given (after its own self-intersections were removed); None in logs written
    /// before it was recorded.
    #[serde(default)]
    pub start: Option<StartRecord>,
    /// How much of its capture the finished surface explains; None while the run is under way, for an
    /// interrupted run and in logs written before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitQuality>,
}

/// How much of its capture a result explains, from the data term of its last stage (normalised as
/// [`IterationRecord::data`]): the final surface's, an empty scene's (no surface, the background alone: a
/// sensor fit's resolved background, or else the capture's best constant level, so that a surface that only
/// spreads light over the background explains nothing) and, for photon counts, the noise floor (what the data
/// term would be were the final surface's expected counts exact, [`IterationRecord::noise_floor`]).
///
/// The share of the light above the noise that the surface explains is
/// `(empty − data) / (empty − floor)`: 0 for a result no better than an empty scene, 1 for one whose misfit is
/// down to the noise ([`FitQuality::explained`], [`FitQuality::describe`] in words).
///
/// **Better than an empty scene by more than the noise** ([`FitQuality::explains_anything`]). For photon
/// counts the record also holds the likelihood-ratio statistic of the surface against the empty scene,
/// ```text
/// Λ = 2 (E_empty − E) / σ²            σ² = Σ_k w_k² μ_k (s I_k)² / Σ_k w_k (s I_k)²   (L2 of counts)
/// Λ = 2 (E_empty − E)                                                             (Poisson)
/// ```
/// in absolute units (`μ_k = max(s I_k, 1)` the expected counts, `w` the data term's weights): the region
/// tests' statistic ([`crate::regions`]) with the whole surface as the region. Were there nothing to explain,
/// `Λ` of a fit along one direction would be χ² with one degree of freedom (Wilks 1938); a surface is judged
/// to explain its capture only when `Λ ≥` [`FIT_DETECTION`] (its light detected at 3σ) as well as `E < E_empty`.
/// A surface has many more degrees of freedom than one, so noise alone can lift `Λ` above 9; what keeps a
/// capture of noise from passing is the empty scene's own best level, which a surface that only spreads
/// light over the background cannot beat (`E ≥ E_empty`, measured on the noise-only capture of the CLI's
/// tests).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitQuality {
    /// The final surface's normalised data term.
    pub data: f64,
    /// An empty scene's normalised data term.
    pub empty: f64,
    /// The normalised noise floor (photon counts only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_floor: Option<f64>,
    /// The likelihood-ratio statistic `Λ` of the surface against the empty scene (photon counts only; None
    /// for intensities without a noise model and in logs written before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detection: Option<f64>,
}

/// The χ²₁ threshold of [`FitQuality::detection`]: a surface's light detected at 3σ, as a region's
/// ([`crate::RegionParams::detection`]'s default).
pub const FIT_DETECTION: f64 = 9.0;

impl FitQuality {
    /// Whether the surface explains more of its capture than an empty scene would, by more than the noise:
    /// `data < empty` and, where the noise model gives one, `detection ≥` [`FIT_DETECTION`]. What
    /// [`crate::Outcome::check_explains`] and the acceptance board judge a run by.
    ///
    /// The margin applies only where the noise model fits the capture, its floor below the empty scene's data
    /// term: a floor above it says the values are not photon counts at the scale the model assumes (a capture
    /// forced to `sensor.noise = "counts"`), and then neither the floor nor `Λ` measures its noise.
    pub fn explains_anything(&self) -> bool {
        let noise_fits = self.noise_floor.is_some_and(|f| f < self.empty);
        self.data < self.empty && (!noise_fits || self.detection.is_none_or(|l| l >= FIT_DETECTION))
    }

    /// The share of the light above the noise floor that the surface explains, in [0, 1]: `(empty − data) /
    /// (empty − floor)`, clamped. None when the capture holds nothing above its floor (or a value is not
    /// finite).
    pub fn explained(&self) -> Option<f64> {
        let floor = self.noise_floor.unwrap_or(0.0);
        let room = self.empty - floor;
        let share = (self.empty - self.data) / room;
        (room > 0.0 && share.is_finite()).then(|| share.clamp(0.0, 1.0))
    }

    /// The verdict in words, with the figures it rests on: "explains 93 % of the light above the noise", or
    /// "explains no more than an empty scene would".
    pub fn describe(&self) -> String {
        let figures = match self.noise_floor {
            Some(f) => {
                format!("data term {:.4} against an empty scene's {:.4}; noise floor {f:.4}", self.data, self.empty)
            }
            None => format!("data term {:.4} against an empty scene's {:.4}", self.data, self.empty),
        };
        let above = if self.noise_floor.is_some() { "the light above the noise" } else { "the light" };
        let figures = match self.detection {
            Some(l) => format!("{figures}; likelihood ratio {l:.1}, detected from {FIT_DETECTION:.0}"),
            None => figures,
        };
        match self.explained() {
            None => format!("the capture holds no light above its noise floor ({figures})"),
            Some(_) if self.data >= self.empty => format!("explains no more than an empty scene would ({figures})"),
            Some(_) if !self.explains_anything() => {
                format!("explains no more than an empty scene would by more than the noise ({figures})")
            }
            Some(e) => format!("explains {:.0} % of {above} ({figures})", 100.0 * e),
        }
    }
}

/// The surface a run started from: what [`crate::Outcome::check_surface_kept`] compares the result with.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StartRecord {
    /// Faces.
    pub faces: usize,
    /// Area (m²).
    pub area: f64,
}

/// A stage as it was started: its target edge, planned for the time budget, beside the schedule's own.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StageRecord {
    /// The stage (0-based).
    pub stage: u32,
    /// Target edge length it ran at (m).
    pub edge_length: f64,
    /// The schedule's own edge for it ([`crate::Schedule::target_edge_length`]); larger `edge_length`:
    /// coarsened so that the stages left fit the time budget whole.
    pub schedule_edge_length: f64,
    /// Bins of the capture summed in it ([`crate::Schedule::rebin_at`]).
    pub bins_summed: usize,
    /// How much of its capture the stage's last surface explains (None while it runs, and in older logs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitQuality>,
}

/// When the surface is checked for self-intersections ([`IntersectionRecord`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntersectionCheck {
    /// The initial surface, before the loop.
    Start,
    /// After a block's remeshing (each of its operations checked, `nlos_mesh::remeshing::RemeshParams::
    /// avoid_intersections`).
    Remeshed,
    /// At the end of a block: after its collision-aware shape steps, pruning and residual patches (whose faces
    /// that would cross the surface are left out).
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
    /// The next stage's predicted time would exceed the time budget ([`crate::Schedule::reference_seconds`]).
    TimeBudget,
    /// The progress callback asked to stop (resume continues).
    Interrupted,
}

/// What collision handling did in one block (El Topo's per-operation checks): the operations its remeshing
/// refused, and how its shape steps' motion was limited so that no step makes the surface intersect itself.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvolveRecord {
    /// Stage.
    pub stage: u32,
    /// Block within the stage.
    pub block: u32,
    /// Wall-clock seconds of the steps' `evolve` calls (the only non-deterministic field).
    pub seconds: f64,
    /// Shape steps evolved.
    #[serde(default)]
    pub steps: u32,
    /// Steps in which some vertex's motion was limited (pushed apart, stopped short or cancelled).
    #[serde(default)]
    pub steps_limited: u32,
    /// Vertices whose end position differs from `x₀ + d`, summed over the steps.
    pub vertices_adjusted: usize,
    /// The smallest share of a step's requested motion applied
    /// (`nlos_mesh::evolve::EvolveReport::motion_fraction`; 1 when nothing was limited).
    pub motion_fraction: f64,
    /// Whether the block's mesh self-intersected before its steps (then evolved with `check_input: false`:
    /// no new intersection, the old ones kept).
    pub input_intersected: bool,
    /// Operations the block's remeshing refused because they would have made the surface intersect itself
    /// (`nlos_mesh::remeshing::RemeshReport::refused_intersections`).
    #[serde(default)]
    pub remesh_refused: usize,
}

#[cfg(test)]
mod tests {
    use super::FitQuality;

    /// The share explained runs from 0 (no better than an empty scene) to 1 (down to the noise floor), and the
    /// words say which.
    #[test]
    fn the_verdict_follows_the_share_above_the_noise() {
        let fit = |data, floor| FitQuality { data, empty: 1.0, noise_floor: floor, detection: None };
        assert!((fit(0.0763, Some(0.0756)).explained().expect("a share") - 0.99924).abs() < 1e-4);
        assert!(fit(0.0763, Some(0.0756)).describe().starts_with("explains 100 % of the light above the noise"));
        assert!((fit(0.55, None).explained().expect("a share") - 0.45).abs() < 1e-12);
        assert_eq!(
            fit(0.55, None).describe(),
            "explains 45 % of the light (data term 0.5500 against an empty scene's 1.0000)"
        );
        assert_eq!(fit(1.01, Some(0.3)).explained(), Some(0.0));
        assert!(fit(1.01, Some(0.3)).describe().starts_with("explains no more than an empty scene would"));
        // Below the floor (an over-fit, or a floor estimated high): all of it, not more.
        assert_eq!(fit(0.2, Some(0.3)).explained(), Some(1.0));
        // Nothing above the floor, or no finite figures: no share.
        assert_eq!(fit(0.9, Some(1.2)).explained(), None);
        assert!(fit(0.9, Some(1.2)).describe().starts_with("the capture holds no light above its noise floor"));
        assert_eq!(fit(f64::NAN, None).explained(), None);
        // Better than an empty scene, but not by more than the noise: the likelihood ratio decides.
        let faint = |l| FitQuality { detection: Some(l), ..fit(0.9, Some(0.3)) };
        assert!(
            faint(25.0).explains_anything() && !faint(4.0).explains_anything() && fit(0.9, None).explains_anything()
        );
        assert!(faint(4.0).describe().starts_with("explains no more than an empty scene would by more than the noise"));
        assert!(faint(4.0).describe().contains("likelihood ratio 4.0, detected from 9"), "{}", faint(4.0).describe());
        assert!(!fit(1.01, None).explains_anything());
        // A floor above the empty scene's term: the noise model does not fit, its Λ is not judged.
        assert!(FitQuality { detection: Some(3.6), ..fit(0.05, Some(11.0)) }.explains_anything());
    }
}
