//! Mesh improvement (stub).
use super::{EvolveError, EvolveParams};
use crate::surface_mesh::SurfaceMesh;

/// What [`improve`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ImproveReport {
    /// Edge splits.
    pub splits: usize,
}

/// Improves the mesh.
pub fn improve(mesh: &mut SurfaceMesh, params: &EvolveParams) -> Result<ImproveReport, EvolveError> {
    let l = params.edge_length.unwrap_or_else(|| mesh.mean_edge_length());
    improve_with_length(mesh, params, l)
}

pub(crate) fn improve_with_length(
    _mesh: &mut SurfaceMesh,
    _params: &EvolveParams,
    _l: f32,
) -> Result<ImproveReport, EvolveError> {
    Ok(ImproveReport::default())
}
