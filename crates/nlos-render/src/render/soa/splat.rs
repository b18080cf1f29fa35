//! The block kernels of the splat rule: a sub-triangle's corner path lengths and the closed form's per-pair
//! constants, the bin weights and gathers of the short pairs, and the adjoint's corner terms, each over a
//! block of triangles at once.

use glam::Vec3;
use nlos_brdf::FittedBrdf;

use crate::kernel::TentAxis;
use crate::render::Isa;
use crate::render::soa::{Acc, Block, Frame, PairGeom, Scratch, at, pair_geometry};
use crate::render::splat::MAX_SPAN;

/// One splat sub-triangle of the triangles of a block: its three corners and centroid in barycentric
/// coordinates `(u, v)` (u along e1, v along e2) and its weight `w` (fraction of the triangle's area).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sub {
    pub(crate) corners: [(f32, f32); 3],
    pub(crate) centroid: (f32, f32),
    pub(crate) w: f32,
}

/// Path length of the point `(u, v)` of the triangle `(p0, e1, e2)` in node units, `(τ − t0)/Δ − ½`, and
/// `∂τ/∂x` there.
#[inline(always)]
fn corner<const CONFOCAL: bool>(
    p0: Vec3,
    e1: Vec3,
    e2: Vec3,
    fr: &Frame,
    (u, v): (f32, f32),
    tent: &TentAxis,
) -> (f32, Vec3) {
    let x = p0 + u * e1 + v * e2;
    let a = fr.l - x;
    let ra = a.length();
    let (tau, d) = if CONFOCAL {
        (ra + ra, a * (-2.0 / ra))
    } else {
        let bb = fr.s - x;
        let rb = bb.length();
        (ra + rb, -(a / ra + bb / rb))
    };
    ((tau - tent.t0) * tent.inv_dt - 0.5, d)
}

/// Forward, one splat sub-triangle per triangle of the block: `g[i]` = w × visibility × f_s × Q at the
/// centroid (0 where the pair or the centroid's cosine tests fail, as in [`forward_samples`]) and the corner
/// path lengths `kn[j][i]` in node units.
#[inline(never)]
pub(crate) fn splat_samples<B: FittedBrdf, const CONFOCAL: bool>(
    isa: Isa,
    brdf: &B,
    b: &Block<'_>,
    fr: &Frame,
    sub: &Sub,
    tent: &TentAxis,
    sc: &mut Scratch,
) {
    dispatch!(isa, splat_samples_body::<B, CONFOCAL>(brdf, b, fr, sub, tent, sc));
    prepare_lanes(isa, b.len, sc);
    short_lanes(isa, b.len, tent.box_kernel, sc);
}

/// The span the vector kernels run with over a block's pairs: the shortest of 4, 8 and `splat::MAX_SPAN`
/// bins that covers seven in eight of its valid pairs (else the longest). The kernels cost about one G
/// evaluation per pair and node; a pair left to the scalar loop costs several times that per bin it spans.
fn block_span(len: usize, sc: &Scratch) -> usize {
    let (c, ok) = (&sc.lanes.v[3][..len], &sc.lanes.v[9][..len]);
    // One pass (this runs per block, measurement and sub-triangle): valid pairs, and those within 4 and 8.
    let (mut valid, mut n4, mut n8) = (0u32, 0u32, 0u32);
    for (&c, &ok) in c.iter().zip(ok) {
        let v = ok != 0.0;
        valid += u32::from(v);
        n4 += u32::from(v & (c <= 3.0));
        n8 += u32::from(v & (c <= 7.0));
    }
    if n4 * 8 >= valid * 7 {
        4
    } else if n8 * 8 >= valid * 7 {
        8
    } else {
        MAX_SPAN
    }
}

