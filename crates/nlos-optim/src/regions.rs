//! Region tests: a dark part of the surface is a hole or print, judged by the data.
//!
//! With an albedo per vertex ([`crate::albedo`]) the fit explains missing light by a darker surface instead
//! of a dent. Where nothing is — a slot cut through a plate, the gap between two objects that the start
//! bridged — the albedo falls toward 0, and where the object is printed dark it falls to the print's
//! albedo. The test tells the two apart by asking the data whether the dark region's light is there at all.
//!
//! **Regions.** The faces whose factor `w_t` ([`crate::albedo::face_weights`]) is below
//! [`RegionParams::dark`] (relative to the mean, 1), grouped by the edge-connected components of the faces
//! below twice `dark` (hysteresis, as Canny's edges): the fitted albedo is noisy, and a printed bar cut into
//! pieces by a few brighter faces would be tested piece by piece, each too small for its light to be
//! detected — on the `holes` scenario's 10 mm bar the whole bar's light is 52 in the units of `Λ` below, a
//! tenth of it 5. Only the dark faces are tested and deleted: the dimmer ones that join them straddle a
//! hole's edge, half on the surface, and stay for pruning to judge on the hole's new rim. Every region is
//! tested, interior ones as well as those on the rim (boundary pruning, [`crate::prune`], tests single rim
//! faces).
//!
//! **Test.** A region R with rendered share `I_R = Σ_{f∈R} I_f` (`nlos_render::Renderer::forward_triangle`,
//! so that `Σ_f I_f = I`) changes the data term by
//! ```text
//! ΔE_R = E(I − I_R) − E(I)                                       (scale s held at the block's value)
//! ```
//! if deleted. The albedo was fitted with the shape, so `I_R` is the light the data ask of R; `ΔE_R` is the
//! log-likelihood ratio of "R as fitted" against "nothing at R". It is weighed in the noise's units:
//! ```text
//! Λ_R = 2 ΔE_R / σ²_R                    σ²_R = Σ_k μ_k (s I_R,k)² / Σ_k (s I_R,k)²
//! ```
//! with `μ_k = max(s I_k, 1)` the expected counts of bin k — the likelihood-ratio statistic of the L2 fit
//! of photon counts (`½ Σ (s I − n)²`, Poisson variance μ). For the sensor fit (the Poisson half-deviance)
//! `Λ_R = 2 ΔE_R` exactly. Under "nothing at R", `Λ_R` is χ² with one degree of freedom (Wilks 1938): the
//! region is deleted when `Λ_R <` [`RegionParams::detection`] (default 9: its light is not detected at 3σ),
//! and kept — darker, as fitted — otherwise. Data without a noise model (intensities) have no σ: there a
//! region is deleted when the data explain it as darker than `dark²` of the mean
//! (`ΔE_R < dark⁴ · ½ c_R / w̄_R²`, `c_R` the data term's second difference along `I_R`, `w̄_R` the region's
//! mean factor: for L2 at the fitted albedo `ΔE_R = ½ c_R`, so the test is `w̄_R < dark²`).
//!
//! **Rim.** A dark region's light can be detected although nothing is there. Where the truth's edge runs
//! through faces, the faces on the region's border carry the surface's light across it: on the `holes`
//! scenario's plate the slots' regions had Λ 10–30 while their cores (the faces sharing no vertex with a
//! face outside) had Λ ≈ 0 — the light was the plate's, a face's width from where the mesh could put it.
//! A region whose light is detected is therefore tested once more, against the alternative "nothing at R,
//! and R's rim `N` (the faces outside it that share a vertex with it) brighter by a common factor":
//! ```text
//! ΔE_R,rim = min_β E(I − I_R + β I_N) − min_β E(I + β I_N)        β ≥ 0 on a grid up to 0.7
//! ```
//! each side with the same freedom, so that a rim merely under-fitted favours neither. The two are not
//! nested — one parameter each — so the test chooses the one that explains the data better: the region is
//! deleted when `ΔE_R,rim < 0`. Print keeps its light in its middle, where no rim reaches: on the `holes`
//! scenario's printed plate at 4.6 mm faces the bars kept `Λ_R,rim` (`ΔE_R,rim` in the units of `Λ_R`) of
//! 7.6 (15 mm), 17–22 (20 mm) and 32–36 (30 mm), where the slots' regions had −4 to −6. At coarser faces a
//! bar two faces across is all rim, and its rim brightened by a tenth stood for it
//! ([`RegionParams::rim_stage`]). The rim's brightening is only the test's: the next shape steps fit the
//! rim's albedo. Data without a noise model get the plain test only.
//!
//! **Deletion.** A deleted region's faces go at once; a vertex the deletion leaves between two fans of faces
//! (a non-manifold pinch) keeps its largest fan and loses the others — a few faces on the new hole's rim,
//! which pruning would test next. (Skipping the faces that would pinch, as pruning does face by face, held
//! back whole strips: each face of a strip one face wide pinches on its own.) Deleting faces cannot make the surface intersect
//! itself: the region test is collision-safe by construction (it moves no vertex). The surface may fall into
//! several components (the two objects a start bridged).

