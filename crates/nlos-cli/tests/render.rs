//! End-to-end tests of `nlos render`: a square's transient peaks at its depth, the setup comes from a
//! capture file, photon counts are integers with the requested budget, and bad arguments are input errors.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient};

mod common;
use common::{nlos, text};

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    common::scratch("render", name)
}

/// A 0.2 m square facing the wall at 0.3 m, and a small setup capture (10 × 10 scan, 300 bins of 4 mm).
fn inputs(dir: &Path) -> (String, String) {
    let (h, d) = (0.1f32, 0.3f32);
    let positions = [Vec3::new(-h, -h, d), Vec3::new(h, -h, d), Vec3::new(h, h, d), Vec3::new(-h, h, d)];
    let mesh = nlos_mesh::SurfaceMesh::from_triangles(&positions, &[[0, 2, 1], [0, 3, 2]]).expect("mesh");
    let mesh_file = dir.join("square.obj");
    nlos_mesh::io::save(&mesh, &mesh_file).expect("save mesh");
    let scan = Scan::confocal(PointSet::wall_grid(10, 10, 0.25, 0.25).expect("grid"));
    let setup = Transient::zeros(scan, TimeAxis::new(0.0, 0.004, 300).expect("axis")).expect("setup");
    let setup_file = dir.join("setup.npy");
    nlos_transient::write(&setup, &setup_file, Format::NpyJson).expect("write setup");
    (mesh_file.to_string_lossy().into_owned(), setup_file.to_string_lossy().into_owned())
}

#[test]
fn renders_a_square_on_the_setup_of_a_capture() {
    let dir = scratch("square");
    let (mesh, setup) = inputs(&dir);
    let out = dir.join("square.hdf5");
    let r = nlos(&["render", &mesh, "--out", &out.to_string_lossy(), "--setup", &setup]);
    assert!(r.status.success(), "{}", text(&r));
    let t = nlos_transient::read(&out).expect("read rendered");
    assert_eq!((t.measurements(), t.bins()), (100, 300));
    let depth = t.summed_peak_depth(Some(0.0)).expect("depth");
    assert!((depth - 0.3).abs() < 0.006, "peak depth {depth} m, square at 0.3 m");
    // Photon counts: integers, about the requested budget per measurement.
    let counts = dir.join("counts.npy");
    let r = nlos(&["render", &mesh, "--out", &counts.to_string_lossy(), "--setup", &setup, "--photons", "500"]);
    assert!(r.status.success(), "{}", text(&r));
    let c = nlos_transient::read(&counts).expect("read counts");
    assert!(c.data().iter().all(|v| v.fract() == 0.0 && *v >= 0.0), "counts must be non-negative integers");
    let per_measurement = c.data().iter().map(|&v| f64::from(v)).sum::<f64>() / c.measurements() as f64;
    assert!((per_measurement - 500.0).abs() < 15.0, "{per_measurement} photons per measurement");
}

#[test]
fn renders_a_non_manifold_mesh() {
    // Three triangles sharing one edge (non-manifold, as in the shared soap bar): rendered as they are.
    let dir = scratch("nonmanifold");
    let (_, setup) = inputs(&dir);
    let obj = "v -0.1 -0.1 0.3\nv 0.1 -0.1 0.3\nv 0 0.1 0.3\nv 0 0.1 0.35\nv 0 0.1 0.4\nf 1 3 2\nf 1 4 2\nf 1 5 2\n";
    let mesh = dir.join("fin.obj");
    std::fs::write(&mesh, obj).expect("write obj");
    assert!(nlos_mesh::io::load(&mesh).is_err(), "the test mesh should be non-manifold");
    let out = dir.join("fin.npy");
    let r =
        nlos(&["render", &mesh.to_string_lossy(), "--out", &out.to_string_lossy(), "--setup", &setup, "--two-sided"]);
    assert!(r.status.success(), "{}", text(&r));
    let t = nlos_transient::read(&out).expect("read");
    assert!(t.data().iter().sum::<f32>() > 0.0, "nothing rendered");
}