/// The bin weights of the pairs that span at most `sc.span` bins (`splat::window_weights`, or
/// `splat::window_box_weights` for the box kernel) from `lanes` into `sw` and `short`, vectorised (separate
/// output arguments; eight weights per pass).
#[inline(never)]
fn short_lanes(isa: Isa, len: usize, box_kernel: bool, sc: &mut Scratch) {
    sc.span = block_span(len, sc);
    let lanes = &sc.lanes.v;
    let (lo, hi) = sc.sw.split_at_mut(8);
    let short = &mut sc.short;
    let (Some(lo), Some(hi)) = (split8(lo), split8(hi)) else { return };
    match (sc.span, box_kernel) {
        (4, false) => short_lanes_best::<4, 0, false>(isa, len, lanes, lo, short),
        (8, false) => short_lanes_best::<8, 0, false>(isa, len, lanes, lo, short),
        (_, false) => {
            short_lanes_best::<{ MAX_SPAN }, 0, false>(isa, len, lanes, lo, short);
            short_lanes_best::<{ MAX_SPAN }, 8, false>(isa, len, lanes, hi, short);
        }
        (4, true) => short_lanes_best::<4, 0, true>(isa, len, lanes, lo, short),
        (8, true) => short_lanes_best::<8, 0, true>(isa, len, lanes, lo, short),
        (_, true) => {
            short_lanes_best::<{ MAX_SPAN }, 0, true>(isa, len, lanes, lo, short);
            short_lanes_best::<{ MAX_SPAN }, 8, true>(isa, len, lanes, hi, short);
        }
    }
}

/// Eight streams of `w` as [`Lanes8`] (None when `w` does not hold eight).
fn split8(w: &mut [Vec<f32>]) -> Option<Lanes8<'_>> {
    let [w0, w1, w2, w3, w4, w5, w6, w7] = w else { return None };
    Some((&mut w0[..], &mut w1[..], &mut w2[..], &mut w3[..], &mut w4[..], &mut w5[..], &mut w6[..], &mut w7[..]))
}

/// Eight weight streams, passed as separate `&mut` (so the compiler knows they alias nothing).
type Lanes8<'a> = (
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
);

kernel! {
    /// Weights `OFF .. OFF + min(N, 8)` of every pair into `w` (the tent's, or the box's with `BOX`); with
    /// `OFF = 0`, `short` = 1.0 for the valid pairs spanning at most N bins.
    fn short_lanes_body [<const N: usize, const OFF: usize, const BOX: bool>] [::<N, OFF, BOX>] (
        len: usize,
        lanes: &[Vec<f32>; 10],
        w: Lanes8<'_>,
        short: &mut [f32],
    ) {
        let v: [&[f32]; 10] = std::array::from_fn(|k| &lanes[k][..len]);
        let (w0, w1, w2, w3, w4, w5, w6, w7) = w;
        let (w0, w1, w2, w3, short) = (&mut w0[..len], &mut w1[..len], &mut w2[..len], &mut w3[..len], &mut short[..len]);
        let (w4, w5, w6, w7) = if N > 4 {
            (&mut w4[..len], &mut w5[..len], &mut w6[..len], &mut w7[..len])
        } else {
            (&mut w4[..0], &mut w5[..0], &mut w6[..0], &mut w7[..0])
        };
        for i in 0..len {
            let p = [v[0][i], v[1][i], v[2][i], v[3][i], v[4][i], v[5][i], v[6][i], v[7][i], v[8][i], v[9][i]];
            let w = if BOX {
                crate::render::splat::window_box_weights::<OFF>(&p)
            } else {
                crate::render::splat::window_weights::<OFF>(&p)
            };
            (w0[i], w1[i], w2[i], w3[i]) = (w[0], w[1], w[2], w[3]);
            if N > 4 {
                (w4[i], w5[i], w6[i], w7[i]) = (w[4], w[5], w[6], w[7]);
            }
            if OFF == 0 {
                short[i] = f32::from(u8::from((p[9] != 0.0) & (p[3] <= (N - 1) as f32)));
            }
        }
    }
    best: short_lanes_best, avx2: short_lanes_avx2;
}

