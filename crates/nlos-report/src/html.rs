//! The one-page HTML report: inline CSS, relative image links, and the inline 3-D view ([`crate::view3d`]).

use std::fmt::Write as _;
use std::path::Path;

use nlos_mesh::SurfaceMesh;
use nlos_mesh::metrics::{EvalParams, Metrics, SILHOUETTE_BAND};
use nlos_optim::{Reflectance, RunLog, StepKind};

use crate::{Report, ReportOptions};

/// Everything the page shows.
pub(crate) struct PageInputs<'a> {
    pub opts: &'a ReportOptions,
    pub log: &'a RunLog,
    pub report: &'a Report,
    pub reflectance: &'a Reflectance,
    pub reflectance_note: &'a str,
    pub final_mesh: &'a SurfaceMesh,
    pub dir: &'a Path,
    pub eval: &'a EvalParams,
    pub gate_note: &'a str,
    /// The 3-D view's HTML ([`crate::view3d::section`]).
    pub view3d: &'a str,
}

/// Escapes text for HTML element content and attribute values.
pub(crate) fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

fn row(out: &mut String, cells: &[String], header: bool) {
    let tag = if header { "th" } else { "td" };
    out.push_str("<tr>");
    for c in cells {
        let _ = write!(out, "<{tag}>{}</{tag}>", esc(c));
    }
    out.push_str("</tr>\n");
}

fn describe(r: &Reflectance) -> String {
    match r.brdf() {
        Ok(b) => b.describe(),
        Err(e) => format!("invalid ({e})"),
    }
}

fn mm(v: Option<f64>) -> String {
    v.map_or_else(|| "–".into(), |x| format!("{:.3} mm", x * 1e3))
}

fn metric_rows(out: &mut String, init: Option<&Metrics>, fin: &Metrics) {
    let cols = |f: &dyn Fn(&Metrics) -> String| -> Vec<String> { vec![init.map_or_else(|| "–".into(), f), f(fin)] };
    // Interior pixels are at least SILHOUETTE_BAND + 1 pixels from any pixel the ground truth misses.
    let inside = format!("depth error, mean inside (≥ {} pixels from the silhouette)", SILHOUETTE_BAND + 1);
    let within = format!("coverage within {:.0} mm", 1e3 * fin.coverage_threshold);
    let far_mm = 1e3 * nlos_mesh::distance::FAR_FROM_REFERENCE;
    let near = format!("normal error, mean within {far_mm:.0} mm of the truth");
    let far = format!("vertices farther than {far_mm:.0} mm from the truth");
    let rows: Vec<(&str, Vec<String>)> = vec![
        (&within, cols(&|m| format!("{:.1} %", 100.0 * m.coverage_within))),
        ("coverage (any hit; reported, not judged)", cols(&|m| format!("{:.1} %", 100.0 * m.coverage))),
        ("depth error, mean", cols(&|m| mm(m.depth_error_mean))),
        (&inside, cols(&|m| mm(m.depth_error_mean_interior))),
        ("depth error, mean on the silhouette band", cols(&|m| mm(m.depth_error_mean_silhouette))),
        ("depth error, median", cols(&|m| mm(m.depth_error_median))),
        ("depth error, RMS", cols(&|m| mm(m.depth_error_rms))),
        ("depth error, max", cols(&|m| mm(m.depth_error_max))),
        ("Chamfer distance", cols(&|m| mm(Some(m.chamfer)))),
        ("Hausdorff distance", cols(&|m| mm(Some(f64::from(m.hausdorff))))),
        ("normal error, mean", cols(&|m| format!("{:.2}°", m.normal_error_mean_deg))),
        ("normal error, RMS", cols(&|m| format!("{:.2}°", m.normal_error_rms_deg))),
        (&near, cols(&|m| m.normal_error_near_deg.map_or_else(|| "–".into(), |d| format!("{d:.2}°")))),
        (&far, cols(&|m| m.far_vertex_fraction.map_or_else(|| "–".into(), |f| format!("{:.1} %", 100.0 * f)))),
    ];
    for (name, mut v) in rows {
        v.insert(0, name.to_string());
        row(out, &v, false);
    }
}

