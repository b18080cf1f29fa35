//! Residual back-projection: new surface where the measurement holds light the rendering lacks.
//!
//! Shape steps move vertices and [`crate::prune`] deletes boundary faces, but neither creates surface away
//! from the mesh. Parts of an object that the initial volume left out (a rabbit's ears: 5–10 % of the
//! LCT's peak, under the albedo halo that a threshold must exclude) are therefore never reconstructed,
//! however long the optimiser runs. Their light is still in the measurement, and once the rest of the
//! object is fitted it is most of what the residual holds.
//!
//! At the end of a stage the residual `Ĩ − Î` (`Î` the model of the data term: `s·I`, or `s·J I + b`
//! for the sensor fit) is reconstructed with the LCT (`nlos_init::lct`, Wiener filter, no gate; on a scan
//! that is not a confocal grid, the phasor field, `nlos_init::pf`) and a
//! surface is extracted from it as from a measurement ([`nlos_init::volume_to_surface_where`], Otsu's
//! threshold, sub-voxel peaks, every region), keeping only the columns whose point lies more than
//! [`ResidualParams::separation`] from the current mesh (near the mesh the residual is the fit's own
//! error, which the shape steps handle). Each connected region of that surface is a candidate.
//!
//! The LCT says where a missing part is, not which way it faces, and that matters: the bunny's ears face
//! up (normal ≈ (0, 0.7, −0.6)), so they light the spots above them and hardly those below, and the
//! untilted wall-facing patch at their place rendered ten times the light the residual holds there
//! (its optimal amplitude was 0.1). Each region is therefore tried untilted and turned about its centroid
//! so that its normal tilts by each of [`ResidualParams::tilts`] toward the four azimuths. Per orientation,
//! faces join by the test of [`crate::prune`] with the sign reversed (`I_f` a face's rendered share, alone:
//! the mesh's shadow is not in it; rendering it in that shadow let a patch of noise join, docs/accuracy.md)
//! ```text
//! ΔE_f = E(I + I_f) − E(I),   joins when ΔE_f + κ · ½ c_f < 0
//! ```
//! greedily: first the face that passes by the most, then the best of the faces sharing an edge with those
//! chosen, each against the rendering the choices before it have left, until none passes (a whole region
//! at once overshoots: its faces' shares overlap in time). The orientation whose choice lowers the data
//! term most wins, when it has at least [`ResidualParams::min_faces`] faces. An accepted patch is a new
//! component of the mesh: the next stage remeshes it, the shape steps fit it, and pruning deletes what of
//! it the data stop supporting.
//!
//! Proposals come in rounds ([`residual_rounds`], [`ResidualParams::rounds`]): the residual is taken again
//! with the accepted patches' light in the model, and the next round proposes what remains. In one volume
//! the brightest missing parts outshine the rest (the phasor field's side lobes around a figure's upper legs
//! are as bright as its feet), as in Högbom's CLEAN (1974), which subtracts the brightest source and looks
//! again.
//!
//! A patch must also explain a *localised* return ([`localisation`]): its light must match the residual at its
//! own place at least [`LOCALISED_CONTRAST`] times better than shifted just before or after it. The data
//! test alone takes any light the model lacks: on Tsai et al.'s preprocessed S and U (gated, fitted without
//! a background), patches 1.0–1.2 m from the wall, half a metre behind the letters, explained the sensor's
//! diffusion tail and the late background, which are flat or falling in time where a surface's return is a
//! peak. Each candidate's depth, contrast and whether it was kept go to the run log
//! ([`ResidualRecord::patches`]).
//!
//! Why after the first stage only: on the shared bunnies it adds the ears' tips and the body's underside
//! (Chamfer distance down 3 mm, coverage up to 2 points), while proposing after later stages as well
//! added patches worth only noise in the data term and raised the normal error (docs/accuracy.md).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use glam::Vec3;
use nlos_init::{Gate, InitError, LctParams, PfParams, SurfaceParams, Threshold, lct, pf, volume_to_surface_where};
use nlos_mesh::bvh::TriangleBvh;
use nlos_mesh::{BuildOptions, FaceId, SurfaceMesh};
use nlos_render::{RenderParams, Renderer, RowSpan};
use nlos_transient::Transient;

use crate::data_term::RowLoss;
use crate::error::{OptimError, Result};
use crate::prune::{apply_spans, delta};
use nlos_render::AnyBrdf;

mod localisation;
mod rounds;
pub use localisation::{LOCALISATION_SHIFT, LOCALISED_CONTRAST, localisation};
pub use rounds::residual_rounds;