use std::collections::HashMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::data_term::RowLoss;
use crate::data_term::intensities::counts_variance;
use crate::error::{OptimError, Result};
use crate::prune::{apply_spans, delta};
use nlos_render::{AnyBrdf, Renderer, RowSpan};

/// Settings of the region tests ([`crate::ReconstructParams::regions`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RegionParams {
    /// Faces darker than this relative albedo (the mean is 1) make the regions tested (default 0.25).
    pub dark: f64,
    /// χ²₁ threshold of the likelihood-ratio statistic: a region whose light is detected below it is deleted
    /// (default 9: 3σ).
    pub detection: f64,
    /// Largest share of the faces deleted per call, in (0, 1] (default 0.5): a guard against a scale gone
    /// wrong.
    pub max_fraction: f64,
    /// The first stage (0-based) whose blocks test regions (default 1; a run of fewer stages tests in its
    /// last). In the first stage of the default schedule (10 mm edges) a 10 mm printed bar is one face wide:
    /// its faces straddle the bar's edges, the few that fall below `dark` carry a fraction of its light, and
    /// on the `holes` scenario's plate the 10 mm bar and pieces of the 20 mm one were deleted there (Λ 4 for
    /// the 10 mm bar's 56 dark faces, against 52 for the whole bar at its true albedo); from the second stage
    /// on every bar's Λ was 20–100.
    pub first_stage: u32,
    /// The first stage (0-based) whose region tests give a region whose light is detected a second test,
    /// with its rim free to brighten (module docs, "Rim"; default 2, the default schedule's last; a run of
    /// fewer stages tests so in its last). On the `holes` scenario's plates at the second stage's 7 mm
    /// edges a printed bar 10–20 mm wide is two or three faces across, and its rim brightened by a tenth
    /// stood for its light (`Λ_R,rim` −9 to 2, the slots' −10 to −20): the bars were deleted. At the third
    /// stage's 4.6 mm the bars kept 7.6–36 and the slots' regions had −4 to −6.
    #[serde(default = "rim_stage")]
    pub rim_stage: u32,
}

fn rim_stage() -> u32 {
    RegionParams::default().rim_stage
}

impl Default for RegionParams {
    fn default() -> Self {
        Self { dark: 0.25, detection: 9.0, max_fraction: 0.5, first_stage: 1, rim_stage: 2 }
    }
}

impl RegionParams {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for `dark` outside (0, 0.5) (regions grow to twice it), a detection threshold that is not finite
    /// and ≥ 0, or `max_fraction` outside (0, 1].
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value, reason| Err(OptimError::InvalidParameter { name, value, reason });
        if !(self.dark > 0.0 && self.dark < 0.5) {
            return bad("regions.dark", self.dark, "the dark threshold is a relative albedo in (0, 0.5)");
        }
        if !(self.detection.is_finite() && self.detection >= 0.0) {
            return bad("regions.detection", self.detection, "the detection threshold must be finite and >= 0");
        }
        if !(self.max_fraction > 0.0 && self.max_fraction <= 1.0) {
            return bad("regions.max_fraction", self.max_fraction, "the share of faces deleted lies in (0, 1]");
        }
        Ok(())
    }
}

