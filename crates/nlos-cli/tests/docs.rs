//! The commands and figures the user documentation quotes: every `nlos` command of the README's code blocks
//! names a real subcommand and real flags and, where it is quick, runs on the shared data; the figures that
//! docs/usage.md quotes from `nlos info` are what `nlos info` prints.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn nlos(args: &[String]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nlos")).args(args).output().expect("run nlos")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("docs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// The `nlos …` command lines of a Markdown file's fenced blocks, without their trailing comments.
fn quoted_commands(markdown: &str) -> Vec<Vec<String>> {
    let mut inside = false;
    let mut out = Vec::new();
    for line in markdown.lines() {
        if line.trim_start().starts_with("```") {
            inside = !inside;
            continue;
        }
        let line = line.split(" # ").next().unwrap_or(line).trim();
        if inside && line.starts_with("nlos ") {
            out.push(line.split_whitespace().skip(1).map(str::to_owned).collect());
        }
    }
    out
}

/// The flags of `nlos SUB --help`.
fn flags_of(sub: &str) -> Vec<String> {
    let o = nlos(&[sub.to_owned(), "--help".to_owned()]);
    assert!(o.status.success(), "nlos {sub} --help: {}", text(&o));
    String::from_utf8_lossy(&o.stdout)
        .split_whitespace()
        .filter_map(|w| w.strip_prefix("--"))
        .map(|w| format!("--{}", w.trim_end_matches(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))))
        .collect()
}

#[test]
fn the_readme_commands_exist_and_run() {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README");
    let commands = quoted_commands(&readme);
    assert!(commands.len() >= 10, "{commands:?}");
    // Every subcommand and flag quoted exists.
    for words in &commands {
        let sub = &words[0];
        let flags = flags_of(sub);
        for flag in words.iter().filter(|w| w.starts_with("--")) {
            let flag = flag.split('=').next().unwrap_or(flag);
            assert!(flags.contains(&flag.to_owned()), "`nlos {}`: {flag} is not a flag of nlos {sub}", words.join(" "));
        }
    }
    // The quick ones run on the shared data: the README's file names stand for these files.
    let Some(chart) = nlos_testdata::shared("measured/data_resolution_chart_40cm.mat") else { return };
    let Some(general) = nlos_testdata::shared("measured/general_nlos/data.mat") else { return };
    let dir = scratch("readme");
    let mesh = dir.join("mesh.obj");
    std::fs::write(&mesh, "v -0.1 -0.1 0.4\nv 0.1 -0.1 0.4\nv 0 0.1 0.4\nf 1 3 2\n").expect("mesh");
    let place = |w: &str| -> String {
        match w {
            "capture.mat" => chart.display().to_string(),
            "data.mat" => general.display().to_string(),
            "mesh.obj" => mesh.display().to_string(),
            "preview.png" | "capture.hdf5" | "sim.hdf5" | "start.obj" => dir.join(w).display().to_string(),
            other => other.to_owned(),
        }
    };
    let mut ran = 0;
    for words in &commands {
        let quick = match words[0].as_str() {
            "info" | "preview" | "convert" | "render" => true,
            // The phasor field on the chart takes seconds.
            "init" => true,
            _ => false,
        };
        if !quick {
            continue;
        }
        let args: Vec<String> = words.iter().map(|w| place(w)).collect();
        let o = nlos(&args);
        assert!(o.status.success(), "`nlos {}`: {}", words.join(" "), text(&o));
        ran += 1;
    }
    assert!(ran >= 6, "{ran} commands ran");
}

/// The commands docs/usage.md quotes in its text (`nlos init --rim-radius R`): real subcommands, real flags.
#[test]
fn the_commands_usage_quotes_exist() {
    let doc = std::fs::read_to_string(root().join("docs/usage.md")).expect("usage.md");
    let quoted: Vec<Vec<String>> = doc
        .split('`')
        .skip(1)
        .step_by(2)
        .filter_map(|span| span.strip_prefix("nlos "))
        .map(|c| c.split_whitespace().map(str::to_owned).collect::<Vec<_>>())
        .filter(|w| !w.is_empty())
        .collect();
    assert!(quoted.len() >= 8, "{quoted:?}");
    for words in &quoted {
        let flags = flags_of(&words[0]);
        for flag in words.iter().filter(|w| w.starts_with("--")) {
            let flag = flag.split('=').next().unwrap_or(flag);
            assert!(
                flags.contains(&flag.to_owned()),
                "`nlos {}`: {flag} is not a flag of nlos {}",
                words.join(" "),
                words[0]
            );
        }
    }
}

