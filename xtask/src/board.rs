//! The board (`docs/results.md`): its rows, what each row is keyed to, and the commands that keep it current.
//!
//! - A row is a scenario of `cargo xtask accept`, the Z-NLOS benchmark, or one fuzz target. Each section
//!   records its inputs ([`inputs`]): the code of the `nlos` binary, the capture readers its files reach, the
//!   xtask sources that define it ([`scenario_sources`]) and the shared data it reads ([`scenario_data`]); a
//!   fuzz target's, its source and its readers. A row is stale only when one of those changed: a comment, a doc,
//!   a test, a benchmark or a lint attribute changes none of them.
//! - `cargo xtask accept --stale` ([`refresh`]) re-runs every stale row, one after another, longest first,
//!   each section written as it lands; a developer commits the batch as one "Board" commit.
//! - `cargo xtask guard` ([`guard::guard`]) runs a short subset in CI and fails when a check that the committed
//!   board shows passing fails on the code under test.

pub(crate) mod guard;
pub(crate) mod inputs;
mod legacy;
pub(crate) mod page;

use std::path::{Path, PathBuf};

use inputs::{Fingerprints, Inputs};

/// The package of the `nlos` binary: every scenario runs it.
pub(crate) const BINARY_PACKAGE: &str = "nlos-cli";

/// The xtask sources (relative to `xtask/src`) that define a scenario: how it runs the product
/// (`accept.rs`, `accept/runner.rs`) and its own module with those it uses. The board's bookkeeping
/// (`accept/results.rs`, this module) is not among them.
pub(crate) fn scenario_sources(name: &str) -> Vec<&'static str> {
    let own: &[&str] = match name {
        "bunny" | "soap" | "reference" | "ggx" => &["accept/shape.rs"],
        "sensor" => &["accept/sensor.rs", "accept/shape.rs"],
        "real" => &["accept/real.rs"],
        "preprocessed" => &["accept/preprocessed.rs"],
        "nonconfocal" => &["accept/nonconfocal.rs", "accept/own_shapes.rs"],
        "relay" => &["accept/relay.rs"],
        "detail" => &["accept/detail.rs", "accept/relay.rs"],
        "holes" => &["accept/holes.rs"],
        "znlos" => return vec!["znlos.rs"],
        _ => &[],
    };
    let mut v = vec!["accept.rs", "accept/runner.rs"];
    v.extend_from_slice(own);
    v
}

/// The shared files a scenario reads (relative to the shared data; a directory stands for all its files).
pub(crate) fn scenario_data(name: &str) -> &'static [&'static str] {
    const BUNNY: &str = "meshes/bunny_centered.obj";
    const SOAP: &str = "meshes/soap_centered.obj";
    const CHART: &str = "measured/data_resolution_chart_40cm.mat";
    const GENERAL: [&str; 2] = ["measured/general_nlos/data.mat", "measured/general_nlos/setup.mat"];
    match name {
        "bunny" | "ggx" => &[BUNNY],
        "soap" => &[SOAP],
        "reference" => &["reference/bunny_mc.hdf5", "reference/bunny_world.obj"],
        "sensor" => &[BUNNY, "sensor/spad_jitter.mat"],
        "real" => &[CHART, "measured/data_diffuse_s.mat", "measured/data_s_u.mat"],
        "preprocessed" => &["measured/data_s_u.mat", "measured/tsai_su_transient.mat"],
        "nonconfocal" => &[
            BUNNY,
            SOAP,
            "reference/bunny_single_mc.json",
            "reference/bunny_single_mc.npy",
            "reference/bunny_world.obj",
        ],
        "relay" => &[BUNNY, GENERAL[0], GENERAL[1]],
        "detail" => &[CHART, GENERAL[0], GENERAL[1]],
        "znlos" => &["znlos"],
        _ => &[],
    }
}

/// Where the shared data live: `$NLOS_SHARED_DATA`, else `../shared/data` beside the workspace (as the
/// scenarios find them).
pub(crate) fn shared(path: &str) -> PathBuf {
    match std::env::var("NLOS_SHARED_DATA") {
        Ok(root) => PathBuf::from(root).join(path),
        Err(_) => crate::workspace_root().join("../shared/data").join(path),
    }
}

