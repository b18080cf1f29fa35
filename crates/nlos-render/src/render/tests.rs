//! Unit tests of the renderer's internals (kernel instantiations, the visibility cache, block culling).

use nlos_brdf::{Fresnel, Ggx};
use nlos_transient::PointSet;

use super::*;
use crate::render::soa::{BLOCK, Packed};

/// The AVX2 + FMA instantiations of the block kernels compute the same bits as the baseline ones (no
/// fused multiply-adds are requested, and every lane is independent), on a CPU that has AVX2 (else the
/// test compares the baseline with itself).
#[test]
fn avx2_and_baseline_kernels_agree_bitwise() {
    let mut p = Vec::new();
    let mut f = Vec::new();
    for i in 0..300u32 {
        let (x, y) = ((i % 20) as f32 * 0.02 - 0.2, (i / 20) as f32 * 0.02 - 0.15);
        let z = 0.4 + 0.05 * (9.0 * x).sin();
        p.extend([Vec3::new(x, y, z), Vec3::new(x, y + 0.02, z + 0.01), Vec3::new(x + 0.02, y, z - 0.01)]);
        f.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let time = TimeAxis::new(0.6, 0.004, 150).expect("axis");
    let brdf = Ggx::new(0.2f32, 0.8, 0.3, Fresnel::Schlick { f0: 0.5 }).expect("valid");
    for scan in [
        Scan::confocal(PointSet::wall_grid(3, 3, 0.2, 0.2).expect("grid")),
        Scan::exhaustive(
            PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"),
            PointSet::wall_grid(2, 1, 0.1, 0.1).expect("grid"),
        ),
    ] {
        for kernel in [Kernel::Tent, Kernel::Gaussian { fwhm_bins: 2.0 }] {
            let params = RenderParams {
                kernel,
                sampling: Sampling::Deterministic(DeterministicRule::fixed(2)),
                visibility: Visibility::Off,
                two_sided: true,
            };
            let mut r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
            let fast = r.forward(&brdf);
            let adj: Vec<f32> = (0..fast.len()).map(|i| (i as f32 * 0.37).sin()).collect();
            let g_fast = r.adjoint(&brdf, &adj).expect("ok");
            r.cpu.isa = Isa::baseline();
            assert_eq!(fast, r.forward(&brdf), "forward ({kernel:?})");
            assert_eq!(g_fast, r.adjoint(&brdf, &adj).expect("ok"), "adjoint ({kernel:?})");
            assert!(fast.iter().any(|v| *v > 0.0));
        }
    }
}

/// A sphere of `2 nu nv` triangles around (0, 0, 0.4), radius 0.1, normals outward, vertices jittered
/// radially by up to `jitter`.
fn sphere(nu: u32, nv: u32, jitter: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for j in 0..=nv {
        for i in 0..nu {
            let (th, ph) = (std::f32::consts::PI * j as f32 / nv as f32, std::f32::consts::TAU * i as f32 / nu as f32);
            let r = 0.1 + jitter * ((i * 7 + j * 13) as f32 * 1.7).sin();
            p.push(Vec3::new(r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), 0.4 + r * th.cos()));
        }
    }
    let id = |i: u32, j: u32| j * nu + i % nu;
    let mut f = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            f.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            f.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    (p, f)
}

/// The visibility cache follows its triangles through `set_positions` (it is stored in the block order,
/// which `set_positions` keeps while a cache exists, though the moved normals would regroup them): on a
/// convex sphere (everything front-facing is visible), a cache computed before a jitter of the vertices
/// gives the render of a cache computed after it, up to grazing pairs that changed orientation.
#[test]
fn cache_survives_set_positions() {
    let (p0, f) = sphere(96, 48, 0.0);
    let (p1, _) = sphere(96, 48, 0.0005);
    let time = TimeAxis::new(0.0, 0.004, 300).expect("axis");
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.3, 0.3).expect("grid"));
    let params = RenderParams {
        sampling: Sampling::Deterministic(DeterministicRule::fixed(1)),
        visibility: Visibility::Cached { level: 1 },
        ..Default::default()
    };
    let brdf = Ggx::new(0.5f32, 0.5, 0.3, Fresnel::One).expect("valid");
    let mut moved = Renderer::new(&p0, &f, &scan, &time, params).expect("valid");
    moved.set_positions(&p1).expect("finite");
    let fresh = Renderer::new(&p1, &f, &scan, &time, params).expect("valid");
    assert_ne!(moved.scene.tris.soa.order, fresh.scene.tris.soa.order, "the jitter must regroup some triangles");
    let (a, b) = (moved.forward(&brdf), fresh.forward(&brdf));
    let num: f64 = a.iter().zip(&b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
    assert!(den > 0.0 && (num / den).sqrt() < 1e-3, "rel-L2 {}", (num / den).sqrt());
}