/// A PLY's per-vertex albedo scales its faces' light: the square at albedo 0.25 renders a quarter of the
/// light at 1 (bit for bit the same shape), with one corner of a triangle at 0 the faces holding it are
/// darker, and a negative albedo is an input error naming the file.
#[test]
fn renders_a_plys_vertex_albedo() {
    let dir = scratch("albedo");
    let (mesh, setup) = inputs(&dir);
    let square = nlos_mesh::io::load(&mesh).expect("mesh");
    let total = |t: &Transient| t.data().iter().map(|&v| f64::from(v)).sum::<f64>();
    let with = |name: &str, albedo: &[f32]| {
        let ply = dir.join(format!("{name}.ply"));
        nlos_mesh::io::save_ply_with_albedo(&square, albedo, &ply).expect("ply");
        ply.to_string_lossy().into_owned()
    };
    let plain = render_with(&dir, &mesh, &setup, "plain", &[]);
    let quarter = render_with(&dir, &with("quarter", &[0.25; 4]), &setup, "quarter", &[]);
    for (q, p) in quarter.data().iter().zip(plain.data()) {
        assert!((q - 0.25 * p).abs() <= 1e-6 * p.abs().max(1e-30), "{q} against a quarter of {p}");
    }
    let dark = render_with(&dir, &with("dark", &[1.0, 1.0, 0.0, 1.0]), &setup, "dark", &[]);
    let ratio = total(&dark) / total(&plain);
    assert!(ratio > 0.5 && ratio < 0.9, "one dark corner of both faces keeps {ratio} of the light");
    let bad = dir.join("bad.ply");
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                  property float albedo\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let body = "0 0 0.3 1\n0.1 0 0.3 -1\n0 0.1 0.3 1\n3 0 2 1\n";
    std::fs::write(&bad, format!("{header}{body}")).expect("write ply");
    let out = dir.join("bad.npy");
    let r = nlos(&["render", &bad.to_string_lossy(), "--out", &out.to_string_lossy(), "--setup", &setup]);
    assert_eq!(r.status.code(), Some(2), "{}", text(&r));
    assert!(text(&r).contains("bad.ply"), "{}", text(&r));
}

#[test]
fn bad_arguments_are_input_errors() {
    let dir = scratch("bad");
    let (mesh, setup) = inputs(&dir);
    let out = dir.join("x.hdf5").to_string_lossy().into_owned();
    for extra in [
        vec!["--brdf", "phong"],
        vec!["--brdf", "ggx", "--alpha", "3"],
        vec!["--mode", "guess"],
        vec!["--mode", "mc", "--spp", "0"],
        vec!["--photons", "-1"],
    ] {
        let mut args = vec!["render", mesh.as_str(), "--out", out.as_str(), "--setup", setup.as_str()];
        args.extend(extra.iter().copied());
        let r = nlos(&args);
        assert_eq!(r.status.code(), Some(2), "{extra:?}: {}", text(&r));
    }
    let r = nlos(&["render", "missing.obj", "--out", &out, "--setup", &setup]);
    assert_eq!(r.status.code(), Some(2), "{}", text(&r));
    assert!(text(&r).contains("missing.obj"));
    let r = nlos(&["render", &mesh, "--out", &dir.join("x.txt").to_string_lossy(), "--setup", &setup]);
    assert_eq!(r.status.code(), Some(2), "{}", text(&r));
}

// ---- the SPAD model through `nlos render --photons N [--jitter …] [--background …] [--dead-time …]` ----

/// The square of [`inputs`] and a longer setup (10 × 10 scan, 400 bins of 4 mm = 1.6 m of path), so that
/// jitter tails and early background bins fit on the axis; returns (mesh, setup).
fn spad_inputs(dir: &Path) -> (String, String) {
    let (mesh, _) = inputs(dir);
    let scan = Scan::confocal(PointSet::wall_grid(10, 10, 0.25, 0.25).expect("grid"));
    let setup = Transient::zeros(scan, TimeAxis::new(0.0, 0.004, 400).expect("axis")).expect("setup");
    let setup_file = dir.join("setup400.npy");
    nlos_transient::write(&setup, &setup_file, Format::NpyJson).expect("write setup");
    (mesh, setup_file.to_string_lossy().into_owned())
}

/// `nlos render MESH --setup SETUP --out DIR/NAME.npy EXTRA…`, read back.
fn render_with(dir: &Path, mesh: &str, setup: &str, name: &str, extra: &[&str]) -> Transient {
    let out = dir.join(format!("{name}.npy"));
    let mut args = vec!["render", mesh, "--setup", setup, "--out"];
    let o = out.to_string_lossy().into_owned();
    args.push(&o);
    args.extend(extra);
    let r = nlos(&args);
    assert!(r.status.success(), "{extra:?}: {}", text(&r));
    nlos_transient::read(&out).expect("read rendered")
}

