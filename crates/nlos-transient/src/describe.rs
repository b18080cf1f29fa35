//! Words for a capture: one description of its scan, its time axis and its values, used by every message that
//! names them (`nlos info`, `nlos preview`, the start's refusals, the run's notes), so that they agree.
//!
//! - [`Scan::describe`]: which spots are lit and where each is recorded ("one laser spot at (0, 0, 0) m,
//!   recorded at 4096 sensor spots on a 64 × 64 grid").
//! - [`TimeAxis::describe`]: bins, their width in millimetres of path and in picoseconds, and the range. The
//!   picoseconds are converted at [`CAPTURE_SPEED_OF_LIGHT`], the speed the capture formats' own code uses, so
//!   that a bin width given as `--bin-width-ps 32` comes back as 32 ps.
//! - [`Quantity`]: what the values are, in the capture's own vocabulary: `counts` for photon counts,
//!   `intensity` for simulations and scaled data.

use crate::scan::{Layout, PointSet, Scan, ScanPattern};
use crate::time_axis::{CAPTURE_SPEED_OF_LIGHT, TimeAxis};

/// What a capture's values are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Every value is a non-negative integer: photon counts (a SPAD capture, or a simulation with photon noise).
    Counts,
    /// Anything else: a noise-free simulation, counts scaled by a constant, a background subtracted.
    Intensity,
}

impl Quantity {
    /// [`Quantity::Counts`] when every value is a non-negative integer, else [`Quantity::Intensity`].
    pub fn of(data: &[f32]) -> Self {
        if crate::sensor::is_integer_counts(data) { Self::Counts } else { Self::Intensity }
    }

    /// The word for the values: `counts` or `intensity`.
    pub fn noun(self) -> &'static str {
        match self {
            Self::Counts => "counts",
            Self::Intensity => "intensity",
        }
    }
}

/// `x` with at most `decimals` decimals, trailing zeros removed (`0.25`, `-0.1`, `0`).
pub fn short_number(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    if s == "-0" { "0".into() } else { s }
}

impl PointSet {
    /// The spots as a noun phrase with their `role` (`laser`, `sensor`, `scan`): "one laser spot at
    /// (0.1, 0.15, 0) m", "4096 sensor spots on a 64 × 64 grid", "4096 laser spots (a list)".
    pub fn describe(&self, role: &str) -> String {
        let n = self.len();
        if n == 1 {
            let p = self.points[0];
            let c = |v: f32| short_number(f64::from(v), 4);
            return format!("one {role} spot at ({}, {}, {}) m", c(p.x), c(p.y), c(p.z));
        }
        match self.layout {
            Layout::Grid { nx, ny } => format!("{n} {role} spots on a {nx} × {ny} grid"),
            Layout::List => format!("{n} {role} spots (a list)"),
        }
    }
}

impl Scan {
    /// One line: which spots are lit and where each is recorded (one measurement per spot or pair, and for
    /// several lasers with a sensor grid, the product, which it says).
    ///
    /// "confocal: 4096 scan spots on a 64 × 64 grid"; "one laser spot at (0, 0, 0) m, recorded at 4096 sensor
    /// spots on a 64 × 64 grid"; "16 laser spots on a 4 × 4 grid, each recorded at all 1024 sensor spots on a
    /// 32 × 32 grid (16384 measurements)"; "paired: 4096 laser spots (a list), each recorded at its own sensor
    /// spot".
    pub fn describe(&self) -> String {
        match &self.pattern {
            ScanPattern::Confocal(p) => format!("confocal: {}", p.describe("scan")),
            ScanPattern::Exhaustive { lasers, sensors } if lasers.len() == 1 => {
                format!("{}, recorded at {}", lasers.describe("laser"), sensors.describe("sensor"))
            }
            ScanPattern::Exhaustive { lasers, sensors } => format!(
                "{}, each recorded at all {} ({} measurements)",
                lasers.describe("laser"),
                sensors.describe("sensor"),
                self.measurements()
            ),
            ScanPattern::Paired { lasers, .. } => {
                format!("paired: {}, each recorded at its own sensor spot", lasers.describe("laser"))
            }
        }
    }

    /// A few words for the kind of scan, for refusals and titles: `confocal`, `one-laser`, `multi-laser`
    /// (every laser spot with every sensor spot) or `paired`.
    pub fn kind(&self) -> &'static str {
        match &self.pattern {
            ScanPattern::Confocal(_) => "confocal",
            ScanPattern::Exhaustive { lasers, .. } if lasers.len() == 1 => "one-laser",
            ScanPattern::Exhaustive { .. } => "multi-laser",
            ScanPattern::Paired { .. } => "paired",
        }
    }
}

