//! Rollback: a non-finite loss, gradient or position restores the last good state and halves the learning
//! rates, up to [`crate::ReconstructParams::max_rollbacks`] times a run.

use nlos_render::Renderer;

use super::record::RunRecord;
use super::set_albedo_weights;
use crate::adam::{VectorAdam, VertexAdam};
use crate::error::{OptimError, Result};
use crate::params::ReconstructParams;
use crate::reflectance::Reflectance;
use crate::surface::Surface;

/// Counts a rollback (failing with [`OptimError::Diverged`] past `max_rollbacks`) and halves the learning
/// rates: the part shared by the shape and reflectance rollbacks.
pub(super) fn count_rollback(st: &mut RunRecord, params: &ReconstructParams, what: &'static str) -> Result<()> {
    st.log.rollbacks += 1;
    if st.log.rollbacks > params.max_rollbacks {
        return Err(OptimError::Diverged { iteration: st.iteration, what, rollbacks: st.log.rollbacks - 1 });
    }
    st.lr_scale *= 0.5;
    Ok(())
}

/// Restores the vertex state before the last step and halves the learning rates.
pub(super) fn rollback(
    st: &mut RunRecord,
    good: &mut Option<GoodShape>,
    renderer: &mut Renderer,
    params: &ReconstructParams,
    what: &'static str,
) -> Result<()> {
    count_rollback(st, params, what)?;
    if let Some((surface, adam, albedo_steps)) = good.take() {
        st.surface = surface;
        st.shape_adam = adam;
        st.albedo_steps = albedo_steps;
        renderer.set_positions(st.surface.positions())?;
        set_albedo_weights(st, renderer)?;
    }
    Ok(())
}

/// Restores θ before the last reflectance step and halves the learning rates.
pub(super) fn rollback_refl(
    st: &mut RunRecord,
    good: &mut Option<GoodReflectance>,
    renderer: &mut Renderer,
    params: &ReconstructParams,
    what: &'static str,
) -> Result<()> {
    count_rollback(st, params, what)?;
    if let Some((r, a, surface, steps)) = good.take() {
        st.reflectance = r;
        st.reflectance_adam = a;
        st.surface = surface;
        st.albedo_steps = steps;
        set_albedo_weights(st, renderer)?;
    }
    Ok(())
}

/// The shape state a shape rollback restores: the surface (its positions and fields, the albedo among them)
/// and the Adam step counts of the shape and of the albedo.
pub(super) type GoodShape = (Surface, VertexAdam, u64);

/// The reflectance state a reflectance rollback restores: θ, its Adam state, the surface (its albedo and
/// the albedo's moments) and the albedo's step count.
pub(super) type GoodReflectance = (Reflectance, VectorAdam, Surface, u64);
