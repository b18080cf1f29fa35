//! `cargo xtask accept --stale [--fuzz-minutes M] [--dry-run]`: every stale row of the board re-run, longest
//! first, each section written as it lands ([`crate::board`]).

use std::path::Path;

use crate::accept::SCENARIOS;
use crate::board::inputs::Fingerprints;
use crate::board::{fuzz_target, page, rows, section, shared, staleness};

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

/// `cargo xtask accept --stale [--fuzz-minutes M] [--dry-run]`: every stale row re-run, longest first, each
/// section written as it lands. Fuzz targets run M minutes each (default 5), adding to their total on the same code.
pub fn refresh(root: &Path, args: &[String]) -> Result<(), String> {
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
    let doc = std::fs::read_to_string(&results).map_err(|e| format!("{}: {e}", results.display()))?;
    let mut fp = Fingerprints::new(root);
    let mut stale = Vec::new();
    for (name, _) in rows(&SCENARIOS) {
        let body = section(&doc, &name);
        let why = match body {
            None => Some("never ran".to_string()),
            Some(b) => staleness(&mut fp, b),
        };
        if let Some(why) = why {
            stale.push((expected_seconds(&name, body, fuzz_minutes), name, why));
        }
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
    crate::board::invalidate_renders(root, &mut fp)?;
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
