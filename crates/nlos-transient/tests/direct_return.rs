//! The capture's own timing response from its direct reflection off the wall
//! (`JitterResponse::from_direct_return`), on the real 40 cm chart capture: a peak at the start of the axis
//! (its rising side completed), a fall to half within about 11 mm of path, and the heavy tail that the shared
//! SPAD response lacks (docs/accuracy.md).

use nlos_transient::sensor::JitterResponse;

#[test]
fn chart_capture_response_has_its_heavy_tail() {
    let Some([chart, jitter]) =
        nlos_testdata::shared_all(["measured/data_resolution_chart_40cm.mat", "sensor/spad_jitter.mat"])
    else {
        return;
    };
    let t = nlos_transient::read(&chart).expect("chart capture");
    let r = JitterResponse::from_direct_return(&t).expect("the chart holds a direct return");
    let spad = JitterResponse::load(&jitter).expect("shared SPAD response");
    // The axis starts at the peak: the rising side is completed from the top's Gaussian (from_direct_return's
    // docs), 3σ before zero delay, and zero delay lies within a bin or two of the axis's first bin.
    let w = r.weights();
    let peak = w.iter().enumerate().fold(0, |b, (i, &v)| if v > w[b] { i } else { b });
    let before = peak as f64 * r.spacing();
    let zero_bins = -r.origin() / r.spacing() - peak as f64;
    assert!((8.0..=30.0).contains(&(peak as f64)), "{peak} bins completed before the maximum");
    assert!((-2.0..=0.6).contains(&zero_bins), "zero delay {zero_bins} bins after the maximum's start");
    let at = |mm: f64| w[peak + (mm * 1e-3 / r.spacing()).round() as usize] / w[peak];
    // Half maximum after 9–10 bins (11 mm of path); 5 % of the peak 120 mm later (docs/accuracy.md).
    let half = w[peak..].iter().position(|&v| v < 0.5 * w[peak]).expect("falls to half") as f64 * r.spacing();
    eprintln!(
        "own response: {:.1} mm of rising side completed, falls to half after {:.1} mm of path, {:.3} of the peak \
         at 48 mm, {:.3} at 120 mm; mean delay {:.1} mm (shared SPAD response {:.1} mm), {:.0} mm long",
        before * 1e3,
        half * 1e3,
        at(48.0),
        at(120.0),
        r.mean_delay() * 1e3,
        spad.mean_delay() * 1e3,
        w.len() as f64 * r.spacing() * 1e3
    );
    assert!((0.009..=0.013).contains(&half), "half maximum after {half} m");
    assert!((0.15..=0.21).contains(&at(48.0)), "{}", at(48.0));
    assert!((0.04..=0.065).contains(&at(120.0)), "{}", at(120.0));
    // The tail moves the mean delay far beyond the shared SPAD response's.
    assert!(r.mean_delay() > 5.0 * spad.mean_delay().max(1e-3), "{} vs {}", r.mean_delay(), spad.mean_delay());
}