/// Settings of residual back-projection ([`crate::ReconstructParams::residual`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResidualParams {
    /// Propose patches at the end of the stages before this one (default `Some(1)`: after stage 0 only);
    /// `None`: after every stage but the last (which would leave a patch no step refines). On the
    /// independent renderer's bunny the stage-1 residual is at the noise level: 44 faces in 6 patches
    /// explained 3.5·10⁻⁵ of the normalised data term (stage 0: 12 faces, 1.9·10⁻³) and took the normal
    /// error from 17.2 to 26.7° and the Chamfer distance from 34.1 to 32.8 mm.
    pub stages: Option<u32>,
    /// Wiener signal-to-noise ratio of the residual's LCT (> 0; default 0.1, as `nlos init`).
    pub snr: f64,
    /// A residual column becomes surface only when its point lies more than this far from the mesh
    /// (metres, > 0; default 0.005: several LCT depth voxels and bins of Tsai et al. 2019's setup, so that the fit's
    /// own error around the mesh is not taken for a missing part). Larger values cut parts that lie close
    /// to the mesh: at 0.02 the bunny's ears, whose lower halves lie within 2 cm of the head, were cut to
    /// their tips.
    pub separation: f64,
    /// Margin κ ≥ 0 of the acceptance test (module docs; default 0.5, as pruning).
    pub margin: f64,
    /// Fewest faces an accepted patch has (≥ 1; default 3). The residual volume resolves parts a few of its
    /// columns wide; one face alone can explain an outlier of the L2 term (a hot pixel's spike, tilted to
    /// light mostly that measurement), which is not a surface.
    pub min_faces: usize,
    /// Tilts θ (degrees) of a candidate patch's normal away from the wall normal, each tried at four
    /// azimuths besides the untilted patch (default [40, 70]).
    pub tilts: Vec<f64>,
    /// Rounds of proposals at a stage's end, at most (≥ 1; default 3): after a round whose patches lowered
    /// the data term by at least [`Self::round_gain`] of it, the residual is taken again with the patches'
    /// light in the model, so parts whose return the brighter missing parts outshone in the first round's
    /// volume come next (Högbom's CLEAN: take the brightest, subtract it, look again).
    pub rounds: usize,
    /// The least share (0–1) of the data term a round's patches must explain for another round to follow
    /// (default 0.02). On a figure with 2.4 cm limbs seen by one laser at (−0.1, 0.15) m (the
    /// `nonconfocal` scenario) the first round explained 5.9 % of the data term with the legs' upper halves,
    /// and a second (1.3 %) 73 faces along the legs and arms: coverage within 5 mm 71.3 → 73.8 %, depth
    /// error inside 0.80 → 0.71 mm (a third round, 0.1 %: 74.7 %, 0.68 mm). Where the first round explained little (the same figure with the laser
    /// at the wall's centre, 1.1 %; the confocal bunny, 1.2 %), the later rounds' patches explained 0.1–0.2 %
    /// and moved the results by −2.1 and +0.1 points of coverage within 5 mm.
    pub round_gain: f64,
}

impl Default for ResidualParams {
    fn default() -> Self {
        Self {
            stages: Some(1),
            snr: 0.1,
            separation: 0.005,
            margin: 0.5,
            min_faces: 3,
            tilts: vec![40.0, 70.0],
            rounds: 3,
            round_gain: 0.02,
        }
    }
}

impl ResidualParams {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a non-positive or non-finite `snr` or `separation`, a
    /// negative or non-finite `margin`, no `rounds`, a `round_gain` outside [0, 1].
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value, reason| Err(OptimError::InvalidParameter { name, value, reason });
        if !(self.snr.is_finite() && self.snr > 0.0) {
            return bad("residual.snr", self.snr, "the Wiener signal-to-noise ratio is finite and > 0");
        }
        if !(self.separation.is_finite() && self.separation > 0.0) {
            return bad("residual.separation", self.separation, "a distance in metres, finite and > 0");
        }
        if self.min_faces == 0 {
            return bad("residual.min_faces", 0.0, "an accepted patch has at least one face");
        }
        if self.rounds == 0 {
            return bad("residual.rounds", 0.0, "at least one round (switch the patches off with stages instead)");
        }
        if !(0.0..=1.0).contains(&self.round_gain) {
            return bad("residual.round_gain", self.round_gain, "a share of the data term, in [0, 1]");
        }
        if let Some(&t) = self.tilts.iter().find(|t| !(t.is_finite() && (0.0..90.0).contains(*t))) {
            return bad("residual.tilts", t, "tilts are angles in degrees in [0, 90) (the azimuths give the sides)");
        }
        if !(self.margin.is_finite() && self.margin >= 0.0) {
            return bad("residual.margin", self.margin, "the margin κ is finite and ≥ 0 (0: the plain sign test)");
        }
        Ok(())
    }
}

