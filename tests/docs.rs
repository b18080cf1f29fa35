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