#[inline(always)]
fn splat_samples_body<B: FittedBrdf, const CONFOCAL: bool>(
    brdf: &B,
    b: &Block<'_>,
    fr: &Frame,
    sub: &Sub,
    tent: &TentAxis,
    sc: &mut Scratch,
) {
    let len = b.len;
    let (sign, vis, g) = (&sc.sign[..len], &sc.vis[..len], &mut sc.g[..len]);
    let [k0, k1, k2] = &mut sc.kn;
    let (k0, k1, k2) = (&mut k0[..len], &mut k1[..len], &mut k2[..len]);
    let [v0, e1, e2, nn] = b.lanes();
    let inv_2n = &b.inv_2n[..len];
    let (u, v) = sub.centroid;
    for i in 0..len {
        let (p0, d1, d2) = (at(&v0, i), at(&e1, i), at(&e2, i));
        let x = p0 + u * d1 + v * d2;
        let n = sign[i] * at(&nn, i);
        let PairGeom { a, b: bb, cl, pl, cs, ps, ok } = pair_geometry::<CONFOCAL>(x, n, fr, sign[i], vis[i]);
        let ra2 = a.length_squared();
        let rb2 = if CONFOCAL { ra2 } else { bb.length_squared() };
        let fs = if CONFOCAL { brdf.eval_confocal(a, n) } else { brdf.eval(a, bb, n) };
        let q = cl * pl * cs * ps * inv_2n[i] / (ra2 * ra2 * rb2 * rb2);
        let val = sub.w * vis[i] * fs * q;
        g[i] = if ok { val } else { 0.0 };
        let tc = if CONFOCAL { 2.0 * ra2.sqrt() } else { ra2.sqrt() + rb2.sqrt() };
        let (t0, t1, t2) = crate::render::splat::centred(
            corner::<CONFOCAL>(p0, d1, d2, fr, sub.corners[0], tent).0,
            corner::<CONFOCAL>(p0, d1, d2, fr, sub.corners[1], tent).0,
            corner::<CONFOCAL>(p0, d1, d2, fr, sub.corners[2], tent).0,
            (tc - tent.t0) * tent.inv_dt - 0.5,
            tc * tent.inv_dt,
            B::DISTANCE_POWER,
        );
        (k0[i], k1[i], k2[i]) = (t0, t1, t2);
    }
}

/// Adjoint, stage 1 of a splat sub-triangle per triangle: `|a|`, `|b|` and the cosine tests at the centroid
/// (as [`adjoint_lengths`] without a kernel), the corner path lengths `kn` (node units) and their gradients
/// `dir` with respect to the corner positions.
#[inline(never)]
pub(crate) fn splat_lengths<const CONFOCAL: bool>(
    isa: Isa,
    b: &Block<'_>,
    fr: &Frame,
    sub: &Sub,
    tent: &TentAxis,
    power: f32,
    sc: &mut Scratch,
) {
    let len = b.len;
    let (sign, vis, ra, rb, ok) =
        (&sc.sign[..len], &sc.vis[..len], &mut sc.tau[..len], &mut sc.g[..len], &mut sc.ok[..len]);
    let [k0, k1, k2] = &mut sc.kn;
    let [d0, d1, d2, d3, d4, d5, d6, d7, d8] = &mut sc.dir;
    let out = [ra, rb, ok, &mut k0[..len], &mut k1[..len], &mut k2[..len]];
    let dirs = [
        &mut d0[..len],
        &mut d1[..len],
        &mut d2[..len],
        &mut d3[..len],
        &mut d4[..len],
        &mut d5[..len],
        &mut d6[..len],
        &mut d7[..len],
        &mut d8[..len],
    ];
    // Separate `&mut` arguments (not captured by a closure, not an array indexed in the loop): the compiler
    // then knows the 15 output streams alias nothing, and vectorises the loop.
    let [ra, rb, ok, k0, k1, k2] = out;
    let [d0, d1, d2, d3, d4, d5, d6, d7, d8] = dirs;
    splat_lengths_best::<CONFOCAL>(
        isa, b, fr, sub, tent, power, sign, vis, ra, rb, ok, k0, k1, k2, d0, d1, d2, d3, d4, d5, d6, d7, d8,
    );
    prepare_lanes(isa, len, sc);
}

