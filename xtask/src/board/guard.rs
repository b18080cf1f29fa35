//! `cargo xtask guard`: what CI checks of the board. A short subset of the scenarios ([`SUBSET`]: the bunny,
//! and the `holes` plate with slots) runs on the code under test with the board's own targets, and the guard
//! fails when a check that the committed `docs/results.md` shows passing fails now. Its sections go to
//! `out/guard/sections.md`, never into the board.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

use super::page::{CAPTURE_ENV, RESULTS};

/// The scenarios the guard runs, with the `holes` fixtures to run (`NLOS_ACCEPT_HOLES`; empty: all).
pub(crate) const SUBSET: [(&str, &str); 2] = [("bunny", ""), ("holes", "slots")];

/// A check of a section: the fixture heading it is under, its text with the figures masked, passed or not,
/// and its text.
#[derive(Debug, Clone, PartialEq)]
struct Check {
    heading: String,
    key: String,
    pass: bool,
    text: String,
}

/// `text` before its parenthesised detail, each number replaced by `#`: what a check checks, whatever it measured.
fn mask(text: &str) -> String {
    let head = text.split(" (").next().unwrap_or(text);
    let mut out = String::with_capacity(head.len());
    let mut in_number = false;
    for c in head.chars() {
        let digit = c.is_ascii_digit() || (in_number && (c == '.' || c == ','));
        if digit && !in_number {
            out.push('#');
        } else if !digit {
            out.push(c);
        }
        in_number = digit;
    }
    out
}

/// The checks of a section body (`- PASS …`, `- FAIL …`; an `- ERROR: …` line is a failed check of its own).
fn checks(body: &str) -> Vec<Check> {
    let mut heading = String::new();
    let mut out = Vec::new();
    for line in body.lines() {
        if let Some(h) = line.strip_prefix("#### ") {
            heading = h.trim().to_string();
        }
        let (pass, text) =
            match (line.strip_prefix("- PASS "), line.strip_prefix("- FAIL "), line.strip_prefix("- ERROR: ")) {
                (Some(t), _, _) => (true, t),
                (_, Some(t), _) => (false, t),
                (_, _, Some(t)) => (false, t),
                _ => continue,
            };
        let key = if line.starts_with("- ERROR") { "the scenario ran".to_string() } else { mask(text) };
        out.push(Check { heading: heading.clone(), key, pass, text: text.to_string() });
    }
    out
}

/// The checks of `now` that fail where the same check of `board` passes: matched by fixture heading, masked
/// text and occurrence, else by masked text and occurrence alone (the checks every scenario ends with sit under
/// its last fixture).
fn regressions(board: &str, now: &str) -> Vec<String> {
    let index = |cs: &[Check], by_heading: bool| {
        let mut seen: HashMap<(String, String), usize> = HashMap::new();
        cs.iter()
            .map(|c| {
                let h = if by_heading { c.heading.clone() } else { String::new() };
                let n = seen.entry((h.clone(), c.key.clone())).or_default();
                *n += 1;
                ((h, c.key.clone(), *n), c.clone())
            })
            .collect::<Vec<_>>()
    };
    let (b, n) = (checks(board), checks(now));
    let board_by_heading: HashMap<_, _> = index(&b, true).into_iter().collect();
    let board_by_key: HashMap<_, _> = index(&b, false).into_iter().collect();
    let mut out = Vec::new();
    let any_board_pass = b.iter().any(|c| c.pass);
    for ((with_h, c), (without_h, _)) in index(&n, true).into_iter().zip(index(&n, false)) {
        if c.pass {
            continue;
        }
        let before = board_by_heading.get(&with_h).or_else(|| board_by_key.get(&without_h));
        let was_passing = match before {
            Some(b) => b.pass,
            // The scenario did not run: a regression where the board shows it passing anything.
            None => c.key == "the scenario ran" && any_board_pass,
        };
        if was_passing {
            let was = before.map_or_else(|| "ran".to_string(), |b| b.text.clone());
            out.push(format!(
                "{}{} — board: PASS {was}",
                if c.heading.is_empty() { String::new() } else { format!("{}: ", c.heading) },
                c.text
            ));
        }
    }
    out
}

