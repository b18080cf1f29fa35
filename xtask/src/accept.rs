//! `cargo xtask accept <bunny|soap|reference|ggx|real|sensor|nonconfocal|relay|all> [--quick]`: the acceptance runs
//! (and the sensor comparison of the noise-aware fit against L2). Each scenario runs the product end to end through the
//! built `nlos` binary — `nlos render` (ground truth → transient), `nlos reconstruct --init lct`, `nlos eval`
//! of the LCT initial mesh and of the result against the ground truth — prints a table, checks the issue's
//! targets and writes the figures (metrics, wall and CPU time, the command) into its section of
//! `docs/results.md`, replacing the previous run's, then regenerates the README's status table from that
//! page ([`status_table`]; `cargo xtask status` does only the latter).
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
use std::process::Command;
use std::time::Instant;

use nlos_transient::sensor::{JitterResponse, PhotonBudget, SpadModel};

mod nonconfocal;
mod preprocessed;
mod relay;

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

/// CPU seconds (user + system) of this process's waited-for children (`/proc/self/stat` fields 16–17).
fn children_cpu_s() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else { return f64::NAN };
    // Fields after the `(comm)` part; cutime and cstime are fields 16 and 17 (1-based) of the whole line.
    let rest = s.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    // rest starts at field 3 (state): field n is f[n − 3].
    let tick = 100.0; // USER_HZ on Linux
    let get = |n: usize| f.get(n - 3).and_then(|x| x.parse::<f64>().ok()).unwrap_or(f64::NAN);
    (get(16) + get(17)) / tick
}

pub(crate) fn utc_now() -> String {
    Command::new("date")
        .args(["-u", "+%Y-%m-%d"])
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map_or_else(|| "?".into(), |s| s.trim().to_string())
}

/// One timed `nlos` invocation.
struct Ran {
    stdout: String,
    wall_s: f64,
    cpu_s: f64,
}

struct Runner {
    bin: PathBuf,
    out: PathBuf,
    root: PathBuf,
    /// Command lines run, for the record.
    log: Vec<String>,
    /// What each reconstruction's self-intersection checks found, in run order.
    collisions: Vec<Collisions>,
}

/// A reconstruction's self-intersection checks and collision handling, from its `run_log.json`.
struct Collisions {
    /// The run's output directory's name.
    run: String,
    /// Pairs the start's check found (repaired there by deleting faces).
    start_pairs: usize,
    /// Checks after the start, and the pairs they found (the promise: none).
    checks: usize,
    pairs_after_start: usize,
    /// Shape steps, those whose motion was limited, and remeshing operations refused.
    steps: u64,
    steps_limited: u64,
    remesh_refused: usize,
}

impl Collisions {
    fn read(run_dir: &Path) -> Result<Self, String> {
        let path = run_dir.join("run_log.json");
        let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let log: nlos_optim::RunLog = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        let start = nlos_optim::IntersectionCheck::Start;
        let after = log.intersections.iter().filter(|r| r.check != start);
        Ok(Self {
            run: run_dir.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            start_pairs: log.intersections.iter().filter(|r| r.check == start).map(|r| r.pairs).sum(),
            checks: after.clone().count(),
            pairs_after_start: after.map(|r| r.pairs).sum(),
            steps: log.collisions.iter().map(|r| u64::from(r.steps)).sum(),
            steps_limited: log.collisions.iter().map(|r| u64::from(r.steps_limited)).sum(),
            remesh_refused: log.collisions.iter().map(|r| r.remesh_refused).sum(),
        })
    }
}

/// The check every scenario ends with (El Topo's promise): no self-intersection found after the start in any
/// of its reconstructions, with what collision handling did for it.
fn collision_check(text: &mut String, pass: &mut bool, runs: &[Collisions]) {
    if runs.is_empty() {
        return;
    }
    let pairs: usize = runs.iter().map(|c| c.pairs_after_start).sum();
    let checks: usize = runs.iter().map(|c| c.checks).sum();
    let each: Vec<String> = runs
        .iter()
        .map(|c| {
            format!(
                "{}: start {} pairs, after it {} in {} checks; {} of {} steps limited, {} remeshing operations refused",
                c.run, c.start_pairs, c.pairs_after_start, c.checks, c.steps_limited, c.steps, c.remesh_refused
            )
        })
        .collect();
    check(
        text,
        pass,
        &format!(
            "the surface never intersected itself after the start: {pairs} pairs in {checks} checks of {} runs ({})",
            runs.len(),
            each.join("; ")
        ),
        pairs == 0,
    );
}

