//! How a scenario runs the product: the built `nlos` binary with its wall and CPU time (`Runner`), the collision
//! records every run is judged on, the photon draw shared by the synthetic captures, and one reconstruction with
//! its evaluation (`reconstruct_and_eval`).

use nlos_transient::sensor::{PhotonBudget, SpadModel};

use crate::accept::{Instant, Metrics, Opts, THRESHOLD, check};
use crate::{Command, Path, PathBuf};

/// CPU seconds (user + system) of this process's waited-for children (`/proc/self/stat` fields 16–17).
pub(super) fn children_cpu_s() -> f64 {
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
pub(super) struct Ran {
    pub(super) stdout: String,
    pub(super) wall_s: f64,
    pub(super) cpu_s: f64,
}

pub(super) struct Runner {
    pub(super) bin: PathBuf,
    pub(super) out: PathBuf,
    pub(super) root: PathBuf,
    /// Command lines run, for the record.
    pub(super) log: Vec<String>,
    /// What each reconstruction's run log says of its self-intersections and its fit, in run order.
    pub(super) collisions: Vec<RunChecks>,
}

/// A reconstruction's self-intersection checks, collision handling and fit, from its `run_log.json`.
pub(super) struct RunChecks {
    /// The run's output directory's name.
    pub(super) run: String,
    /// Pairs the start's check found (repaired there by deleting faces).
    pub(super) start_pairs: usize,
    /// Checks after the start, and the pairs they found (the promise: none).
    pub(super) checks: usize,
    pub(super) pairs_after_start: usize,
    /// Shape steps, those whose motion was limited, and remeshing operations refused.
    pub(super) steps: u64,
    pub(super) steps_limited: u64,
    pub(super) remesh_refused: usize,
    /// How much of its capture the finished surface explains (None in a log without the record).
    pub(super) fit: Option<nlos_optim::FitQuality>,
}

impl RunChecks {
    pub(super) fn read(run_dir: &Path) -> Result<Self, String> {
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
            fit: log.fit,
        })
    }
}

/// The check every scenario ends with after the collisions' (issue "Every result says how well it explains
/// its capture"): each reconstruction's own verdict on its fit, the share of the light above the noise it
/// explains, from its run log; a run without the record, or one no better than an empty scene by more than the noise (`nlos_optim::FitQuality::explains_anything`), fails it.
pub(super) fn fit_check(text: &mut String, pass: &mut bool, runs: &[RunChecks]) {
    if runs.is_empty() {
        return;
    }
    let each: Vec<String> = runs
        .iter()
        .map(|c| match &c.fit {
            Some(f) => format!("{}: {}", c.run, f.describe()),
            None => format!("{}: no fit record in its run log", c.run),
        })
        .collect();
    let ok = runs.iter().all(|c| c.fit.is_some_and(|f| f.explains_anything()));
    check(
        text,
        pass,
        &format!(
            "every run explains more of its capture than an empty scene would, by more than the noise ({})",
            each.join("; ")
        ),
        ok,
    );
}