/// (sum, mean path, variance of the path) of the histogram summed over all measurements.
fn moments(t: &Transient) -> (f64, f64, f64) {
    let h = t.summed_histogram();
    let ax = t.time();
    let sum: f64 = h.iter().sum();
    let mean = h.iter().enumerate().map(|(k, v)| v * ax.bin_center(k)).sum::<f64>() / sum;
    let var = h.iter().enumerate().map(|(k, v)| v * (ax.bin_center(k) - mean).powi(2)).sum::<f64>() / sum;
    (sum, mean, var)
}

#[test]
fn jitter_widens_the_summed_histogram_by_its_variance() {
    let dir = scratch("jitter");
    let (mesh, setup) = spad_inputs(&dir);
    let plain = render_with(&dir, &mesh, &setup, "plain", &["--photons", "100000", "--seed", "1"]);
    let fwhm_ps = 200.0;
    let jit = render_with(&dir, &mesh, &setup, "jit", &["--photons", "100000", "--seed", "2", "--jitter-fwhm", "200"]);
    let (s0, m0, v0) = moments(&plain);
    let (s1, m1, v1) = moments(&jit);
    // A convolution with a zero-mean kernel of variance σ² adds σ² to the variance and keeps the mass and
    // the mean (up to Poisson noise of 10⁷ photons: ~1e-3 relative on the variance difference).
    let sigma = fwhm_ps * 1e-12 * nlos_transient::SPEED_OF_LIGHT / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
    let added = v1 - v0;
    assert!(
        (added / (sigma * sigma) - 1.0).abs() < 0.03,
        "variance grew by {added:.3e} m², expected {:.3e}",
        sigma * sigma
    );
    assert!((s1 / s0 - 1.0).abs() < 0.005, "photon totals {s0} vs {s1}");
    assert!((m1 - m0).abs() < 5e-4, "mean path moved from {m0} to {m1}");
    // The shared SPAD jitter file, when present, loads and widens the histogram too.
    if let Some(file) = nlos_testdata::shared("sensor/spad_jitter.mat") {
        let f = file.to_string_lossy().into_owned();
        let real = render_with(&dir, &mesh, &setup, "real", &["--photons", "100000", "--seed", "3", "--jitter", &f]);
        let (_, _, v2) = moments(&real);
        assert!(v2 > v0 * 1.001, "the measured SPAD response did not widen the histogram ({v0} → {v2})");
    }
}

#[test]
fn background_raises_the_early_bins_to_its_mean_and_info_reports_it() {
    let dir = scratch("background");
    let (mesh, setup) = spad_inputs(&dir);
    // `SpadModel::background_per_bin` = R·(Δ/c)·f_rep·T_exp; a rate giving ≈ 3 counts per 4 mm bin (10 MHz, 0.1 s).
    let model = nlos_transient::sensor::SpadModel {
        background_rate: 2.25e5,
        ..nlos_transient::sensor::SpadModel::ideal(nlos_transient::sensor::PhotonBudget::PerMeasurement(1.0))
    };
    let b = model.background_per_bin(0.004);
    assert!(b > 2.0 && b < 4.0, "{b}");
    let t = render_with(&dir, &mesh, &setup, "bg", &["--photons", "2000", "--seed", "5", "--background", "2.25e5"]);
    // Before the first return (path 0.6 m: the square at 0.3 m) only background is counted.
    let early: Vec<f64> = t.histograms().flat_map(|h| h[..140].iter().map(|&v| f64::from(v))).collect();
    let mean = early.iter().sum::<f64>() / early.len() as f64;
    let se = (b / early.len() as f64).sqrt();
    assert!((mean - b).abs() < 5.0 * se, "early bins hold {mean} counts on average, expected {b} ± {se}");
    let var = early.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (early.len() - 1) as f64;
    assert!((var / b - 1.0).abs() < 0.1, "Poisson background: variance {var}, mean {b}");
    // `nlos info` estimates that background and the signal photons.
    let file = dir.join("bg.npy");
    let r = nlos(&["info", &file.to_string_lossy(), "--json"]);
    assert!(r.status.success(), "{}", text(&r));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).expect("info json");
    let pc = &v["photon_counts"];
    let est = pc["background_per_bin"].as_f64().expect("background in info");
    assert!((est / b - 1.0).abs() < 0.05, "nlos info: background {est} per bin, simulated {b}");
    let signal = pc["signal_per_measurement"].as_f64().expect("signal in info");
    assert!((signal / 2000.0 - 1.0).abs() < 0.1, "nlos info: {signal} signal photons per measurement, simulated 2000");
    let r = nlos(&["info", &file.to_string_lossy()]);
    assert!(text(&r).contains("photon counts: background"), "{}", text(&r));
}