/// One candidate patch of [`residual_patches`]: where it was, what it explained, and whether and why it
/// was kept (the run log's account of each patch).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PatchNote {
    /// Faces chosen.
    pub faces: usize,
    /// Mean depth of the chosen faces' vertices, metres.
    pub depth: f64,
    /// `Σ ΔE` of the chosen faces (unnormalised data term; in the run log, normalised as the stage's).
    pub data_change: f64,
    /// The residual's contrast at the patch's place ([`localisation`]; `None` when the shifted matches are
    /// ≤ 0 while the patch's own is positive: no comparable light beside it, a localised return).
    pub contrast: Option<f64>,
    /// Whether it was added to the mesh.
    pub kept: bool,
    /// Faces of its region (in the chosen orientation) left out because they would cross the surface.
    #[serde(default)]
    pub crossing: usize,
}

/// What one call of [`residual_patches`] did (one per stage in the run's checkpoint).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResidualRecord {
    /// The stage that had just ended.
    pub stage: u32,
    /// The round of proposals at that stage's end (0 first; [`ResidualParams::rounds`]).
    #[serde(default)]
    pub round: usize,
    /// Residual columns kept away from the mesh.
    pub columns: usize,
    /// Candidate patches (connected regions) tested.
    pub regions: usize,
    /// Patches accepted.
    pub accepted: usize,
    /// Faces added.
    pub faces: usize,
    /// Change of the normalised data term from the accepted patches (≤ 0).
    pub data_change: f64,
    /// Every candidate that passed the data test, kept or refused as not a localised return.
    #[serde(default)]
    pub patches: Vec<PatchNote>,
}

/// The result of [`residual_patches`]: the accepted patches' vertices (numbered from the mesh's vertex
/// count on) and faces.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Patches {
    /// New vertex positions.
    pub positions: Vec<Vec3>,
    /// New faces, indexing the old vertices followed by [`Self::positions`].
    pub triangles: Vec<[u32; 3]>,
    /// Residual columns kept away from the mesh.
    pub columns: usize,
    /// Candidate patches tested.
    pub regions: usize,
    /// Patches accepted.
    pub accepted: usize,
    /// `Σ ΔE_p` of the accepted patches (unnormalised data term).
    pub data_change: f64,
    /// Why nothing was tried, when the measurement does not allow it (device legs in the times, wall points
    /// that span no area).
    pub skipped: Option<String>,
    /// Every candidate that passed the data test, kept or refused ([`localisation`]).
    pub notes: Vec<PatchNote>,
}

/// The fit a patch is tested against ([`residual_patches`]): the renderer's settings and the BRDF that render
/// a patch's share, the mesh's forward pass `rendered` (updated in place with the accepted patches' shares),
/// and `row_loss`, the data term of histogram `m` ([`RowLoss`]) at the block's scale; a term that keeps
/// something of the rendering ([`crate::RowTerm::applied`]) must hold `rendered`'s, and is told of every share
/// tried and taken back.
pub struct PatchFit<'a> {
    /// The renderer's settings for the patches' shares.
    pub render: RenderParams,
    /// The reflectance of the patches.
    pub brdf: &'a AnyBrdf,
    /// The mesh's forward pass, one value per measurement and bin.
    pub rendered: &'a mut [f32],
    /// The data term, one histogram at a time.
    pub row_loss: &'a RowLoss<'a>,
}

impl std::fmt::Debug for PatchFit<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PatchFit")
            .field("render", &self.render)
            .field("brdf", self.brdf)
            .field("rendered", &self.rendered.len())
            .finish_non_exhaustive()
    }
}