/// The noise model the test weighs `ΔE_R` in (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RegionNoise {
    /// The L2 fit of photon counts at scale `s`: `σ²` from the expected counts.
    Counts {
        /// The block's scale.
        scale: f64,
    },
    /// The sensor fit's Poisson half-deviance: `Λ = 2ΔE`.
    Poisson,
    /// Intensities without a noise model: the relative test.
    None,
}

/// What one call of [`dark_regions`] did (one per block in the run's checkpoint).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RegionRecord {
    /// Stage.
    pub stage: u32,
    /// Block within the stage.
    pub block: u32,
    /// Dark regions tested.
    pub tested: usize,
    /// Regions deleted.
    pub deleted: usize,
    /// Faces deleted.
    pub removed: usize,
    /// Dark regions kept (their light detected: print).
    pub kept: usize,
    /// Change of the data term from the deletions, normalised as the run log's data term.
    pub data_change: f64,
}

/// The result of [`dark_regions`].
#[derive(Debug, Clone, PartialEq)]
pub struct Regions {
    /// Per input triangle: kept (`true`) or deleted.
    pub keep: Vec<bool>,
    /// Regions tested, deleted and kept.
    pub tested: usize,
    /// Regions deleted.
    pub deleted: usize,
    /// Faces deleted.
    pub removed: usize,
    /// `Σ ΔE_R` of the deletions (unnormalised data term).
    pub data_change: f64,
}

/// The edge-connected components of the faces for which `member` holds, each a list of face indices.
pub fn components(triangles: &[[u32; 3]], member: &[bool]) -> Vec<Vec<usize>> {
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (f, t) in triangles.iter().enumerate().filter(|(f, _)| member[*f]) {
        for k in 0..3 {
            by_edge.entry(key(t[k], t[(k + 1) % 3])).or_default().push(f);
        }
    }
    let mut seen = vec![false; triangles.len()];
    let mut out = Vec::new();
    for start in 0..triangles.len() {
        if !member[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        let (mut region, mut stack) = (Vec::new(), vec![start]);
        while let Some(f) = stack.pop() {
            region.push(f);
            let t = triangles[f];
            for k in 0..3 {
                for &g in &by_edge[&key(t[k], t[(k + 1) % 3])] {
                    if !seen[g] {
                        seen[g] = true;
                        stack.push(g);
                    }
                }
            }
        }
        region.sort_unstable();
        out.push(region);
    }
    out
}

/// The sum of several faces' shares, one span per measurement.
fn merge(spans: impl IntoIterator<Item = RowSpan>) -> Vec<RowSpan> {
    let mut rows: std::collections::BTreeMap<usize, RowSpan> = std::collections::BTreeMap::new();
    for s in spans {
        match rows.get_mut(&s.measurement) {
            None => {
                rows.insert(s.measurement, s);
            }
            Some(r) => {
                let first = r.first_bin.min(s.first_bin);
                let end = (r.first_bin + r.values.len()).max(s.first_bin + s.values.len());
                let mut values = vec![0.0f32; end - first];
                for part in [&*r, &s] {
                    for (x, v) in values[part.first_bin - first..].iter_mut().zip(&part.values) {
                        *x += v;
                    }
                }
                *r = RowSpan { measurement: s.measurement, first_bin: first, values };
            }
        }
    }
    rows.into_values().collect()
}

/// The rendered share of `faces` (their shares summed, [`merge`]).
fn share(renderer: &Renderer, brdf: &AnyBrdf, faces: &[usize]) -> Result<Vec<RowSpan>> {
    let mut all = Vec::new();
    for &f in faces {
        all.extend(renderer.forward_triangle_any(brdf, f)?);
    }
    Ok(merge(all))
}

/// `Λ_R / ΔE_R` for a region of share `spans` (module docs): 2 for the Poisson half-deviance, `2 / σ²_R` for
/// the L2 fit of counts; None for intensities, which have no noise to weigh in.
fn units(spans: &[RowSpan], rendered: &[f32], bins: usize, noise: RegionNoise) -> Option<f64> {
    match noise {
        RegionNoise::Poisson => Some(2.0),
        RegionNoise::Counts { scale } => {
            let terms = spans.iter().flat_map(|s| {
                let row = &rendered[s.measurement * bins..(s.measurement + 1) * bins];
                row[s.first_bin..].iter().zip(&s.values).map(|(&r, &v)| (r, v, 1.0))
            });
            let variance = counts_variance(terms, scale);
            Some(if variance.is_nan() { 0.0 } else { 2.0 / variance })
        }
        RegionNoise::None => None,
    }
}

/// The likelihood-ratio statistic `Λ_R` of deleting a region of share `spans` (module docs).
fn statistic(
    spans: &[RowSpan],
    rendered: &[f32],
    bins: usize,
    row_loss: &RowLoss<'_>,
    noise: RegionNoise,
    mean_weight: f64,
    dark: f64,
) -> Result<f64> {
    let (test, change) = delta(spans, rendered, bins, row_loss, 1.0, false)?;
    Ok(match units(spans, rendered, bins, noise) {
        Some(k) => k * change,
        // `test − change = ½ c_R` (margin 1): the region's light relative to its light at the mean albedo,
        // squared, over `dark⁴`; the caller's threshold is 1.
        None => {
            let half_c = test - change;
            if half_c > 0.0 { change / (half_c / mean_weight.max(1e-12).powi(2)) / dark.powi(4) } else { 0.0 }
        }
    })
}

/// The brightenings of a region's rim tried by [`rim_refit`]: the rim's light times `1 + β`.
const BRIGHTENINGS: [f32; 12] = [0.01, 0.02, 0.04, 0.06, 0.08, 0.1, 0.13, 0.17, 0.22, 0.3, 0.45, 0.7];

/// The present faces outside `region` that share a vertex with it: its rim.
fn rim(region: &[usize], triangles: &[[u32; 3]], keep: &[bool], vertex_faces: &[Vec<usize>]) -> Vec<usize> {
    let inside: std::collections::HashSet<usize> = region.iter().copied().collect();
    let mut out: Vec<usize> = region
        .iter()
        .flat_map(|&f| triangles[f])
        .flat_map(|v| vertex_faces[v as usize].iter().copied())
        .filter(|g| keep[*g] && !inside.contains(g))
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// The bins of `rendered` that share `s` covers.
fn window<'r>(rendered: &'r [f32], bins: usize, s: &RowSpan) -> &'r [f32] {
    let row = &rendered[s.measurement * bins..(s.measurement + 1) * bins];
    &row[s.first_bin.min(bins)..(s.first_bin + s.values.len()).min(bins)]
}

