//! The adjoint pass (Proposition 1 of Tsai et al. 2019, with the normal and area terms): the gradient of a
//! loss with respect to the vertices, the reflectance parameters and the per-face weights, per rule.

use glam::Vec3;
use nlos_brdf::FittedBrdf;
use rayon::prelude::*;

use crate::error::{RenderError, Result};
use crate::kernel::KernelEval;
use crate::render::cpu::{Cpu, Pair, Pass, Row, Tile};
use crate::render::soa::{self, Acc, BLOCK, Packed, Scratch, TentAxis};
use crate::render::splat::{self, Knots};
use crate::render::{FLUSH, subtriangles};
use crate::{Gradient, Visibility};

impl Cpu<'_> {
    /// The adjoint pass with kernel `k` (its bin count sets the row length of `d_loss`).
    pub(in crate::render) fn adjoint_with<B: FittedBrdf>(
        &self,
        brdf: &B,
        d_loss: &[f32],
        k: &KernelEval,
    ) -> Result<Gradient> {
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
        // (about 32 tasks, 1..16 blocks each), so the result does not depend on the thread count. The tasks
        // run longest first (`longest_first`: by the seconds each took in the last pass, kept in
        // `adjoint_costs`), so that a pass does not end on one thread finishing a long range; the order they
        // run in changes no sum. Per triangle: the 12 geometric sums of `Acc::flush`.
        let per_task = nt.div_ceil(32).next_multiple_of(BLOCK).clamp(BLOCK, 16 * BLOCK);
        // The tent fast path gathers from rows padded by a zero bin at each end (bin k at k + 1).
        let splat = self.splat_axis(k);
        if splat.is_some_and(|a| a.box_kernel) {
            return Err(RenderError::InvalidParameter {
                name: "Sampling::Splat with Kernel::Box",
                value: 0.0,
                reason: "the box splat simulates measurements (forward only); the adjoint integrates the tent \
                         (Kernel::Tent), whose weights are smooth in the vertices",
            });
        }
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
        let tasks: Vec<&mut [[f64; 12]]> = per_tri.chunks_mut(per_task).collect();
        let per_task_params: Vec<[f64; 4]> = super::longest_first(tasks, &self.adjoint_costs, |ci, out| {
            let (r0, r1) = (ci * per_task, ci * per_task + out.len());
            let blocks = || (r0..r1).step_by(BLOCK).map(move |b0| (b0, (b0 + BLOCK).min(r1)));
            let (mut sc, mut params) = (Scratch::new(), [0.0f64; 4]);
            if !packed {
                for (m, adj) in d_loss.chunks(bins).enumerate().filter(|(m, _)| nonzero[*m]) {
                    for (b0, b1) in blocks() {
                        let o = &mut out[b0 - r0..b1 - r0];
                        let row = Row { m, d: adj, d2: &[] };
                        self.adjoint_pairs(Pass { brdf, kernel: k }, row, (b0, b1), o, &mut params, &mut sc);
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
                    let tile = Tile { t0: b0, pk: &pk, level: n };
                    let o = &mut out[b0 - r0..b1 - r0];
                    let slots = &pk.slots[..pk.len];
                    subtriangles(n, |sub| {
                        for &m in group {
                            let adj = &padded[m * row_len..(m + 1) * row_len];
                            match &splat {
                                Some(axis) => {
                                    let d2 = &second[m * row_len..(m + 1) * row_len];
                                    let (pass, row) = (Pass { brdf, kernel: axis }, Row { m, d: adj, d2 });
                                    self.adjoint_tile_splat(pass, tile, row, &sub, &mut acc, &mut sc);
                                }
                                None => {
                                    let (u, v) = sub.centroid;
                                    let (pass, row) = (Pass { brdf, kernel: k }, Row { m, d: adj, d2: &[] });
                                    self.adjoint_tile_fixed(pass, tile, row, (u, v, sub.w), &mut acc, &mut sc);
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
        });
        let dp = per_task_params.iter().fold([0.0f64; 4], |mut a, b| {
            for i in 0..4 {
                a[i] += b[i];
            }
            a
        });
        Ok(self.distribute::<B>(&per_tri, dp))
    }

    /// Adjoint pass of measurement m (padded adjoint row `adj`) for sub-triangle `sub` of the splat rule over
    /// the packed triangles `pk` of the block starting at slot `t0`, into `acc` (packed order). Stage 1
    /// (vector): centroid lengths and cosine tests, corner path lengths and their gradients; stage 2: each
    /// active pair's closed-form gather `Σ_k r_k w_k` and `Σ_k r_k ∂w_k/∂τ_j`, split through the centring
    /// shift into corner terms and a centroid path-length term; stage 3 (vector): the centroid value's
    /// gradient and the centroid term; stage 4 (vector): the corners' path-length terms.
    pub(in crate::render) fn adjoint_tile_splat<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, TentAxis>,
        tile: Tile<'_>,
        row: Row<'_>,
        sub: &soa::Sub,
        acc: &mut Acc,
        sc: &mut Scratch,
    ) {
        let (Pass { brdf, kernel: axis }, Tile { t0, pk, .. }, Row { m, d: adj, d2 }) = (pass, tile, row);
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
        // Pairs spanning at most `sc.span` bins: their gathers and their split in the vector kernels.
        soa::short_gathers(isa, len, adj, sc);
        soa::split_short_gathers(isa, len, axis.inv_dt, B::DISTANCE_POWER, sc);
        // The other active pairs one by one: those longer than the span, and hidden samples (live visibility).
        let todo = sc.select(len, |sc, i| (sc.ok[i] != 0.0) & (live | (sc.short[i] == 0.0)));
        for t in 0..todo {
            let i = sc.todo[t] as usize;
            let corners = [sc.kn[0][i], sc.kn[1][i], sc.kn[2][i]];
            let out =
                if live && !self.visible_live(blk.point(i, u, v), self.mesh_triangle(t0 + pk.slots[i] as usize), &fr) {
                    sc.ok[i] = 0.0;
                    Some((0.0, [0.0; 3]))
                } else if sc.short[i] == 0.0 {
                    Knots::lane(&sc.lanes, i).or_else(|| Knots::new(corners)).map(|kn| {
                        kn.gather_d2(
                            -1,
                            last,
                            |k| adj[(k + 1) as usize],
                            |j| d2.get((j + 1) as usize).copied().unwrap_or(0.0),
                        )
                    })
                } else {
                    None
                };
            if let Some((val, d)) = out {
                let tc = (sc.tau[i] + sc.g[i]) * axis.inv_dt;
                let (der, ct) = splat::split_gather(corners, d, tc, axis.inv_dt, B::DISTANCE_POWER);
                sc.a_val[i] = val;
                sc.a_der[i] = der;
                for (c, t) in sc.ct.iter_mut().zip(ct) {
                    c[i] = t;
                }
            }
        }
        if confocal {
            soa::adjoint_samples::<B, true, true>(isa, brdf, &blk, &fr, (u, v, sub.w), sc, acc);
        } else {
            soa::adjoint_samples::<B, false, true>(isa, brdf, &blk, &fr, (u, v, sub.w), sc, acc);
        }
        soa::splat_corner_terms(isa, len, sc, acc);
    }

    /// Adjoint pass of measurement m (adjoint row `adj`) at sample point `(u, v, w)` of the fixed rule over
    /// the packed triangles `pk` of the block starting at slot `t0`, into `acc` (packed order).
    pub(in crate::render) fn adjoint_tile_fixed<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, KernelEval>,
        tile: Tile<'_>,
        row: Row<'_>,
        (u, v, w): (f32, f32, f32),
        acc: &mut Acc,
        sc: &mut Scratch,
    ) {
        let (Pass { brdf, kernel: k }, Tile { t0, pk, .. }, Row { m, d: adj, .. }) = (pass, tile, row);
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
        let axis = tent.unwrap_or(TentAxis { t0: 0.0, inv_dt: 0.0, last: 0.0, box_kernel: false });
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
    pub(in crate::render) fn adjoint_pairs<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, KernelEval>,
        row: Row<'_>,
        (t0, t1): (usize, usize),
        out: &mut [[f64; 12]],
        params: &mut [f64; 4],
        sc: &mut Scratch,
    ) {
        let Row { m, d: adj, .. } = row;
        let fr = self.frame(m);
        let blk = self.tris.soa.block(t0, t1);
        if !self.pair_factors(m, t0, &blk, &fr, sc) {
            return;
        }
        for (i, o) in out.iter_mut().enumerate() {
            if sc.sign[i] != 0.0 && sc.vis[i] != 0.0 {
                let pair = Pair { m, t: self.mesh_triangle(t0 + i), fr: &fr, sign: sc.sign[i], vis: sc.vis[i] };
                let (g0, g1, g2, g_n, g_p) = self.adjoint_pair(pass, pair, adj);
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

    /// Adjoint pass of one pair (t, m) with any sampling: `(Σ (1−u−v) dE/dx, Σ u dE/dx, Σ v dE/dx,
    /// sign·Σ dE/dN, dE/d(params))` over its samples.
    pub(in crate::render) fn adjoint_pair<B: FittedBrdf>(
        &self,
        pass: Pass<'_, B, KernelEval>,
        pair: Pair<'_>,
        adj: &[f32],
    ) -> (Vec3, Vec3, Vec3, Vec3, [f32; 4]) {
        let (Pass { brdf, kernel: k }, Pair { m, t, fr, sign, vis: vis_c }) = (pass, pair);
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
