//! Release: the albedo of a region is set free where the data ask for a darker surface by more than the
//! noise ([`crate::AlbedoParams::held`]).
//!
//! A free albedo per vertex lets the fit explain missing light by a darker surface instead of a dent
//! ([`crate::albedo`]), but in a confocal capture a face's tilt and its albedo trade against each other:
//! free everywhere, the albedo lets tilts stay wrong (the bunny's interior, docs/accuracy.md). Held, every
//! vertex keeps the surface's albedo until a region test finds a connected region that the data want
//! darker — the alternative "R at albedo ρ < 1" against "R as it is", the test of [`crate::regions`] with
//! one more value in between.
//!
//! **Candidates.** The adjoint of the block's first rendering gives every face's slope `g_f = dE/dw_f`
//! along its factor (`nlos_render::Gradient::faces`, as the albedo steps use it) and, as the adjoint of the
//! sum over all bins, its light `L_f = Σ_k I_f,k`. One face's light is too little to tell from the photon
//! noise (on the `holes` plates a 5 mm face has `Λ` of a few), so both are summed over each vertex's faces
//! and then over each face's corners (about two rings), and the faces are ranked by
//! ```text
//! q_f = Σ g / (Σ L)²
//! ```
//! (for L2, `1 − ρ = g / c` with the curvature `c = s²‖I‖²`, which grows as the square of the light; the
//! neighbourhood's shares overlap in the same bins, so `q_f` ranks and the region test below measures).
//! Candidate regions are the edge-connected components of the faces among the third with the largest
//! `q_f > 0` that hold one of the tenth with the largest (hysteresis, as the region tests), at least three
//! faces each. Only faces at (about) the surface's albedo are candidates.
//!
//! **Test.** Each candidate region's share `I_R` is rendered whole and the data term evaluated with the
//! region at the relative albedos of [`ALBEDOS`]:
//! ```text
//! ΔE_R(ρ) = E(I + (ρ − 1) I_R) − E(I),      ρ̂ = argmin ΔE_R,      Λ_R = −2 ΔE_R(ρ̂) / σ²_R
//! ```
//! in the noise units of [`crate::regions`]. The region is released when `Λ_R ≥`
//! [`ReleaseParams::detection`] and `ρ̂ ≤` [`ReleaseParams::dark`]: its vertices' albedo starts at `ρ̂`
//! and steps from then on; the region tests judge it later as hole or print. A region that the data want
//! only a little darker (`ρ̂ > dark`: a tilt or a shade, not print) stays held. Data without a noise model
//! release on `ρ̂` alone.
//!
//! The test moves no vertex and deletes nothing: it is collision-safe by construction.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{OptimError, Result};
use crate::regions::{RegionFit, RegionNoise, components, share, units};

/// The relative albedos a candidate region is evaluated at (module docs, "Test").
pub const ALBEDOS: [f32; 12] = [0.0, 0.03, 0.06, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.75, 0.9];

/// The share of the faces the data want darker that make a candidate region's core, and that it grows
/// through (module docs, "Candidates").
const CORE: f64 = 0.1;
const GROW: f64 = 0.33;
/// Candidate regions of fewer faces are not tested.
const MIN_FACES: usize = 3;

/// What the adjoint gives per face for the candidates (module docs, "Candidates").
#[derive(Debug, Clone, Copy)]
pub struct FaceTerms<'a> {
    /// `dE/dw_f`, the data term's slope along each face's factor.
    pub slope: &'a [f32],
    /// `Σ_k I_f,k`, each face's light summed over every bin.
    pub light: &'a [f32],
}

/// Settings of the release test ([`crate::AlbedoParams::held`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ReleaseParams {
    /// A region is released when the data ask for a relative albedo at or below this (default 0.5).
    pub dark: f64,
    /// Only faces whose factor is at least this are candidates (default 0.75: held, or released and back
    /// near the surface's albedo).
    pub held: f64,
    /// χ²₁ threshold of the likelihood-ratio statistic (default 9: 3σ).
    pub detection: f64,
}

impl Default for ReleaseParams {
    fn default() -> Self {
        Self { dark: 0.5, held: 0.75, detection: 9.0 }
    }
}

