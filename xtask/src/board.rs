//! The board (`docs/results.md`): its rows, what each row is keyed to, and the commands that keep it current.
//!
//! - A row is a scenario of `cargo xtask accept`, the Z-NLOS benchmark, or one fuzz target. Each section
//!   records its inputs ([`inputs`]): the code of the `nlos` binary, the capture readers its files reach, the
//!   xtask sources that define it ([`scenario_sources`]) and the shared data it reads ([`scenario_data`]); a
//!   fuzz target's, its source and its readers. A row is stale only when one of those changed: a comment, a doc,
//!   a test, a benchmark or a lint attribute changes none of them.
//! - `cargo xtask accept --stale` ([`crate::refresh`]) re-runs every stale row, one after another, longest first,
//!   each section written as it lands; a developer commits the batch as one "Board" commit.
//! - `cargo xtask guard` ([`guard::guard`]) runs a short subset in CI and fails when a check that the committed
//!   board shows passing fails on the code under test.

pub(crate) mod guard;
pub(crate) mod inputs;
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
        "holes" => &["accept/holes.rs", "accept/holes/mc_noise.rs"],
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
        "holes" => &["reference/plane_mc.hdf5", "reference/plane_quadrature.hdf5"],
        "znlos" => &["znlos"],
        _ => &[],
    }
}

/// Where the shared data live: `$NLOS_SHARED_DATA`, else `../shared/data` beside the workspace, as the
/// scenarios find them (`accept.rs` keeps its own copy of these lines: it is part of every scenario's definition,
/// and moving them would stale every row).
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

/// The scenarios with what each checks, in the order of `docs/results.md` (`crate::accept::SCENARIOS`; the
/// callers pass it, so that the board depends on no scenario's code). Its `fuzz` entry stands for the fuzz
/// targets ([`FUZZ_TARGETS`]).
pub(crate) type Scenarios = [(&'static str, &'static str)];

/// Every fuzz target, with what it reads.
pub(crate) const FUZZ_TARGETS: [(&str, &str); 11] = [
    ("mat_v5", "MAT v5: Stanford LCT, Tsai 2019, Stanford f-k"),
    ("znlos_mat", "MAT v5: Z-NLOS as NeTF preprocessed it, and its wall"),
    ("general_nlos", "MAT v5 pair: general-NLOS `data.mat` + `setup.mat`"),
    ("hdf5", "HDF5: y-tal, Z-NLOS, MAT v7.3"),
    ("npy", "`.npy` + JSON sidecar"),
    ("exr", "OpenEXR captures"),
    ("maps", "depth and normal maps (`.npy`, `.mat`, EXR), both layouts, scoring"),
    ("mesh", "OBJ, PLY, GLB meshes"),
    ("settings", "settings TOML → `Config`, resolved against a capture"),
    ("checkpoint", "`checkpoint.json` through `resume`"),
    ("grid", "grid detection from point lists"),
];

/// The capture readers (`crates/nlos-transient/src/formats` children) a target enters; the board keys its
/// row to them and to those they use.
pub(crate) fn fuzz_readers(target: &str) -> &'static [&'static str] {
    match target {
        "mat_v5" | "znlos_mat" | "general_nlos" => &["mat"],
        "hdf5" => &["hdf5"],
        "npy" | "grid" => &["npy"],
        "exr" => &["exr"],
        "maps" => &["npy", "mat", "exr"],
        _ => &[],
    }
}

/// Every row of the board in the order of `docs/results.md`, with what it checks: the scenarios, the fuzz
/// targets in the place of `fuzz`.
pub(crate) fn rows(scenarios: &Scenarios) -> Vec<(String, String)> {
    let mut v = Vec::new();
    for &(name, what) in scenarios {
        if name == "fuzz" {
            for (target, reads) in FUZZ_TARGETS {
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
        Some(target) => fp.fuzz_inputs(target, fuzz_readers(target)),
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
/// components of its `inputs:` line that changed (a section without one is stale).
pub(crate) fn staleness(fp: &mut Fingerprints, body: &str) -> Option<String> {
    if let Some(inputs) = Inputs::parse(body) {
        return fp.changed(&inputs);
    }
    if let Some(why) = body.lines().find_map(|l| l.strip_prefix(inputs::INPUTS_LINE)) {
        return Some(format!("inputs unknown: {why}"));
    }
    Some("no inputs recorded".to_string())
}

/// The section of row `name` in `doc`, if any.
pub(crate) fn section<'a>(doc: &'a str, name: &str) -> Option<&'a str> {
    let (open, close) = (format!("<!-- scenario: {name} -->"), format!("<!-- end: {name} -->"));
    let i = doc.find(&open)? + open.len();
    let j = doc[i..].find(&close)? + i;
    Some(&doc[i..j])
}

/// The scenarios' cached renders (`out/accept/*_clean.*`) are made by the code that made them: removed when
/// the `nlos` binary's code is not what the last refresh or guard ran.
pub(crate) fn invalidate_renders(root: &Path, fp: &mut Fingerprints) -> Result<(), String> {
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
