//! The GPU backend (feature `gpu`) against the CPU renderer: the same forward pass (to 1e-4 of the transient's
//! peak), the same adjoint (vertex, BRDF and face-weight gradients), a gradient that matches finite differences
//! of the GPU's own forward pass, and bit-identical results on repeated calls. Runs wherever wgpu finds an
//! adapter — in CI Mesa's software Vulkan (lavapipe). Without one the tests say so and pass, unless
//! `NLOS_REQUIRE_GPU=1` (set by CI) turns that into a failure.
#![cfg(feature = "gpu")]

mod common;

use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx, Lambertian, Retroreflective};
use nlos_render::{FittedBrdf, GpuRenderer, RenderError, RenderParams, Renderer, Sampling, SplatRule, Visibility};
use nlos_transient::{PointSet, Scan, TimeAxis};

/// The device, or None (with the reason printed) where the machine has none and none is required.
fn gpu() -> Option<GpuRenderer> {
    match GpuRenderer::new() {
        Ok(g) => {
            eprintln!("GPU adapter: {}", g.adapter());
            Some(g)
        }
        Err(e) if std::env::var("NLOS_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
            panic!("NLOS_REQUIRE_GPU=1 but {e}")
        }
        Err(e) => {
            eprintln!("skipping: {e}");
            None
        }
    }
}

fn splat(visibility: Visibility) -> RenderParams {
    RenderParams { sampling: Sampling::Splat(SplatRule::default()), visibility, ..RenderParams::default() }
}

fn confocal_scan() -> Scan {
    Scan::confocal(PointSet::wall_grid(6, 5, 0.3, 0.25).expect("grid"))
}

fn general_scan() -> Scan {
    Scan::exhaustive(
        PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"),
        PointSet::wall_grid(3, 2, 0.15, 0.1).expect("grid"),
    )
}

/// A smooth adjoint row per measurement (non-trivial, different everywhere).
fn adjoint_rows(len: usize, bins: usize) -> Vec<f32> {
    (0..len).map(|i| ((i % bins) as f32 * 0.13 + (i / bins) as f32 * 0.7).cos() + 0.2).collect()
}

fn max_abs(v: impl IntoIterator<Item = f32>) -> f32 {
    v.into_iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Forward and adjoint on both devices; the transients agree to `1e-4` of their peak, the vertex gradients to
/// `tol` of their largest, the BRDF and face gradients likewise.
fn compare<B: FittedBrdf + Sync>(g: &mut GpuRenderer, r: &Renderer, brdf: &B, tol: f32, what: &str) {
    let cpu = r.forward(brdf);
    let dev = g.forward(r, brdf).expect("GPU forward");
    assert_eq!(cpu.len(), dev.len());
    let peak = max_abs(cpu.iter().copied());
    assert!(peak > 0.0, "{what}: a non-trivial render");
    let err = max_abs(cpu.iter().zip(&dev).map(|(c, d)| c - d));
    eprintln!("{what}: forward max |GPU − CPU| = {:.2e} of the peak", err / peak);
    assert!(err <= 1e-4 * peak, "{what}: forward differs by {err} (peak {peak})");
    // Repeated calls give the same bits.
    let again = g.forward(r, brdf).expect("GPU forward");
    assert!(dev.iter().zip(&again).all(|(a, b)| a.to_bits() == b.to_bits()), "{what}: forward not repeatable");

    let adj = adjoint_rows(cpu.len(), r.time().bins);
    let gc = r.adjoint(brdf, &adj).expect("CPU adjoint");
    let gd = g.adjoint(r, brdf, &adj).expect("GPU adjoint");
    let top = max_abs(gc.vertices.iter().flat_map(|v| v.to_array()));
    assert!(top > 0.0, "{what}: a non-trivial gradient");
    let verr = max_abs(gc.vertices.iter().zip(&gd.vertices).flat_map(|(a, b)| (*a - *b).to_array()));
    eprintln!("{what}: adjoint max |GPU − CPU| = {:.2e} of the largest", verr / top);
    assert!(verr <= tol * top, "{what}: vertex gradients differ by {verr} (largest {top})");
    for (a, b) in gc.brdf.iter().zip(&gd.brdf) {
        assert!((a - b).abs() <= tol * a.abs().max(1e-30), "{what}: BRDF gradient {b} against {a}");
    }
    let ftop = max_abs(gc.faces.iter().copied());
    let ferr = max_abs(gc.faces.iter().zip(&gd.faces).map(|(a, b)| a - b));
    assert!(ferr <= tol * ftop, "{what}: face gradients differ by {ferr} (largest {ftop})");
    let again = g.adjoint(r, brdf, &adj).expect("GPU adjoint");
    assert!(
        gd.vertices
            .iter()
            .zip(&again.vertices)
            .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)),
        "{what}: adjoint not repeatable"
    );
}