/// The check every scenario ends with (El Topo's promise): no self-intersection found after the start in any
/// of its reconstructions, with what collision handling did for it.
pub(super) fn collision_check(text: &mut String, pass: &mut bool, runs: &[RunChecks]) {
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
    pub(super) fn new(root: &Path) -> Result<Self, String> {
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
    pub(super) fn nlos(&mut self, args: &[String]) -> Result<Ran, String> {
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
            self.collisions.push(RunChecks::read(Path::new(dir))?);
        }
        Ok(Ran { stdout, wall_s, cpu_s })
    }

    pub(super) fn eval(&mut self, mesh: &Path, gt: &Path) -> Result<Metrics, String> {
        let r = self.nlos(&[s("eval"), p(mesh), s("--gt"), p(gt), s("--json")])?;
        let line = r.stdout.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or("");
        Metrics::parse(line)
    }

    /// The run's depth maps of the start and the result (the report's own PNGs) copied to
    /// `docs/img/{prefix}_depth_{init,final}.png`, as Markdown images for the results page.
    pub(super) fn depth_pictures(
        &self,
        run_dir: &Path,
        prefix: &str,
        name: &str,
        start: &str,
    ) -> Result<String, String> {
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
    pub(super) fn clean_render(
        &mut self,
        mesh: &Path,
        name: &str,
        args: &[String],
    ) -> Result<(PathBuf, Option<Ran>), String> {
        self.clean_render_as(mesh, name, "hdf5", args)
    }

    /// [`Runner::clean_render`] into a file with extension `ext` (its format: `npy` for a paired scan, which
    /// y-tal's HDF5 cannot hold).
    pub(super) fn clean_render_as(
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

pub(super) fn s(x: &str) -> String {
    x.to_string()
}

pub(super) fn p(x: &Path) -> String {
    x.to_string_lossy().into_owned()
}

/// Poisson counts from a clean capture, as `nlos render --photons N --seed S` draws them, written in the
/// format of `out`'s extension.
pub(super) fn with_photons(clean: &Path, photons: f64, seed: u64, out: &Path) -> Result<(), String> {
    let t = nlos_transient::read(clean).map_err(|e| e.to_string())?;
    let noisy =
        SpadModel::ideal(PhotonBudget::PerMeasurement(photons)).simulate(&t, seed).map_err(|e| e.to_string())?;
    let format = nlos_transient::Format::for_writing_extension(out).unwrap_or(nlos_transient::Format::Tal);
    nlos_transient::write(&noisy, out, format).map_err(|e| e.to_string())
}

/// The reconstruction arguments of the acceptance configuration (or the quick one).
pub(super) fn reconstruct_args(opts: &Opts) -> Vec<String> {
    args(opts, true)
}

/// [`reconstruct_args`] for a capture whose spots are a list (paired spots on a curved wall): the quick
/// configuration leaves out `--subsample`, which needs a grid.
pub(super) fn reconstruct_args_list(opts: &Opts) -> Vec<String> {
    args(opts, false)
}

fn args(opts: &Opts, grid: bool) -> Vec<String> {
    let mut a: Vec<String> = if opts.quick {
        let quick = [
            "--set",
            "schedule.max_stages=1",
            "--set",
            "schedule.max_blocks_per_stage=1",
            "--set",
            "schedule.shape_iterations=5",
            "--rebin",
            "2",
        ];
        let subsample: &[&str] = if grid { &["--subsample", "2"] } else { &[] };
        quick.into_iter().chain(subsample.iter().copied()).map(s).collect()
    } else {
        Vec::new()
    };
    a.extend(opts.extra.iter().cloned());
    a
}

/// The LCT mask threshold for `nlos init` (`--threshold` of `cargo xtask accept`), if any.
pub(super) fn threshold() -> Option<String> {
    THRESHOLD.with(|c| c.borrow().clone())
}

/// Result of one reconstruction scenario.
pub(super) struct Outcome {
    pub(super) init: Metrics,
    /// The f-k surface of the same capture (volume → surface, `nlos eval --volume`).
    pub(super) fk: Metrics,
    pub(super) result: Metrics,
    pub(super) recon: Ran,
    pub(super) run_dir: PathBuf,
}

pub(super) fn reconstruct_and_eval(
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
    let fk = r.nlos(&[s("eval"), s("--volume"), p(capture), s("--method"), s("fk"), s("--gt"), p(gt), s("--json")])?;
    let fk = Metrics::parse(fk.stdout.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or(""))?;
    Ok(Outcome { init, fk, result, recon, run_dir: run_dir.to_path_buf() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(name: &str, fit: Option<(f64, f64)>) -> RunChecks {
        RunChecks {
            run: name.into(),
            start_pairs: 0,
            checks: 1,
            pairs_after_start: 0,
            steps: 1,
            steps_limited: 0,
            remesh_refused: 0,
            fit: fit.map(|(data, empty)| nlos_optim::FitQuality {
                data,
                empty,
                noise_floor: Some(0.07),
                detection: None,
            }),
        }
    }

    #[test]
    fn the_fit_check_names_each_runs_share_and_fails_a_run_that_explains_nothing() {
        let (mut text, mut pass) = (String::new(), true);
        fit_check(&mut text, &mut pass, &[run("a", Some((0.0763, 0.9368))), run("b", Some((0.5, 0.93)))]);
        assert!(pass, "{text}");
        assert!(text.contains("a: explains 99 % of the light above the noise"), "{text}");
        assert!(text.contains("b: explains 50 %"), "{text}");
        // Better than empty, but by less than the noise (likelihood ratio below 9).
        let mut faint = run("e", Some((0.92, 0.93)));
        faint.fit = faint.fit.map(|f| nlos_optim::FitQuality { detection: Some(4.0), ..f });
        for bad in [run("c", Some((0.95, 0.93))), run("d", None), faint] {
            let (mut text, mut pass) = (String::new(), true);
            fit_check(&mut text, &mut pass, &[run("a", Some((0.0763, 0.9368))), bad]);
            assert!(!pass && text.starts_with("- FAIL"), "{text}");
        }
    }
}