/// A region the data release: its faces and the relative albedo they ask for.
#[derive(Debug, Clone, PartialEq)]
pub struct Release {
    /// Face indices.
    pub faces: Vec<usize>,
    /// `ρ̂` (module docs).
    pub albedo: f64,
    /// `Λ_R` (module docs; infinite for data without a noise model).
    pub statistic: f64,
}

/// What [`released_regions`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Released {
    /// Candidate regions tested.
    pub tested: usize,
    /// The regions released.
    pub regions: Vec<Release>,
}

/// The regions of the surface whose albedo the data ask to be set free (module docs).
///
/// `fit.renderer` holds `triangles` at the current positions with the face factors `weights`, and
/// `face_terms` its adjoint's slope and light per face at the rendering `fit.rendered`.
///
/// # Errors
/// [`OptimError::LengthMismatch`] for `weights`, `face_terms` or `rendered` of the wrong length; the errors of the
/// renderer and of the data term.
pub fn released_regions(
    triangles: &[[u32; 3]],
    weights: &[f32],
    face_terms: &FaceTerms<'_>,
    fit: RegionFit<'_>,
    noise: RegionNoise,
    params: &ReleaseParams,
) -> Result<Released> {
    let nt = triangles.len();
    for (what, got) in [
        ("face weights", weights.len()),
        ("face slopes", face_terms.slope.len()),
        ("face light", face_terms.light.len()),
    ] {
        if got != nt {
            return Err(OptimError::LengthMismatch { what, expected: nt, got });
        }
    }
    let rows = fit.renderer.scan().measurements();
    if fit.bins == 0 || fit.rendered.len() != rows * fit.bins {
        return Err(OptimError::LengthMismatch {
            what: "rendered",
            expected: rows * fit.bins,
            got: fit.rendered.len(),
        });
    }
    let candidate: Vec<bool> = (0..nt).map(|f| f64::from(weights[f]) >= params.held).collect();
    // Summed over each vertex's faces, then over each face's corners.
    let nv = triangles.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
    let mut at_vertex = vec![(0.0f64, 0.0f64); nv];
    for (f, t) in triangles.iter().enumerate().filter(|(f, _)| candidate[*f]) {
        for &v in t {
            at_vertex[v as usize].0 += f64::from(face_terms.slope[f]);
            at_vertex[v as usize].1 += f64::from(face_terms.light[f]);
        }
    }
    let asked: Vec<f64> = triangles
        .iter()
        .map(|t| {
            let (g, l) =
                t.iter().fold((0.0, 0.0), |(g, l), &v| (g + at_vertex[v as usize].0, l + at_vertex[v as usize].1));
            if l > 0.0 && l.is_finite() && g.is_finite() { g / (l * l) } else { 0.0 }
        })
        .collect();
    // Cores: the tenth of the faces the data want darker that they want darkest, grown through the third.
    let mut order: Vec<f64> = (0..nt).filter(|&f| candidate[f] && asked[f] > 0.0).map(|f| asked[f]).collect();
    order.sort_by(|a, b| b.total_cmp(a));
    let quantile = |q: f64| order.get(((order.len() as f64 * q) as usize).min(order.len().saturating_sub(1))).copied();
    let (Some(core), Some(grow)) = (quantile(CORE), quantile(GROW)) else {
        return Ok(Released { tested: 0, regions: Vec::new() });
    };
    let member: Vec<bool> = (0..nt).map(|f| candidate[f] && asked[f] > 0.0 && asked[f] >= grow).collect();
    let regions: Vec<Vec<usize>> = components(triangles, &member)
        .into_iter()
        .filter(|r| r.len() >= MIN_FACES && r.iter().any(|&f| asked[f] >= core))
        .collect();
    let fit = &fit;
    let tested = regions.len();
    let ks: Vec<f32> = ALBEDOS.iter().map(|a| a - 1.0).collect();
    let released: Vec<Option<Release>> = regions
        .into_par_iter()
        .map(|faces| {
            let spans = share(fit.renderer, fit.brdf, &faces)?;
            let mut sums = vec![0.0f64; ks.len()];
            for s in &spans {
                let m = s.measurement;
                let row = &fit.rendered[m * fit.bins..(m + 1) * fit.bins];
                let c = fit.row_loss.changes(m, row, s, &ks)?;
                if c.len() != ks.len() {
                    return Err(OptimError::LengthMismatch {
                        what: "RowTerm::changes",
                        expected: ks.len(),
                        got: c.len(),
                    });
                }
                sums.iter_mut().zip(c).for_each(|(a, x)| *a += x);
            }
            let (best, change) =
                sums.iter().enumerate().fold((0, 0.0f64), |b, (i, &x)| if x < b.1 { (i, x) } else { b });
            let albedo = f64::from(ALBEDOS[best]);
            if change >= 0.0 || albedo > params.dark {
                return Ok(None);
            }
            let statistic = match units(&spans, fit.rendered, fit.bins, noise) {
                Some(k) => -k * change,
                None => f64::INFINITY,
            };
            Ok((statistic >= params.detection).then_some(Release { faces, albedo, statistic }))
        })
        .collect::<Result<_>>()?;
    Ok(Released { tested, regions: released.into_iter().flatten().collect() })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::data_term::RowLoss;
    use crate::regions::tests::{plate_light, strip_plate};
    use nlos_render::AnyBrdf;

    /// The regions released on a plate held at albedo 1 everywhere, for a capture of `truth` (per-face
    /// weights) in photon counts (the brightest bin 10⁴).
    fn released_on(truth: &[f32]) -> Released {
        let (p, t, _, _) = strip_plate();
        let brdf = AnyBrdf::Lambertian(nlos_brdf::Lambertian::new(1.0).unwrap());
        let (_, measured) = plate_light(&p, &t, truth);
        let weights = vec![1.0f32; t.len()];
        let (renderer, mut rendered) = plate_light(&p, &t, &weights);
        let scale = 1e4 / f64::from(measured.iter().copied().fold(0.0, f32::max));
        let bins = 50;
        let loss = |m: usize, row: &[f32], window: std::ops::Range<usize>| -> Result<f64> {
            let data = &measured[m * bins..(m + 1) * bins];
            Ok(window.map(|k| 0.5 * (scale * f64::from(row[k]) - scale * f64::from(data[k])).powi(2)).sum())
        };
        let row_loss: &RowLoss<'_> = &loss;
        // The slope of that data term along each face's factor, and each face's light, from the adjoint.
        let d: Vec<f32> = rendered.iter().zip(&measured).map(|(r, m)| (scale * scale) as f32 * (r - m)).collect();
        let slope = renderer.adjoint_any(&brdf, &d).unwrap().faces;
        let light = renderer.adjoint_any(&brdf, &vec![1.0; rendered.len()]).unwrap().faces;
        let terms = FaceTerms { slope: &slope, light: &light };
        let fit = RegionFit { renderer: &renderer, brdf: &brdf, rendered: &mut rendered, bins, row_loss };
        released_regions(&t, &weights, &terms, fit, RegionNoise::Counts { scale }, &ReleaseParams::default()).unwrap()
    }

    /// A strip printed at 0.1 is released at about that albedo, and holds most of the strip; a slot (the strip
    /// at 0) at 0; a uniform plate releases nothing, and neither does a strip only a little darker (0.8: a
    /// shade, not print).
    #[test]
    fn a_region_the_data_want_dark_is_released_and_a_uniform_plate_is_not() {
        let (_, t, strip, _) = strip_plate();
        for (w, want) in [(0.1f32, 0.1f64), (0.0, 0.0)] {
            let truth: Vec<f32> = strip.iter().map(|&s| if s { w } else { 1.0 }).collect();
            let r = released_on(&truth);
            assert_eq!(
                r.regions.len(),
                1,
                "strip at {w}: {:?}",
                r.regions.iter().map(|x| x.albedo).collect::<Vec<_>>()
            );
            let region = &r.regions[0];
            assert!((region.albedo - want).abs() <= 0.06, "strip at {w}: released at {}", region.albedo);
            let inside = region.faces.iter().filter(|&&f| strip[f]).count();
            let n_strip = strip.iter().filter(|&&s| s).count();
            assert!(inside * 10 >= n_strip * 8, "strip at {w}: {inside} of its {n_strip} faces");
            assert!(region.faces.len() <= 2 * n_strip, "strip at {w}: {} faces", region.faces.len());
        }
        assert!(released_on(&vec![1.0; t.len()]).regions.is_empty());
        let shade: Vec<f32> = strip.iter().map(|&s| if s { 0.8 } else { 1.0 }).collect();
        assert!(released_on(&shade).regions.is_empty());
    }
}