/// Per-stage summary of the run log: (stage, iterations, shape, reflectance, first loss, last loss, last
/// data term, the share of the light its last surface explains, faces at the end, vertices at the end, λ,
/// seconds at the end).
fn stage_rows(log: &RunLog) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    let mut start = 0;
    let it = &log.iterations;
    while start < it.len() {
        let stage = it[start].stage;
        let end = it[start..].iter().position(|r| r.stage != stage).map_or(it.len(), |k| start + k);
        let s = &it[start..end];
        let (first, last) = (&s[0], &s[s.len() - 1]);
        let shape = s.iter().filter(|r| r.kind == StepKind::Shape).count();
        rows.push(vec![
            (stage + 1).to_string(),
            s.len().to_string(),
            shape.to_string(),
            (s.len() - shape).to_string(),
            format!("{:.4e}", first.loss),
            format!("{:.4e}", last.loss),
            format!("{:.4e}", last.data),
            log.stages
                .iter()
                .find(|r| r.stage == stage)
                .and_then(|r| r.fit)
                .and_then(|f| f.explained())
                .map_or_else(|| "–".to_string(), |e| format!("{:.0} %", 100.0 * e)),
            last.faces.to_string(),
            last.vertices.to_string(),
            format!("{:.3e}", last.reg_weight),
            format!("{:.1}", last.time_s),
        ]);
        start = end;
    }
    rows
}

