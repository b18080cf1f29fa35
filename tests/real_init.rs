//! `nlos init` with its defaults on each shared real capture puts the start where the light says: the median
//! depth of the start's vertices within 1 cm of the depth at which the summed histogram's first return
//! rises (computed here from the histogram alone, independently of the library's preparation); for the two
//! letters of `data_s_u`, a third of the start at that first return.
//!
//! What it catches: `nlos init` preparing a capture differently from `nlos reconstruct` — before they shared
//! `Prepared`, the 40 cm chart's start from `nlos init` lay at a median depth of 1.165 m (the bins after the
//! last return, background only, were reconstructed as surface).

use std::process::ExitCode;

mod common;
use common::scratch;

fn nlos(args: &[&str]) -> ExitCode {
    nlos_cli::run(std::iter::once("nlos").chain(args.iter().copied()))
}

/// The depth (metres, confocal: half the path) where the summed histogram's first return rises: the first
/// bin after the direct light (ended where the smoothed histogram stops falling) whose 6 mm box-smoothed
/// excess over the 10th-percentile background reaches half of the largest excess.
fn onset_depth(t: &nlos_transient::Transient) -> f64 {
    let ax = *t.time();
    let h = t.summed_histogram();
    let w = ((0.006 / ax.bin_width).round() as usize).max(1);
    let smooth: Vec<f64> = (0..h.len())
        .map(|k| {
            let (lo, hi) = (k.saturating_sub(w / 2), (k + w / 2 + 1).min(h.len()));
            h[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
        })
        .collect();
    // The direct light: from the largest bin of the first tenth down to the first local minimum.
    let head = ax.bins / 10;
    let peak = (0..head).fold(0, |b, k| if smooth[k] > smooth[b] { k } else { b });
    let mut end = peak;
    while end + 1 < smooth.len() && smooth[end + 1] <= smooth[end] {
        end += 1;
    }
    let mut sorted = smooth[end..].to_vec();
    sorted.sort_by(f64::total_cmp);
    let background = sorted[sorted.len() / 10];
    let max_excess = smooth[end..].iter().fold(0.0f64, |m, &v| m.max(v - background));
    let k = (end..smooth.len()).find(|&k| smooth[k] - background >= 0.5 * max_excess).expect("a return");
    0.5 * (ax.t0 + (k as f64 + 0.5) * ax.bin_width)
}

#[test]
fn nlos_init_defaults_put_each_real_capture_where_its_light_rises() {
    for name in ["data_resolution_chart_40cm", "data_diffuse_s", "data_s_u"] {
        let Some(capture) = nlos_testdata::shared(&format!("measured/{name}.mat")) else {
            nlos_testdata::skip(&format!("{name}: ../shared/data/measured/{name}.mat is absent"));
            continue;
        };
        let t = nlos_transient::read(&capture).expect("capture");
        let onset = onset_depth(&t);
        let out = scratch(&format!("real-init-{name}")).join("start.obj");
        let (c, o) = (capture.to_string_lossy().into_owned(), out.to_string_lossy().into_owned());
        assert_eq!(nlos(&["init", &c, "--out", &o]), ExitCode::SUCCESS, "{name}");
        let mesh = nlos_mesh::io::load(&out).expect("start");
        let mut z: Vec<f32> = mesh.positions().iter().map(|p| p.z).collect();
        z.sort_by(f32::total_cmp);
        let median = f64::from(z[z.len() / 2]);
        eprintln!("{name}: onset {onset:.4} m, start median {median:.4} m");
        if name == "data_s_u" {
            // Two letters: the S at the first return (0.57–0.72 m, tilted) and the U behind it (0.95–1.1 m), in
            // about equal parts of the start, so its median falls on either. What the light says is that the
            // start holds the first return: at least a third of its vertices from 5 cm before the onset to 15
            // cm after it.
            let near = z.iter().filter(|&&d| (onset - 0.05..=onset + 0.15).contains(&f64::from(d))).count();
            assert!(
                3 * near >= z.len(),
                "{name}: {near} of {} start vertices at the first return {onset:.4} m",
                z.len()
            );
        } else {
            assert!(
                (median - onset).abs() <= 0.01,
                "{name}: the start's median depth {median:.4} m, onset {onset:.4} m"
            );
        }
    }
}
