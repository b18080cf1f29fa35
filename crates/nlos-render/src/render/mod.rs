//! The renderer: geometry in structure-of-arrays form, the forward pass (eq. 1–5 of Tsai et al. 2019) and
//! the adjoint pass (Proposition 1, with the normal and area terms). See the crate docs for the derivation.

use glam::{DVec3, Vec3};
use nlos_transient::{Scan, TimeAxis, Transient};
use rayon::prelude::*;

use crate::brdf::RenderBrdf;
use crate::error::{RenderError, Result};
use crate::kernel::{Kernel, KernelEval};
use crate::loss::Loss;
use crate::rng::SplitMix64;
use crate::soa::{self, Acc, BLOCK, Block, Frame, Isa, Packed, Scratch, Soa, SpotBox, TentAxis};
use crate::splat::{self, Knots};
use crate::visibility::Bvh;

mod lobe;
mod params;

use lobe::Lobe;
pub use params::*;

/// Measurements per task of the forward pass (their histograms stay in L1/L2 while each block of triangles
/// is swept over them).
const M_CHUNK: usize = 8;
/// Measurements between flushes of the adjoint's f32 per-triangle accumulators into f64, which bounds the
/// length of every f32 sum.
const FLUSH: usize = 16;

/// Per-measurement wall geometry, structure of arrays.
#[derive(Debug, Clone)]
struct Wall {
    l: Vec<Vec3>,
    n_l: Vec<Vec3>,
    s: Vec<Vec3>,
    n_s: Vec<Vec3>,
    confocal: bool,
}

/// Triangles as structure of arrays.
#[derive(Debug, Clone, Default)]
struct Tris {
    v0: Vec<Vec3>,
    e1: Vec<Vec3>,
    e2: Vec<Vec3>,
    /// Unnormalised geometric normal `e1 × e2` (|N| = 2 × area).
    n: Vec<Vec3>,
    /// Longest edge.
    e_max: Vec<f32>,
    valid: Vec<bool>,
    /// The same geometry, one array per coordinate, for the block kernels.
    soa: Soa,
}

/// A transient renderer for one mesh topology, scan and time axis.
///
/// Build once per topology ([`Renderer::new`]), move vertices with [`Renderer::set_positions`], render with
/// [`Renderer::forward`], differentiate with [`Renderer::adjoint`] or [`Renderer::loss_and_gradient`].
#[derive(Debug)]
pub struct Renderer {
    triangles: Vec<[u32; 3]>,
    n_vertices: usize,
    tris: Tris,
    total_area: f32,
    wall: Wall,
    scan: Scan,
    time: TimeAxis,
    params: RenderParams,
    kernel: KernelEval,
    bvh: Option<Bvh>,
    /// Visible fraction × 255 per (measurement, triangle), measurement-major, triangles in the block order
    /// (`tris.soa.order`, kept by `set_positions` while the cache exists).
    cache: Option<Vec<u8>>,
    /// Instruction set of the block kernels (runtime-detected).
    isa: Isa,
    /// Fraction of the stratified samples drawn from the glossy lobe (0: area sampling only).
    lobe_fraction: f32,
    /// Per-triangle reflectance factors (mesh triangle order), None = all 1.
    face_weights: Option<Vec<f32>>,
    /// Bounding box of every laser and sensor spot (the splat rule's distance bound).
    spots: (Vec3, Vec3),
    /// Splat rule: the subdivision level of each block of `BLOCK` storage slots, and of each mesh triangle
    /// (its block's level); empty for the other rules.
    block_levels: Vec<u32>,
    tri_levels: Vec<u32>,
}

