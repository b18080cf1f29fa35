//! The `nlos` command line: inspect, convert, preview and render transient captures, reconstruct hidden
//! surfaces, evaluate and report. The binary is `nlos`; [`run`] is the same command as a function (for
//! tests and tools that drive the command in-process).
//!
//! Every subcommand composes calls into the library crates ([`nlos_transient`] for data and operations,
//! [`nlos_viz`] for figures); the command line itself only parses arguments and prints.
//!
//! Exit codes: 0 on success, 2 for bad input (an unreadable, truncated or malformed file, an argument out
//! of range, a usage error), 1 for other failures (an output that cannot be written, a figure that cannot
//! be encoded). Errors are printed to stderr as `error: <message>`.

/// `println!` that ends the command quietly when stdout is a closed pipe (`nlos info FILE | head -1`); inside
/// a function returning `Result<_, CliError>`.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::write_stdout(format_args!($($arg)*))?
    };
}

mod benchmark;
mod choices;
mod convert;
mod eval;
mod info;
mod init;
mod preview;
mod progress;
mod reconstruct;
mod render;
mod report;
mod table;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use nlos_transient::TransientError;

/// Non-line-of-sight imaging: inspect, convert, preview and simulate transient captures, reconstruct the
/// hidden surface, evaluate and report.
#[derive(Debug, Parser)]
#[command(
    name = "nlos",
    version,
    about,
    after_help = "Exit status: 0 on success; 2 for bad input (an unreadable, truncated or malformed file, an \
                  argument out of range, a usage error); 1 for other failures (an output that cannot be written, a \
                  reconstruction that kept almost no surface: its files are written, and the message says why)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the format, scan geometry, time axis, values (photon counts or intensity), background and peak
    /// depth of a capture.
    Info {
        /// The capture file (any readable format, detected from its content).
        file: PathBuf,
        /// Print machine-readable JSON instead of text.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        read: choices::ReadArgs,
    },
    /// Convert a capture to another format, optionally transforming it on the way.
    ///
    /// Transformations apply in this order: --remove-legs, --crop-bins, --gate, --rebin, --subsample.
    Convert(convert::Args),
    /// Draw a PNG preview: the time-summed image beside an x–t slice (log scale), axes in metres.
    ///
    /// The direct light off the wall is gated out by default (`--gate auto`) so that the hidden scene is
    /// visible. Scans whose sensor points are a list, not a grid, get the summed histogram instead.
    Preview(preview::Args),
    /// Metrics of a reconstructed mesh, or of a run's start and result side by side, against the ground truth:
    /// a table of coverage within 5 mm, depth error inside the silhouette, Chamfer distance and normal error;
    /// with --json every metric as one JSON line per mesh (coverage, depth error mean, median, RMS and inside
    /// from a +z ray grid over the wall, Chamfer and Hausdorff distances, normal angular error over all
    /// vertices and those within 1 cm of the truth); or against ground-truth depth and normal maps
    /// (--gt-depth, --gt-normal), or the capture's volume (--front-view).
    Eval(eval::Args),
    /// Volumetric reconstruction (LCT, f-k, phasor field, FBP or space carving; `auto` chooses) → initial
    /// surface mesh, with a front-view/depth PNG.
    Init(init::Args),
    /// Reconstruct the hidden surface: initial surface (LCT, f-k, phasor field, space carving or a mesh; `auto`
    /// chooses) → optimised mesh in --out.
    Reconstruct(Box<reconstruct::Args>),
    /// Simulate the measurements of a mesh (box kernel), optionally as SPAD photon counts.
    Render(render::Args),
    /// (Re)write the report of a reconstruction run: figures and `report.html` in the run directory.
    Report(report::Args),
    /// The shared benchmark: every Z-NLOS capture of a folder with ground-truth depth (and normal) maps
    /// beside it, reconstructed by LCT, f-k and the surface fit, scored against the maps as one table.
    Benchmark(benchmark::Args),
}

/// A failure, with the exit code it maps to.
#[derive(Debug)]
pub(crate) enum CliError {
    /// Bad input: exit code 2.
    Input(String),
    /// Anything else: exit code 1.
    Failure(String),
    /// Standard output was closed by its reader (a pipe into `head`): the command ends quietly, exit code 0.
    Closed,
}

/// Writes one line to standard output ([`outln!`]).
pub(crate) fn write_stdout(args: std::fmt::Arguments<'_>) -> Result<(), CliError> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_fmt(args).and_then(|()| out.write_all(b"\n")) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(CliError::Closed),
        Err(e) => Err(CliError::Failure(format!("cannot write to standard output: {e}"))),
    }
}

/// Checks, before any work, that an output can be written at `path` (given with `flag`): its directory
/// exists and the path is not a directory (exit code 1, as for any output that cannot be written).
pub(crate) fn check_output(path: &Path, flag: &str) -> Result<(), CliError> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(CliError::Failure(format!(
            "{flag} {}: the directory {} does not exist; create it first",
            path.display(),
            dir.display()
        )));
    }
    if path.is_dir() {
        return Err(CliError::Failure(format!("{flag} {}: is a directory; give a file name", path.display())));
    }
    Ok(())
}

impl CliError {
    /// An error from reading or transforming the input: bad input (exit 2).
    pub(crate) fn input(e: TransientError) -> Self {
        CliError::Input(e.to_string())
    }

    /// An error from writing an output: exit 2 when the transient cannot be represented in the format
    /// (the user's choice), 1 otherwise.
    pub(crate) fn output(e: TransientError) -> Self {
        match e {
            TransientError::CannotWrite { .. } | TransientError::InvalidArgument { .. } => {
                CliError::Input(e.to_string())
            }
            other => CliError::Failure(other.to_string()),
        }
    }
}

/// Runs the `nlos` command with `args` (the first is the program name, as in `std::env::args_os`): parses,
/// runs the subcommand, prints errors as `error: <message>` and returns the exit code.
pub fn run<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version are successes; usage errors are bad input (exit 2), as clap's own exit.
            let _ = e.print();
            return if e.use_stderr() { ExitCode::from(2) } else { ExitCode::SUCCESS };
        }
    };
    let result = match cli.command {
        Command::Info { file, json, read } => info::run(&file, json, read),
        Command::Convert(args) => convert::run(&args),
        Command::Preview(args) => preview::run(&args),
        Command::Eval(args) => eval::run(&args),
        Command::Init(args) => init::run(&args),
        Command::Reconstruct(args) => reconstruct::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Report(args) => report::run(&args),
        Command::Benchmark(args) => benchmark::run(&args),
    };
    match result {
        Ok(()) | Err(CliError::Closed) => ExitCode::SUCCESS,
        Err(CliError::Input(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
        Err(CliError::Failure(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(1)
        }
    }
}
