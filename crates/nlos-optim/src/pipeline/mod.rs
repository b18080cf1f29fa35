//! The whole reconstruction as users run it: a capture file in, a mesh out, every `auto` decided here.
//!
//! [`Config`] holds every setting a user may change, each with its default ([`Config::default`] takes them
//! from [`ReconstructParams::default`](crate::ReconstructParams::default) and the initialisers' defaults: one source). It reads and writes TOML
//! ([`Config::from_toml`], [`Config::to_toml`]; `nlos reconstruct --print-config` prints the defaults).
//! [`Prepared::new`] prepares the capture (rebin, gate, max depth, subsample), [`Prepared::params`] decides
//! the optimiser's parameters (noise model, sensor fit, background) and [`Prepared::initial_surface`]
//! extracts the start. `nlos reconstruct`, `cargo xtask reconstruct` and the Python package all go through
//! here, so a Rust caller gets the same run as the command line:
//!
//! [`run`] then owns the run directory: it writes the settings and the start surface and starts the
//! optimisation, or resumes it ([`Start`]).
//!
//! ```no_run
//! # fn demo() -> nlos_optim::Result<()> {
//! use nlos_optim::pipeline::{self, Config, Prepared, Start};
//! let config = Config::default();
//! let prepared = Prepared::load("capture.hdf5".as_ref(), &config)?;
//! let params = prepared.params(&config, Some("run".into()))?;
//! let outcome = pipeline::run(&prepared, &config, &params, Start::New, nlos_optim::Hooks::default())?;
//! println!("{} faces", outcome.mesh.n_faces());
//! # Ok(()) }
//! ```

mod choose;
mod config;
mod files;
mod prepared;
mod run_dir;

