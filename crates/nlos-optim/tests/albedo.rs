//! Reflectance on the surface (`nlos_optim::albedo`) and the region tests (`nlos_optim::regions`), where the
//! model is exact (noise-free renders of the model itself):
//! - a flat plate with printed dark bars: with one albedo for the whole surface the fit can explain the bars'
//!   missing light only with shape, and the plate loses its flatness; with an albedo per vertex it stays flat
//!   at its depth and `mesh.ply`'s albedo shows the bars;
//! - a plate with a slot cut through it, started whole: with one albedo the slot's faces stay (bent back,
//!   a dent); with the albedo they go dark and the region test deletes them — a hole.
#![allow(clippy::unwrap_used)]

use nlos_brdf::Lambertian;
use nlos_mesh::{SurfaceMesh, shapes};
use nlos_optim::{
    AlbedoParams, OptimError, PruneParams, ReconstructParams, RegionParams, RenderSettings, SamplingSchedule, Schedule,
    reconstruct,
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

/// The slot: x ∈ [−0.015, 0.015], y ∈ [−0.05, 0.05], cut through the plate.
fn in_slot(x: f32, y: f32) -> bool {
    x.abs() < 0.015 && y.abs() < 0.05
}

/// 12 × 12 confocal spots over the plate, 2.4 mm bins: the plate of 48 × 48 quads with the factor
/// `weight(x, y)` at each face's centroid (0: the face is cut away).
fn measurement_of(weight: impl Fn(f32, f32) -> f32) -> Transient {
    let scan = Scan::confocal(PointSet::wall_grid(12, 12, f64::from(HALF), f64::from(HALF)).unwrap());
    let time = TimeAxis::new(0.78, 0.0024, 120).unwrap();
    let (p, t) = plate(DEPTH, 48).to_triangles();
    let centroid = |f: &[u32; 3]| f.iter().fold(glam::Vec3::ZERO, |s, &v| s + p[v as usize]) / 3.0;
    let t: Vec<[u32; 3]> = t.into_iter().filter(|f| weight(centroid(f).x, centroid(f).y) > 0.0).collect();
    let mut r = Renderer::new(&p, &t, &scan, &time, render()).unwrap();
    let w: Vec<f32> = t.iter().map(|f| weight(centroid(f).x, centroid(f).y)).collect();
    r.set_face_weights(Some(&w)).unwrap();
    Transient::new(scan, time, r.forward(&Lambertian::new(1.0f32).unwrap())).unwrap()
}

fn measurement() -> Transient {
    measurement_of(|x, _| printed(x))
}

fn params(albedo: Option<AlbedoParams>) -> ReconstructParams {
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
        regions: albedo.map(|_| RegionParams::default()),
        albedo,
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
    let with_albedo = ReconstructParams { out_dir: Some(dir.clone()), ..params(Some(AlbedoParams::default())) };
    let fitted = reconstruct(&measured, &init, &with_albedo).unwrap();
    let (su, mu) = depth_spread(&uniform.mesh);
    let (sm, mm) = depth_spread(&fitted.mesh);
    println!(
        "depth p10–p90 spread: uniform albedo {:.2} mm (median {mu:.4} m), per-vertex albedo {:.2} mm (median {mm:.4} m)",
        su * 1e3,
        sm * 1e3
    );
    assert!(uniform.albedo.is_none());
    let albedo = fitted.albedo.as_ref().expect("a fitted albedo");
    let (p, _) = fitted.mesh.to_triangles();
    assert_eq!(albedo.len(), p.len());
    let removed: usize = fitted.regions.iter().map(|r| r.removed).sum();
    assert!(removed * 50 <= fitted.mesh.n_faces(), "the print is kept: {:?}", fitted.regions);
    assert!(sm < 1.5e-3, "with the albedo the plate should stay flat, spread {sm}");
    assert!((mm - DEPTH).abs() < 1.5e-3, "with the albedo the plate should sit at {DEPTH} m, median {mm}");
    assert!(su > 2.0 * sm, "a uniform albedo should need relief to explain the bars: {su} vs {sm}");
    // mesh.ply carries the albedo at each vertex: dark on the bars.
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
    println!("albedo: bars {:.3}, white {:.3} (truth ratio 0.25)", mean(true), mean(false));
    assert!(mean(true) / mean(false) < 0.5, "bars {} white {}", mean(true), mean(false));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A slot cut through the plate, the start whole, photon counts: with one albedo the slot's faces stay, bent away from the
/// plate (a dent); with the albedo per vertex they turn dark and the region test deletes them (a hole), and
/// the rest of the plate stays at its depth. What it catches: a dark strip fitted as a dent.
#[test]
fn a_slot_becomes_a_hole_not_a_dent() {
    // Photon counts, as a capture holds them: 2,000 photons per measurement, an ideal counter.
    let clean = measurement_of(|x, y| if in_slot(x, y) { 0.0 } else { 1.0 });
    let spad = nlos_transient::sensor::SpadModel::ideal(nlos_transient::sensor::PhotonBudget::PerMeasurement(2000.0));
    let measured = spad.simulate(&clean, 3).unwrap();
    let init = plate(DEPTH - 0.004, 10);
    // Edges of 8 mm: a face's corners can all lie inside the 30 mm slot.
    let with = |albedo: Option<AlbedoParams>| {
        let p = params(albedo);
        ReconstructParams {
            prune: Some(PruneParams::default()),
            data: nlos_optim::DataTerm { counts: true, ..nlos_optim::DataTerm::default() },
            schedule: Schedule { initial_resolution: 20.0, ..p.schedule },
            ..p
        }
    };
    // Faces whose centroid lies inside the slot (5 mm from its edges), and the area they cover.
    let in_slot_area = |m: &SurfaceMesh| -> f64 {
        let (p, t) = m.to_triangles();
        t.iter()
            .filter(|f| {
                let c = f.iter().fold(glam::Vec3::ZERO, |s, &v| s + p[v as usize]) / 3.0;
                c.x.abs() < 0.010 && c.y.abs() < 0.045
            })
            .map(|f| {
                let [a, b, c] = f.map(|v| p[v as usize]);
                0.5 * f64::from((b - a).cross(c - a).length())
            })
            .sum()
    };
    let slot = 0.020 * 0.090;
    let uniform = reconstruct(&measured, &init, &with(None)).unwrap();
    let fitted = reconstruct(&measured, &init, &with(Some(AlbedoParams::default()))).unwrap();
    let (du, df) = (in_slot_area(&uniform.mesh) / slot, in_slot_area(&fitted.mesh) / slot);
    let deleted: usize = fitted.regions.iter().map(|r| r.removed).sum();
    println!(
        "slot covered: one albedo {:.0} %, per-vertex albedo {:.0} % ({deleted} faces deleted by region tests)",
        100.0 * du,
        100.0 * df
    );
    assert!(du > 0.5, "with one albedo the slot stays covered (a dent): {du}");
    assert!(df < 0.2, "with the albedo the slot should open: {df} covered");
    assert!(deleted > 0);
    let (spread, median) = depth_spread(&fitted.mesh);
    assert!((median - DEPTH).abs() < 2e-3, "the plate stays at {DEPTH} m: median {median}");
    assert!(spread < 3e-3, "the plate stays flat: spread {spread}");
}

#[test]
fn bad_albedo_and_region_parameters_are_typed_errors() {
    let measured = measurement();
    let init = plate(DEPTH, 4);
    for max in [0.5, f64::NAN, f64::INFINITY] {
        let r = reconstruct(&measured, &init, &params(Some(AlbedoParams { max, ..Default::default() })));
        assert!(matches!(r, Err(OptimError::InvalidParameter { name: "albedo.max", .. })), "{max}: {r:?}");
    }
    let r = reconstruct(&measured, &init, &params(Some(AlbedoParams { lr: f64::INFINITY, ..Default::default() })));
    assert!(matches!(r, Err(OptimError::InvalidParameter { name: "albedo.lr", .. })), "{r:?}");
    for dark in [0.0, 0.5, f64::NAN] {
        let p = ReconstructParams { regions: Some(RegionParams { dark, ..Default::default() }), ..params(None) };
        let r = reconstruct(&measured, &init, &p);
        assert!(matches!(r, Err(OptimError::InvalidParameter { name: "regions.dark", .. })), "{dark}: {r:?}");
    }
}