impl Renderer {
    /// Validates the inputs and builds the geometry (and the BVH and cache the visibility mode needs).
    ///
    /// Degenerate triangles (zero or non-finite area) are skipped: they have no area to integrate over.
    ///
    /// # Errors
    /// [`RenderError::NonFiniteVertex`], [`RenderError::IndexOutOfRange`], [`RenderError::InvalidSetup`]
    /// for an invalid or empty scan / time axis, [`RenderError::InvalidParameter`] for bad params.
    pub fn new(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        scan: &Scan,
        time: &TimeAxis,
        params: RenderParams,
    ) -> Result<Self> {
        scan.validate().map_err(|e| RenderError::InvalidSetup(e.to_string()))?;
        time.validate().map_err(|e| RenderError::InvalidSetup(e.to_string()))?;
        if scan.measurements() == 0 {
            return Err(RenderError::InvalidSetup("the scan has no measurements".into()));
        }
        check_params(&params)?;
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                if v as usize >= positions.len() {
                    return Err(RenderError::IndexOutOfRange { triangle: t, vertex: v, vertices: positions.len() });
                }
            }
        }
        let m = scan.measurements();
        let mut wall = Wall {
            l: Vec::with_capacity(m),
            n_l: Vec::with_capacity(m),
            s: Vec::with_capacity(m),
            n_s: Vec::with_capacity(m),
            confocal: scan.is_confocal(),
        };
        for i in 0..m {
            let g = scan.measurement(i);
            wall.l.push(g.laser);
            wall.n_l.push(g.laser_normal);
            wall.s.push(g.sensor);
            wall.n_s.push(g.sensor_normal);
        }
        let mut r = Self {
            triangles: triangles.to_vec(),
            n_vertices: positions.len(),
            tris: Tris::default(),
            total_area: 0.0,
            wall,
            scan: scan.clone(),
            time: *time,
            params,
            kernel: KernelEval::new(params.kernel, time.t0, time.bin_width, time.bins),
            bvh: None,
            cache: None,
            isa: Isa::detect(),
            lobe_fraction: 0.0,
            face_weights: None,
            spots: spot_box(scan),
            block_levels: Vec::new(),
            tri_levels: Vec::new(),
        };
        r.set_positions(positions)?;
        if matches!(params.visibility, Visibility::Cached { .. }) {
            r.refresh_visibility();
        }
        Ok(r)
    }

    /// Moves the vertices (same topology). With [`Visibility::Live`] the BVH is rebuilt; with
    /// [`Visibility::Cached`] the cache is kept (visibility held fixed) until [`Renderer::refresh_visibility`].
    ///
    /// # Errors
    /// [`RenderError::TopologyChanged`] for a different vertex count, [`RenderError::NonFiniteVertex`].
    pub fn set_positions(&mut self, positions: &[Vec3]) -> Result<()> {
        if positions.len() != self.n_vertices {
            return Err(RenderError::TopologyChanged { expected: self.n_vertices, got: positions.len() });
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(RenderError::NonFiniteVertex { index: i, value: positions[i].to_array() });
        }
        let nt = self.triangles.len();
        let mut tris = Tris {
            v0: Vec::with_capacity(nt),
            e1: Vec::with_capacity(nt),
            e2: Vec::with_capacity(nt),
            n: Vec::with_capacity(nt),
            e_max: Vec::with_capacity(nt),
            valid: Vec::with_capacity(nt),
            soa: Soa::default(),
        };
        let mut area = 0.0f64;
        for &[a, b, c] in &self.triangles {
            let (p0, p1, p2) = (positions[a as usize], positions[b as usize], positions[c as usize]);
            let (e1, e2) = (p1 - p0, p2 - p0);
            let n = e1.cross(e2);
            let len = n.length();
            // Guard: a zero-area (or overflowing) face has no integral and no defined normal: skipped.
            let valid = len > 0.0 && len.is_finite();
            if valid {
                area += 0.5 * f64::from(len);
            }
            tris.v0.push(p0);
            tris.e1.push(e1);
            tris.e2.push(e2);
            tris.n.push(n);
            tris.e_max.push(e1.length().max(e2.length()).max((p2 - p1).length()));
            tris.valid.push(valid);
        }
        // The visibility cache is stored in the block order, which is therefore kept while the cache is.
        let keep = (self.cache.is_some() && matches!(self.params.visibility, Visibility::Cached { .. }))
            .then(|| std::mem::take(&mut self.tris.soa.order));
        tris.soa = Soa::new(&tris.v0, &tris.e1, &tris.e2, &tris.n, &tris.valid, keep);
        self.tris = tris;
        self.total_area = area as f32;
        if self.params.visibility == Visibility::Live {
            self.bvh = Bvh::build(&self.tris.v0, &self.tris.e1, &self.tris.e2, &self.tris.valid);
        }
        self.update_levels();
        Ok(())
    }

    /// Each triangle's level under the splat rule ([`SplatRule`]) at the positions of `t` (mesh order), None
    /// for the other rules.
    fn splat_levels(&self, t: &Tris) -> Option<Vec<u32>> {
        let Sampling::Splat(rule) = self.params.sampling else { return None };
        let tol = rule.max_deviation * self.time.bin_width as f32;
        let (lo, hi) = self.spots;
        let level = |i: usize| -> u32 {
            if !t.valid[i] {
                return 1;
            }
            let e = t.e_max[i];
            let r = [t.v0[i], t.v0[i] + t.e1[i], t.v0[i] + t.e2[i]]
                .iter()
                .map(|p| (lo - *p).max(*p - hi).max(Vec3::ZERO).length())
                .fold(f32::INFINITY, f32::min)
                - e;
            // Guard: a triangle touching a spot's box has no useful bound: the finest level (1e-4 m keeps the
            // arithmetic finite).
            let deviation = (2.0 / r.max(1e-4)) * e * e / 6.0;
            let n = (deviation / tol).sqrt().ceil();
            if n < rule.max_level as f32 { (n as u32).max(1) } else { rule.max_level }
        };
        Some((0..t.valid.len()).map(level).collect())
    }

    /// The splat rule's levels ([`SplatRule`]) for the current positions and block order: a block runs the
    /// largest level of its triangles.
    fn update_levels(&mut self) {
        let Some(level) = self.splat_levels(&self.tris) else { return };
        let order = &self.tris.soa.order;
        self.block_levels =
            order.chunks(BLOCK).map(|blk| blk.iter().map(|&i| level[i as usize]).max().unwrap_or(1)).collect();
        let mut tri = vec![1u32; order.len()];
        for (slot, &i) in order.iter().enumerate() {
            tri[i as usize] = self.block_levels[slot / BLOCK];
        }
        self.tri_levels = tri;
    }

    /// Rebuilds the BVH at the current positions and, in [`Visibility::Cached`] mode, recomputes the cache.
    pub fn refresh_visibility(&mut self) {
        if self.params.visibility == Visibility::Off {
            return;
        }
        self.bvh = Bvh::build(&self.tris.v0, &self.tris.e1, &self.tris.e2, &self.tris.valid);
        let Visibility::Cached { level } = self.params.visibility else { return };
        // Regroup the triangles by their current normals; the cache is stored in that order (row m, slot i:
        // mesh triangle order[i]), so the block kernels read it contiguously.
        let t = &self.tris;
        self.tris.soa = Soa::new(&t.v0, &t.e1, &t.e2, &t.n, &t.valid, None);
        self.update_levels();
        let nt = self.tris.v0.len();
        let mut cache = vec![0u8; nt * self.wall.l.len()];
        let this = &*self;
        cache.par_chunks_mut(nt.max(1)).enumerate().for_each(|(m, row)| {
            let fr = this.frame(m);
            for (slot, out) in row.iter_mut().enumerate() {
                let t = this.mesh_triangle(slot);
                if this.orientation(t, &fr).is_none() {
                    continue;
                }
                let mut visible = 0u32;
                this.centroids(level, |u, v, _| {
                    let x = this.point(t, u, v);
                    visible += u32::from(this.visible_live(x, t, &fr));
                });
                let total = level * level;
                *out = ((visible * 255 + total / 2) / total) as u8;
            }
        });
        self.cache = Some(cache);
    }

    /// The scan.
    pub fn scan(&self) -> &Scan {
        &self.scan
    }

    /// The time axis.
    pub fn time(&self) -> &TimeAxis {
        &self.time
    }

    /// The parameters.
    pub fn params(&self) -> &RenderParams {
        &self.params
    }

    /// Multiple importance sampling of glossy surfaces in [`Sampling::Stratified`] mode (confocal scans; off
    /// by default): a share `φ = lobe_fraction · Ω_t/(Ω_t + 4πα²)` of each (triangle, measurement)'s expected
    /// sample count (`Ω_t` the triangle's solid angle seen from the spot: a lobe wider than the triangle is
    /// left to area sampling) is drawn from the BRDF's microfacet lobe instead of uniformly over the area,
    /// stratified in the polar angle — a microfacet normal `m` from the GGX
    /// distribution `D(m)(m·n)` about the triangle's normal (roughness [`RenderBrdf::lobe_alpha`]), mapped
    /// to the point where the ray from the laser spot along `−m` meets the triangle's plane (for a confocal
    /// measurement the half vector there is exactly `m`), kept when inside the triangle. Every sample, of
    /// either strategy, is weighted by the balance heuristic `1/(c₁ p₁(x) + c₂ p₂(x))` (Veach 1997, §9.2;
    /// `p₁ = 1/A`, `p₂ = D(m)(n·m)²/|x − l|²` the lobe density on the plane, `c₁ = (1 − φ)c`, `c₂ = φc` the
    /// expected counts), so the estimator stays unbiased; the weights are held fixed when differentiating,
    /// as the area weights are. Glossy lobes (small α) are then sampled where they peak — Tsai et al. 2019's
    /// stated weakness: on a specular plane (`tests/mis.rs`, 64 samples per measurement, `lobe_fraction`
    /// 0.9) the single-render error drops to 0.56× at α = 0.1, 0.87× at α = 0.15, and is unchanged (1.03×)
    /// at α = 0.2. No effect for a BRDF without a lobe, for exhaustive scans or for deterministic sampling.
    /// `lobe_fraction = 0` turns it off.
    ///
    /// # Errors
    /// [`RenderError::InvalidParameter`] unless `0 ≤ lobe_fraction < 1`.
    pub fn set_lobe_sampling(&mut self, lobe_fraction: f32) -> Result<()> {
        if !(0.0..1.0).contains(&lobe_fraction) {
            return Err(RenderError::InvalidParameter {
                name: "lobe_fraction",
                value: f64::from(lobe_fraction),
                reason: "must be in [0, 1)",
            });
        }
        self.lobe_fraction = lobe_fraction;
        Ok(())
    }

    /// Sets one reflectance factor per mesh triangle (`None`: all 1): triangle t's contribution to the
    /// forward pass, and to every gradient, is multiplied by `w_t` — a spatially varying albedo constant over
    /// each face, on top of the BRDF. The factors are kept across [`Renderer::set_positions`]; the adjoint
    /// pass returns dE/dw_t in [`Gradient::faces`]. A factor of 0 makes the triangle black: it is skipped, but
    /// it still casts shadows (visibility sees geometry only).
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] unless there is one factor per triangle,
    /// [`RenderError::InvalidParameter`] for a negative or non-finite factor.
    pub fn set_face_weights(&mut self, weights: Option<&[f32]>) -> Result<()> {
        if let Some(w) = weights {
            if w.len() != self.triangles.len() {
                return Err(RenderError::LengthMismatch {
                    what: "face weights",
                    expected: self.triangles.len(),
                    got: w.len(),
                });
            }
            if let Some(bad) = w.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                return Err(RenderError::InvalidParameter {
                    name: "face weight",
                    value: f64::from(*bad),
                    reason: "must be finite and ≥ 0 (a reflectance factor)",
                });
            }
        }
        self.face_weights = weights.map(<[f32]>::to_vec);
        Ok(())
    }

    /// The per-triangle reflectance factors set by [`Renderer::set_face_weights`], if any.
    pub fn face_weights(&self) -> Option<&[f32]> {
        self.face_weights.as_deref()
    }

    /// Triangle t's reflectance factor (1 without factors).
    #[inline(always)]
    fn face_weight(&self, t: usize) -> f32 {
        self.face_weights.as_ref().map_or(1.0, |w| w[t])
    }

    /// Number of skipped degenerate triangles.
    pub fn degenerate_triangles(&self) -> usize {
        self.tris.valid.iter().filter(|v| !**v).count()
    }

    /// Number of values of a transient (measurements × bins).
    pub fn len(&self) -> usize {
        self.wall.l.len() * self.time.bins
    }

    /// Whether the transient is empty (never: the scan and time axis are validated non-empty).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The forward pass, eq. (1): `I[m·bins + k] = Σ_t ∫_t K_k(τ(x)) f(x) v(x,l) v(x,s) dA(x)` with f the
    /// product of eq. (2) (see the crate docs for the scale convention).
    pub fn forward<B: RenderBrdf>(&self, brdf: &B) -> Vec<f32> {
        self.forward_with(brdf, &self.kernel)
    }

    /// The forward pass with kernel `k` (its bin count sets the histogram length).
    fn forward_with<B: RenderBrdf>(&self, brdf: &B, k: &KernelEval) -> Vec<f32> {
        let bins = k.bins();
        let nt = self.tris.v0.len();
        let mut data = vec![0.0f32; self.wall.l.len() * bins];
        // The tent fast path of the fixed rule and the splat rule write into histograms padded by one bin at
        // each end.
        let splat = self.splat_axis(k);
        let pad = usize::from(self.tent_path(k).is_some() || splat.is_some());
        // Tiles of M_CHUNK measurements × BLOCK triangles: each task owns its histograms (no lock, no
        // reduction) and sweeps every block of triangles over them while the block is in cache.
        let packed = self.packed_rule();
        data.par_chunks_mut(bins * M_CHUNK).enumerate().for_each(|(c, out)| {
            let (mut sc, mut pk) = (Scratch::new(), Packed::new());
            let rows = out.len() / bins;
            let mut local = vec![0.0f32; if pad == 1 { rows * (bins + 2) } else { 0 }];
            let ms: Vec<usize> = (c * M_CHUNK..c * M_CHUNK + rows).collect();
            for t0 in (0..nt).step_by(BLOCK) {
                let t1 = (t0 + BLOCK).min(nt);
                if packed {
                    // Fixed and splat rules: the tile's potentially active triangles of the block packed once,
                    // then swept over its measurements.
                    let n = self.block_level(t0);
                    let (hists, row_len) = if pad == 1 { (&mut local[..], bins + 2) } else { (&mut out[..], bins) };
                    if self.pack(&ms, t0, t1, &mut pk) {
                        for (&m, hist) in ms.iter().zip(hists.chunks_mut(row_len)) {
                            match &splat {
                                Some(axis) => self.forward_splat(brdf, axis, n, m, t0, &pk, hist, &mut sc),
                                None => self.forward_packed(brdf, k, n, m, t0, &pk, hist, &mut sc),
                            }
                        }
                    }
                } else if pad == 1 {
                    for (j, hist) in local.chunks_mut(bins + 2).enumerate() {
                        self.forward_block(brdf, k, c * M_CHUNK + j, t0, t1, hist, &mut sc);
                    }
                } else {
                    for (j, hist) in out.chunks_mut(bins).enumerate() {
                        self.forward_block(brdf, k, c * M_CHUNK + j, t0, t1, hist, &mut sc);
                    }
                }
            }
            if pad == 1 {
                for (o, l) in out.chunks_mut(bins).zip(local.chunks(bins + 2)) {
                    o.copy_from_slice(&l[1..=bins]);
                }
            }
        });
        data
    }

    /// The forward pass of one mesh triangle: its share of [`Renderer::forward`] (same samples, kernel and
    /// visibility; summed over every triangle it equals the forward pass up to f32 rounding). Sparse: one
    /// [`RowSpan`] per measurement the triangle reaches, holding the bins from its first to its last
    /// non-zero one. Used to ask what the loss would be without a face (boundary pruning in `nlos-optim`).
    ///
    /// Degenerate triangles (skipped by the forward pass) give no rows.
    ///
    /// # Errors
    /// [`RenderError::InvalidParameter`] when `triangle` is not a triangle of the mesh.
    pub fn forward_triangle<B: RenderBrdf>(&self, brdf: &B, triangle: usize) -> Result<Vec<RowSpan>> {
        let nt = self.tris.v0.len();
        if triangle >= nt {
            return Err(RenderError::InvalidParameter {
                name: "triangle",
                value: triangle as f64,
                reason: "not a triangle of the renderer's mesh (0 ≤ triangle < number of triangles)",
            });
        }
        // The cached visibility is stored in the block order: the triangle's storage slot. `order` is a
        // permutation of 0..nt and triangle < nt, so the search always succeeds (0 only as a formal fallback).
        let slot = self.tris.soa.order.iter().position(|&o| o as usize == triangle).unwrap_or(0);
        let bins = self.kernel.bins();
        let mut hist = vec![0.0f32; bins];
        let mut rows = Vec::new();
        for m in 0..self.wall.l.len() {
            let fr = self.frame(m);
            let Some(sign) = self.orientation(triangle, &fr) else { continue };
            let vis = match (&self.params.visibility, &self.cache) {
                (Visibility::Cached { .. }, Some(c)) => f32::from(c[m * nt + slot]) * (1.0 / 255.0),
                _ => 1.0,
            } * self.face_weight(triangle);
            if vis == 0.0 {
                continue;
            }
            // The bins written: all of them for a general kernel, those the splat rule reports for the tent.
            // Scanning and clearing only those keeps a face's share proportional to its own extent in time
            // rather than to the histogram's length (boundary pruning renders thousands of shares per block).
            let written = match self.splat_axis(&self.kernel) {
                Some(axis) => self.forward_tm_splat(brdf, &axis, triangle, &fr, sign, vis, &mut hist),
                None => {
                    self.forward_tm(brdf, &self.kernel, m, triangle, &fr, sign, vis, &mut hist);
                    bins.checked_sub(1).map(|last| (0, last))
                }
            };
            let Some((lo, hi)) = written else { continue };
            let part = &mut hist[lo..=hi];
            if let (Some(first), Some(last)) =
                (part.iter().position(|x| *x != 0.0), part.iter().rposition(|x| *x != 0.0))
            {
                rows.push(RowSpan { measurement: m, first_bin: lo + first, values: part[first..=last].to_vec() });
            }
            part.fill(0.0);
        }
        Ok(rows)
    }

    /// [`Renderer::forward`] wrapped as a [`Transient`] with the renderer's scan and time axis.
    ///
    /// # Errors
    /// [`RenderError::InvalidSetup`] if the transient crate rejects the combination (it should not).
    pub fn forward_transient<B: RenderBrdf>(&self, brdf: &B) -> Result<Transient> {
        Transient::new(self.scan.clone(), self.time, self.forward(brdf))
            .map_err(|e| RenderError::InvalidSetup(e.to_string()))
    }

    /// The adjoint pass: given `d_loss[m·bins + k] = dE/dI`, returns dE/d(vertices) and dE/d(BRDF
    /// parameters) of the same estimator the forward pass computes (same samples, same kernel, visibility
    /// held fixed). Samples are recomputed, nothing is stored between passes.
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] when `d_loss` is not measurements × bins long.
    pub fn adjoint<B: RenderBrdf>(&self, brdf: &B, d_loss: &[f32]) -> Result<Gradient> {
        self.adjoint_with(brdf, d_loss, &self.kernel)
    }

    /// The adjoint pass with kernel `k` (its bin count sets the row length of `d_loss`).
    fn adjoint_with<B: RenderBrdf>(&self, brdf: &B, d_loss: &[f32], k: &KernelEval) -> Result<Gradient> {
        let bins = k.bins();
        let expected = self.wall.l.len() * bins;
        if d_loss.len() != expected {
            return Err(RenderError::LengthMismatch { what: "d_loss", expected, got: d_loss.len() });
        }
        let nt = self.tris.v0.len();
        let nonzero: Vec<bool> = d_loss.par_chunks(bins).map(|a| a.iter().any(|x| *x != 0.0)).collect();
        // Parallel over ranges of triangles: each task sweeps every measurement over its range, block by
        // block (the adjoint row stays in L1 across the blocks), and owns the range's accumulators, so there
        // is no lock and no reduction of per-thread vertex arrays. The range size depends on the mesh only
        // (about 32 tasks, 1..16 blocks each), so the result does not depend on the thread count. Per
        // triangle: the 12 geometric sums of `Acc::flush`.
        let per_task = nt.div_ceil(32).next_multiple_of(BLOCK).clamp(BLOCK, 16 * BLOCK);
        // The tent fast path gathers from rows padded by a zero bin at each end (bin k at k + 1).
        let splat = self.splat_axis(k);
        let (padded, row_len) = if self.tent_path(k).is_some() || splat.is_some() {
            let mut p = vec![0.0f32; d_loss.len() / bins * (bins + 2)];
            p.par_chunks_mut(bins + 2).zip(d_loss.par_chunks(bins)).for_each(|(p, a)| p[1..=bins].copy_from_slice(a));
            (std::borrow::Cow::Owned(p), bins + 2)
        } else {
            (std::borrow::Cow::Borrowed(d_loss), bins)
        };
        // The splat's gather sums the padded rows' second differences (`Knots::gather_d2`).
        let second: Vec<f32> = if splat.is_some() {
            let mut d = vec![0.0f32; padded.len()];
            d.par_chunks_mut(row_len).zip(padded.par_chunks(row_len)).for_each(|(d, r)| {
                for p in 1..row_len - 1 {
                    d[p] = r[p - 1] - 2.0 * r[p] + r[p + 1];
                }
            });
            d
        } else {
            Vec::new()
        };
        let packed = self.packed_rule();
        let mut per_tri = vec![[0.0f64; 12]; nt];
        let per_task_params: Vec<[f64; 4]> = per_tri
            .par_chunks_mut(per_task)
            .enumerate()
            .map(|(ci, out)| {
                let (r0, r1) = (ci * per_task, ci * per_task + out.len());
                let blocks = || (r0..r1).step_by(BLOCK).map(move |b0| (b0, (b0 + BLOCK).min(r1)));
                let (mut sc, mut params) = (Scratch::new(), [0.0f64; 4]);
                if !packed {
                    for (m, adj) in d_loss.chunks(bins).enumerate().filter(|(m, _)| nonzero[*m]) {
                        for (b0, b1) in blocks() {
                            let o = &mut out[b0 - r0..b1 - r0];
                            self.adjoint_pairs(brdf, k, m, b0, b1, adj, o, &mut params, &mut sc);
                        }
                    }
                    return params;
                }
                // Fixed and splat rules. Groups of FLUSH measurements × blocks: the group's potentially active
                // triangles of the block are packed once; per sample point (sub-triangle) they are swept over
                // the group's measurements, accumulating in f32 (packed order), then flushed into f64 (the
                // f32 accumulators hold plain sums of dE/dx, the barycentric weights are applied at the
                // flush). Per triangle the additions come in the same order whatever the packing and the
                // thread count.
                let (mut acc, mut pk) = (Acc::new(BLOCK), Packed::new());
                let ms: Vec<usize> = (0..nonzero.len()).filter(|m| nonzero[*m]).collect();
                for group in ms.chunks(FLUSH) {
                    for (b0, b1) in blocks() {
                        if !self.pack(group, b0, b1, &mut pk) {
                            continue;
                        }
                        let n = self.block_level(b0);
                        let o = &mut out[b0 - r0..b1 - r0];
                        let slots = &pk.slots[..pk.len];
                        subtriangles(n, |sub| {
                            for &m in group {
                                let adj = &padded[m * row_len..(m + 1) * row_len];
                                match &splat {
                                    Some(axis) => {
                                        let d2 = &second[m * row_len..(m + 1) * row_len];
                                        self.adjoint_splat(brdf, axis, m, b0, &pk, adj, d2, &sub, &mut acc, &mut sc);
                                    }
                                    None => {
                                        let (u, v) = sub.centroid;
                                        self.adjoint_packed(brdf, k, m, b0, &pk, adj, (u, v, sub.w), &mut acc, &mut sc);
                                    }
                                }
                            }
                            if splat.is_some() {
                                acc.flush_splat(sub.centroid, sub.corners, slots, o, &mut params);
                            } else {
                                acc.flush_packed(sub.centroid, slots, o, &mut params);
                            }
                        });
                    }
                }
                params
            })
            .collect();
        // Distribution to the vertices (serial, in triangle order: deterministic). N = sign·(e1 × e2) and the
        // sums carry the sign: dE/de1 = e2 × G_N, dE/de2 = G_N × e1.
        let mut dv = vec![DVec3::ZERO; self.n_vertices];
        let mut faces = vec![0.0f32; nt];
        for (slot, g) in per_tri.iter().enumerate() {
            let t = self.mesh_triangle(slot);
            let v3 = |k: usize| DVec3::new(g[k], g[k + 1], g[k + 2]);
            let (g0, g1, g2, g_n) = (v3(0), v3(3), v3(6), v3(9));
            let (e1, e2) = (self.tris.e1[t].as_dvec3(), self.tris.e2[t].as_dvec3());
            // The triangle's integrand w_t·f_s(n̂)·Q(N) is homogeneous of degree 1 in N = e1 × e2 (Q holds
            // (N·a)(N·b)/|N|, f_s sees N only through n̂ = N/|N|) and the time kernel does not see N, so by
            // Euler's theorem N·dE/dN = Σ (dE/dI)·(the triangle's contribution) = w_t·dE/dw_t.
            let w = self.face_weight(t);
            if w > 0.0 {
                faces[t] = (e1.cross(e2).dot(g_n) / f64::from(w)) as f32;
            }
            let (d_e1, d_e2) = (e2.cross(g_n), g_n.cross(e1));
            let [i0, i1, i2] = self.triangles[t];
            dv[i0 as usize] += g0 - d_e1 - d_e2;
            dv[i1 as usize] += g1 + d_e1;
            dv[i2 as usize] += g2 + d_e2;
        }
        let dp = per_task_params.iter().fold([0.0f64; 4], |mut a, b| {
            for i in 0..4 {
                a[i] += b[i];
            }
            a
        });
        Ok(Gradient {
            vertices: dv.iter().map(|g| g.as_vec3()).collect(),
            brdf: dp[..B::PARAM_NAMES.len()].iter().map(|g| *g as f32).collect(),
            faces,
        })
    }

    /// Steady-state (time-integrated) intensity, one value per measurement: `S(l, s) = ∫_S f(x) v(x,l) v(x,s)
    /// dA(x)`, eq. (1) without the temporal kernel — what a conventional (non-transient) camera would record
    /// at s under a continuous source at l. Tsai et al. 2019 note that the method applies to any radiometric
    /// measurement; this is the simplest one. Equals the time sum of [`Renderer::forward`] (any kernel)
    /// whenever the time axis holds every path length; the same samples and visibility as the transient.
    pub fn forward_steady<B: RenderBrdf>(&self, brdf: &B) -> Vec<f32> {
        self.forward_with(brdf, &KernelEval::steady())
    }

    /// Adjoint of [`Renderer::forward_steady`]: given `d_loss[m] = dE/dS_m` (one per measurement), dE/d(vertices)
    /// and dE/d(BRDF parameters) (no time-shift term: S does not depend on path length).
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] when `d_loss` does not hold one value per measurement.
    pub fn adjoint_steady<B: RenderBrdf>(&self, brdf: &B, d_loss: &[f32]) -> Result<Gradient> {
        self.adjoint_with(brdf, d_loss, &KernelEval::steady())
    }

    /// [`Renderer::loss_and_gradient`] for steady-state measurements (`measured`: one value per measurement).
    ///
    /// # Errors
    /// As [`Loss::evaluate`].
    pub fn loss_and_gradient_steady<B: RenderBrdf>(
        &self,
        brdf: &B,
        measured: &[f32],
        loss: Loss,
        weights: Option<&[f32]>,
    ) -> Result<LossAndGradient> {
        let rendered = self.forward_steady(brdf);
        let (e, adj) = loss.evaluate(&rendered, measured, weights)?;
        let gradient = self.adjoint_steady(brdf, &adj)?;
        Ok(LossAndGradient { loss: e, gradient, rendered })
    }

    /// Forward pass, loss, adjoint pass: `E(I; measured)` and its gradient (eq. 6–7 of Tsai et al. 2019 for
    /// [`Loss::L2`]).
    ///
    /// # Errors
    /// As [`Loss::evaluate`].
    pub fn loss_and_gradient<B: RenderBrdf>(
        &self,
        brdf: &B,
        measured: &[f32],
        loss: Loss,
        weights: Option<&[f32]>,
    ) -> Result<LossAndGradient> {
        let rendered = self.forward(brdf);
        let (e, adj) = loss.evaluate(&rendered, measured, weights)?;
        let gradient = self.adjoint(brdf, &adj)?;
        Ok(LossAndGradient { loss: e, gradient, rendered })
    }

    // ----- internals -----

    #[inline(always)]
    fn frame(&self, m: usize) -> Frame {
        Frame { l: self.wall.l[m], n_l: self.wall.n_l[m], s: self.wall.s[m], n_s: self.wall.n_s[m] }
    }

    #[inline(always)]
    fn point(&self, t: usize, u: f32, v: f32) -> Vec3 {
        self.tris.v0[t] + u * self.tris.e1[t] + v * self.tris.e2[t]
    }

    /// +1 when l and s are both on the front side of triangle t, −1 when both behind and two-sided, else
    /// None. Exact for the whole face: N·(l − x) does not depend on x in the plane.
    #[inline(always)]
    fn orientation(&self, t: usize, fr: &Frame) -> Option<f32> {
        if !self.tris.valid[t] {
            return None;
        }
        let (n, v0) = (self.tris.n[t], self.tris.v0[t]);
        let (dl, ds) = (n.dot(fr.l - v0), n.dot(fr.s - v0));
        if dl > 0.0 && ds > 0.0 {
            Some(1.0)
        } else if self.params.two_sided && dl < 0.0 && ds < 0.0 {
            Some(-1.0)
        } else {
            None
        }
    }

    #[inline(always)]
    fn visible_live(&self, x: Vec3, t: usize, fr: &Frame) -> bool {
        match &self.bvh {
            None => true,
            Some(b) => b.visible(x, fr.l, t as u32) && (self.wall.confocal || b.visible(x, fr.s, t as u32)),
        }
    }

    /// Calls `f(u, v, w)` for the `n²` sub-triangle centroids of level n (barycentric coordinates u along
    /// e1, v along e2; weight `w = 1/n²`, the fraction of the triangle's area).
    #[inline(always)]
    fn centroids(&self, n: u32, mut f: impl FnMut(f32, f32, f32)) {
        subtriangles(n, |s| f(s.centroid.0, s.centroid.1, s.w));
    }

    /// Deterministic level for (t, m): see [`DeterministicRule`].
    #[inline(always)]
    fn level(&self, rule: &DeterministicRule, t: usize, fr: &Frame) -> u32 {
        if rule.min_level >= rule.max_level {
            return rule.max_level;
        }
        let v = [self.tris.v0[t], self.tris.v0[t] + self.tris.e1[t], self.tris.v0[t] + self.tris.e2[t]];
        let (mut lo, mut hi, mut r_min) = (f32::INFINITY, 0.0f32, f32::INFINITY);
        for p in v {
            let (a, b) = ((fr.l - p).length(), (fr.s - p).length());
            lo = lo.min(a + b);
            hi = hi.max(a + b);
            r_min = r_min.min(a).min(b);
        }
        let tol = rule.max_bin_fraction * self.time.bin_width as f32;
        // Guard: a vertex on a wall spot (r_min = 0) would make the curvature bound infinite; the clamp to
        // max_level below handles it, and 1e-6 m keeps the arithmetic finite.
        let curv = self.tris.e_max[t] * self.tris.e_max[t] / r_min.max(1e-6);
        let range = hi - lo;
        // Smallest n with tol·n² − range·n − curv ≥ 0.
        let n = (range + (range * range + 4.0 * tol * curv).sqrt()) / (2.0 * tol);
        if !(n < rule.max_level as f32) { rule.max_level } else { (n.ceil() as u32).max(rule.min_level) }
    }

    /// Calls `f(u, v, w)` for every sample of (t, m); `w` is the sample's weight as a fraction of the
    /// triangle's area (the estimator of `∫_t h dA` is `A_t Σ w h(x)`). `lobe`: the BRDF's lobe roughness
    /// (see [`Renderer::set_lobe_sampling`]); `sign`: the pair's orientation.
    #[inline(always)]
    fn samples(&self, m: usize, t: usize, fr: &Frame, lobe: Option<f32>, sign: f32, mut f: impl FnMut(f32, f32, f32)) {
        match self.params.sampling {
            Sampling::Deterministic(rule) => {
                let n = self.level(&rule, t, fr);
                self.centroids(n, f);
            }
            // The splat rule's sub-triangle centroids (reached only with a kernel the closed form does not
            // cover, where it is the fixed centroid rule of the triangle's level).
            Sampling::Splat(_) => self.centroids(self.tri_levels.get(t).copied().unwrap_or(1), f),
            Sampling::Stratified { samples_per_measurement, seed } => {
                let area = 0.5 * self.tris.n[t].length();
                let c = samples_per_measurement as f32 * area / self.total_area;
                // Guard: c is finite and > 0 for a valid triangle (total_area ≥ area > 0).
                if !(c > 0.0) {
                    return;
                }
                let mut rng = SplitMix64::new(seed, m as u64, t as u64);
                let lobe = match lobe {
                    Some(alpha) if self.lobe_fraction > 0.0 && self.wall.confocal && alpha > 0.0 => {
                        Some(Lobe::new(alpha, sign * self.tris.n[t], fr.l))
                    }
                    _ => None,
                };
                // The lobe's share of the samples: `lobe_fraction` scaled by Ω_t/(Ω_t + Ω_lobe), the solid angle
                // Ω_t of the triangle seen from l against the lobe's Ω_lobe = 4πα² (a lobe wider than the
                // triangle is better served by area sampling). A function of the geometry only (held fixed
                // when differentiating, as the weights are).
                let (c1, c2) = match (&lobe, lobe.map(|_| self.tris.v0[t] + (self.tris.e1[t] + self.tris.e2[t]) / 3.0))
                {
                    (Some(l), Some(centroid)) => {
                        let d = fr.l - centroid;
                        let r2 = d.length_squared();
                        let omega_t = area * l.n.dot(d).max(0.0) / (r2 * r2.sqrt());
                        let omega_lobe = 4.0 * std::f32::consts::PI * l.alpha2;
                        let phi = self.lobe_fraction * omega_t / (omega_t + omega_lobe);
                        let phi = if phi.is_finite() { phi } else { 0.0 };
                        ((1.0 - phi) * c, phi * c)
                    }
                    _ => (c, 0.0),
                };
                // The balance-heuristic weight of a sample at x, as a fraction of the area: 1/(c₁ + c₂ A p₂(x))
                // (= 1/c without the lobe).
                let weight = |u: f32, v: f32| match &lobe {
                    Some(l) => 1.0 / (c1 + c2 * area * l.pdf(self.point(t, u, v))),
                    None => 1.0 / c1,
                };
                let base = c1.floor();
                let n = base as u32 + u32::from(rng.next_f32() < c1 - base);
                // Weights are held constant when differentiating (sampling weights, not part of the
                // integrand); the random counts have expectation c₁, c₂, so the estimator is unbiased.
                let inv_n = 1.0 / n.max(1) as f32;
                for i in 0..n {
                    // Stratified along the first coordinate of the area-preserving map
                    // (r1, r2) ↦ (√r1 (1 − r2), √r1 r2).
                    let r1 = (i as f32 + rng.next_f32()) * inv_n;
                    let r2 = rng.next_f32();
                    let sr = r1.sqrt();
                    let (u, v) = (sr * (1.0 - r2), sr * r2);
                    f(u, v, weight(u, v));
                }
                let Some(lobe) = lobe else { return };
                let base = c2.floor();
                let n2 = base as u32 + u32::from(rng.next_f32() < c2 - base);
                let (v0, e1, e2) = (self.tris.v0[t], self.tris.e1[t], self.tris.e2[t]);
                let inv_n2 = 1.0 / n2.max(1) as f32;
                for i in 0..n2 {
                    // Stratified along the lobe's polar coordinate, like the area samples.
                    let (r1, r2) = ((i as f32 + rng.next_f32()) * inv_n2, rng.next_f32());
                    if let Some((u, v)) = lobe.sample(r1, r2, v0, e1, e2) {
                        f(u, v, weight(u, v));
                    }
                }
            }
        }
    }

    /// Orientation sign and cached visible fraction of every pair (m, t) of the block `t0..t1`; false when no
    /// pair of the block needs work (the block faces away as a whole, or every triangle faces away or is
    /// hidden in the cache), and then the buffers are not filled.
    #[inline(always)]
    fn pair_factors(&self, m: usize, t0: usize, blk: &Block<'_>, fr: &Frame, sc: &mut Scratch) -> bool {
        let len = blk.len;
        if !self.params.two_sided && self.tris.soa.culled(t0, fr) {
            return false;
        }
        soa::orientation(blk, fr, self.params.two_sided, &mut sc.sign);
        match (&self.params.visibility, &self.cache) {
            (Visibility::Cached { .. }, Some(c)) => {
                let row = &c[m * self.tris.v0.len() + t0..][..len];
                for (o, b) in sc.vis[..len].iter_mut().zip(row) {
                    *o = f32::from(*b) * (1.0 / 255.0);
                }
            }
            _ => sc.vis[..len].fill(1.0),
        }
        if let Some(w) = &self.face_weights {
            for (i, o) in sc.vis[..len].iter_mut().enumerate() {
                *o *= w[self.mesh_triangle(t0 + i)];
            }
        }
        // Whether any pair is active, without an early exit (so the loop vectorises).
        sc.sign[..len].iter().zip(&sc.vis[..len]).fold(false, |any, (s, v)| any | ((*s != 0.0) & (*v != 0.0)))
    }

    /// The mesh triangle at storage slot `slot` of the block kernels' layout.
    #[inline(always)]
    fn mesh_triangle(&self, slot: usize) -> usize {
        self.tris.soa.order[slot] as usize
    }

    /// The fixed level when the sampling is the deterministic rule with `min_level = max_level` (the block
    /// kernels' case), else None.
    #[inline(always)]
    fn fixed_level(&self) -> Option<u32> {
        match self.params.sampling {
            Sampling::Deterministic(rule) if rule.min_level >= rule.max_level => Some(rule.max_level),
            _ => None,
        }
    }

    /// Whether the sampling runs the packed block kernels: the fixed deterministic rule and the splat rule.
    #[inline(always)]
    fn packed_rule(&self) -> bool {
        self.fixed_level().is_some() || matches!(self.params.sampling, Sampling::Splat(_))
    }

    /// The subdivision level of the block starting at slot `t0` for the packed rules (1 for the others).
    #[inline(always)]
    fn block_level(&self, t0: usize) -> u32 {
        match self.params.sampling {
            Sampling::Splat(_) => self.block_levels.get(t0 / BLOCK).copied().unwrap_or(1),
            _ => self.fixed_level().unwrap_or(1),
        }
    }

    /// The tent kernel's constants when the splat rule applies (splat sampling and the tent kernel `k`).
    #[inline(always)]
    fn splat_axis(&self, k: &KernelEval) -> Option<TentAxis> {
        match self.params.sampling {
            Sampling::Splat(_) => k.tent(),
            _ => None,
        }
    }

    /// Forward pass of measurement m over the packed triangles `pk` of the block starting at slot `t0` into its
    /// padded histogram (bin k at k + 1), splat rule of level n: per sub-triangle, the vector kernel gives
    /// each triangle's centroid value and corner path lengths, then each active pair's closed-form tent
    /// weights are added over the bins it spans.
    #[allow(clippy::too_many_arguments)]
    fn forward_splat<B: RenderBrdf>(
        &self,
        brdf: &B,
        axis: &TentAxis,
        n: u32,
        m: usize,
        t0: usize,
        pk: &Packed,
        hist: &mut [f32],
        sc: &mut Scratch,
    ) {
        let fr = self.frame(m);
        if !self.packed_factors(m, t0, pk, &fr, sc) {
            return;
        }
        let blk = pk.block();
        let len = blk.len;
        let live = self.params.visibility == Visibility::Live && self.bvh.is_some();
        let last = hist.len() as i64 - 2;
        subtriangles(n, |sub| {
            if self.wall.confocal {
                soa::splat_samples::<B, true>(self.isa, brdf, &blk, &fr, &sub, axis, sc);
            } else {
                soa::splat_samples::<B, false>(self.isa, brdf, &blk, &fr, &sub, axis, sc);
            }
            let (u, v) = sub.centroid;
            for i in 0..len {
                let g = sc.g[i];
                if g == 0.0 {
                    continue;
                }
                if live && !self.visible_live(blk.point(i, u, v), self.mesh_triangle(t0 + pk.slots[i] as usize), &fr) {
                    continue;
                }
                // Pairs spanning at most `sc.span` bins: their weights came with the vector kernels.
                let k0 = sc.lanes.v[0][i];
                if sc.short[i] != 0.0 && k0 >= -1.0 {
                    let p = (k0 + 1.0) as usize;
                    if sc.span == 4 {
                        if let Some(h) = hist.get_mut(p..p + 4) {
                            for (x, w) in h.iter_mut().zip([sc.sw[0][i], sc.sw[1][i], sc.sw[2][i], sc.sw[3][i]]) {
                                *x += g * w;
                            }
                            continue;
                        }
                    } else if let Some(h) = hist.get_mut(p..p + sc.span) {
                        for (x, w) in h.iter_mut().zip(&sc.sw) {
                            *x += g * w[i];
                        }
                        continue;
                    }
                }
                if let Some(kn) =
                    Knots::lane(&sc.lanes, i).or_else(|| Knots::new([sc.kn[0][i], sc.kn[1][i], sc.kn[2][i]]))
                {
                    // Bins −1 and `bins` are the padding (index 0 and bins + 1): dropped afterwards.
                    kn.weights(-1, last, |k, w| hist[(k + 1) as usize] += g * w);
                }
            }
        });
    }

    /// The splat rule for one pair (t, m) into an unpadded histogram (the per-triangle forward pass): the same
    /// sub-triangles, values and weights as [`Renderer::forward_splat`]. Returns the range of bins written
    /// (`None`: none).
    #[allow(clippy::too_many_arguments)]
    fn forward_tm_splat<B: RenderBrdf>(
        &self,
        brdf: &B,
        axis: &TentAxis,
        t: usize,
        fr: &Frame,
        sign: f32,
        vis_c: f32,
        hist: &mut [f32],
    ) -> Option<(usize, usize)> {
        let live = self.params.visibility == Visibility::Live;
        let n = sign * self.tris.n[t];
        let inv_2n = 0.5 / n.length();
        let (mut k_min, mut k_max) = (i64::MAX, i64::MIN);
        let node = |x: Vec3| ((fr.l - x).length() + (fr.s - x).length() - axis.t0) * axis.inv_dt - 0.5;
        let last = hist.len() as i64 - 1;
        subtriangles(self.tri_levels.get(t).copied().unwrap_or(1), |sub| {
            let (u, v) = sub.centroid;
            let x = self.point(t, u, v);
            let (a, b) = (fr.l - x, fr.s - x);
            let (cl, cs) = (-fr.n_l.dot(a), -fr.n_s.dot(b));
            let (pl, ps) = (n.dot(a), n.dot(b));
            if !(cl > 0.0 && cs > 0.0 && pl > 0.0 && ps > 0.0) {
                return;
            }
            if live && !self.visible_live(x, t, fr) {
                return;
            }
            let (ra2, rb2) = (a.length_squared(), b.length_squared());
            let fs = if self.wall.confocal { brdf.eval_confocal(a, n) } else { brdf.eval(a, b, n) };
            let g = sub.w * vis_c * fs * (cl * pl * cs * ps * inv_2n / (ra2 * ra2 * rb2 * rb2));
            let c = sub.corners.map(|(cu, cv)| node(self.point(t, cu, cv)));
            let (c0, c1, c2) =
                splat::centred(c[0], c[1], c[2], node(x), (ra2.sqrt() + rb2.sqrt()) * axis.inv_dt, B::DISTANCE_POWER);
            if let Some(kn) = Knots::new([c0, c1, c2]) {
                kn.weights(0, last, |k, w| {
                    hist[k as usize] += g * w;
                    (k_min, k_max) = (k_min.min(k), k_max.max(k));
                });
            }
        });
        (k_min <= k_max).then_some((k_min as usize, k_max as usize))
    }

    /// Adjoint pass of measurement m (padded adjoint row `adj`) for sub-triangle `sub` of the splat rule over
    /// the packed triangles `pk` of the block starting at slot `t0`, into `acc` (packed order). Stage 1
    /// (vector): centroid lengths and cosine tests, corner path lengths and their gradients; stage 2: each
    /// active pair's closed-form gather `Σ_k r_k w_k` and `Σ_k r_k ∂w_k/∂τ_j`, split through the centring
    /// shift into corner terms and a centroid path-length term; stage 3 (vector): the centroid value's
    /// gradient and the centroid term; stage 4 (vector): the corners' path-length terms.
    #[allow(clippy::too_many_arguments)]
    fn adjoint_splat<B: RenderBrdf>(
        &self,
        brdf: &B,
        axis: &TentAxis,
        m: usize,
        t0: usize,
        pk: &Packed,
        adj: &[f32],
        d2: &[f32],
        sub: &soa::Sub,
        acc: &mut Acc,
        sc: &mut Scratch,
    ) {
        let fr = self.frame(m);
        if !self.packed_factors(m, t0, pk, &fr, sc) {
            return;
        }
        let blk = pk.block();
        let len = blk.len;
        let live = self.params.visibility == Visibility::Live && self.bvh.is_some();
        let (confocal, isa) = (self.wall.confocal, self.isa);
        if confocal {
            soa::splat_lengths::<true>(isa, &blk, &fr, sub, axis, B::DISTANCE_POWER, sc);
        } else {
            soa::splat_lengths::<false>(isa, &blk, &fr, sub, axis, B::DISTANCE_POWER, sc);
        }
        let last = adj.len() as i64 - 2;
        let (u, v) = sub.centroid;
        // Pairs spanning at most `sc.span` bins: their gathers in the vector kernels.
        soa::short_gathers(isa, len, adj, sc);
        for i in 0..len {
            let mut out = (0.0f32, [0.0f32; 3]);
            let corners = [sc.kn[0][i], sc.kn[1][i], sc.kn[2][i]];
            if sc.ok[i] != 0.0 && sc.short[i] != 0.0 {
                let d = [sc.sw[1][i], sc.sw[2][i], sc.sw[3][i]];
                out = (sc.sw[0][i], splat::to_corners(corners, d));
            } else if sc.ok[i] != 0.0
                && let Some(kn) = Knots::lane(&sc.lanes, i).or_else(|| Knots::new(corners))
            {
                let (val, d) = kn.gather_d2(
                    -1,
                    last,
                    |k| adj[(k + 1) as usize],
                    |j| d2.get((j + 1) as usize).copied().unwrap_or(0.0),
                );
                out = (val, splat::to_corners(corners, d));
            }
            if live
                && sc.ok[i] != 0.0
                && !self.visible_live(blk.point(i, u, v), self.mesh_triangle(t0 + pk.slots[i] as usize), &fr)
            {
                sc.ok[i] = 0.0;
                out = (0.0, [0.0; 3]);
            }
            sc.a_val[i] = out.0;
            // Through the shift of `splat::centred` (∂s/∂u_j, ∂s/∂τ_c): the corners carry ∂/∂u_j + Σ ∂s/∂u_j,
            // the centroid Σ ∂s/∂τ_c (its path-length term of stage 3); node units → metres of path.
            let sum = out.1[0] + out.1[1] + out.1[2];
            let (ds_du, ds_dtc) = splat::centred_grad(corners, (sc.tau[i] + sc.g[i]) * axis.inv_dt, B::DISTANCE_POWER);
            sc.a_der[i] = sum * ds_dtc * axis.inv_dt;
            for ((ct, d), ds) in sc.ct.iter_mut().zip(out.1).zip(ds_du) {
                ct[i] = (d + sum * ds) * axis.inv_dt;
            }
        }
        if confocal {
            soa::adjoint_samples::<B, true, true>(isa, brdf, &blk, &fr, (u, v, sub.w), sc, acc);
        } else {
            soa::adjoint_samples::<B, false, true>(isa, brdf, &blk, &fr, (u, v, sub.w), sc, acc);
        }
        soa::splat_corner_terms(isa, len, sc, acc);
    }

    /// Forward pass of measurement m over the triangles `t0..t1` into its histogram, pair by pair (any
    /// sampling but the fixed rule, which runs [`Renderer::forward_packed`]).
    #[allow(clippy::too_many_arguments)]
    fn forward_block<B: RenderBrdf>(
        &self,
        brdf: &B,
        k: &KernelEval,
        m: usize,
        t0: usize,
        t1: usize,
        hist: &mut [f32],
        sc: &mut Scratch,
    ) {
        let fr = self.frame(m);
        let blk = self.tris.soa.block(t0, t1);
        if !self.pair_factors(m, t0, &blk, &fr, sc) {
            return;
        }
        for i in 0..blk.len {
            if sc.sign[i] != 0.0 && sc.vis[i] != 0.0 {
                self.forward_tm(brdf, k, m, self.mesh_triangle(t0 + i), &fr, sc.sign[i], sc.vis[i], hist);
            }
        }
    }

    /// Packs into `pk` the triangles of the block `t0..t1` that may reflect for some measurement of `ms`
    /// (see [`Packed::pack`]; measurements for which the whole block faces away are left out of the spot
    /// boxes). False when none may.
    fn pack(&self, ms: &[usize], t0: usize, t1: usize, pk: &mut Packed) -> bool {
        pk.len = 0;
        let mut boxes: Option<(SpotBox, SpotBox)> = None;
        for &m in ms {
            let fr = self.frame(m);
            if !self.params.two_sided && self.tris.soa.culled(t0, &fr) {
                continue;
            }
            let ((ll, lh), (sl, sh)) = boxes.unwrap_or(((fr.l, fr.l), (fr.s, fr.s)));
            boxes = Some(((ll.min(fr.l), lh.max(fr.l)), (sl.min(fr.s), sh.max(fr.s))));
        }
        let Some((l, s)) = boxes else { return false };
        let keep_all = self.params.two_sided || self.tris.soa.no_cull;
        pk.pack(&self.tris.soa.block(t0, t1), l, s, keep_all) > 0
    }

    /// Orientation sign and cached visible fraction of every packed triangle of `pk` (block starting at slot
    /// `t0`) for measurement m; false when none of them needs work.
    #[inline(always)]
    fn packed_factors(&self, m: usize, t0: usize, pk: &Packed, fr: &Frame, sc: &mut Scratch) -> bool {
        if !self.params.two_sided && self.tris.soa.culled(t0, fr) {
            return false;
        }
        let len = pk.len;
        soa::orientation_dispatch(self.isa, &pk.block(), fr, self.params.two_sided, &mut sc.sign);
        match (&self.params.visibility, &self.cache) {
            (Visibility::Cached { .. }, Some(c)) => {
                let row = &c[m * self.tris.v0.len() + t0..];
                for (o, &t) in sc.vis[..len].iter_mut().zip(&pk.slots[..len]) {
                    *o = f32::from(row[t as usize]) * (1.0 / 255.0);
                }
            }
            _ => sc.vis[..len].fill(1.0),
        }
        if let Some(w) = &self.face_weights {
            for (o, &slot) in sc.vis[..len].iter_mut().zip(&pk.slots[..len]) {
                *o *= w[self.mesh_triangle(t0 + slot as usize)];
            }
        }
        sc.sign[..len].iter().zip(&sc.vis[..len]).fold(false, |any, (s, v)| any | ((*s != 0.0) & (*v != 0.0)))
    }

    /// Forward pass of measurement m over the packed triangles `pk` of the block starting at slot `t0` into
    /// its histogram (padded by one bin at each end on the tent fast path), fixed rule of level n.
    #[allow(clippy::too_many_arguments)]
    fn forward_packed<B: RenderBrdf>(
        &self,
        brdf: &B,
        k: &KernelEval,
        n: u32,
        m: usize,
        t0: usize,
        pk: &Packed,
        hist: &mut [f32],
        sc: &mut Scratch,
    ) {
        let fr = self.frame(m);
        if !self.packed_factors(m, t0, pk, &fr, sc) {
            return;
        }
        let blk = pk.block();
        let len = blk.len;
        let slots = &pk.slots[..len];
        let live = self.params.visibility == Visibility::Live && self.bvh.is_some();
        let tent = self.tent_path(k);
        let axis = tent.unwrap_or(TentAxis { t0: 0.0, inv_dt: 0.0, last: 0.0 });
        let isa = self.isa;
        self.centroids(n, |u, v, w| {
            match (self.wall.confocal, tent.is_some()) {
                (true, true) => soa::forward_samples::<B, true, true>(isa, brdf, &blk, &fr, (u, v, w), &axis, sc),
                (false, true) => soa::forward_samples::<B, false, true>(isa, brdf, &blk, &fr, (u, v, w), &axis, sc),
                (true, false) => soa::forward_samples::<B, true, false>(isa, brdf, &blk, &fr, (u, v, w), &axis, sc),
                (false, false) => soa::forward_samples::<B, false, false>(isa, brdf, &blk, &fr, (u, v, w), &axis, sc),
            }
            if live {
                for (i, &slot) in slots.iter().enumerate() {
                    let t = self.mesh_triangle(t0 + slot as usize);
                    if sc.g[i] != 0.0 && !self.visible_live(blk.point(i, u, v), t, &fr) {
                        sc.g[i] = 0.0;
                        sc.w0[i] = 0.0;
                        sc.w1[i] = 0.0;
                    }
                }
            }
            if tent.is_some() {
                // `hist` is padded (bin k at k + 1) and idx ≤ bins, so both writes are in range; zero weights
                // (skipped pairs) add nothing.
                for i in 0..len {
                    let p = sc.idx[i] as usize;
                    if let Some([h0, h1]) = hist.get_mut(p..p + 2) {
                        *h0 += sc.w0[i];
                        *h1 += sc.w1[i];
                    }
                }
            } else {
                k.splat_all(&sc.tau[..len], &sc.g[..len], hist);
            }
        });
    }

    /// The tent kernel's block constants when the fast path applies (fixed deterministic rule, tent kernel).
    #[inline(always)]
    fn tent_path(&self, k: &KernelEval) -> Option<TentAxis> {
        self.fixed_level().and(k.tent())
    }

    /// Adjoint pass of measurement m (adjoint row `adj`) at sample point `(u, v, w)` of the fixed rule over
    /// the packed triangles `pk` of the block starting at slot `t0`, into `acc` (packed order).
    #[allow(clippy::too_many_arguments)]
    fn adjoint_packed<B: RenderBrdf>(
        &self,
        brdf: &B,
        k: &KernelEval,
        m: usize,
        t0: usize,
        pk: &Packed,
        adj: &[f32],
        (u, v, w): (f32, f32, f32),
        acc: &mut Acc,
        sc: &mut Scratch,
    ) {
        let fr = self.frame(m);
        if !self.packed_factors(m, t0, pk, &fr, sc) {
            return;
        }
        let blk = pk.block();
        let len = blk.len;
        let live = self.params.visibility == Visibility::Live && self.bvh.is_some();
        let confocal = self.wall.confocal;
        let isa = self.isa;
        let tent = self.tent_path(k);
        let axis = tent.unwrap_or(TentAxis { t0: 0.0, inv_dt: 0.0, last: 0.0 });
        // Stage 1 (vector): |a|, |b|, the cosine tests (and the tent's bins).
        match (confocal, tent.is_some()) {
            (true, true) => soa::adjoint_lengths::<true, true>(isa, &blk, &fr, (u, v), &axis, sc),
            (false, true) => soa::adjoint_lengths::<false, true>(isa, &blk, &fr, (u, v), &axis, sc),
            (true, false) => soa::adjoint_lengths::<true, false>(isa, &blk, &fr, (u, v), &axis, sc),
            (false, false) => soa::adjoint_lengths::<false, false>(isa, &blk, &fr, (u, v), &axis, sc),
        }
        // Stage 2: gather the adjoint through the kernel (the tent from the padded row `adj`, vectorisable;
        // other kernels pair by pair), then the shadow ray of the samples that carry a gradient; zero for
        // skipped pairs and occluded samples.
        if tent.is_some() {
            soa::tent_gather(isa, len, adj, k.inv_dt(), sc);
        } else {
            for i in 0..len {
                (sc.a_val[i], sc.a_der[i]) =
                    if sc.ok[i] != 0.0 { k.gather(sc.tau[i] + sc.g[i], adj) } else { (0.0, 0.0) };
            }
        }
        if live {
            for i in 0..len {
                if (sc.a_val[i] != 0.0 || sc.a_der[i] != 0.0)
                    && !self.visible_live(blk.point(i, u, v), self.mesh_triangle(t0 + pk.slots[i] as usize), &fr)
                {
                    (sc.a_val[i], sc.a_der[i]) = (0.0, 0.0);
                }
            }
        }
        // Stage 3 (vector): the gradient terms, accumulated per triangle.
        if confocal {
            soa::adjoint_samples::<B, true, false>(isa, brdf, &blk, &fr, (u, v, w), sc, acc);
        } else {
            soa::adjoint_samples::<B, false, false>(isa, brdf, &blk, &fr, (u, v, w), sc, acc);
        }
    }

    /// Adjoint pass of measurement m over the triangles `t0..t1` with any sampling, pair by pair, into `out`
    /// (the per-triangle sums of [`Renderer::adjoint`]) and `params`, in f64.
    #[allow(clippy::too_many_arguments)]
    fn adjoint_pairs<B: RenderBrdf>(
        &self,
        brdf: &B,
        k: &KernelEval,
        m: usize,
        t0: usize,
        t1: usize,
        adj: &[f32],
        out: &mut [[f64; 12]],
        params: &mut [f64; 4],
        sc: &mut Scratch,
    ) {
        let fr = self.frame(m);
        let blk = self.tris.soa.block(t0, t1);
        if !self.pair_factors(m, t0, &blk, &fr, sc) {
            return;
        }
        for (i, o) in out.iter_mut().enumerate() {
            if sc.sign[i] != 0.0 && sc.vis[i] != 0.0 {
                let (g0, g1, g2, g_n, g_p) =
                    self.adjoint_tm(brdf, k, m, self.mesh_triangle(t0 + i), &fr, sc.sign[i], sc.vis[i], adj);
                for (k, g) in [g0, g1, g2, g_n].iter().enumerate() {
                    o[3 * k] += f64::from(g.x);
                    o[3 * k + 1] += f64::from(g.y);
                    o[3 * k + 2] += f64::from(g.z);
                }
                for (p, g) in params.iter_mut().zip(g_p) {
                    *p += f64::from(g);
                }
            }
        }
    }

    /// Forward pass of one pair (t, m) with any sampling (`sign` its orientation, `vis_c` its cached visible
    /// fraction, both non-zero).
    #[allow(clippy::too_many_arguments)]
    fn forward_tm<B: RenderBrdf>(
        &self,
        brdf: &B,
        k: &KernelEval,
        m: usize,
        t: usize,
        fr: &Frame,
        sign: f32,
        vis_c: f32,
        hist: &mut [f32],
    ) {
        let live = self.params.visibility == Visibility::Live;
        let n = sign * self.tris.n[t];
        let inv_2n = 0.5 / n.length();
        self.samples(m, t, fr, brdf.lobe_alpha(), sign, |u, v, w| {
            let x = self.point(t, u, v);
            let (a, b) = (fr.l - x, fr.s - x);
            let (cl, cs) = (-fr.n_l.dot(a), -fr.n_s.dot(b));
            let (pl, ps) = (n.dot(a), n.dot(b));
            // One-sided wall and surface cosines (max(0, ·) of eq. 2).
            if !(cl > 0.0 && cs > 0.0 && pl > 0.0 && ps > 0.0) {
                return;
            }
            if live && !self.visible_live(x, t, fr) {
                return;
            }
            let (ra2, rb2) = (a.length_squared(), b.length_squared());
            let tau = ra2.sqrt() + rb2.sqrt();
            let fs = if self.wall.confocal { brdf.eval_confocal(a, n) } else { brdf.eval(a, b, n) };
            let q = cl * pl * cs * ps * inv_2n / (ra2 * ra2 * rb2 * rb2);
            k.splat(tau, w * vis_c * fs * q, hist);
        });
    }

    /// Adjoint pass of one pair (t, m) with any sampling: `(Σ (1−u−v) dE/dx, Σ u dE/dx, Σ v dE/dx,
    /// sign·Σ dE/dN, dE/d(params))` over its samples.
    #[allow(clippy::too_many_arguments)]
    fn adjoint_tm<B: RenderBrdf>(
        &self,
        brdf: &B,
        k: &KernelEval,
        m: usize,
        t: usize,
        fr: &Frame,
        sign: f32,
        vis_c: f32,
        adj: &[f32],
    ) -> (Vec3, Vec3, Vec3, Vec3, [f32; 4]) {
        let live = self.params.visibility == Visibility::Live;
        let n = sign * self.tris.n[t];
        let n2 = n.length_squared();
        let inv_2n = 0.5 / n2.sqrt();
        let (mut g0, mut g1, mut g2, mut g_n) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        let mut g_p = [0.0f32; 4];
        self.samples(m, t, fr, brdf.lobe_alpha(), sign, |u, v, w| {
            let x = self.point(t, u, v);
            let (a, b) = (fr.l - x, fr.s - x);
            let (cl, cs) = (-fr.n_l.dot(a), -fr.n_s.dot(b));
            let (pl, ps) = (n.dot(a), n.dot(b));
            if !(cl > 0.0 && cs > 0.0 && pl > 0.0 && ps > 0.0) {
                return;
            }
            let (ra2, rb2) = (a.length_squared(), b.length_squared());
            let (ra, rb) = (ra2.sqrt(), rb2.sqrt());
            let (a_val, a_der) = k.gather(ra + rb, adj);
            if a_val == 0.0 && a_der == 0.0 {
                return;
            }
            if live && !self.visible_live(x, t, fr) {
                return;
            }
            let (fs, df_a, df_b, df_n, df_p) = if self.wall.confocal {
                let g = brdf.eval_grad_confocal(a, n);
                // Total derivative along the shared direction: only d/da + d/db is ever used below.
                (g.value, g.d_omega, Vec3::ZERO, g.d_n, B::param_grad_array(&g.d_params))
            } else {
                let g = brdf.eval_grad(a, b, n);
                (g.value, g.d_omega_l, g.d_omega_s, g.d_n, B::param_grad_array(&g.d_params))
            };
            // Q = cl pl cs ps / (2|N| ra⁴ rb⁴): the geometry of eq. (2) times the area |N|/2 (see crate docs).
            let denom = inv_2n / (ra2 * ra2 * rb2 * rb2);
            let q = cl * pl * cs * ps * denom;
            let dq_a = cs * ps * denom * (cl * n - pl * fr.n_l) - (4.0 * q / ra2) * a;
            let dq_b = cl * pl * denom * (cs * n - ps * fr.n_s) - (4.0 * q / rb2) * b;
            let dq_n = cl * cs * denom * (ps * a + pl * b) - (q / n2) * n;
            let s = w * vis_c;
            let h = fs * q;
            // dE = A_val dh + h A_der dτ, dτ/da = a/ra, dτ/db = b/rb.
            let ga = s * (a_val * (fs * dq_a + q * df_a) + (h * a_der / ra) * a);
            let gb = s * (a_val * (fs * dq_b + q * df_b) + (h * a_der / rb) * b);
            let gn = s * a_val * (fs * dq_n + q * df_n);
            // x = v0 + u e1 + v e2 and a = l − x, b = s − x ⇒ dE/dx = −(ga + gb).
            let gx = -(ga + gb);
            g0 += (1.0 - u - v) * gx;
            g1 += u * gx;
            g2 += v * gx;
            g_n += gn;
            let sp = s * a_val * q;
            for i in 0..4 {
                g_p[i] += sp * df_p[i];
            }
        });
        // N = sign·(e1 × e2): the vertex distribution needs G_N' = sign·G_N.
        (g0, g1, g2, sign * g_n, g_p)
    }
}