impl Runner {
    fn new(root: &Path) -> Result<Self, String> {
        let bin = match std::env::var("NLOS_BIN") {
            Ok(b) => PathBuf::from(b),
            Err(_) => {
                println!("building the nlos binary: cargo build --release -p nlos-cli");
                let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
                let st = Command::new(cargo)
                    .current_dir(root)
                    .env("CARGO_INCREMENTAL", "0")
                    .args(["build", "--release", "-p", "nlos-cli"])
                    .status()
                    .map_err(|e| format!("cannot run cargo: {e}"))?;
                if !st.success() {
                    return Err("building nlos-cli failed".into());
                }
                root.join("target/release/nlos")
            }
        };
        let out = root.join("out/accept");
        std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
        Ok(Self { bin, out, root: root.to_path_buf(), log: Vec::new(), collisions: Vec::new() })
    }

    /// Runs `nlos ARGS`, echoing its output; fails on a non-zero exit.
    fn nlos(&mut self, args: &[String]) -> Result<Ran, String> {
        let line = format!("nlos {}", args.join(" "));
        println!("$ {line}");
        self.log.push(line.clone());
        let cpu0 = children_cpu_s();
        let t0 = Instant::now();
        let out = Command::new(&self.bin)
            .args(args)
            .stderr(std::process::Stdio::inherit())
            .output()
            .map_err(|e| format!("cannot run {}: {e}", self.bin.display()))?;
        let wall_s = t0.elapsed().as_secs_f64();
        let cpu_s = children_cpu_s() - cpu0;
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        print!("{stdout}");
        if !out.status.success() {
            return Err(format!("`{line}` failed ({})", out.status));
        }
        if args.first().is_some_and(|a| a == "reconstruct")
            && let Some(dir) = args.iter().position(|a| a == "--out").and_then(|i| args.get(i + 1))
        {
            self.collisions.push(Collisions::read(Path::new(dir))?);
        }
        Ok(Ran { stdout, wall_s, cpu_s })
    }

    fn eval(&mut self, mesh: &Path, gt: &Path) -> Result<Metrics, String> {
        let r = self.nlos(&[s("eval"), p(mesh), s("--gt"), p(gt)])?;
        let line = r.stdout.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or("");
        Metrics::parse(line)
    }

    /// The run's depth maps of the start and the result (the report's own PNGs) copied to
    /// `docs/img/{prefix}_depth_{init,final}.png`, as Markdown images for the results page.
    fn depth_pictures(&self, run_dir: &Path, prefix: &str, name: &str, start: &str) -> Result<String, String> {
        let mut pictures = Vec::new();
        for (which, file) in [(start, "depth_init.png"), ("result", "depth_final.png")] {
            let rel = format!("img/{prefix}_{file}");
            let (from, to) = (run_dir.join(file), self.root.join("docs").join(&rel));
            std::fs::copy(&from, &to).map_err(|e| format!("{} → {}: {e}", from.display(), to.display()))?;
            pictures.push(format!("![{name}: depth of the {which}]({rel})"));
        }
        Ok(pictures.join(" "))
    }

    /// The clean render of `mesh` (cached): `nlos render MESH --out FILE [ARGS]`.
    fn clean_render(&mut self, mesh: &Path, name: &str, args: &[String]) -> Result<(PathBuf, Option<Ran>), String> {
        self.clean_render_as(mesh, name, "hdf5", args)
    }

    /// [`Runner::clean_render`] into a file with extension `ext` (its format: `npy` for a paired scan, which
    /// y-tal's HDF5 cannot hold).
    fn clean_render_as(
        &mut self,
        mesh: &Path,
        name: &str,
        ext: &str,
        args: &[String],
    ) -> Result<(PathBuf, Option<Ran>), String> {
        let file = self.out.join(format!("{name}_clean.{ext}"));
        if file.exists() {
            println!("using the cached render {}", file.display());
            return Ok((file, None));
        }
        let mut a = vec![s("render"), p(mesh), s("--out"), p(&file)];
        a.extend_from_slice(args);
        let r = self.nlos(&a)?;
        Ok((file, Some(r)))
    }
}

fn s(x: &str) -> String {
    x.to_string()
}

fn p(x: &Path) -> String {
    x.to_string_lossy().into_owned()
}

/// Poisson counts from a clean capture, as `nlos render --photons N --seed S` draws them, written in the
/// format of `out`'s extension.
fn with_photons(clean: &Path, photons: f64, seed: u64, out: &Path) -> Result<(), String> {
    let t = nlos_transient::read(clean).map_err(|e| e.to_string())?;
    let noisy =
        SpadModel::ideal(PhotonBudget::PerMeasurement(photons)).simulate(&t, seed).map_err(|e| e.to_string())?;
    let format = nlos_transient::Format::for_writing_extension(out).unwrap_or(nlos_transient::Format::Tal);
    nlos_transient::write(&noisy, out, format).map_err(|e| e.to_string())
}

