//! The run's budget planner ([`Plan`]): what a block and a stage are predicted to cost, the edge each stage
//! is planned at, whether the next block fits, and whether the next stage starts — every decision the
//! schedule and the time budget make, in one place.
//!
//! The budget is in seconds of the reference machine (2 cores), predicted from the shape steps' face counts
//! (their sum is what has been *spent*), not timed: a run stays a deterministic function of its inputs on
//! every machine ([`crate::Schedule::reference_seconds`]).

use super::record::RunRecord;
use super::{StageRecord, StopReason};
use crate::schedule::{Schedule, faces_at};

/// Seconds per face, per measurement and per logged shape step that a block costs on the reference machine
/// (2 cores), everything in the block included (reflectance steps, pruning, evolution, visibility), when
/// the data are fitted through a sensor response: 1.2–1.6e-7 over every block of the three Stanford
/// captures' default runs (4,096 measurements, 2,048 bins of 4 ps).
pub const BLOCK_COST_SENSOR_S: f64 = 1.4e-7;
/// The same for a fit of intensities by L2 (no sensor response): measured on the shared bunny's default
/// run at Tsai et al. 2019's setup (6.0–8.6e-8 per block).
pub const BLOCK_COST_L2_S: f64 = 7.0e-8;

/// The budget planner of one run: its schedule, the measurements every step renders, and whether they are
/// fitted through a sensor response (which costs about twice as much per face).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    /// The schedule (sized to the capture and the start: [`Schedule::sized_to`], [`Schedule::for_start`]).
    pub schedule: Schedule,
    /// Histograms rendered per step.
    pub measurements: usize,
    /// Whether the data are fitted through a sensor response ([`BLOCK_COST_SENSOR_S`], else
    /// [`BLOCK_COST_L2_S`]).
    pub sensor: bool,
}

/// What follows a stage that ended (`Plan::next_stage`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Next {
    /// The next stage starts, planned at this target edge (metres).
    Go(f64),
    /// The run ends here, for this reason.
    Stop(StopReason),
}

/// What the end of a block decides ([`Plan::block_end`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct BlockEnd {
    /// The stage ends with this block (converged, its last block, or the next block would not fit the budget).
    pub(super) stage_ends: bool,
    /// The next stage's first block would not fit the time budget.
    pub(super) next_over_budget: bool,
    /// No block follows this one.
    pub(super) last_block: bool,
}

impl Plan {
    /// The planner of a run with `schedule` over `measurements` histograms, through a sensor response or not.
    pub fn new(schedule: Schedule, measurements: usize, sensor: bool) -> Self {
        Self { schedule, measurements, sensor }
    }

    /// Predicted seconds of the reference machine for `face_steps` (the sum over shape steps of the mesh's
    /// faces) ([`BLOCK_COST_SENSOR_S`], [`BLOCK_COST_L2_S`]).
    pub fn predicted_seconds(&self, face_steps: f64) -> f64 {
        face_steps * self.measurements as f64 * if self.sensor { BLOCK_COST_SENSOR_S } else { BLOCK_COST_L2_S }
    }

    /// Whether a block on a mesh of about `faces` faces may start when the blocks so far took `spent`
    /// face-steps ([`Schedule::reference_seconds`]): their predicted seconds and the block's
    /// (`shape_iterations` steps) within the budget. A stage ends early when its next block does not fit, and
    /// the next stage is not started when its first block does not.
    pub fn block_fits(&self, spent: f64, faces: f64) -> bool {
        let s = &self.schedule;
        let steps = f64::from(s.shape_iterations);
        s.reference_seconds <= 0.0 || self.predicted_seconds(spent + faces * steps) <= s.reference_seconds
    }

    /// Predicted seconds of one stage on a mesh of `faces` faces, all its blocks run.
    fn stage_seconds(&self, faces: f64) -> f64 {
        let s = &self.schedule;
        self.predicted_seconds(faces * f64::from(s.max_blocks_per_stage) * f64::from(s.shape_iterations))
    }

