//! Rollback: a non-finite loss, gradient or position restores the last good state and halves the learning
//! rates, up to [`crate::ReconstructParams::max_rollbacks`] times a run.

use nlos_render::Renderer;

use super::record::RunRecord;
use super::set_albedo_weights;
use crate::adam::{VectorAdam, VertexAdam};
use crate::albedo::AlbedoMap;
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
    if let Some((surface, adam)) = good.take() {
        st.surface = surface;
        st.shape_adam = adam;
        renderer.set_positions(st.surface.positions())?;
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
    if let Some((r, a, map, map_adam)) = good.take() {
        st.reflectance = r;
        st.reflectance_adam = a;
        st.albedo = map;
        st.albedo_adam = map_adam;
        set_albedo_weights(st, renderer)?;
    }
    Ok(())
}

/// The shape state a shape rollback restores: the surface (its positions and fields) and the Adam step count.
pub(super) type GoodShape = (Surface, VertexAdam);

/// The reflectance state a reflectance rollback restores: θ, its Adam state, the albedo map and its Adam
/// state.
pub(super) type GoodReflectance = (Reflectance, VectorAdam, Option<AlbedoMap>, VectorAdam);
