//! The coarse-to-fine schedule ([`Schedule`]): the stages' target edge lengths and summed bins, the sizing to a
//! capture and to its start, and the run's budget of reference seconds — a cost predicted from face counts in
//! seconds of the reference machine (2 cores), not a wall-clock limit, so that a run stays a deterministic
//! function of its inputs on every machine. What the budget decides during a run is the planner's
//! ([`crate::Plan`]).

/// How many times `max_blocks_per_stage` a run started from the phasor field may take ([`Schedule::for_start`]).
pub const PHASOR_START_BLOCKS: u32 = 2;
/// The first stage's target edge length in scan spacings at least ([`Schedule::sized_to`]).
pub const EDGE_PER_SPACING: f64 = 0.9;
/// The first stage's target edge length in bins (of path) at least ([`Schedule::sized_to`]).
pub const EDGE_PER_BIN: f64 = 1.5;
/// Faces per measurement at most ([`Schedule::sized_to`]; 61,440 for 64 × 64, above the default cap).
pub const FACES_PER_MEASUREMENT: usize = 15;

/// The coarse-to-fine schedule (Tsai et al. 2019, Sec. 5: target edge length `L = 0.5/res`, `res × 1.5`
/// per stage from 64). Stage k has resolution `res_k = initial_resolution · growthᵏ` and target edge
/// length `L_k = extent / res_k`. Each stage runs blocks (a shape block of `shape_iterations` Adam steps,
/// then a reflectance block of `reflectance_iterations` steps) until the loss falls by less than `rel_tol`
/// (relative) over a block or `max_blocks_per_stage` blocks ran; the run stops after `max_stages` stages,
/// or when the next stage would exceed `max_faces` faces. Stages after the first are planned at their start
/// for the budget of reference seconds ([`crate::Plan::planned_edge`]): when the stages left would not fit
/// `reference_seconds` whole at the schedule's edges, they refine by less, so that every stage runs all its
/// blocks; only when not even that fits do blocks stop at the budget ([`crate::Plan::block_fits`]).
///
/// Coarse to fine in time as well: a stage sums consecutive bins of the capture while the summed bin stays
/// within `rebin_fraction` of its target edge length, in path length ([`Schedule::rebin`]). A face of the
/// first stage (10.4 mm edges by default) spans about fifteen 1.2 mm bins of Tsai et al. 2019's setup, so its shape is
/// fitted as well from 4.8 mm bins, and one forward + adjoint then costs about a fifth (the splat rule's
/// sub-triangle level follows the bin width); at the default fraction 0.5 Tsai et al. 2019's stages sum 4, 2 and 1
/// bins. The sensor fit ([`crate::SensorFit`]) and per-bin weights are defined on the capture's own bins:
/// with either, every stage runs at the capture's resolution.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Schedule {
    /// Resolution of the first stage (default 48; Tsai et al. 2019's is 64).
    pub initial_resolution: f64,
    /// Resolution factor between stages (default 1.5, Tsai et al. 2019's).
    pub growth: f64,
    /// Numerator of `L = extent/res` in metres (default 0.5, Tsai et al. 2019's; about the width of the scene).
    pub extent: f64,
    /// Number of stages (default 3: res 48, 72, 108, target edges 10.4, 6.9 and 4.6 mm; Tsai et al. 2019's schedule
    /// is 4 stages from 64). A step's cost grows with the face count (docs/performance.md), so Tsai et al. 2019's
    /// fourth stage (about 27k faces at the bunny's size) alone would cost more than this whole schedule.
    pub max_stages: u32,
    /// Face limit: a stage whose estimated face count (`area / (√3/4 · L²)`) exceeds it is not started
    /// (default 60,000).
    pub max_faces: usize,
    /// Blocks per stage at most (default 4).
    pub max_blocks_per_stage: u32,
    /// Adam steps on the vertices per shape block (default 20).
    pub shape_iterations: u32,
    /// Adam steps on θ per reflectance block (default 5; 0 disables reflectance steps).
    pub reflectance_iterations: u32,
    /// Relative-decrease stopping rule: a stage ends when a block lowers the loss by less than this
    /// fraction (default 1e-3).
    pub rel_tol: f64,
    /// Largest summed bin of a stage as a fraction of its target edge length, both in metres (default 0.5;
    /// 0: every stage at the capture's resolution).
    pub rebin_fraction: f64,
    /// Seconds of the reference machine (2 cores) the blocks may take (default 480: ten minutes less what the
    /// start, the residual patches and the stage changes take; 0: no budget). Each stage after the first is
    /// planned so that it and the stages after it fit whole ([`crate::Plan::planned_edge`]); a block is started
    /// only when the blocks so far and its own predicted time fit ([`crate::Plan::block_fits`]). Predicted from
    /// face counts, not timed, so the run stays a deterministic function of its inputs on every machine.
    pub reference_seconds: f64,
}

impl Default for Schedule {
    fn default() -> Self {
        Self {
            initial_resolution: 48.0,
            growth: 1.5,
            extent: 0.5,
            max_stages: 3,
            max_faces: 60_000,
            max_blocks_per_stage: 4,
            shape_iterations: 20,
            reflectance_iterations: 5,
            rel_tol: 1e-3,
            rebin_fraction: 0.5,
            reference_seconds: 480.0,
        }
    }
}

