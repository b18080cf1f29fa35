//! Test 1: the forward model against the independent reference data of `shared/data/reference/` (README
//! sections 3 and 7). Our scale convention leaves out the wall's (ρ_w/π)², so reference = ours / π².

mod common;

use std::f32::consts::PI;
use std::time::Instant;

use common::*;
use glam::Vec3;
use nlos_brdf::{Fresnel, Ggx, Lambertian};
use nlos_render::{DeterministicRule, FittedBrdf, Kernel, RenderParams, Renderer, Sampling, Visibility};

fn square() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (h, d) = (0.1, 0.4);
    // The README's two triangles, (−h,−h,d), (h,h,d), (h,−h,d) and (−h,−h,d), (−h,h,d), (h,h,d).
    let p = vec![Vec3::new(-h, -h, d), Vec3::new(h, h, d), Vec3::new(h, -h, d), Vec3::new(-h, h, d)];
    (p, vec![[0, 1, 2], [0, 3, 1]])
}

fn render_reference<B: FittedBrdf>(p: &[Vec3], f: &[[u32; 3]], brdf: &B, params: RenderParams) -> Vec<f32> {
    let t = Instant::now();
    let r = Renderer::new(p, f, &reference_scan(), &reference_time(), params).expect("valid scene");
    let out: Vec<f32> = r.forward(brdf).iter().map(|v| v / (PI * PI)).collect();
    eprintln!("render: {:.2} s", t.elapsed().as_secs_f64());
    out
}

fn check_square<B: FittedBrdf>(file: &str, brdf: &B, total_ref: f64) {
    let Some(path) = reference(file) else { return };
    let (reference, shape) = npy(&path);
    assert_eq!(shape, vec![64, 64, 512]);
    let (p, f) = square();
    let params = RenderParams {
        kernel: Kernel::Box,
        sampling: Sampling::Deterministic(DeterministicRule { max_bin_fraction: 0.5, min_level: 1, max_level: 512 }),
        visibility: Visibility::Off,
        two_sided: false,
    };
    let ours = render_reference(&p, &f, brdf, params);
    let m = metrics(&ours, &reference, 512);
    eprintln!("{file}: {m:?}");
    let total_ref_file: f64 = reference.iter().map(|v| f64::from(*v)).sum();
    assert!((total_ref_file / total_ref - 1.0).abs() < 1e-4, "README total {total_ref} vs file {total_ref_file}");
    assert!((m.total_ratio - 1.0).abs() < 0.002, "total ratio {}", m.total_ratio);
    assert!(m.image_rel_l2 < 0.005, "image rel-L2 {}", m.image_rel_l2);
    assert!(m.mean_bin_global_delta.abs() < 0.05, "global mean-bin Δ {}", m.mean_bin_global_delta);
    assert!(m.mean_bin_pixel_rms < 0.05, "per-pixel mean-bin RMS {}", m.mean_bin_pixel_rms);
    assert!(m.pooled8_rel_l2 < 0.01, "pooled-8 rel-L2 {}", m.pooled8_rel_l2);
}

#[test]
fn lambertian_square_matches_quadrature() {
    check_square("plane_quadrature.npy", &Lambertian::new(1.0f32).expect("valid"), 91.42858);
}

#[test]
fn ggx_square_matches_quadrature() {
    // README section 3: Walter 2007 GGX, separable Smith G1, F ≡ 1, α = 0.3 as is, no diffuse part:
    // ρ_d = 0, ρ_s = 1 (nlos_brdf::Ggx uses the same D of W07 eq. 33 and the same separable G1).
    let brdf = Ggx::new(0.0f32, 1.0, 0.3, Fresnel::One).expect("valid");
    check_square("ggx_plane_quadrature.npy", &brdf, 77.37796);
}

#[test]
fn hand_checkable_voxel() {
    // README section 3: pixel (31, 31), bin 200 = (2/π²)(1/d² − d⁴/r₁⁶)/6 = 0.0062232 (reference units).
    let (p, f) = square();
    let mut pts = reference_scan().lasers().points.clone();
    pts.truncate(0);
    pts.push(Vec3::new((-0.25 + 31.5 * 0.5 / 64.0) as f32, (-0.25 + 31.5 * 0.5 / 64.0) as f32, 0.0));
    let scan = nlos_transient::Scan::confocal(nlos_transient::PointSet::list(pts));
    let params = RenderParams {
        kernel: Kernel::Box,
        sampling: Sampling::Deterministic(DeterministicRule { max_bin_fraction: 0.05, min_level: 1, max_level: 2048 }),
        visibility: Visibility::Off,
        two_sided: false,
    };
    let r = Renderer::new(&p, &f, &scan, &reference_time(), params).expect("valid");
    let h = r.forward(&Lambertian::new(1.0f32).expect("valid"));
    let v = f64::from(h[200]) / std::f64::consts::PI.powi(2);
    eprintln!("voxel (31,31,200): {v}");
    assert!((v / 0.0062232 - 1.0).abs() < 0.01, "{v}");
}

