//! Which depth does `data_resolution_chart_40cm.mat` imply for the chart plane? Prints the evidence
//! recorded in `docs/chart-depth.md`:
//!
//! 1. the data alone: summed-histogram peak and onset, per-pixel histogram peaks and onsets over the
//!    chart's pixels;
//! 2. the SPAD timing response (`sensor/spad_jitter.mat`): FWHM, mean delay, the delay of its rising
//!    half-maximum;
//! 3. the volumetric methods: LCT, f-k and FBP argmax along depth (median over the chart's columns);
//! 4. self-consistency: a flat square (the chart's lateral extent) rendered with `nlos-render` at
//!    candidate depths, convolved with the measured timing response, fitted to every chart pixel's
//!    histogram (free scale and background per pixel): which depth reproduces the data best, and which
//!    summed-histogram peak and per-pixel peaks that depth predicts. Both radiometric models are tried:
//!    diffuse (cos²·cos²/r⁴, the renderer) and retroreflective (1/r⁴, the renderer's histogram times
//!    (r/d)⁴ per bin, exact for a plane parallel to the wall in a confocal scan).
//!
//! Run: `cargo run --release -p nlos-init --example chart_depth` (needs `../shared/data`; ~1–2 min).

use std::path::PathBuf;

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_init::{FbpParams, FkParams, Gate, LctParams, SurfaceParams, Volume, fbp, fk, lct, volume_to_surface};
use nlos_render::{DeterministicRule, Kernel, RenderParams, Renderer, Sampling, Visibility};
use nlos_transient::sensor::JitterResponse;
use nlos_transient::{TimeAxis, Transient};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/");