/// The reconstruction arguments of the acceptance configuration (or the quick one).
fn reconstruct_args(opts: &Opts) -> Vec<String> {
    let mut a: Vec<String> = if opts.quick {
        [
            "--set",
            "schedule.max_stages=1",
            "--set",
            "schedule.max_blocks_per_stage=1",
            "--set",
            "schedule.shape_iterations=5",
        ]
        .into_iter()
        .chain(["--subsample", "2", "--rebin", "2"])
        .map(s)
        .collect()
    } else {
        Vec::new()
    };
    a.extend(opts.extra.iter().cloned());
    a
}

/// The LCT mask threshold for `nlos init` (`--threshold` of `cargo xtask accept`), if any.
fn threshold() -> Option<String> {
    THRESHOLD.with(|c| c.borrow().clone())
}

/// Result of one reconstruction scenario.
struct Outcome {
    init: Metrics,
    /// The f-k surface of the same capture (volume → surface, `nlos eval --volume`).
    fk: Metrics,
    result: Metrics,
    recon: Ran,
    run_dir: PathBuf,
}

fn reconstruct_and_eval(
    r: &mut Runner,
    capture: &Path,
    gt: &Path,
    run_dir: &Path,
    args: &[String],
) -> Result<Outcome, String> {
    let _ = std::fs::remove_dir_all(run_dir);
    // `--threshold T`: the LCT surface is extracted by `nlos init` with that mask threshold (Otsu's default
    // keeps only the brightest columns: about half the bunny's silhouette), then passed as the mesh to
    // start from.
    let init = match threshold() {
        Some(t) => {
            std::fs::create_dir_all(run_dir).map_err(|e| format!("{}: {e}", run_dir.display()))?;
            let f = run_dir.join("lct_init.obj");
            r.nlos(&[s("init"), p(capture), s("--method"), s("lct"), s("--threshold"), t, s("--out"), p(&f)])?;
            p(&f)
        }
        None => s("lct"),
    };
    let mut a = vec![s("reconstruct"), p(capture), s("--out"), p(run_dir), s("--init"), init, s("--seed"), s("1")];
    a.extend([s("--quiet"), s("--gt"), p(gt)]);
    a.extend_from_slice(args);
    let recon = r.nlos(&a)?;
    let init = r.eval(&run_dir.join("init.obj"), gt)?;
    let result = r.eval(&run_dir.join("mesh.obj"), gt)?;
    let fk = r.nlos(&[s("eval"), s("--volume"), p(capture), s("--method"), s("fk"), s("--gt"), p(gt)])?;
    let fk = Metrics::parse(fk.stdout.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or(""))?;
    Ok(Outcome { init, fk, result, recon, run_dir: run_dir.to_path_buf() })
}

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

/// The judged targets of a shape scenario (the accuracy issue's decisions): coverage within 5 mm, the
/// mean depth error inside the silhouette, the normal error, and better than the LCT start and the f-k surface
/// on those three.
struct Targets {
    within: Option<f64>,
    interior_mm: f64,
    normal_deg: Option<f64>,
    /// Also judged: better than the LCT start and the f-k surface on the three.
    beat_baselines: bool,
}