fn bunny() -> Option<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let path = reference("bunny_world.obj")?;
    let (v, f) = parse_obj(&std::fs::read_to_string(path).expect("readable OBJ"));
    assert_eq!((v.len(), f.len()), (1839, 3674));
    Some((v, f))
}

#[test]
fn bunny_matches_quadrature_subset() {
    // README sections 5 and 7: the 256-pixel visibility quadrature (0.057 % image noise): sum within 0.3 %,
    // image rel-L2 ≤ 0.5 %, per-pixel mean-bin RMS ≤ 0.05, pooled-8 ≤ 1 %.
    let (Some((v, f)), Some(qp), Some(pp)) =
        (bunny(), reference("bunny_quadrature_stride4.npy"), reference("bunny_quadrature_stride4_pixels.npy"))
    else {
        return;
    };
    let (quad, shape) = npy(&qp);
    assert_eq!(shape, vec![256, 512]);
    let (pix, _) = npy(&pp);
    let all = reference_scan();
    let pts: Vec<Vec3> = pix.chunks(2).map(|c| all.lasers().points[c[0] as usize + 64 * c[1] as usize]).collect();
    let scan = nlos_transient::Scan::confocal(nlos_transient::PointSet::list(pts));
    let params = RenderParams {
        kernel: Kernel::Box,
        sampling: Sampling::Deterministic(DeterministicRule { max_bin_fraction: 1.0, min_level: 1, max_level: 8 }),
        visibility: Visibility::Live,
        two_sided: false,
    };
    let t = Instant::now();
    let r = Renderer::new(&v, &f, &scan, &reference_time(), params).expect("valid scene");
    let ours: Vec<f32> = r.forward(&Lambertian::new(1.0f32).expect("valid")).iter().map(|x| x / (PI * PI)).collect();
    eprintln!("bunny subset render: {:.2} s", t.elapsed().as_secs_f64());
    let m = metrics(&ours, &quad, 512);
    eprintln!("bunny_quadrature_stride4: {m:?}");
    assert!((m.total_ratio - 1.0).abs() < 0.003, "total ratio {}", m.total_ratio);
    assert!(m.image_rel_l2 < 0.005, "image rel-L2 {}", m.image_rel_l2);
    assert!(m.mean_bin_pixel_rms < 0.05, "per-pixel mean-bin RMS {}", m.mean_bin_pixel_rms);
    assert!(m.pooled8_rel_l2 < 0.01, "pooled-8 rel-L2 {}", m.pooled8_rel_l2);
}

#[test]
fn bunny_matches_path_tracer() {
    // README section 7, `bunny_mc` row: total within 0.5 %, image rel-L2 ≤ 1.5·0.0065 (+ mesh error),
    // |Δ mean bin| ≤ 0.05 (MC is ≈ 0.03 bins early, quirk 1), pooled-8 ≤ 1.5·0.0140.
    let (Some((v, f)), Some(mc)) = (bunny(), reference("bunny_mc.npy")) else { return };
    let (mc, shape) = npy(&mc);
    assert_eq!(shape, vec![64, 64, 512]);
    let params = RenderParams {
        kernel: Kernel::Box,
        sampling: Sampling::Deterministic(DeterministicRule { max_bin_fraction: 2.0, min_level: 1, max_level: 8 }),
        visibility: Visibility::Cached { level: 1 },
        two_sided: false,
    };
    let ours = render_reference(&v, &f, &Lambertian::new(1.0f32).expect("valid"), params);
    let m = metrics(&ours, &mc, 512);
    eprintln!("bunny_mc: {m:?}");
    assert!((m.total_ratio - 1.0).abs() < 0.005, "total ratio {}", m.total_ratio);
    assert!(m.image_rel_l2 < 1.5 * 0.0065, "image rel-L2 {}", m.image_rel_l2);
    assert!(m.mean_bin_global_delta.abs() < 0.05, "global mean-bin Δ {}", m.mean_bin_global_delta);
    assert!(m.pooled8_rel_l2 < 1.5 * 0.0140, "pooled-8 rel-L2 {}", m.pooled8_rel_l2);
}
