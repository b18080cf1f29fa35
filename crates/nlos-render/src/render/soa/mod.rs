//! Triangles as structure of arrays (one `f32` array per coordinate) and the block kernels of the fixed
//! deterministic rule: for one measurement and one sub-triangle centroid `(u, v)`, the same arithmetic as
//! the per-pair code of the renderer (`render/`; same operations in the same order, so the same bits) over a block of
//! triangles at once, written as straight-line loops over the block with selects instead of branches so
//! that the compiler vectorises them across triangles. The scalar parts (kernel scatter/gather, shadow rays)
//! run in separate passes over the block's buffers.

use glam::Vec3;

pub(crate) use crate::kernel::TentAxis;

/// Triangles per block of the tiled loops: a block's geometry (13 arrays), per-pair buffers and adjoint
/// accumulators (16 arrays) take about 40 KiB, so they stay in L1/L2 while the measurements stream past.
pub(crate) const BLOCK: usize = 256;

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

/// The geometry every block kernel starts from, for one pair at a point x with oriented normal N: `a = l − x`,
/// `b = s − x` (`b = a` for a confocal scan), the numerators of eq. (2)'s four cosines `c_l = −n_l·a`,
/// `p_l = N·a`, `c_s = −n_s·b`, `p_s = N·b`, and whether the pair reflects there (oriented, visible in the cache,
/// all four positive; NaN fails).
#[derive(Clone, Copy)]
pub(crate) struct PairGeom {
    pub(crate) a: Vec3,
    pub(crate) b: Vec3,
    pub(crate) cl: f32,
    pub(crate) pl: f32,
    pub(crate) cs: f32,
    pub(crate) ps: f32,
    pub(crate) ok: bool,
}

/// [`PairGeom`] of a pair (`sign`, `vis`: its orientation and cached visibility), branch-free for the vector
/// loops (`&`, not `&&`: a short-circuit branch in the loop body blocks vectorisation).
#[inline(always)]
pub(crate) fn pair_geometry<const CONFOCAL: bool>(x: Vec3, n: Vec3, fr: &Frame, sign: f32, vis: f32) -> PairGeom {
    let a = fr.l - x;
    let b = if CONFOCAL { a } else { fr.s - x };
    let cl = -fr.n_l.dot(a);
    let pl = n.dot(a);
    let (cs, ps) = if CONFOCAL { (cl, pl) } else { (-fr.n_s.dot(b), n.dot(b)) };
    let ok = (sign != 0.0) & (vis != 0.0) & (cl > 0.0) & (cs > 0.0) & (pl > 0.0) & (ps > 0.0);
    PairGeom { a, b, cl, pl, cs, ps, ok }
}

impl<'a> Block<'a> {
    /// The vertex, edge and normal lanes `(v0, e1, e2, N)`, each cut to the block's length (so the vector loops
    /// index them without bounds checks).
    #[inline(always)]
    pub(crate) fn lanes(&self) -> [[&'a [f32]; 3]; 4] {
        let len = self.len;
        let cut = |a: &[&'a [f32]; 3]| [&a[0][..len], &a[1][..len], &a[2][..len]];
        [cut(&self.v0), cut(&self.e1), cut(&self.e2), cut(&self.n)]
    }
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
    pub(crate) lanes: crate::render::splat::Lanes,
    /// Splat (forward): the bin weights of pairs spanning at most `span` bins (`splat::window_weights`); the
    /// adjoint's gathers in the first four (`splat::gather_window`). `short`: 1.0 for those pairs.
    pub(crate) sw: [Vec<f32>; crate::render::splat::MAX_SPAN],
    pub(crate) short: Vec<f32>,
    /// Splat: the pairs the scalar loops visit ([`Scratch::select`]), ascending.
    pub(crate) todo: Vec<u32>,
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
            lanes: crate::render::splat::Lanes::new(BLOCK),
            sw: std::array::from_fn(|_| z()),
            short: z(),
            todo: vec![0; BLOCK],
            span: 4,
        }
    }

    /// Collects into `todo` the pairs `0..len` for which `pick` holds, in order, without a branch per pair
    /// (the scalar loops then skip the others without mispredicted branches). Returns their number.
    #[inline(always)]
    pub(crate) fn select(&mut self, len: usize, pick: impl Fn(&Self, usize) -> bool) -> usize {
        let mut c = 0;
        for i in 0..len {
            let p = pick(self, i);
            self.todo[c] = i as u32;
            c += usize::from(p);
        }
        c
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

/// Defines a block kernel once: `$body` (the code, `#[inline(always)]`), `$avx2` (the same compiled for
/// AVX2 + FMA, where LLVM vectorises it 8 lanes wide) and `$best(isa, …)`, which runs `$avx2` when `isa`
/// says the CPU has the instructions and `$body` otherwise. Unlike [`dispatch!`] the arguments go through as
/// separate parameters, not captured by a closure: separate `&mut` slices tell the compiler that the output
/// streams alias nothing, so their loops vectorise without runtime overlap checks (captured by a closure,
/// LLVM left them scalar). Generics are given twice: as declared, and as the turbofish that names them.
macro_rules! kernel {
    (
        $(#[$attr:meta])*
        fn $body:ident [$($generics:tt)*] [$($turbofish:tt)*] ($($arg:ident : $ty:ty),* $(,)?) $code:block
        best: $best:ident, avx2: $avx2:ident;
    ) => {
        $(#[$attr])*
        #[inline(always)]
        #[allow(clippy::too_many_arguments)] // separate `&mut` parameters by design (the macro's docs)
        fn $body $($generics)* ($($arg: $ty),*) $code

        #[doc = concat!("[`", stringify!($body), "`] compiled for AVX2 + FMA.")]
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        #[allow(clippy::too_many_arguments)] // as `$body`
        fn $avx2 $($generics)* ($($arg: $ty),*) {
            $body $($turbofish)* ($($arg),*)
        }

        #[doc = concat!("[`", stringify!($body), "`], compiled for the best instruction set `isa` has.")]
        #[inline(always)]
        #[allow(clippy::too_many_arguments)] // as `$body`, and `isa`
        fn $best $($generics)* (isa: Isa, $($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            if isa.avx2 {
                // SAFETY: `Isa { avx2: true }` is only built by `Isa::detect` after
                // `is_x86_feature_detected!("avx2")` and `("fma")` both returned true on this CPU.
                #[allow(unsafe_code)]
                unsafe {
                    $avx2 $($turbofish)* ($($arg),*)
                };
                return;
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = isa;
            $body $($turbofish)* ($($arg),*)
        }
    };
}

/// [`orientation`] compiled for AVX2 + FMA when the CPU has them (the same bits).
#[inline(never)]
pub(crate) fn orientation_dispatch(isa: Isa, b: &Block<'_>, fr: &Frame, two_sided: bool, sign: &mut [f32]) {
    dispatch!(isa, orientation(b, fr, two_sided, sign))
}

mod point;
mod splat;
pub(crate) use point::{Acc, adjoint_lengths, adjoint_samples, forward_samples, tent_gather};
pub(crate) use splat::{Sub, short_gathers, splat_corner_terms, splat_lengths, splat_samples, split_short_gathers};
