//! Probe of residual back-projection on a capture and a mesh: prints what `nlos_optim::residual_patches`
//! proposes and accepts, and writes the accepted patches joined to the mesh.
//!
//! ```text
//! cargo run --release -p nlos-optim --example residual_probe -- CAPTURE MESH OUT.obj [subsample] [margin] [separation]
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nlos_brdf::Lambertian;
use nlos_optim::{ConcreteBrdf, DataTerm, ResidualParams, residual_patches};
use nlos_render::{DeterministicRule, RenderParams, Renderer, Sampling, Visibility};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    assert!(args.len() >= 3, "usage: residual_probe CAPTURE MESH OUT.obj [subsample] [margin] [separation]");
    let mut measured = nlos_transient::read(&args[0]).expect("capture");
    let k: usize = args.get(3).map_or(1, |a| a.parse().unwrap());
    if k > 1 {
        measured = measured.subsample(k, k).unwrap();
    }
    let margin: f64 = args.get(4).map_or(0.5, |a| a.parse().unwrap());
    let separation: f64 = args.get(5).map_or(0.02, |a| a.parse().unwrap());
    let mesh = nlos_mesh::io::load(&args[1]).expect("mesh");
    let (positions, triangles) = mesh.to_triangles();
    let rule = DeterministicRule { max_level: 3, ..DeterministicRule::default() };
    let render = RenderParams {
        visibility: Visibility::Cached { level: 1 },
        sampling: Sampling::Deterministic(rule),
        ..RenderParams::default()
    };
    let brdf = ConcreteBrdf::Lambertian(Lambertian::new(1.0f32).unwrap());
    let r = Renderer::new(&positions, &triangles, measured.scan(), measured.time(), render).unwrap();
    let mut rendered = brdf.forward(&r);
    let term = DataTerm::default();
    let data = measured.data().to_vec();
    let scale = term.optimal_scale(&rendered, &data).unwrap();
    let bins = measured.bins();
    let row_loss = |m: usize, row: &[f32], w: std::ops::Range<usize>| {
        term.row_value_in(row, &data[m * bins..(m + 1) * bins], m * bins, scale, w)
    };
    let residual: Vec<f32> = data.iter().zip(&rendered).map(|(&d, &r)| d - (scale * f64::from(r)) as f32).collect();
    let params = ResidualParams { margin, separation, ..ResidualParams::default() };
    let p =
        residual_patches(&positions, &triangles, &measured, residual, render, &brdf, &mut rendered, &row_loss, &params)
            .unwrap();
    let norm = term.normaliser(&data).unwrap();
    println!(
        "{} columns, {} regions, {} accepted, {} faces, data change {:.4e} (normalised {:.4e})",
        p.columns,
        p.regions,
        p.accepted,
        p.triangles.len(),
        p.data_change,
        p.data_change / norm
    );
    let mut all_p = positions;
    all_p.extend(&p.positions);
    let mut all_t = triangles;
    all_t.extend(&p.triangles);
    let out = nlos_mesh::SurfaceMesh::from_triangles(&all_p, &all_t).unwrap();
    nlos_mesh::io::save(&out, &args[2]).unwrap();
}
