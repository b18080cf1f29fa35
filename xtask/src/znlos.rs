//! The `znlos` row: `cargo xtask benchmark znlos DIR [-- ARGS…]` runs `nlos benchmark` on DIR's Z-NLOS captures
//! (each with its ground-truth maps) and records its table as the `znlos` section of `docs/results.md`.

use std::path::Path;

use crate::{accept, nlos, workspace_root};

/// `cargo xtask benchmark znlos DIR [-- ARGS…]`: runs `nlos benchmark` and records its table.
pub(crate) fn benchmark(args: &[String]) -> Result<(), String> {
    let usage = "usage: cargo xtask benchmark znlos DIR [-- NLOS_BENCHMARK_ARGS...]";
    let (Some("znlos"), Some(dir)) = (args.first().map(String::as_str), args.get(1)) else {
        return Err(usage.into());
    };
    let extra: Vec<&str> = match args.get(2).map(String::as_str) {
        Some("--") => args[3..].iter().map(String::as_str).collect(),
        Some(other) => return Err(format!("unexpected `{other}`; {usage}")),
        None => Vec::new(),
    };
    let root = workspace_root();
    let out = root.join("out/benchmark");
    let table = out.join("znlos.md");
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let (o, t) = (out.to_string_lossy().into_owned(), table.to_string_lossy().into_owned());
    let mut cmd = vec!["benchmark", dir.as_str(), "--out", &o, "--table", &t];
    cmd.extend(extra.iter().copied());
    let started = std::time::Instant::now();
    nlos(&cmd)?;
    let rows = std::fs::read_to_string(&table).map_err(|e| format!("{}: {e}", table.display()))?;
    let name = Path::new(dir).file_name().map_or_else(|| dir.clone(), |n| n.to_string_lossy().into_owned());
    let md = format!(
        "## znlos — measured — {}

`nlos benchmark` on the Z-NLOS captures of `{name}` (ground-truth maps beside \
         each), {:.0} s in all: each capture reconstructed by LCT and f-k (their surfaces: the arg-max depth of the \
         kept columns) and by `nlos reconstruct` with the default settings{}, scored as `nlos eval --gt-depth \
         --gt-normal --gt-layout dlct --wall CAPTURE` scores them: the maps as published, on the capture's full \
         wall grid. Normal errors are over the pixels in brackets (the truth's and the method's surface).\n\n{rows}",
        accept::utc_now(),
        started.elapsed().as_secs_f64(),
        if extra.is_empty() { String::new() } else { format!(" and `{}`", extra.join(" ")) },
    );
    accept::record(&root, "znlos", &md)
}