/// `min_β E(I + β I_N) − E(I)` over [`BRIGHTENINGS`] and β = 0, for the rim's share `rim` and the rendering
/// `rendered` (the data term's state must match it).
fn brightened(rim: &[RowSpan], rendered: &[f32], bins: usize, row_loss: &RowLoss<'_>) -> Result<f64> {
    let mut sums = [0.0f64; BRIGHTENINGS.len()];
    for s in rim {
        let m = s.measurement;
        let changes = row_loss.changes(m, &rendered[m * bins..(m + 1) * bins], s, &BRIGHTENINGS)?;
        sums.iter_mut().zip(changes).for_each(|(a, c)| *a += c);
    }
    Ok(sums.into_iter().fold(0.0, f64::min))
}

/// The change of the data term of deleting a region of share `spans` when its rim (share `rim`) may brighten,
/// against the region kept with the same freedom: `min_β E(I − I_R + β I_N) − min_β E(I + β I_N)`
/// (module docs, "Rim"). `rendered` and the data term are left as they were.
fn rim_refit(
    spans: &[RowSpan],
    rim: &[RowSpan],
    rendered: &mut [f32],
    bins: usize,
    row_loss: &RowLoss<'_>,
) -> Result<f64> {
    let kept = brightened(rim, rendered, bins, row_loss)?;
    let (_, change) = delta(spans, rendered, bins, row_loss, 0.0, false)?;
    // Restored from a copy, not by adding the share back: the subtraction clamps at 0.
    let saved: Vec<Vec<f32>> = spans.iter().map(|s| window(rendered, bins, s).to_vec()).collect();
    apply_spans(spans, rendered, bins, false);
    row_loss.applied(spans, false)?;
    let deleted = brightened(rim, rendered, bins, row_loss);
    for (s, w) in spans.iter().zip(&saved) {
        let start = s.measurement * bins + s.first_bin;
        rendered[start..start + w.len()].copy_from_slice(w);
    }
    row_loss.applied(spans, true)?;
    Ok(change + deleted? - kept)
}