/// Proposes new surface from the residual of the fit (module docs).
///
/// `positions`/`triangles` are the current mesh, `measured` the measurement (for its scan and time axis),
/// `residual` the measurement minus the data term's model (one value per measurement and bin), and `fit` what
/// a patch is tested against ([`PatchFit`]).
///
/// # Errors
/// Invalid parameters, a residual of the wrong length, and renderer or volume failures other than an
/// unsupported scan (one the volume cannot take returns empty [`Patches`] with [`Patches::skipped`] set).
pub fn residual_patches(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    measured: &Transient,
    residual: Vec<f32>,
    fit: PatchFit<'_>,
    params: &ResidualParams,
) -> Result<Patches> {
    let PatchFit { render, brdf, rendered, row_loss } = fit;
    params.validate()?;
    let bins = measured.bins();
    let n = measured.data().len();
    if residual.len() != n {
        return Err(OptimError::LengthMismatch { what: "residual", expected: n, got: residual.len() });
    }
    if rendered.len() != n {
        return Err(OptimError::LengthMismatch { what: "rendered", expected: n, got: rendered.len() });
    }
    let t = Transient::new(measured.scan().clone(), *measured.time(), residual)
        .map_err(|source| OptimError::Transient { context: "the residual's histograms", source })?;
    // The start's method for this scan (`nlos_init::Method::for_scan`): the LCT on a confocal grid (its
    // Wiener filter sharpens), the phasor field on every other scan; ungated, unweighted.
    let volume = match nlos_init::Method::for_scan(t.scan()).0 {
        nlos_init::Method::Lct => lct(&t, &LctParams { snr: params.snr, gate: Gate::None, ..LctParams::default() }),
        _ => pf(&t, &PfParams { gate: Gate::None, depth_noise: nlos_init::DepthNoise::Off, ..PfParams::default() }),
    };
    let vol = match volume {
        Ok(v) => v,
        Err(
            e @ (InitError::NotConfocal { .. }
            | InitError::NotGrid { .. }
            | InitError::BadGrid { .. }
            | InitError::DeviceLegs
            | InitError::TimeOrigin { .. }),
        ) => return Ok(Patches { skipped: Some(e.to_string()), ..Patches::default() }),
        Err(e) => return Err(e.into()),
    };
    let bvh = TriangleBvh::from_triangles(positions, triangles)?;
    let sep = params.separation as f32;
    let surface_params = SurfaceParams {
        threshold: Threshold::Otsu,
        subvoxel: true,
        min_region_fraction: 0.0,
        ..SurfaceParams::default()
    };
    let surface = match volume_to_surface_where(&vol, &surface_params, &|p| !bvh.any_within(p, sep)) {
        Ok(s) => s,
        // Nothing away from the mesh: no proposal.
        Err(InitError::Empty { .. }) => return Ok(Patches::default()),
        Err(e) => return Err(e.into()),
    };
    let columns = surface.mask.iter().filter(|&&k| k).count();
    let (patch_pos, patch_tri) = surface.mesh.to_triangles();
    let (regions, neighbours) = regions_of(&surface.mesh);
    let mut out = Patches { columns, regions: regions.len(), ..Patches::default() };
    let n_old = positions.len() as u32;
    // The accepted patches' faces (a new patch may not cross them either).
    let mut out_faces: Vec<[Vec3; 3]> = Vec::new();
    for faces in &regions {
        // The region's own vertices and faces.
        let mut verts: Vec<u32> = faces.iter().flat_map(|&f| patch_tri[f]).collect();
        verts.sort_unstable();
        verts.dedup();
        let local = |v: u32| verts.binary_search(&v).map_or(u32::MAX, |i| i as u32);
        let tri: Vec<[u32; 3]> = faces.iter().map(|&f| patch_tri[f].map(local)).collect();
        let pos: Vec<Vec3> = verts.iter().map(|&v| patch_pos[v as usize]).collect();
        let centroid = pos.iter().copied().sum::<Vec3>() / pos.len() as f32;
        // Edge neighbours within the region, as indices into `faces` (sorted).
        let adjacency: Vec<Vec<usize>> =
            faces.iter().map(|&f| neighbours[f].iter().filter_map(|g| faces.binary_search(g).ok()).collect()).collect();
        // (Σ ΔE, turned positions, chosen faces, their shares) of the best orientation so far.
        let mut best: Option<Candidate> = None;
        for &(theta, phi) in &orientations(&params.tilts) {
            // Turn the region about its centroid so that its wall-facing normal (−z) tilts by θ toward the
            // azimuth φ (the LCT gives where a part is, not which way it faces; a part facing up lights only
            // the spots above it).
            let (st, ct) = (theta.to_radians().sin() as f32, theta.to_radians().cos() as f32);
            let (sp, cp) = (phi.to_radians().sin() as f32, phi.to_radians().cos() as f32);
            let q = glam::Quat::from_rotation_arc(Vec3::NEG_Z, Vec3::new(st * cp, st * sp, -ct));
            let turned: Vec<Vec3> = pos.iter().map(|&p| centroid + q * (p - centroid)).collect();
            let r = Renderer::new(&turned, &tri, measured.scan(), measured.time(), render)?;
            let shares: Vec<Vec<RowSpan>> = (0..tri.len())
                .into_par_iter()
                .map(|f| r.forward_triangle_any(brdf, f))
                .collect::<nlos_render::Result<_>>()?;
            // A face that would cross the surface (the mesh, or a patch accepted before) is no candidate: the
            // surface never intersects itself (El Topo's promise; crate::reconstruct's checks).
            let mut shares = shares;
            let mut crossing = 0;
            for (f, share) in shares.iter_mut().enumerate() {
                let face = tri[f].map(|v| turned[v as usize]);
                if crosses(face, &bvh, &out_faces) {
                    share.clear();
                    crossing += 1;
                }
            }
            let mut trial = rendered.to_vec();
            let (chosen, change) = grow_connected(&shares, &adjacency, &mut trial, bins, row_loss, params.margin)?;
            // Back to `rendered` for a term that keeps something of the rendering (RowTerm::applied).
            for &f in &chosen {
                row_loss.applied(&shares[f], false)?;
            }
            if chosen.len() >= params.min_faces && best.as_ref().is_none_or(|b| change < b.0) {
                best = Some((change, turned, chosen, shares, crossing));
            }
        }
        let Some((change, turned, chosen, shares, crossing)) = best else { continue };
        let contrast =
            localisation(chosen.iter().map(|&f| shares[f].as_slice()), t.data(), bins, measured.time().bin_width);
        let depth = f64::from(turned.iter().map(|p| p.z).sum::<f32>()) / turned.len() as f64;
        let kept = contrast >= LOCALISED_CONTRAST;
        let contrast = contrast.is_finite().then_some(contrast);
        out.notes.push(PatchNote { faces: chosen.len(), depth, data_change: change, contrast, kept, crossing });
        if !kept {
            continue;
        }
        for &f in &chosen {
            apply_spans(&shares[f], rendered, bins, true);
            row_loss.applied(&shares[f], true)?;
        }
        out.accepted += 1;
        out.data_change += change;
        let (p, t) = patch_mesh(&turned, &tri, &chosen)?;
        out_faces.extend(t.iter().map(|f| f.map(|v| p[v as usize])));
        let offset = n_old + out.positions.len() as u32;
        out.positions.extend(p);
        out.triangles.extend(t.into_iter().map(|t| t.map(|v| v + offset)));
    }
    Ok(out)
}

