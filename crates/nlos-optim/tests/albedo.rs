//! Spatially varying albedo (`nlos_optim::albedo`): a flat plate with printed dark bars. With one albedo for
//! the whole surface the fit can explain the bars' missing light only with shape, and the plate loses its
//! flatness; with the albedo map it stays flat at its depth and the map shows the bars.
#![allow(clippy::unwrap_used)]

use nlos_brdf::Lambertian;
use nlos_mesh::{SurfaceMesh, shapes};
use nlos_optim::{
    AlbedoMapParams, OptimError, ReconstructParams, RenderSettings, SamplingSchedule, Schedule, reconstruct,
};
use nlos_render::{DeterministicRule, RenderParams, Renderer, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

const HALF: f32 = 0.08;
const DEPTH: f32 = 0.42;

/// A flat square of side 2·HALF at depth `z`, facing the wall, n × n quads.
fn plate(z: f32, n: usize) -> SurfaceMesh {
    let side = 2.0 * HALF;
    let m = shapes::height_field(side, side, n, n, |_, _| z).unwrap();
    let (mut p, t) = m.to_triangles();
    for q in &mut p {
        q.x -= HALF;
        q.y -= HALF;
    }
    let t: Vec<[u32; 3]> = t.iter().map(|f| [f[0], f[2], f[1]]).collect();
    SurfaceMesh::from_triangles(&p, &t).unwrap()
}

/// The print: two dark vertical bars (albedo 0.25) 3 cm wide on white (1), at x ∈ [−0.06, −0.03] and
/// [0.02, 0.05].
fn printed(x: f32) -> f32 {
    if (-0.06..-0.03).contains(&x) || (0.02..0.05).contains(&x) { 0.25 } else { 1.0 }
}

fn render() -> RenderParams {
    RenderParams { visibility: Visibility::Off, ..RenderParams::default() }
}

/// 12 × 12 confocal spots over the plate, 2.4 mm bins.
fn measurement() -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(12, 12, f64::from(HALF), f64::from(HALF)).unwrap());
    let time = TimeAxis::new(0.78, 0.0024, 120).unwrap();
    let (p, t) = plate(DEPTH, 48).to_triangles();
    let mut r = Renderer::new(&p, &t, &scan, &time, render()).unwrap();
    let w: Vec<f32> =
        t.iter().map(|f| printed((p[f[0] as usize].x + p[f[1] as usize].x + p[f[2] as usize].x) / 3.0)).collect();
    r.set_face_weights(Some(&w)).unwrap();
    Transient::new(scan, time, r.forward(&Lambertian::new(1.0f32).unwrap())).unwrap()
}

fn params(map: Option<AlbedoMapParams>) -> ReconstructParams {
    ReconstructParams {
        schedule: Schedule {
            initial_resolution: 10.0,
            extent: 0.16,
            growth: 1.0,
            max_stages: 2,
            max_blocks_per_stage: 4,
            shape_iterations: 10,
            reflectance_iterations: 10,
            rel_tol: 0.0,
            ..Schedule::default()
        },
        render: RenderSettings { visibility: Visibility::Off, ..RenderSettings::default() },
        sampling: SamplingSchedule::Deterministic(DeterministicRule {
            max_bin_fraction: 1.0,
            min_level: 1,
            max_level: 5,
        }),
        prune: None,
        residual: None,
        albedo_map: map,
        seed: 5,
        ..ReconstructParams::default()
    }
}

/// Spread of the vertex depths inside the plate (10th to 90th percentile), metres, and their median.
fn depth_spread(m: &SurfaceMesh) -> (f32, f32) {
    let (p, _) = m.to_triangles();
    let mut z: Vec<f32> = p.iter().filter(|v| v.x.abs() < 0.07 && v.y.abs() < 0.07).map(|v| v.z).collect();
    z.sort_by(f32::total_cmp);
    let q = |f: f64| z[((z.len() - 1) as f64 * f) as usize];
    (q(0.9) - q(0.1), q(0.5))
}

#[test]
fn printed_bars_become_albedo_not_relief() {
    let measured = measurement();
    let init = plate(DEPTH - 0.004, 10);
    let uniform = reconstruct(&measured, &init, &params(None)).unwrap();
    let dir = std::env::temp_dir().join(format!("nlos-optim-albedo-ply-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let with_map = ReconstructParams { out_dir: Some(dir.clone()), ..params(Some(AlbedoMapParams::default())) };
    let mapped = reconstruct(&measured, &init, &with_map).unwrap();
    let (su, mu) = depth_spread(&uniform.mesh);
    let (sm, mm) = depth_spread(&mapped.mesh);
    println!(
        "depth p10–p90 spread: uniform albedo {:.2} mm (median {mu:.4} m), albedo map {:.2} mm (median {mm:.4} m)",
        su * 1e3,
        sm * 1e3
    );
    let map = mapped.albedo.expect("a fitted map");
    assert!(uniform.albedo.is_none());
    // The map at the bars' centres against the white between and beside them.
    let a = |x: f64| map.log_albedo_at(x, 0.0).exp();
    let (dark, white) = ((a(-0.045) + a(0.035)) / 2.0, (a(-0.005) + a(0.065)) / 2.0);
    println!("albedo map: bars {dark:.3}, white {white:.3} (truth ratio 0.25)");
    assert!(dark / white < 0.6, "the map should show the bars: dark {dark} white {white}");
    assert!(sm < 1.5e-3, "with the map the plate should stay flat, spread {sm}");
    assert!((mm - DEPTH).abs() < 1.5e-3, "with the map the plate should sit at {DEPTH} m, median {mm}");
    assert!(su > 2.0 * sm, "a uniform albedo should need relief to explain the bars: {su} vs {sm}");
    // mesh.ply carries the map at each vertex: dark on the bars.
    let soup = nlos_mesh::io::read_ply(&std::fs::read(dir.join("mesh.ply")).unwrap(), "mesh.ply").unwrap();
    let albedo = soup.albedo.expect("mesh.ply has the albedo");
    let mean = |bar: bool| {
        let v: Vec<f32> = soup
            .positions
            .iter()
            .zip(&albedo)
            .filter(|(p, _)| p.x.abs() < 0.07 && (printed(p.x) < 1.0) == bar)
            .map(|(_, a)| *a)
            .collect();
        v.iter().sum::<f32>() / v.len() as f32
    };
    assert!(mean(true) / mean(false) < 0.7, "bars {} white {}", mean(true), mean(false));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_albedo_map_parameters_are_typed_errors() {
    let measured = measurement();
    let init = plate(DEPTH, 4);
    for cell in [0.0, -0.01, f64::NAN, 5.0] {
        let r = reconstruct(&measured, &init, &params(Some(AlbedoMapParams { cell, ..Default::default() })));
        assert!(matches!(r, Err(OptimError::InvalidParameter { name: "albedo_map.cell", .. })), "{cell}: {r:?}");
    }
    let r = reconstruct(&measured, &init, &params(Some(AlbedoMapParams { lr: f64::INFINITY, ..Default::default() })));
    assert!(matches!(r, Err(OptimError::InvalidParameter { name: "albedo_map.lr", .. })), "{r:?}");
}
