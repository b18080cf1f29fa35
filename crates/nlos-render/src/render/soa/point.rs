//! The block kernels of the point rules (the fixed deterministic rule and the stratified samples): the
//! forward samples, the adjoint's path lengths, the tent kernel's gather and the adjoint's per-sample
//! gradients, each over a block of triangles at once.

use nlos_brdf::FittedBrdf;

use crate::kernel::TentAxis;
use crate::render::Isa;
use crate::render::soa::{Block, Frame, PairGeom, Scratch, at, pair_geometry};

/// Forward, one sample `(u, v, w)` per triangle of the block: `tau[i]` and `g[i]` = weight × visibility ×
/// f_s × Q (0 where the pair or the sample is skipped); with `TENT`, also the tent kernel's padded bin index
/// `idx[i]` and the two weighted bin contributions `w0[i]`, `w1[i]` (0 out of range). `CONFOCAL`: `s = l`
/// (`b = a`, one square root).
#[inline(never)]
pub(crate) fn forward_samples<B: FittedBrdf, const CONFOCAL: bool, const TENT: bool>(
    isa: Isa,
    brdf: &B,
    b: &Block<'_>,
    fr: &Frame,
    uvw: (f32, f32, f32),
    tent: &TentAxis,
    sc: &mut Scratch,
) {
    dispatch!(isa, forward_samples_body::<B, CONFOCAL, TENT>(brdf, b, fr, uvw, tent, sc))
}

#[inline(always)]
fn forward_samples_body<B: FittedBrdf, const CONFOCAL: bool, const TENT: bool>(
    brdf: &B,
    b: &Block<'_>,
    fr: &Frame,
    (u, v, w): (f32, f32, f32),
    tent: &TentAxis,
    sc: &mut Scratch,
) {
    let len = b.len;
    let (sign, vis, tau, g) = (&sc.sign[..len], &sc.vis[..len], &mut sc.tau[..len], &mut sc.g[..len]);
    let (idx, w0, w1) = (&mut sc.idx[..len], &mut sc.w0[..len], &mut sc.w1[..len]);
    let [v0, e1, e2, nn] = b.lanes();
    let inv_2n = &b.inv_2n[..len];
    for i in 0..len {
        let x = at(&v0, i) + u * at(&e1, i) + v * at(&e2, i);
        let n = sign[i] * at(&nn, i);
        // One-sided wall and surface cosines (max(0, ·) of eq. 2).
        let PairGeom { a, b: bb, cl, pl, cs, ps, ok } = pair_geometry::<CONFOCAL>(x, n, fr, sign[i], vis[i]);
        let ra2 = a.length_squared();
        let rb2 = if CONFOCAL { ra2 } else { bb.length_squared() };
        let ra = ra2.sqrt();
        let t = if CONFOCAL { ra + ra } else { ra + rb2.sqrt() };
        tau[i] = t;
        let fs = if CONFOCAL { brdf.eval_confocal(a, n) } else { brdf.eval(a, bb, n) };
        let q = cl * pl * cs * ps * inv_2n[i] / (ra2 * ra2 * rb2 * rb2);
        let val = w * vis[i] * fs * q;
        let gv = if ok { val } else { 0.0 };
        g[i] = gv;
        if TENT {
            let (p, frac, in_range) = tent.bin(t);
            let gt = if in_range { gv } else { 0.0 };
            idx[i] = p;
            w0[i] = gt * (1.0 - frac);
            w1[i] = gt * frac;
        }
    }
}

/// Adjoint, stage 1 of one sample per triangle: `ra[i] = |a|`, `rb[i] = |b|`, `ok[i]` = the pair is
/// oriented, visible in the cache and passes the cosine tests (1.0 or 0.0); with `TENT`, also the padded
/// bin index `idx[i]` and fraction `w0[i]` of the tent kernel, and `ok[i]` = 0 where no bin is in range.
#[inline(never)]
pub(crate) fn adjoint_lengths<const CONFOCAL: bool, const TENT: bool>(
    isa: Isa,
    b: &Block<'_>,
    fr: &Frame,
    uv: (f32, f32),
    tent: &TentAxis,
    sc: &mut Scratch,
) {
    dispatch!(isa, adjoint_lengths_body::<CONFOCAL, TENT>(b, fr, uv, tent, sc))
}

