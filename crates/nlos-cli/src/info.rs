//! `nlos info`: what a capture holds.

use std::path::Path;

use nlos_transient::describe::short_number as num;
use nlos_transient::sensor::{BackgroundWindow, count_summary};
use nlos_transient::{Format, Layout, PointSet, Quantity, ScanPattern, Transient};
use serde_json::{Value, json};

use crate::CliError;

/// The depth (or path) of the summed-histogram peak, as far as it is defined for this capture.
struct Peak {
    /// Depth from the wall (confocal only), metres.
    depth: Option<f64>,
    /// Path length of the peak, metres.
    path: Option<f64>,
    /// The direct-light gate used, metres of path; `None` when no direct light was found.
    gate: Option<f64>,
    /// Where the last return ends.
    end: SignalEnd,
    /// How it was obtained, or why it is missing.
    note: String,
}

/// Where the last return of the summed histogram ends, metres of path.
#[derive(Debug, Clone, Copy, PartialEq)]
enum SignalEnd {
    /// The end of the last bin clearly above the background (`Transient::signal_end_path`).
    AboveBackground(f64),
    /// A capture without background: the end of the last bin that is not zero.
    LastNonZero(f64),
    /// Returns or background up to the axis's last bin.
    AxisEnd,
}

impl SignalEnd {
    fn path(self) -> Option<f64> {
        match self {
            Self::AboveBackground(e) | Self::LastNonZero(e) => Some(e),
            Self::AxisEnd => None,
        }
    }
}

fn signal_end(t: &Transient, gate: f64) -> SignalEnd {
    let ax = t.time();
    let end = t.signal_end_path(gate);
    if end < ax.end() {
        return SignalEnd::AboveBackground(end);
    }
    // A capture without background keeps its whole axis for the fit (`signal_end_path`), but a reader still
    // wants to know where its light stops: the end of its last bin that is not zero.
    let h = t.summed_histogram();
    match h.iter().rposition(|&v| v != 0.0) {
        Some(k) if k + 1 < ax.bins => SignalEnd::LastNonZero(ax.bin_start(k + 1)),
        _ => SignalEnd::AxisEnd,
    }
}

fn peak(t: &Transient) -> Peak {
    let mut note = String::new();
    let removed;
    let t = if t.time().includes_device_legs {
        match t.remove_device_legs() {
            Ok(r) => {
                removed = r;
                note.push_str("after removing the device legs; ");
                &removed
            }
            Err(e) => {
                let note = format!("not computed: {e}");
                return Peak { depth: None, path: None, gate: None, end: SignalEnd::AxisEnd, note };
            }
        }
    } else {
        t
    };
    let direct_end = t.direct_light_end();
    // Guard: `direct_light_end` returns the axis's start when it finds no direct light (a simulation).
    let gate = (direct_end > t.time().t0).then_some(direct_end);
    match gate {
        Some(g) => {
            note.push_str(&format!("summed histogram after gating the direct light before {} m of path", num(g, 4)))
        }
        None => note.push_str("summed histogram; no direct light found to gate"),
    }
    let path = t.summed_peak_path(Some(direct_end));
    let depth = t.summed_peak_depth(Some(direct_end)).ok();
    let end = signal_end(t, direct_end);
    match path {
        Ok(p) => Peak { depth, path: Some(p), gate, end, note },
        Err(e) => Peak { depth: None, path: None, gate, end, note: format!("not computed: {e}") },
    }
}

fn points_json(p: &PointSet) -> Value {
    match p.layout {
        Layout::Grid { nx, ny } => json!({ "layout": "grid", "nx": nx, "ny": ny, "points": p.len() }),
        Layout::List => json!({ "layout": "list", "points": p.len() }),
    }
}

/// An `f32` as the `f64` with the same shortest decimal form (`0.2f32` → `0.2`, not `0.20000000298…`).
fn short(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(f64::from(v))
}

