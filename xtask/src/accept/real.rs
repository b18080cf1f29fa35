//! The `real` scenario: the Stanford captures (the 40 cm chart, the diffuse S, the S and U) through the default
//! command, judged on time, the chart's plane and the letters.

use std::fmt::Write as _;

use crate::accept::{MEASURED_DIR, Opts, Runner, Section, check, p, reconstruct_args, s, shared};

pub(super) fn real(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    let dir = shared(MEASURED_DIR);
    let mut text = String::new();
    let mut pass = true;
    for name in ["data_resolution_chart_40cm", "data_diffuse_s", "data_s_u"] {
        let capture = dir.join(format!("{name}.mat"));
        if !capture.exists() {
            let _ = writeln!(text, "- {name}: skipped, {} is missing", capture.display());
            continue;
        }
        let run_dir = r.out.join(name);
        let _ = std::fs::remove_dir_all(&run_dir);
        // The default command; the captures' reference code treats every scene but the diffuse S as
        // retroreflective (../shared/data/README.md).
        let mut a = vec![s("reconstruct"), p(&capture), s("--out"), p(&run_dir), s("--quiet")];
        if name != "data_diffuse_s" {
            a.extend([s("--brdf"), s("retroreflective")]);
        }
        a.extend(reconstruct_args(opts));
        let ran = r.nlos(&a)?;
        let mesh = nlos_mesh::io::load(run_dir.join("mesh.obj")).map_err(|e| e.to_string())?;
        let mut z: Vec<f32> = mesh.positions().iter().map(|q| q.z).collect();
        z.sort_by(f32::total_cmp);
        let median = z.get(z.len() / 2).copied().unwrap_or(f32::NAN);
        let q = |f: f64| z.get(((z.len().max(1) - 1) as f64 * f) as usize).copied().unwrap_or(f32::NAN);
        let (p10, p90) = (q(0.1), q(0.9));
        let pictures = r.depth_pictures(&run_dir, &format!("real_{name}"), name, "LCT start")?;
        let _ = writeln!(
            text,
            "\n#### {name}\n\n{} faces, median vertex depth {median:.4} m (10th–90th percentile {p10:.4}–{p90:.4} m); \
             {:.0} s wall, {:.0} s CPU\n\n{}\n",
            mesh.n_faces(),
            ran.wall_s,
            ran.cpu_s,
            pictures
        );
        if !opts.quick {
            check(&mut text, &mut pass, &format!("{:.0} s ≤ 600 s on this machine", ran.wall_s), ran.wall_s <= 600.0);
        }
        // The whole schedule: every stage started and ended by its own rule, none cut by the time budget.
        let log: nlos_optim::RunLog = serde_json::from_str(
            &std::fs::read_to_string(run_dir.join("run_log.json")).map_err(|e| format!("{name} run log: {e}"))?,
        )
        .map_err(|e| format!("{name} run log: {e}"))?;
        let edges = |f: fn(&nlos_optim::StageRecord) -> f64| {
            log.stages.iter().map(|r| format!("{:.1}", 1e3 * f(r))).collect::<Vec<_>>().join(", ")
        };
        check(
            &mut text,
            &mut pass,
            &format!(
                "the whole schedule ran: {} stages at {} mm edges (the schedule's {} mm), stop `{}`",
                log.stages.len(),
                edges(|r| r.edge_length),
                edges(|r| r.schedule_edge_length),
                ran.stdout.lines().rev().find_map(|l| l.split("stop: ").nth(1)).unwrap_or("?").trim()
            ),
            ran.stdout.contains("stop: all stages ran"),
        );
        if name.contains("chart") {
            // A plane: the 10th–90th percentile spread of the vertices' depths about their least-squares plane
            // within 10 mm (about two depth bins at --rebin 8; a fit that turns the print into relief spreads
            // over 60–80 mm).
            let (plane, spread) = plane_fit(mesh.positions());
            check(
                &mut text,
                &mut pass,
                &format!(
                    "chart flat: depths about the plane z = {:.4} {:+.4}·x {:+.4}·y spread {:.1} mm (10th–90th \
                     percentile) ≤ 10 mm",
                    plane[0],
                    plane[1],
                    plane[2],
                    spread * 1e3
                ),
                spread <= 0.010,
            );
            check(
                &mut text,
                &mut pass,
                &format!(
                    "chart plane at {median:.4} m, 0.410 ± 0.005 m (docs/accuracy.md; the summed histogram peaks at 0.425 m)"
                ),
                (f64::from(median) - 0.410).abs() <= 0.005,
            );
        } else {
            let _ = writeln!(text, "- letters: judged by eye in the depth maps above");
        }
    }
    Ok(Section { text, pass })
}

/// The least-squares plane `z = a + b·x + c·y` through the points, and the 10th–90th percentile spread of
/// their depths about it (metres). NaN for fewer than three points or a degenerate layout.
pub(super) fn plane_fit(points: &[glam::Vec3]) -> ([f64; 3], f64) {
    // Normal equations, centred for conditioning.
    let n = points.len() as f64;
    let mean = points.iter().fold(glam::DVec3::ZERO, |a, p| a + p.as_dvec3()) / n.max(1.0);
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let d = p.as_dvec3() - mean;
        (sxx, sxy, syy, sxz, syz) =
            (sxx + d.x * d.x, sxy + d.x * d.y, syy + d.y * d.y, sxz + d.x * d.z, syz + d.y * d.z);
    }
    let det = sxx * syy - sxy * sxy;
    if points.len() < 3 || det.abs() <= 1e-18 || det.is_nan() {
        return ([f64::NAN; 3], f64::NAN);
    }
    let b = (sxz * syy - syz * sxy) / det;
    let c = (syz * sxx - sxz * sxy) / det;
    let a = mean.z - b * mean.x - c * mean.y;
    let mut r: Vec<f64> =
        points.iter().map(|p| f64::from(p.z) - (a + b * f64::from(p.x) + c * f64::from(p.y))).collect();
    r.sort_by(f64::total_cmp);
    let q = |f: f64| r[((r.len() - 1) as f64 * f) as usize];
    ([a, b, c], q(0.9) - q(0.1))
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::plane_fit;

    #[test]
    fn plane_fit_recovers_a_tilted_plane_and_its_spread() {
        // z = 0.41 + 0.02 x − 0.05 y, and every seventh point (14 %, spread over the grid) 20 mm behind it.
        let pts: Vec<Vec3> = (0..400)
            .map(|i| {
                let (x, y) = ((i % 20) as f32 * 0.01 - 0.1, (i / 20) as f32 * 0.01 - 0.1);
                let off = if i % 7 == 0 { 0.02 } else { 0.0 };
                Vec3::new(x, y, 0.41 + 0.02 * x - 0.05 * y + off)
            })
            .collect();
        let (p, spread) = plane_fit(&pts);
        assert!((p[1] - 0.02).abs() < 2e-3 && (p[2] + 0.05).abs() < 2e-3, "{p:?}");
        // 14 % of the points sit 20 mm behind: the 90th percentile is among them, the 10th among the rest.
        assert!((spread - 0.02).abs() < 1e-4, "{spread}");
        assert!(plane_fit(&pts[..2]).1.is_nan());
    }
}
