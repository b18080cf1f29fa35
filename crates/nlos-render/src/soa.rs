//! Triangles as structure of arrays (one `f32` array per coordinate) and the block kernels of the fixed
//! deterministic rule: for one measurement and one sub-triangle centroid `(u, v)`, the same arithmetic as
//! the per-pair code of `render.rs` (same operations in the same order, so the same bits) over a block of
//! triangles at once, written as straight-line loops over the block with selects instead of branches so
//! that the compiler vectorises them across triangles. The scalar parts (kernel scatter/gather, shadow rays)
//! run in separate passes over the block's buffers.

use glam::Vec3;

use crate::brdf::RenderBrdf;

/// Triangles per block of the tiled loops: a block's geometry (13 arrays), per-pair buffers and adjoint
/// accumulators (16 arrays) take about 40 KiB, so they stay in L1/L2 while the measurements stream past.
pub(crate) const BLOCK: usize = 256;

use crate::splat::MAX_SPAN;

/// Triangle geometry, structure of arrays.
#[derive(Debug, Clone, Default)]
pub(crate) struct Soa {
    v0: [Vec<f32>; 3],
    e1: [Vec<f32>; 3],
    e2: [Vec<f32>; 3],
    /// Unnormalised geometric normal `e1 × e2`.
    n: [Vec<f32>; 3],
    /// `0.5/|N|` (0 for degenerate triangles, which `valid` excludes anyway).
    inv_2n: Vec<f32>,
    /// `1/|N|²` (0 for degenerate triangles).
    inv_n2: Vec<f32>,
    valid: Vec<bool>,
    /// `order[slot]`: the mesh triangle stored at `slot`.
    pub(crate) order: Vec<u32>,
    /// Per block of `BLOCK` slots: bounds for culling whole blocks that face away from a wall spot.
    bounds: Vec<BlockBound>,
    /// Culling and packing off (tests that they change no bit): every valid triangle is packed.
    pub(crate) no_cull: bool,
}

/// Conservative bounds of a block of triangles: componentwise range `[lo, hi]` of the unit normals and the
/// smallest plane offset `n̂·v0` of its valid triangles.
#[derive(Debug, Clone, Copy, Default)]
struct BlockBound {
    lo: Vec3,
    hi: Vec3,
    d_min: f32,
}

impl BlockBound {
    /// An upper bound of `n̂·p − n̂·v0` (signed distance of p in front of the plane) over the block.
    #[inline(always)]
    fn max_front(&self, p: Vec3) -> f32 {
        (self.lo * p).max(self.hi * p).element_sum() - self.d_min
    }
}

/// Margin (m) of the block culling test: far above the f32 rounding of the bounds (~1e-6 m at the scale of
/// metres), so a culled block never holds a pair that the exact per-triangle test would keep.
const CULL_MARGIN: f32 = 1e-3;

/// Bucket of a normal direction: a `res × res` grid on its octahedral map (0 for a zero or non-finite
/// normal).
fn normal_bucket(n: Vec3, res: u32) -> u32 {
    let l1 = n.x.abs() + n.y.abs() + n.z.abs();
    // Guard: degenerate normals (skipped triangles) share bucket 0.
    if !(l1 > 0.0 && l1.is_finite()) {
        return 0;
    }
    let (mut x, mut y) = (n.x / l1, n.y / l1);
    if n.z < 0.0 {
        (x, y) = ((1.0 - y.abs()).copysign(x), (1.0 - x.abs()).copysign(y));
    }
    let cell = |c: f32| (((c + 1.0) * 0.5 * res as f32) as u32).min(res - 1);
    cell(x) * res + cell(y)
}

impl Soa {
    /// Stores the triangles grouped by normal direction (stable: mesh order within a group), so that most
    /// blocks face a wall spot either all toward or all away: whole blocks are then skipped at once.
    ///
    /// `keep_order`: the storage order to reuse (the visibility cache is stored in it), None to regroup.
    pub(crate) fn new(
        v0: &[Vec3],
        e1: &[Vec3],
        e2: &[Vec3],
        n: &[Vec3],
        valid: &[bool],
        keep_order: Option<Vec<u32>>,
    ) -> Self {
        let order = match keep_order {
            Some(o) if o.len() == v0.len() => o,
            _ => {
                // About two blocks per bucket: finer groups would scatter the mesh order (spatial locality of
                // the histogram accesses), coarser ones would mix orientations within a block.
                let res = ((v0.len() as f64 / (2 * BLOCK) as f64).sqrt() as u32).clamp(1, 16);
                let mut order: Vec<u32> = (0..v0.len() as u32).collect();
                order.sort_by_key(|&t| normal_bucket(n[t as usize], res));
                order
            }
        };
        let gather = |a: &[Vec3]| order.iter().map(|&t| a[t as usize]).collect::<Vec<_>>();
        let (v0, e1, e2, n) = (gather(v0), gather(e1), gather(e2), gather(n));
        let valid: Vec<bool> = order.iter().map(|&t| valid[t as usize]).collect();
        let split = |a: &[Vec3]| {
            [a.iter().map(|p| p.x).collect(), a.iter().map(|p| p.y).collect(), a.iter().map(|p| p.z).collect()]
        };
        let (v0, e1, e2, n, valid) = (&v0[..], &e1[..], &e2[..], &n[..], &valid[..]);
        let bounds = (0..v0.len())
            .step_by(BLOCK)
            .map(|t0| {
                let t1 = (t0 + BLOCK).min(v0.len());
                let mut b = BlockBound { lo: Vec3::INFINITY, hi: Vec3::NEG_INFINITY, d_min: f32::INFINITY };
                for t in (t0..t1).filter(|t| valid[*t]) {
                    let u = n[t] / n[t].length();
                    b.lo = b.lo.min(u);
                    b.hi = b.hi.max(u);
                    b.d_min = b.d_min.min(u.dot(v0[t]));
                }
                // Guard: a block without a valid triangle (or with a non-finite bound) is never active: a
                // bound that always culls.
                if !(b.lo.is_finite() && b.hi.is_finite() && b.d_min.is_finite()) {
                    b = BlockBound { lo: Vec3::ZERO, hi: Vec3::ZERO, d_min: 1e30 };
                }
                b
            })
            .collect();
        Self {
            bounds,
            v0: split(v0),
            e1: split(e1),
            e2: split(e2),
            n: split(n),
            // Same expressions as the per-pair code: 0.5 / n.length() and 1 / n.length_squared().
            inv_2n: n.iter().zip(valid).map(|(n, ok)| if *ok { 0.5 / n.length() } else { 0.0 }).collect(),
            inv_n2: n.iter().zip(valid).map(|(n, ok)| if *ok { 1.0 / n.length_squared() } else { 0.0 }).collect(),
            valid: valid.to_vec(),
            order,
            no_cull: false,
        }
    }