/// Runs `cargo xtask guard`.
pub(crate) fn guard(root: &Path, args: &[String]) -> Result<(), String> {
    if let Some(a) = args.first() {
        return Err(format!("`cargo xtask guard` takes no arguments, not `{a}`"));
    }
    let board_file = root.join(RESULTS);
    let board = std::fs::read_to_string(&board_file).map_err(|e| format!("{}: {e}", board_file.display()))?;
    let dir = root.join("out/guard");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let capture = dir.join("sections.md");
    let _ = std::fs::remove_file(&capture);
    // A render cached by other code is not this code's (a clean checkout, as in CI, has none).
    super::invalidate_renders(root, &mut super::inputs::Fingerprints::new(root))?;
    let exe = std::env::current_exe().map_err(|e| format!("the xtask binary: {e}"))?;
    let started = std::time::Instant::now();
    for (scenario, fixtures) in SUBSET {
        println!(
            "==== guard: {scenario}{} ====",
            if fixtures.is_empty() { String::new() } else { format!(" ({fixtures})") }
        );
        let mut cmd = Command::new(&exe);
        cmd.current_dir(root).args(["accept", scenario]).env(CAPTURE_ENV, &capture);
        if !fixtures.is_empty() {
            cmd.env("NLOS_ACCEPT_HOLES", fixtures);
        }
        // A scenario that misses a target exits non-zero: the comparison below judges it.
        cmd.status().map_err(|e| format!("cannot run {}: {e}", exe.display()))?;
    }
    let now = std::fs::read_to_string(&capture).unwrap_or_default();
    let mut failed = Vec::new();
    for (scenario, _) in SUBSET {
        let Some(b) = super::section(&board, scenario) else {
            println!("guard: the board has no {scenario} section: nothing to hold it to");
            continue;
        };
        let n = super::section(&now, scenario).unwrap_or("- ERROR: the scenario wrote no section\n");
        for r in regressions(b, n) {
            failed.push(format!("{scenario}: {r}"));
        }
    }
    println!("guard: {} scenarios in {:.0} s", SUBSET.len(), started.elapsed().as_secs_f64());
    if failed.is_empty() {
        println!("guard: every check the board shows passing passes");
        Ok(())
    } else {
        Err(format!("checks the board shows passing fail now:\n  {}", failed.join("\n  ")))
    }
}

#[cfg(test)]
mod tests {
    use super::{mask, regressions};

    #[test]
    fn a_check_that_passes_on_the_board_and_fails_now_is_a_regression() {
        let board = "- PASS coverage within 5 mm 84.5 % ≥ 82 %\n- FAIL depth error 0.46 mm ≤ 0.4 mm\n#### slots\n\n- PASS slot 10 mm open 98 % ≥ 70 %\n- PASS slot 15 mm open 80 % ≥ 70 %\n";
        let same = "- PASS coverage within 5 mm 83.0 % ≥ 82 %\n- FAIL depth error 0.50 mm ≤ 0.4 mm\n#### slots\n\n- PASS slot 10 mm open 90 % ≥ 70 %\n- PASS slot 15 mm open 71 % ≥ 70 %\n";
        assert!(regressions(board, same).is_empty(), "{:?}", regressions(board, same));
        let worse = "- FAIL coverage within 5 mm 80.0 % ≥ 82 %\n- FAIL depth error 0.50 mm ≤ 0.4 mm\n#### slots\n\n- PASS slot 10 mm open 90 % ≥ 70 %\n- FAIL slot 15 mm open 60 % ≥ 70 %\n";
        let r = regressions(board, worse);
        assert_eq!(r.len(), 2, "{r:?}");
        assert!(
            r[0].starts_with("coverage within 5 mm 80.0 %") && r[1].starts_with("slots: slot 15 mm open 60 %"),
            "{r:?}"
        );
        assert_eq!(regressions(board, "- ERROR: nlos failed\n").len(), 1);
        assert_eq!(mask("slot 10 mm open 98 % ≥ 70 % (detail 3)"), "slot # mm open # % ≥ # %");
    }
}