/// The chosen faces of a region as a mesh of their own: only the vertices they use, and a separate copy
/// of a vertex per fan where the choice touches itself at a vertex only (faces joined through an edge
/// chain around a vertex whose fan they do not fill). Such a pinched vertex is non-manifold, and the
/// run's next `SurfaceMesh` of the whole mesh would refuse it (it stopped `data_resolution_chart_40cm`
/// at the end of stage 0). The copies would still touch there, which is a self-intersection (two faces
/// meeting where they share no vertex): each copy is pulled into its own fan by [`PINCH_PULL`] of the way
/// to its neighbours' mean, so that the fans are apart.
fn patch_mesh(positions: &[Vec3], triangles: &[[u32; 3]], chosen: &[usize]) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let mut used: Vec<u32> = chosen.iter().flat_map(|&f| triangles[f]).collect();
    used.sort_unstable();
    used.dedup();
    let local = |v: u32| used.binary_search(&v).map_or(u32::MAX, |i| i as u32);
    let pos: Vec<Vec3> = used.iter().map(|&v| positions[v as usize]).collect();
    let tri: Vec<[u32; 3]> = chosen.iter().map(|&f| triangles[f].map(local)).collect();
    let mesh = SurfaceMesh::from_triangles_with(&pos, &tri, BuildOptions { split_non_manifold_vertices: true })?;
    let (mut p, t) = mesh.to_triangles();
    // Vertices sharing a position: the copies of a pinched vertex.
    let mut at: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    for q in &p {
        *at.entry(q.to_array().map(f32::to_bits)).or_default() += 1;
    }
    let pinched: Vec<bool> = p.iter().map(|q| at[&q.to_array().map(f32::to_bits)] > 1).collect();
    if pinched.contains(&true) {
        let mut sum = vec![(Vec3::ZERO, 0u32); p.len()];
        for f in &t {
            for k in 0..3 {
                let (v, a, b) = (f[k] as usize, f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
                if pinched[v] {
                    sum[v].0 += p[a] + p[b];
                    sum[v].1 += 2;
                }
            }
        }
        for (v, (s, n)) in sum.into_iter().enumerate() {
            if pinched[v] && n > 0 {
                let pull = PINCH_PULL * (s / n as f32 - p[v]);
                p[v] += pull;
            }
        }
    }
    Ok((p, t))
}

/// How far a copy of a pinched vertex moves into its own fan ([`patch_mesh`]): this share of the way to the
/// mean of its neighbours (a hundredth of an edge or so, far below the data's resolution).
const PINCH_PULL: f32 = 0.01;

/// Stale tests of [`grow_connected`]'s queue repeated together (in parallel).
const RETEST_BATCH: usize = 8;

/// One orientation's choice: `Σ ΔE`, the turned region's positions, the chosen faces, every face's share
/// (empty for the faces that would cross the surface), and how many faces would.
type Candidate = (f64, Vec<Vec3>, Vec<usize>, Vec<Vec<RowSpan>>, usize);