/// A target for the page: at most two decimals, no trailing zeros (0.4·1.5 is 0.6000000000000001 in f64).
fn short(x: f64) -> String {
    let t = format!("{x:.2}");
    t.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn shape_section(
    title: &str,
    o: &Outcome,
    targets: &Targets,
    time_limit_s: Option<f64>,
    notes: &[String],
) -> (String, bool) {
    let mut t = String::new();
    let mut pass = true;
    let rows = [o.init.row("LCT start"), o.fk.row("f-k surface"), o.result.row(title)];
    let _ = writeln!(t, "{TABLE_HEAD}\n{}\n", rows.join("\n"));
    let _ = writeln!(t, "{}  ", timing_line(o));
    let _ = writeln!(t, "run directory: `{}`\n", o.run_dir.display());
    let r = &o.result;
    if let Some(within) = targets.within {
        check(
            &mut t,
            &mut pass,
            &format!("coverage within 5 mm {:.1} % ≥ {} %", r.coverage_within * 100.0, short(within * 100.0)),
            r.coverage_within >= within,
        );
    }
    check(
        &mut t,
        &mut pass,
        &format!(
            "depth error inside the silhouette {:.2} mm ≤ {} mm",
            r.depth_interior * 1e3,
            short(targets.interior_mm)
        ),
        r.depth_interior * 1e3 <= targets.interior_mm,
    );
    if let Some(deg) = targets.normal_deg {
        // Judged on the vertices on the surface; the rims that hang back along the line of sight are counted
        // apart (docs/accuracy.md: the data term keeps them, and cutting them costs coverage).
        check(
            &mut t,
            &mut pass,
            &format!(
                "normal error {:.1}° ≤ {deg}° on the vertices within {:.0} mm of the truth ({:.1} % of the vertices \
                 lie farther: rims and pieces, docs/accuracy.md; all vertices {:.1}°)",
                r.normal_near_deg,
                nlos_mesh::distance::FAR_FROM_REFERENCE * 1e3,
                r.far_fraction * 100.0,
                r.normal_deg
            ),
            r.normal_near_deg <= deg,
        );
    }
    if targets.beat_baselines {
        let judged = "coverage within 5 mm, depth error inside, normal error";
        check(&mut t, &mut pass, &format!("better than the LCT start on {judged}"), r.better_than(&o.init));
        check(&mut t, &mut pass, &format!("better than the f-k surface on {judged}"), r.better_than(&o.fk));
    }
    if let Some(limit) = time_limit_s {
        check(
            &mut t,
            &mut pass,
            &format!("reconstruction {:.0} s ≤ {:.0} s (10 min)", o.recon.wall_s, limit),
            o.recon.wall_s <= limit,
        );
    }
    for n in notes {
        let _ = writeln!(t, "- {n}");
    }
    (t, pass)
}

fn bunny_like(r: &mut Runner, opts: &Opts, name: &str, mesh: &Path, extra_notes: &[String]) -> Result<Section, String> {
    let (clean, render) = r.clean_render(mesh, name, &[])?;
    let tag = seed_tag(opts);
    let capture = r.out.join(format!("{name}_{}ph{tag}.hdf5", opts.photons));
    with_photons(&clean, opts.photons, opts.photon_seed, &capture)?;
    let o = reconstruct_and_eval(r, &capture, mesh, &r.out.join(format!("{name}{tag}")), &reconstruct_args(opts))?;
    let mut notes: Vec<String> = extra_notes.to_vec();
    notes.push(format!(
        "capture: Tsai et al. 2019's setup, {} photons per measurement (Poisson, seed {})",
        opts.photons, opts.photon_seed
    ));
    if let Some(rr) = render {
        notes.push(format!("render of the ground truth: {:.0} s wall, {:.0} s CPU", rr.wall_s, rr.cpu_s));
    }
    let limit = (!opts.quick).then_some(600.0);
    let targets = match name {
        "soap" => Targets { within: None, interior_mm: 0.3, normal_deg: None, beat_baselines: false },
        _ => Targets { within: Some(0.82), interior_mm: 0.4, normal_deg: Some(20.0), beat_baselines: true },
    };
    let (text, pass) = shape_section(name, &o, &targets, limit, &notes);
    Ok(Section { text, pass })
}

/// The suffix of captures and run directories drawn with another photon seed than 1.
fn seed_tag(opts: &Opts) -> String {
    if opts.photon_seed == 1 { String::new() } else { format!("_seed{}", opts.photon_seed) }
}

fn bunny(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    bunny_like(r, opts, "bunny", &shared(BUNNY), &[])
}

fn soap(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    // The soap bar has 30 edges shared by three faces: `nlos render` builds a half-edge mesh and refuses it,
    // so it renders the same triangles unwelded (every face on its own vertices, as `nlos eval` reads it).
    let gt = shared(SOAP);
    let unwelded = r.out.join("soap_unwelded.obj");
    let mesh = nlos_mesh::metrics::load_for_eval(&gt).map_err(|e| format!("{}: {e}", gt.display()))?;
    nlos_mesh::io::save(&mesh, &unwelded).map_err(|e| e.to_string())?;
    let note = format!(
        "rendered from the unwelded triangles (the input has 30 edges with three faces); the relief lettering, \
         judged by eye (depth minus its 25 mm local mean, final mesh beside the ground truth):\n\n  \
         ![relief of the soap bar: final mesh and ground truth]({SOAP_RELIEF})"
    );
    let section = bunny_like(r, opts, "soap", &unwelded, &[note])?;
    // The lettering is the soap's claim: its picture goes into the results page (a 45 kB PNG).
    let relief = r.out.join(format!("soap{}", seed_tag(opts))).join("relief.png");
    let dest = r.root.join("docs").join(SOAP_RELIEF);
    std::fs::copy(&relief, &dest).map_err(|e| format!("{} → {}: {e}", relief.display(), dest.display()))?;
    Ok(section)
}

/// The soap run's relief picture, relative to `docs/`.
const SOAP_RELIEF: &str = "img/soap_relief.png";

fn reference(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    let dir = shared(REFERENCE_DIR);
    let capture = dir.join("bunny_mc.hdf5");
    let gt = dir.join("bunny_world.obj");
    if !capture.exists() {
        return Err(format!("{} is missing", capture.display()));
    }
    let o = reconstruct_and_eval(r, &capture, &gt, &r.out.join("reference"), &reconstruct_args(opts))?;
    let notes = [s("capture: independent path tracer (bunny_mc, 393k spp, 4 mm bins, no noise model)")];
    let targets = Targets { within: Some(0.86), interior_mm: 0.4, normal_deg: None, beat_baselines: false };
    let (text, pass) = shape_section("reference bunny", &o, &targets, None, &notes);
    Ok(Section { text, pass })
}

/// GGX α of a finished run (its checkpoint's reflectance).
fn fitted_alpha(run_dir: &Path) -> Result<f64, String> {
    let f = run_dir.join("checkpoint.json");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&f).map_err(|e| format!("{}: {e}", f.display()))?)
        .map_err(|e| format!("{}: {e}", f.display()))?;
    let refl: nlos_optim::Reflectance =
        serde_json::from_value(v["reflectance"].clone()).map_err(|e| format!("{}: reflectance: {e}", f.display()))?;
    match refl.brdf().map_err(|e| e.to_string())? {
        nlos_render::AnyBrdf::Ggx(g) => Ok(f64::from(g.alpha())),
        nlos_render::AnyBrdf::Lambertian(_) => Err("the run fitted a Lambertian model".into()),
        nlos_render::AnyBrdf::Retroreflective(_) => Err("the run fitted a retroreflective model".into()),
    }
}

