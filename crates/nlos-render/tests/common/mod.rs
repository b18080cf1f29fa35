//! Shared helpers of the integration tests: reference data location, OBJ parsing, metrics.
#![allow(dead_code)]

use glam::Vec3;
use nlos_transient::{Layout, PointSet, Scan, TimeAxis};

/// Path of a file of the shared reference data, or None (with the reason printed) when absent.
pub fn reference(name: &str) -> Option<std::path::PathBuf> {
    nlos_testdata::shared(&format!("reference/{name}"))
}

/// Loads a float .npy cube as (values, shape).
pub fn npy(path: &std::path::Path) -> (Vec<f32>, Vec<usize>) {
    nlos_transient::formats::npy::read_npy_array(path).expect("readable reference .npy")
}

/// A 30-line OBJ parser: `v x y z` and `f a b c` (1-based, `a/b/c` forms, fans for polygons).
pub fn parse_obj(text: &str) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut v, mut f) = (Vec::new(), Vec::new());
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f32> = it.take(3).map(|x| x.parse().expect("number")).collect();
                v.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let idx: Vec<u32> = it
                    .map(|w| w.split('/').next().expect("index").parse::<i64>().expect("integer"))
                    .map(|i| if i < 0 { (v.len() as i64 + i) as u32 } else { (i - 1) as u32 })
                    .collect();
                for k in 1..idx.len() - 1 {
                    f.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    (v, f)
}

/// The reference README's confocal grid: 64 × 64 pixel centres on [−0.25, 0.25]², x fastest.
pub fn reference_scan() -> Scan {
    let mut pts = Vec::new();
    for iy in 0..64 {
        for ix in 0..64 {
            let c = |i: usize| -0.25 + (i as f64 + 0.5) * 0.5 / 64.0;
            pts.push(Vec3::new(c(ix) as f32, c(iy) as f32, 0.0));
        }
    }
    let mut p = PointSet::list(pts);
    p.layout = Layout::Grid { nx: 64, ny: 64 };
    Scan::confocal(p)
}

/// 512 bins of 4 mm from 0.
pub fn reference_time() -> TimeAxis {
    TimeAxis::new(0.0, 0.004, 512).expect("valid")
}

/// The README's section-7 metrics of `m` against `r` (both measurement-major, `bins` per histogram).
#[derive(Debug)]
pub struct Metrics {
    pub total_ratio: f64,
    pub image_rel_l2: f64,
    pub pooled8_rel_l2: f64,
    pub voxel_rel_l2: f64,
    pub mean_bin_global_delta: f64,
    pub mean_bin_pixel_rms: f64,
}

fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

pub fn metrics(m: &[f32], r: &[f32], bins: usize) -> Metrics {
    let md: Vec<f64> = m.iter().map(|x| f64::from(*x)).collect();
    let rd: Vec<f64> = r.iter().map(|x| f64::from(*x)).collect();
    let img = |d: &[f64]| d.chunks(bins).map(|h| h.iter().sum::<f64>()).collect::<Vec<_>>();
    let pool = |d: &[f64]| d.chunks(8).map(|h| h.iter().sum::<f64>()).collect::<Vec<_>>();
    let profile = |d: &[f64]| {
        let mut p = vec![0.0; bins];
        for h in d.chunks(bins) {
            for (k, v) in h.iter().enumerate() {
                p[k] += v;
            }
        }
        p
    };
    let mean_bin = |h: &[f64]| {
        let s: f64 = h.iter().sum();
        h.iter().enumerate().map(|(k, v)| k as f64 * v).sum::<f64>() / s
    };
    let (im, ir) = (img(&md), img(&rd));
    let peak = ir.iter().cloned().fold(0.0, f64::max);
    let mut sq = 0.0;
    let mut cnt = 0usize;
    for (p, (hm, hr)) in md.chunks(bins).zip(rd.chunks(bins)).enumerate() {
        if ir[p] > 0.01 * peak {
            let d = mean_bin(hm) - mean_bin(hr);
            sq += d * d;
            cnt += 1;
        }
    }
    Metrics {
        total_ratio: md.iter().sum::<f64>() / rd.iter().sum::<f64>(),
        image_rel_l2: rel_l2(&im, &ir),
        pooled8_rel_l2: rel_l2(&pool(&md), &pool(&rd)),
        voxel_rel_l2: rel_l2(&md, &rd),
        mean_bin_global_delta: mean_bin(&profile(&md)) - mean_bin(&profile(&rd)),
        mean_bin_pixel_rms: (sq / cnt.max(1) as f64).sqrt(),
    }
}

/// A bumpy height field of `2 n²` triangles over [−0.2, 0.2]² at z ≈ 0.4 facing the wall (normals toward
/// −z), plus a small occluder triangle in front of it.
pub fn bumpy_surface_with_occluder(n: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, y) = (-0.2 + 0.4 * i as f32 / n as f32, -0.2 + 0.4 * j as f32 / n as f32);
            p.push(Vec3::new(x, y, 0.4 + 0.03 * (17.0 * x).sin() * (11.0 * y).cos()));
        }
    }
    let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
    let mut f = Vec::new();
    for i in 0..n {
        for j in 0..n {
            // (p01 − p00) × (p10 − p00) points to −z.
            f.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            f.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    let k = p.len() as u32;
    p.extend([Vec3::new(-0.05, -0.05, 0.2), Vec3::new(0.02, 0.1, 0.21), Vec3::new(0.12, -0.02, 0.19)]);
    f.push([k, k + 1, k + 2]);
    (p, f)
}
