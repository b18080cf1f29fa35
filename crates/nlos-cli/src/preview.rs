//! `nlos preview`: a PNG with the time-summed image beside an x–t slice.

use std::path::{Path, PathBuf};

use nlos_transient::{Quantity, Transient};
use nlos_viz::{Colormap, Extent, Figure, Interp, MarkerAxis, Norm, Panel, Rgb, ScalarGrid, Scale};

use crate::CliError;
use crate::convert::check_gate;

/// Decades below the maximum that the log-scaled slice shows (its floor is `max · 10^-DECADES`).
const DECADES: f64 = 3.0;

/// Arguments of `nlos preview`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    read: crate::choices::ReadArgs,
    /// The capture file (any readable format).
    file: PathBuf,
    /// Where to write the PNG.
    #[arg(long, value_name = "PNG")]
    out: PathBuf,
    /// Zero the bins before this path length (metres) so the direct light off the wall does not drown the
    /// hidden scene; `auto` estimates where the direct light ends, `off` shows everything.
    #[arg(
        long,
        value_name = "METRES|auto|off",
        default_value = "auto",
        value_parser = parse_gate,
        allow_hyphen_values = true
    )]
    gate: Gate,
    /// Show only path lengths before this (metres): the time-summed image then sums the gated window up
    /// to it instead of the whole axis, whose late bins hold mostly background.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    until: Option<f64>,
    /// Sensor grid row of the x–t slice (default: the middle row).
    #[arg(long, value_name = "IY")]
    row: Option<usize>,
}

/// The `--gate` choice.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Gate {
    Auto,
    Off,
    At(f64),
}

fn parse_gate(s: &str) -> Result<Gate, String> {
    match s {
        "auto" => Ok(Gate::Auto),
        "off" | "none" => Ok(Gate::Off),
        _ => s
            .parse::<f64>()
            .ok()
            .filter(|g| g.is_finite())
            .map(Gate::At)
            .ok_or_else(|| format!("`{s}` is not a path length in metres, `auto` or `off`")),
    }
}

fn viz(e: nlos_viz::VizError) -> CliError {
    CliError::Failure(e.to_string())
}

/// Runs `nlos preview`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    if !args.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(CliError::Input(format!("--out {}: the preview is a PNG image; name it .png", args.out.display())));
    }
    crate::check_output(&args.out, "--out")?;
    let t = args.read.read(&args.file)?;
    let (gated, gate_note, gate) = match args.gate {
        Gate::Off => (t, "direct light not gated (--gate off)".to_string(), None),
        Gate::At(g) => {
            check_gate(&t, g)?;
            let note = format!("direct light gated: bins before {g:.3} m of path zeroed (--gate)");
            (t.gate(g).map_err(CliError::input)?, note, Some(g))
        }
        Gate::Auto => {
            let g = t.direct_light_end();
            if g > t.time().t0 {
                let note = format!("direct light gated: bins before {g:.3} m of path zeroed (auto)");
                (t.gate(g).map_err(CliError::input)?, note, Some(g))
            } else {
                (t, "no direct light found to gate (auto)".to_string(), None)
            }
        }
    };
    let (gated, gate_note) = match args.until {
        None => (gated, gate_note),
        Some(u) => {
            let ax = *gated.time();
            let cropped = gated.crop_path(ax.t0, u).map_err(CliError::input)?;
            let end = cropped.time().end();
            (cropped, format!("{gate_note}; path lengths after {end:.3} m not shown (--until)"))
        }
    };
    let name = args.file.file_name().map_or_else(|| args.file.display().to_string(), |n| n.to_string_lossy().into());
    let shown = match gated.sensor_grid() {
        Some((nx, ny)) => {
            let iy = args.row.unwrap_or(ny / 2);
            grid_figure(&gated, &name, (nx, ny), iy, (gate, &gate_note), &args.out)?;
            format!("the time-summed image and the x–t slice of row {iy}")
        }
        None => {
            list_figure(&gated, &name, gate, &gate_note, &args.out)?;
            "the summed histogram".to_string()
        }
    };
    outln!("wrote {}: {shown}; {gate_note}", args.out.display());
    Ok(())
}

/// The physical extents (x, y) of the sensor grid, from its corner points.
fn grid_extents(t: &Transient, nx: usize, ny: usize) -> Result<(Extent, Extent), CliError> {
    let p = &t.scan().sensors().points;
    let (first, last_x, last_y) = (p[0], p[nx - 1], p[nx * (ny - 1)]);
    let ex = Extent::from_centres(f64::from(first.x), f64::from(last_x.x), nx).map_err(viz)?;
    let ey = Extent::from_centres(f64::from(first.y), f64::from(last_y.y), ny).map_err(viz)?;
    Ok((ex, ey))
}

