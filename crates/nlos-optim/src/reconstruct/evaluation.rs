//! One evaluation of the run's data term at the current state ([`evaluate`]: value, scale, noise floor and
//! gradients through the renderer's adjoint), its normaliser, and what each stage fits ([`StageData`]).

use std::sync::RwLock;

use glam::Vec3;
use nlos_render::Renderer;
use nlos_transient::Transient;

use super::log::FitQuality;
use super::record::RunRecord;
use crate::data_term::RowLoss;
use crate::data_term::counts::{SensorModel, SensorRows};
use crate::data_term::intensities::{DataTermRows, counts_variance};
use crate::error::{OptimError, Result};
use crate::params::ReconstructParams;

/// Loss pieces at the current state.
pub(super) struct Eval {
    pub(super) data: f64,
    /// The normalised noise floor of the data term ([`crate::SensorFit::noise_floor`],
    /// [`crate::DataTerm::noise_floor`]) when asked for and the data are counts; 0 otherwise.
    pub(super) floor: f64,
    pub(super) scale: f64,
    pub(super) grad_vertices: Vec<Vec3>,
    pub(super) grad_theta: Vec<f64>,
    /// dE/dw_t per triangle (`nlos_render::Gradient::faces`), for the albedo map.
    pub(super) grad_faces: Vec<f32>,
}

/// The data term of a run: the plain [`crate::DataTerm`], or the sensor fit on the stage's bins.
pub(super) struct Fit<'a> {
    pub(super) params: &'a ReconstructParams,
    pub(super) measured: &'a [f32],
    /// The sensor fit on this stage's capture (None: the plain data term).
    pub(super) sensor: Option<&'a SensorModel>,
    /// Normaliser of the data term.
    pub(super) norm: f64,
}

/// The data term, its scale and gradients at the current state; with `want_floor`, also the data term's
/// noise floor (for the automatic regulariser weight).
pub(super) fn evaluate(st: &RunRecord, r: &Renderer, fit: &Fit<'_>, want_floor: bool) -> Result<Eval> {
    let (params, measured, norm) = (fit.params, fit.measured, fit.norm);
    let brdf = st.reflectance.brdf()?;
    let rendered = r.forward_any(&brdf);
    let inv = (1.0 / norm) as f32;
    let (data, floor, scale, g) = match fit.sensor {
        Some(sensor) => {
            let (ev, a) = sensor.evaluate(&rendered, measured, params.data.solve_scale, st.scale)?;
            let floor = if want_floor { sensor.noise_floor(&a, ev.scale) / norm } else { 0.0 };
            let d: Vec<f32> = ev.d_rendered.iter().map(|x| x * inv).collect();
            (ev.value, floor, ev.scale, r.adjoint_any(&brdf, &d)?)
        }
        None => {
            // `DataTerm::evaluate`'s scale, value and gradient, to the bit: the gradient bin by bin on both
            // cores, then the adjoint on both cores while the value and the noise floor (sums in bin order)
            // take whichever core is free.
            let term = &params.data;
            let scale = term.scale_for(&rendered, measured, st.scale)?;
            let (s32, w) = (scale as f32, term.weights.as_deref());
            let d = term.loss.gradient_scaled(&rendered, s32, measured, w, inv)?;
            let (g, sums) = rayon::join(
                || r.adjoint_any(&brdf, &d),
                || -> Result<(f64, f64)> {
                    let value = term.loss.value_scaled(&rendered, s32, measured, w)?;
                    let floor = if want_floor && term.counts {
                        term.noise_floor(&rendered, measured, scale)? / norm
                    } else {
                        0.0
                    };
                    Ok((value, floor))
                },
            );
            let (value, floor) = sums?;
            (value, floor, scale, g?)
        }
    };
    Ok(Eval {
        data: data / norm,
        floor,
        scale,
        grad_theta: st.reflectance.chain(&g.brdf),
        grad_vertices: g.vertices,
        grad_faces: g.faces,
    })
}

/// How much of the capture `fit` holds the surface that `r` renders explains ([`FitQuality`]): the data term
/// at the fitted scale, an empty scene's (no surface, the background alone: under a sensor fit its resolved
/// background, else the best constant level) and the noise floor where the data are photon counts.
///
/// # Errors
/// As [`evaluate`].
pub(super) fn fit_quality(st: &RunRecord, r: &Renderer, fit: &Fit<'_>) -> Result<FitQuality> {
    let (params, measured, norm) = (fit.params, fit.measured, fit.norm);
    let rendered = r.forward_any(&st.reflectance.brdf()?);
    Ok(match fit.sensor {
        Some(sensor) => {
            let (ev, a) = sensor.evaluate(&rendered, measured, params.data.solve_scale, st.scale)?;
            // Nothing rendered: the sensor fit's background alone.
            let (empty, _) = sensor.evaluate(&vec![0.0; rendered.len()], measured, false, 1.0)?;
            FitQuality {
                data: ev.value / norm,
                empty: empty.value / norm,
                noise_floor: Some(sensor.noise_floor(&a, ev.scale) / norm),
                // The Poisson half-deviance: Λ = 2ΔE.
                detection: Some(2.0 * (empty.value - ev.value)),
            }
        }
        None => {
            let ev = params.data.evaluate(&rendered, measured, st.scale)?;
            // No surface, the capture's background alone: with the scale solved, a constant rendering fits the
            // best constant level (the mean, for L2 and Poisson alike); with a fixed scale, nothing.
            let level = if params.data.solve_scale { 1.0f32 } else { 0.0 };
            let empty = params.data.evaluate(&vec![level; rendered.len()], measured, 0.0)?;
            let (floor, detection) = if params.data.counts {
                let gain = empty.value - ev.value;
                let detection = match params.data.loss {
                    nlos_render::Loss::L2 => {
                        2.0 * gain / counts_variance(along_itself(&rendered, params.data.weights.as_deref()), ev.scale)
                    }
                    nlos_render::Loss::PoissonNll { .. } => 2.0 * gain,
                };
                (
                    Some(params.data.noise_floor(&rendered, measured, ev.scale)? / norm),
                    Some(detection).filter(|l| l.is_finite()),
                )
            } else {
                (None, None)
            };
            FitQuality { data: ev.value / norm, empty: empty.value / norm, noise_floor: floor, detection }
        }
    })
}