fn ggx(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    let mesh = shared(BUNNY);
    let mut text = String::new();
    let mut pass = true;
    for alpha in [0.2, 0.4] {
        let name = format!("ggx{alpha}");
        let (clean, _) = r.clean_render(&mesh, &name, &[s("--brdf"), s("ggx"), s("--alpha"), alpha.to_string()])?;
        let tag = seed_tag(opts);
        let capture = r.out.join(format!("{name}_{}ph{tag}.hdf5", opts.photons));
        with_photons(&clean, opts.photons, opts.photon_seed, &capture)?;
        let mut args = vec![s("--brdf"), s("ggx"), s("--set"), s("reflectance.alpha=0.3")];
        args.extend(reconstruct_args(opts));
        let o = reconstruct_and_eval(r, &capture, &mesh, &r.out.join(format!("{name}{tag}")), &args)?;
        let fit = fitted_alpha(&o.run_dir)?;
        let _ = writeln!(text, "\n#### α = {alpha} (fit starts at 0.3)\n");
        let notes = [
            format!("fitted α = {fit:.3}"),
            format!("capture: {} photons per measurement (Poisson, seed {})", opts.photons, opts.photon_seed),
        ];
        // Shape within a factor 1.5 of the Lambertian bunny's targets.
        let targets =
            Targets { within: Some(0.82 / 1.5), interior_mm: 0.4 * 1.5, normal_deg: None, beat_baselines: false };
        let (t, p) = shape_section(&name, &o, &targets, None, &notes);
        text.push_str(&t);
        pass &= p;
        check(
            &mut text,
            &mut pass,
            &format!("|α − {alpha}| = {:.3} ≤ 0.05", (fit - alpha).abs()),
            (fit - alpha).abs() <= 0.05,
        );
    }
    Ok(Section { text, pass })
}

