//! The `sensor` scenario: SPAD counts (measured jitter, background) fitted by the sensor-aware Poisson fit and by
//! plain L2.

use std::fmt::Write as _;

use nlos_transient::sensor::{JitterResponse, PhotonBudget, SpadModel};

use crate::accept::{
    BUNNY, JITTER, Opts, Runner, Section, TABLE_HEAD, check, p, reconstruct_and_eval, reconstruct_args, s, seed_tag,
    shared, timing_line,
};

pub(super) fn sensor(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    // The clean transient: the render at Tsai et al. 2019's setup of the shared bunny (64×64×1200 bins of 1.2 mm, the same
    // cached render as the `bunny` scenario). Its bins are 4 ps: the measured jitter (FWHM ≈ 37 ps, with
    // the SPAD's slow tail) spans about ten of them, so ignoring it (plain L2) visibly blurs and delays the
    // fitted transients, which is what the noise-aware fit is for.
    let mesh = shared(BUNNY);
    let jitter_file = shared(JITTER);
    let (clean, _) = r.clean_render(&mesh, "bunny", &[])?;
    let t = nlos_transient::read(&clean).map_err(|e| format!("{}: {e}", clean.display()))?;
    let jitter = JitterResponse::load(&jitter_file).map_err(|e| format!("{}: {e}", jitter_file.display()))?;
    let photons = (opts.photons / 10.0).max(10.0);
    // Low budget, jitter, background; an ideal counter otherwise (no pile-up, dead time or afterpulsing).
    let model = SpadModel {
        jitter: Some(jitter.clone()),
        // Ambient + dark counts of 0.01 per bin over the exposure (≈ 12 per 1200-bin histogram).
        background_rate: 0.01 * nlos_transient::SPEED_OF_LIGHT
            / (t.time().bin_width * SpadModel::default().rep_rate * SpadModel::default().exposure),
        afterpulse_probability: 0.0,
        dead_time: 0.0,
        pile_up: false,
        ..SpadModel::ideal(PhotonBudget::PerMeasurement(photons))
    };
    let counts = model.simulate(&t, opts.photon_seed).map_err(|e| e.to_string())?;
    let tag = seed_tag(opts);
    let capture = r.out.join(format!("sensor_{photons}ph{tag}.hdf5"));
    nlos_transient::write(&counts, &capture, nlos_transient::Format::Tal).map_err(|e| e.to_string())?;
    let base = reconstruct_args(opts);
    let plain = reconstruct_and_eval(r, &capture, &mesh, &r.out.join(format!("sensor_l2{tag}")), &base)?;
    // Both with the default command: plain L2 is what `auto` chooses for a capture without a direct
    // reflection; the noise-aware fit names the jitter file.
    let mut aware_args = vec![s("--sensor"), p(&jitter_file)];
    aware_args.extend(base);
    let aware = reconstruct_and_eval(r, &capture, &mesh, &r.out.join(format!("sensor_poisson{tag}")), &aware_args)?;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "capture: the render at Tsai et al. 2019's setup of the shared bunny as flux, {photons} signal photons per measurement, jitter `{}` (FWHM {:.0} ps), background {:.3} \
         counts per bin, seed {}\n",
        jitter_file.display(),
        jitter.fwhm_ps(),
        model.background_per_bin(t.time().bin_width),
        opts.photon_seed
    );
    let _ = writeln!(
        text,
        "{TABLE_HEAD}\n{}\n{}\n{}\n",
        plain.init.row("LCT start"),
        plain.result.row("plain L2"),
        aware.result.row("Poisson + jitter + background")
    );
    let _ = writeln!(text, "plain L2 {}  \nnoise-aware {}\n", timing_line(&plain), timing_line(&aware));
    let mut pass = true;
    let (a, b) = (aware.result, plain.result);
    check(
        &mut text,
        &mut pass,
        &format!(
            "noise-aware fit at least as accurate as L2 (coverage within 5 mm {:.1} vs {:.1} %, depth inside {:.2} vs \
             {:.2} mm)",
            a.coverage_within * 100.0,
            b.coverage_within * 100.0,
            a.depth_interior * 1e3,
            b.depth_interior * 1e3,
        ),
        a.coverage_within >= b.coverage_within && a.depth_interior <= b.depth_interior,
    );
    Ok(Section { text, pass })
}