kernel! {
    fn splat_lengths_body [<const CONFOCAL: bool>] [::<CONFOCAL>] (
        b: &Block<'_>,
        fr: &Frame,
        sub: &Sub,
        tent: &TentAxis,
        power: f32,
        sign: &[f32],
        vis: &[f32],
        ra: &mut [f32],
        rb: &mut [f32],
        ok: &mut [f32],
        k0: &mut [f32],
        k1: &mut [f32],
        k2: &mut [f32],
        d0: &mut [f32],
        d1: &mut [f32],
        d2: &mut [f32],
        d3: &mut [f32],
        d4: &mut [f32],
        d5: &mut [f32],
        d6: &mut [f32],
        d7: &mut [f32],
        d8: &mut [f32],
    ) {
        let len = b.len;
        let (sign, vis, ra, rb, ok) = (&sign[..len], &vis[..len], &mut ra[..len], &mut rb[..len], &mut ok[..len]);
        let (k0, k1, k2) = (&mut k0[..len], &mut k1[..len], &mut k2[..len]);
        let (d0, d1, d2, d3, d4) = (&mut d0[..len], &mut d1[..len], &mut d2[..len], &mut d3[..len], &mut d4[..len]);
        let (d5, d6, d7, d8) = (&mut d5[..len], &mut d6[..len], &mut d7[..len], &mut d8[..len]);
        let [v0, e1, e2, nn] = b.lanes();
        let (u, v) = sub.centroid;
        for i in 0..len {
            let (p0, q1, q2) = (at(&v0, i), at(&e1, i), at(&e2, i));
            let x = p0 + u * q1 + v * q2;
            let n = sign[i] * at(&nn, i);
            let PairGeom { a, b: bb, ok: pass, .. } = pair_geometry::<CONFOCAL>(x, n, fr, sign[i], vis[i]);
            let r = a.length_squared().sqrt();
            let r2 = if CONFOCAL { r } else { bb.length_squared().sqrt() };
            ra[i] = r;
            rb[i] = r2;
            ok[i] = f32::from(u8::from(pass));
            let (t0, g0) = corner::<CONFOCAL>(p0, q1, q2, fr, sub.corners[0], tent);
            let (t1, g1) = corner::<CONFOCAL>(p0, q1, q2, fr, sub.corners[1], tent);
            let (t2, g2) = corner::<CONFOCAL>(p0, q1, q2, fr, sub.corners[2], tent);
            let tc = r + r2;
            let (t0, t1, t2) =
                crate::render::splat::centred(t0, t1, t2, (tc - tent.t0) * tent.inv_dt - 0.5, tc * tent.inv_dt, power);
            (k0[i], k1[i], k2[i]) = (t0, t1, t2);
            (d0[i], d1[i], d2[i]) = (g0.x, g0.y, g0.z);
            (d3[i], d4[i], d5[i]) = (g1.x, g1.y, g1.z);
            (d6[i], d7[i], d8[i]) = (g2.x, g2.y, g2.z);
        }
    }
    best: splat_lengths_best, avx2: splat_lengths_avx2;
}

/// The closed form's per-pair constants (`splat::prepare`) of the corner path lengths `kn` into `lanes`,
/// vectorised (3 input and 10 output streams as separate arguments).
#[inline(never)]
pub(crate) fn prepare_lanes(isa: Isa, len: usize, sc: &mut Scratch) {
    let [k0, k1, k2] = &sc.kn;
    let [l0, l1, l2, l3, l4, l5, l6, l7, l8, l9] = &mut sc.lanes.v;
    prepare_lanes_best(isa, len, k0, k1, k2, l0, l1, l2, l3, l4, l5, l6, l7, l8, l9);
}

kernel! {
    fn prepare_lanes_body [] [] (
        len: usize,
        k0: &[f32],
        k1: &[f32],
        k2: &[f32],
        l0: &mut [f32],
        l1: &mut [f32],
        l2: &mut [f32],
        l3: &mut [f32],
        l4: &mut [f32],
        l5: &mut [f32],
        l6: &mut [f32],
        l7: &mut [f32],
        l8: &mut [f32],
        l9: &mut [f32],
    ) {
        let (k0, k1, k2) = (&k0[..len], &k1[..len], &k2[..len]);
        let (l0, l1, l2, l3, l4) = (&mut l0[..len], &mut l1[..len], &mut l2[..len], &mut l3[..len], &mut l4[..len]);
        let (l5, l6, l7, l8, l9) = (&mut l5[..len], &mut l6[..len], &mut l7[..len], &mut l8[..len], &mut l9[..len]);
        for i in 0..len {
            let p = crate::render::splat::prepare(k0[i], k1[i], k2[i]);
            (l0[i], l1[i], l2[i], l3[i], l4[i]) = (p[0], p[1], p[2], p[3], p[4]);
            (l5[i], l6[i], l7[i], l8[i], l9[i]) = (p[5], p[6], p[7], p[8], p[9]);
        }
    }
    best: prepare_lanes_best, avx2: prepare_lanes_avx2;
}

