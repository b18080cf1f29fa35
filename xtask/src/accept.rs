//! `cargo xtask accept <bunny|soap|reference|ggx|real|sensor|nonconfocal|relay|detail|holes|all> [--quick]`: the acceptance runs
//! (and the sensor comparison of the noise-aware fit against L2). Each scenario runs the product end to end through the
//! built `nlos` binary — `nlos render` (ground truth → transient), `nlos reconstruct --init lct`, `nlos eval`
//! of the LCT initial mesh and of the result against the ground truth — prints a table, checks the issue's
//! targets and writes the figures (metrics, wall and CPU time, the command) into its section of
//! `docs/results.md`, replacing the previous run's, then regenerates the README's status table from that
//! page ([`results::status_table`]; `cargo xtask status` does only the latter).
//!
//! Photon noise: the clean transient is rendered once by `nlos render` (cached in `out/accept/`), then the
//! counts are drawn with `SpadModel::ideal(PhotonBudget::PerMeasurement(N)).simulate(clean, seed)` — the
//! very call `nlos render --photons N --seed S` makes — so that several budgets and the SPAD scenario share
//! one (slow) render of the 70k-face bunny.
//!
//! `--threshold T` extracts the LCT surface with `nlos init --method lct --threshold T` and starts
//! `nlos reconstruct` from that mesh (the default Otsu mask covers about half of the bunny's silhouette).
//!
//! The binary is `$NLOS_BIN` when set (e.g. a copy that other builds in a shared `target/` cannot
//! overwrite mid-run), else `target/release/nlos`, built first with `cargo build --release -p nlos-cli`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod detail;
mod holes;
mod nonconfocal;
mod own_shapes;
mod preprocessed;
mod real;
mod relay;
mod results;
mod runner;
mod sensor;
mod shape;

use real::real;
pub(crate) use results::record;
pub use results::update_readme;
pub(crate) use runner::utc_now;
use runner::{
    Outcome, Ran, Runner, collision_check, fit_check, p, reconstruct_and_eval, reconstruct_args, reconstruct_args_list,
    s, with_photons,
};
use sensor::sensor;
use shape::{bunny, ggx, reference, seed_tag, soap};

const BUNNY: &str = "meshes/bunny_centered.obj";
const SOAP: &str = "meshes/soap_centered.obj";
const REFERENCE_DIR: &str = "reference";
const MEASURED_DIR: &str = "measured";
const JITTER: &str = "sensor/spad_jitter.mat";

/// Where the shared data live: `$NLOS_SHARED_DATA`, else `../shared/data` beside the workspace.
fn shared(path: &str) -> PathBuf {
    match std::env::var("NLOS_SHARED_DATA") {
        Ok(root) => PathBuf::from(root).join(path),
        Err(_) => crate::workspace_root().join("../shared/data").join(path),
    }
}

/// Options of a scenario run.
#[derive(Debug, Clone)]
struct Opts {
    /// Small, fast configuration (iteration on the pipeline, not acceptance figures).
    quick: bool,
    /// Photon budget per measurement of the synthetic captures.
    photons: f64,
    /// Seed of the Poisson draw of the synthetic captures (bunny, soap, GGX, sensor; default 1): another seed
    /// is another noise realisation, for telling a change's effect from the run-to-run spread. Its captures
    /// and run directories get a `_seedN` suffix.
    photon_seed: u64,
    /// Extra `nlos reconstruct` arguments (after `--`).
    extra: Vec<String>,
}

/// The metrics line of `nlos eval`.
#[derive(Debug, Clone, Copy, Default)]
struct Metrics {
    coverage: f64,
    coverage_within: f64,
    depth_interior: f64,
    depth_mean: f64,
    depth_median: f64,
    depth_rms: f64,
    chamfer: f64,
    normal_deg: f64,
    /// Over the vertices within `nlos_mesh::distance::FAR_FROM_REFERENCE` of the truth (`normal_error_near_deg`).
    normal_near_deg: f64,
    /// Vertices farther than that (`far_vertex_fraction`).
    far_fraction: f64,
}