/// Calls `f` for the `n²` congruent sub-triangles of level n (n per edge): the "up" sub-triangle with corner
/// (i, j) has its centroid at (i + 1/3, j + 1/3)/n, the "down" one at (i + 2/3, j + 2/3)/n; each carries its
/// corners, centroid and weight `1/n²` (the fraction of the triangle's area).
#[inline(always)]
fn subtriangles(n: u32, mut f: impl FnMut(soa::Sub)) {
    let inv = 1.0 / n as f32;
    let w = inv * inv;
    let p = |i: u32, j: u32| (i as f32 * inv, j as f32 * inv);
    for i in 0..n {
        for j in 0..n - i {
            let centroid = ((i as f32 + 1.0 / 3.0) * inv, (j as f32 + 1.0 / 3.0) * inv);
            f(soa::Sub { corners: [p(i, j), p(i + 1, j), p(i, j + 1)], centroid, w });
            if j + 1 < n - i {
                let centroid = ((i as f32 + 2.0 / 3.0) * inv, (j as f32 + 2.0 / 3.0) * inv);
                f(soa::Sub { corners: [p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)], centroid, w });
            }
        }
    }
}

/// Componentwise bounding box of every laser and sensor spot of the scan.
fn spot_box(scan: &Scan) -> (Vec3, Vec3) {
    (0..scan.measurements()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), i| {
        let g = scan.measurement(i);
        (lo.min(g.laser).min(g.sensor), hi.max(g.laser).max(g.sensor))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nlos_brdf::{Fresnel, Ggx};
    use nlos_transient::PointSet;

    /// The AVX2 + FMA instantiations of the block kernels compute the same bits as the baseline ones (no
    /// fused multiply-adds are requested, and every lane is independent), on a CPU that has AVX2 (else the
    /// test compares the baseline with itself).
    #[test]
    fn avx2_and_baseline_kernels_agree_bitwise() {
        let mut p = Vec::new();
        let mut f = Vec::new();
        for i in 0..300u32 {
            let (x, y) = ((i % 20) as f32 * 0.02 - 0.2, (i / 20) as f32 * 0.02 - 0.15);
            let z = 0.4 + 0.05 * (9.0 * x).sin();
            p.extend([Vec3::new(x, y, z), Vec3::new(x, y + 0.02, z + 0.01), Vec3::new(x + 0.02, y, z - 0.01)]);
            f.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let time = TimeAxis::new(0.6, 0.004, 150).expect("axis");
        let brdf = Ggx::new(0.2f32, 0.8, 0.3, Fresnel::Schlick { f0: 0.5 }).expect("valid");
        for scan in [
            Scan::confocal(PointSet::wall_grid(3, 3, 0.2, 0.2).expect("grid")),
            Scan::exhaustive(
                PointSet::wall_grid(2, 2, 0.2, 0.2).expect("grid"),
                PointSet::wall_grid(2, 1, 0.1, 0.1).expect("grid"),
            ),
        ] {
            for kernel in [Kernel::Tent, Kernel::Gaussian { fwhm_bins: 2.0 }] {
                let params = RenderParams {
                    kernel,
                    sampling: Sampling::Deterministic(DeterministicRule::fixed(2)),
                    visibility: Visibility::Off,
                    two_sided: true,
                };
                let mut r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
                let fast = r.forward(&brdf);
                let adj: Vec<f32> = (0..fast.len()).map(|i| (i as f32 * 0.37).sin()).collect();
                let g_fast = r.adjoint(&brdf, &adj).expect("ok");
                r.isa = Isa::baseline();
                assert_eq!(fast, r.forward(&brdf), "forward ({kernel:?})");
                assert_eq!(g_fast, r.adjoint(&brdf, &adj).expect("ok"), "adjoint ({kernel:?})");
                assert!(fast.iter().any(|v| *v > 0.0));
            }
        }
    }

    /// A sphere of `2 nu nv` triangles around (0, 0, 0.4), radius 0.1, normals outward, vertices jittered
    /// radially by up to `jitter`.
    fn sphere(nu: u32, nv: u32, jitter: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..=nv {
            for i in 0..nu {
                let (th, ph) =
                    (std::f32::consts::PI * j as f32 / nv as f32, std::f32::consts::TAU * i as f32 / nu as f32);
                let r = 0.1 + jitter * ((i * 7 + j * 13) as f32 * 1.7).sin();
                p.push(Vec3::new(r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), 0.4 + r * th.cos()));
            }
        }
        let id = |i: u32, j: u32| j * nu + i % nu;
        let mut f = Vec::new();
        for j in 0..nv {
            for i in 0..nu {
                f.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
                f.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
            }
        }
        (p, f)
    }

    /// The visibility cache follows its triangles through `set_positions` (it is stored in the block order,
    /// which `set_positions` keeps while a cache exists, though the moved normals would regroup them): on a
    /// convex sphere (everything front-facing is visible), a cache computed before a jitter of the vertices
    /// gives the render of a cache computed after it, up to grazing pairs that changed orientation.
    #[test]
    fn cache_survives_set_positions() {
        let (p0, f) = sphere(96, 48, 0.0);
        let (p1, _) = sphere(96, 48, 0.0005);
        let time = TimeAxis::new(0.0, 0.004, 300).expect("axis");
        let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.3, 0.3).expect("grid"));
        let params = RenderParams {
            sampling: Sampling::Deterministic(DeterministicRule::fixed(1)),
            visibility: Visibility::Cached { level: 1 },
            ..Default::default()
        };
        let brdf = Ggx::new(0.5f32, 0.5, 0.3, Fresnel::One).expect("valid");
        let mut moved = Renderer::new(&p0, &f, &scan, &time, params).expect("valid");
        moved.set_positions(&p1).expect("finite");
        let fresh = Renderer::new(&p1, &f, &scan, &time, params).expect("valid");
        assert_ne!(moved.tris.soa.order, fresh.tris.soa.order, "the jitter must regroup some triangles");
        let (a, b) = (moved.forward(&brdf), fresh.forward(&brdf));
        let num: f64 = a.iter().zip(&b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
        let den: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
        assert!(den > 0.0 && (num / den).sqrt() < 1e-3, "rel-L2 {}", (num / den).sqrt());
    }

    /// Culling whole blocks that face away, and packing a block's front-facing triangles (fixed rule), change
    /// no bit: a closed, bumpy sphere (every orientation) seen from spots all around it, one-sided faces,
    /// fixed and adaptive rules, with and without the cache.
    #[test]
    fn block_culling_is_exact() {
        let (nu, nv) = (96u32, 48u32);
        let mut p = Vec::new();
        for j in 0..=nv {
            for i in 0..nu {
                let (th, ph) =
                    (std::f32::consts::PI * j as f32 / nv as f32, std::f32::consts::TAU * i as f32 / nu as f32);
                let r = 0.1 * (1.0 + 0.1 * (5.0 * ph).sin() * th.sin());
                p.push(Vec3::new(r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), 0.4 + r * th.cos()));
            }
        }
        let id = |i: u32, j: u32| j * nu + i % nu;
        let mut f = Vec::new();
        for j in 0..nv {
            for i in 0..nu {
                f.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                f.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        assert!(f.len() > 8 * BLOCK);
        let time = TimeAxis::new(0.0, 0.004, 300).expect("axis");
        let brdf = Ggx::new(0.2f32, 0.8, 0.3, Fresnel::One).expect("valid");
        // Wall spots around the sphere (a confocal list; the "wall" normals face the sphere).
        let spots: Vec<Vec3> = (0..12)
            .map(|k| {
                let a = k as f32 * 0.55;
                Vec3::new(0.3 * a.cos(), 0.3 * a.sin(), 0.4 + 0.25 * (1.3 * a).sin())
            })
            .collect();
        let mut set = PointSet::list(spots.clone());
        set.normals = spots.iter().map(|s| (Vec3::new(0.0, 0.0, 0.4) - *s).normalize()).collect();
        let scan = Scan::confocal(set);
        for sampling in [
            Sampling::Deterministic(DeterministicRule::fixed(1)),
            Sampling::Deterministic(DeterministicRule { max_bin_fraction: 1.0, min_level: 1, max_level: 3 }),
        ] {
            for visibility in [Visibility::Off, Visibility::Cached { level: 1 }] {
                let params = RenderParams { kernel: Kernel::Tent, sampling, visibility, two_sided: false };
                let mut r = Renderer::new(&p, &f, &scan, &time, params).expect("valid");
                let culled = r.forward(&brdf);
                let adj: Vec<f32> = (0..culled.len()).map(|i| (i as f32 * 0.37).sin()).collect();
                let g = r.adjoint(&brdf, &adj).expect("ok");
                let active = (0..scan.measurements())
                    .flat_map(|m| (0..f.len()).step_by(BLOCK).map(move |t0| (m, t0)))
                    .filter(|(m, t0)| !r.tris.soa.culled(*t0, &r.frame(*m)))
                    .count();
                let total = scan.measurements() * f.len().div_ceil(BLOCK);
                assert!(active < total && active > 0, "some blocks culled, not all: {active} of {total}");
                // Packing leaves out part of the blocks that culling keeps.
                let mut pk = Packed::new();
                let (mut packed, mut kept) = (0, 0);
                for m in 0..scan.measurements() {
                    for t0 in (0..f.len()).step_by(BLOCK) {
                        let t1 = (t0 + BLOCK).min(f.len());
                        if r.pack(&[m], t0, t1, &mut pk) {
                            packed += pk.len;
                            kept += t1 - t0;
                        }
                    }
                }
                assert!(packed > 0 && packed < kept, "packing must leave some triangles out: {packed} of {kept}");
                r.tris.soa.disable_culling();
                assert_eq!(culled, r.forward(&brdf), "forward ({sampling:?}, {visibility:?})");
                assert_eq!(g, r.adjoint(&brdf, &adj).expect("ok"), "adjoint ({sampling:?}, {visibility:?})");
                assert!(culled.iter().any(|v| *v > 0.0));
            }
        }
    }
}