    /// Whether every triangle of the block starting at slot `t0` (a multiple of `BLOCK`) certainly faces
    /// away from l or from s, so that no pair of it reflects (one-sided faces only).
    #[inline(always)]
    pub(crate) fn culled(&self, t0: usize, fr: &Frame) -> bool {
        let b = &self.bounds[t0 / BLOCK];
        b.max_front(fr.l) < -CULL_MARGIN || b.max_front(fr.s) < -CULL_MARGIN
    }

    /// Turns the block culling off (bounds that never cull) and the packing of front-facing triangles (every
    /// valid triangle packed), for tests that they change nothing.
    #[cfg(test)]
    pub(crate) fn disable_culling(&mut self) {
        self.no_cull = true;
        for b in &mut self.bounds {
            *b = BlockBound { lo: Vec3::splat(-1e30), hi: Vec3::splat(1e30), d_min: -1e30 };
        }
    }

    /// The triangles `t0..t1`.
    pub(crate) fn block(&self, t0: usize, t1: usize) -> Block<'_> {
        fn s3(a: &[Vec<f32>; 3], t0: usize, t1: usize) -> [&[f32]; 3] {
            [&a[0][t0..t1], &a[1][t0..t1], &a[2][t0..t1]]
        }
        Block {
            len: t1 - t0,
            v0: s3(&self.v0, t0, t1),
            e1: s3(&self.e1, t0, t1),
            e2: s3(&self.e2, t0, t1),
            n: s3(&self.n, t0, t1),
            inv_2n: &self.inv_2n[t0..t1],
            inv_n2: &self.inv_n2[t0..t1],
            valid: &self.valid[t0..t1],
        }
    }
}