/// Whether the triangle `face` meets a face of the mesh in `bvh` or one of `others` (closed triangles, exact:
/// [`nlos_mesh::intersect::triangles_intersect`]; touching counts). Degenerate triangles never cross.
fn crosses(face: [Vec3; 3], bvh: &TriangleBvh, others: &[[Vec3; 3]]) -> bool {
    use nlos_mesh::intersect::{is_degenerate_triangle, triangles_intersect};
    let [a, b, c] = face;
    if is_degenerate_triangle(a, b, c) {
        return false;
    }
    let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
    let overlaps = |u: &[Vec3; 3]| {
        let (ulo, uhi) = (u[0].min(u[1]).min(u[2]), u[0].max(u[1]).max(u[2]));
        ulo.cmple(hi).all() && uhi.cmpge(lo).all()
    };
    let meets = |u: [Vec3; 3]| !is_degenerate_triangle(u[0], u[1], u[2]) && triangles_intersect(face, u);
    if others.iter().any(|u| overlaps(u) && meets(*u)) {
        return true;
    }
    let mut hit = false;
    bvh.for_each_overlapping(lo, hi, |t| hit = hit || meets(bvh.triangle(t)));
    hit
}

/// The (θ, φ) pairs tried per region: θ = 0 once, every other tilt at the four azimuths 0°, 90°, 180°, 270°.
fn orientations(tilts: &[f64]) -> Vec<(f64, f64)> {
    let mut out = vec![(0.0, 0.0)];
    for &t in tilts.iter().filter(|&&t| t != 0.0) {
        out.extend([0.0, 90.0, 180.0, 270.0].map(|phi| (t, phi)));
    }
    out
}

/// Greedy connected selection: the face whose addition passes the test by the most, then, repeatedly, the
/// best of the faces sharing an edge with those chosen, each tested against the rendering the choices so
/// far have left, until none passes. Returns the chosen faces and `Σ ΔE`; `rendered` is updated.
///
/// Lazily (Minoux's accelerated greedy): every face is tested once against the starting rendering, and a
/// test is repeated only when its face comes first in the queue with a value from an older rendering.
/// Additions only raise the rendering, and for a data term that is a sum over bins of convex functions of a
/// non-negative linear map of it (L2, the Poisson deviance through the timing response) both forward
/// differences `E(I + I_f) − E(I)` and `E(I + 2I_f) − E(I + I_f)` rise with it; the test value is
/// `(1 − κ/2)` times the first plus `κ/2` times the second, so for `0 ≤ κ ≤ 2` an old value is a lower
/// bound of the current one, and a face that comes first with a current value is the face the full scan of
/// the frontier would choose (ties by the lower face index, as the scan). The full scan re-tested the whole
/// frontier after every addition: quadratic in a patch's faces (650 s of the 40 cm chart's run).
fn grow_connected(
    shares: &[Vec<RowSpan>],
    adjacency: &[Vec<usize>],
    rendered: &mut [f32],
    bins: usize,
    row_loss: &RowLoss<'_>,
    margin: f64,
) -> Result<(Vec<usize>, f64)> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    /// A queue entry: the test value, the face, the rendering's version it was taken at.
    #[derive(PartialEq)]
    struct Entry(f64, usize, u64);
    impl Eq for Entry {}
    impl PartialOrd for Entry {
        fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
            Some(self.cmp(other))
        }
    }
    impl Ord for Entry {
        fn cmp(&self, other: &Self) -> std::cmp::Ordering {
            self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
        }
    }
    let snapshot: &[f32] = rendered;
    // Every face against the starting rendering (in parallel): the first choice, and lower bounds after it.
    let mut last: Vec<Option<(f64, f64, u64)>> = (0..shares.len())
        .into_par_iter()
        .map(|f| {
            if shares[f].is_empty() {
                return Ok(None);
            }
            delta(&shares[f], snapshot, bins, row_loss, margin, true).map(|(t, d)| Some((t, d, 0)))
        })
        .collect::<Result<_>>()?;
    let mut queue: BinaryHeap<Reverse<Entry>> =
        last.iter().enumerate().filter_map(|(f, l)| l.map(|(t, _, v)| Reverse(Entry(t, f, v)))).collect();
    let mut chosen: Vec<usize> = Vec::new();
    let mut in_frontier = vec![true; shares.len()];
    let mut taken = vec![false; shares.len()];
    let (mut change, mut version) = (0.0, 0u64);
    while let Some(Reverse(Entry(test, f, v))) = queue.pop() {
        // Taken, not (yet) a candidate, or superseded by a later test of the same face still queued.
        if taken[f] || !in_frontier[f] || last[f].is_some_and(|l| l.2 != v) {
            continue;
        }
        if v != version {
            // Re-test this face and the next few stale ones together (in parallel, against the same
            // rendering): testing more faces than needed changes no choice, only what is known.
            let mut batch = vec![f];
            while batch.len() < RETEST_BATCH {
                let Some(Reverse(Entry(_, g, w))) = queue.pop() else { break };
                if taken[g] || !in_frontier[g] || last[g].is_some_and(|l| l.2 != w) {
                    continue;
                }
                if w == version {
                    queue.push(Reverse(Entry(last[g].map_or(f64::INFINITY, |l| l.0), g, w)));
                    break;
                }
                batch.push(g);
            }
            let snapshot: &[f32] = rendered;
            let tests: Vec<(f64, f64)> = batch
                .par_iter()
                .map(|&g| delta(&shares[g], snapshot, bins, row_loss, margin, true))
                .collect::<Result<_>>()?;
            for (&g, (t, d)) in batch.iter().zip(tests) {
                last[g] = Some((t, d, version));
                queue.push(Reverse(Entry(t, g, version)));
            }
            continue;
        }
        if !(test < 0.0) {
            break;
        }
        let d = last[f].map_or(0.0, |l| l.1);
        apply_spans(&shares[f], rendered, bins, true);
        row_loss.applied(&shares[f], true)?;
        version += 1;
        if chosen.is_empty() {
            // From now on only faces sharing an edge with the choice are candidates.
            in_frontier.fill(false);
            queue.clear();
        }
        taken[f] = true;
        chosen.push(f);
        change += d;
        for &g in &adjacency[f] {
            if !taken[g] && !in_frontier[g] {
                in_frontier[g] = true;
                if let Some((t, _, v)) = last[g] {
                    queue.push(Reverse(Entry(t, g, v)));
                }
            }
        }
    }
    chosen.sort_unstable();
    Ok((chosen, change))
}