/// The preview of a capture on an `nx × ny` sensor grid: its time-summed image and the x–t slice of grid row
/// `iy`, titled with `name`; `gate` is the path length before which bins were zeroed (marked on the slice) and
/// the note saying how it was chosen.
fn grid_figure(
    t: &Transient,
    name: &str,
    (nx, ny): (usize, usize),
    iy: usize,
    (gate, gate_note): (Option<f64>, &str),
    out: &Path,
) -> Result<(), CliError> {
    let noun = Quantity::of(t.data()).noun();
    let image = t.time_summed_image().map_err(CliError::input)?;
    let slice = t.grid_row_slice(iy).map_err(CliError::input)?;
    let (ex, ey) = grid_extents(t, nx, ny)?;
    let ax = t.time();
    let path = Extent::new(ax.t0, ax.end()).map_err(viz)?;
    let row_y = t.scan().sensors().points[nx * iy].y;
    let legs = if ax.includes_device_legs { " incl. device legs" } else { "" };

    let img_grid = ScalarGrid::new(&image, nx, ny, ex, ey).map_err(viz)?;
    // The slice holds one histogram per column ix: path length runs along its fast axis.
    let slice_grid = ScalarGrid::new(&slice, ax.bins, nx, path, ex).map_err(viz)?;
    let side = 360;
    let (w, h) = if ex.max() - ex.min() >= ey.max() - ey.min() {
        (side, ((side as f64 * (ey.max() - ey.min()) / (ex.max() - ex.min())).round() as usize).max(60))
    } else {
        (((side as f64 * (ex.max() - ex.min()) / (ey.max() - ey.min())).round() as usize).max(60), side)
    };
    let left = Panel::image(img_grid, Norm::auto(&image, Scale::Linear).map_err(viz)?)
        .with_title("time-summed")
        .with_labels("x (m)", "y (m)")
        .with_size(w, h)
        .with_colorbar(noun);
    let mut right = Panel::image(slice_grid, Norm::auto(&slice, Scale::Log { decades: DECADES }).map_err(viz)?)
        .with_title(format!("x-t slice at y = {row_y:.3} m (row {iy})"))
        .with_labels(format!("path length{legs} (m)"), "x (m)")
        .with_size(480, h)
        .with_colormap(Colormap::Magma)
        .with_interp(Interp::Area)
        .with_colorbar(format!("{noun} (log)"));
    if let Some(g) = gate {
        right = right.with_marker(MarkerAxis::X, g, "gate", Rgb::new(80, 200, 255));
    }
    let mut fig = Figure::new(name);
    fig.notes.push(gate_note.to_string());
    let summed = if t.scan().kind() == "multi-laser" { " (summed over laser spots)" } else { "" };
    fig.notes.push(format!("{}{summed}", t.scan().describe()));
    fig.notes.push(format!("{}; slice log-scaled over {DECADES} decades", ax.describe()));
    fig.panels = vec![left, right];
    fig.render().map_err(viz)?.save_png(out).map_err(viz)
}

fn list_figure(t: &Transient, name: &str, gate: Option<f64>, gate_note: &str, out: &Path) -> Result<(), CliError> {
    let ax = t.time();
    let x: Vec<f64> = (0..ax.bins).map(|k| ax.bin_center(k)).collect();
    let y = t.summed_histogram();
    let noun = Quantity::of(t.data()).noun();
    let legs = if ax.includes_device_legs { " incl. device legs" } else { "" };
    let mut panel = Panel::line(&x, &y)
        .map_err(viz)?
        .with_title("summed histogram")
        .with_labels(format!("path length{legs} (m)"), noun)
        .with_size(640, 320);
    if let Some(g) = gate {
        panel = panel.with_marker(MarkerAxis::X, g, "gate", Rgb::RED);
    }
    let mut fig = Figure::new(name);
    fig.notes.push(format!(
        "the sensor points are a list of {}, not a grid: no image, showing the histogram summed over all {} \
         measurements",
        t.scan().sensors().len(),
        t.measurements()
    ));
    fig.notes.push(gate_note.to_string());
    fig.panels = vec![panel];
    fig.render().map_err(viz)?.save_png(out).map_err(viz)
}
