//! Fuzz target: HDF5 detection and the HDF5-based readers (y-tal HDF5_TAL, Z-NLOS, Stanford f-k and LCT
//! in MAT v7.3) plus `read_dataset_f64_bytes` on arbitrary bytes. Any panic that escapes is a bug; every
//! input must give `Ok` or a typed error.
//!
//! The reader guards its HDF5 dependency (`hdf5-pure`) with `catch_unwind` and turns its panics into
//! `TransientError::Malformed`. libFuzzer's panic hook would abort on those caught panics too, so this
//! target replaces the hook with one that only counts them: a panic outside the guard still unwinds out
//! of the target, and libfuzzer-sys aborts on it. With `NLOS_FUZZ_SAVE_PANICS=DIR` set, the first inputs
//! that panic inside the dependency are saved to `DIR` (to turn into regression tests).
#![no_main]

use std::cell::RefCell;
use std::path::Path;
use std::sync::Once;
use std::sync::atomic::{AtomicUsize, Ordering};

use libfuzzer_sys::fuzz_target;
use nlos_transient::formats::{Format, detect_bytes, hdf5, read_bytes_as};

static HOOK: Once = Once::new();
static DEPENDENCY_PANICS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static CURRENT: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

fuzz_target!(|data: &[u8]| {
    HOOK.call_once(|| {
        std::panic::set_hook(Box::new(|info| {
            let n = DEPENDENCY_PANICS.fetch_add(1, Ordering::Relaxed);
            if n < 5 || n.is_power_of_two() {
                eprintln!("panic #{n} (caught by the reader's guard, or fatal if it escapes): {info}");
            }
            if let Ok(dir) = std::env::var("NLOS_FUZZ_SAVE_PANICS") {
                if n < 20 {
                    let _ =
                        CURRENT.with(|c| std::fs::write(Path::new(&dir).join(format!("panic-{n}.bin")), &*c.borrow()));
                }
            }
        }));
    });
    // Keep the fuzzer inside the HDF5 parser: inputs without a signature get the HDF5 one.
    let mut owned;
    let bytes = if data.starts_with(b"\x89HDF\r\n\x1a\n") || data.starts_with(b"MATLAB") {
        data
    } else {
        owned = b"\x89HDF\r\n\x1a\n".to_vec();
        owned.extend_from_slice(data);
        &owned
    };
    CURRENT.with(|c| *c.borrow_mut() = bytes.to_vec());
    let file = Path::new("<memory>");
    let _ = detect_bytes(bytes, file);
    for format in [Format::Tal, Format::ZNlos, Format::FkMat, Format::LctMat] {
        let _ = read_bytes_as(bytes, format, file);
    }
    let _ = hdf5::read_dataset_f64_bytes(bytes, "counts", file);
});