/// Physical units: a background of `R` counts per second puts `R·Δt` counts per bin into every laser period,
/// i.e. `R·Δt·f_rep·T_exp` per bin over the exposure (`Δt = Δ/c`). Regression test for
/// `SpadModel::background_per_bin` once computing `R·Δt·T_exp` (no `f_rep`), which made a realistic rate add
/// ~1e-9 counts per bin instead of ~0.013.
#[test]
fn background_rate_is_counts_per_second() {
    let dir = scratch("background-units");
    let (mesh, setup) = spad_inputs(&dir);
    // 1e6 counts/s, 13.3 ps bins, 10 MHz, 0.1 s: 1e6 · 1.334e-11 · 1e7 · 0.1 = 13.3 counts per bin.
    let t = render_with(&dir, &mesh, &setup, "bgu", &["--photons", "2000", "--background", "1e6", "--rep-rate", "1e7"]);
    let early: Vec<f64> = t.histograms().flat_map(|h| h[..140].iter().map(|&v| f64::from(v))).collect();
    let mean = early.iter().sum::<f64>() / early.len() as f64;
    let expected = 1e6 * 0.004 / nlos_transient::SPEED_OF_LIGHT * 1e7 * 0.1;
    assert!((mean / expected - 1.0).abs() < 0.05, "{mean} counts per bin, expected {expected}");
}

#[test]
fn dead_time_skews_the_histogram_early_as_first_photon_theory_predicts() {
    let dir = scratch("deadtime");
    let (mesh, setup) = spad_inputs(&dir);
    let flux = render_with(&dir, &mesh, &setup, "flux", &[]);
    // 2·10⁶ photons per measurement over 10⁶ laser cycles (10 MHz × 0.1 s): ~2 photons per cycle, deep
    // pile-up. The 50 ns hold-off ends before the next period (100 ns) with this 5.3 ns window: no cycle lost.
    let (n, cycles) = (2.0e6, 1.0e6);
    let piled = render_with(
        &dir,
        &mesh,
        &setup,
        "piled",
        &["--photons", "2e6", "--seed", "9", "--dead-time", "50e-9", "--rep-rate", "10e6"],
    );
    // Theory (Coates 1968): per cycle, bin k fires first with p_k = (1 − e^{−λ_k}) e^{−Σ_{j<k} λ_j},
    // λ_k = s·x_k / N, s scaling the flux to n photons per measurement on average. Each histogram skews
    // toward its early bins (the sum over measurements need not: the brightest, nearest spots saturate most).
    let x = flux.data();
    let s = n * flux.measurements() as f64 / x.iter().map(|&v| f64::from(v)).sum::<f64>();
    let ax = *flux.time();
    let mean_path = |h: &mut dyn Iterator<Item = f64>| {
        let (mut w, mut wp) = (0.0, 0.0);
        for (k, v) in h.enumerate() {
            (w, wp) = (w + v, wp + v * ax.bin_center(k));
        }
        (w, wp / w)
    };
    let (mut skew, mut worst, mut lost) = (0.0f64, 0.0f64, 0.0f64);
    for (m, h) in flux.histograms().enumerate() {
        let mut before = 0.0f64;
        let expected: Vec<f64> = h
            .iter()
            .map(|&v| {
                let lambda = s * f64::from(v) / cycles;
                let p = (1.0 - (-lambda).exp()) * (-before).exp();
                before += lambda;
                cycles * p
            })
            .collect();
        let (_, m_flux) = mean_path(&mut h.iter().map(|&v| f64::from(v)));
        let (total, m_theory) = mean_path(&mut expected.iter().copied());
        let (count, m_sim) = mean_path(&mut piled.histogram(m).iter().map(|&v| f64::from(v)));
        skew += (m_flux - m_theory) / flux.measurements() as f64;
        // In standard errors of the mean path over `count` detections drawn from the theoretical histogram.
        let var: f64 =
            expected.iter().enumerate().map(|(k, v)| v * (ax.bin_center(k) - m_theory).powi(2)).sum::<f64>() / total;
        worst = worst.max((m_sim - m_theory).abs() / (var / count).sqrt());
        lost += (total - count).abs() / total / flux.measurements() as f64;
    }
    assert!(skew > 2e-3, "theory: pile-up moves each histogram's mean path earlier by {skew} m on average");
    assert!(worst < 5.0, "simulated and theoretical mean paths differ by up to {worst} standard errors");
    assert!(lost < 0.01, "detections differ from theory by {lost} on average (relative)");
    let (sum_piled, _, _) = moments(&piled);
    assert!(sum_piled < 0.9 * n * flux.measurements() as f64, "pile-up must lose photons: {sum_piled}");
}