/// The faces of `mesh` (numbered in `mesh.faces()` order, as `to_triangles`) grouped by connected
/// component, largest first (ties by the smallest face), each in increasing order; and per face the faces
/// across its interior edges.
fn regions_of(mesh: &SurfaceMesh) -> (Vec<Vec<usize>>, Vec<Vec<usize>>) {
    let faces: Vec<FaceId> = mesh.faces().collect();
    let mut number = vec![usize::MAX; faces.iter().map(|f| f.idx() + 1).max().unwrap_or(0)];
    for (i, f) in faces.iter().enumerate() {
        number[f.idx()] = i;
    }
    let (component, n) = mesh.connected_components();
    let mut regions = vec![Vec::new(); n];
    for (i, &f) in faces.iter().enumerate() {
        regions[component[mesh.face_vertices(f)[0].idx()] as usize].push(i);
    }
    regions.retain(|r| !r.is_empty());
    regions.sort_by(|a, b| b.len().cmp(&a.len()).then(a[0].cmp(&b[0])));
    let neighbours = faces
        .iter()
        .map(|&f| {
            mesh.face_halfedges(f)
                .into_iter()
                .map(|h| h.opposite())
                .filter(|&o| !mesh.is_boundary_halfedge(o))
                .map(|o| number[mesh.face(o).idx()])
                .collect()
        })
        .collect();
    (regions, neighbours)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn residual_patch_pinched_at_a_vertex_is_split_there() {
        // Faces 0 and 2 of a fan around vertex 0 (face 1 between them not chosen) touch at vertex 0 only.
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, -Vec3::X, -Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        let triangles = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [1, 5, 2]];
        let (p, t) = patch_mesh(&positions, &triangles, &[0, 2, 3]).expect("patch");
        assert_eq!(t.len(), 3);
        assert_eq!(p.len(), 7, "vertex 0 copied once, vertex 5 kept, nothing unused: {p:?}");
        assert!(SurfaceMesh::from_triangles(&p, &t).is_ok());
        // The two copies of vertex 0 are pulled apart into their fans (touching there would be a
        // self-intersection); the other corners stay.
        let pairs = nlos_mesh::intersect::triangle_self_intersections(&p, &t).expect("checked");
        assert!(pairs.is_empty(), "{pairs:?}");
        let near_origin: Vec<&Vec3> = p.iter().filter(|q| q.length() < 0.02).collect();
        assert_eq!(near_origin.len(), 2, "{p:?}");
        assert!(near_origin.iter().all(|q| q.length() > 0.001), "{p:?}");
        let corners: Vec<[Vec3; 3]> = t.iter().map(|t| t.map(|v| p[v as usize])).collect();
        assert!(corners.contains(&[Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]));
    }

    /// The full scan the lazy greedy replaces: every frontier face re-tested after every addition.
    fn grow_by_full_scan(
        shares: &[Vec<RowSpan>],
        adjacency: &[Vec<usize>],
        rendered: &mut [f32],
        bins: usize,
        row_loss: &RowLoss<'_>,
        margin: f64,
    ) -> (Vec<usize>, f64) {
        let (mut chosen, mut taken, mut change) = (Vec::new(), vec![false; shares.len()], 0.0);
        loop {
            let frontier: Vec<usize> = if chosen.is_empty() {
                (0..shares.len()).collect()
            } else {
                let mut f: Vec<usize> =
                    chosen.iter().flat_map(|&c: &usize| adjacency[c].clone()).filter(|&g| !taken[g]).collect();
                f.sort_unstable();
                f.dedup();
                f
            };
            let best = frontier
                .iter()
                .filter(|&&f| !shares[f].is_empty())
                .map(|&f| {
                    let (t, d) = delta(&shares[f], rendered, bins, row_loss, margin, true).unwrap();
                    (t, d, f)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
            let Some((t, d, f)) = best else { break };
            if !(t < 0.0) {
                break;
            }
            apply_spans(&shares[f], rendered, bins, true);
            taken[f] = true;
            chosen.push(f);
            change += d;
        }
        chosen.sort_unstable();
        (chosen, change)
    }

    /// The lazy greedy chooses what the full scan chooses, for the L2 term and for the Poisson term through a
    /// long timing response, with and without a margin: a strip of faces whose shares overlap in time, over
    /// measurements whose residual supports some of them and not others.
    #[test]
    fn lazy_growth_chooses_what_the_full_scan_chooses() {
        let (m, bins, nf) = (6usize, 40usize, 24usize);
        // Face f lights measurement j at bins around 8 + (f + 2j) % 20, with values that vary by face.
        let shares: Vec<Vec<RowSpan>> = (0..nf)
            .map(|f| {
                (0..m)
                    .map(|j| RowSpan {
                        measurement: j,
                        first_bin: 8 + (f + 2 * j) % 20,
                        values: vec![0.2 + 0.05 * (f % 3) as f32, 0.5, 0.3 + 0.02 * (j % 4) as f32],
                    })
                    .collect()
            })
            .collect();
        // A strip: f touches f − 1 and f + 1.
        let adjacency: Vec<Vec<usize>> =
            (0..nf).map(|f| [f.wrapping_sub(1), f + 1].into_iter().filter(|&g| g < nf).collect()).collect();
        let base: Vec<f32> = (0..m * bins).map(|i| 0.1 * ((i * 7 % 5) as f32)).collect();
        // Measured: the base plus faces 3..9 and 15..18 of the strip (and rounding-size noise).
        let mut truth = base.clone();
        for f in (3..9).chain(15..18) {
            apply_spans(&shares[f], &mut truth, bins, true);
        }
        let counts: Vec<f32> = truth.iter().enumerate().map(|(i, &v)| (3.0 * v + (i % 3) as f32).round()).collect();
        let l2 = |mm: usize, row: &[f32], w: std::ops::Range<usize>| -> Result<f64> {
            Ok(row[w.clone()]
                .iter()
                .zip(&truth[mm * bins..][w])
                .map(|(&r, &t)| 0.5 * (f64::from(r) - f64::from(t)).powi(2))
                .sum())
        };
        let fit = crate::SensorFit {
            kernel: nlos_transient::sensor::BinKernel::new(-1, (0..30).map(|i| 1.0 / (1.0 + i as f64)).collect())
                .unwrap(),
            background: crate::SensorBackground::Fixed(0.4),
        };
        let poisson =
            crate::SensorRows { fit: &fit, counts: &counts, bins, background: 0.4, scale: 3.0, response: None };
        let terms: [&RowLoss<'_>; 2] = [&l2, &poisson];
        for (which, term) in terms.into_iter().enumerate() {
            for margin in [0.0, 0.5, 1.0] {
                let (mut a, mut b) = (base.clone(), base.clone());
                let lazy = grow_connected(&shares, &adjacency, &mut a, bins, term, margin).unwrap();
                let full = grow_by_full_scan(&shares, &adjacency, &mut b, bins, term, margin);
                assert!(margin >= 1.0 || !full.0.is_empty(), "term {which} margin {margin}: the scan chose nothing");
                assert_eq!(lazy.0, full.0, "term {which} margin {margin}");
                assert!((lazy.1 - full.1).abs() <= 1e-9 * full.1.abs(), "term {which} margin {margin}");
                assert_eq!(a, b);
            }
        }
    }

    #[test]
    fn bad_parameters_are_errors() {
        for p in [
            ResidualParams { snr: 0.0, ..ResidualParams::default() },
            ResidualParams { separation: f64::NAN, ..ResidualParams::default() },
            ResidualParams { margin: -1.0, ..ResidualParams::default() },
            ResidualParams { tilts: vec![40.0, -30.0], ..ResidualParams::default() },
            ResidualParams { tilts: vec![90.0], ..ResidualParams::default() },
            ResidualParams { min_faces: 0, ..ResidualParams::default() },
        ] {
            assert!(matches!(p.validate(), Err(OptimError::InvalidParameter { .. })));
        }
        ResidualParams::default().validate().unwrap();
    }
}
