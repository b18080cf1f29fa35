//! A reconstruction from Rust, as `nlos reconstruct CAPTURE --out DIR [--config FILE]` runs it:
//! `cargo run --release -p nlos-optim --example reconstruct -- CAPTURE DIR [SETTINGS.toml]`.
//!
//! The pipeline ([`nlos_optim::pipeline`]) prepares the capture and decides every `auto` setting; the loop
//! writes `mesh.obj`, the run log and the checkpoint into DIR.

use std::path::PathBuf;

use nlos_optim::pipeline::{Config, Prepared};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(capture), Some(out)) = (args.first(), args.get(1)) else {
        return Err("usage: reconstruct CAPTURE DIR [SETTINGS.toml]".into());
    };
    let config = match args.get(2) {
        Some(file) => Config::load(file.as_ref())?,
        None => Config::default(),
    };
    let prepared = Prepared::load(capture.as_ref(), &config)?;
    for note in &prepared.notes {
        eprintln!("{note}");
    }
    let params = prepared.params(&config, Some(PathBuf::from(out)))?;
    let init = prepared.initial_surface(&config)?;
    let outcome = nlos_optim::reconstruct(&prepared.measured, &init, &params)?;
    println!("{out}/mesh.obj: {} faces after {} blocks", outcome.mesh.n_faces(), outcome.blocks_done);
    Ok(())
}