#[test]
fn gpu_matches_the_cpu_on_a_confocal_scan_with_cached_visibility() {
    let Some(mut g) = gpu() else { return };
    let (p, f) = common::bumpy_surface_with_occluder(20);
    let time = TimeAxis::new(0.6, 0.004, 300).expect("axis");
    let r = Renderer::new(&p, &f, &confocal_scan(), &time, splat(Visibility::Cached { level: 2 })).expect("valid");
    compare(&mut g, &r, &Lambertian::new(0.8f32).expect("albedo"), 1e-4, "confocal Lambertian, cached visibility");
    compare(&mut g, &r, &Retroreflective::new(0.6f32).expect("albedo"), 1e-4, "confocal retroreflective");
}

#[test]
fn gpu_matches_the_cpu_on_a_general_scan_two_sided_with_face_weights() {
    let Some(mut g) = gpu() else { return };
    let (p, f) = common::bumpy_surface_with_occluder(12);
    let time = TimeAxis::new(0.6, 0.004, 300).expect("axis");
    let params = RenderParams { two_sided: true, ..splat(Visibility::Off) };
    let mut r = Renderer::new(&p, &f, &general_scan(), &time, params).expect("valid");
    let weights: Vec<f32> = (0..f.len()).map(|i| 0.5 + 0.5 * ((i as f32) * 0.37).sin().abs()).collect();
    r.set_face_weights(Some(&weights)).expect("weights");
    compare(&mut g, &r, &Lambertian::new(1.0f32).expect("albedo"), 1e-4, "general Lambertian, two-sided, weights");
    let wide = Retroreflective::with_lobe_width(0.7f32, 0.2).expect("lobe");
    compare(&mut g, &r, &wide, 1e-4, "general retroreflective, 0.2 rad lobe");
}

/// Paired spots on a wall curved by ±5 cm, each with its own normal (the general-NLOS shape of capture).
fn paired_curved_scan() -> Scan {
    let spot = |x: f32, y: f32| Vec3::new(x, y, 0.05 * (4.0 * x).sin() * (3.0 * y).cos());
    let normal = |p: Vec3| {
        Vec3::new(-0.2 * (4.0 * p.x).cos() * (3.0 * p.y).cos(), 0.15 * (4.0 * p.x).sin() * (3.0 * p.y).sin(), 1.0)
            .normalize()
    };
    let set = |points: Vec<Vec3>| PointSet {
        normals: points.iter().map(|p| normal(*p)).collect(),
        points,
        layout: nlos_transient::Layout::List,
    };
    let lasers: Vec<Vec3> = (0..12).map(|i| spot(-0.25 + 0.1 * (i % 4) as f32, -0.2 + 0.2 * (i / 4) as f32)).collect();
    let sensors = lasers.iter().map(|l| spot(l.x + 0.27 * (0.5 * l.y).cos(), l.y + 0.27 * (0.5 * l.y).sin())).collect();
    Scan::paired(set(lasers), set(sensors))
}