/// Adjoint, stage 4 of a splat sub-triangle: the path-length terms `dE/d(corner j) = h_i · ct_j · ∂τ/∂x_j`
/// (h the sample value stage 3 left in `hs`, zero for inactive pairs), accumulated into `acc.gc`.
#[inline(never)]
pub(crate) fn splat_corner_terms(isa: Isa, len: usize, sc: &Scratch, acc: &mut Acc) {
    for j in 0..3 {
        let [gx, gy, gz] = &mut acc.gc[3 * j..3 * j + 3] else { return };
        let (dx, dy, dz) = (&sc.dir[3 * j][..len], &sc.dir[3 * j + 1][..len], &sc.dir[3 * j + 2][..len]);
        let (ct, hs) = (&sc.ct[j][..len], &sc.hs[..len]);
        dispatch!(isa, corner_terms_body(hs, ct, [dx, dy, dz], &mut gx[..len], &mut gy[..len], &mut gz[..len]));
    }
}

/// `g += hs · ct · d`, per component. The three outputs are separate `&mut` slices (they alias nothing,
/// so the loop vectorises); the read-only direction streams `d` may share one argument.
#[inline(always)]
fn corner_terms_body(hs: &[f32], ct: &[f32], d: [&[f32]; 3], gx: &mut [f32], gy: &mut [f32], gz: &mut [f32]) {
    let len = hs.len();
    let [dx, dy, dz] = d;
    let (ct, dx, dy, dz) = (&ct[..len], &dx[..len], &dy[..len], &dz[..len]);
    let (gx, gy, gz) = (&mut gx[..len], &mut gy[..len], &mut gz[..len]);
    for i in 0..len {
        let c = hs[i] * ct[i];
        gx[i] += c * dx[i];
        gy[i] += c * dy[i];
        gz[i] += c * dz[i];
    }
}

/// The adjoint's gathers of the pairs that span at most `sc.span` bins (`splat::gather_window`; the span
/// chosen as in the forward pass) against the padded adjoint row `adj` (bin k at k + 1): `sw[0..4]` =
/// `(Σ r w, Σ r ∂w/∂a, ∂/∂b, ∂/∂c)` and `short` = 1.0 for those pairs (inside the row), vectorised.
#[inline(never)]
pub(crate) fn short_gathers(isa: Isa, len: usize, adj: &[f32], sc: &mut Scratch) {
    sc.span = block_span(len, sc);
    let lanes = &sc.lanes.v;
    let [w0, w1, w2, w3, ..] = &mut sc.sw;
    let short = &mut sc.short;
    match sc.span {
        4 => short_gathers_best::<4, 0, 4>(isa, len, lanes, adj, w0, w1, w2, w3, short),
        8 => short_gathers_best::<8, 0, 8>(isa, len, lanes, adj, w0, w1, w2, w3, short),
        _ => {
            short_gathers_best::<{ MAX_SPAN }, 0, 8>(isa, len, lanes, adj, w0, w1, w2, w3, short);
            short_gathers_best::<{ MAX_SPAN }, 8, 8>(isa, len, lanes, adj, w0, w1, w2, w3, short);
        }
    }
}

