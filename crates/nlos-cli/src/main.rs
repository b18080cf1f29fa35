//! The `nlos` binary: [`nlos_cli::run`] on the process's arguments.

use std::process::ExitCode;

fn main() -> ExitCode {
    // SAFETY: the first statement of `main`: no other thread exists yet to read the environment.
    #[allow(unsafe_code)]
    unsafe {
        nlos_render::silence_display_probe();
    }
    keep_large_buffers_in_the_heap();
    nlos_cli::run(std::env::args_os())
}

/// The reconstruction loop allocates and frees buffers of a histogram per measurement on every shape step
/// (at 4,096 measurements × 1,200 bins, 20 MB each: the rendering, the loss's adjoint, the padded and
/// differenced adjoint rows). glibc serves allocations from 128 KiB up by `mmap` and gives them back by
/// `munmap`, so each step faulted in and zeroed about 120 MB of fresh pages: 2.8 M page faults and 6 s of
/// system time in the bunny's default run (docs/performance.md). Served from the heap, and the heap's top
/// kept rather than trimmed, a freed buffer's pages are reused by the next step's.
///
/// 32 MiB is the largest threshold `mallopt` accepts on 64-bit glibc (half its arena heap size); larger
/// buffers are still mapped and unmapped. The cost is a resident size that stays at its peak.
fn keep_large_buffers_in_the_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only sets allocator parameters; it is called before any other thread exists.
    #[allow(unsafe_code)]
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}
