//! The forward pass (eq. 1–5 of Tsai et al. 2019): per rule (splat, point blocks, packed point rules,
//! stratified Monte Carlo) the transient of every measurement, and one triangle's share of it.

use glam::Vec3;
use nlos_brdf::FittedBrdf;
use rayon::prelude::*;

use crate::error::{RenderError, Result};
use crate::kernel::KernelEval;
use crate::render::cpu::{Cpu, Pair, Pass, Tile};
use crate::render::soa::{self, BLOCK, Block, Frame, Packed, Scratch, SpotBox, TentAxis};
use crate::render::splat::{self, Knots};
use crate::render::{M_CHUNK, subtriangles};
use crate::{RowSpan, Visibility};

impl Cpu<'_> {
    /// The forward pass with kernel `k` (its bin count sets the histogram length).
    pub(in crate::render) fn forward_with<B: FittedBrdf>(&self, brdf: &B, k: &KernelEval) -> Vec<f32> {
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
                    let (hists, row_len) = if pad == 1 { (&mut local[..], bins + 2) } else { (&mut out[..], bins) };
                    if self.pack(&ms, t0, t1, &mut pk) {
                        let tile = Tile { t0, pk: &pk, level: self.block_level(t0) };
                        for (&m, hist) in ms.iter().zip(hists.chunks_mut(row_len)) {
                            match &splat {
                                Some(axis) => {
                                    self.forward_tile_splat(Pass { brdf, kernel: axis }, tile, m, hist, &mut sc)
                                }
                                None => self.forward_tile_fixed(Pass { brdf, kernel: k }, tile, m, hist, &mut sc),
                            }
                        }
                    }
                } else if pad == 1 {
                    for (j, hist) in local.chunks_mut(bins + 2).enumerate() {
                        self.forward_pairs(Pass { brdf, kernel: k }, c * M_CHUNK + j, (t0, t1), hist, &mut sc);
                    }
                } else {
                    for (j, hist) in out.chunks_mut(bins).enumerate() {
                        self.forward_pairs(Pass { brdf, kernel: k }, c * M_CHUNK + j, (t0, t1), hist, &mut sc);
                    }
                }
            }
            if pad == 1 {
                for (o, l) in out.chunks_mut(bins).zip(local.chunks(bins + 2)) {
                    o.copy_from_slice(&l[1..=bins]);
                }
            }
            self.count_done(rows);
        });
        data
    }

    /// [`Renderer::forward_triangle`].
    pub(in crate::render) fn forward_triangle<B: FittedBrdf>(&self, brdf: &B, triangle: usize) -> Result<Vec<RowSpan>> {
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
                (Visibility::Cached { .. }, Some(c)) => {
                    f32::from(c[self.cache_layout().index(m, slot)]) * (1.0 / 255.0)
                }
                _ => 1.0,
            } * self.face_weight(triangle);
            if vis == 0.0 {
                continue;
            }
            let pair = Pair { m, t: triangle, fr: &fr, sign, vis };
            // The bins written: all of them for a general kernel, those the splat rule reports for the tent.
            // Scanning and clearing only those keeps a face's share proportional to its own extent in time
            // rather than to the histogram's length (boundary pruning renders thousands of shares per block).
            let written = match self.splat_axis(&self.kernel) {
                Some(axis) => self.forward_pair_splat(Pass { brdf, kernel: &axis }, pair, &mut hist),
                None => {
                    self.forward_pair(Pass { brdf, kernel: &self.kernel }, pair, &mut hist);
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

    /// Orientation sign and cached visible fraction of every pair (m, t) of the block `t0..t1`; false when no
    /// pair of the block needs work (the block faces away as a whole, or every triangle faces away or is
    /// hidden in the cache), and then the buffers are not filled.
    #[inline(always)]
    pub(in crate::render) fn pair_factors(
        &self,
        m: usize,
        t0: usize,
        blk: &Block<'_>,
        fr: &Frame,
        sc: &mut Scratch,
    ) -> bool {
        let len = blk.len;
        if !self.params.two_sided && self.tris.soa.culled(t0, fr) {
            return false;
        }
        soa::orientation(blk, fr, self.params.two_sided, &mut sc.sign);
        match (&self.params.visibility, &self.cache) {
            (Visibility::Cached { .. }, Some(c)) => {
                let row = &c[self.cache_layout().row(m, t0)][..len];
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

    /// Forward pass of measurement m over the packed triangles `pk` of the block starting at slot `t0` into its
    /// padded histogram (bin k at k + 1), splat rule of level n: per sub-triangle, the vector kernel gives
    /// each triangle's centroid value and corner path lengths, then each active pair's closed-form tent (or
    /// box, `axis.box_kernel`) weights are added over the bins it spans.
    pub(in crate::render) fn forward_tile_splat<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, TentAxis>,
        tile: Tile<'_>,
        m: usize,
        hist: &mut [f32],
        sc: &mut Scratch,
    ) {
        let (Pass { brdf, kernel: axis }, Tile { t0, pk, level: n }) = (pass, tile);
        let fr = self.frame(m);
        if !self.packed_factors(m, t0, pk, &fr, sc) {
            return;
        }
        let blk = pk.block();
        let len = blk.len;
        let live = self.params.visibility == Visibility::Live && self.bvh.is_some();
        subtriangles(n, |sub| {
            if self.wall.confocal {
                soa::splat_samples::<B, true>(self.isa, brdf, &blk, &fr, &sub, axis, sc);
            } else {
                soa::splat_samples::<B, false>(self.isa, brdf, &blk, &fr, &sub, axis, sc);
            }
            let (u, v) = sub.centroid;
            let hidden =
                |i: usize| !self.visible_live(blk.point(i, u, v), self.mesh_triangle(t0 + pk.slots[i] as usize), &fr);
            let hidden: Option<&dyn Fn(usize) -> bool> = if live { Some(&hidden) } else { None };
            match sc.span {
                4 => scatter::<4>(hist, sc, len, axis.box_kernel, hidden),
                8 => scatter::<8>(hist, sc, len, axis.box_kernel, hidden),
                _ => scatter::<{ splat::MAX_SPAN }>(hist, sc, len, axis.box_kernel, hidden),
            }
        });
    }

    /// The splat rule for one pair (t, m) into an unpadded histogram (the per-triangle forward pass): the same
    /// sub-triangles, values and weights as [`Renderer::forward_tile_splat`]. Returns the range of bins written
    /// (`None`: none).
    pub(in crate::render) fn forward_pair_splat<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, TentAxis>,
        pair: Pair<'_>,
        hist: &mut [f32],
    ) -> Option<(usize, usize)> {
        let (Pass { brdf, kernel: axis }, Pair { t, fr, sign, vis: vis_c, .. }) = (pass, pair);
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
                let mut add = |k: i64, w: f32| {
                    hist[k as usize] += g * w;
                    (k_min, k_max) = (k_min.min(k), k_max.max(k));
                };
                if axis.box_kernel { kn.box_weights(0, last, &mut add) } else { kn.weights(0, last, &mut add) }
            }
        });
        (k_min <= k_max).then_some((k_min as usize, k_max as usize))
    }

    /// Forward pass of measurement m over the triangles `t0..t1` into its histogram, pair by pair (any
    /// sampling but the fixed rule, which runs [`Renderer::forward_tile_fixed`]).
    pub(in crate::render) fn forward_pairs<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, KernelEval>,
        m: usize,
        (t0, t1): (usize, usize),
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
                let pair = Pair { m, t: self.mesh_triangle(t0 + i), fr: &fr, sign: sc.sign[i], vis: sc.vis[i] };
                self.forward_pair(pass, pair, hist);
            }
        }
    }

    /// Packs into `pk` the triangles of the block `t0..t1` that may reflect for some measurement of `ms`
    /// (see [`Packed::pack`]; measurements for which the whole block faces away are left out of the spot
    /// boxes). False when none may.
    pub(in crate::render) fn pack(&self, ms: &[usize], t0: usize, t1: usize, pk: &mut Packed) -> bool {
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
    pub(in crate::render) fn packed_factors(
        &self,
        m: usize,
        t0: usize,
        pk: &Packed,
        fr: &Frame,
        sc: &mut Scratch,
    ) -> bool {
        if !self.params.two_sided && self.tris.soa.culled(t0, fr) {
            return false;
        }
        let len = pk.len;
        soa::orientation_dispatch(self.isa, &pk.block(), fr, self.params.two_sided, &mut sc.sign);
        match (&self.params.visibility, &self.cache) {
            (Visibility::Cached { .. }, Some(c)) => {
                let row = &c[self.cache_layout().row(m, t0)];
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
    pub(in crate::render) fn forward_tile_fixed<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, KernelEval>,
        tile: Tile<'_>,
        m: usize,
        hist: &mut [f32],
        sc: &mut Scratch,
    ) {
        let (Pass { brdf, kernel: k }, Tile { t0, pk, level: n }) = (pass, tile);
        let fr = self.frame(m);
        if !self.packed_factors(m, t0, pk, &fr, sc) {
            return;
        }
        let blk = pk.block();
        let len = blk.len;
        let slots = &pk.slots[..len];
        let live = self.params.visibility == Visibility::Live && self.bvh.is_some();
        let tent = self.tent_path(k);
        let axis = tent.unwrap_or(TentAxis { t0: 0.0, inv_dt: 0.0, last: 0.0, box_kernel: false });
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

    /// Forward pass of one pair (t, m) with any sampling.
    pub(in crate::render) fn forward_pair<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, KernelEval>,
        pair: Pair<'_>,
        hist: &mut [f32],
    ) {
        let (Pass { brdf, kernel: k }, Pair { m, t, fr, sign, vis: vis_c }) = (pass, pair);
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
}

/// Adds one splat sub-triangle's pairs into the padded histogram `hist` (bin k at k + 1), in pair order: the
/// pairs spanning at most N bins (N = the block's `sc.span`) from the weights the vector kernels left in
/// `sc.sw`, the others through their knots (the tent's weights, or the box's). `hidden` (live visibility)
/// drops pairs whose sample is occluded.
#[inline(always)]
fn scatter<const N: usize>(
    hist: &mut [f32],
    sc: &Scratch,
    len: usize,
    box_kernel: bool,
    hidden: Option<&dyn Fn(usize) -> bool>,
) {
    let last = hist.len() as i64 - 2;
    let sw: [&[f32]; N] = std::array::from_fn(|k| &sc.sw[k][..len]);
    let (gs, short, k0s) = (&sc.g[..len], &sc.short[..len], &sc.lanes.v[0][..len]);
    for i in 0..len {
        let g = gs[i];
        if g == 0.0 || hidden.is_some_and(|h| h(i)) {
            continue;
        }
        let k0 = k0s[i];
        if short[i] != 0.0 && k0 >= -1.0 {
            let p = (k0 + 1.0) as usize;
            if let Some(h) = hist.get_mut(p..p + N) {
                for (x, w) in h.iter_mut().zip(sw) {
                    *x += g * w[i];
                }
                continue;
            }
        }
        if let Some(kn) = Knots::lane(&sc.lanes, i).or_else(|| Knots::new([sc.kn[0][i], sc.kn[1][i], sc.kn[2][i]])) {
            // Bins −1 and `bins` are the padding (index 0 and bins + 1): dropped afterwards.
            if box_kernel {
                kn.box_weights(-1, last, |k, w| hist[(k + 1) as usize] += g * w);
            } else {
                kn.weights(-1, last, |k, w| hist[(k + 1) as usize] += g * w);
            }
        }
    }
}