#[inline(always)]
fn adjoint_lengths_body<const CONFOCAL: bool, const TENT: bool>(
    b: &Block<'_>,
    fr: &Frame,
    (u, v): (f32, f32),
    tent: &TentAxis,
    sc: &mut Scratch,
) {
    let len = b.len;
    let (sign, vis, ra, rb, ok) =
        (&sc.sign[..len], &sc.vis[..len], &mut sc.tau[..len], &mut sc.g[..len], &mut sc.ok[..len]);
    let (idx, fr_) = (&mut sc.idx[..len], &mut sc.w0[..len]);
    let [v0, e1, e2, nn] = b.lanes();
    for i in 0..len {
        let x = at(&v0, i) + u * at(&e1, i) + v * at(&e2, i);
        let n = sign[i] * at(&nn, i);
        let PairGeom { a, b: bb, ok: pass, .. } = pair_geometry::<CONFOCAL>(x, n, fr, sign[i], vis[i]);
        let r = a.length_squared().sqrt();
        let r2 = if CONFOCAL { r } else { bb.length_squared().sqrt() };
        ra[i] = r;
        rb[i] = r2;
        if TENT {
            let (p, frac, in_range) = tent.bin(r + r2);
            idx[i] = p;
            fr_[i] = frac;
            ok[i] = f32::from(u8::from(pass & in_range));
        } else {
            ok[i] = f32::from(u8::from(pass));
        }
    }
}

/// Adjoint, stage 2 of the tent kernel: `a_val[i] = Σ_k a_k K_k(τ)` and `a_der[i] = Σ_k a_k dK_k/dτ` from the
/// padded adjoint row `adj` (bin k at k + 1, zeros at both ends), 0 where `ok[i] = 0`.
#[inline(never)]
pub(crate) fn tent_gather(isa: Isa, len: usize, adj: &[f32], inv_dt: f32, sc: &mut Scratch) {
    dispatch!(isa, tent_gather_body(len, adj, inv_dt, sc))
}

#[inline(always)]
fn tent_gather_body(len: usize, adj: &[f32], inv_dt: f32, sc: &mut Scratch) {
    let (idx, frac, ok) = (&sc.idx[..len], &sc.w0[..len], &sc.ok[..len]);
    let (a_val, a_der) = (&mut sc.a_val[..len], &mut sc.a_der[..len]);
    // p ≤ bins by construction and the row has bins + 2 entries; the `min` lets the compiler drop the bounds
    // checks (so the loop vectorises with gathers) and keeps it panic-free whatever the input.
    let last = adj.len().saturating_sub(2);
    if adj.len() < 2 {
        return;
    }
    for i in 0..len {
        let p = (idx[i] as usize).min(last);
        let a0 = adj[p];
        let a1 = adj[p + 1];
        let f = frac[i];
        a_val[i] = ok[i] * (a0 * (1.0 - f) + a1 * f);
        a_der[i] = ok[i] * ((a1 - a0) * inv_dt);
    }
}

/// Per-triangle adjoint accumulators of a task's triangles for one sample point (u, v), f32, flushed into f64 every
/// few measurements: `gx` = Σ dE/dx (distributed to the vertices as (1−u−v, u, v) at the flush),
/// `gn` = Σ sign·dE/dN, `p` = dE/d(BRDF parameters).
pub(crate) struct Acc {
    pub(crate) gx: [Vec<f32>; 3],
    pub(crate) gn: [Vec<f32>; 3],
    pub(crate) p: [Vec<f32>; 4],
    /// Splat: Σ dE/d(corner j) of the sub-triangle through its path length, coordinate c at `3j + c`
    /// (distributed to the vertices by the corners' barycentric coordinates at the flush).
    pub(crate) gc: [Vec<f32>; 9],
}

impl Acc {
    pub(crate) fn new(len: usize) -> Self {
        let z = || vec![0.0f32; len];
        Self {
            gx: [z(), z(), z()],
            gn: [z(), z(), z()],
            p: [z(), z(), z(), z()],
            gc: [z(), z(), z(), z(), z(), z(), z(), z(), z()],
        }
    }

    /// [`Acc::flush_packed`] of a splat sub-triangle: also adds the corner accumulators, corner j (barycentric
    /// `corners[j]`) to the three vertices with weights `(1 − u_j − v_j, u_j, v_j)`, and zeroes them.
    pub(crate) fn flush_splat(
        &mut self,
        centroid: (f32, f32),
        corners: [(f32, f32); 3],
        slots: &[u32],
        out: &mut [[f64; 12]],
        params: &mut [f64; 4],
    ) {
        self.flush_packed(centroid, slots, out, params);
        for (j, &(u, v)) in corners.iter().enumerate() {
            let bw = [f64::from(1.0 - u - v), f64::from(u), f64::from(v)];
            for (c, &t) in slots.iter().enumerate() {
                let o = &mut out[t as usize];
                for k in 0..3 {
                    let g = f64::from(self.gc[3 * j + k][c]);
                    o[k] += bw[0] * g;
                    o[3 + k] += bw[1] * g;
                    o[6 + k] += bw[2] * g;
                }
            }
        }
        let n = slots.len();
        for g in &mut self.gc {
            g[..n].fill(0.0);
        }
    }