/// Runs `nlos info`.
pub(crate) fn run(file: &Path, as_json: bool, read: crate::choices::ReadArgs) -> Result<(), CliError> {
    let t = read.read(file)?;
    let format = detected_format(file)?;
    let scan = t.scan();
    let ax = t.time();
    let all_points: Vec<_> = scan.lasers().points.iter().chain(&scan.sensors().points).copied().collect();
    let (lo, hi) = PointSet::list(all_points).bounds().unwrap_or_default();
    let total: f64 = t.summed_histogram().iter().sum();
    let peak = peak(&t);
    let ps = ax.bin_width_ps();
    let quantity = Quantity::of(t.data());
    let counts = count_summary(&t, BackgroundWindow::Auto);
    let zero_gate = t.zero_gate().map(|z| (z, ax.bin_start(z)));

    if as_json {
        let device = |d: Option<[f32; 3]>| d.map_or(Value::Null, |d| json!(d.map(short)));
        let out = json!({
            "file": file.display().to_string(),
            "format": format.name(),
            "format_description": describe(format),
            "scan": {
                "pattern": scan.pattern_name(),
                "measurements": t.measurements(),
                "lasers": points_json(scan.lasers()),
                "sensors": points_json(scan.sensors()),
                "wall_extent_m": { "min": lo.to_array().map(short), "max": hi.to_array().map(short) },
                "laser_device_m": device(scan.laser_device.map(|d| d.to_array())),
                "sensor_device_m": device(scan.sensor_device.map(|d| d.to_array())),
            },
            "time": {
                "bins": ax.bins,
                "bin_width_m": ax.bin_width,
                "bin_width_ps": ps,
                "t0_m": ax.t0,
                "t_end_m": ax.end(),
                "includes_device_legs": ax.includes_device_legs,
            },
            "zero_gate": zero_gate.map_or(Value::Null, |(z, path)| json!({ "bins": z, "path_m": path })),
            "quantity": quantity.noun(),
            "total_counts": total,
            "photon_counts": match &counts {
                Ok(c) => json!({
                    "background_per_bin": c.background.per_bin,
                    "background_std_error": c.background.std_error,
                    "background_window_bins": [c.background.window.0, c.background.window.1],
                    "background_total": c.background_total,
                    "signal_total": c.signal_total,
                    "signal_per_measurement": c.signal_per_measurement,
                    "integer_counts": c.integer_counts,
                }),
                Err(e) => json!({ "note": format!("not computed: {e}") }),
            },
            "peak": {
                "depth_m": peak.depth,
                "path_m": peak.path,
                "direct_light_gate_m": peak.gate,
                "signal_end_path_m": peak.end.path(),
                "note": peak.note,
            },
        });
        let text = serde_json::to_string_pretty(&out).map_err(|e| CliError::Failure(e.to_string()))?;
        outln!("{text}");
        return Ok(());
    }

    let geometry = match &scan.pattern {
        ScanPattern::Paired { lasers, sensors } => {
            let gap = lasers.points.iter().zip(&sensors.points).map(|(l, s)| l.distance(*s));
            let (lo, hi) = gap.fold((f32::INFINITY, 0.0f32), |(lo, hi), d| (lo.min(d), hi.max(d)));
            let curved = lasers.normals.iter().chain(&sensors.normals).any(|n| *n != lasers.normals[0]);
            format!(
                "{}; laser and sensor spots {}–{} m apart; {}",
                scan.describe(),
                num(f64::from(lo), 3),
                num(f64::from(hi), 3),
                if curved { "a normal per spot (curved wall)" } else { "one wall normal" }
            )
        }
        _ => scan.describe(),
    };
    let device = |d: Option<[f32; 3]>| {
        d.map_or("unknown".to_string(), |[x, y, z]| {
            format!("({}, {}, {}) m", num(f64::from(x), 4), num(f64::from(y), 4), num(f64::from(z), 4))
        })
    };
    outln!("file:          {}", file.display());
    outln!("format:        {} ({})", format.name(), describe(format));
    // The description names the count itself where it is a product (several lasers with a sensor grid).
    let count =
        if scan.kind() == "multi-laser" { String::new() } else { format!("; {} measurements", t.measurements()) };
    outln!("scan:          {geometry}{count}");
    outln!(
        "wall extent:   x {} .. {} m, y {} .. {} m, z {} .. {} m",
        num(f64::from(lo.x), 4),
        num(f64::from(hi.x), 4),
        num(f64::from(lo.y), 4),
        num(f64::from(hi.y), 4),
        num(f64::from(lo.z), 4),
        num(f64::from(hi.z), 4)
    );
    outln!(
        "devices:       laser {}, sensor {}",
        device(scan.laser_device.map(|d| d.to_array())),
        device(scan.sensor_device.map(|d| d.to_array()))
    );
    outln!("time axis:     {}", ax.describe());
    if let Some((z, path)) = zero_gate {
        outln!(
            "gate:          bins 0..{z} (path < {} m) are zero in every measurement: gated before it reached us \
             (the direct light removed); the estimates below use the bins after it",
            num(path, 4)
        );
    }
    let what = if quantity == Quantity::Counts { "photon counts" } else { "intensity: not photon counts" };
    outln!("sum of values: {} ({what})", num(total, 3));
    let label = match quantity {
        Quantity::Counts => "photon counts:",
        Quantity::Intensity => "intensity:",
    };
    match &counts {
        Ok(c) if c.background.per_bin == 0.0 && c.background.std_error == 0.0 => outln!(
            "{label:<15}no background (bins {}..{}, where the returns have not begun or have ended, are zero); signal {}",
            c.background.window.0,
            c.background.window.1,
            num(c.signal_total, 3),
        ),
        Ok(c) => outln!(
            "{label:<15}background {} ± {} per bin (from bins {}..{}); signal {} ({} per measurement){}",
            num(c.background.per_bin, 4),
            num(c.background.std_error, 4),
            c.background.window.0,
            c.background.window.1,
            num(c.signal_total, 1),
            num(c.signal_per_measurement, 2),
            if quantity == Quantity::Counts { "" } else { "; values are not integers: not raw photon counts" }
        ),
        Err(e) => outln!("{label:<15}n/a (background not estimated: {e})"),
    }
    match (peak.depth, peak.path) {
        (Some(d), Some(p)) if !scan.is_confocal() => {
            outln!("peak depth:    {} m straight in front of the scan (path {} m; {})", num(d, 4), num(p, 4), peak.note)
        }
        (Some(d), _) => outln!("peak depth:    {} m ({})", num(d, 4), peak.note),
        (None, Some(p)) => outln!("peak path:     {} m ({}; depth needs a confocal scan)", num(p, 4), peak.note),
        _ => outln!("peak depth:    n/a ({})", peak.note),
    }
    match peak.end {
        SignalEnd::AboveBackground(e) => outln!(
            "signal ends:   {} m of path (depth {} m): later bins hold only background",
            num(e, 4),
            num(t.depth_of_path(e), 4)
        ),
        SignalEnd::LastNonZero(e) => outln!(
            "signal ends:   {} m of path (depth {} m): later bins are zero",
            num(e, 4),
            num(t.depth_of_path(e), 4)
        ),
        SignalEnd::AxisEnd => {
            outln!("signal ends:   at the end of the axis (returns or background up to its last bin)")
        }
    }
    Ok(())
}

/// The format of a readable file; a `.json` sidecar stands for its `.npy`.
pub(crate) fn detected_format(file: &Path) -> Result<Format, CliError> {
    nlos_transient::detect(file)
        .or_else(|e| if file.extension().is_some_and(|x| x == "json") { Ok(Format::NpyJson) } else { Err(e) })
        .map_err(CliError::input)
}

/// A one-line description of a format.
pub(crate) fn describe(f: Format) -> &'static str {
    match f {
        Format::LctMat => "Stanford LCT .mat",
        Format::TsaiMat => "Tsai 2019 .mat",
        Format::ZNlosMat => "Z-NLOS .mat (NeTF)",
        Format::FkMat => "Stanford f-k .mat",
        Format::ZNlos => "Zaragoza Z-NLOS HDF5",
        Format::Tal => "y-tal HDF5_TAL",
        Format::NpyJson => ".npy + .json sidecar",
        Format::Exr => "OpenEXR",
        Format::GeneralNlosMat => "general-NLOS data.mat + setup.mat",
        _ => "other",
    }
}