kernel! {
    fn short_gathers_body [<const N: usize, const OFF: usize, const W: usize>] [::<N, OFF, W>] (
        len: usize,
        lanes: &[Vec<f32>; 10],
        adj: &[f32],
        w0: &mut [f32],
        w1: &mut [f32],
        w2: &mut [f32],
        w3: &mut [f32],
        short: &mut [f32],
    ) {
        const MAGIC: f32 = 12_582_912.0; // 1.5 · 2²³
        let v: [&[f32]; 10] = std::array::from_fn(|k| &lanes[k][..len]);
        let (w0, w1, w2, w3, short) = (&mut w0[..len], &mut w1[..len], &mut w2[..len], &mut w3[..len], &mut short[..len]);
        if adj.len() < N {
            short.fill(0.0);
            return;
        }
        // The padded index of bin k0 is k0 + 1; N bins from there must lie in the row.
        let top = (adj.len() - N) as f32;
        let last = adj.len() - N;
        for i in 0..len {
            let p = [v[0][i], v[1][i], v[2][i], v[3][i], v[4][i], v[5][i], v[6][i], v[7][i], v[8][i], v[9][i]];
            let s = (p[9] != 0.0) & (p[3] <= (N - 1) as f32);
            let pos = p[0] + 1.0;
            let inside = (pos >= 0.0) & (pos <= top);
            // An exact small integer read from the bits (no float → int cast, which does not vectorise).
            let q = (pos.max(0.0).min(top) + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits()) as usize;
            let q = q.min(last);
            let r = |m: usize| if m < N { adj[q + m] } else { 0.0 };
            let o = crate::render::splat::gather_window::<OFF, W>(&p, r);
            if OFF == 0 {
                (w0[i], w1[i], w2[i], w3[i]) = (o[0], o[1], o[2], o[3]);
            } else {
                (w0[i], w1[i], w2[i], w3[i]) = (w0[i] + o[0], w1[i] + o[1], w2[i] + o[2], w3[i] + o[3]);
            }
            short[i] = f32::from(u8::from(s & inside));
        }
    }
    best: short_gathers_best, avx2: short_gathers_avx2;
}

/// Adjoint, stage 2 of a splat sub-triangle, the pairs [`short_gathers`] gathered: their gathers split into
/// the centroid's and the corners' path-length terms (`splat::split_gather`) into `a_val`, `a_der` and `ct`,
/// vectorised; every other pair gets zeros (the scalar loop redoes the pairs longer than the span).
#[inline(never)]
pub(crate) fn split_short_gathers(isa: Isa, len: usize, inv_dt: f32, power: f32, sc: &mut Scratch) {
    let [k0, k1, k2] = &sc.kn;
    let [s0, s1, s2, s3, ..] = &sc.sw;
    let [c0, c1, c2] = &mut sc.ct;
    let (a_val, a_der) = (&mut sc.a_val, &mut sc.a_der);
    let (ok, short, ra, rb) = (&sc.ok, &sc.short, &sc.tau, &sc.g);
    split_short_best(
        isa,
        len,
        inv_dt,
        power,
        ok,
        short,
        [k0, k1, k2],
        [s0, s1, s2, s3],
        ra,
        rb,
        a_val,
        a_der,
        c0,
        c1,
        c2,
    );
}

kernel! {
    fn split_short_body [] [] (
        len: usize,
        inv_dt: f32,
        power: f32,
        ok: &[f32],
        short: &[f32],
        kn: [&Vec<f32>; 3],
        sw: [&Vec<f32>; 4],
        ra: &[f32],
        rb: &[f32],
        a_val: &mut [f32],
        a_der: &mut [f32],
        c0: &mut [f32],
        c1: &mut [f32],
        c2: &mut [f32],
    ) {
        let (ok, short, ra, rb) = (&ok[..len], &short[..len], &ra[..len], &rb[..len]);
        let (k0, k1, k2) = (&kn[0][..len], &kn[1][..len], &kn[2][..len]);
        let (s0, s1, s2, s3) = (&sw[0][..len], &sw[1][..len], &sw[2][..len], &sw[3][..len]);
        let (a_val, a_der) = (&mut a_val[..len], &mut a_der[..len]);
        let (c0, c1, c2) = (&mut c0[..len], &mut c1[..len], &mut c2[..len]);
        for i in 0..len {
            let gathered = (ok[i] != 0.0) & (short[i] != 0.0);
            let (val, d) = if gathered { (s0[i], [s1[i], s2[i], s3[i]]) } else { (0.0, [0.0; 3]) };
            let tc = (ra[i] + rb[i]) * inv_dt;
            let (der, ct) = crate::render::splat::split_gather([k0[i], k1[i], k2[i]], d, tc, inv_dt, power);
            a_val[i] = val;
            a_der[i] = der;
            (c0[i], c1[i], c2[i]) = (ct[0], ct[1], ct[2]);
        }
    }
    best: split_short_best, avx2: split_short_avx2;
}
