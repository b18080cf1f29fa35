//! What a newcomer reads: labels true to the capture, hints that name a real flag of the command they appear
//! in, failures before the work, progress on long steps, a line naming what was written, quiet closed pipes.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use glam::Vec3;
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient};

mod common;
use common::{nlos, stderr, stdout};

fn scratch(name: &str) -> PathBuf {
    common::scratch("messages", name)
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf8 path")
}

/// A noise-free simulation: one laser spot at (−0.1, 0.15, 0) m, a 16 × 16 sensor grid, a return in bins
/// 60–69 of 200 bins of 5 mm and nothing after it (not integers: an intensity, not counts).
fn one_laser(dir: &Path) -> PathBuf {
    let laser = PointSet::list(vec![Vec3::new(-0.1, 0.15, 0.0)]);
    let sensors = PointSet::wall_grid(16, 16, 0.25, 0.25).expect("grid");
    let mut t = Transient::zeros(Scan::exhaustive(laser, sensors), TimeAxis::new(0.0, 0.005, 200).expect("axis"))
        .expect("transient");
    for m in 0..t.measurements() {
        for (k, v) in t.histogram_mut(m)[60 + m % 4..66 + m % 4].iter_mut().enumerate() {
            *v = 0.37 * (k + 1) as f32;
        }
    }
    let path = dir.join("one_laser.npy");
    nlos_transient::write(&t, &path, Format::NpyJson).expect("write");
    path
}

/// The flags that `nlos SUB --help` lists.
fn flags_of(sub: &str) -> Vec<String> {
    let o = nlos(&[sub, "--help"]);
    assert!(o.status.success(), "{sub} --help: {}", stderr(&o));
    flags_in(&stdout(&o))
}

/// Every `--flag` token of `text`.
fn flags_in(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("--") {
        let after = &rest[i + 2..];
        let end =
            after.find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')).unwrap_or(after.len());
        let name = &after[..end];
        if name.starts_with(|c: char| c.is_ascii_lowercase()) {
            out.push(format!("--{}", name.trim_end_matches('-')));
        }
        rest = &after[end..];
    }
    out
}

/// Every subcommand of `nlos`, from its help.
fn subcommands() -> Vec<String> {
    let help = stdout(&nlos(&["--help"]));
    let list = help.split("Commands:").nth(1).expect("a command list");
    list.lines()
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_owned)
        .collect()
}

