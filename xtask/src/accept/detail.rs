//! The `detail` scenario: what the volume shows, the mesh keeps. The 40 cm chart through the default
//! command, judged by the front-view detail (`nlos eval --front-view`: Pearson's r of the LCT volume's front
//! view and the mesh's over the chart's region, and the share of the volume's bright pixels the mesh covers)
//! and its plane; and the general-NLOS capture thinned to every 4th spot each way (256 of 4,096 pairs), judged
//! by where its three objects lie.

use std::fmt::Write as _;
use std::path::Path;

use nlos_transient::Format;

use super::relay::{check_objects, object_windows};
use super::{MEASURED_DIR, Opts, Runner, Section, check, p, reconstruct_args, reconstruct_args_list, s, shared};

pub(super) fn detail(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    let (mut text, mut pass) = (String::new(), true);
    chart(r, opts, &mut text, &mut pass)?;
    sparse(r, opts, &mut text, &mut pass)?;
    Ok(Section { text, pass })
}

/// `nlos eval MESH --front-view CAPTURE --brdf retroreflective`: (r, coverage).
fn front_view(r: &mut Runner, mesh: &Path, capture: &Path) -> Result<(f64, f64), String> {
    let ran =
        r.nlos(&[s("eval"), p(mesh), s("--front-view"), p(capture), s("--brdf"), s("retroreflective"), s("--json")])?;
    let line = ran.stdout.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or("");
    let v: serde_json::Value = serde_json::from_str(line).map_err(|e| format!("nlos eval --front-view: {e}"))?;
    let num = |k: &str| v[k].as_f64().ok_or_else(|| format!("nlos eval --front-view printed no `{k}`: {line}"));
    Ok((num("r")?, num("coverage")?))
}

fn chart(r: &mut Runner, opts: &Opts, text: &mut String, pass: &mut bool) -> Result<(), String> {
    let capture = shared(MEASURED_DIR).join("data_resolution_chart_40cm.mat");
    if !capture.exists() {
        let _ = writeln!(text, "- 40 cm chart: skipped, {} is missing", capture.display());
        return Ok(());
    }
    let run_dir = r.out.join("detail_chart");
    let _ = std::fs::remove_dir_all(&run_dir);
    let mut a = vec![s("reconstruct"), p(&capture), s("--brdf"), s("retroreflective"), s("--out"), p(&run_dir)];
    a.push(s("--quiet"));
    a.extend(reconstruct_args(opts));
    let ran = r.nlos(&a)?;
    let (r0, c0) = front_view(r, &run_dir.join("init.obj"), &capture)?;
    let (r1, c1) = front_view(r, &run_dir.join("mesh.ply"), &capture)?;
    let mesh = nlos_mesh::io::load(run_dir.join("mesh.obj")).map_err(|e| e.to_string())?;
    let mut z: Vec<f32> = mesh.positions().iter().map(|q| q.z).collect();
    z.sort_by(f32::total_cmp);
    let median = z.get(z.len() / 2).copied().unwrap_or(f32::NAN);
    let _ = writeln!(
        text,
        "\n#### the 40 cm chart (`--brdf retroreflective`)\n\n| mesh | front-view r | coverage of the volume's bright \
         pixels |\n|---|---|---|\n| LCT start | {r0:.3} | {:.1} % |\n| result | {r1:.3} | {:.1} % |\n\n{} faces, median \
         vertex depth {median:.4} m; {:.0} s wall, {:.0} s CPU (children)\n",
        100.0 * c0,
        100.0 * c1,
        mesh.n_faces(),
        ran.wall_s,
        ran.cpu_s
    );
    check(text, pass, &format!("front-view r {r1:.3} ≥ 0.8"), r1 >= 0.8);
    check(text, pass, &format!("coverage {:.1} % ≥ 85 %", 100.0 * c1), c1 >= 0.85);
    check(text, pass, &format!("plane at {median:.4} m (0.41 ± 0.005 m)"), (median - 0.41).abs() <= 0.005);
    if !opts.quick {
        check(text, pass, &format!("{:.0} s ≤ 600 s", ran.wall_s), ran.wall_s <= 600.0);
    }
    Ok(())
}

/// The general-NLOS capture with every 4th spot each way kept.
fn thinned(r: &mut Runner, general: &Path) -> Result<std::path::PathBuf, String> {
    let full = r.out.join("detail_general_full.npy");
    r.nlos(&[s("convert"), p(general), s("--bin-width-ps"), s("32"), p(&full)])?;
    let t = nlos_transient::read(&full).map_err(|e| e.to_string())?;
    let keep: Vec<usize> = (0..64).step_by(4).flat_map(|iy| (0..64).step_by(4).map(move |ix| 64 * iy + ix)).collect();
    if t.scan().measurements() != 64 * 64 {
        return Err(format!("{}: expected 64 × 64 pairs, found {}", general.display(), t.scan().measurements()));
    }
    let thin = t.select(&keep).map_err(|e| e.to_string())?;
    let file = r.out.join("detail_general_thin.npy");
    nlos_transient::write(&thin, &file, Format::NpyJson).map_err(|e| e.to_string())?;
    Ok(file)
}

fn sparse(r: &mut Runner, opts: &Opts, text: &mut String, pass: &mut bool) -> Result<(), String> {
    let general = shared(MEASURED_DIR).join("general_nlos/data.mat");
    if !general.exists() {
        let _ = writeln!(text, "- thinned general-NLOS capture: skipped, {} is missing", general.display());
        return Ok(());
    }
    let capture = thinned(r, &general)?;
    let run_dir = r.out.join("detail_general_thin");
    let _ = std::fs::remove_dir_all(&run_dir);
    let mut a = vec![s("reconstruct"), p(&capture), s("--out"), p(&run_dir), s("--quiet")];
    a.extend(reconstruct_args_list(opts));
    let t0 = std::time::Instant::now();
    // A run that keeps almost no surface exits 1 after writing its files: judged like any other.
    let ran = r.nlos(&a);
    let wall_s = t0.elapsed().as_secs_f64();
    let mesh = nlos_mesh::io::load(run_dir.join("mesh.obj")).map_err(|e| e.to_string())?;
    let _ = writeln!(
        text,
        "\n#### the general-NLOS capture thinned to every 4th spot each way (256 pairs)\n\n{} faces; {wall_s:.0} s \
         wall\n",
        mesh.n_faces()
    );
    if let Err(e) = &ran {
        let _ = writeln!(text, "- the run: {e}");
    }
    check(text, pass, "the run succeeds", ran.is_ok());
    let (area, centroid) = object_windows(&mesh);
    check_objects(text, pass, &area, &centroid, 0.1);
    if !opts.quick {
        check(text, pass, &format!("{wall_s:.0} s ≤ 600 s"), wall_s <= 600.0);
    }
    Ok(())
}