/// The fuzz target of a row name `fuzz TARGET`.
pub(crate) fn fuzz_target(row: &str) -> Option<&str> {
    row.strip_prefix("fuzz ")
}

/// Every row of the board in the order of `docs/results.md`, with what it checks: the scenarios, then one row
/// per fuzz target.
pub(crate) fn rows() -> Vec<(String, String)> {
    let mut v = Vec::new();
    for (name, what) in crate::accept::SCENARIOS {
        if name == "fuzz" {
            for (target, reads) in crate::fuzz::TARGETS {
                v.push((format!("fuzz {target}"), format!("fuzzed (`cargo xtask fuzz {target}`): {reads}")));
            }
        } else {
            v.push((name.to_string(), what.to_string()));
        }
    }
    v
}

/// The components of row `name` now, for a run whose commands were `commands`.
pub(crate) fn row_inputs(fp: &mut Fingerprints, name: &str, commands: &[String]) -> Result<Inputs, String> {
    match fuzz_target(name) {
        Some(target) => fp.fuzz_inputs(target, crate::fuzz::readers(target)),
        None => fp.scenario_inputs(name, commands),
    }
}

/// The command lines in a section's `commands` block.
pub(crate) fn commands_of(body: &str) -> Vec<String> {
    let Some(i) = body.find("<summary>commands</summary>") else { return Vec::new() };
    body[i..]
        .lines()
        .skip(1)
        .skip_while(|l| !l.starts_with("```"))
        .skip(1)
        .take_while(|l| !l.starts_with("```"))
        .map(str::to_string)
        .collect()
}

/// Why a row's section no longer describes the code and data as they are now, or None when it does: the
/// components of its `inputs:` line that changed; a section from before inputs were recorded is compared at
/// the commit it names ([`legacy`]).
pub(crate) fn staleness(fp: &mut Fingerprints, name: &str, body: &str) -> Option<String> {
    if let Some(inputs) = Inputs::parse(body) {
        return fp.changed(&inputs);
    }
    if let Some(why) = body.lines().find_map(|l| l.strip_prefix(inputs::INPUTS_LINE)) {
        return Some(format!("inputs unknown: {why}"));
    }
    legacy::equivalent(fp, name, body).err()
}

/// The section of row `name` in `doc`, if any.
pub(crate) fn section<'a>(doc: &'a str, name: &str) -> Option<&'a str> {
    let (open, close) = (format!("<!-- scenario: {name} -->"), format!("<!-- end: {name} -->"));
    let i = doc.find(&open)? + open.len();
    let j = doc[i..].find(&close)? + i;
    Some(&doc[i..j])
}

/// Seconds a row last took: a scenario's "scenario wall time", the benchmark's "in all", a fuzz target's
/// campaign (`fuzz_minutes`); 0 when its section says none.
fn expected_seconds(name: &str, body: Option<&str>, fuzz_minutes: f64) -> f64 {
    if fuzz_target(name).is_some() {
        return fuzz_minutes * 60.0;
    }
    let body = body.unwrap_or_default();
    let after = |m: &str| body.split(m).nth(1)?.split_whitespace().next()?.parse::<f64>().ok();
    let before =
        |m: &str| body.split(m).next().filter(|b| b.len() < body.len())?.split_whitespace().last()?.parse().ok();
    after("scenario wall time ").or_else(|| before(" s in all")).unwrap_or(0.0)
}

