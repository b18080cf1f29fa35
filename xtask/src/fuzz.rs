//! `cargo xtask fuzz [--minutes N] [--jobs J] [TARGET…]`: a fuzzing campaign of every target in `fuzz/` (or
//! the ones named), N minutes each (default 60), J at a time (default 1), with cargo-fuzz on the nightly
//! toolchain (installed with `cargo install cargo-fuzz` when missing). Each target's corpus lives in
//! `out/fuzz/corpus/TARGET`, seeded from the project's fixtures and the small shared files; crashes land in
//! `fuzz/artifacts/TARGET`. Each target is a row of the board, its section `fuzz TARGET` of `docs/results.md`
//! keyed to the target's source and the code it reaches ([`crate::board::inputs`]); a campaign on the same
//! code adds a line to the section (minutes, runs, coverage, crashes, date), one on other code starts it anew.
//! A target is done at 60 minutes in total with no crash, so short campaigns on different days complete it.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::accept;
use crate::board::FUZZ_TARGETS as TARGETS;

/// Seed files for a target's corpus (those that exist), relative to the workspace root; `prefix` is put
/// before each (the maps target's first byte picks the reader).
fn seeds(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let f = |p: &str, prefix: &[u8]| (PathBuf::from(p), prefix.to_vec());
    match target {
        "mat_v5" => vec![f("../shared/data/measured/data_resolution_chart_40cm.mat", b"")],
        "znlos_mat" => vec![f("../shared/data/znlos/bunny_8x8.mat", b"")],
        "hdf5" => vec![f("fixtures/builtin/capture.hdf5", b"")],
        "npy" | "grid" => vec![f("fixtures/builtin/capture.npy", b"")],
        "exr" => vec![f("fixtures/builtin/capture.exr", b"")],
        "maps" => {
            vec![f("../shared/data/znlos/bunny_depth.mat", &[1]), f("../shared/data/znlos/bunny_normal.mat", &[1])]
        }
        "mesh" => vec![f("fixtures/builtin/truth.obj", b"")],
        _ => Vec::new(),
    }
}

/// One target's campaign: runs, coverage, crashes.
struct Campaign {
    runs: Option<u64>,
    coverage: Option<u64>,
    crashes: usize,
    /// Minutes the campaign fuzzed (libFuzzer's count; the wall clock when it printed none).
    minutes: f64,
}

fn ensure_cargo_fuzz() -> Result<(), String> {
    let ok = Command::new("cargo").args(["+nightly", "fuzz", "--version"]).output().is_ok_and(|o| o.status.success());
    if ok {
        return Ok(());
    }
    println!("installing cargo-fuzz: cargo install cargo-fuzz");
    let status = Command::new("cargo").args(["install", "cargo-fuzz"]).status().map_err(|e| e.to_string())?;
    if status.success() { Ok(()) } else { Err("cargo install cargo-fuzz failed".into()) }
}

/// libFuzzer's artifacts that are failures (a `slow-unit-` file is not: see [`campaign`]).
const FAILURES: [&str; 4] = ["crash-", "leak-", "timeout-", "oom-"];

/// Files in `dir` whose names start with one of `prefixes`.
fn artifacts_named(dir: &Path, prefixes: &[&str]) -> usize {
    std::fs::read_dir(dir).map_or(0, |d| {
        d.filter_map(Result::ok)
            .filter(|e| prefixes.iter().any(|k| e.file_name().to_string_lossy().starts_with(k)))
            .count()
    })
}