/// Culling whole blocks that face away, and packing a block's front-facing triangles (fixed rule), change
/// no bit: a closed, bumpy sphere (every orientation) seen from spots all around it, one-sided faces,
/// fixed and adaptive rules, with and without the cache.
#[test]
fn block_culling_is_exact() {
    let (nu, nv) = (96u32, 48u32);
    let mut p = Vec::new();
    for j in 0..=nv {
        for i in 0..nu {
            let (th, ph) = (std::f32::consts::PI * j as f32 / nv as f32, std::f32::consts::TAU * i as f32 / nu as f32);
            let r = 0.1 * (1.0 + 0.1 * (5.0 * ph).sin() * th.sin());
            p.push(Vec3::new(r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), 0.4 + r * th.cos()));
        }
    }
    let id = |i: u32, j: u32| j * nu + i % nu;
    let mut f = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            f.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
            f.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    assert!(f.len() > 8 * BLOCK);
    let time = TimeAxis::new(0.0, 0.004, 300).expect("axis");
    let brdf = Ggx::new(0.2f32, 0.8, 0.3, Fresnel::One).expect("valid");
    // Wall spots around the sphere (a confocal list; the "wall" normals face the sphere).
    let spots: Vec<Vec3> = (0..12)
        .map(|k| {
            let a = k as f32 * 0.55;
            Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), 0.4 + 0.25 * (1.3 * a).sin())
        })
        .collect();
    let mut set = PointSet::list(spots.clone());
    set.normals = spots.iter().map(|s| (Vec3::new(0.0, 0.0, 0.4) - *s).normalize()).collect();
    let scan = Scan::confocal(set);
    for sampling in [
        Sampling::Deterministic(DeterministicRule::fixed(1)),
        Sampling::Deterministic(DeterministicRule { max_bin_fraction: 1.0, min_level: 1, max_level: 3 }),
    ] {
        for visibility in [Visibility::Off, Visibility::Cached { level: 1 }] {
            let params = RenderParams { kernel: Kernel::Tent, sampling, visibility, two_sided: false };
            let mut r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
            let culled = r.forward(&brdf);
            let adj: Vec<f32> = (0..culled.len()).map(|i| (i as f32 * 0.37).sin()).collect();
            let g = r.adjoint(&brdf, &adj).expect("ok");
            let active = (0..scan.measurements())
                .flat_map(|m| (0..f.len()).step_by(BLOCK).map(move |t0| (m, t0)))
                .filter(|(m, t0)| !r.scene.tris.soa.culled(*t0, &r.scene.frame(*m)))
                .count();
            let total = scan.measurements() * f.len().div_ceil(BLOCK);
            assert!(active < total && active > 0, "some blocks culled, not all: {active} of {total}");
            // Packing leaves out part of the blocks that culling keeps.
            let mut pk = Packed::new();
            let (mut packed, mut kept) = (0, 0);
            for m in 0..scan.measurements() {
                for t0 in (0..f.len()).step_by(BLOCK) {
                    let t1 = (t0 + BLOCK).min(f.len());
                    if r.cpu.view(&r.scene).pack(&[m], t0, t1, &mut pk) {
                        packed += pk.len;
                        kept += t1 - t0;
                    }
                }
            }
            assert!(packed > 0 && packed < kept, "packing must leave some triangles out: {packed} of {kept}");
            r.scene.tris.soa.disable_culling();
            assert_eq!(culled, r.forward(&brdf), "forward ({sampling:?}, {visibility:?})");
            assert_eq!(g, r.adjoint(&brdf, &adj).expect("ok"), "adjoint ({sampling:?}, {visibility:?})");
            assert!(culled.iter().any(|v| *v > 0.0));
        }
    }
}