fn real(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    let dir = shared(MEASURED_DIR);
    let mut text = String::new();
    let mut pass = true;
    for name in ["data_resolution_chart_40cm", "data_diffuse_s", "data_s_u"] {
        let capture = dir.join(format!("{name}.mat"));
        if !capture.exists() {
            let _ = writeln!(text, "- {name}: skipped, {} is missing", capture.display());
            continue;
        }
        let run_dir = r.out.join(name);
        let _ = std::fs::remove_dir_all(&run_dir);
        // The default command; the captures' reference code treats every scene but the diffuse S as
        // retroreflective (../shared/data/README.md).
        let mut a = vec![s("reconstruct"), p(&capture), s("--out"), p(&run_dir), s("--quiet")];
        if name != "data_diffuse_s" {
            a.extend([s("--brdf"), s("retroreflective")]);
        }
        a.extend(reconstruct_args(opts));
        let ran = r.nlos(&a)?;
        let mesh = nlos_mesh::io::load(run_dir.join("mesh.obj")).map_err(|e| e.to_string())?;
        let mut z: Vec<f32> = mesh.positions().iter().map(|q| q.z).collect();
        z.sort_by(f32::total_cmp);
        let median = z.get(z.len() / 2).copied().unwrap_or(f32::NAN);
        let q = |f: f64| z.get(((z.len().max(1) - 1) as f64 * f) as usize).copied().unwrap_or(f32::NAN);
        let (p10, p90) = (q(0.1), q(0.9));
        let pictures = r.depth_pictures(&run_dir, &format!("real_{name}"), name, "LCT start")?;
        let _ = writeln!(
            text,
            "\n#### {name}\n\n{} faces, median vertex depth {median:.4} m (10th–90th percentile {p10:.4}–{p90:.4} m); \
             {:.0} s wall, {:.0} s CPU\n\n{}\n",
            mesh.n_faces(),
            ran.wall_s,
            ran.cpu_s,
            pictures
        );
        if !opts.quick {
            check(&mut text, &mut pass, &format!("{:.0} s ≤ 600 s on this machine", ran.wall_s), ran.wall_s <= 600.0);
        }
        // The whole schedule: every stage started and ended by its own rule, none cut by the time budget.
        let log: nlos_optim::RunLog = serde_json::from_str(
            &std::fs::read_to_string(run_dir.join("run_log.json")).map_err(|e| format!("{name} run log: {e}"))?,
        )
        .map_err(|e| format!("{name} run log: {e}"))?;
        let edges = |f: fn(&nlos_optim::StageRecord) -> f64| {
            log.stages.iter().map(|r| format!("{:.1}", 1e3 * f(r))).collect::<Vec<_>>().join(", ")
        };
        check(
            &mut text,
            &mut pass,
            &format!(
                "the whole schedule ran: {} stages at {} mm edges (the schedule's {} mm), stop `{}`",
                log.stages.len(),
                edges(|r| r.edge_length),
                edges(|r| r.schedule_edge_length),
                ran.stdout.lines().rev().find_map(|l| l.split("stop: ").nth(1)).unwrap_or("?").trim()
            ),
            ran.stdout.contains("stop: all stages ran"),
        );
        if name.contains("chart") {
            // A plane: the 10th–90th percentile spread of the vertices' depths about their least-squares plane
            // within 10 mm (about two depth bins at --rebin 8; a fit that turns the print into relief spreads
            // over 60–80 mm).
            let (plane, spread) = plane_fit(mesh.positions());
            check(
                &mut text,
                &mut pass,
                &format!(
                    "chart flat: depths about the plane z = {:.4} {:+.4}·x {:+.4}·y spread {:.1} mm (10th–90th \
                     percentile) ≤ 10 mm",
                    plane[0],
                    plane[1],
                    plane[2],
                    spread * 1e3
                ),
                spread <= 0.010,
            );
            check(
                &mut text,
                &mut pass,
                &format!(
                    "chart plane at {median:.4} m, 0.410 ± 0.005 m (docs/accuracy.md; the summed histogram peaks at 0.425 m)"
                ),
                (f64::from(median) - 0.410).abs() <= 0.005,
            );
        } else {
            let _ = writeln!(text, "- letters: judged by eye in the depth maps above");
        }
    }
    Ok(Section { text, pass })
}

/// The least-squares plane `z = a + b·x + c·y` through the points, and the 10th–90th percentile spread of
/// their depths about it (metres). NaN for fewer than three points or a degenerate layout.
fn plane_fit(points: &[glam::Vec3]) -> ([f64; 3], f64) {
    // Normal equations, centred for conditioning.
    let n = points.len() as f64;
    let mean = points.iter().fold(glam::DVec3::ZERO, |a, p| a + p.as_dvec3()) / n.max(1.0);
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let d = p.as_dvec3() - mean;
        (sxx, sxy, syy, sxz, syz) =
            (sxx + d.x * d.x, sxy + d.x * d.y, syy + d.y * d.y, sxz + d.x * d.z, syz + d.y * d.z);
    }
    let det = sxx * syy - sxy * sxy;
    if points.len() < 3 || det.abs() <= 1e-18 || det.is_nan() {
        return ([f64::NAN; 3], f64::NAN);
    }
    let b = (sxz * syy - syz * sxy) / det;
    let c = (syz * sxx - sxz * sxy) / det;
    let a = mean.z - b * mean.x - c * mean.y;
    let mut r: Vec<f64> =
        points.iter().map(|p| f64::from(p.z) - (a + b * f64::from(p.x) + c * f64::from(p.y))).collect();
    r.sort_by(f64::total_cmp);
    let q = |f: f64| r[((r.len() - 1) as f64 * f) as usize];
    ([a, b, c], q(0.9) - q(0.1))
}