fn campaign(root: &Path, target: &str, minutes: f64) -> Result<Campaign, String> {
    let corpus = root.join("out/fuzz/corpus").join(target);
    std::fs::create_dir_all(&corpus).map_err(|e| format!("{}: {e}", corpus.display()))?;
    for (i, (file, prefix)) in seeds(target).iter().enumerate() {
        if let Ok(bytes) = std::fs::read(root.join(file)) {
            let seed = corpus.join(format!("seed-{i}"));
            std::fs::write(&seed, [prefix.as_slice(), &bytes].concat())
                .map_err(|e| format!("{}: {e}", seed.display()))?;
        }
    }
    if target == "general_nlos" {
        // The pair target's input: the length of `data.mat` (u32, little-endian), which file to give, then both.
        let dir = root.join("../shared/data/measured/general_nlos");
        if let (Ok(data), Ok(setup)) = (std::fs::read(dir.join("data.mat")), std::fs::read(dir.join("setup.mat"))) {
            let len = u32::try_from(data.len()).map_err(|e| e.to_string())?;
            for which in [0u8, 1] {
                let seed = [len.to_le_bytes().as_slice(), &[which], &data, &setup].concat();
                std::fs::write(corpus.join(format!("seed-pair-{which}")), seed).map_err(|e| e.to_string())?;
            }
        }
    }
    if target == "settings" {
        let text = nlos_optim::pipeline::Config::default().to_toml().map_err(|e| e.to_string())?;
        std::fs::write(corpus.join("seed-defaults.toml"), text).map_err(|e| e.to_string())?;
    }
    let artifacts = root.join("fuzz/artifacts").join(target);
    let before = artifacts_named(&artifacts, &FAILURES);
    let slow_before = artifacts_named(&artifacts, &["slow-unit-"]);
    let secs = (minutes * 60.0).round().max(1.0) as u64;
    println!("==== fuzz {target}: {secs} s ====");
    let started = std::time::Instant::now();
    let out = Command::new("cargo")
        .current_dir(root)
        .args(["+nightly", "fuzz", "run", "-O", target])
        .arg(&corpus)
        .args(["--", &format!("-max_total_time={secs}"), "-print_final_stats=1", "-rss_limit_mb=4096"])
        .output()
        .map_err(|e| format!("cannot run cargo fuzz: {e}"))?;
    let log = String::from_utf8_lossy(&out.stderr);
    let stat = |key: &str| {
        log.lines()
            .rev()
            .find_map(|l| l.strip_prefix(key).and_then(|v| v.trim().trim_start_matches(':').trim().parse().ok()))
    };
    // The last status line: "#N DONE cov: C ft: …" (or the last "#N … cov: C").
    let coverage = log.lines().rev().find_map(|l| {
        let mut it = l.split_whitespace();
        it.position(|w| w == "cov:").and_then(|_| it.next()).and_then(|c| c.parse().ok())
    });
    // Failures are libFuzzer's crash-, leak-, timeout- and oom- files; a slow-unit- file only says an input
    // took over ten seconds of wall clock (a campaign at low priority on a busy machine writes them for inputs
    // that take a fraction of a second alone), and is reported apart.
    let after = artifacts_named(&artifacts, &FAILURES);
    let slow = artifacts_named(&artifacts, &["slow-unit-"]).saturating_sub(slow_before);
    if slow > 0 {
        println!("fuzz {target}: {slow} slow units in {} (inputs over 10 s of wall clock)", artifacts.display());
    }
    let crashes = after.saturating_sub(before) + usize::from(!out.status.success() && after == before);
    if !out.status.success() {
        eprintln!(
            "{}",
            log.lines().rev().take(30).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join("\n")
        );
    }
    // libFuzzer's own "Done N runs in S second(s)": the fuzzing time, without the build before it.
    let fuzzed = log.lines().rev().find_map(|l| {
        let rest = l.strip_prefix("Done ")?;
        let secs = rest.split(" runs in ").nth(1)?.split_whitespace().next()?;
        secs.parse::<f64>().ok()
    });
    let minutes = fuzzed.unwrap_or_else(|| started.elapsed().as_secs_f64()) / 60.0;
    println!("==== fuzz {target}: done after {minutes:.1} min, {crashes} crashes ====");
    Ok(Campaign { runs: stat("stat::number_of_executed_units"), coverage, crashes, minutes })
}

/// Minutes a target must be fuzzed in total, on the same code, to be done.
const DONE_MINUTES: f64 = 60.0;

/// One campaign's line of a target's table: `| date | minutes | runs | coverage | crashes |`.
fn campaign_line(c: &Campaign, date: &str) -> String {
    let n = |v: Option<u64>| v.map_or_else(|| "–".into(), |x| x.to_string());
    format!("| {date} | {:.1} | {} | {} | {} |", c.minutes, n(c.runs), n(c.coverage), c.crashes)
}

/// The campaign lines of a target's section (not its total).
fn campaign_lines(body: &str) -> Vec<String> {
    body.lines().filter(|l| l.starts_with("| 2") && l.matches('|').count() == 6).map(str::to_string).collect()
}

