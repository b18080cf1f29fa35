//! The `nlos` binary: [`nlos_cli::run`] on the process's arguments.

use std::process::ExitCode;

fn main() -> ExitCode {
    // SAFETY: the first statement of `main`: no other thread exists yet to read the environment.
    #[allow(unsafe_code)]
    unsafe {
        nlos_render::silence_display_probe();
    }
    nlos_cli::run(std::env::args_os())
}