impl Metrics {
    fn parse(line: &str) -> Result<Self, String> {
        let v: serde_json::Value = serde_json::from_str(line.trim()).map_err(|e| format!("nlos eval output: {e}"))?;
        let f = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
        Ok(Self {
            coverage: f("coverage"),
            coverage_within: f("coverage_within"),
            depth_interior: f("depth_error_mean_interior"),
            depth_mean: f("depth_error_mean"),
            depth_median: f("depth_error_median"),
            depth_rms: f("depth_error_rms"),
            chamfer: f("chamfer"),
            normal_deg: f("normal_error_mean_deg"),
            normal_near_deg: f("normal_error_near_deg"),
            far_fraction: f("far_vertex_fraction"),
        })
    }

    /// Better on the judged metrics: coverage within 5 mm higher, interior depth error and normal error
    /// lower (plain coverage is reported, not judged: an overhanging start wins it for free).
    fn better_than(&self, o: &Self) -> bool {
        self.coverage_within > o.coverage_within
            && self.depth_interior < o.depth_interior
            && self.normal_deg < o.normal_deg
    }

    fn row(&self, name: &str) -> String {
        format!(
            "| {name} | {:.1} % | {:.2} | {:.1} % | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} |",
            self.coverage_within * 100.0,
            self.depth_interior * 1e3,
            self.coverage * 100.0,
            self.depth_mean * 1e3,
            self.depth_median * 1e3,
            self.depth_rms * 1e3,
            self.chamfer * 1e3,
            self.normal_deg
        )
    }
}

const TABLE_HEAD: &str = "| mesh | coverage within 5 mm | depth inside (mm) | coverage | depth mean (mm) | median (mm) | \
                          RMS (mm) | Chamfer (mm) | normal err (°) |\n|---|---|---|---|---|---|---|---|---|";

/// A markdown section for `docs/results.md`.
struct Section {
    text: String,
    pass: bool,
}

fn check(text: &mut String, pass: &mut bool, what: &str, ok: bool) {
    *pass &= ok;
    let _ = writeln!(text, "- {} {what}", if ok { "PASS" } else { "FAIL" });
}

fn timing_line(o: &Outcome) -> String {
    format!("reconstruction: {:.0} s wall, {:.0} s CPU (children)", o.recon.wall_s, o.recon.cpu_s)
}

/// Runs the scenarios named by `args` and writes their sections of `docs/results.md`.
pub fn accept(root: &Path, args: &[String]) -> Result<(), String> {
    let mut opts = Opts { quick: false, photons: 1000.0, photon_seed: 1, extra: Vec::new() };
    let mut names = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--quick" => opts.quick = true,
            "--threshold" => {
                let t = it.next().ok_or("--threshold needs a value (otsu, a fraction or abs:VALUE)")?;
                set_threshold(t);
            }
            "--photon-seed" => {
                opts.photon_seed =
                    it.next().and_then(|v| v.parse().ok()).ok_or("--photon-seed needs a non-negative integer")?;
            }
            "--photons" => {
                opts.photons = it.next().and_then(|v| v.parse().ok()).ok_or("--photons needs a number")?;
            }
            "--" => {
                opts.extra = it.by_ref().cloned().collect();
            }
            "all" => names.extend(
                [
                    "bunny",
                    "reference",
                    "soap",
                    "sensor",
                    "ggx",
                    "real",
                    "preprocessed",
                    "nonconfocal",
                    "relay",
                    "detail",
                    "holes",
                ]
                .map(s),
            ),
            n @ ("bunny" | "soap" | "reference" | "ggx" | "real" | "preprocessed" | "sensor" | "nonconfocal"
            | "relay" | "detail" | "holes") => names.push(n.to_string()),
            other => return Err(format!("unknown scenario or option `{other}`; see `cargo xtask help`")),
        }
    }
    if names.is_empty() {
        return Err(
            "name a scenario: bunny, soap, reference, ggx, real, preprocessed, sensor, nonconfocal, relay, detail, holes or all"
                .into(),
        );
    }
    let mut r = Runner::new(root)?;
    let mut failed = Vec::new();
    for name in &names {
        println!("==== acceptance: {name}{} ====", if opts.quick { " (quick)" } else { "" });
        let first_cmd = r.log.len();
        let first_run = r.collisions.len();
        let t0 = Instant::now();
        let res = match name.as_str() {
            "bunny" => bunny(&mut r, &opts),
            "soap" => soap(&mut r, &opts),
            "reference" => reference(&mut r, &opts),
            "ggx" => ggx(&mut r, &opts),
            "real" => real(&mut r, &opts),
            "preprocessed" => preprocessed::preprocessed(&mut r, &opts),
            "nonconfocal" => nonconfocal::nonconfocal(&mut r, &opts),
            "relay" => relay::relay(&mut r, &opts),
            "detail" => detail::detail(&mut r, &opts),
            "holes" => holes::holes(&mut r, &opts),
            _ => sensor(&mut r, &opts),
        };
        let (text, pass) = match res {
            Ok(mut sec) => {
                collision_check(&mut sec.text, &mut sec.pass, &r.collisions[first_run..]);
                fit_check(&mut sec.text, &mut sec.pass, &r.collisions[first_run..]);
                (sec.text, sec.pass)
            }
            Err(e) => (format!("- ERROR: {e}\n"), false),
        };
        if !pass {
            failed.push(name.clone());
        }
        let mut md = format!(
            "## {name}{} — {} — {}\n\nmachine: {} cores; scenario wall time {:.0} s\n\n",
            if opts.quick { " (quick configuration)" } else { "" },
            if pass { "PASS" } else { "FAIL" },
            utc_now(),
            std::thread::available_parallelism().map_or(0, usize::from),
            t0.elapsed().as_secs_f64()
        );
        md.push_str(&text);
        md.push_str("\n<details><summary>commands</summary>\n\n```\n");
        for c in &r.log[first_cmd..] {
            md.push_str(c);
            md.push('\n');
        }
        md.push_str("```\n</details>\n");
        println!("{md}");
        // Quick runs check the pipeline; only acceptance configurations go on record.
        if !opts.quick {
            record(&r.root, name, &md)?;
        }
    }
    if failed.is_empty() { Ok(()) } else { Err(format!("scenarios not passing: {}", failed.join(", "))) }
}

