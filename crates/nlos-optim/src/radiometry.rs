//! The volumetric start matched to the reflectance model: a retroreflective scene (`1/r²` in a confocal
//! scan) gets the light-cone transform's retroreflective weighting, a diffuse one (`1/r⁴`) the diffuse
//! weighting (O'Toole, Lindell & Wetzstein 2018: data weighted by `t²` or `t⁴`).

use nlos_init::{LctParams, Model};

/// The LCT settings of a radiometric model: its weighting and Wiener SNR — 0.1 for diffuse (tuned on the
/// simulated bunny; the captures' reference code uses 0.08 on 16 ps bins for its diffuse S), 0.8 for
/// retroreflective (the reference code's value for its retroreflective scenes).
pub fn lct_params(reflectance: Model) -> LctParams {
    let snr = match reflectance {
        Model::Lambert | Model::Ggx => LctParams::default().snr,
        Model::Retroreflective => 0.8,
    };
    LctParams { reflectance, snr, ..LctParams::default() }
}