/// A block of triangles (every slice `len` long).
#[derive(Clone, Copy)]
pub(crate) struct Block<'a> {
    pub(crate) len: usize,
    v0: [&'a [f32]; 3],
    e1: [&'a [f32]; 3],
    e2: [&'a [f32]; 3],
    n: [&'a [f32]; 3],
    inv_2n: &'a [f32],
    inv_n2: &'a [f32],
    valid: &'a [bool],
}

#[inline(always)]
fn at(a: &[&[f32]; 3], i: usize) -> Vec3 {
    Vec3::new(a[0][i], a[1][i], a[2][i])
}

impl Block<'_> {
    /// `x(u, v) = v0 + u e1 + v e2` of triangle `i` (the expression of `Renderer::point`).
    #[inline(always)]
    pub(crate) fn point(&self, i: usize, u: f32, v: f32) -> Vec3 {
        at(&self.v0, i) + u * at(&self.e1, i) + v * at(&self.e2, i)
    }
}

/// The triangles of one block that may reflect for some measurement of a group, gathered contiguously (in
/// slot order) so that the block kernels run over them only. On the bunny at Tsai et al. 2019's setup about half of
/// a block's triangles face away from any given spot although the block as a whole does not
/// ([`Soa::culled`] fails); the vector loops, the orientation test and the kernel scatter/gather then did
/// twice the necessary work. A group is a few consecutive measurements (a forward tile, an adjoint flush
/// group) whose spots are close together, so the union of their front-facing sets is barely larger than one.
pub(crate) struct Packed {
    v0: [Vec<f32>; 3],
    e1: [Vec<f32>; 3],
    e2: [Vec<f32>; 3],
    n: [Vec<f32>; 3],
    inv_2n: Vec<f32>,
    inv_n2: Vec<f32>,
    /// All true (only valid triangles are packed); the kernels' `Block` needs the slice.
    valid: Vec<bool>,
    /// `slots[c]`: the block-local slot of packed triangle c (ascending).
    pub(crate) slots: Vec<u32>,
    /// Number of packed triangles.
    pub(crate) len: usize,
    /// Per slot of the block: whether it is packed (1) or not (0).
    keep: Vec<u8>,
}

/// Componentwise bounding box `(lo, hi)` of a set of wall spots.
pub(crate) type SpotBox = (Vec3, Vec3);

impl Packed {
    pub(crate) fn new() -> Self {
        let z = || vec![0.0f32; BLOCK];
        Self {
            v0: [z(), z(), z()],
            e1: [z(), z(), z()],
            e2: [z(), z(), z()],
            n: [z(), z(), z()],
            inv_2n: z(),
            inv_n2: z(),
            valid: vec![true; BLOCK],
            slots: vec![0; BLOCK],
            len: 0,
            keep: vec![0; BLOCK],
        }
    }

    /// Packs the valid triangles of `b` that may face a laser spot of the box `l` and a sensor spot of the
    /// box `s` (all valid triangles when `two_sided`). A superset of the triangles that
    /// [`orientation`] gives a non-zero sign for any spot pair of the group: `N·(p − v0)` is linear in p,
    /// so its maximum over the box is `N·(c − v0) + |N|·h` (centre c, half extent h, |N| componentwise).
    /// Returns the number of packed triangles.
    pub(crate) fn pack(&mut self, b: &Block<'_>, l: SpotBox, s: SpotBox, two_sided: bool) -> usize {
        let len = b.len;
        let (cl, hl) = ((l.0 + l.1) * 0.5, (l.1 - l.0) * 0.5);
        let (cs, hs) = ((s.0 + s.1) * 0.5, (s.1 - s.0) * 0.5);
        let keep = &mut self.keep[..len];
        for (i, k) in keep.iter_mut().enumerate() {
            let (nv, p) = (at(&b.n, i), at(&b.v0, i));
            let na = nv.abs();
            let dl = nv.dot(cl - p) + na.dot(hl);
            let ds = nv.dot(cs - p) + na.dot(hs);
            // Guard: a margin of 1 mm (times |N|₁ ≥ |N|, since N is unnormalised) absorbs the f32 rounding of
            // the bound (~1e-7 relative), so a triangle the exact per-measurement test keeps is never dropped.
            let margin = 1e-3 * na.element_sum();
            let front = (dl > -margin) & (ds > -margin);
            *k = u8::from(b.valid[i] & (two_sided | front));
        }
        // Branch-free compaction: every slot is written, the count advances only for kept ones.
        let mut c = 0usize;
        for (i, k) in self.keep[..len].iter().enumerate() {
            self.slots[c] = i as u32;
            c += usize::from(*k);
        }
        self.len = c;
        let slots = &self.slots[..c];
        let copy = |dst: &mut Vec<f32>, src: &[f32]| {
            for (d, &t) in dst[..c].iter_mut().zip(slots) {
                *d = src[t as usize];
            }
        };
        for k in 0..3 {
            copy(&mut self.v0[k], b.v0[k]);
            copy(&mut self.e1[k], b.e1[k]);
            copy(&mut self.e2[k], b.e2[k]);
            copy(&mut self.n[k], b.n[k]);
        }
        copy(&mut self.inv_2n, b.inv_2n);
        copy(&mut self.inv_n2, b.inv_n2);
        c
    }

    /// The packed triangles as a block (`len` of them).
    pub(crate) fn block(&self) -> Block<'_> {
        let c = self.len;
        fn s3(a: &[Vec<f32>; 3], c: usize) -> [&[f32]; 3] {
            [&a[0][..c], &a[1][..c], &a[2][..c]]
        }
        Block {
            len: c,
            v0: s3(&self.v0, c),
            e1: s3(&self.e1, c),
            e2: s3(&self.e2, c),
            n: s3(&self.n, c),
            inv_2n: &self.inv_2n[..c],
            inv_n2: &self.inv_n2[..c],
            valid: &self.valid[..c],
        }
    }
}

/// One measurement's wall geometry.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    pub(crate) l: Vec3,
    pub(crate) n_l: Vec3,
    pub(crate) s: Vec3,
    pub(crate) n_s: Vec3,
}

/// Per-pair orientation of a block: `sign[i]` = +1 when l and s are both in front of triangle i, −1 when
/// both behind and `two_sided`, else 0 (also for degenerate triangles). Exact for the whole face:
/// `N·(l − x)` does not depend on x in the plane.
#[inline(always)]
pub(crate) fn orientation(b: &Block<'_>, fr: &Frame, two_sided: bool, sign: &mut [f32]) {
    let len = b.len;
    let sign = &mut sign[..len];
    let (v0, n, valid) = (
        [&b.v0[0][..len], &b.v0[1][..len], &b.v0[2][..len]],
        [&b.n[0][..len], &b.n[1][..len], &b.n[2][..len]],
        &b.valid[..len],
    );
    for i in 0..len {
        let (nv, p) = (at(&n, i), at(&v0, i));
        let (dl, ds) = (nv.dot(fr.l - p), nv.dot(fr.s - p));
        let s = if dl > 0.0 && ds > 0.0 {
            1.0
        } else if two_sided && dl < 0.0 && ds < 0.0 {
            -1.0
        } else {
            0.0
        };
        sign[i] = if valid[i] { s } else { 0.0 };
    }
}