#[test]
fn info_says_what_the_capture_is_in_its_own_words() {
    let dir = scratch("info-words");
    let file = one_laser(&dir);
    let o = nlos(&["info", s(&file)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for needle in [
        "scan:          one laser spot at (-0.1, 0.15, 0) m, recorded at 256 sensor spots on a 16 × 16 grid",
        "200 bins of 5 mm (16.667 ps) of path length, 0 .. 1 m",
        "(intensity: not photon counts)",
        "intensity:     no background",
        "no direct light found to gate",
        // The last non-zero bin is 68: its end at 0.345 m of path.
        "signal ends:   0.345 m of path",
    ] {
        assert!(out.contains(needle), "{needle:?} not in\n{out}");
    }
    for wrong in ["list of 1", "exhaustive", "total counts", "photon counts:", "0.0000 m", "at the end of the axis"] {
        assert!(!out.contains(wrong), "{wrong:?} in\n{out}");
    }
    let v: serde_json::Value = serde_json::from_str(&stdout(&nlos(&["info", "--json", s(&file)]))).expect("json");
    assert_eq!(v["quantity"], "intensity");
    assert_eq!(v["peak"]["direct_light_gate_m"], serde_json::Value::Null);
    // A paired capture read with the bin width as typed: it comes back as typed, and its scan is paired.
    let Some(general) = nlos_testdata::shared("measured/general_nlos/data.mat") else { return };
    let o = nlos(&["info", s(&general), "--bin-width-ps", "32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("512 bins of 9.6 mm (32 ps) of path length"), "{out}");
    assert!(
        out.contains("scan:          paired: 4096 laser spots (a list), each recorded at its own sensor spot"),
        "{out}"
    );
    assert!(out.contains("sum of values: 8979788 (photon counts)"), "{out}");
}

/// A simulation cut from later bins (`convert --crop-bins`) is not a capture gated before it reached us: no
/// gate in `nlos info`, and `reconstruct` does not fit it through a background.
#[test]
fn a_cropped_simulation_is_not_taken_for_a_gated_capture() {
    let dir = scratch("crop");
    let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.25, 0.25).expect("grid"));
    let bins = 1200;
    // Photon counts of a flat face at 0.42 m: an abrupt first return at bin 700 and a long tail to bin 1000.
    let data = (0..64 * bins)
        .map(|i| {
            let k = i % bins;
            if !(700..1000).contains(&k) { 0.0 } else { (400.0 * (-((k - 700) as f32) / 300.0).exp()).round() }
        })
        .collect();
    let t = Transient::new(scan, TimeAxis::new(0.0, 0.0012, bins).expect("axis"), data).expect("transient");
    let full = dir.join("sim.npy");
    nlos_transient::write(&t, &full, Format::NpyJson).expect("write");
    let crop = dir.join("crop.npy");
    let o = nlos(&["convert", s(&full), s(&crop), "--crop-bins", "500..900"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = nlos(&["info", s(&crop)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stdout(&o).contains("gate:"), "{}", stdout(&o));
    assert!(stdout(&o).contains("photon counts: no background"), "{}", stdout(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&nlos(&["info", "--json", s(&crop)]))).expect("json");
    assert_eq!(v["zero_gate"], serde_json::Value::Null);
}

/// The start's refusals name the flag of the command they appear in, and a method that takes the scan.
#[test]
fn a_refused_start_names_this_commands_flag() {
    let dir = scratch("refusal");
    let file = one_laser(&dir);
    let out = dir.join("start.obj");
    let o = nlos(&["init", s(&file), "--method", "lct", "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("this capture is a one-laser scan"), "{err}");
    assert!(err.contains("`--method pf`"), "{err}");
    for wrong in ["--init", "nlos_init::", "space carving", "exhaustive"] {
        assert!(!err.contains(wrong), "{wrong:?} in {err}");
    }
    let init_flags = flags_of("init");
    assert!(flags_in(&err).iter().all(|f| init_flags.contains(f)), "{err}");

    let run = dir.join("run");
    let o = nlos(&["reconstruct", s(&file), "--init", "lct", "--out", s(&run)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("`--init pf`"), "{err}");
    let reconstruct_flags = flags_of("reconstruct");
    assert!(flags_in(&err).iter().all(|f| reconstruct_flags.contains(f)), "{err}");
}

/// `--resume` where no run was started fails before anything is written, and says so; a missing `--config`
/// file is not an output directory's problem; a mistyped `--set` key is named, not a line of a TOML document.
#[test]
fn reconstruct_errors_say_what_is_wrong_before_the_work() {
    let dir = scratch("reconstruct-errors");
    let file = one_laser(&dir);
    let run = dir.join("never-run");
    std::fs::create_dir_all(&run).expect("dir");
    let o = nlos(&["reconstruct", s(&file), "--out", s(&run), "--resume"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("nothing to resume"), "{}", stderr(&o));
    assert_eq!(std::fs::read_dir(&run).expect("dir").count(), 0, "--resume wrote into a directory without a run");

    let o = nlos(&["reconstruct", s(&file), "--out", s(&run), "--config", s(&dir.join("missing.toml"))]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("settings file"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("output directory"), "{}", stderr(&o));

    let o = nlos(&["reconstruct", "--print-config", "--set", "schedule.max_stage=2"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("setting schedule.max_stage: no such setting"), "{err}");
    assert!(err.contains("schedule.max_stages"), "{err}");
    assert!(!err.contains("line "), "{err}");
    let o = nlos(&["reconstruct", "--print-config", "--set", "schedule.max_stages=many"]);
    assert!(stderr(&o).contains("setting schedule.max_stages: invalid type"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("line "), "{}", stderr(&o));

    // A truncated capture: its path once, not twice.
    let bytes = std::fs::read(&file).expect("read");
    let trunc = dir.join("trunc.npy");
    std::fs::write(&trunc, &bytes[..bytes.len() / 2]).expect("write");
    std::fs::copy(file.with_extension("json"), trunc.with_extension("json")).expect("sidecar");
    let o = nlos(&["reconstruct", s(&trunc), "--out", s(&dir.join("r"))]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches("trunc.npy").count(), 1, "{}", stderr(&o));
}

/// Outputs are checked before the work: `init` refuses a mesh extension it cannot write even before reading
/// the capture, `preview` writes PNG only under `.png`, `render --bin-width-ps` needs `--setup`.
#[test]
fn outputs_are_checked_before_the_work() {
    let dir = scratch("outputs");
    let o = nlos(&["init", s(&dir.join("no-such-capture.mat")), "--out", s(&dir.join("start.txt"))]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--out") && stderr(&o).contains(".obj, .ply or .glb"), "{}", stderr(&o));
    let file = one_laser(&dir);
    let jpg = dir.join("p.jpg");
    let o = nlos(&["preview", s(&file), "--out", s(&jpg)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!jpg.exists());
    let png = dir.join("p.png");
    let o = nlos(&["preview", s(&file), "--out", s(&png)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).starts_with(&format!("wrote {}", png.display())), "{}", stdout(&o));
    let mesh = dir.join("tri.obj");
    std::fs::write(&mesh, "v -0.1 -0.1 0.4\nv 0.1 -0.1 0.4\nv 0 0.1 0.4\nf 1 3 2\n").expect("write");
    let o = nlos(&["render", s(&mesh), "--out", s(&dir.join("r.npy")), "--bin-width-ps", "32"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--setup"), "{}", stderr(&o));
}

/// `nlos render` says what it renders as its first line on stderr (here a log, not a terminal), how far it got
/// while it runs, and names the file it wrote.
#[test]
fn render_shows_progress_and_names_what_it_wrote() {
    let dir = scratch("render-progress");
    let setup = one_laser(&dir);
    let mesh = dir.join("tri.obj");
    std::fs::write(&mesh, "v -0.1 -0.1 0.4\nv 0.1 -0.1 0.4\nv 0 0.1 0.4\nf 1 3 2\n").expect("write");
    let out = dir.join("sim.npy");
    // Shown from the start (by default a step shows after a second, and this one is quicker).
    let o = Command::new(env!("CARGO_BIN_EXE_nlos"))
        .args(["render", s(&mesh), "--out", s(&out), "--setup", s(&setup)])
        .env("NLOS_PROGRESS_DELAY_MS", "0")
        .output()
        .expect("run nlos");
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let first = err.lines().next().unwrap_or("");
    assert_eq!(first, "render: 1 triangles × 256 measurements…", "{err}");
    assert!(err.contains("render: 1 triangles × 256 measurements: done in"), "{err}");
    assert!(stdout(&o).starts_with(&format!("wrote {}", out.display())), "{}", stdout(&o));
}

/// `nlos info FILE | head -1`: the reader closes the pipe; the command ends quietly. The pipe is closed before
/// the command writes anything (a reader that waits for one line may find the whole output already in the
/// pipe's buffer, and the command would never meet the closed pipe), so that every line meets it.
#[test]
fn a_closed_pipe_ends_quietly() {
    let dir = scratch("pipe");
    let file = one_laser(&dir);
    for args in [vec!["info", s(&file)], vec!["info", "--json", s(&file)]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_nlos"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn");
        drop(child.stdout.take());
        let o = child.wait_with_output().expect("wait");
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{args:?}: {}", stderr(&o));
    }
    // And as `head -1` reads it: the first line arrives whole.
    let mut child = Command::new(env!("CARGO_BIN_EXE_nlos"))
        .args(["info", s(&file)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let mut first = String::new();
    BufReader::new(child.stdout.take().expect("stdout")).read_line(&mut first).expect("first line");
    let o = child.wait_with_output().expect("wait");
    assert!(first.starts_with("file:"), "{first}");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// Every flag that a message names exists: in each subcommand's `--help`, a flag of that subcommand or of the
/// one the line names (`nlos reconstruct --init`); in the workspace's sources (strings, not comments), a flag of
/// the subcommand the message names or whose source file it is in, else of some subcommand. Every setting a
/// message names in backticks (`capture.gate`) is one that `--print-config` lists.
#[test]
fn every_flag_and_setting_a_message_names_exists() {
    let subs = subcommands();
    assert!(subs.len() >= 9, "{subs:?}");
    let help: Vec<(String, Vec<String>)> = subs.iter().map(|c| (c.clone(), flags_of(c))).collect();
    let any: Vec<String> = help.iter().flat_map(|(_, f)| f.clone()).collect();
    let config = stdout(&nlos(&["reconstruct", "--print-config"]));
    let settings = settings_in(&config);
    let mut problems = Vec::new();
    let mut checked = 0;
    // The help texts: a flag named in a subcommand's help is one of its own, or of the command it names.
    for (sub, own) in &help {
        let text = stdout(&nlos(&[sub, "--help"]));
        for line in text.lines() {
            for flag in flags_in(line) {
                let named = subs.iter().find(|c| line.contains(&format!("nlos {c} ")));
                let known = named.map_or(own, |c| &help.iter().find(|(h, _)| h == c).expect("listed").1);
                checked += 1;
                if !known.contains(&flag) {
                    problems.push(format!("nlos {sub} --help: {flag} is not a flag there: {}", line.trim()));
                }
            }
            for setting in backticked_settings(line) {
                checked += 1;
                if !settings.contains(&setting) {
                    problems.push(format!("nlos {sub} --help: `{setting}` is not a setting: {}", line.trim()));
                }
            }
        }
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut files = Vec::new();
    collect_rs(&root.join("crates"), &mut files);
    for file in files.iter().filter(|f| f.components().any(|c| c.as_os_str() == "src")) {
        let text = std::fs::read_to_string(file).expect("source");
        let own = file.file_stem().and_then(|s| s.to_str()).filter(|_| file.starts_with(root.join("crates/nlos-cli")));
        let mut in_tests = false;
        for (n, line) in text.lines().enumerate() {
            let code = line.trim_start();
            in_tests |= code.starts_with("mod tests");
            // Comments, attributes (clap's help is the flags' own text) and cargo's command lines are no messages.
            if in_tests || code.starts_with("//") || code.starts_with("#[") || line.contains("cargo ") {
                continue;
            }
            // A string that is a flag alone ("--quiet") is an argument being passed, not a message.
            for flag in flags_in(line).into_iter().filter(|f| !line.contains(&format!("\"{f}\""))) {
                let named = subs.iter().find(|c| line.contains(&format!("nlos {c} ")));
                let (scope, known) = match (named, own.and_then(|o| help.iter().find(|(c, _)| c == o))) {
                    (Some(c), _) => (c.as_str(), &help.iter().find(|(h, _)| h == c).expect("listed").1),
                    (None, Some((c, f))) => (c.as_str(), f),
                    (None, None) => ("any subcommand", &any),
                };
                checked += 1;
                if !known.contains(&flag) {
                    problems.push(format!("{}:{}: {flag} is not a flag of {scope}", file.display(), n + 1));
                }
            }
            for setting in backticked_settings(line) {
                checked += 1;
                if !settings.contains(&setting) {
                    problems.push(format!("{}:{}: `{setting}` is not a setting", file.display(), n + 1));
                }
            }
        }
    }
    assert!(checked > 30, "only {checked} names found: the scan is broken");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

fn collect_rs(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("dir").flatten() {
        let p = entry.path();
        if p.is_dir() {
            collect_rs(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The dotted keys of the settings TOML (`capture.gate`), and the top-level ones.
fn settings_in(toml: &str) -> Vec<String> {
    let mut section = String::new();
    let mut out = Vec::new();
    for line in toml.lines().map(str::trim).filter(|l| !l.starts_with('#') && !l.is_empty()) {
        if let Some(s) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            section = s.to_owned();
        } else if let Some((key, _)) = line.split_once('=') {
            let key = key.trim();
            out.push(if section.is_empty() { key.to_owned() } else { format!("{section}.{key}") });
        }
    }
    out
}

/// `section.key` names in backticks whose section is one of the settings' sections.
fn backticked_settings(line: &str) -> Vec<String> {
    const SECTIONS: [&str; 8] =
        ["capture", "reflectance", "sensor", "schedule", "optimiser", "render", "boundary", "albedo"];
    line.split('`')
        .skip(1)
        .step_by(2)
        .filter_map(|t| {
            let name = t.split(['=', ' ']).next().unwrap_or(t);
            let (section, key) = name.split_once('.')?;
            let plain = key.chars().all(|c| c.is_ascii_lowercase() || c == '_' || c.is_ascii_digit());
            (SECTIONS.contains(&section) && plain && !key.is_empty()).then(|| name.to_owned())
        })
        .collect()
}