    /// The target edge of stage `stage` ≥ 1, planned at its start so that it and the stages after it fit the
    /// time budget whole ([`Schedule::reference_seconds`]): `previous` is the edge of the stage before,
    /// `area` the mesh's area now (m²) and `spent` the shape steps' faces so far. The remaining stages refine
    /// by a common growth `g ≤ growth`, the largest for which all their blocks (`max_blocks_per_stage` each,
    /// on the faces of the current area at their edges) are predicted to fit what the budget has left
    /// (bisection; deterministic). Never finer than the stage's own edge ([`Schedule::target_edge_length`]);
    /// `g = 1` (the previous edge again) when not even that fits, and the blocks then stop at the budget
    /// ([`Plan::block_fits`]). Without a budget, the stage's own edge. Why: a large object (the S and U
    /// capture's two letters, 0.14 m²) at the default edges would need 12,600 faces in the third stage and
    /// about 900 s; cutting the stage short, or skipping it, left its refinement undone, whereas a slightly
    /// coarser third stage runs every block.
    pub fn planned_edge(&self, stage: u32, previous: f64, area: f64, spent: f64) -> f64 {
        let s = &self.schedule;
        let own = s.target_edge_length(stage);
        if s.reference_seconds <= 0.0 || stage == 0 || !(area.is_finite() && area > 0.0) {
            return own;
        }
        let left = s.reference_seconds - self.predicted_seconds(spent);
        let stages = s.max_stages.saturating_sub(stage);
        let cost = |g: f64| -> f64 {
            (1..=stages)
                .map(|j| {
                    let edge = (previous / g.powi(j as i32)).max(s.target_edge_length(stage + j - 1));
                    self.stage_seconds(faces_at(area, edge))
                })
                .sum()
        };
        let growth = s.growth.max(1.0);
        if cost(growth) <= left {
            return (previous / growth).max(own);
        }
        if cost(1.0) > left {
            return previous.max(own);
        }
        let (mut lo, mut hi) = (1.0, growth);
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            if cost(mid) <= left { lo = mid } else { hi = mid }
        }
        (previous / lo).max(own)
    }

    /// The shape steps' faces so far: what the budget has spent.
    pub(super) fn spent(st: &RunRecord) -> f64 {
        st.log.iterations.iter().map(|r| r.faces as f64).sum()
    }

    /// The edge stage `stage` would be planned at now, after a stage of edge `previous`.
    fn planned_now(&self, st: &RunRecord, stage: u32, previous: f64) -> f64 {
        self.planned_edge(stage, previous, st.surface.area(), Self::spent(st))
    }

    /// The target edge of the current stage: as recorded when it started (a resumed run keeps it), or planned
    /// now and recorded ([`StageRecord`], with the bins it sums: `bins_summed` of the edge).
    pub(super) fn stage_edge(&self, st: &mut RunRecord, bins_summed: impl Fn(f64) -> usize) -> f64 {
        if let Some(r) = st.log.stages.iter().find(|r| r.stage == st.stage) {
            return r.edge_length;
        }
        let s = &self.schedule;
        let previous = st.log.stages.last().map_or_else(|| s.target_edge_length(0), |r| r.edge_length);
        let edge = self.planned_now(st, st.stage, previous);
        st.log.stages.push(StageRecord {
            stage: st.stage,
            edge_length: edge,
            schedule_edge_length: s.target_edge_length(st.stage),
            bins_summed: bins_summed(edge),
            fit: None,
        });
        edge
    }

    /// The end of a block of the stage at edge `target` whose loss went from `first` to `last`: the
    /// relative-decrease test and the budget — the next block of this stage, and the first of the next stage
    /// at its planned face count, must fit.
    pub(super) fn block_end(&self, st: &RunRecord, target: f64, first: f64, last: f64) -> BlockEnd {
        let s = &self.schedule;
        let rel = (first - last) / first.abs().max(f64::MIN_POSITIVE);
        // NaN-safe: a NaN `rel` counts as converged (the rollback logic has already run out otherwise).
        let converged = !(rel >= s.rel_tol);
        let spent = Self::spent(st);
        let over_budget = !self.block_fits(spent, st.surface.n_faces() as f64);
        let stage_ends = converged || st.block_in_stage + 1 >= s.max_blocks_per_stage || over_budget;
        let next_edge = self.planned_now(st, st.stage + 1, target);
        let next_faces = faces_at(st.surface.area(), next_edge);
        let next_over_budget = stage_ends && !self.block_fits(spent, next_faces);
        let last_block = stage_ends && (st.stage + 1 >= s.max_stages || next_over_budget);
        BlockEnd { stage_ends, next_over_budget, last_block }
    }

    /// After stage `st.stage − 1` (edge `previous`) ended as `end` said, and pruning and residual patches
    /// changed the mesh: [`StopReason::MaxStages`] after the last stage; [`StopReason::FaceLimit`] when the
    /// next stage, planned on the mesh as it is now, would exceed `max_faces`; [`StopReason::TimeBudget`]
    /// when its first block did not fit at the block's end ([`Plan::block_end`]); else the next stage's edge.
    pub(super) fn next_stage(&self, st: &RunRecord, end: &BlockEnd, previous: f64) -> Next {
        let s = &self.schedule;
        if st.stage >= s.max_stages {
            return Next::Stop(StopReason::MaxStages);
        }
        let edge = self.planned_now(st, st.stage, previous);
        if faces_at(st.surface.area(), edge) > s.max_faces as f64 {
            Next::Stop(StopReason::FaceLimit)
        } else if end.next_over_budget {
            Next::Stop(StopReason::TimeBudget)
        } else {
            Next::Go(edge)
        }
    }
}
