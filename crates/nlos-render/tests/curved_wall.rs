//! The renderer on a curved relay wall with paired spots, against a brute-force quadrature of the
//! measurement equation written here from the crate docs' eq. (1)–(2) and nothing else of the renderer:
//!
//! `I_k(l, s) = ∫_S box_k(|x − l| + |x − s|) · f_s · ⟨−ω_l, n_l⟩⟨ω_l, n⟩/|x − l|² · ⟨−ω_s, n_s⟩⟨ω_s, n⟩/|x − s|² dA`
//!
//! with `ω_l = (l − x)/|l − x|`, a Lambertian `f_s = ρ/π`, cosines clamped at 0, in f64 by the midpoint rule
//! on a fine grid of the hidden rectangle (0.25 mm cells). The wall bends by ±5 cm, each spot with its own
//! normal, so a renderer that used +z (or the laser's normal at the sensor) at any cosine fails.

use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use nlos_brdf::Lambertian;
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::{Layout, PointSet, Scan, TimeAxis};

/// The wall `z = 0.05 sin(4x) cos(3y)` and its unit normal.
fn wall(x: f64, y: f64) -> (DVec3, DVec3) {
    let p = DVec3::new(x, y, 0.05 * (4.0 * x).sin() * (3.0 * y).cos());
    let n = DVec3::new(-0.2 * (4.0 * x).cos() * (3.0 * y).cos(), 0.15 * (4.0 * x).sin() * (3.0 * y).sin(), 1.0);
    (p, n.normalize())
}

/// Eight pairs: lasers over the wall, each sensor 0.27 m away (as the general-NLOS capture's spots).
fn pairs() -> Vec<[(DVec3, DVec3); 2]> {
    (0..8)
        .map(|i| {
            let (x, y) = (-0.2 + 0.13 * (i % 4) as f64, -0.15 + 0.3 * (i / 4) as f64);
            let a = 0.7 * i as f64;
            [wall(x, y), wall(x + 0.27 * a.cos(), y + 0.27 * a.sin())]
        })
        .collect()
}

/// The hidden rectangle `c + u e1 + v e2`, `u, v ∈ [0, 1]`, tilted towards the wall.
const CORNER: DVec3 = DVec3::new(-0.12, -0.1, 0.42);
const E1: DVec3 = DVec3::new(0.22, 0.02, 0.06);
const E2: DVec3 = DVec3::new(-0.03, 0.2, -0.05);

fn quadrature(l: (DVec3, DVec3), s: (DVec3, DVec3), time: &TimeAxis, albedo: f64) -> Vec<f64> {
    let cells = 880;
    let normal = E2.cross(E1); // faces −z, towards the wall
    let d_area = normal.length() / (cells * cells) as f64;
    let n = normal.normalize();
    let mut out = vec![0.0; time.bins];
    for i in 0..cells {
        for j in 0..cells {
            let (u, v) = ((i as f64 + 0.5) / cells as f64, (j as f64 + 0.5) / cells as f64);
            let x = CORNER + u * E1 + v * E2;
            let (a, b) = (l.0 - x, s.0 - x);
            let (ra, rb) = (a.length(), b.length());
            let (wl, ws) = (a / ra, b / rb);
            let cos = |c: f64| c.max(0.0);
            let f = albedo / PI * cos(-wl.dot(l.1)) * cos(wl.dot(n)) / (ra * ra) * cos(-ws.dot(s.1)) * cos(ws.dot(n))
                / (rb * rb);
            let k = ((ra + rb - time.t0) / time.bin_width).floor();
            if k >= 0.0 && (k as usize) < time.bins {
                out[k as usize] += f * d_area;
            }
        }
    }
    out
}

#[test]
fn renderer_matches_quadrature_on_a_curved_wall_with_paired_spots() {
    let pairs = pairs();
    let set = |k: usize| PointSet {
        points: pairs.iter().map(|p| p[k].0.as_vec3()).collect(),
        normals: pairs.iter().map(|p| p[k].1.as_vec3()).collect(),
        layout: Layout::List,
    };
    let scan = Scan::paired(set(0), set(1));
    let time = TimeAxis::new(0.6, 0.01, 90).expect("axis");
    let p: Vec<Vec3> = [CORNER, CORNER + E1, CORNER + E1 + E2, CORNER + E2].iter().map(|v| v.as_vec3()).collect();
    // Faces oriented towards the wall: N = (v1 − v0) × (v2 − v0) must point to −z.
    let faces = if E1.cross(E2).z < 0.0 { vec![[0, 1, 2], [0, 2, 3]] } else { vec![[0, 2, 1], [0, 3, 2]] };
    let params = RenderParams {
        kernel: Kernel::Box,
        sampling: Sampling::Deterministic(DeterministicRule { max_bin_fraction: 0.05, min_level: 1, max_level: 1024 }),
        visibility: Visibility::Off,
        two_sided: false,
    };
    let albedo = 0.8;
    let ours = Renderer::new(&p, &faces, &scan, &time, params)
        .expect("valid")
        .forward(&Lambertian::new(albedo as f32).expect("valid"));
    let flat_normals = Scan::paired(
        PointSet { normals: vec![Vec3::Z; pairs.len()], ..set(0) },
        PointSet { normals: vec![Vec3::Z; pairs.len()], ..set(1) },
    );
    let flat = Renderer::new(&p, &faces, &flat_normals, &time, params)
        .expect("valid")
        .forward(&Lambertian::new(albedo as f32).expect("valid"));
    for (m, pair) in pairs.iter().enumerate() {
        let q = quadrature(pair[0], pair[1], &time, albedo);
        let h = &ours[m * time.bins..(m + 1) * time.bins];
        let total_q: f64 = q.iter().sum();
        let total: f64 = h.iter().map(|v| f64::from(*v)).sum();
        assert!(total_q > 0.0, "pair {m}: the rectangle is seen");
        let rel_total = total / total_q - 1.0;
        let l2 = (h.iter().zip(&q).map(|(a, b)| (f64::from(*a) - b).powi(2)).sum::<f64>()
            / q.iter().map(|b| b * b).sum::<f64>())
        .sqrt();
        let flat_total: f64 = flat[m * time.bins..(m + 1) * time.bins].iter().map(|v| f64::from(*v)).sum();
        eprintln!(
            "pair {m}: total {total:.5e} vs quadrature {total_q:.5e} ({:+.3} %), per-bin rel-L2 {:.3} %; with +z \
             normals {:+.2} %",
            100.0 * rel_total,
            100.0 * l2,
            100.0 * (flat_total / total_q - 1.0)
        );
        assert!(rel_total.abs() < 1e-4, "pair {m}: total off by {rel_total}");
        assert!(l2 < 0.005, "pair {m}: per-bin rel-L2 {l2}");
    }
    // The wall's normals matter: with +z everywhere the totals differ by more than the tolerance above.
    let flat_off = pairs
        .iter()
        .enumerate()
        .map(|(m, pair)| {
            let total_q: f64 = quadrature(pair[0], pair[1], &time, albedo).iter().sum();
            let t: f64 = flat[m * time.bins..(m + 1) * time.bins].iter().map(|v| f64::from(*v)).sum();
            (t / total_q - 1.0).abs()
        })
        .fold(0.0, f64::max);
    assert!(flat_off > 0.01, "the curved wall's normals change a total by {flat_off} only");
}