/// The rendering's bins as `(I, d, w)` terms of [`counts_variance`] along the rendering itself, `w` the data
/// term's weights (1 without).
fn along_itself<'a>(rendered: &'a [f32], weights: Option<&'a [f32]>) -> impl Iterator<Item = (f32, f32, f64)> + 'a {
    rendered.iter().enumerate().map(move |(k, &r)| (r, r, weights.map_or(1.0, |w| f64::from(w[k]))))
}

/// The data term of `fit` row by row at `scale` ([`RowLoss`], what pruning, the region tests, the residual
/// patches and the support take): the sensor fit's rows with the cached `J I` of the rendering (`response`,
/// kept current through the deletions), else the plain data term's.
pub(super) fn row_terms<'a>(
    fit: &Fit<'a>,
    bins: usize,
    scale: f64,
    response: Option<&'a RwLock<Vec<f64>>>,
) -> Box<RowLoss<'a>> {
    let (params, data) = (fit.params, fit.measured);
    match fit.sensor {
        Some(m) => Box::new(SensorRows { fit: &m.fit, counts: data, bins, background: m.background, scale, response }),
        None => Box::new(DataTermRows { term: &params.data, measured: data, bins, scale }),
    }
}

/// The support of every face of the final surface ([`crate::support`]) at the run's scale.
pub(super) fn face_support(st: &RunRecord, r: &Renderer, fit: &Fit<'_>) -> Result<Vec<f64>> {
    let brdf = st.reflectance.brdf()?;
    let rendered = r.forward_any(&brdf);
    let bins = r.time().bins;
    let response = match fit.sensor {
        Some(m) => Some(RwLock::new(m.response(&rendered)?)),
        None => None,
    };
    let rows = row_terms(fit, bins, st.scale, response.as_ref());
    crate::support::face_support(st.surface.n_faces(), r, &brdf, &rendered, bins, &*rows)
}

/// A shape step's evaluation: data term and gradient, the regulariser (normal + boundary smoothing), the
/// normal-smoothing part alone (what λ is set against), the regulariser's gradient.
pub(super) type Attempt = (Eval, f64, f64, Vec<Vec3>);

/// Normaliser of the data term on `data` (the measurement a stage fits).
pub(super) fn data_normaliser(params: &ReconstructParams, data: &[f32]) -> Result<f64> {
    let norm = match &params.sensor {
        Some(_) => crate::data_term::counts::SensorFit::normaliser(data),
        None => params.data.normaliser(data),
    };
    norm.ok_or(OptimError::InvalidParameter {
        name: "measured",
        value: 0.0,
        reason: "the (weighted) measurement is zero everywhere: there is nothing to fit",
    })
}

/// What one stage fits: the capture with [`crate::Schedule::rebin`] bins summed (`None`: `measured` itself,
/// for a factor of 1 or per-bin weights, which are defined on its own bins) and the sensor fit on those bins
/// (the response of the summed bins and their background, [`SensorModel::summed`]).
pub(super) struct StageData {
    pub(super) stage: u32,
    pub(super) capture: Option<Transient>,
    pub(super) sensor: Option<SensorModel>,
}

impl StageData {
    /// Bins summed by a stage of target edge `edge` (none with per-bin weights, defined on the capture's bins).
    pub(super) fn bins_summed(measured: &Transient, params: &ReconstructParams, edge: f64) -> usize {
        let k = params.schedule.rebin_at(edge, measured.time().bin_width).min(measured.bins());
        if params.data.weights.is_some() { 1 } else { k }
    }

    /// The data of stage `stage` at target edge `edge`; `background` is the sensor fit's background on the
    /// capture's own bins.
    pub(super) fn new(
        measured: &Transient,
        params: &ReconstructParams,
        stage: u32,
        edge: f64,
        background: f64,
    ) -> Result<Self> {
        let k = Self::bins_summed(measured, params, edge);
        let capture = if k > 1 {
            Some(measured.rebin(k).map_err(|source| OptimError::Transient { context: "stage capture", source })?)
        } else {
            None
        };
        let fitted = capture.as_ref().unwrap_or(measured);
        let sensor = match &params.sensor {
            Some(fit) => Some(SensorModel::summed(fit, k, background, fitted.bins(), fitted.data())?),
            None => None,
        };
        Ok(Self { stage, capture, sensor })
    }
}