#[test]
fn gpu_matches_the_cpu_on_paired_spots_of_a_curved_wall() {
    let Some(mut g) = gpu() else { return };
    let (p, f) = common::bumpy_surface_with_occluder(12);
    let time = TimeAxis::new(0.6, 0.004, 300).expect("axis");
    let r = Renderer::new(&p, &f, &paired_curved_scan(), &time, splat(Visibility::Cached { level: 2 })).expect("valid");
    compare(&mut g, &r, &Lambertian::new(0.8f32).expect("albedo"), 1e-4, "paired curved wall, Lambertian");
    let wide = Retroreflective::with_lobe_width(0.7f32, 0.2).expect("lobe");
    compare(&mut g, &r, &wide, 1e-4, "paired curved wall, retroreflective, 0.2 rad lobe");
}

#[test]
fn gpu_gradient_matches_finite_differences_of_the_gpu_forward() {
    let Some(mut g) = gpu() else { return };
    let (p, f) = common::bumpy_surface_with_occluder(8);
    let time = TimeAxis::new(0.6, 0.004, 300).expect("axis");
    let scan = confocal_scan();
    let brdf = Lambertian::new(1.0f32).expect("albedo");
    let mut r = Renderer::new(&p, &f, &scan, &time, splat(Visibility::Off)).expect("valid");
    let base = g.forward(&r, &brdf).expect("forward");
    // E = Σ c_k I_k with fixed weights: dE/dI = c.
    let c = adjoint_rows(base.len(), time.bins);
    let grad = g.adjoint(&r, &brdf, &c).expect("adjoint");
    let h = 5e-4f32;
    let top = f64::from(max_abs(grad.vertices.iter().flat_map(|v| v.to_array())));
    for vi in [10usize, 30, 40, 55] {
        for axis in 0..3 {
            // E at the vertex moved by d (the renderer keeps its blocks and levels, as in tests/gradients.rs).
            let mut at = |d: f32| -> f64 {
                let mut q = p.clone();
                q[vi][axis] += d;
                r.set_positions(&q).expect("finite");
                let i = g.forward(&r, &brdf).expect("forward");
                i.iter().zip(&c).map(|(i, c)| f64::from(*i) * f64::from(*c)).sum()
            };
            // Five-point difference (as tests/gradients.rs), the same criterion: relative error below 1e-3, the
            // largest component as the floor for near-zero entries.
            let fd = (-at(2.0 * h) + 8.0 * at(h) - 8.0 * at(-h) + at(-2.0 * h)) / (12.0 * f64::from(h));
            let an = f64::from(grad.vertices[vi][axis]);
            let err = (fd - an).abs() / an.abs().max(0.1 * top);
            assert!(err < 1e-3, "vertex {vi} axis {axis}: adjoint {an}, finite difference {fd} (rel {err})");
        }
    }
}

#[test]
fn unsupported_requests_are_typed_errors() {
    let Some(mut g) = gpu() else { return };
    let (p, f) = common::bumpy_surface_with_occluder(4);
    let time = TimeAxis::new(0.6, 0.004, 100).expect("axis");
    let scan = confocal_scan();
    let lamb = Lambertian::new(1.0f32).expect("albedo");
    let live = Renderer::new(&p, &f, &scan, &time, splat(Visibility::Live)).expect("valid");
    assert!(matches!(g.forward(&live, &lamb), Err(RenderError::Gpu(m)) if m.contains("Cached")));
    let point = Renderer::new(&p, &f, &scan, &time, RenderParams::default()).expect("valid");
    assert!(matches!(g.forward(&point, &lamb), Err(RenderError::Gpu(m)) if m.contains("splat")));
    let r = Renderer::new(&p, &f, &scan, &time, splat(Visibility::Off)).expect("valid");
    let ggx = Ggx::new(0.5f32, 0.5, 0.2, Fresnel::One).expect("ggx");
    assert!(matches!(g.forward(&r, &ggx), Err(RenderError::Gpu(m)) if m.contains("no GPU version")));
    assert!(matches!(g.adjoint(&r, &lamb, &[1.0; 3]), Err(RenderError::LengthMismatch { .. })));
}