pub use choose::{Candidate, StartChoice, misfit_at_choice, saved_choice};
pub use config::{
    AlbedoChoice, BoundaryConfig, CaptureConfig, Config, FIELD_DOCS, InitMethod, Method, Noise, OptimiserConfig,
    ReflectanceConfig, RenderConfig, SensorChoice, SensorConfig, Setting, StartRim, VisibilityChoice, Word,
};
pub use files::{CANDIDATES_DIR, CHOICE_FILE, INIT_FILE, SETTINGS_FILE};
pub use prepared::{MAX_START_SLOPE, Prepared};
pub use run_dir::{Start, check_resumable, run, saved_config};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{OptimError, SensorBackground, SensorFit};
    use nlos_init::Model;
    use nlos_transient::Transient;
    use nlos_transient::sensor::BackgroundWindow;

    /// Every setting printed has its comment, and every comment names a setting.
    #[test]
    fn every_setting_is_documented() {
        let text = Config::default().to_toml().expect("toml");
        let mut section = String::new();
        let mut keys = Vec::new();
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                section = format!("{name}.");
            } else if let Some((key, _)) = line.split_once(" = ") {
                keys.push(format!("{section}{key}"));
            }
        }
        for key in &keys {
            assert!(FIELD_DOCS.iter().any(|(k, _)| k == key), "{key} has no comment");
        }
        for (k, _) in FIELD_DOCS {
            assert!(keys.iter().any(|key| key == k), "comment for {k}, which is not a setting");
        }
    }

    /// A raw capture holding its direct light and the same capture gated before it reached us (bins 0..600
    /// zeroed, as Tsai et al.'s files are) get the same sensor-fit floor: the level of the axis's last 10 %,
    /// bins both hold, here above the quiet bins' background because a late return reaches the axis's end;
    /// the gated capture scaled by a constant (not integers) gets the Poisson fit too, its floor scaled.
    #[test]
    fn a_raw_capture_and_its_gated_version_get_the_same_floor() {
        use nlos_transient::sensor::estimate_background;
        use nlos_transient::{PointSet, Scan, TimeAxis};
        let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.25, 0.25).expect("grid"));
        let bins = 1600;
        // A Gaussian rise (σ = 4 bins), then 90 % Gaussian fall and a 10 % diffusion tail (τ = 60 bins).
        let response = |j: f64| {
            let g = (-0.5 * (j / 4.0).powi(2)).exp();
            if j < 0.0 { g } else { 0.9 * g + 0.1 * (-j / 60.0).exp() }
        };
        let mut data = Vec::with_capacity(64 * bins);
        for m in 0..64 {
            let first = 1100.0 + (m / 4) as f64;
            data.extend((0..bins).map(|k| {
                let k = k as f64;
                let mean = 2.0e4 * response(k) + 40.0 * response(k - first) + 20.0 * response(k - 1500.0) + 1.0;
                mean.round() as f32
            }));
        }
        let raw = Transient::new(scan, TimeAxis::new(0.0, 0.0012, bins).expect("axis"), data).expect("capture");
        let mut gated = raw.clone();
        for m in 0..64 {
            gated.histogram_mut(m)[..600].fill(0.0);
        }
        assert_eq!((raw.zero_gate(), gated.zero_gate()), (None, Some(600)));
        let config = Config::default();
        let floor = |t: Transient| {
            let prepared = Prepared::new(t, &config).expect("prepare");
            assert!(prepared.gated);
            match prepared.params(&config, None).expect("params").sensor {
                Some(SensorFit { background: SensorBackground::Fixed(b), .. }) => b,
                other => panic!("{other:?}"),
            }
        };
        // The gated capture scaled by a constant (values no longer integers) is fitted alike, its floor scaled.
        let mut scaled = gated.clone();
        for m in 0..64 {
            scaled.histogram_mut(m).iter_mut().for_each(|v| *v *= 0.37);
        }
        let from_scaled = floor(scaled);
        let (from_raw, from_gated) = (floor(raw.clone()), floor(gated));
        assert!((from_scaled - 0.37 * from_gated).abs() < 1e-6 * from_gated, "{from_scaled} against {from_gated}");
        assert_eq!(from_raw, from_gated);
        let axis_end = estimate_background(&raw, BackgroundWindow::AxisEnd).expect("estimate");
        assert_eq!(from_raw, axis_end.per_bin);
        // The quiet bins between the direct light and the first return hold the background (1 per bin).
        let quiet = estimate_background(&raw, BackgroundWindow::Auto).expect("estimate");
        assert_eq!(quiet.per_bin, 1.0, "{quiet:?}");
        assert!(from_raw > 1.5, "the floor {from_raw} holds the late return");
    }

    /// The settings file spells the start as `nlos init --method` and `nlos reconstruct --init` do.
    #[test]
    fn init_is_written_by_name() {
        assert_eq!(Config::default().init, InitMethod::Auto);
        for (text, want) in [
            ("auto", InitMethod::Auto),
            ("pf", InitMethod::Volume(Method::Pf)),
            ("fbp", InitMethod::Volume(Method::Fbp)),
            ("start.obj", InitMethod::Mesh("start.obj".into())),
        ] {
            let c = Config::from_toml(&format!("init = \"{text}\"\n")).expect("parse");
            assert_eq!(c.init, want);
            assert_eq!(c.init.to_string(), text);
        }
    }

    /// `init_rim = "auto"` runs two starts only for the phasor field on a capture lit from one spot.
    #[test]
    fn auto_chooses_between_two_starts_for_one_lasers_phasor_field_only() {
        use glam::Vec3;
        use nlos_transient::{PointSet, Scan};
        let grid = || PointSet::wall_grid(4, 4, 0.25, 0.25).expect("grid");
        let one = || PointSet::list(vec![Vec3::ZERO]);
        let auto = |method, scan: &Scan| StartRim::Auto.resolve(method, scan);
        assert_eq!(auto(Method::Pf, &Scan::exhaustive(one(), grid())), StartRim::Choose);
        assert_eq!(auto(Method::Pf, &Scan::exhaustive(grid(), one())), StartRim::Choose, "one sensor spot");
        assert_eq!(auto(Method::Pf, &Scan::exhaustive(grid(), grid())), StartRim::Receding, "several lasers");
        assert_eq!(auto(Method::Pf, &Scan::paired(grid(), grid())), StartRim::Receding);
        assert_eq!(auto(Method::Lct, &Scan::confocal(grid())), StartRim::Receding);
        assert_eq!(StartRim::Choose.resolve(Method::Lct, &Scan::confocal(grid())), StartRim::Choose, "as asked");
    }

    #[test]
    fn overrides_change_only_the_fields_they_name() {
        let base = Config { seed: 7, ..Config::default() };
        let mut schedule = toml::Table::new();
        schedule.insert("max_stages".into(), toml::Value::Integer(2));
        let mut overrides = toml::Table::new();
        overrides.insert("schedule".into(), toml::Value::Table(schedule));
        let c = base.overridden(overrides).expect("valid");
        assert_eq!(c.schedule.max_stages, 2);
        assert_eq!(c.seed, 7, "a field not named keeps the base's value");
        assert_eq!(c.schedule.shape_iterations, base.schedule.shape_iterations);
        let mut bad = toml::Table::new();
        bad.insert("no_such_section".into(), toml::Value::Integer(1));
        assert!(matches!(base.overridden(bad), Err(OptimError::Config { .. })));
    }

    #[test]
    fn settings_round_trip_through_toml() {
        assert_eq!(Config::from_toml(&Config::default().to_toml().expect("toml")).expect("parse"), Config::default());
        let mut c = Config { seed: 9, init: InitMethod::Mesh("start.obj".into()), ..Config::default() };
        c.capture.gate = Setting::Value(0.3);
        c.capture.max_depth = Setting::OFF;
        c.sensor.response = SensorChoice::File("jitter.mat".into());
        c.reflectance.model = Model::Ggx;
        c.schedule.max_stages = 2;
        c.boundary.residual_tilts = vec![30.0];
        assert_eq!(Config::from_toml(&c.to_toml().expect("toml")).expect("parse"), c);
        // Absent fields keep their defaults; integers are numbers too.
        let partial = Config::from_toml("[capture]\ngate = 1\n").expect("parse");
        assert_eq!(
            partial,
            Config {
                capture: CaptureConfig { gate: Setting::Value(1.0), ..CaptureConfig::default() },
                ..Config::default()
            }
        );
    }

    #[test]
    fn bad_settings_are_typed_errors_naming_the_field() {
        for (text, field) in [
            ("[capture]\ngate = \"lots\"\n", "gate"),
            ("[schedule]\nmax_stages = -1\n", "max_stages"),
            ("[render]\nvisibility = \"sometimes\"\n", "visibility"),
            ("no_such_setting = 1\n", "no_such_setting"),
            ("init_rim = \"sideways\"\n", "init_rim"),
            ("[capture\n", "capture"),
        ] {
            match Config::from_toml(text) {
                Err(OptimError::Config { reason, .. }) => assert!(reason.contains(field), "{text}: {reason}"),
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    #[test]
    fn a_renamed_setting_says_what_replaced_it() {
        let from_file = Config::from_toml("[schedule]\ntime_budget = 300\n");
        let mut set = toml::Table::new();
        set.insert("schedule".into(), toml::Value::Table(toml::toml! { time_budget = 300 }));
        for result in [from_file, Config::default().overridden(set)] {
            match result {
                Err(OptimError::Config { field, reason }) => {
                    assert_eq!(field, "schedule.time_budget");
                    assert!(reason.contains("renamed schedule.reference_seconds"), "{reason}");
                }
                other => panic!("{other:?}"),
            }
        }
        let renamed = Config::from_toml("[schedule]\nreference_seconds = 300\n").expect("the new name");
        assert_eq!(renamed.schedule.reference_seconds, 300.0);
    }
}