/// Scratch buffers of one block (one set per task).
pub(crate) struct Scratch {
    /// Orientation sign per pair (0 = skipped).
    pub(crate) sign: Vec<f32>,
    /// Cached visible fraction per pair (1 without a cache).
    pub(crate) vis: Vec<f32>,
    /// Path length τ per pair (forward), `|a|` (adjoint).
    pub(crate) tau: Vec<f32>,
    /// Weighted sample value (forward), `|b|` (adjoint).
    pub(crate) g: Vec<f32>,
    /// `Σ_k a_k K_k(τ)` per pair (adjoint; 0 when the pair is inactive).
    pub(crate) a_val: Vec<f32>,
    /// `Σ_k a_k dK_k/dτ` per pair (adjoint).
    pub(crate) a_der: Vec<f32>,
    /// Whether the sample passed the cosine tests (1.0 or 0.0: a float store keeps the loop vectorised).
    pub(crate) ok: Vec<f32>,
    /// Tent fast path: index of the lower bin in the padded histogram / adjoint row (bin k at k + 1).
    pub(crate) idx: Vec<u32>,
    /// Tent fast path: weight of the lower bin (forward: times the sample value), or the fraction (adjoint).
    pub(crate) w0: Vec<f32>,
    /// Tent fast path: weight of the upper bin times the sample value (forward).
    pub(crate) w1: Vec<f32>,
    /// Splat: the sub-triangle's corner path lengths in node units (`(τ − t0)/Δ − ½`), corner order.
    pub(crate) kn: [Vec<f32>; 3],
    /// Splat (adjoint): `∂τ/∂(corner j)` = `−(a_j/|a_j| + b_j/|b_j|)`, coordinate c at index `3j + c`.
    pub(crate) dir: [Vec<f32>; 9],
    /// Splat (adjoint): `Σ_k r_k ∂w_k/∂τ_j` per corner j (per metre of path).
    pub(crate) ct: [Vec<f32>; 3],
    /// Splat (adjoint): the sample value `w·vis·f_s·Q` of active pairs (stage 3 writes it, stage 4 reads it).
    pub(crate) hs: Vec<f32>,
    /// Splat: the per-pair constants of the closed form (`splat::prepare`).
    pub(crate) lanes: crate::splat::Lanes,
    /// Splat (forward): the bin weights of pairs spanning at most `span` bins (`splat::window_weights`); the
    /// adjoint's gathers in the first four (`splat::gather_window`). `short`: 1.0 for those pairs.
    pub(crate) sw: [Vec<f32>; crate::splat::MAX_SPAN],
    pub(crate) short: Vec<f32>,
    /// The span (4, 8 or `splat::MAX_SPAN` bins) the vector kernels ran with for this block ([`block_span`]).
    pub(crate) span: usize,
}

impl Scratch {
    pub(crate) fn new() -> Self {
        let z = || vec![0.0f32; BLOCK];
        Self {
            sign: z(),
            vis: z(),
            tau: z(),
            g: z(),
            a_val: z(),
            a_der: z(),
            ok: z(),
            idx: vec![0; BLOCK],
            w0: z(),
            w1: z(),
            kn: [z(), z(), z()],
            dir: [z(), z(), z(), z(), z(), z(), z(), z(), z()],
            ct: [z(), z(), z()],
            hs: z(),
            lanes: crate::splat::Lanes::new(BLOCK),
            sw: std::array::from_fn(|_| z()),
            short: z(),
            span: 4,
        }
    }
}

/// The instruction set the block kernels run with: baseline x86-64 (SSE2, 4 lanes), or AVX2 + FMA (8 lanes)
/// when the CPU has them. A value with `avx2 = true` exists only after a positive runtime check
/// ([`Isa::detect`]), which is what makes the `unsafe` calls of the `target_feature` kernels sound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Isa {
    avx2: bool,
}

impl Isa {
    /// The best instruction set of this CPU.
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            Self { avx2: std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            Self { avx2: false }
        }
    }

    /// Baseline instructions only (for tests of the dispatch).
    #[cfg(test)]
    pub(crate) fn baseline() -> Self {
        Self { avx2: false }
    }
}

/// Runs `$body` (a call of an `#[inline(always)]` kernel body) compiled for AVX2 + FMA when `$isa` says the
/// CPU has them, else for the baseline. The body is instantiated twice: inside a `#[target_feature]` function
/// (where LLVM vectorises it 8 lanes wide) and in place.
macro_rules! dispatch {
    ($isa:expr, $body:expr) => {{
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx2,fma")]
            #[inline]
            fn avx2<R>(f: impl FnOnce() -> R) -> R {
                f()
            }
            if $isa.avx2 {
                // SAFETY: `Isa { avx2: true }` is only built by `Isa::detect` after
                // `is_x86_feature_detected!("avx2")` and `("fma")` both returned true on this CPU.
                #[allow(unsafe_code)]
                let r = unsafe { avx2(|| $body) };
                r
            } else {
                $body
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            $body
        }
    }};
}

/// [`orientation`] compiled for AVX2 + FMA when the CPU has them (the same bits).
#[inline(never)]
pub(crate) fn orientation_dispatch(isa: Isa, b: &Block<'_>, fr: &Frame, two_sided: bool, sign: &mut [f32]) {
    dispatch!(isa, orientation(b, fr, two_sided, sign))
}

/// The tent kernel's bin arithmetic in the block kernels (the same expressions as `KernelEval::weights`):
/// `c = (τ − t0)/Δ − ½`, lower bin `k0 = ⌊c⌋`, weights `1 − (c − k0)` and `c − k0`. Histograms and adjoint
/// rows are padded by one zero bin at each end (bin k at index k + 1), so a pair whose lower bin is in
/// `−1..bins` needs no bounds logic; other pairs have no bin in range and get weight 0.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TentAxis {
    pub(crate) t0: f32,
    pub(crate) inv_dt: f32,
    /// `bins − 1`, the largest valid lower bin.
    pub(crate) last: f32,
}