/// The backend seam: the CPU runs every setting, the GPU what `gpu_support` accepts, and through the trait
/// both render the same scene — the CPU bit for bit as the renderer does, the GPU to f32 rounding. The GPU
/// half is skipped (with a line saying so) where no adapter is found, unless `NLOS_REQUIRE_GPU=1`.
#[test]
fn both_backends_render_the_same_scene_through_the_seam() {
    use nlos_brdf::Lambertian;

    use super::backend::Backend;
    let mut p = Vec::new();
    let mut f = Vec::new();
    for i in 0..40u32 {
        let (x, y) = ((i % 8) as f32 * 0.03 - 0.12, (i / 8) as f32 * 0.03 - 0.07);
        let z = 0.35 + 0.04 * (7.0 * x).sin();
        p.extend([Vec3::new(x, y, z), Vec3::new(x + 0.03, y, z + 0.01), Vec3::new(x, y + 0.03, z - 0.01)]);
        f.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.3, 0.3).expect("grid"));
    let time = TimeAxis::new(0.5, 0.004, 200).expect("axis");
    let params = RenderParams {
        kernel: Kernel::Tent,
        sampling: Sampling::Splat(SplatRule::default()),
        visibility: Visibility::Cached { level: 1 },
        two_sided: true,
    };
    let r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
    let live = RenderParams { visibility: Visibility::Live, ..params };
    for model in Model::ALL {
        assert_eq!(r.cpu.supports(model, &live), Ok(()), "the CPU runs {model} with live visibility");
    }
    // The seam is compiled in every build: through it the CPU renders the renderer's own bits.
    let brdf = Lambertian::new(0.7f32).expect("valid");
    let any = brdf.to_any();
    assert_eq!(Backend::forward(&r.cpu, &r.scene, &any).expect("the CPU's pass"), r.forward(&brdf));
    assert_eq!(r.device(), Device::Cpu);
    #[cfg(feature = "gpu")]
    gpu_half(&r, &params, &live);
    #[cfg(not(feature = "gpu"))]
    {
        let mut r = r;
        assert!(matches!(r.set_device(Device::Gpu), Err(RenderError::Gpu(_))), "no GPU backend in this build");
        r.set_device(Device::Auto).expect("auto takes the CPU");
        assert_eq!(r.device(), Device::Cpu);
    }
}

/// The GPU half of the seam's test.
#[cfg(feature = "gpu")]
fn gpu_half(r: &Renderer, params: &RenderParams, live: &RenderParams) {
    use nlos_brdf::Lambertian;

    use super::backend::Backend;
    let gpu = match gpu::attach(Device::Gpu, params) {
        Ok(Some(g)) => g,
        Err(e) if std::env::var("NLOS_REQUIRE_GPU").is_ok_and(|v| v == "1") => panic!("NLOS_REQUIRE_GPU=1 but {e}"),
        Ok(None) | Err(_) => {
            eprintln!("skipped: no GPU adapter (the CPU side of the seam is checked above)");
            return;
        }
    };
    assert!(gpu.supports(Model::Ggx, params).is_err());
    assert!(gpu.supports(Model::Lambert, live).is_err());
    assert_eq!(gpu.supports(Model::Retroreflective, params), Ok(()));
    let brdf = Lambertian::new(0.7f32).expect("valid");
    let any = brdf.to_any();
    assert_eq!((Backend::device(&r.cpu), Backend::device(&gpu)), (Device::Cpu, Device::Gpu));
    let on_cpu = Backend::forward(&r.cpu, &r.scene, &any).expect("the CPU's pass");
    assert_eq!(on_cpu, r.forward(&brdf), "the renderer without a GPU runs the CPU's pass");
    let on_gpu = Backend::forward(&gpu, &r.scene, &any).expect("the GPU's pass");
    let peak = on_cpu.iter().copied().fold(0.0f32, f32::max);
    assert!(peak > 0.0);
    let worst = on_cpu.iter().zip(&on_gpu).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst <= 1e-4 * peak, "forward: {worst} against a peak of {peak}");
    let d: Vec<f32> = (0..on_cpu.len()).map(|i| (i as f32 * 0.37).sin()).collect();
    let (a, b) = (
        Backend::adjoint(&r.cpu, &r.scene, &any, &d).expect("cpu"),
        Backend::adjoint(&gpu, &r.scene, &any, &d).expect("gpu"),
    );
    let scale = a.vertices.iter().map(|g| g.length()).fold(0.0f32, f32::max);
    let worst = a.vertices.iter().zip(&b.vertices).map(|(x, y)| (*x - *y).length()).fold(0.0f32, f32::max);
    assert!(scale > 0.0 && worst <= 1e-3 * scale, "adjoint: {worst} against {scale}");
}