impl Schedule {
    /// Bins of `bin_width` metres (of path length) summed in stage `stage`: the largest `k` with
    /// `k · bin_width ≤ rebin_fraction · L_stage`, at least 1.
    pub fn rebin(&self, stage: u32, bin_width: f64) -> usize {
        self.rebin_at(self.target_edge_length(stage), bin_width)
    }

    /// Bins of `bin_width` metres summed by a stage of target edge length `edge` metres (see
    /// [`Schedule::rebin`]).
    pub fn rebin_at(&self, edge: f64, bin_width: f64) -> usize {
        let k = (self.rebin_fraction * edge / bin_width).floor();
        // NaN or below 1 (a zero fraction, bins wider than the limit) sum nothing; `as` saturates huge values.
        if k >= 1.0 { k as usize } else { 1 }
    }

    /// Target edge length of stage `stage` (metres).
    pub fn target_edge_length(&self, stage: u32) -> f64 {
        self.extent / (self.initial_resolution * self.growth.powi(stage.min(i32::MAX as u32) as i32))
    }

    /// This schedule sized to a capture with scan spacing `spacing` and bins of `bin_width` (metres of
    /// path), `measurements` histograms: the first stage's target edge is at least [`EDGE_PER_SPACING`]
    /// spacings and [`EDGE_PER_BIN`] bins (`extent` raised; later stages follow by `growth`), and no stage
    /// has more than [`FACES_PER_MEASUREMENT`] faces per measurement. Why: detail finer than the scan's
    /// spacing or the bins cannot be told apart by the data, and only costs time; Tsai et al. 2019's 64 × 64 scan
    /// over 0.5 m (7.9 mm, its 10.4 mm first edge is 1.3 spacings) and every shared capture (at most
    /// 11.1 mm, 4 mm bins, 4,096 measurements) keep the schedule as set, while a 32 × 32 scan over 1 m
    /// starts at 28 mm and an 8 × 8 one at 11 cm. Returns the sentence saying what changed, if anything.
    pub fn sized_to(&self, spacing: f64, bin_width: f64, measurements: usize) -> (Schedule, Option<String>) {
        let mut out = *self;
        let mut said = Vec::new();
        let edge = self.target_edge_length(0);
        let (by_spacing, by_bin) = (EDGE_PER_SPACING * spacing, EDGE_PER_BIN * bin_width);
        let floor = by_spacing.max(by_bin);
        if floor.is_finite() && floor > edge {
            out.extent = floor * self.initial_resolution;
            let why = if by_spacing >= by_bin {
                format!("{EDGE_PER_SPACING} × the scan's {:.1} mm spacing", 1e3 * spacing)
            } else {
                format!("{EDGE_PER_BIN} × its {:.1} mm bins", 1e3 * bin_width)
            };
            said.push(format!(
                "first edge length {:.1} mm ({why}; schedule.extent {:.3} m)",
                1e3 * out.target_edge_length(0),
                out.extent
            ));
        }
        let cap = FACES_PER_MEASUREMENT.saturating_mul(measurements);
        if cap < out.max_faces {
            out.max_faces = cap;
            said.push(format!("at most {cap} faces ({FACES_PER_MEASUREMENT} per measurement)"));
        }
        let note = (!said.is_empty()).then(|| format!("schedule sized to the capture: {}", said.join("; ")));
        (out, note)
    }

    /// This schedule for a run whose start is the phasor field's (`phasor`: scans that are not confocal
    /// grids): [`PHASOR_START_BLOCKS`] times the blocks per stage; the relative-decrease rule and the time
    /// budget still end a stage that stops improving or does not fit. Why: that start lies farther from the
    /// surface than the LCT's (the shared bunny seen by one laser and 64 × 64 sensors: 47.5 % of the truth
    /// within 5 mm and 7.8 mm inside, against the LCT's 66.7 % and 2.2 mm on the confocal capture), and its
    /// early stages were still gaining when their fourth block ended: 8 blocks a stage took that run from
    /// 58.0 % and 3.2 mm to 64.1 % and 1.7 mm. Returns the sentence saying what changed, if anything.
    pub fn for_start(&self, phasor: bool) -> (Schedule, Option<String>) {
        if !phasor {
            return (*self, None);
        }
        let blocks = self.max_blocks_per_stage.saturating_mul(PHASOR_START_BLOCKS);
        let note = format!(
            "schedule for a phasor-field start: at most {blocks} blocks per stage ({PHASOR_START_BLOCKS} × \
             schedule.max_blocks_per_stage; the start lies farther from the surface than the LCT's)"
        );
        (Schedule { max_blocks_per_stage: blocks, ..*self }, Some(note))
    }
}

/// Faces of a mesh of `area` m² remeshed to edges of `edge` m (equilateral triangles).
pub fn faces_at(area: f64, edge: f64) -> f64 {
    area / (3f64.sqrt() / 4.0 * edge * edge)
}
