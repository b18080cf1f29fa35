//! `nlos convert`: any readable format to any writable one, with optional transformations.

use std::path::PathBuf;

use nlos_transient::{Format, Transient};

use crate::CliError;

/// Arguments of `nlos convert`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    read: crate::choices::ReadArgs,
    /// The input capture (any readable format, detected from its content).
    input: PathBuf,
    /// The output file.
    output: PathBuf,
    /// Output format: tal, npy or exr. Default: from OUTPUT's extension (.hdf5/.h5 → tal, .npy → npy,
    /// .exr → exr).
    #[arg(long, value_name = "NAME")]
    format: Option<String>,
    /// 1. Remove the device→wall and wall→device legs from the times (needs the device positions).
    #[arg(long)]
    remove_legs: bool,
    /// 2. Keep bins A..B (B exclusive), e.g. `600..1400`.
    #[arg(long, value_name = "A..B", value_parser = parse_range)]
    crop_bins: Option<(usize, usize)>,
    /// 3. Zero every bin that begins before this path length (metres), e.g. to gate out direct light.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    gate: Option<f64>,
    /// 4. Sum every K consecutive bins into one.
    #[arg(long, value_name = "K")]
    rebin: Option<usize>,
    /// 5. Keep every K-th scan point along x and y of a grid scan.
    #[arg(long, value_name = "K")]
    subsample: Option<usize>,
}

/// Parses `A..B`.
fn parse_range(s: &str) -> Result<(usize, usize), String> {
    let (a, b) = s.split_once("..").ok_or_else(|| format!("`{s}` is not a bin range A..B"))?;
    let parse = |x: &str| x.trim().parse::<usize>().map_err(|e| format!("`{x}` in `{s}`: {e}"));
    Ok((parse(a)?, parse(b)?))
}

/// The output format: `--format`, else from the extension.
fn output_format(args: &Args) -> Result<Format, CliError> {
    let writable = || Format::ALL.iter().filter(|f| f.can_write()).map(|f| f.name()).collect::<Vec<_>>().join(", ");
    match &args.format {
        Some(name) => {
            let f = Format::from_name(name)
                .ok_or_else(|| CliError::Input(format!("unknown format `{name}`; writable formats: {}", writable())))?;
            if !f.can_write() {
                return Err(CliError::Input(format!("format `{name}` is read-only; writable formats: {}", writable())));
            }
            Ok(f)
        }
        None => Format::for_writing_extension(&args.output).ok_or_else(|| {
            CliError::Input(format!(
                "{}: cannot tell the output format from the extension; use .hdf5, .npy or .exr, or pass \
                 --format ({})",
                args.output.display(),
                writable()
            ))
        }),
    }
}

/// Applies the transformations in their documented order.
pub(crate) fn transform(mut t: Transient, args: &Args) -> Result<Transient, CliError> {
    if args.remove_legs {
        t = t.remove_device_legs().map_err(CliError::input)?;
    }
    if let Some((a, b)) = args.crop_bins {
        t = t.crop_bins(a, b).map_err(CliError::input)?;
    }
    if let Some(g) = args.gate {
        check_gate(&t, g)?;
        t = t.gate(g).map_err(CliError::input)?;
    }
    if let Some(k) = args.rebin {
        t = t.rebin(k).map_err(CliError::input)?;
    }
    if let Some(k) = args.subsample {
        t = t.subsample(k, k).map_err(CliError::input)?;
    }
    Ok(t)
}

/// Refuses a gate that is not finite or that would zero the whole axis.
pub(crate) fn check_gate(t: &Transient, g: f64) -> Result<(), CliError> {
    let ax = t.time();
    if !g.is_finite() {
        return Err(CliError::Input(format!("gate {g} m is not a finite path length")));
    }
    if g > ax.bin_start(ax.bins.saturating_sub(1)) {
        return Err(CliError::Input(format!(
            "gate {g} m would zero every bin: the last bin begins at {:.4} m (the axis spans {:.4} .. {:.4} m)",
            ax.bin_start(ax.bins.saturating_sub(1)),
            ax.t0,
            ax.end()
        )));
    }
    Ok(())
}

/// Runs `nlos convert`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    let format = output_format(args)?;
    crate::check_output(&args.output, "output")?;
    let t = args.read.read(&args.input)?;
    let t = transform(t, args)?;
    nlos_transient::write(&t, &args.output, format).map_err(CliError::output)?;
    eprintln!(
        "wrote {} ({}, {} measurements × {} bins)",
        args.output.display(),
        format.name(),
        t.measurements(),
        t.bins()
    );
    Ok(())
}