#[test]
fn bad_spad_arguments_are_input_errors() {
    let dir = scratch("bad-spad");
    let (mesh, setup) = inputs(&dir);
    let out = dir.join("x.npy").to_string_lossy().into_owned();
    for extra in [
        vec!["--jitter-fwhm", "100"],
        vec!["--background", "10"],
        vec!["--photons", "10", "--dead-time", "5e-8"],
        vec!["--photons", "10", "--jitter", "missing-jitter.mat"],
        vec!["--photons", "10", "--jitter-fwhm=-3"],
        vec!["--photons", "10", "--afterpulse", "1.5"],
        vec!["--photons", "10", "--background=-1"],
        vec!["--photons", "10", "--dead-time", "5e-8", "--rep-rate", "0"],
    ] {
        let mut args = vec!["render", mesh.as_str(), "--out", out.as_str(), "--setup", setup.as_str()];
        args.extend(extra.iter().copied());
        let r = nlos(&args);
        assert_eq!(r.status.code(), Some(2), "{extra:?}: {}", text(&r));
    }
}

/// `--device`: on a machine with no Vulkan driver (the loader pointed at none), `gpu` fails with the reason and
/// what to install, `auto` and `cpu` render on the CPU; where there is an adapter, `--mode splat --device gpu`
/// gives the CPU's transient to 1e-4 of its peak. `gpu` outside the splat rule, or with GGX, is refused.
#[cfg(feature = "gpu")]
#[test]
fn device_choice_and_the_gpu_without_a_driver() {
    let dir = scratch("device");
    let (mesh, setup) = inputs(&dir);
    let out = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let run = |device: &str, file: &str, no_driver: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_nlos"));
        c.args(["render", &mesh, "--setup", &setup, "--mode", "splat", "--device", device, "--out", file]);
        if no_driver {
            c.env("VK_DRIVER_FILES", "/nonexistent.json").env("VK_ICD_FILENAMES", "/nonexistent.json");
        }
        c.output().expect("run nlos")
    };
    let refused = run("gpu", &out("none.npy"), true);
    assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
    assert!(
        text(&refused).contains("no GPU adapter found") && text(&refused).contains("mesa-vulkan-drivers"),
        "{}",
        text(&refused)
    );
    for device in ["auto", "cpu"] {
        let ok = run(device, &out(&format!("{device}.npy")), true);
        assert!(ok.status.success(), "{device}: {}", text(&ok));
    }
    let read = |f: &str| nlos_transient::read(f).expect("transient").data().to_vec();
    if nlos_render::GpuRenderer::new().is_ok() {
        let gpu = run("gpu", &out("gpu.npy"), false);
        assert!(gpu.status.success(), "{}", text(&gpu));
        let (g, c) = (read(&out("gpu.npy")), read(&out("cpu.npy")));
        let peak = c.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        let err = g.iter().zip(&c).fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
        assert!(peak > 0.0 && err <= 1e-4 * peak, "GPU against CPU: {err} (peak {peak})");
    }
    for extra in [&["--mode", "exact"][..], &["--brdf", "ggx"][..]] {
        let mut args = vec!["render", &mesh, "--setup", &setup, "--device", "gpu", "--out"];
        let f = out("bad.npy");
        args.push(&f);
        if extra[0] != "--mode" {
            args.extend(["--mode", "splat"]);
        }
        args.extend(extra);
        let bad = nlos(&args);
        assert_eq!(bad.status.code(), Some(2), "{extra:?}: {}", text(&bad));
    }
}