impl TimeAxis {
    /// The bin width in picoseconds at [`CAPTURE_SPEED_OF_LIGHT`] (the capture formats' convention: the
    /// Stanford captures' 1.2 mm bins are 4 ps, a general-NLOS capture read with `--bin-width-ps 32` has 32).
    pub fn bin_width_ps(&self) -> f64 {
        self.bin_width / CAPTURE_SPEED_OF_LIGHT * 1e12
    }

    /// "1200 bins of 1.2 mm (4 ps) of path length, 0 .. 1.44 m", with "device legs included" when they are.
    pub fn describe(&self) -> String {
        format!(
            "{} bins of {} mm ({} ps) of path length, {} .. {} m{}",
            self.bins,
            short_number(self.bin_width * 1e3, 4),
            short_number(self.bin_width_ps(), 3),
            short_number(self.t0, 4),
            short_number(self.end(), 4),
            if self.includes_device_legs { ", device legs included" } else { "" }
        )
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    #[test]
    fn scans_say_what_they_are() {
        let grid = PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid");
        let one = PointSet::list(vec![Vec3::new(-0.1, 0.15, 0.0)]);
        let four = PointSet::wall_grid(4, 4, 0.25, 0.25).expect("grid");
        let confocal = Scan::confocal(grid.clone()).describe();
        assert_eq!(confocal, "confocal: 4096 scan spots on a 64 × 64 grid");
        let single = Scan::exhaustive(one.clone(), grid.clone()).describe();
        assert_eq!(single, "one laser spot at (-0.1, 0.15, 0) m, recorded at 4096 sensor spots on a 64 × 64 grid");
        let many = Scan::exhaustive(four.clone(), grid.clone()).describe();
        assert_eq!(
            many,
            "16 laser spots on a 4 × 4 grid, each recorded at all 4096 sensor spots on a 64 × 64 grid (65536 measurements)"
        );
        let list = PointSet::list(grid.points.clone());
        let paired = Scan::paired(list.clone(), list);
        assert!(paired.describe().starts_with("paired: 4096 laser spots (a list), each recorded at its own"));
        assert!(!paired.describe().contains("exhaustive"));
        let kinds = [
            Scan::confocal(grid.clone()).kind(),
            Scan::exhaustive(one, grid.clone()).kind(),
            Scan::exhaustive(four, grid).kind(),
            paired.kind(),
        ];
        assert_eq!(kinds, ["confocal", "one-laser", "multi-laser", "paired"]);
    }

    #[test]
    fn pattern_names_parse_back() {
        for kind in crate::PatternKind::ALL {
            assert_eq!(kind.name().parse::<crate::PatternKind>().expect("a name"), kind);
            assert_eq!(kind.to_string(), kind.name());
        }
        let e = "pairs".parse::<crate::PatternKind>().expect_err("not a name");
        assert!(e.to_string().contains("\"pairs\" is not \"confocal\", \"exhaustive\" or \"paired\""), "{e}");
        let grid = PointSet::wall_grid(2, 2, 0.1, 0.1).expect("grid");
        assert_eq!(Scan::paired(grid.clone(), grid).pattern.kind(), crate::PatternKind::Paired);
    }

    #[test]
    fn picoseconds_round_trip_as_typed() {
        // 32 ps given on the command line become 9.6 mm at the capture formats' c; they read back as 32 ps.
        let axis = TimeAxis::new(0.0, 32e-12 * CAPTURE_SPEED_OF_LIGHT, 512).expect("axis");
        assert_eq!(short_number(axis.bin_width_ps(), 3), "32");
        let stanford = TimeAxis::new(0.0, 0.0012, 1200).expect("axis");
        assert_eq!(stanford.describe(), "1200 bins of 1.2 mm (4 ps) of path length, 0 .. 1.44 m");
    }

    #[test]
    fn values_are_counts_or_intensity() {
        assert_eq!(Quantity::of(&[0.0, 3.0, 12.0]), Quantity::Counts);
        assert_eq!(Quantity::of(&[0.0, 0.37, 12.0]).noun(), "intensity");
        assert_eq!(Quantity::of(&[-1.0, 2.0]), Quantity::Intensity);
    }
}
