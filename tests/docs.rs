//! Tracked docs and comments say what and why, not where or when: no absolute path of a machine, no time
//! of day, no load average (history lives in git). And the README stays a page a new user reads: at most
//! about 120 lines.

use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The project's own text files: sources, manifests, docs, CI (not `target/`, `out/` or fixtures' data).
fn tracked_text() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md"), root().join("Cargo.toml"), root().join(".ci/run")];
    let mut stack: Vec<PathBuf> =
        ["crates", "docs", "benches", "tests", "xtask", "fuzz/fuzz_targets", "fixtures"].map(|d| root().join(d)).into();
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for entry in entries.flatten() {
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            if path.is_dir() {
                if name != "target" && !name.starts_with('.') {
                    stack.push(path);
                }
            } else if [".rs", ".md", ".toml", ".py", ".pyi"].iter().any(|ext| name.ends_with(ext)) {
                files.push(path);
            }
        }
    }
    files
}

/// `h:mm` or `hh:mm` (optionally `:ss`) followed by a time zone: a time of day.
fn has_time_of_day(line: &str) -> bool {
    let b = line.as_bytes();
    (0..b.len()).any(|i| {
        let digits = |from: usize, n: usize| b.get(from..from + n).is_some_and(|s| s.iter().all(u8::is_ascii_digit));
        let start_ok = i == 0 || !b[i - 1].is_ascii_digit();
        let h = if digits(i, 2) {
            2
        } else if digits(i, 1) {
            1
        } else {
            return false;
        };
        if !start_ok || b.get(i + h) != Some(&b':') || !digits(i + h + 1, 2) {
            return false;
        }
        let mut j = i + h + 3;
        if b.get(j) == Some(&b':') && digits(j + 1, 2) {
            j += 3;
        }
        let rest = line[j..].trim_start();
        ["UTC", "GMT", "CET", "CEST"].iter().any(|tz| rest.starts_with(tz))
    })
}

/// Words of the project's history a user cannot look up: an issue number, or "the seed" for the paper's
/// codebase (say "Tsai et al. 2019's setup", or what the setup is).
fn names_history(line: &str) -> bool {
    let lower = line.to_lowercase();
    let issue = ["issue ", "issues "]
        .iter()
        .any(|w| lower.match_indices(w).any(|(i, _)| lower[i + w.len()..].starts_with(|c: char| c.is_ascii_digit())));
    let seed = lower.match_indices("the seed").any(|(i, _)| {
        !lower[i + "the seed".len()..].starts_with(|c: char| c.is_alphanumeric() || c == '_' || c == ' ')
            || lower[i + "the seed".len()..].starts_with(" setup")
    }) || lower.contains("seed setup")
        || lower.contains("seed-setup");
    issue || seed
}

#[test]
fn the_history_detector_detects() {
    let (n, t) = ("issue ".to_string() + "7", "the ".to_string() + "seed");
    assert!(names_history(&format!("(El Topo, {n})")));
    assert!(names_history(&format!("{t}'s schedule")));
    assert!(names_history(&format!("{t}-setup bunny")));
    assert!(names_history(&format!("at {t} setup")));
    assert!(names_history(&format!("capture: {} setup, 1000 photons", "seed")));
    assert!(!names_history("the same seed as before, a seeded generator, --seed 3"));
    assert!(!names_history("the seed of the generator"));
}

#[test]
fn the_time_of_day_detector_detects() {
    // Built at run time, so that this file holds no time of day itself.
    assert!(has_time_of_day(&format!("runs at {}:{} UTC and", 18, 33)));
    assert!(has_time_of_day(&format!("({}:{:02}:{} GMT)", 9, 5, 12)));
    assert!(!has_time_of_day("ratio 1:10, bins 0..2:"));
    assert!(!has_time_of_day("at 2026-11-25"));
}

#[test]
fn no_machine_paths_times_of_day_or_load_in_tracked_text() {
    let own = root().join("tests/docs.rs");
    // Spelled in pieces so that this file does not match itself.
    let paths =
        ["/wo".to_string() + "rk/", "/ho".to_string() + "me/", "/Us".to_string() + "ers/", "/ro".to_string() + "ot/"];
    let load = "load ".to_string() + "average";
    let mut found = Vec::new();
    for file in tracked_text() {
        if file == own {
            continue;
        }
        let Ok(text) = std::fs::read_to_string(&file) else { continue };
        for (n, line) in text.lines().enumerate() {
            let what = if paths.iter().any(|p| line.contains(p.as_str())) {
                "absolute path"
            } else if names_history(line) {
                "the project's history (an issue number, or an earlier codebase called \"the seed\")"
            } else if has_time_of_day(line) {
                "time of day"
            } else if line.contains(&load) {
                "load average"
            } else {
                continue;
            };
            found.push(format!(
                "{}:{}: {what}: {}",
                file.strip_prefix(root()).unwrap_or(&file).display(),
                n + 1,
                line.trim()
            ));
        }
    }
    assert!(found.is_empty(), "history belongs in git, not in tracked text:\n{}", found.join("\n"));
}

#[test]
fn the_readme_is_short() {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let lines = readme.lines().count();
    assert!(lines <= 125, "README.md has {lines} lines; keep it a page (details go to docs/)");
}

