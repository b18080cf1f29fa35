//! CPU seconds (user + system, from `/proc/self/stat`) and wall seconds per call of LCT and f-k on a
//! 64 × 64 × 1024 capture and space carving on 64 × 64 × 1200: the benchmark's workloads, measured in a
//! way that a busy machine disturbs less than wall time (Linux only). The speed targets themselves live in
//! `benches/init.rs` (criterion).
//!
//! Run: `cargo run --release -p nlos-init --example init_cpu [calls]` (default 5).

use std::time::Instant;

use nlos_init::{CarveParams, FkParams, Gate, LctParams, carve, fk, lct};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

fn capture(bins: usize) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(64, 64, 0.4, 0.4).expect("grid"));
    let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.0024, bins).expect("axis")).expect("zeros");
    let mut s = 0x2545_f491_4f6c_dd1du64;
    for v in t.data_mut() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        *v = (s >> 40) as f32 / (1u64 << 24) as f32;
    }
    t
}

/// [`capture`] plus the return of a plane at 0.4 m (5× the noise's maximum at path `2r`), so that
/// carving finds first returns and carves (on noise alone it stops early with `InitError::Empty`).
fn capture_with_plane(bins: usize) -> Transient {
    let mut t = capture(bins);
    for m in 0..t.measurements() {
        let p = t.scan().measurement(m).laser;
        let r = (0.16 + (p.x * p.x + p.y * p.y) as f64).sqrt();
        let k = (2.0 * r / 0.0024) as usize;
        if k < bins {
            t.histogram_mut(m)[k] += 5.0;
        }
    }
    t
}

/// User + system CPU seconds of this process so far (clock ticks of 1/100 s).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15 (1-based).
    let rest = stat.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(f64::NAN);
    (tick(11) + tick(12)) / 100.0
}

fn measure(name: &str, calls: usize, mut f: impl FnMut()) {
    f(); // warm-up (thread pool, page cache)
    let (c0, w0) = (cpu_seconds(), Instant::now());
    for _ in 0..calls {
        f();
    }
    let (cpu, wall) = ((cpu_seconds() - c0) / calls as f64, w0.elapsed().as_secs_f64() / calls as f64);
    println!(
        "{name}: {cpu:.3} CPU-s, {wall:.3} s wall per call ({calls} calls, {} threads)",
        rayon::current_num_threads()
    );
}

fn main() {
    let calls = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(5);
    let t = capture(1024);
    measure("LCT 64×64×1024", calls, || {
        lct(&t, &LctParams { gate: Gate::None, ..LctParams::default() }).expect("lct");
    });
    measure("f-k 64×64×1024", calls, || {
        fk(&t, &FkParams { gate: Gate::None, ..FkParams::default() }).expect("fk");
    });
    let t = capture_with_plane(1200);
    measure("carving 64×64×1200", calls, || {
        carve(&t, &CarveParams { gate: Gate::None, ..CarveParams::default() }).expect("carve");
    });
}