impl TentAxis {
    /// `(padded index of the lower bin, fraction c − k0, whether any bin is in range)`. Branch-free and free
    /// of float → int conversions (Rust's saturating casts do not vectorise): c is clamped to
    /// `[−2, bins]` (NaN → −2, out of range), rounded with the 1.5·2²³ trick (exact round-to-nearest for
    /// |c| < 2²², no fast-math here), stepped down to the floor, and the integer read from the bits.
    #[inline(always)]
    fn bin(&self, tau: f32) -> (u32, f32, bool) {
        const MAGIC: f32 = 12_582_912.0; // 1.5 · 2²³: ulp 1 over [2²³, 2²⁴)
        let c = ((tau - self.t0) * self.inv_dt - 0.5).max(-2.0).min(self.last + 1.0);
        let r = (c + MAGIC) - MAGIC;
        let kf = if r > c { r - 1.0 } else { r };
        let frac = c - kf;
        let in_range = (kf >= -1.0) & (kf <= self.last);
        // kf + 1 ∈ [−1, bins + 1] is an integer: MAGIC + it has it in the low mantissa bits.
        let p = (kf.max(-1.0).min(self.last) + 1.0 + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits());
        (p, frac, in_range)
    }
}

/// Forward, one sample `(u, v, w)` per triangle of the block: `tau[i]` and `g[i]` = weight × visibility ×
/// f_s × Q (0 where the pair or the sample is skipped); with `TENT`, also the tent kernel's padded bin index
/// `idx[i]` and the two weighted bin contributions `w0[i]`, `w1[i]` (0 out of range). `CONFOCAL`: `s = l`
/// (`b = a`, one square root).
#[inline(never)]
pub(crate) fn forward_samples<B: RenderBrdf, const CONFOCAL: bool, const TENT: bool>(
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
fn forward_samples_body<B: RenderBrdf, const CONFOCAL: bool, const TENT: bool>(
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
    let v0 = [&b.v0[0][..len], &b.v0[1][..len], &b.v0[2][..len]];
    let e1 = [&b.e1[0][..len], &b.e1[1][..len], &b.e1[2][..len]];
    let e2 = [&b.e2[0][..len], &b.e2[1][..len], &b.e2[2][..len]];
    let nn = [&b.n[0][..len], &b.n[1][..len], &b.n[2][..len]];
    let inv_2n = &b.inv_2n[..len];
    for i in 0..len {
        let x = at(&v0, i) + u * at(&e1, i) + v * at(&e2, i);
        let n = sign[i] * at(&nn, i);
        let a = fr.l - x;
        let bb = if CONFOCAL { a } else { fr.s - x };
        let cl = -fr.n_l.dot(a);
        let pl = n.dot(a);
        let (cs, ps) = if CONFOCAL { (cl, pl) } else { (-fr.n_s.dot(bb), n.dot(bb)) };
        // One-sided wall and surface cosines (max(0, ·) of eq. 2); NaN fails too; `&`, not `&&`: no
        // short-circuit branches in the loop body.
        let ok = (sign[i] != 0.0) & (vis[i] != 0.0) & (cl > 0.0) & (cs > 0.0) & (pl > 0.0) & (ps > 0.0);
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
    let v0 = [&b.v0[0][..len], &b.v0[1][..len], &b.v0[2][..len]];
    let e1 = [&b.e1[0][..len], &b.e1[1][..len], &b.e1[2][..len]];
    let e2 = [&b.e2[0][..len], &b.e2[1][..len], &b.e2[2][..len]];
    let nn = [&b.n[0][..len], &b.n[1][..len], &b.n[2][..len]];
    for i in 0..len {
        let x = at(&v0, i) + u * at(&e1, i) + v * at(&e2, i);
        let n = sign[i] * at(&nn, i);
        let a = fr.l - x;
        let bb = if CONFOCAL { a } else { fr.s - x };
        let cl = -fr.n_l.dot(a);
        let pl = n.dot(a);
        let (cs, ps) = if CONFOCAL { (cl, pl) } else { (-fr.n_s.dot(bb), n.dot(bb)) };
        // `&`, not `&&`: no short-circuit branches in the loop body (they block vectorisation).
        let pass = (sign[i] != 0.0) & (vis[i] != 0.0) & (cl > 0.0) & (cs > 0.0) & (pl > 0.0) & (ps > 0.0);
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
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn adjoint_samples<B: RenderBrdf, const CONFOCAL: bool, const SPLAT: bool>(
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
    let g = [&mut gx0[..], &mut gx1[..], &mut gx2[..], &mut gn0[..], &mut gn1[..], &mut gn2[..]];
    let p = [&mut p0[..], &mut p1[..], &mut p2[..], &mut p3[..]];
    let mut hs = std::mem::take(&mut sc.hs);
    adjoint_samples_acc::<B, CONFOCAL, SPLAT>(isa, brdf, b, fr, uvw, sc, g, p, &mut hs);
    sc.hs = hs;
}

#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn adjoint_samples_acc<B: RenderBrdf, const CONFOCAL: bool, const SPLAT: bool>(
    isa: Isa,
    brdf: &B,
    b: &Block<'_>,
    fr: &Frame,
    uvw: (f32, f32, f32),
    sc: &Scratch,
    [gx0, gx1, gx2, gn0, gn1, gn2]: [&mut [f32]; 6],
    [p0, p1, p2, p3]: [&mut [f32]; 4],
    hs: &mut [f32],
) {
    // Separate `&mut` arguments: the compiler knows the 10 accumulator streams alias nothing, so the loop
    // vectorises without runtime overlap checks. (Not through `dispatch!`: slices captured by a closure lose
    // that knowledge, and LLVM then leaves the loop scalar.)
    #[cfg(target_arch = "x86_64")]
    if isa.avx2 {
        // SAFETY: `Isa { avx2: true }` is only built by `Isa::detect` after `is_x86_feature_detected!("avx2")`
        // and `("fma")` both returned true on this CPU.
        #[allow(unsafe_code)]
        unsafe {
            adjoint_samples_avx2::<B, CONFOCAL, SPLAT>(
                brdf, b, fr, uvw, sc, gx0, gx1, gx2, gn0, gn1, gn2, p0, p1, p2, p3, hs,
            )
        };
        return;
    }
    adjoint_samples_body::<B, CONFOCAL, SPLAT>(brdf, b, fr, uvw, sc, gx0, gx1, gx2, gn0, gn1, gn2, p0, p1, p2, p3, hs)
}

/// [`adjoint_samples_body`] compiled for AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn adjoint_samples_avx2<B: RenderBrdf, const CONFOCAL: bool, const SPLAT: bool>(
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
    adjoint_samples_body::<B, CONFOCAL, SPLAT>(brdf, b, fr, uvw, sc, gx0, gx1, gx2, gn0, gn1, gn2, p0, p1, p2, p3, hs)
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn adjoint_samples_body<B: RenderBrdf, const CONFOCAL: bool, const SPLAT: bool>(
    brdf: &B,
    b: &Block<'_>,
    fr: &Frame,
    (u, v, w): (f32, f32, f32),
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
    let len = b.len;
    let (ok, hs) = (&sc.ok[..len], &mut hs[..len]);
    let (sign, vis, ra_s, rb_s, a_val, a_der) =
        (&sc.sign[..len], &sc.vis[..len], &sc.tau[..len], &sc.g[..len], &sc.a_val[..len], &sc.a_der[..len]);
    let v0 = [&b.v0[0][..len], &b.v0[1][..len], &b.v0[2][..len]];
    let e1 = [&b.e1[0][..len], &b.e1[1][..len], &b.e1[2][..len]];
    let e2 = [&b.e2[0][..len], &b.e2[1][..len], &b.e2[2][..len]];
    let nn = [&b.n[0][..len], &b.n[1][..len], &b.n[2][..len]];
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
pub(crate) fn splat_samples<B: RenderBrdf, const CONFOCAL: bool>(
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
    short_lanes(isa, b.len, sc);
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

/// The bin weights of the pairs that span at most `sc.span` bins (`splat::window_weights`) from `lanes`
/// into `sw` and `short`, vectorised (separate output arguments; eight weights per pass).
#[inline(never)]
fn short_lanes(isa: Isa, len: usize, sc: &mut Scratch) {
    sc.span = block_span(len, sc);
    let lanes = &sc.lanes.v;
    let (lo, hi) = sc.sw.split_at_mut(8);
    let short = &mut sc.short;
    let (Some(lo), Some(hi)) = (split8(lo), split8(hi)) else { return };
    match sc.span {
        4 => short_lanes_dispatch::<4, 0>(isa, len, lanes, lo, short),
        8 => short_lanes_dispatch::<8, 0>(isa, len, lanes, lo, short),
        _ => {
            short_lanes_dispatch::<{ crate::splat::MAX_SPAN }, 0>(isa, len, lanes, lo, short);
            short_lanes_dispatch::<{ crate::splat::MAX_SPAN }, 8>(isa, len, lanes, hi, short);
        }
    }
}

/// Eight streams of `w` as [`Lanes8`] (None when `w` does not hold eight).
fn split8(w: &mut [Vec<f32>]) -> Option<Lanes8<'_>> {
    let [w0, w1, w2, w3, w4, w5, w6, w7] = w else { return None };
    Some((&mut w0[..], &mut w1[..], &mut w2[..], &mut w3[..], &mut w4[..], &mut w5[..], &mut w6[..], &mut w7[..]))
}

fn short_lanes_dispatch<const N: usize, const OFF: usize>(
    isa: Isa,
    len: usize,
    lanes: &[Vec<f32>; 10],
    w: Lanes8<'_>,
    short: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if isa.avx2 {
        // SAFETY: as in `splat_lengths`.
        #[allow(unsafe_code)]
        unsafe {
            short_lanes_avx2::<N, OFF>(len, lanes, w, short);
        }
        return;
    }
    short_lanes_body::<N, OFF>(len, lanes, w, short);
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

/// [`short_lanes_body`] compiled for AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn short_lanes_avx2<const N: usize, const OFF: usize>(
    len: usize,
    lanes: &[Vec<f32>; 10],
    w: Lanes8<'_>,
    short: &mut [f32],
) {
    let (w0, w1, w2, w3, w4, w5, w6, w7) = w;
    short_lanes_body::<N, OFF>(len, lanes, (w0, w1, w2, w3, w4, w5, w6, w7), short);
}

/// Weights `OFF .. OFF + min(N, 8)` of every pair into `w`; with `OFF = 0`, `short` = 1.0 for the valid
/// pairs spanning at most N bins.
#[inline(always)]
fn short_lanes_body<const N: usize, const OFF: usize>(
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
        let w = crate::splat::window_weights::<OFF>(&p);
        (w0[i], w1[i], w2[i], w3[i]) = (w[0], w[1], w[2], w[3]);
        if N > 4 {
            (w4[i], w5[i], w6[i], w7[i]) = (w[4], w[5], w[6], w[7]);
        }
        if OFF == 0 {
            short[i] = f32::from(u8::from((p[9] != 0.0) & (p[3] <= (N - 1) as f32)));
        }
    }
}

#[inline(always)]
fn splat_samples_body<B: RenderBrdf, const CONFOCAL: bool>(
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
    let nn = [&b.n[0][..len], &b.n[1][..len], &b.n[2][..len]];
    let v0 = [&b.v0[0][..len], &b.v0[1][..len], &b.v0[2][..len]];
    let e1 = [&b.e1[0][..len], &b.e1[1][..len], &b.e1[2][..len]];
    let e2 = [&b.e2[0][..len], &b.e2[1][..len], &b.e2[2][..len]];
    let inv_2n = &b.inv_2n[..len];
    let (u, v) = sub.centroid;
    for i in 0..len {
        let (p0, d1, d2) = (at(&v0, i), at(&e1, i), at(&e2, i));
        let x = p0 + u * d1 + v * d2;
        let n = sign[i] * at(&nn, i);
        let a = fr.l - x;
        let bb = if CONFOCAL { a } else { fr.s - x };
        let cl = -fr.n_l.dot(a);
        let pl = n.dot(a);
        let (cs, ps) = if CONFOCAL { (cl, pl) } else { (-fr.n_s.dot(bb), n.dot(bb)) };
        let ok = (sign[i] != 0.0) & (vis[i] != 0.0) & (cl > 0.0) & (cs > 0.0) & (pl > 0.0) & (ps > 0.0);
        let ra2 = a.length_squared();
        let rb2 = if CONFOCAL { ra2 } else { bb.length_squared() };
        let fs = if CONFOCAL { brdf.eval_confocal(a, n) } else { brdf.eval(a, bb, n) };
        let q = cl * pl * cs * ps * inv_2n[i] / (ra2 * ra2 * rb2 * rb2);
        let val = sub.w * vis[i] * fs * q;
        g[i] = if ok { val } else { 0.0 };
        let tc = if CONFOCAL { 2.0 * ra2.sqrt() } else { ra2.sqrt() + rb2.sqrt() };
        let (t0, t1, t2) = crate::splat::centred(
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
#[allow(clippy::too_many_arguments)]
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
    #[cfg(target_arch = "x86_64")]
    if isa.avx2 {
        // SAFETY: `Isa { avx2: true }` is only built by `Isa::detect` after `is_x86_feature_detected!("avx2")`
        // and `("fma")` both returned true on this CPU.
        #[allow(unsafe_code)]
        unsafe {
            splat_lengths_avx2::<CONFOCAL>(
                b, fr, sub, tent, power, sign, vis, ra, rb, ok, k0, k1, k2, d0, d1, d2, d3, d4, d5, d6, d7, d8,
            );
        }
        prepare_lanes(isa, len, sc);
        return;
    }
    splat_lengths_body::<CONFOCAL>(
        b, fr, sub, tent, power, sign, vis, ra, rb, ok, k0, k1, k2, d0, d1, d2, d3, d4, d5, d6, d7, d8,
    );
    prepare_lanes(isa, len, sc);
}

/// [`splat_lengths_body`] compiled for AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn splat_lengths_avx2<const CONFOCAL: bool>(
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
    splat_lengths_body::<CONFOCAL>(
        b, fr, sub, tent, power, sign, vis, ra, rb, ok, k0, k1, k2, d0, d1, d2, d3, d4, d5, d6, d7, d8,
    );
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn splat_lengths_body<const CONFOCAL: bool>(
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
    let nn = [&b.n[0][..len], &b.n[1][..len], &b.n[2][..len]];
    let v0 = [&b.v0[0][..len], &b.v0[1][..len], &b.v0[2][..len]];
    let e1 = [&b.e1[0][..len], &b.e1[1][..len], &b.e1[2][..len]];
    let e2 = [&b.e2[0][..len], &b.e2[1][..len], &b.e2[2][..len]];
    let (u, v) = sub.centroid;
    for i in 0..len {
        let (p0, q1, q2) = (at(&v0, i), at(&e1, i), at(&e2, i));
        let x = p0 + u * q1 + v * q2;
        let n = sign[i] * at(&nn, i);
        let a = fr.l - x;
        let bb = if CONFOCAL { a } else { fr.s - x };
        let cl = -fr.n_l.dot(a);
        let pl = n.dot(a);
        let (cs, ps) = if CONFOCAL { (cl, pl) } else { (-fr.n_s.dot(bb), n.dot(bb)) };
        let pass = (sign[i] != 0.0) & (vis[i] != 0.0) & (cl > 0.0) & (cs > 0.0) & (pl > 0.0) & (ps > 0.0);
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
            crate::splat::centred(t0, t1, t2, (tc - tent.t0) * tent.inv_dt - 0.5, tc * tent.inv_dt, power);
        (k0[i], k1[i], k2[i]) = (t0, t1, t2);
        (d0[i], d1[i], d2[i]) = (g0.x, g0.y, g0.z);
        (d3[i], d4[i], d5[i]) = (g1.x, g1.y, g1.z);
        (d6[i], d7[i], d8[i]) = (g2.x, g2.y, g2.z);
    }
}

/// The closed form's per-pair constants (`splat::prepare`) of the corner path lengths `kn` into `lanes`,
/// vectorised (3 input and 10 output streams as separate arguments).
#[inline(never)]
pub(crate) fn prepare_lanes(isa: Isa, len: usize, sc: &mut Scratch) {
    let [k0, k1, k2] = &sc.kn;
    let [l0, l1, l2, l3, l4, l5, l6, l7, l8, l9] = &mut sc.lanes.v;
    #[cfg(target_arch = "x86_64")]
    if isa.avx2 {
        // SAFETY: as in `splat_lengths`.
        #[allow(unsafe_code)]
        unsafe {
            prepare_lanes_avx2(len, k0, k1, k2, l0, l1, l2, l3, l4, l5, l6, l7, l8, l9);
        }
        return;
    }
    prepare_lanes_body(len, k0, k1, k2, l0, l1, l2, l3, l4, l5, l6, l7, l8, l9);
}

/// [`prepare_lanes_body`] compiled for AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn prepare_lanes_avx2(
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
    prepare_lanes_body(len, k0, k1, k2, l0, l1, l2, l3, l4, l5, l6, l7, l8, l9);
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn prepare_lanes_body(
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
        let p = crate::splat::prepare(k0[i], k1[i], k2[i]);
        (l0[i], l1[i], l2[i], l3[i], l4[i]) = (p[0], p[1], p[2], p[3], p[4]);
        (l5[i], l6[i], l7[i], l8[i], l9[i]) = (p[5], p[6], p[7], p[8], p[9]);
    }
}

/// Adjoint, stage 4 of a splat sub-triangle: the path-length terms `dE/d(corner j) = h_i · ct_j · ∂τ/∂x_j`
/// (h the sample value stage 3 left in `hs`, zero for inactive pairs), accumulated into `acc.gc`.
#[inline(never)]
pub(crate) fn splat_corner_terms(isa: Isa, len: usize, sc: &Scratch, acc: &mut Acc) {
    for j in 0..3 {
        let [gx, gy, gz] = &mut acc.gc[3 * j..3 * j + 3] else { return };
        let (dx, dy, dz) = (&sc.dir[3 * j][..len], &sc.dir[3 * j + 1][..len], &sc.dir[3 * j + 2][..len]);
        let (ct, hs) = (&sc.ct[j][..len], &sc.hs[..len]);
        dispatch!(isa, corner_terms_body(hs, ct, dx, dy, dz, &mut gx[..len], &mut gy[..len], &mut gz[..len]));
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn corner_terms_body(
    hs: &[f32],
    ct: &[f32],
    dx: &[f32],
    dy: &[f32],
    dz: &[f32],
    gx: &mut [f32],
    gy: &mut [f32],
    gz: &mut [f32],
) {
    let len = hs.len();
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
    #[cfg(target_arch = "x86_64")]
    if isa.avx2 {
        // SAFETY: as in `splat_lengths`.
        #[allow(unsafe_code)]
        unsafe {
            match sc.span {
                4 => short_gathers_avx2::<4, 0, 4>(len, lanes, adj, w0, w1, w2, w3, short),
                8 => short_gathers_avx2::<8, 0, 8>(len, lanes, adj, w0, w1, w2, w3, short),
                _ => {
                    short_gathers_avx2::<{ MAX_SPAN }, 0, 8>(len, lanes, adj, w0, w1, w2, w3, short);
                    short_gathers_avx2::<{ MAX_SPAN }, 8, 8>(len, lanes, adj, w0, w1, w2, w3, short);
                }
            }
        }
        return;
    }
    match sc.span {
        4 => short_gathers_body::<4, 0, 4>(len, lanes, adj, w0, w1, w2, w3, short),
        8 => short_gathers_body::<8, 0, 8>(len, lanes, adj, w0, w1, w2, w3, short),
        _ => {
            short_gathers_body::<{ MAX_SPAN }, 0, 8>(len, lanes, adj, w0, w1, w2, w3, short);
            short_gathers_body::<{ MAX_SPAN }, 8, 8>(len, lanes, adj, w0, w1, w2, w3, short);
        }
    }
}

/// [`short_gathers_body`] compiled for AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn short_gathers_avx2<const N: usize, const OFF: usize, const W: usize>(
    len: usize,
    lanes: &[Vec<f32>; 10],
    adj: &[f32],
    w0: &mut [f32],
    w1: &mut [f32],
    w2: &mut [f32],
    w3: &mut [f32],
    short: &mut [f32],
) {
    short_gathers_body::<N, OFF, W>(len, lanes, adj, w0, w1, w2, w3, short);
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn short_gathers_body<const N: usize, const OFF: usize, const W: usize>(
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
        let o = crate::splat::gather_window::<OFF, W>(&p, r);
        if OFF == 0 {
            (w0[i], w1[i], w2[i], w3[i]) = (o[0], o[1], o[2], o[3]);
        } else {
            (w0[i], w1[i], w2[i], w3[i]) = (w0[i] + o[0], w1[i] + o[1], w2[i] + o[2], w3[i] + o[3]);
        }
        short[i] = f32::from(u8::from(s & inside));
    }
}
