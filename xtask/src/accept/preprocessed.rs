//! The `preprocessed` scenario: the same real capture as its owners preprocessed it and as it was recorded.
//!
//! Tsai et al. 2019's `tsai_su_transient.mat` is the Stanford `data_s_u.mat` with bins 1–600 zeroed (the
//! direct reflection gated away) and its axes turned by a half turn about z. The default command with
//! `--brdf retroreflective` (as the captures' reference code treats the scene) runs on both; the letters
//! are told apart by depth (the S lies at about 0.6–0.7 m, the U at about 1.04 m). Checks:
//! - `nlos info` on the preprocessed file names the gate and gives a non-zero background;
//! - each letter's median depth (area-weighted over its faces) within 5 mm between the two results, and its
//!   centre within 3 cm after the half turn;
//! - no face more than 10 cm behind the U's median depth in either result;
//! - each run within the real scenario's 600 s.

use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;

use super::{MEASURED_DIR, Opts, Runner, Section, check, p, reconstruct_args, s, shared};

/// Depth (metres) that separates the S (in front) from the U (behind).
const LETTERS_SPLIT: f32 = 0.85;

/// One letter of a result: its share of the mesh's area, its area-weighted median depth and its centre.
#[derive(Debug, Clone, Copy)]
struct Letter {
    area_share: f64,
    median_depth: f64,
    centre: [f64; 2],
}

/// The S (faces whose centroid lies in front of [`LETTERS_SPLIT`]) and the U (behind it) of `mesh`, and the
/// deepest vertex.
fn letters(mesh: &Path) -> Result<(Letter, Letter, f64), String> {
    let m = nlos_mesh::io::load(mesh).map_err(|e| format!("{}: {e}", mesh.display()))?;
    let (pos, tri) = m.to_triangles();
    // (depth, area, centroid) per face.
    let faces: Vec<(f32, f64, Vec3)> = tri
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| pos[v as usize]);
            let centroid = (a + b + c) / 3.0;
            (centroid.z, 0.5 * f64::from((b - a).cross(c - a).length()), centroid)
        })
        .collect();
    let total: f64 = faces.iter().map(|f| f.1).sum();
    let letter = |front: bool| -> Letter {
        let mut sel: Vec<&(f32, f64, Vec3)> = faces.iter().filter(|f| (f.0 < LETTERS_SPLIT) == front).collect();
        sel.sort_by(|a, b| a.0.total_cmp(&b.0));
        let area: f64 = sel.iter().map(|f| f.1).sum();
        let mut acc = 0.0;
        let median = sel
            .iter()
            .find(|f| {
                acc += f.1;
                acc >= 0.5 * area
            })
            .map_or(f64::NAN, |f| f64::from(f.0));
        let centre = sel.iter().fold([0.0; 2], |c, f| [c[0] + f.1 * f64::from(f.2.x), c[1] + f.1 * f64::from(f.2.y)]);
        Letter { area_share: area / total, median_depth: median, centre: centre.map(|c| c / area) }
    };
    let deepest = pos.iter().map(|q| f64::from(q.z)).fold(f64::NEG_INFINITY, f64::max);
    Ok((letter(true), letter(false), deepest))
}

pub(super) fn preprocessed(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    let dir = shared(MEASURED_DIR);
    let (raw, gated) = (dir.join("data_s_u.mat"), dir.join("tsai_su_transient.mat"));
    let mut text = String::new();
    let mut pass = true;
    for f in [&raw, &gated] {
        if !f.exists() {
            let _ = writeln!(text, "- skipped: {} is missing", f.display());
            return Ok(Section { text, pass: false });
        }
    }
    let info = r.nlos(&[s("info"), p(&gated)])?;
    let line = |key: &str| info.stdout.lines().find(|l| l.starts_with(key)).unwrap_or("").to_string();
    let (gate, counts) = (line("gate:"), line("photon counts:"));
    let background: f64 = counts
        .split("background ")
        .nth(1)
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    let _ = writeln!(text, "\n`nlos info tsai_su_transient.mat`:\n\n```\n{gate}\n{counts}\n```\n");
    check(
        &mut text,
        &mut pass,
        &format!("`nlos info` names the gate and gives a non-zero background ({background} per bin)"),
        gate.contains("bins 0..600") && background > 0.0,
    );
    let mut results = Vec::new();
    for (name, capture) in [("raw", &raw), ("preprocessed", &gated)] {
        let run_dir = r.out.join(format!("su_{name}"));
        let _ = std::fs::remove_dir_all(&run_dir);
        let mut a = vec![s("reconstruct"), p(capture), s("--out"), p(&run_dir), s("--quiet")];
        a.extend([s("--brdf"), s("retroreflective")]);
        a.extend(reconstruct_args(opts));
        let ran = r.nlos(&a)?;
        let (letter_s, letter_u, deepest) = letters(&run_dir.join("mesh.obj"))?;
        let pictures = r.depth_pictures(&run_dir, &format!("preprocessed_{name}"), name, "start")?;
        let _ = writeln!(
            text,
            "\n#### {name} ({})\n\nS: {:.1} % of the area, median depth {:.4} m, centre ({:+.3}, {:+.3}) m; U: {:.1} %, \
             {:.4} m, centre ({:+.3}, {:+.3}) m; deepest vertex {deepest:.4} m; {:.0} s wall, {:.0} s CPU\n\n{}\n",
            capture.file_name().and_then(|n| n.to_str()).unwrap_or("?"),
            100.0 * letter_s.area_share,
            letter_s.median_depth,
            letter_s.centre[0],
            letter_s.centre[1],
            100.0 * letter_u.area_share,
            letter_u.median_depth,
            letter_u.centre[0],
            letter_u.centre[1],
            ran.wall_s,
            ran.cpu_s,
            pictures
        );
        if !opts.quick {
            check(&mut text, &mut pass, &format!("{:.0} s ≤ 600 s on this machine", ran.wall_s), ran.wall_s <= 600.0);
        }
        check(
            &mut text,
            &mut pass,
            &format!(
                "no face more than 10 cm behind the U: deepest vertex {deepest:.4} m ≤ {:.4} m",
                letter_u.median_depth + 0.1
            ),
            deepest <= letter_u.median_depth + 0.1,
        );
        results.push((letter_s, letter_u));
    }
    let _ = writeln!(text, "\n#### the two results\n");
    for (i, which) in ["S", "U"].iter().enumerate() {
        let pick = |r: &(Letter, Letter)| if i == 0 { r.0 } else { r.1 };
        let (a, b) = (pick(&results[0]), pick(&results[1]));
        let dz = (a.median_depth - b.median_depth).abs();
        check(
            &mut text,
            &mut pass,
            &format!(
                "{which}: median depth {:.4} m (raw) and {:.4} m (preprocessed), {:.1} mm apart ≤ 5 mm",
                a.median_depth,
                b.median_depth,
                1e3 * dz
            ),
            dz <= 0.005,
        );
        // The preprocessed file's axes are the raw file's turned by a half turn about z.
        let d = ((a.centre[0] + b.centre[0]).powi(2) + (a.centre[1] + b.centre[1]).powi(2)).sqrt();
        check(
            &mut text,
            &mut pass,
            &format!("{which}: centres {:.1} mm apart after the half turn ≤ 30 mm", 1e3 * d),
            d <= 0.03,
        );
    }
    let _ = writeln!(
        text,
        "- letters: judged by eye in the depth maps above (the preprocessed file's turned by a half turn)"
    );
    Ok(Section { text, pass })
}
