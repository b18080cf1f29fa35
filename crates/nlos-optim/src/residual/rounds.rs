//! Residual patches in rounds ([`residual_rounds`]): Högbom's CLEAN on the fit's residual.

use glam::Vec3;
use nlos_transient::Transient;

use super::{PatchFit, Patches, ResidualParams, residual_patches};
use crate::error::Result;

/// [`residual_patches`] in rounds ([`ResidualParams::rounds`]): each round takes the residual of the
/// rendering as the rounds before it left it, `residual_of(rendered)` (the data minus the model of the data
/// term; `fit.rendered` gains each accepted patch's share), and tests patches away from the mesh and every
/// patch accepted before. The rounds end at the first that accepts nothing or whose patches explain less
/// than [`ResidualParams::round_gain`] of the data term (`fit.row_loss` over every histogram).
///
/// Returns each round's [`Patches`] in order; a round's new vertices are numbered after the mesh's and all
/// earlier rounds', so appending the rounds in order to the mesh gives the grown mesh.
///
/// # Errors
/// As [`residual_patches`], and whatever `residual_of` returns.
pub fn residual_rounds(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    measured: &Transient,
    residual_of: &mut dyn FnMut(&[f32]) -> Result<Vec<f32>>,
    fit: PatchFit<'_>,
    params: &ResidualParams,
) -> Result<Vec<Patches>> {
    let (mut pos, mut tri) = (positions.to_vec(), triangles.to_vec());
    let PatchFit { render, brdf, rendered, row_loss } = fit;
    let bins = measured.time().bins;
    let mut data_term = 0.0;
    for (m, row) in rendered.chunks(bins).enumerate() {
        data_term += row_loss.value(m, row, 0..bins)?;
    }
    let mut rounds = Vec::new();
    for _ in 0..params.rounds {
        let residual = residual_of(rendered)?;
        let fit = PatchFit { render, brdf, rendered: &mut *rendered, row_loss };
        let p = residual_patches(&pos, &tri, measured, residual, fit, params)?;
        pos.extend_from_slice(&p.positions);
        tri.extend_from_slice(&p.triangles);
        // A round that accepted nothing leaves the residual as it was: another would propose the same.
        let last = p.accepted == 0 || -p.data_change < params.round_gain * data_term;
        data_term += p.data_change;
        rounds.push(p);
        if last {
            break;
        }
    }
    Ok(rounds)
}
