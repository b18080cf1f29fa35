//! The loop's configuration shared by `loop_cost.rs` (time), `memory.rs` (heap) and `remesh.rs` (its
//! remeshing): Tsai et al. 2019's setup, the LCT start of the shared bunny (`fixtures/bunny_lct_start.obj`)
//! remeshed as the optimiser's stages do, and the renderer settings of `nlos_optim::ReconstructParams::default()`.
#![allow(dead_code)]

use glam::Vec3;
use nlos_mesh::remeshing::{BoundaryMode, RemeshParams, uniform_remeshing};
use nlos_render::{Kernel, RenderParams, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// The sizes measured: name, target edge length (m), visibility (off at 200k faces: its cache takes
/// minutes to build).
pub const CASES: [(&str, f32, Visibility); 3] = [
    ("stage0_3k", 0.5 / 64.0, Visibility::Cached { level: 1 }),
    ("remeshed_20k", 0.0031, Visibility::Cached { level: 1 }),
    ("remeshed_200k", 0.00099, Visibility::Off),
];

/// Confocal 64 × 64 over [−0.25, 0.25]² m, 1200 bins of 1.2 mm.
pub fn seed_setup() -> (Scan, TimeAxis) {
    (
        Scan::confocal(PointSet::wall_grid(64, 64, 0.25, 0.25).expect("grid")),
        TimeAxis::new(0.0, 0.0012, 1200).expect("axis"),
    )
}

/// Tsai et al. 2019's time axis as a stage with target edge length `edge` fits it: bins summed by
/// `nlos_optim::Schedule::rebin_at` at the default `rebin_fraction` (coarse to fine in time; 3 bins at 7.8 mm,
/// 1 at 3.1 mm and below).
pub fn stage_axis(edge: f32) -> TimeAxis {
    let (_, full) = seed_setup();
    let k = nlos_optim::Schedule::default().rebin_at(f64::from(edge), full.bin_width);
    TimeAxis::new(full.t0, full.bin_width * k as f64, full.bins / k).expect("axis")
}

/// The loop's renderer settings with `visibility`.
pub fn loop_params(visibility: Visibility) -> RenderParams {
    RenderParams { kernel: Kernel::Tent, sampling: Sampling::Splat(SplatRule::default()), visibility, two_sided: false }
}

/// The committed start, remeshed isotropically to edge length `edge`: positions and triangles.
pub fn remeshed_start(edge: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/bunny_lct_start.obj");
    let mut mesh = nlos_mesh::io::load(path).expect("fixtures/bunny_lct_start.obj (`cargo xtask fixtures`)");
    let rp = RemeshParams { boundary: BoundaryMode::Remesh, ..RemeshParams::fast() };
    uniform_remeshing(&mut mesh, edge, &rp).expect("remesh");
    mesh.to_triangles()
}