/// A height field over [−0.2, 0.2]² at depth ≈ 0.35 m with hills tall enough to shadow their neighbours from
/// the wall's far spots, and a small plate in front of it (z = 0.2 m) that shadows a patch of it from every
/// spot: `n × n` quads of the field, two triangles each, facing the wall (−z).
fn shadowed_scene(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    let mut f = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (-0.2 + 0.4 * i as f32 / n as f32, -0.2 + 0.4 * j as f32 / n as f32);
            let z = 0.35 - 0.04 * (14.0 * x).sin().max(0.0) * (11.0 * y).cos().max(0.0) + 0.002 * (97.0 * x * y).sin();
            p.push(Vec3::new(x, y, z));
        }
    }
    let id = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            f.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            f.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    let base = p.len() as u32;
    p.extend([
        Vec3::new(-0.03, -0.05, 0.2),
        Vec3::new(0.05, -0.05, 0.2),
        Vec3::new(-0.03, 0.04, 0.21),
        Vec3::new(0.05, 0.04, 0.21),
    ]);
    f.extend([[base, base + 2, base + 1], [base + 1, base + 2, base + 3]]);
    (p, f)
}

/// The cache from one bundle query per centroid ([`Scene::visibility_cache`]) is the cache of one shadow ray
/// per centroid and spot, entry by entry: confocal and non-confocal scans (a laser shared by many sensor spots),
/// one- and two-sided faces, levels 1 and 2, on a scene with self-shadowing and a separate occluder.
#[test]
fn bundled_cache_is_the_cache_of_rays() {
    let (p, f) = shadowed_scene(40);
    let time = TimeAxis::new(0.0, 0.01, 200).expect("axis");
    let scans = [
        Scan::confocal(PointSet::wall_grid(24, 24, 0.4, 0.4).expect("grid")),
        Scan::exhaustive(
            PointSet::wall_grid(2, 1, 0.3, 0.1).expect("grid"),
            PointSet::wall_grid(16, 16, 0.45, 0.45).expect("grid"),
        ),
    ];
    for scan in scans {
        for (level, two_sided) in [(1, false), (2, false), (1, true)] {
            let params = RenderParams {
                kernel: Kernel::Tent,
                sampling: Sampling::Splat(SplatRule::default()),
                visibility: Visibility::Cached { level },
                two_sided,
            };
            let r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
            let fast = r.scene.visibility_cache(level);
            let rays = r.scene.visibility_cache_by_rays(level);
            let lit = rays.iter().filter(|&&v| v > 0).count();
            let shadowed = rays.iter().filter(|&&v| v < 255).count() - rays.iter().filter(|&&v| v == 0).count();
            let differ = fast.iter().zip(&rays).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{} of {} entries differ (level {level}, two-sided {two_sided})", differ, rays.len());
            // The scene must shadow: partly and wholly occluded pairs both occur.
            let dark = fast.iter().zip(&r.scene.visibility_cache_unshadowed()).filter(|(a, b)| a < b).count();
            assert!(lit > rays.len() / 4 && dark > rays.len() / 100, "lit {lit}, shadowed {dark} of {}", rays.len());
            assert!(level == 1 || shadowed > 0, "level 2 gives partial shares");
        }
    }
}

/// The cache's layout is one-to-one: every (measurement, slot) has its own entry, a block's row for a
/// measurement holds the block's slots in order, and the measurement-major copy the GPU reads puts each
/// entry at `m · triangles + slot` (ragged last blocks and a mesh smaller than a block included).
#[test]
fn cache_layout_is_one_to_one() {
    for (triangles, measurements) in [(3 * BLOCK + 37, 5), (BLOCK, 3), (17, 4), (2 * BLOCK, 1)] {
        let layout = cache::CacheLayout { triangles, measurements };
        let mut seen = vec![false; triangles * measurements];
        let cache: Vec<u8> = (0..triangles * measurements).map(|i| (i % 251) as u8).collect();
        let rows = layout.measurement_major(&cache);
        for m in 0..measurements {
            for t0 in (0..triangles).step_by(BLOCK) {
                let row = layout.row(m, t0);
                assert_eq!(row.len(), BLOCK.min(triangles - t0));
                for (k, i) in row.enumerate() {
                    assert_eq!(layout.index(m, t0 + k), i);
                    assert!(!std::mem::replace(&mut seen[i], true), "entry {i} twice");
                    assert_eq!(rows[m * triangles + t0 + k], cache[i]);
                }
            }
        }
        assert!(seen.iter().all(|&s| s), "{triangles} × {measurements}: an entry unused");
    }
}
