//! The `nlos` binary: [`nlos_cli::run`] on the process's arguments.

use std::process::ExitCode;

fn main() -> ExitCode {
    nlos_cli::run(std::env::args_os())
}