    /// Adds the packed accumulators of sample point (u, v) into `out` and `params`, in f64, and zeroes them:
    /// entry `c` (of `slots.len()`) belongs to triangle `slots[c]` of `out`, which receives Σ (1−u−v) dE/dx,
    /// Σ u dE/dx, Σ v dE/dx and Σ sign·dE/dN (12 values). Triangles left out of the packing would add zeros,
    /// so the result has the same bits as a flush over the whole block.
    pub(crate) fn flush_packed(
        &mut self,
        (u, v): (f32, f32),
        slots: &[u32],
        out: &mut [[f64; 12]],
        params: &mut [f64; 4],
    ) {
        let bu = f64::from(1.0 - u - v);
        let (u, v) = (f64::from(u), f64::from(v));
        for (c, &t) in slots.iter().enumerate() {
            let o = &mut out[t as usize];
            for k in 0..3 {
                let gx = f64::from(self.gx[k][c]);
                o[k] += bu * gx;
                o[3 + k] += u * gx;
                o[6 + k] += v * gx;
                o[9 + k] += f64::from(self.gn[k][c]);
            }
            for (k, p) in params.iter_mut().enumerate() {
                *p += f64::from(self.p[k][c]);
            }
        }
        let n = slots.len();
        for g in self.gx.iter_mut().chain(&mut self.gn).chain(&mut self.p) {
            g[..n].fill(0.0);
        }
    }
}

/// Adjoint, stage 3 of one sample `(u, v, w)` per triangle: the gradient of `w·vis·f_s·Q` against
/// `(A_val, A_der)` (see the crate docs), accumulated into `acc` (index i for triangle i of `b`) where
/// `a_val[i]` or `a_der[i]` is non-zero (stage 2 zeroes both for skipped pairs and occluded samples).
#[inline(never)]
pub(crate) fn adjoint_samples<B: FittedBrdf, const CONFOCAL: bool, const SPLAT: bool>(
    isa: Isa,
    brdf: &B,
    b: &Block<'_>,
    fr: &Frame,
    uvw: (f32, f32, f32),
    sc: &mut Scratch,
    acc: &mut Acc,
) {
    let [gx0, gx1, gx2] = &mut acc.gx;
    let [gn0, gn1, gn2] = &mut acc.gn;
    let [p0, p1, p2, p3] = &mut acc.p;
    let mut hs = std::mem::take(&mut sc.hs);
    // Separate `&mut` arguments: the compiler knows the 11 output streams alias nothing, so the loop
    // vectorises without runtime overlap checks (`kernel!`).
    adjoint_samples_best::<B, CONFOCAL, SPLAT>(
        isa, brdf, b, fr, uvw, sc, gx0, gx1, gx2, gn0, gn1, gn2, p0, p1, p2, p3, &mut hs,
    );
    sc.hs = hs;
}