/// A target's section from its campaign lines: the total, and the verdict (FAIL on any crash, PASS at
/// [`DONE_MINUTES`] in total, measured before).
fn target_section(target: &str, what: &str, lines: &[String], date: &str) -> String {
    let cells: Vec<Vec<String>> = lines.iter().map(|l| l.split('|').map(|c| c.trim().to_string()).collect()).collect();
    let num = |c: &Vec<String>, k: usize| c.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    let minutes: f64 = cells.iter().map(|c| num(c, 2)).sum();
    let runs: f64 = cells.iter().map(|c| num(c, 3)).sum();
    let coverage = cells.iter().map(|c| num(c, 4)).fold(0.0, f64::max);
    let crashes: f64 = cells.iter().map(|c| num(c, 5)).sum();
    let verdict = if crashes > 0.0 {
        "FAIL".to_string()
    } else if minutes >= DONE_MINUTES - 0.5 {
        "PASS".to_string()
    } else {
        format!("measured ({minutes:.0} of {DONE_MINUTES:.0} min)")
    };
    format!(
        "## fuzz {target} — {verdict} — {date}\n\nReads {what}. `cargo xtask fuzz {target}` on this machine's {} cores \
         (cargo-fuzz, libFuzzer, AddressSanitizer), its corpus seeded from the fixtures and the small shared files and \
         kept between campaigns. The campaigns on the same code add up; done at {DONE_MINUTES:.0} minutes in total with \
         no crash.\n\n| campaign | minutes | runs | coverage | crashes |\n|---|---|---|---|---|\n{}\n\
         | total | {minutes:.1} | {runs:.0} | {coverage:.0} (most) | {crashes:.0} |\n\n{}\n",
        std::thread::available_parallelism().map_or(0, usize::from),
        lines.join("\n"),
        if crashes > 0.0 {
            format!("- FAIL {crashes:.0} crashes: see fuzz/artifacts/{target}")
        } else {
            format!(
                "- {} fuzzed {minutes:.1} of {DONE_MINUTES:.0} minutes with no crash",
                if verdict == "PASS" { "PASS" } else { "measured:" }
            )
        }
    )
}

/// Runs `cargo xtask fuzz ARGS`.
pub fn fuzz(root: &Path, args: &[String]) -> Result<(), String> {
    let usage = "usage: cargo xtask fuzz [--minutes N] [--jobs J] [TARGET...]";
    let mut minutes = 60.0;
    let mut jobs = 1usize;
    let mut chosen: Vec<&str> = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--minutes" => {
                minutes = it
                    .next()
                    .and_then(|m| m.parse::<f64>().ok())
                    .filter(|m| m.is_finite() && *m > 0.0)
                    .ok_or(format!("--minutes takes a positive number; {usage}"))?;
            }
            "--jobs" => {
                jobs = it
                    .next()
                    .and_then(|j| j.parse::<usize>().ok())
                    .filter(|j| *j > 0)
                    .ok_or(format!("--jobs takes a positive whole number; {usage}"))?;
            }
            t => match TARGETS.iter().find(|(n, _)| *n == t) {
                Some((n, _)) => chosen.push(n),
                None => return Err(format!("unknown target `{t}` (one of {:?}); {usage}", TARGETS.map(|t| t.0))),
            },
        }
    }
    ensure_cargo_fuzz()?;
    let todo: Vec<(&str, &str)> =
        TARGETS.iter().copied().filter(|(n, _)| chosen.is_empty() || chosen.contains(n)).collect();
    // Build every target first: parallel campaigns would otherwise queue on cargo's build lock.
    let status = Command::new("cargo")
        .current_dir(root)
        .args(["+nightly", "fuzz", "build", "-O"])
        .status()
        .map_err(|e| format!("cannot run cargo fuzz: {e}"))?;
    if !status.success() {
        return Err("cargo fuzz build failed".into());
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..jobs.min(todo.len()) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    let Some((name, what)) = todo.get(i) else { break };
                    let c = campaign(root, name, minutes);
                    results.lock().unwrap_or_else(std::sync::PoisonError::into_inner).push((i, *name, *what, c));
                }
            });
        }
    });
    let mut results = results.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
    results.sort_by_key(|r| r.0);
    let date = accept::utc_now();
    let mut failed = Vec::new();
    for (_, name, what, c) in results {
        let c = c?;
        if c.crashes > 0 {
            failed.push(name);
        }
        let row = format!("fuzz {name}");
        let doc = std::fs::read_to_string(root.join(crate::board::page::RESULTS)).unwrap_or_default();
        // The campaigns so far, when they ran on the code as it is.
        let mut fp = crate::board::inputs::Fingerprints::new(root);
        let mut lines = match crate::board::section(&doc, &row) {
            Some(body) if crate::board::staleness(&mut fp, body).is_none() => campaign_lines(body),
            _ => Vec::new(),
        };
        lines.push(campaign_line(&c, &date));
        accept::record(root, &row, &target_section(name, what, &lines, &date))?;
    }
    if failed.is_empty() { Ok(()) } else { Err(format!("crashes in {failed:?}: see fuzz/artifacts/")) }
}