/// What `nlos --help` says of the subcommands and the exit status, and the README of the PyTorch layer.
#[test]
fn the_summaries_name_every_start_and_the_exit_status() {
    let o = nlos(&["--help".to_owned()]);
    let help = String::from_utf8_lossy(&o.stdout).into_owned();
    for line in help.lines().filter(|l| l.trim_start().starts_with("init") || l.trim_start().starts_with("reconstruct"))
    {
        for method in ["LCT", "f-k", "phasor field", "space carving"] {
            assert!(line.contains(method), "{method} missing from: {line}");
        }
    }
    assert!(help.contains("Exit status: 0 on success; 2 for bad input"), "{help}");
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README");
    assert!(readme.contains("Exit status: 0 success, 2 bad input"), "the README says no exit status");
    assert!(readme.contains("`import nlos.torch`"), "the README does not say how to reach nlos.torch");
}

/// The figure after `before` in `doc`, as written (`0.851`).
fn figure_after<'a>(doc: &'a str, before: &str) -> &'a str {
    let at = doc.find(before).unwrap_or_else(|| panic!("docs/usage.md no longer says {before:?}"));
    let rest = &doc[at + before.len()..];
    rest.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '–' || c == '-')).next().unwrap_or("")
}

/// `nlos info`'s value on the line starting with `key`, the number after `marker`.
fn info_number(info: &str, key: &str, marker: &str) -> f64 {
    let line = info.lines().find(|l| l.starts_with(key)).unwrap_or_else(|| panic!("no {key} in\n{info}"));
    let rest = line.split(marker).nth(1).unwrap_or_else(|| panic!("no {marker:?} in {line}"));
    rest.split(|c: char| !(c.is_ascii_digit() || c == '.')).next().and_then(|v| v.parse().ok()).expect("number")
}

#[test]
fn the_figures_usage_quotes_from_nlos_info_are_what_it_prints() {
    let doc = std::fs::read_to_string(root().join("docs/usage.md")).expect("usage.md");
    let info =
        |file: &Path| String::from_utf8_lossy(&nlos(&["info".into(), file.display().to_string()]).stdout).into_owned();
    let Some(diffuse) = nlos_testdata::shared("measured/data_diffuse_s.mat") else { return };
    let Some(chart) = nlos_testdata::shared("measured/data_resolution_chart_40cm.mat") else { return };
    let Some(gated) = nlos_testdata::shared("measured/tsai_su_transient.mat") else { return };
    // Where the last return ends, as depth.
    for (file, before) in [(&diffuse, "printed by `nlos info`: "), (&chart, "m of depth for the diffuse S, ")] {
        let depth = info_number(&info(file), "signal ends:", "(depth ");
        assert_eq!(figure_after(&doc, before), format!("{depth:.3}"), "{}", file.display());
    }
    // The gated S and U: the direct light's end and the background window.
    let gated_info = info(&gated);
    let end = info_number(&gated_info, "peak depth:", "gating the direct light before ");
    assert_eq!(figure_after(&doc, "on `tsai_su_transient.mat` it ends at "), format!("{end:.4}"));
    let background = info_number(&gated_info, "photon counts:", "background ");
    assert_eq!(figure_after(&doc, "(`BackgroundWindow::Auto`; "), format!("{background:.3}"));
    let window = gated_info
        .lines()
        .find(|l| l.starts_with("photon counts:"))
        .and_then(|l| l.split("(from bins ").nth(1))
        .and_then(|w| w.split(')').next())
        .expect("window")
        .replace("..", "–");
    assert_eq!(figure_after(&doc, "counts per bin, from bins "), window);
}
