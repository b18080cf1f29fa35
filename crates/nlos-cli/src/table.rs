//! `nlos eval`'s default output: the few figures that say whether a reconstruction worked, in words and
//! units, one column per mesh (a run's start beside its result). `--json` prints the full metrics instead.
//!
//! Each row reads its value from the same metrics the JSON serialises, so the two never disagree
//! (`tests/eval.rs` checks the printed figures against the JSON's).

use std::fmt::Write as _;

use nlos_init::FrontViewDetail;
use nlos_mesh::map_metrics::MapMetrics;
use nlos_mesh::metrics::Metrics;

/// How a row prints its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Unit {
    /// A share in [0, 1], printed as a percentage with one decimal.
    Percent,
    /// Metres, printed in millimetres with two decimals.
    Millimetres,
    /// Degrees, one decimal.
    Degrees,
    /// A plain number, three decimals.
    Plain,
}

impl Unit {
    fn format(self, v: Option<f64>) -> String {
        match v.filter(|v| v.is_finite()) {
            None => "–".into(),
            Some(v) => match self {
                Self::Percent => format!("{:.1} %", 100.0 * v),
                Self::Millimetres => format!("{:.2} mm", 1e3 * v),
                Self::Degrees => format!("{v:.1}°"),
                Self::Plain => format!("{v:.3}"),
            },
        }
    }
}

/// A table of figures: a title line, named columns, and rows of one value per column.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Table {
    title: String,
    columns: Vec<String>,
    rows: Vec<(String, Unit, Vec<Option<f64>>)>,
}

impl Table {
    fn new(title: String, columns: Vec<String>) -> Self {
        Self { title, columns, rows: Vec::new() }
    }

    fn row(&mut self, label: impl Into<String>, unit: Unit, values: Vec<Option<f64>>) {
        self.rows.push((label.into(), unit, values));
    }

    /// The two judged figures (docs/accuracy.md): coverage within `threshold` metres and the depth error inside
    /// the silhouette, one `(coverage, depth)` per column.
    fn judged(&mut self, threshold: f64, values: Vec<(f64, Option<f64>)>) {
        let label = format!("coverage within {:.0} mm", threshold * 1e3);
        self.row(label, Unit::Percent, values.iter().map(|v| Some(v.0)).collect());
        self.row("depth error inside the silhouette", Unit::Millimetres, values.iter().map(|v| v.1).collect());
    }

    /// The metrics of `nlos eval MESH --gt GT` (`metrics`: one per column, named in `columns`).
    pub(crate) fn meshes(columns: Vec<String>, metrics: &[Metrics], truth: &str) -> Self {
        let first = metrics.first();
        let grid = first.map_or(0, |m| m.grid);
        let mut t = Self::new(format!("against {truth} (+z rays from a {grid} × {grid} grid over the wall)"), columns);
        let judged = metrics.iter().map(|m| (m.coverage_within, m.depth_error_mean_interior));
        t.judged(first.map_or(0.005, |m| m.coverage_threshold), judged.collect());
        t.row("Chamfer distance", Unit::Millimetres, metrics.iter().map(|m| Some(m.chamfer)).collect());
        t.row("normal error", Unit::Degrees, metrics.iter().map(|m| Some(m.normal_error_mean_deg)).collect());
        t
    }

    /// The metrics of `nlos eval MESH --gt-depth DEPTH` against ground-truth maps.
    pub(crate) fn maps(columns: Vec<String>, metrics: &[MapMetrics], truth: &str) -> Self {
        let first = metrics.first();
        let (w, h) = first.map_or((0, 0), |m| (m.width, m.height));
        let mut t = Self::new(format!("against the maps of {truth} ({w} × {h} pixels)"), columns);
        let judged = metrics.iter().map(|m| (m.coverage_within, m.depth_error_mean_interior));
        t.judged(first.map_or(0.005, |m| m.coverage_threshold), judged.collect());
        t.row("depth error over the mask", Unit::Millimetres, metrics.iter().map(|m| m.depth_error_mean).collect());
        if metrics.iter().any(|m| m.normal_error_mean_deg.is_some()) {
            t.row("normal error", Unit::Degrees, metrics.iter().map(|m| m.normal_error_mean_deg).collect());
        }
        t
    }

    /// The front-view detail of `nlos eval MESH --front-view CAPTURE` (`weighting`: the reflectance its volume
    /// is weighted for, and where that choice came from).
    pub(crate) fn front_view(columns: Vec<String>, detail: &[FrontViewDetail], capture: &str, weighting: &str) -> Self {
        let mut t = Self::new(format!("front view against the volume of {capture} ({weighting})"), columns);
        t.row("Pearson's r of the front views", Unit::Plain, detail.iter().map(|d| Some(d.r)).collect());
        t.row("the volume's bright pixels covered", Unit::Percent, detail.iter().map(|d| Some(d.coverage)).collect());
        t
    }
}

impl std::fmt::Display for Table {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let cells: Vec<Vec<String>> =
            self.rows.iter().map(|(_, unit, values)| values.iter().map(|&v| unit.format(v)).collect()).collect();
        let label_width = self.rows.iter().map(|(l, _, _)| l.chars().count()).max().unwrap_or(0);
        let widths: Vec<usize> = (0..self.columns.len())
            .map(|c| {
                let head = self.columns[c].chars().count();
                cells.iter().filter_map(|r| r.get(c)).map(|s| s.chars().count()).fold(head, usize::max)
            })
            .collect();
        let mut out = String::new();
        let _ = writeln!(out, "{}", self.title);
        let _ = write!(out, "{:label_width$}", "");
        for (name, w) in self.columns.iter().zip(&widths) {
            let _ = write!(out, "  {name:>w$}");
        }
        for ((label, _, _), row) in self.rows.iter().zip(&cells) {
            let _ = write!(out, "\n{label:<label_width$}");
            for (cell, w) in row.iter().zip(&widths) {
                let _ = write!(out, "  {cell:>w$}");
            }
        }
        f.write_str(&out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aligns_columns_and_prints_units() {
        let mut t = Table::new("title".into(), vec!["start".into(), "result".into()]);
        t.row("coverage within 5 mm", Unit::Percent, vec![Some(0.615), Some(0.8447)]);
        t.row("depth", Unit::Millimetres, vec![Some(0.00418), None]);
        t.row("normal error", Unit::Degrees, vec![Some(35.54), Some(f64::NAN)]);
        let text = t.to_string();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "title");
        assert!(lines[2].ends_with("61.5 %  84.5 %"), "{text}");
        assert!(lines[3].ends_with("4.18 mm       –"), "{text}");
        assert!(lines[4].ends_with("35.5°       –"), "{text}");
        // Every line of the body is as wide as the header: the columns line up.
        let width = lines[1].chars().count();
        assert!(lines[2..].iter().all(|l| l.chars().count() == width), "{text}");
    }
}