fn sensor(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
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
                ["bunny", "reference", "soap", "sensor", "ggx", "real", "preprocessed", "nonconfocal", "relay"].map(s),
            ),
            n @ ("bunny" | "soap" | "reference" | "ggx" | "real" | "preprocessed" | "sensor" | "nonconfocal"
            | "relay") => names.push(n.to_string()),
            other => return Err(format!("unknown scenario or option `{other}`; see `cargo xtask help`")),
        }
    }
    if names.is_empty() {
        return Err(
            "name a scenario: bunny, soap, reference, ggx, real, preprocessed, sensor, nonconfocal, relay or all"
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
            _ => sensor(&mut r, &opts),
        };
        let (text, pass) = match res {
            Ok(mut sec) => {
                collision_check(&mut sec.text, &mut sec.pass, &r.collisions[first_run..]);
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
pub const SCENARIOS: [(&str, &str); 11] = [
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
        "one laser × 64 × 64 sensors, 4 × 4 lasers × 32 × 32 sensors, the independent one-laser render: default command",
    ),
    (
        "relay",
        "paired spots on curved walls: the bunny behind a ±3 cm bend, the real general-NLOS capture (A, 2, figurine)",
    ),
    (
        "znlos",
        "the Z-NLOS benchmark (`cargo xtask benchmark znlos DIR`): LCT, f-k and the fit against depth/normal maps",
    ),
    ("fuzz", "every reader a user reaches, fuzzed (`cargo xtask fuzz`): runs, coverage, crashes per target"),
];

const RESULTS: &str = "docs/results.md";
const RESULTS_HEAD: &str = "# Results\n\n\
Generated by `cargo xtask accept <scenario>`: each section is the latest acceptance run of its scenario — the \
product end to end (`nlos render` → `nlos reconstruct` → `nlos eval`) with the default settings at full \
resolution — its figures, its checks and its commands. A new run replaces its section; history is in git. \
The README's status table is made from this page.\n";

/// Writes `md` (a section starting `## NAME — PASS|FAIL — DATE`) as the section of scenario `name` of
/// `docs/results.md`, replacing the previous one, and regenerates the README's status table.
pub(crate) fn record(root: &Path, name: &str, md: &str) -> Result<(), String> {
    let f = root.join(RESULTS);
    let doc = std::fs::read_to_string(&f).unwrap_or_else(|_| RESULTS_HEAD.to_string());
    // No machine paths in a tracked file: the workspace and the shared data are named relative to the root.
    let shared = root.join("../shared/data");
    let md = md
        .replace(&format!("{}/", root.display()), "")
        .replace(&format!("{}/", shared.canonicalize().unwrap_or(shared.clone()).display()), "../shared/data/");
    let doc = replace_section(&doc, name, md.trim_end());
    std::fs::write(&f, doc).map_err(|e| format!("{}: {e}", f.display()))?;
    update_readme(root)
}

fn markers(name: &str) -> (String, String) {
    (format!("<!-- scenario: {name} -->"), format!("<!-- end: {name} -->"))
}

/// `doc` with the section of `name` replaced by `body` (inserted in [`SCENARIOS`] order when absent).
pub fn replace_section(doc: &str, name: &str, body: &str) -> String {
    let mut sections: Vec<(String, String)> = Vec::new();
    for (scenario, _) in SCENARIOS {
        let (open, close) = markers(scenario);
        if scenario == name {
            sections.push((scenario.to_string(), body.to_string()));
        } else if let (Some(i), Some(j)) = (doc.find(&open), doc.find(&close)) {
            sections.push((scenario.to_string(), doc[i + open.len()..j].trim().to_string()));
        }
    }
    let head = SCENARIOS.iter().filter_map(|(n, _)| doc.find(&markers(n).0)).min().map_or(doc, |i| &doc[..i]);
    let mut out = head.trim_end().to_string();
    out.push('\n');
    for (scenario, body) in sections {
        let (open, close) = markers(&scenario);
        let _ = write!(out, "\n{open}\n{body}\n{close}\n");
    }
    out
}

/// The README's status table, made from `docs/results.md`: one row per scenario with its latest status,
/// date and the targets it missed.
pub fn status_table(results: &str) -> String {
    let mut t =
        String::from("| scenario | what it checks | latest run | status | targets missed |\n|---|---|---|---|---|\n");
    for (name, what) in SCENARIOS {
        let (open, close) = markers(name);
        let row = match (results.find(&open), results.find(&close)) {
            (Some(i), Some(j)) => {
                let body = &results[i + open.len()..j];
                let title = body.lines().find(|l| l.starts_with("## ")).unwrap_or_default();
                let parts: Vec<&str> = title.split(" — ").collect();
                let (status, date) = (parts.get(1).copied().unwrap_or("?"), parts.get(2).copied().unwrap_or("?"));
                let missed: Vec<&str> = body.lines().filter_map(|l| l.strip_prefix("- FAIL ")).collect();
                let missed = if missed.is_empty() { "—".to_string() } else { missed.join("; ") };
                format!("| [{name}](docs/results.md) | {what} | {date} | **{status}** | {missed} |")
            }
            _ => format!("| {name} | {what} | never | — | — |"),
        };
        t.push_str(&row);
        t.push('\n');
    }
    t
}

const STATUS_BEGIN: &str = "<!-- status: generated by cargo xtask status from docs/results.md -->";
const STATUS_END: &str = "<!-- end status -->";

/// `readme` with its status table regenerated from `results`; `None` when the README has no table markers.
pub fn readme_with_status(readme: &str, results: &str) -> Option<String> {
    let i = readme.find(STATUS_BEGIN)? + STATUS_BEGIN.len();
    let j = readme.find(STATUS_END)?;
    Some(format!("{}\n{}{}", &readme[..i], status_table(results), &readme[j..]))
}

/// `cargo xtask status`: rewrites the README's status table from `docs/results.md`.
pub fn update_readme(root: &Path) -> Result<(), String> {
    let (rf, sf) = (root.join("README.md"), root.join(RESULTS));
    let readme = std::fs::read_to_string(&rf).map_err(|e| format!("{}: {e}", rf.display()))?;
    let results = std::fs::read_to_string(&sf).map_err(|e| format!("{}: {e}", sf.display()))?;
    let new = readme_with_status(&readme, &results)
        .ok_or_else(|| format!("{}: no status table markers ({STATUS_BEGIN} … {STATUS_END})", rf.display()))?;
    std::fs::write(&rf, new).map_err(|e| format!("{}: {e}", rf.display()))
}

#[cfg(test)]
mod tests {
    use super::{plane_fit, readme_with_status, replace_section};

    #[test]
    fn sections_are_replaced_in_place_and_inserted_in_order() {
        let doc = replace_section("# Results\n", "soap", "## soap — FAIL — d1\n\n- FAIL x");
        let doc = replace_section(&doc, "bunny", "## bunny — PASS — d2");
        let doc = replace_section(&doc, "soap", "## soap — PASS — d3");
        assert!(doc.starts_with("# Results\n"));
        let (b, s) = (doc.find("## bunny").expect("bunny"), doc.find("## soap — PASS — d3").expect("soap"));
        assert!(b < s && !doc.contains("d1"), "{doc}");
    }

    #[test]
    fn the_readme_status_table_is_the_one_generated_from_docs_results() {
        let root = crate::workspace_root();
        let readme = std::fs::read_to_string(root.join("README.md")).expect("README");
        let results = std::fs::read_to_string(root.join("docs/results.md")).expect("docs/results.md");
        let generated = readme_with_status(&readme, &results).expect("the README has the status markers");
        assert!(generated == readme, "the README's status table is stale: run `cargo xtask status`");
    }
    use glam::Vec3;

    #[test]
    fn plane_fit_recovers_a_tilted_plane_and_its_spread() {
        // z = 0.41 + 0.02 x − 0.05 y, and every seventh point (14 %, spread over the grid) 20 mm behind it.
        let pts: Vec<Vec3> = (0..400)
            .map(|i| {
                let (x, y) = ((i % 20) as f32 * 0.01 - 0.1, (i / 20) as f32 * 0.01 - 0.1);
                let off = if i % 7 == 0 { 0.02 } else { 0.0 };
                Vec3::new(x, y, 0.41 + 0.02 * x - 0.05 * y + off)
            })
            .collect();
        let (p, spread) = plane_fit(&pts);
        assert!((p[1] - 0.02).abs() < 2e-3 && (p[2] + 0.05).abs() < 2e-3, "{p:?}");
        // 14 % of the points sit 20 mm behind: the 90th percentile is among them, the 10th among the rest.
        assert!((spread - 0.02).abs() < 1e-4, "{spread}");
        assert!(plane_fit(&pts[..2]).1.is_nan());
    }
}