/// Fine splat levels (up to 64² sub-triangles per face and measurement): the GPU's sub-triangle of a flat index
/// is computed in closed form. Mesa's llvmpipe ends long-running loops early (its loop limiter), which an
/// earlier row-by-row search ran into above level 40, dropping sub-triangles without an error.
#[test]
fn gpu_matches_the_cpu_at_fine_splat_levels() {
    let Some(mut g) = gpu() else { return };
    let (h, d) = (0.1f32, 0.3f32);
    let p = [Vec3::new(-h, -h, d), Vec3::new(h, -h, d), Vec3::new(h, h, d)];
    let scan = Scan::confocal(PointSet::wall_grid(2, 2, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.0, 0.004, 300).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("albedo");
    for level in [7u32, 48, 64] {
        let sampling = Sampling::Splat(SplatRule { max_deviation: 1e-6, max_level: level });
        let params = RenderParams { sampling, visibility: Visibility::Off, ..RenderParams::default() };
        let r = Renderer::new(&p, &[[0, 2, 1]], &scan, &time, params).expect("valid");
        let (c, d) = (r.forward(&brdf), g.forward(&r, &brdf).expect("GPU forward"));
        let peak = max_abs(c.iter().copied());
        let err = max_abs(c.iter().zip(&d).map(|(a, b)| a - b));
        assert!(peak > 0.0 && err <= 1e-4 * peak, "level {level}: forward differs by {err} (peak {peak})");
        let ones = vec![1.0f32; r.len()];
        let (ac, ag) =
            (r.adjoint(&brdf, &ones).expect("CPU").brdf[0], g.adjoint(&r, &brdf, &ones).expect("GPU").brdf[0]);
        assert!((ac - ag).abs() <= 1e-4 * ac, "level {level}: albedo gradient {ag} on the GPU, {ac} on the CPU");
    }
}

/// Renderers made one after another (as the loop makes one per block) each get their own visibility on the
/// device, even when a new one has the same size as, and perhaps the address of, one dropped before it.
#[test]
fn each_renderer_gets_its_own_cached_visibility() {
    let Some(mut g) = gpu() else { return };
    let (p, f) = common::bumpy_surface_with_occluder(10);
    let time = TimeAxis::new(0.6, 0.004, 300).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("albedo");
    let occluder = p.len() - 3;
    for shift in [0.0f32, 0.08, -0.08] {
        let mut q = p.clone();
        for v in &mut q[occluder..] {
            v.x += shift;
        }
        let r = Renderer::new(&q, &f, &confocal_scan(), &time, splat(Visibility::Cached { level: 2 })).expect("valid");
        let (c, d) = (r.forward(&brdf), g.forward(&r, &brdf).expect("GPU forward"));
        let peak = max_abs(c.iter().copied());
        let err = max_abs(c.iter().zip(&d).map(|(a, b)| a - b));
        assert!(err <= 1e-4 * peak, "occluder moved by {shift} m: forward differs by {err} (peak {peak})");
    }
}

/// One triangle against 65,536 measurements (more adjoint ranges than the grid's 65,535 rows would allow):
/// still on the GPU, and as the CPU.
#[test]
fn one_triangle_and_many_measurements() {
    let Some(mut g) = gpu() else { return };
    let p = [Vec3::new(-0.1, -0.1, 0.4), Vec3::new(0.1, 0.1, 0.4), Vec3::new(0.1, -0.1, 0.4)];
    let scan = Scan::confocal(PointSet::wall_grid(256, 256, 0.25, 0.25).expect("grid"));
    let time = TimeAxis::new(0.7, 0.004, 64).expect("axis");
    let brdf = Lambertian::new(1.0f32).expect("albedo");
    let r = Renderer::new(&p, &[[0, 1, 2]], &scan, &time, splat(Visibility::Off)).expect("valid");
    let ones = vec![1.0f32; r.len()];
    let (ac, ag) = (r.adjoint(&brdf, &ones).expect("CPU").brdf[0], g.adjoint(&r, &brdf, &ones).expect("GPU").brdf[0]);
    assert!(ac > 0.0 && (ac - ag).abs() <= 1e-4 * ac, "albedo gradient {ag} on the GPU, {ac} on the CPU");
}
