//! Memory at scale: the peak heap of the loop's renderer (construction + one forward + adjoint, the
//! configuration of `loop_cost.rs`) on the LCT start of the shared bunny (`fixtures/bunny_lct_start.obj`)
//! remeshed to about 3k, 20k and 200k faces, at Tsai et al. 2019's setup (confocal 64 × 64, 1200 bins).
//! `cargo bench --bench memory` prints one line per size: faces, peak heap above the mesh alone, and bytes
//! per face. Not a criterion benchmark: it measures bytes, not time; the figures are in
//! docs/performance.md.
#![allow(missing_docs)]
// A counting global allocator is the one way to measure the heap from inside the process; the unsafe is
// the `GlobalAlloc` contract, forwarded unchanged to the system allocator.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use nlos_brdf::Lambertian;
use nlos_render::{Loss, Renderer};

mod common;

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded to `System` with the caller's own layout and pointer; the counters are
// plain atomics and allocate nothing.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded unchanged (the caller upholds `alloc`'s contract).
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = CURRENT.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged (`ptr` came from `alloc` with this layout).
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn main() {
    let (scan, time) = common::seed_setup();
    let brdf = Lambertian::new(1.0f32).expect("valid");
    let measured = vec![0.0f32; scan.measurements() * time.bins];
    for (name, edge, visibility) in common::CASES {
        let (v, f) = common::remeshed_start(edge);
        let before = CURRENT.load(Ordering::Relaxed);
        PEAK.store(before, Ordering::Relaxed);
        let params = common::loop_params(visibility);
        let r = Renderer::new(&v, &f, &scan, &time, params).expect("valid");
        let out = r.loss_and_gradient(&brdf, &measured, Loss::L2, None).expect("ok");
        drop(out);
        drop(r);
        let peak = PEAK.load(Ordering::Relaxed) - before;
        println!(
            "{name}: {} faces, peak heap {:.1} MiB above the inputs ({:.0} bytes per face; the measurement \
             alone is {:.1} MiB)",
            f.len(),
            peak as f64 / (1 << 20) as f64,
            peak as f64 / f.len() as f64,
            (measured.len() * 4) as f64 / (1 << 20) as f64
        );
    }
}
