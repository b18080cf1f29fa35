//! Filtered backprojection for confocal grid scans.
//!
//! Backprojection is the adjoint of the light-cone forward model: the LCT pipeline with `conj(Ĥ)` in
//! place of the Wiener filter (O'Toole et al. 2018, Sec. "Reconstruction"; `isbackprop` in their
//! `cnlos_reconstruction.m`). Its blur is sharpened, as in Velten et al. (Nat. Commun. 2012) and the
//! FBP of Lindell et al.'s f-k code (`filterLaplacian`), by a negative second derivative, here along
//! depth only and taken in the LCT's `u = t²` domain before resampling back: `(2v(u) − v(u − 2) −
//! v(u + 2)) / 4`, the square of the central difference (0 within two bins of either end), then clamped
//! at 0. The three-point rule `2v(u) − v(u − 1) − v(u + 1)` would amplify the Nyquist component
//! fourfold, and the backprojection's discretisation ripple then becomes a comb of spurious peaks in
//! front of the surface (seen on rendered planes, `tests/rendered.rs`); the five-point rule passes none. The lateral terms of the full 3-D
//! Laplacian erase the interior of a flat surface wider than the blur (a plane's backprojection is
//! laterally constant) and leave only its outline; the depth term alone turns the backprojection's
//! ramp at the surface into a peak. Taking it in `u`, where the backprojection is smooth, avoids the
//! staircase that resampling to `t` creates near the wall (every early time bin comes from the first
//! u-bin).
//!
//! Exhaustive scans are not handled by this fast path (they need an ellipsoidal backprojection, which
//! this crate does not implement yet): they are refused with [`crate::InitError::NotConfocal`].

use nlos_transient::Transient;

use crate::error::Result;
use crate::lct::{LctParams, Material, lct_grid, volume_from_grid};
use crate::prep;
use crate::prep::Gate;
use crate::volume::Volume;

/// Parameters of [`fbp`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FbpParams {
    /// Radiometric model. Default [`Material::Diffuse`].
    pub material: Material,
    /// Sum this many consecutive bins before reconstructing (≥ 1; default 1 = none).
    pub bin_merge: usize,
    /// Removal of the direct light. Default [`Gate::Auto`].
    pub gate: Gate,
    /// Ignore path lengths beyond `2 × max_depth` (metres; default `None`).
    pub max_depth: Option<f64>,
}

impl Default for FbpParams {
    fn default() -> Self {
        Self { material: Material::Diffuse, bin_merge: 1, gate: Gate::Auto, max_depth: None }
    }
}

/// Laplacian-filtered backprojection of a confocal grid capture.
///
/// # Errors
/// As [`crate::lct`] (`snr` aside).
pub fn fbp(t: &Transient, params: &FbpParams) -> Result<Volume> {
    let p = LctParams {
        material: params.material,
        bin_merge: params.bin_merge,
        gate: params.gate,
        max_depth: params.max_depth,
        backprojection: true,
        ..LctParams::default()
    };
    let g = prep::prepare(t, "filtered backprojection", params.gate, params.max_depth, params.bin_merge)?;
    let data = lct_grid(&g, &p, true);
    Ok(volume_from_grid(&g, data))
}