/// The scenarios' cached renders (`out/accept/*_clean.*`) are made by the code that made them: removed when
/// the `nlos` binary's code is not what the last refresh ran.
fn invalidate_renders(root: &Path, fp: &mut Fingerprints) -> Result<(), String> {
    let code = fp.component(&format!("code {BINARY_PACKAGE}"))?;
    let out = root.join("out/accept");
    let key = out.join("renders.code");
    if std::fs::read_to_string(&key).is_ok_and(|k| k.trim() == code) {
        return Ok(());
    }
    if let Ok(dir) = std::fs::read_dir(&out) {
        for e in dir.flatten() {
            if e.file_name().to_string_lossy().contains("_clean.") {
                println!("removing {} (rendered by other code)", e.path().display());
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    std::fs::write(&key, &code).map_err(|e| format!("{}: {e}", key.display()))
}

/// `cargo xtask accept --stale [--fuzz-minutes M] [--dry-run]`: every stale row re-run, longest first, each
/// section written as it lands; a section from before inputs were recorded whose code is unchanged gets its
/// inputs line instead. Fuzz targets run M minutes each (default 5), adding to their total on the same code.
pub(crate) fn refresh(root: &Path, args: &[String]) -> Result<(), String> {
    let mut fuzz_minutes = 5.0;
    let mut dry = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--stale" => {}
            "--dry-run" => dry = true,
            "--fuzz-minutes" => {
                fuzz_minutes = it
                    .next()
                    .and_then(|m| m.parse::<f64>().ok())
                    .filter(|m| m.is_finite() && *m > 0.0)
                    .ok_or("--fuzz-minutes takes a positive number")?;
            }
            other => return Err(format!("`accept --stale` takes --fuzz-minutes M and --dry-run, not `{other}`")),
        }
    }
    let results = root.join(page::RESULTS);
    let mut doc = std::fs::read_to_string(&results).map_err(|e| format!("{}: {e}", results.display()))?;
    let mut fp = Fingerprints::new(root);
    let mut stale = Vec::new();
    for (name, _) in rows() {
        let current = doc.clone();
        let body = section(&current, &name);
        let why = match body {
            None => Some("never ran".to_string()),
            Some(b) if Inputs::parse(b).is_none() && !b.contains(inputs::INPUTS_LINE) => {
                match legacy::equivalent(&mut fp, &name, b) {
                    Ok(inputs) => {
                        let commit = legacy::commit_of(b).unwrap_or("?");
                        let what = if dry { "its inputs would be recorded" } else { "inputs recorded" };
                        println!("{name}: its code is as it ran ({commit}); {what}");
                        if !dry {
                            doc = page::replace_section(&doc, &name, &legacy::rekeyed(b, &inputs));
                        }
                        None
                    }
                    Err(why) => Some(why),
                }
            }
            Some(b) => staleness(&mut fp, &name, b),
        };
        if let Some(why) = why {
            stale.push((expected_seconds(&name, body, fuzz_minutes), name, why));
        }
    }
    if !dry {
        std::fs::write(&results, &doc).map_err(|e| format!("{}: {e}", results.display()))?;
        page::update_readme(root)?;
    }
    stale.sort_by(|a, b| b.0.total_cmp(&a.0));
    let total: f64 = stale.iter().map(|s| s.0).sum();
    println!("{} stale rows, about {:.0} min in all, longest first:", stale.len(), total / 60.0);
    for (secs, name, why) in &stale {
        println!("  {name} ({why}; about {:.0} min)", secs / 60.0);
    }
    if dry || stale.is_empty() {
        return Ok(());
    }
    invalidate_renders(root, &mut fp)?;
    let mut failed = Vec::new();
    for (_, name, _) in &stale {
        let res = match (fuzz_target(name), name.as_str()) {
            (Some(target), _) => crate::fuzz::fuzz(root, &[s("--minutes"), fuzz_minutes.to_string(), s(target)]),
            (None, "znlos") => crate::znlos::benchmark(&[s("znlos"), shared("znlos").to_string_lossy().into_owned()]),
            (None, scenario) => crate::accept::accept(root, &[s(scenario)]),
        };
        if let Err(e) = res {
            println!("{name}: {e}");
            failed.push(name.clone());
        }
    }
    let not_passing =
        if failed.is_empty() { String::new() } else { format!("; not passing or not run: {}", failed.join(", ")) };
    println!(
        "refreshed {} rows{not_passing}; commit docs/results.md, README.md and docs/img as one Board commit",
        stale.len()
    );
    Ok(())
}

fn s(x: &str) -> String {
    x.to_string()
}