/// The page.
pub(crate) fn page(p: &PageInputs<'_>) -> String {
    let mut o = String::new();
    let title = esc(&p.opts.title);
    let _ = write!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{title}</title>\n<style>\n\
         body {{ font-family: sans-serif; max-width: 1400px; margin: 1em auto; padding: 0 1em; color: #222; }}\n\
         table {{ border-collapse: collapse; margin: 0.5em 0 1.5em; }}\n\
         th, td {{ border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: left; }}\n\
         th {{ background: #eee; }}\n\
         img {{ max-width: 100%; border: 1px solid #ddd; margin: 0.3em; vertical-align: top; }}\n\
         .row {{ display: flex; flex-wrap: wrap; align-items: flex-start; }}\n\
         canvas {{ border: 1px solid #ddd; max-width: 100%; cursor: grab; }}\n\
         .note {{ color: #555; font-size: 90%; }}\n\
         </style>\n</head>\n<body>\n<h1>{title}</h1>\n"
    );
    let log = p.log;
    let last = log.iterations.last();
    let stages = log.iterations.iter().map(|r| r.stage).max().map_or(0, |s| s + 1);
    let _ = writeln!(
        o,
        "<p>{} iterations over {stages} stage(s); final mesh {} faces, {} vertices. Rendered with the run's \
         renderer settings and reflectance, scaled by the closed-form scale; {}.</p>",
        log.iterations.len(),
        p.final_mesh.n_faces(),
        p.final_mesh.n_vertices(),
        esc(p.gate_note)
    );
    // What a user looks for first: the surface (3-D view, depth seen from the wall), then the verdict.
    let imgs = &p.report.images;
    let section = |o: &mut String, heading: &str, names: &[&str]| {
        let present: Vec<&&str> = names.iter().filter(|n| imgs.iter().any(|i| i == *n)).collect();
        if present.is_empty() {
            return;
        }
        let _ = writeln!(o, "<h2>{}</h2>\n<div class=\"row\">", esc(heading));
        for n in present {
            let _ = writeln!(o, "<img src=\"{0}\" alt=\"{0}\">", esc(n));
        }
        o.push_str("</div>\n");
    };
    o.push_str(p.view3d);
    section(
        &mut o,
        "Depth maps seen from the wall",
        &["depth_init.png", "depth_final.png", "depth_gt.png", "albedo.png", "residual.png"],
    );
    if let Some(fit) = &log.fit {
        let _ = writeln!(o, "<p class=\"verdict\"><b>Fit:</b> the surface {}.</p>", esc(&fit.describe()));
    }

    o.push_str("<h2>Result</h2>\n<table>\n");
    row(&mut o, &["".into(), "value".into()], true);
    let mut add = |k: &str, v: String| row(&mut o, &[k.to_string(), v], false);
    add("final mesh", format!("{} faces, {} vertices", p.final_mesh.n_faces(), p.final_mesh.n_vertices()));
    add("fitted reflectance", format!("{} ({})", describe(p.reflectance), p.reflectance_note));
    if let Some(l) = last {
        add("final loss", format!("{:.5e}", l.loss));
        add("final data term (normalised)", format!("{:.5e}", l.data));
        add("final regulariser (unweighted), weight", format!("{:.5e}, {:.3e}", l.regulariser, l.reg_weight));
        add("run time", format!("{:.1} s", l.time_s));
    }
    add("iterations, rollbacks", format!("{}, {}", log.iterations.len(), log.rollbacks));
    add("scale s* of the final rendering", format!("{:.5e}", p.report.scale));
    add("relative residual |s*I - m| / |m|", format!("{:.4}", p.report.relative_residual));
    o.push_str("</table>\n");

    if let Some(fin) = &p.report.metrics_final {
        let _ = writeln!(
            o,
            "<h2>Metrics against the ground truth</h2>\n<p>+z rays from a {n} × {n} grid over x ∈ [{:.3}, {:.3}] m, \
             y ∈ [{:.3}, {:.3}] m of the wall (as <code>nlos eval</code>).</p>\n<table>",
            p.eval.x_range[0],
            p.eval.x_range[1],
            p.eval.y_range[0],
            p.eval.y_range[1],
            n = p.eval.grid,
        );
        row(&mut o, &["metric".into(), "initial surface".into(), "final mesh".into()], true);
        metric_rows(&mut o, p.report.metrics_init.as_ref(), fin);
        o.push_str("</table>\n");
    }

    section(&mut o, "Measured vs rendered", &["summed.png", "xt_slice.png"]);
    section(&mut o, "Loss", &["loss.png"]);
    section(&mut o, "Relief", &["relief.png"]);
    section(&mut o, "Coverage against the ground truth", &["coverage.png"]);
    // Any image not placed above still gets shown.
    let placed = [
        "summed.png",
        "xt_slice.png",
        "loss.png",
        "depth_init.png",
        "depth_final.png",
        "depth_gt.png",
        "albedo.png",
        "residual.png",
        "relief.png",
        "coverage.png",
    ];
    let others: Vec<&str> = imgs.iter().map(String::as_str).filter(|i| !placed.contains(i)).collect();
    section(&mut o, "Other figures", &others);

    o.push_str("<h2>Stages</h2>\n<table>\n");
    row(
        &mut o,
        &[
            "stage",
            "iterations",
            "shape",
            "reflectance",
            "first loss",
            "last loss",
            "last data",
            "explained",
            "faces",
            "vertices",
            "lambda",
            "t end (s)",
            "mesh",
        ]
        .map(String::from),
        true,
    );
    for mut r in stage_rows(log) {
        let stage: u32 = r[0].parse().unwrap_or(1);
        let name = format!("stage_{:02}.obj", stage.saturating_sub(1));
        let cells: String = r.drain(..).map(|c| format!("<td>{}</td>", esc(&c))).collect();
        let link = if p.dir.join(&name).is_file() {
            format!("<td><a href=\"{0}\">{0}</a></td>", esc(&name))
        } else {
            "<td>–</td>".into()
        };
        let _ = writeln!(o, "<tr>{cells}{link}</tr>");
    }
    o.push_str("</table>\n");
    // The settings last, each once (the run's own record of them, then what the renderer and data term ran).
    o.push_str("<h2>Settings</h2>\n<table>\n");
    row(&mut o, &["setting".into(), "value".into()], true);
    for (k, v) in &p.opts.parameters {
        row(&mut o, &[k.clone(), v.clone()], false);
    }
    let mut add = |k: &str, v: String| row(&mut o, &[k.to_string(), v], false);
    add(
        "data term",
        match &p.opts.sensor {
            Some(s) => format!(
                "sensor fit: Poisson NLL of scale x J(I) + b, jitter kernel of {} bins, background {:?}",
                s.kernel.weights().len(),
                s.background
            ),
            None => format!("{:?}, closed-form scale", p.opts.loss),
        },
    );
    add("renderer kernel", format!("{:?}", p.opts.render.kernel));
    if !p.opts.parameters.iter().any(|(k, _)| k.starts_with("visibility")) {
        add("visibility", format!("{:?}", p.opts.render.visibility));
    }
    o.push_str("</table>\n");
    o.push_str("<p>Files: <a href=\"mesh.obj\">mesh.obj</a>, <a href=\"run_log.json\">run_log.json</a>.</p>\n");
    o.push_str("</body>\n</html>\n");
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup() {
        assert_eq!(esc("a<b & \"c\">'"), "a&lt;b &amp; &quot;c&quot;&gt;&#39;");
    }
}