fn box_smooth(h: &[f64], w: usize) -> Vec<f64> {
    let half = w / 2;
    (0..h.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(h.len()));
            h[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect()
}

/// Bin of the maximum within `[lo, hi)` and the first bin of the rising edge (from the left of the
/// maximum, last bin below `frac × (max − base) + base`, +1), `base` the median of `[lo, lo + 100)`.
fn peak_and_onset(h: &[f64], lo: usize, hi: usize, frac: f64) -> (usize, f64) {
    let k = (lo..hi).fold(lo, |b, k| if h[k] > h[b] { k } else { b });
    let mut base: Vec<f64> = h[lo..(lo + 100).min(hi)].to_vec();
    base.sort_by(f64::total_cmp);
    let base = base[base.len() / 2];
    let level = base + frac * (h[k] - base);
    let j = (lo..k).rev().find(|&j| h[j] < level).unwrap_or(lo);
    // Linear interpolation of the crossing between bin centres j and j + 1.
    let x = j as f64 + (level - h[j]) / (h[j + 1] - h[j]).max(1e-30);
    (k, x)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn column_depths(vol: &Volume, cols: &[usize]) -> f64 {
    let (depth, _) = vol.depth_map(Some(0.3), Some(0.6)).expect("depth map");
    median(cols.iter().map(|&c| depth[c] as f64).collect())
}

fn main() {
    let path = PathBuf::from(DATA).join("measured/data_resolution_chart_40cm.mat");
    if !path.exists() {
        eprintln!("skipping: {} is absent", path.display());
        return;
    }
    let t = nlos_transient::read(&path).expect("chart");
    let ax = *t.time();
    let bin = ax.bin_width;
    println!("time axis: t0 {} m, bin {} m, {} bins", ax.t0, bin, ax.bins);
    let gate = t.direct_light_end();
    let g0 = (0..ax.bins).find(|&k| ax.bin_start(k) >= gate).expect("chart_depth");
    println!("direct light ends at {gate:.4} m of path (bin {g0})");
    let (lo, hi) = ((0.6 / bin) as usize, (1.1 / bin) as usize);

    // 1. Data alone.
    let summed = t.summed_histogram();
    let sm = box_smooth(&summed, 5);
    let (kp, on50) = peak_and_onset(&sm, lo, hi, 0.5);
    let (_, on10) = peak_and_onset(&sm, lo, hi, 0.1);
    println!(
        "summed histogram (5-bin box): peak bin {kp} → depth {:.4} m (raw-bin peak depth {:.4}); onset 10 % {:.4} m, \
         50 % {:.4} m",
        ax.bin_center(kp) / 2.0,
        t.summed_peak_depth(None).expect("chart_depth"),
        ax.t0 + (on10 + 0.5) * bin / 2.0,
        ax.t0 + (on50 + 0.5) * bin / 2.0,
    );

    // Chart pixels: the columns the LCT keeps (the same code as tests/real.rs).
    let lp = LctParams { bin_merge: 4, max_depth: Some(1.2), ..LctParams::default() };
    let vol = lct(&t, &lp).expect("lct");
    let s = volume_to_surface(&vol, &SurfaceParams::default()).expect("surface");
    let cols: Vec<usize> = (0..s.nx * s.ny).filter(|&c| s.mask[c]).collect();
    let (xs, ys): (Vec<f64>, Vec<f64>) = cols.iter().map(|&c| (vol.x.at(c % vol.nx), vol.y.at(c / vol.nx))).unzip();
    let bbox = (
        xs.iter().copied().fold(f64::INFINITY, f64::min),
        xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ys.iter().copied().fold(f64::INFINITY, f64::min),
        ys.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    println!(
        "chart pixels: {} (LCT mask), bounding box x {:.3}…{:.3}, y {:.3}…{:.3} m",
        cols.len(),
        bbox.0,
        bbox.1,
        bbox.2,
        bbox.3
    );
    let per_pixel = |h: &dyn Fn(usize) -> Vec<f64>| {
        let (mut pk, mut o50) = (Vec::new(), Vec::new());
        for &c in &cols {
            let hs = box_smooth(&h(c), 5);
            let (k, o) = peak_and_onset(&hs, lo, hi, 0.5);
            pk.push(ax.bin_center(k) / 2.0);
            o50.push(ax.t0 + (o + 0.5) * bin / 2.0);
        }
        (median(pk), median(o50))
    };
    let (pk, o50) = per_pixel(&|c| t.histogram(c).iter().map(|&v| v as f64).collect());
    println!("per-pixel (5-bin box), median over chart pixels: peak depth {pk:.4} m, 50 % onset {o50:.4} m");

    // 2. Timing response.
    let jitter = JitterResponse::load(PathBuf::from(DATA).join("sensor/spad_jitter.mat")).expect("jitter");
    let w = jitter.weights();
    let peak = w.iter().enumerate().fold(0, |b, (i, &v)| if v > w[b] { i } else { b });
    let left = (0..peak).rev().find(|&i| w[i] < 0.5 * w[peak]).expect("chart_depth");
    let left_delay = jitter.origin() + (left as f64 + 1.0) * jitter.spacing();
    println!(
        "SPAD response: FWHM {:.1} ps = {:.4} m of path, mean delay {:.4} m of path (mode = 0), rising half-maximum at \
         {left_delay:.4} m of path",
        jitter.fwhm_ps(),
        jitter.fwhm(),
        jitter.mean_delay(),
    );
    let kernel = jitter.to_bins(bin).expect("kernel");

    // 3. Volumetric methods.
    let l = column_depths(&vol, &cols);
    let f = column_depths(
        &fk(&t, &FkParams { bin_merge: 4, max_depth: Some(1.2), gate: Gate::Auto }).expect("chart_depth"),
        &cols,
    );
    let b = column_depths(
        &fbp(&t, &FbpParams { bin_merge: 4, max_depth: Some(1.2), ..FbpParams::default() }).expect("chart_depth"),
        &cols,
    );
    let l1 = column_depths(&lct(&t, &LctParams { bin_merge: 1, ..lp }).expect("chart_depth"), &cols);
    println!("argmax along depth, median over chart pixels: LCT {l:.4} m (1-bin: {l1:.4}), f-k {f:.4}, FBP {b:.4}");

    // The direct reflection off the wall (path 0) is the system's own impulse response, as far as it is
    // on the axis: print the start of the summed histogram.
    let head: Vec<String> = (0..24).map(|k| format!("{:.3}", summed[k] / summed[0].max(1e-30))).collect();
    println!("summed histogram, bins 0–23 relative to bin 0: {}", head.join(" "));

    // 5. (printed before 4) The same fit with the capture's own response: its falling side is the summed
    //    histogram's direct return (bins 0–99, relative to bin 0, where its maximum lies), its rising side,
    //    cut off by the axis, the SPAD's.
    let bins = (1.2 / bin) as usize;
    let time = TimeAxis::new(0.0, bin, bins).expect("chart_depth");
    let (w0, w1) = ((0.70 / bin) as usize, (1.05 / bin) as usize);
    let measured: Vec<Vec<f64>> =
        cols.iter().map(|&c| t.histogram(c)[w0..w1].iter().map(|&v| v as f64).collect()).collect();
    let own = {
        let k0 = kernel.weights()[(-kernel.first()) as usize];
        let mut w: Vec<f64> = kernel.weights()[..(-kernel.first()) as usize].to_vec();
        w.extend((0..100).map(|d| k0 * summed[d] / summed[0]));
        let total: f64 = w.iter().sum();
        nlos_transient::sensor::BinKernel::new(kernel.first(), w.iter().map(|v| v / total).collect())
            .expect("chart_depth")
    };
    let mean_delay: f64 = own.weights().iter().enumerate().map(|(i, w)| w * (own.first() + i as i64) as f64).sum();
    println!("own response: mean delay {:.4} m of path", mean_delay * bin);
    // One render per candidate depth, shared by both fits.
    let depths: Vec<f64> = (0..=18).map(|i| 0.402 + 0.001 * i as f64).collect();
    let renders: Vec<Vec<f32>> = depths.iter().map(|&d| render_plane(&t, &time, bbox, d as f32)).collect();
    let own_depths = depths.clone();
    let mut own_res = vec![vec![0.0f64; own_depths.len()]; 2];
    for (di, &d) in own_depths.iter().enumerate() {
        let b = own.apply(&renders[di], bins).expect("chart_depth");
        for (model, row) in own_res.iter_mut().enumerate() {
            let (mut num, mut den) = (0.0, 0.0);
            for (&c, y) in cols.iter().zip(&measured) {
                let m: Vec<f64> = (w0..w1)
                    .map(|k| {
                        let v = b[c * bins + k] as f64;
                        if model == 1 { v * ((k as f64 + 0.5) * bin / 2.0 / d).powi(4) } else { v }
                    })
                    .collect();
                let (rr, tot) = ls_residual(&m, y);
                num += rr;
                den += tot;
            }
            row[di] = num / den;
        }
    }
    for (m, name) in ["diffuse", "retroreflective"].iter().enumerate() {
        let r = &own_res[m];
        let i = (0..r.len()).fold(0, |b, i| if r[i] < r[b] { i } else { b });
        let d = if i > 0 && i + 1 < r.len() {
            own_depths[i] + 0.001 * 0.5 * (r[i - 1] - r[i + 1]) / (r[i - 1] - 2.0 * r[i] + r[i + 1])
        } else {
            own_depths[i]
        };
        println!("best fit ({name}, the capture's own response): depth {d:.4} m, relative residual {:.4}", r[i]);
    }
    if std::env::var_os("CHART_DEPTH_OWN_ONLY").is_some() {
        return;
    }

    // 4. Self-consistency with rendered planes: per depth, the model histograms of the chart pixels in the
    //    window, blurred by the measured response and optionally by an extra Gaussian (FWHM in metres of
    //    path) that stands for a wider system response than the shared SPAD's.
    let extras = [0.0, 0.008, 0.016];
    let extra_kernels: Vec<_> = extras
        .iter()
        .map(|&f| {
            if f > 0.0 {
                Some(JitterResponse::gaussian(f).expect("chart_depth").to_bins(bin).expect("chart_depth"))
            } else {
                None
            }
        })
        .collect();
    // residual[model][extra][depth], per-pixel residual[depth][pixel] (retro, no extra blur).
    let mut residual = vec![vec![vec![0.0f64; depths.len()]; extras.len()]; 2];
    let mut pixel_res = vec![vec![0.0f64; cols.len()]; depths.len()];
    println!("depth | model summed peak | per-pixel peak | per-pixel 50 % onset (diffuse, measured response only)");
    for (di, &d) in depths.iter().enumerate() {
        let blurred = kernel.apply(&renders[di], bins).expect("chart_depth");
        for (ei, ek) in extra_kernels.iter().enumerate() {
            let b = match ek {
                Some(k) => k.apply(&blurred, bins).expect("chart_depth"),
                None => blurred.clone(),
            };
            for (model, per_model) in residual.iter_mut().enumerate() {
                let (mut num, mut den) = (0.0, 0.0);
                for (pi, (&c, y)) in cols.iter().zip(&measured).enumerate() {
                    let m: Vec<f64> = (w0..w1)
                        .map(|k| {
                            let v = b[c * bins + k] as f64;
                            if model == 1 { v * ((k as f64 + 0.5) * bin / 2.0 / d).powi(4) } else { v }
                        })
                        .collect();
                    let (rr, tot) = ls_residual(&m, y);
                    num += rr;
                    den += tot;
                    if model == 1 && ei == 0 {
                        pixel_res[di][pi] = rr / tot.max(1e-30);
                    }
                }
                per_model[ei][di] = num / den;
            }
        }
        let sum: Vec<f64> =
            (0..bins).map(|k| (0..t.measurements()).map(|c| blurred[c * bins + k] as f64).sum()).collect();
        let (kp, _) = peak_and_onset(&box_smooth(&sum, 5), lo, bins - 1, 0.5);
        let mh = |c: usize| -> Vec<f64> {
            let mut v: Vec<f64> = blurred[c * bins..(c + 1) * bins].iter().map(|&x| x as f64).collect();
            v.resize(ax.bins, 0.0);
            v
        };
        let (mpk, mo50) = per_pixel(&mh);
        println!("{d:.3} | {:.4} | {mpk:.4} | {mo50:.4}", ax.bin_center(kp) / 2.0);
    }
    let best = |r: &[f64]| -> (f64, f64) {
        let i = (0..r.len()).fold(0, |b, i| if r[i] < r[b] { i } else { b });
        let d = if i > 0 && i + 1 < r.len() {
            let (a, b0, c) = (r[i - 1], r[i], r[i + 1]);
            depths[i] + 0.001 * 0.5 * (a - c) / (a - 2.0 * b0 + c)
        } else {
            depths[i]
        };
        (d, r[i])
    };
    for (m, name) in ["diffuse", "retroreflective"].iter().enumerate() {
        for (ei, e) in extras.iter().enumerate() {
            let (d, r) = best(&residual[m][ei]);
            println!(
                "best fit ({name}, extra blur FWHM {:.0} mm of path): depth {d:.4} m, relative residual {r:.4}",
                e * 1e3
            );
        }
    }
    // Per-pixel best depth (retroreflective, measured response): spread and tilt.
    let per: Vec<f64> = (0..cols.len())
        .map(|pi| best(&depths.iter().enumerate().map(|(di, _)| pixel_res[di][pi]).collect::<Vec<_>>()).0)
        .collect();
    let mut sorted = per.clone();
    sorted.sort_by(f64::total_cmp);
    let q = |f: f64| sorted[((sorted.len() - 1) as f64 * f) as usize];
    // Least squares z = a + b·x + c·y over the chart pixels.
    let (mut ata, mut atz) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    for (&c, &z) in cols.iter().zip(&per) {
        let r = [1.0, vol.x.at(c % vol.nx), vol.y.at(c / vol.nx)];
        for i in 0..3 {
            for j in 0..3 {
                ata[i][j] += r[i] * r[j];
            }
            atz[i] += r[i] * z;
        }
    }
    let sol = solve3(ata, atz);
    println!(
        "per-pixel best depth (retroreflective): median {:.4} m, quartiles {:.4}–{:.4} m; plane fit z = {:.4} + {:.4}·x + \
         {:.4}·y (m)",
        q(0.5),
        q(0.25),
        q(0.75),
        sol[0],
        sol[1],
        sol[2]
    );
}

/// Solves a 3 × 3 system by Cramer's rule.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> [f64; 3] {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut m = a;
        for i in 0..3 {
            m[i][k] = b[i];
        }
        *o = det(m) / d;
    }
    out
}

/// Σ (y − a·m − b)² at the least-squares a, b, and Σ (y − ȳ)².
fn ls_residual(m: &[f64], y: &[f64]) -> (f64, f64) {
    let n = m.len() as f64;
    let (sm, sy) = (m.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut smm, mut smy, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in m.iter().zip(y) {
        smm += (a - sm) * (a - sm);
        smy += (a - sm) * (b - sy);
        syy += (b - sy) * (b - sy);
    }
    let rr = if smm > 0.0 { syy - smy * smy / smm } else { syy };
    (rr, syy)
}

/// The chart's scan rendered for a Lambertian square over `bbox` (expanded by half a scan step) at depth
/// `d`, split into 8 × 8 quads, no occlusion; tent kernel (it keeps the mean arrival of the box, and its
/// continuity lets a capped quadrature rule, ≤ 16² samples per triangle and pixel, stay smooth: the
/// response blur that follows is ~9 bins wide).
fn render_plane(t: &Transient, time: &TimeAxis, bbox: (f64, f64, f64, f64), d: f32) -> Vec<f32> {
    let pad = 0.5 * 0.4 / 63.0;
    let (x0, x1, y0, y1) = ((bbox.0 - pad) as f32, (bbox.1 + pad) as f32, (bbox.2 - pad) as f32, (bbox.3 + pad) as f32);
    let n = 8u32;
    let mut p = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            p.push(Vec3::new(x0 + u * (x1 - x0), y0 + v * (y1 - y0), d));
        }
    }
    let mut tri = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, e) = (a + 1, a + n + 1, a + n + 2);
            // (v1 − v0) × (v2 − v0) = −z: faces the wall.
            tri.push([a, c, b]);
            tri.push([b, c, e]);
        }
    }
    let rule = DeterministicRule { max_level: 16, ..DeterministicRule::default() };
    let params = RenderParams {
        kernel: Kernel::Tent,
        visibility: Visibility::Off,
        sampling: Sampling::Deterministic(rule),
        ..RenderParams::default()
    };
    let r = Renderer::new(&p, &tri, t.scan(), time, params).expect("renderer");
    r.forward(&Lambertian::new(1.0f32).expect("chart_depth"))
}
