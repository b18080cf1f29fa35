//! The `nlos` command line.

use clap::Parser;

/// Non-line-of-sight imaging: inspect, convert and preview transient captures.
#[derive(Debug, Parser)]
#[command(name = "nlos", version, about)]
enum Cli {
    /// Print format, geometry and time axis of a capture.
    Info {
        /// The capture file.
        file: std::path::PathBuf,
    },
}

fn main() -> std::process::ExitCode {
    match Cli::parse() {
        Cli::Info { file } => match nlos_transient::read(&file) {
            Ok(t) => {
                println!("{} measurements × {} bins", t.measurements(), t.bins());
                std::process::ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                std::process::ExitCode::FAILURE
            }
        },
    }
}