fn set_threshold(t: &str) {
    THRESHOLD.with(|c| *c.borrow_mut() = Some(t.to_string()));
}

thread_local! {
    static THRESHOLD: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
}

/// The scenarios in the order of `docs/results.md`, with what each checks (the README's status table).
pub const SCENARIOS: [(&str, &str); 13] = [
    ("bunny", "the shared bunny, rendered at Tsai et al. 2019's setup, 1000 photons: coverage, depth error, time"),
    ("soap", "the shared soap bar (relief lettering), same setup: coverage, depth error, time"),
    ("reference", "the independent renderer's bunny (three bounces): coverage, depth error"),
    ("ggx", "a glossy (GGX) bunny at two roughnesses: the fitted roughness, the shape"),
    ("sensor", "SPAD counts (jitter, background): the sensor-aware fit against plain L2"),
    (
        "real",
        "the Stanford captures (chart, diffuse S, S and U), default command: time, the chart's plane, the letters",
    ),
    (
        "preprocessed",
        "the S and U as Tsai et al. preprocessed them (gated) and raw: the same letters at the same depths, no phantoms",
    ),
    (
        "nonconfocal",
        "bunny, soap, a figure with thin limbs, a dish and a ball, each by one laser at the centre and the corner × 64 × 64 \
         sensors; the bunny by 4 × 4 lasers × 32 × 32 sensors; the independent one-laser render: default command",
    ),
    (
        "relay",
        "paired spots on curved walls: the bunny behind a ±3 cm bend, the real general-NLOS capture (A, 2, figurine)",
    ),
    (
        "detail",
        "what the volume shows, the mesh keeps: the 40 cm chart's front-view detail, the general-NLOS capture thinned to every 4th spot",
    ),
    (
        "holes",
        "dark strips where the model is exact: a plate with slots, a plate with printed bars, a thin-stroked E, two plates apart, a curved object plain and with grey print; each as photon counts and as intensities — holes or print, never dents",
    ),
    (
        "znlos",
        "the Z-NLOS benchmark (`cargo xtask benchmark znlos DIR`): LCT, f-k and the fit against depth/normal maps",
    ),
    ("fuzz", "every reader a user reaches, fuzzed (`cargo xtask fuzz`): runs, coverage, crashes per target"),
];