/// What the region tests render and measure: the block's renderer with its BRDF, its forward pass (updated in
/// place: the deleted regions' shares are subtracted), `bins` per histogram, and the data term per histogram
/// at the block's scale.
pub struct RegionFit<'a> {
    /// The block's renderer (the mesh at the current positions, with its face factors).
    pub renderer: &'a Renderer,
    /// The BRDF it renders with.
    pub brdf: &'a AnyBrdf,
    /// Its forward pass, measurement-major.
    pub rendered: &'a mut [f32],
    /// Bins per histogram.
    pub bins: usize,
    /// The data term per histogram ([`RowLoss`]).
    pub row_loss: &'a RowLoss<'a>,
}

impl std::fmt::Debug for RegionFit<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RegionFit")
            .field("brdf", self.brdf)
            .field("rendered", &self.rendered.len())
            .field("bins", &self.bins)
            .finish_non_exhaustive()
    }
}

/// Deletes the dark regions whose light the data do not detect (module docs); with `rim_test`, also those whose
/// light the data detect but a brighter rim explains better (module docs, "Rim").
///
/// `fit.renderer` holds `triangles` at the current positions with the face factors `weights`; `keep` marks
/// the faces still present (faces already deleted, by pruning, are not tested).
///
/// # Errors
/// [`OptimError::InvalidParameter`] for invalid `params`, [`OptimError::LengthMismatch`] for `weights`,
/// `keep` or `rendered` of the wrong length, and the errors of `row_loss` and of the renderer.
pub fn dark_regions(
    triangles: &[[u32; 3]],
    weights: &[f32],
    keep: &[bool],
    fit: RegionFit<'_>,
    noise: RegionNoise,
    params: &RegionParams,
    rim_test: bool,
) -> Result<Regions> {
    let RegionFit { renderer, brdf, rendered, bins, row_loss } = fit;
    params.validate()?;
    let nt = triangles.len();
    for (what, got) in [("face weights", weights.len()), ("kept faces", keep.len())] {
        if got != nt {
            return Err(OptimError::LengthMismatch { what, expected: nt, got });
        }
    }
    let rows = renderer.scan().measurements();
    if bins == 0 || rendered.len() != rows * bins {
        return Err(OptimError::LengthMismatch { what: "rendered", expected: rows * bins, got: rendered.len() });
    }
    let dim: Vec<bool> = (0..nt).map(|f| keep[f] && f64::from(weights[f]) < 2.0 * params.dark).collect();
    let regions: Vec<Vec<usize>> = components(triangles, &dim)
        .into_iter()
        .map(|r| r.into_iter().filter(|&f| f64::from(weights[f]) < params.dark).collect::<Vec<_>>())
        .filter(|r| !r.is_empty())
        .collect();
    let threshold = if matches!(noise, RegionNoise::None) { 1.0 } else { params.detection };
    let snapshot: &[f32] = rendered;
    let mut scored: Vec<(f64, Vec<usize>, Vec<RowSpan>)> = regions
        .into_par_iter()
        .map(|region| {
            let spans = share(renderer, brdf, &region)?;
            let w = region.iter().map(|&f| f64::from(weights[f])).sum::<f64>() / region.len() as f64;
            let lambda = statistic(&spans, snapshot, bins, row_loss, noise, w, params.dark)?;
            Ok((lambda, region, spans))
        })
        .collect::<Result<_>>()?;
    let tested = scored.len();
    // The least supported first: each is re-tested against the rendering the deletions before it left. The
    // regions whose light is detected come last, for the rim test (module docs, "Rim").
    scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1[0].cmp(&b.1[0])));
    let budget = ((nt as f64 * params.max_fraction).floor() as usize).min(nt.saturating_sub(1));
    let mut keep = keep.to_vec();
    let n_vertices = triangles.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
    let vertex_faces = crate::prune::vertex_faces(n_vertices, triangles);
    let (mut deleted, mut removed, mut total) = (0, 0, 0.0);
    for (_, region, spans) in scored {
        if removed + region.len() > budget {
            break;
        }
        let w = region.iter().map(|&f| f64::from(weights[f])).sum::<f64>() / region.len() as f64;
        let lambda = statistic(&spans, rendered, bins, row_loss, noise, w, params.dark)?;
        let hole = if lambda < threshold {
            true
        } else if rim_test && let Some(k) = units(&spans, rendered, bins, noise) {
            let rim_spans = share(renderer, brdf, &rim(&region, triangles, &keep, &vertex_faces))?;
            k * rim_refit(&spans, &rim_spans, rendered, bins, row_loss)? < 0.0
        } else {
            false
        };
        if !hole {
            continue;
        }
        // The whole region at once; a vertex it leaves pinched between two fans keeps its largest fan and
        // loses the others (a few faces on the new hole's rim), until no vertex is pinched.
        let mut gone = region.clone();
        gone.iter().for_each(|&f| keep[f] = false);
        let seeds = region.iter().flat_map(|&f| triangles[f]);
        gone.extend(crate::prune::unpinch(seeds, triangles, &vertex_faces, &mut keep));
        // Faces a pinch took with the region are rendered too: subtract the share of every deleted face.
        let spans = if gone.len() == region.len() { spans } else { share(renderer, brdf, &gone)? };
        let (_, change) = delta(&spans, rendered, bins, row_loss, 0.0, false)?;
        apply_spans(&spans, rendered, bins, false);
        row_loss.applied(&spans, false)?;
        deleted += 1;
        removed += gone.len();
        total += change;
    }
    Ok(Regions { keep, tested, deleted, removed, data_change: total })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// Two squares of two faces each, sharing only vertex 2: members join across edges, not vertices.
    #[test]
    fn components_join_faces_across_edges_only() {
        let t = [[0, 1, 2], [0, 2, 3], [2, 4, 5], [2, 5, 6]];
        assert_eq!(components(&t, &[true; 4]), vec![vec![0, 1], vec![2, 3]]);
        assert_eq!(components(&t, &[true, false, true, true]), vec![vec![0], vec![2, 3]]);
        assert!(components(&t, &[false; 4]).is_empty());
    }

    /// Shares of one measurement are summed over the union of their bins; other measurements stay apart.
    #[test]
    fn merged_shares_sum_bin_by_bin() {
        let a = RowSpan { measurement: 3, first_bin: 2, values: vec![1.0, 2.0] };
        let b = RowSpan { measurement: 3, first_bin: 3, values: vec![0.5, 0.5, 0.5] };
        let c = RowSpan { measurement: 1, first_bin: 0, values: vec![4.0] };
        let m = merge([a, b, c.clone()]);
        assert_eq!(m, vec![c, RowSpan { measurement: 3, first_bin: 2, values: vec![1.0, 2.5, 0.5, 0.5] }]);
    }

    /// A plate 16 cm square at 0.4 m of 24 × 24 quads (6.7 mm), a strip |x| < 12 mm of it four quads wide, and
    /// its rim (the two columns of quads beside it).
    fn strip_plate() -> (Vec<glam::Vec3>, Vec<[u32; 3]>, Vec<bool>, Vec<bool>) {
        let (n, half, z) = (24u32, 0.08f32, 0.4f32);
        let at = |i: u32, j: u32| i * (n + 1) + j;
        let mut p = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let step = 2.0 * half / n as f32;
                p.push(glam::Vec3::new(-half + j as f32 * step, -half + i as f32 * step, z));
            }
        }
        let (mut t, mut strip, mut rim) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..n {
            for j in 0..n {
                // Normals toward the wall (−z).
                t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                let column = j as i32 - n as i32 / 2;
                for _ in 0..2 {
                    strip.push((-2..2).contains(&column));
                    rim.push(column == -3 || column == 2);
                }
            }
        }
        (p, t, strip, rim)
    }

    /// The light of the plate at per-face weights `w` (faces of weight 0 left out), photons per unit.
    fn plate_light(p: &[glam::Vec3], t: &[[u32; 3]], w: &[f32]) -> (Renderer, Vec<f32>) {
        let scan = nlos_transient::Scan::confocal(nlos_transient::PointSet::wall_grid(12, 12, 0.08, 0.08).unwrap());
        let time = nlos_transient::TimeAxis::new(0.78, 0.0024, 50).unwrap();
        let params = nlos_render::RenderParams { visibility: nlos_render::Visibility::Off, ..Default::default() };
        let mut r = Renderer::new(p, t, &scan, &time, params).unwrap();
        r.set_face_weights(Some(w)).unwrap();
        let brdf = AnyBrdf::Lambertian(nlos_brdf::Lambertian::new(1.0).unwrap());
        let light = r.forward_any(&brdf);
        (r, light)
    }

    /// Deletes the strip or keeps it, for a capture of `truth` (per-face weights) fitted as a plate whose
    /// strip has weight `w_strip`: the number of regions deleted.
    fn strip_test(truth: &[f32], w_strip: f32, rim_test: bool) -> usize {
        let (p, t, strip, _) = strip_plate();
        let brdf = AnyBrdf::Lambertian(nlos_brdf::Lambertian::new(1.0).unwrap());
        let (_, measured) = plate_light(&p, &t, truth);
        let weights: Vec<f32> = strip.iter().map(|&s| if s { w_strip } else { 1.0 }).collect();
        let (renderer, mut rendered) = plate_light(&p, &t, &weights);
        // Photon counts: the brightest bin of the capture holds 10⁴.
        let scale = 1e4 / f64::from(measured.iter().copied().fold(0.0, f32::max));
        let bins = 50;
        let loss = |m: usize, row: &[f32], window: std::ops::Range<usize>| -> Result<f64> {
            let data = &measured[m * bins..(m + 1) * bins];
            Ok(window.map(|k| 0.5 * (scale * f64::from(row[k]) - scale * f64::from(data[k])).powi(2)).sum())
        };
        let row_loss: &RowLoss<'_> = &loss;
        let keep = vec![true; t.len()];
        let fit = RegionFit { renderer: &renderer, brdf: &brdf, rendered: &mut rendered, bins, row_loss };
        let r =
            dark_regions(&t, &weights, &keep, fit, RegionNoise::Counts { scale }, &RegionParams::default(), rim_test);
        r.unwrap().deleted
    }

    /// A slot whose edge light the fit put on the dark strip (the truth: the strip cut away, its rim 15 %
    /// brighter; the fit: the strip at 4 % of the plate): the plain test detects the strip's light and keeps
    /// it; with its rim free to brighten, the strip goes. Printed (the truth: the strip at 10 %, fitted
    /// exactly), the strip stays under both tests.
    #[test]
    fn a_detected_strip_that_a_brighter_rim_explains_is_a_hole() {
        let (_, t, strip, rim) = strip_plate();
        let slot: Vec<f32> = (0..t.len())
            .map(|f| {
                if strip[f] {
                    0.0
                } else if rim[f] {
                    1.15
                } else {
                    1.0
                }
            })
            .collect();
        assert_eq!(strip_test(&slot, 0.04, false), 0, "the plain test detects the strip's light");
        assert_eq!(strip_test(&slot, 0.04, true), 1, "the rim explains the strip's light: a hole");
        let print: Vec<f32> = strip.iter().map(|&s| if s { 0.1 } else { 1.0 }).collect();
        assert_eq!(strip_test(&print, 0.1, false), 0);
        assert_eq!(strip_test(&print, 0.1, true), 0, "print is not a hole");
    }

    #[test]
    fn parameters_are_validated() {
        assert!(RegionParams::default().validate().is_ok());
        for bad in [
            RegionParams { dark: 0.5, ..RegionParams::default() },
            RegionParams { detection: -1.0, ..RegionParams::default() },
            RegionParams { max_fraction: 0.0, ..RegionParams::default() },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