/// The crate table of docs/ARCHITECTURE.md lists, for every workspace crate, its `[dependencies]`
/// (platform-specific ones included) exactly as its `Cargo.toml` declares them (parenthesised remarks aside;
/// `—` for none).
#[test]
fn the_architecture_crate_table_matches_the_manifests() {
    let arch = std::fs::read_to_string(root().join("docs/ARCHITECTURE.md")).expect("docs/ARCHITECTURE.md");
    let mut rows = std::collections::BTreeMap::new();
    for line in arch.lines() {
        let cells: Vec<&str> = line.split(" | ").collect();
        let Some(name) = cells.first().and_then(|c| c.strip_prefix("| `")).and_then(|c| c.strip_suffix('`')) else {
            continue;
        };
        if cells.len() != 3 || !(name.starts_with("nlos-") || name == "xtask") {
            continue;
        }
        let mut listed = String::new();
        let mut depth = 0;
        for c in cells[2].trim_end_matches(" |").chars() {
            match c {
                '(' => depth += 1,
                ')' => depth -= 1,
                _ if depth == 0 => listed.push(c),
                _ => {}
            }
        }
        let deps: std::collections::BTreeSet<String> =
            listed.split(',').map(|d| d.trim().to_string()).filter(|d| !d.is_empty() && d != "—").collect();
        rows.insert(name.to_string(), deps);
    }
    let mut manifests: Vec<PathBuf> = std::fs::read_dir(root().join("crates"))
        .expect("crates/")
        .flatten()
        .map(|e| e.path().join("Cargo.toml"))
        .filter(|p| p.exists())
        .collect();
    manifests.push(root().join("xtask/Cargo.toml"));
    let mut wrong = Vec::new();
    for manifest in manifests {
        let text = std::fs::read_to_string(&manifest).expect("Cargo.toml");
        let toml: toml::Table = text.parse().expect("a valid Cargo.toml");
        let name = toml["package"]["name"].as_str().expect("package.name").to_string();
        // `[dependencies]` and every `[target.'cfg(…)'.dependencies]`: a platform's dependency is one too.
        let targets = toml.get("target").and_then(|t| t.as_table());
        let declared: std::collections::BTreeSet<String> = std::iter::once(toml.get("dependencies"))
            .chain(targets.into_iter().flat_map(|t| t.values().map(|cfg| cfg.get("dependencies"))))
            .flatten()
            .filter_map(|d| d.as_table())
            .flat_map(|d| d.keys().cloned())
            .collect();
        match rows.remove(&name) {
            None => wrong.push(format!("{name}: no row in the crate table")),
            Some(listed) if listed != declared => wrong.push(format!(
                "{name}: the table lists {:?}, Cargo.toml declares {:?}",
                listed.difference(&declared).collect::<Vec<_>>(),
                declared.difference(&listed).collect::<Vec<_>>()
            )),
            Some(_) => {}
        }
    }
    wrong.extend(rows.keys().map(|name| format!("{name}: a row for a crate that is not in the workspace")));
    assert!(wrong.is_empty(), "docs/ARCHITECTURE.md's crate table against the manifests:\n{}", wrong.join("\n"));
}

/// The sources stay readable in pieces: a file of `crates/*/src` over 800 lines says at its top (its first
/// 40 lines) why it is one file, and at most five `too_many_arguments` allows remain, each with its reason
/// on the same line (the SoA kernels' separate `&mut` streams, PyO3's keyword arguments).
#[test]
fn long_files_say_why_and_long_argument_lists_are_few() {
    let sources: Vec<PathBuf> = tracked_text()
        .into_iter()
        .filter(|p| {
            let rel = p.strip_prefix(root()).unwrap_or(p);
            rel.starts_with("crates")
                && rel.components().nth(2).is_some_and(|c| c.as_os_str() == "src")
                && p.extension().is_some_and(|e| e == "rs")
        })
        .collect();
    assert!(sources.len() > 50, "found only {} source files", sources.len());
    let mut long = Vec::new();
    let mut allows = Vec::new();
    for path in &sources {
        let text = std::fs::read_to_string(path).expect("readable");
        let rel = path.strip_prefix(root()).unwrap_or(path).display().to_string();
        let lines: Vec<&str> = text.lines().collect();
        if lines.len() > 800 && !lines.iter().take(40).any(|l| l.starts_with("//!") && l.contains("Why one file")) {
            long.push(format!("{rel}: {} lines and no \"Why one file\" in its opening doc", lines.len()));
        }
        for (i, line) in lines.iter().enumerate() {
            if line.contains("allow(clippy::too_many_arguments)") {
                let reason = line.split_once("//").map(|(_, r)| r.trim()).unwrap_or("");
                allows.push((format!("{rel}:{}", i + 1), reason.len() >= 10));
            }
        }
    }
    assert!(long.is_empty(), "{}", long.join("\n"));
    let unexplained: Vec<&String> = allows.iter().filter(|(_, ok)| !ok).map(|(at, _)| at).collect();
    assert!(unexplained.is_empty(), "too_many_arguments allowed without a reason on the line: {unexplained:?}");
    let at: Vec<&String> = allows.iter().map(|(at, _)| at).collect();
    assert!(allows.len() <= 5, "{} too_many_arguments allows (at most 5): {at:?}", allows.len());
}