kernel! {
    fn adjoint_samples_body [<B: FittedBrdf, const CONFOCAL: bool, const SPLAT: bool>] [::<B, CONFOCAL, SPLAT>] (
        brdf: &B,
        b: &Block<'_>,
        fr: &Frame,
        uvw: (f32, f32, f32),
        sc: &Scratch,
        gx0: &mut [f32],
        gx1: &mut [f32],
        gx2: &mut [f32],
        gn0: &mut [f32],
        gn1: &mut [f32],
        gn2: &mut [f32],
        p0: &mut [f32],
        p1: &mut [f32],
        p2: &mut [f32],
        p3: &mut [f32],
        hs: &mut [f32],
    ) {
        let (u, v, w) = uvw;
        let len = b.len;
        let (ok, hs) = (&sc.ok[..len], &mut hs[..len]);
        let (sign, vis, ra_s, rb_s, a_val, a_der) =
            (&sc.sign[..len], &sc.vis[..len], &sc.tau[..len], &sc.g[..len], &sc.a_val[..len], &sc.a_der[..len]);
        let [v0, e1, e2, nn] = b.lanes();
        let (inv_2n, inv_n2) = (&b.inv_2n[..len], &b.inv_n2[..len]);
        let np = B::PARAM_NAMES.len().min(4);
        let (gx0, gx1, gx2, gn0, gn1, gn2) =
            (&mut gx0[..len], &mut gx1[..len], &mut gx2[..len], &mut gn0[..len], &mut gn1[..len], &mut gn2[..len]);
        let (p0, p1, p2, p3) = (&mut p0[..len], &mut p1[..len], &mut p2[..len], &mut p3[..len]);
        for i in 0..len {
            let (av, ad) = (a_val[i], a_der[i]);
            // Splat: the corner terms (stage 4) need the sample value even where A_val vanishes.
            let active = if SPLAT { ok[i] != 0.0 } else { (av != 0.0) | (ad != 0.0) };
            let x = at(&v0, i) + u * at(&e1, i) + v * at(&e2, i);
            let sg = sign[i];
            let n = sg * at(&nn, i);
            let a = fr.l - x;
            let cl = -fr.n_l.dot(a);
            let pl = n.dot(a);
            let (ra, rb) = (ra_s[i], rb_s[i]);
            let s = w * vis[i];
            // One division per pair: 1/|a|² (and 1/|b|²) from 1/(|a|²|b|²); 1/|a| = |a|/|a|².
            let (gx, gn, sp, df_p, sh) = if CONFOCAL {
                // b = a, c_s = c_l, p_s = p_l, n_s = n_l: dE/da + dE/db in one expression.
                let ra2 = a.length_squared();
                let inv_ra2 = 1.0 / ra2;
                let i4 = inv_ra2 * inv_ra2;
                let denom = inv_2n[i] * (i4 * i4);
                let clpl = cl * pl;
                let q = clpl * clpl * denom;
                let g = brdf.eval_grad_confocal(a, n);
                let fs = g.value;
                let h = fs * q;
                // ∂Q/∂a (= ∂Q/∂b): c_l p_l/(2|N| r⁸) (c_l N − p_l n_l) − 4 Q a/r².
                let dq_a = (clpl * denom) * (cl * n - pl * fr.n_l) - (4.0 * q * inv_ra2) * a;
                // ∂Q/∂N = c_l² (2 p_l a)/(2|N| r⁸) − Q N/|N|².
                let dq_n = (cl * cl * denom * 2.0 * pl) * a - (q * inv_n2[i]) * n;
                // g.d_omega is the total derivative along the shared direction (∂/∂a + ∂/∂b).
                let gab = s * (av * (2.0 * fs * dq_a + q * g.d_omega) + (2.0 * h * ad * (ra * inv_ra2)) * a);
                let gn = sg * (s * av * (fs * dq_n + q * g.d_n));
                (-gab, gn, s * av * q, B::param_grad_array(&g.d_params), s * h)
            } else {
                let bb = fr.s - x;
                let cs = -fr.n_s.dot(bb);
                let ps = n.dot(bb);
                let (ra2, rb2) = (a.length_squared(), bb.length_squared());
                let inv = 1.0 / (ra2 * rb2);
                let (inv_ra2, inv_rb2) = (rb2 * inv, ra2 * inv);
                let denom = inv_2n[i] * (inv * inv);
                let q = cl * pl * cs * ps * denom;
                let g = brdf.eval_grad(a, bb, n);
                let fs = g.value;
                let h = fs * q;
                let dq_a = (cs * ps * denom) * (cl * n - pl * fr.n_l) - (4.0 * q * inv_ra2) * a;
                let dq_b = (cl * pl * denom) * (cs * n - ps * fr.n_s) - (4.0 * q * inv_rb2) * bb;
                let dq_n = (cl * cs * denom) * (ps * a + pl * bb) - (q * inv_n2[i]) * n;
                // dE = A_val dh + h A_der dτ, dτ/da = a/|a|, dτ/db = b/|b|.
                let ga = s * (av * (fs * dq_a + q * g.d_omega_l) + (h * ad * (ra * inv_ra2)) * a);
                let gb = s * (av * (fs * dq_b + q * g.d_omega_s) + (h * ad * (rb * inv_rb2)) * bb);
                let gn = sg * (s * av * (fs * dq_n + q * g.d_n));
                (-(ga + gb), gn, s * av * q, B::param_grad_array(&g.d_params), s * h)
            };
            // x = v0 + u e1 + v e2 and a = l − x, b = s − x ⇒ dE/dx = −(ga + gb) (gx above).
            // A bit mask, not a branch or a select (which the compiler turns back into a conditional store that
            // blocks vectorisation): inactive lanes (possibly non-finite) add exactly +0.
            let mask = 0u32.wrapping_sub(u32::from(active));
            let pick = |z: f32| f32::from_bits(z.to_bits() & mask);
            if SPLAT {
                hs[i] = pick(sh);
            }
            gx0[i] += pick(gx.x);
            gx1[i] += pick(gx.y);
            gx2[i] += pick(gx.z);
            gn0[i] += pick(gn.x);
            gn1[i] += pick(gn.y);
            gn2[i] += pick(gn.z);
            p0[i] += pick(sp * df_p[0]);
            if np > 1 {
                p1[i] += pick(sp * df_p[1]);
            }
            if np > 2 {
                p2[i] += pick(sp * df_p[2]);
            }
            if np > 3 {
                p3[i] += pick(sp * df_p[3]);
            }
        }
    }
    best: adjoint_samples_best, avx2: adjoint_samples_avx2;
}
