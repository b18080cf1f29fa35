//! Closed-form time integration of a triangle against the tent kernel (the "splat" of [`crate::Sampling::Splat`]).
//!
//! Over a (sub-)triangle whose path length τ is linear — the three corner values `τ_0, τ_1, τ_2`, τ(x) =
//! Σ λ_i τ_i with λ the barycentric coordinates, uniformly distributed over the triangle — the area
//! density of τ is the linear B-spline with knots `a ≤ b ≤ c` (the sorted corner values; Curry &
//! Schoenberg 1966): it rises linearly from `a` to `b` and falls linearly to `c`, with unit integral. With
//! the integrand `h` taken at the centroid, the triangle adds `A h̄ w_k` to bin k, where
//! ```text
//! w_k = ∫ p(u) T_k(u) du,    T_k(u) = max(0, 1 − |u − k|)          (the tent kernel, Kernel::Tent)
//! ```
//! in **node units** `u = (τ − t0)/Δ − ½` (bin centres at the integers). Since `T_k'' = δ_{k−1} − 2δ_k +
//! δ_{k+1}`, two integrations by parts give
//! ```text
//! w_k = G(k − 1) − 2 G(k) + G(k + 1),    G(u) = E[(u − S)₊] = ∫_{−∞}^{u} F,     S ~ p,
//! ```
//! and G is a piecewise cubic in closed form (the `node` function). Σ_k w_k = 1 (the second differences
//! telescope to G'(∞) = 1) and w_k ≠ 0 only for `⌊a⌋ ≤ k ≤ ⌈c⌉`: a pair costs about (c − a) + 2 bins
//! instead of the n² samples a point rule needs to resolve the same span. The derivatives `∂G/∂a`,
//! `∂G/∂b`, `∂G/∂c` are closed form too (translation invariance: their sum is `−F(u)`), so the adjoint
//! gets the exact derivative of the splat with respect to each corner's path length.
//!
//! **The box kernel** (eq. 3 of Tsai et al. 2019; what `nlos render` simulates, a bin holding the integral
//! over `[t0 + kΔ, t0 + (k+1)Δ)`) is the first difference of the same density's CDF instead of the second
//! difference of its integral: in **bin units** `u = (τ − t0)/Δ` (the node units of an axis half a bin earlier,
//! `KernelEval::box_axis`),
//! ```text
//! w_k = ∫_k^{k+1} p = F(k + 1) − F(k),    F(u) = G'(u) = P(S ≤ u),
//! ```
//! F piecewise quadratic (`(u − a)²/(l1 d)` on (a, b], `(l1 + 2t − t²/l2)/d` with `t = u − b` on (b, c], 1
//! beyond), non-zero only for `⌊a⌋ ≤ k ≤ ⌊c⌋`. Forward only: the optimiser's passes take the tent, whose
//! weights are smooth in the corners.
//!
//! The only approximations are τ's departure from linear over the triangle (τ is convex: its Hessian has
//! norm ≤ 1/|x − l| + 1/|x − s|; the renderer bounds the departure and subdivides, see
//! [`crate::SplatRule`]) and h taken at the centroid (second order, as for the centroid rule).

/// `⌊x⌋` for finite |x| < 2⁶³ without a libm call (baseline x86-64 has no rounding instruction): truncate,
/// then step down for negative non-integers (the expression of `KernelEval::weights`).
#[inline(always)]
fn floor(x: f32) -> f32 {
    let tr = x as i64 as f32;
    if tr > x { tr - 1.0 } else { tr }
}

/// Lanes of per-pair splat constants, filled by the vector kernels ([`prepare`]) and read by the scalar
/// loops ([`Knots::lane`]): structure of arrays, one entry per packed triangle.
pub(crate) struct Lanes {
    /// `⌊a⌋` (as f32, exact), the shifted sorted values `a − ⌊a⌋ ≤ b − ⌊a⌋ ≤ c − ⌊a⌋`, `l1 = b − a`,
    /// `1/(c − a)`, `1/(3 l1 (c − a))`, `1/(c − b)`, the mean, and 1.0 where the fast path applies (finite
    /// values within ±2²² nodes), else 0.
    pub(crate) v: [Vec<f32>; 10],
}

impl Lanes {
    pub(crate) fn new(len: usize) -> Self {
        Self { v: std::array::from_fn(|_| vec![0.0f32; len]) }
    }
}

/// The splat constants of one pair from its three corner values (node units), branch-free (for the vector
/// kernels): the entries of [`Lanes`].
#[inline(always)]
pub(crate) fn prepare(u0: f32, u1: f32, u2: f32) -> [f32; 10] {
    const MAGIC: f32 = 12_582_912.0; // 1.5 · 2²³: exact rounding to an integer for |x| < 2²²
    const LIMIT: f32 = 4_194_304.0; // 2²²
    let lo = u0.min(u1).min(u2);
    let hi = u0.max(u1).max(u2);
    // The median of three: max(min(u0, u1), min(max(u0, u1), u2)).
    let mid = u0.min(u1).max(u0.max(u1).min(u2));
    let ok = (lo > -LIMIT) & (hi < LIMIT);
    let x = if ok { lo } else { 0.0 };
    let r = (x + MAGIC) - MAGIC;
    let k0 = if r > x { r - 1.0 } else { r };
    let (a, b, c) = (lo - k0, mid - k0, hi - k0);
    let (l1, l2, d) = (b - a, c - b, c - a);
    let inv_d = if d > 0.0 { 1.0 / d } else { 0.0 };
    let c2 = if l1 > 0.0 { inv_d / (3.0 * l1) } else { 0.0 };
    let inv_l2 = if l2 > 0.0 { 1.0 / l2 } else { 0.0 };
    [k0, a, b, c, l1, inv_d, c2, inv_l2, (a + b + c) * (1.0 / 3.0), f32::from(u8::from(ok))]
}

/// The corner values `u0, u1, u2` (node units) shifted by one `s` for the two first-order effects the
/// linear, uniformly weighted splat misses; `uc` is the centroid's value and `tc = τ_c/Δ` its path length
/// in bins.
/// - **Curvature.** τ is convex, so its linear interpolant lies above it. For a quadratic τ the triangle's
///   mean is `E[τ] = (τ_0 + τ_1 + τ_2)/12 + ¾ τ_c` (the uniform triangle's covariance is
///   `(1/12) Σ (v_i − c)(v_i − c)ᵀ`), against the splat's `(τ_0 + τ_1 + τ_2)/3`: shift by
///   `¾ (u_c − (u0 + u1 + u2)/3)`. Without it every face arrives late by about three quarters of its
///   curvature departure: on 8 mm faces at 0.4 m with 1.2 mm bins, about 0.05 bins and a 1 % bin-level
///   error against the exact quadrature.
/// - **Fall-off.** The integrand is taken at the centroid, but its distance factor `1/(|a|²|b|²)` (= 16/τ⁴
///   for a confocal pair, a function of τ alone) falls across the face by 4 Δτ/τ (±4 % on those faces),
///   weighting the early part of each face's profile more than the late part. To first order a density
///   tilted by `1 − β (τ − τ_c)` is the density shifted by `−β Var(τ)`; with `β = 4/τ_c` and the splat's
///   variance `Var = ((u0 − u1)² + (u1 − u2)² + (u0 − u2)²)/36`, shift by `−4 Var/t_c`. The 4 is `power`,
///   the BRDF's [`nlos_brdf::FittedBrdf::DISTANCE_POWER`]: 2 for a retroreflector, whose value grows as
///   `|a||b|` and leaves a `1/τ²` falloff.
///
/// [`centred_grad`] gives the derivatives.
#[inline(always)]
pub(crate) fn centred(u0: f32, u1: f32, u2: f32, uc: f32, tc: f32, power: f32) -> (f32, f32, f32) {
    let var = ((u0 - u1) * (u0 - u1) + (u1 - u2) * (u1 - u2) + (u0 - u2) * (u0 - u2)) * (1.0 / 36.0);
    let s = 0.75 * (uc - (u0 + u1 + u2) * (1.0 / 3.0)) - power * var / tc;
    (u0 + s, u1 + s, u2 + s)
}

/// The derivatives of [`centred`]'s shift s: `(∂s/∂u_j, ∂s/∂t_c)` where the centroid enters through both
/// `u_c` and `t_c` (∂u_c = ∂t_c: both are τ_c/Δ up to a constant). `u` may be the shifted values (the
/// variance does not see a common shift).
#[inline(always)]
pub(crate) fn centred_grad(u: [f32; 3], tc: f32, power: f32) -> ([f32; 3], f32) {
    let sum = u[0] + u[1] + u[2];
    let var =
        ((u[0] - u[1]) * (u[0] - u[1]) + (u[1] - u[2]) * (u[1] - u[2]) + (u[0] - u[2]) * (u[0] - u[2])) * (1.0 / 36.0);
    let k = power / tc;
    (u.map(|x| -0.25 - k * (3.0 * x - sum) * (1.0 / 18.0)), 0.75 + k * var / tc)
}

/// The spans (in bins) the vector kernels' branch-free weights and gathers ([`window_weights`],
/// [`short_gather`]) run with, chosen per block as its pairs need: 4 for fine faces, 8 (a 3 mm face at 0.4 m
/// spans up to 6 bins of 1.2 mm) and `MAX_SPAN` (an 8 mm face up to 15). Longer pairs go through [`Knots`].
pub(crate) const MAX_SPAN: usize = 16;

/// G at the shifted node u from a pair's [`prepare`] constants, branch-free (the three pieces of G selected).
#[inline(always)]
pub(crate) fn g_lane(p: &[f32; 10], u: f32) -> f32 {
    let [_, a, b, c, l1, inv_d, c2, inv_l2, mean, _] = *p;
    let d = u - a;
    let g2 = d * d * d * c2;
    let t = u - b;
    let g3 = (l1 * l1 * (1.0 / 3.0) + l1 * t + t * t * (1.0 - t * inv_l2 * (1.0 / 3.0))) * inv_d;
    if u <= b {
        g2
    } else if u <= c {
        g3
    } else {
        u - mean
    }
}

/// F = G' (the CDF of the pair's path-length density) at the shifted bin edge u from a pair's [`prepare`]
/// constants, branch-free: 0 up to a, `(u − a)²/(l1 d)` on (a, b], `(l1 + 2t − t²/l2)/d` on (b, c], 1 beyond.
#[inline(always)]
pub(crate) fn f_lane(p: &[f32; 10], u: f32) -> f32 {
    let [_, a, b, c, l1, inv_d, c2, inv_l2, _, _] = *p;
    let d = u - a;
    let f2 = d * d * (3.0 * c2);
    let t = u - b;
    let f3 = (l1 + 2.0 * t - t * t * inv_l2) * inv_d;
    if u <= a {
        0.0
    } else if u <= b {
        f2
    } else if u <= c {
        f3
    } else {
        1.0
    }
}

/// Eight box weights of a pair in bin units, `w_m = F(m + 1) − F(m)` for `m = OFF .. OFF + 8` (bins
/// `k0 + m`), branch-free for the vector kernels (the box counterpart of [`window_weights`]; F = 0 at
/// shifted edges ≤ 0). A pair whose largest shifted corner value is c < N has all its weight in `m < N`.
#[inline(always)]
pub(crate) fn window_box_weights<const OFF: usize>(p: &[f32; 10]) -> [f32; 8] {
    let f: [f32; 9] = std::array::from_fn(|j| if OFF + j == 0 { 0.0 } else { f_lane(p, (OFF + j) as f32) });
    std::array::from_fn(|m| f[m + 1] - f[m])
}

/// `(G, ∂G/∂a, ∂G/∂b, ∂G/∂c)` at the shifted node u ≥ 1 > a, branch-free (as [`Knots::g_grad2`],
/// [`Knots::g_grad3`] and the linear tail).
#[inline(always)]
fn g_grad_lane(p: &[f32; 10], u: f32) -> [f32; 4] {
    const THIRD: f32 = -1.0 / 3.0;
    let [_, a, b, c, l1, inv_d, c2, inv_l2, mean, _] = *p;
    let d = u - a;
    let f2 = d * d * (3.0 * c2);
    let g2 = f2 * d * (1.0 / 3.0);
    let (gb2, gc2) = (-g2 * (3.0 * c2 * (c - a)), -g2 * inv_d);
    let t = u - b;
    let rho = t * inv_l2;
    let n3 = l1 * l1 * (1.0 / 3.0) + l1 * t + t * t - t * t * rho * (1.0 / 3.0);
    let g3 = n3 * inv_d;
    let f3 = (l1 + 2.0 * t - t * rho) * inv_d;
    let gc3 = (t * rho * rho * (1.0 / 3.0) - g3) * inv_d;
    let ga3 = (g3 - (2.0 / 3.0) * l1 - t) * inv_d;
    if u <= b {
        [g2, -f2 - gb2 - gc2, gb2, gc2]
    } else if u <= c {
        [g3, ga3, -f3 - ga3 - gc3, gc3]
    } else {
        [u - mean, THIRD, THIRD, THIRD]
    }
}

/// Eight of the bin weights of a pair, `w_m` for `m = OFF .. OFF + 8` (bins `k0 + m`), branch-free from its
/// [`prepare`] constants `p`, for the vector kernels: `w_m = G(m − 1) − 2 G(m) + G(m + 1)` with G at the
/// shifted nodes, which vanishes at nodes ≤ 0 (a ≥ 0 after the shift). A pair spanning at most N bins (its
/// largest shifted corner value c ≤ N − 1) has all its weight in `m < N`.
#[inline(always)]
pub(crate) fn window_weights<const OFF: usize>(p: &[f32; 10]) -> [f32; 8] {
    // G at the nodes OFF − 1 ..= OFF + 8.
    let g: [f32; 10] = std::array::from_fn(|j| if OFF + j < 2 { 0.0 } else { g_lane(p, (OFF + j) as f32 - 1.0) });
    std::array::from_fn(|m| g[m] - 2.0 * g[m + 1] + g[m + 2])
}

/// The bin weights of a pair that spans at most N bins (N = 4 or 8; the first N of [`window_weights`]) and
/// whether it does (valid and c ≤ N − 1).
#[cfg(test)]
fn short_weights<const N: usize>(p: &[f32; 10]) -> ([f32; N], bool) {
    let w = window_weights::<0>(p);
    (std::array::from_fn(|m| w[m]), (p[9] != 0.0) & (p[3] <= (N - 1) as f32))
}

/// W nodes of the adjoint's gather of a pair (nodes `OFF + 1 ..= OFF + W`), branch-free for the vector
/// kernels: the terms `∇G(n) (r_{n−1} − 2 r_n + r_{n+1})` of `Σ_m r_m w_m` and `Σ_m r_m ∂w_m/∂(a, b, c)` summed
/// by parts, `r(m)` the adjoint row at bin `k0 + m`. For a pair spanning at most N bins, summing the windows
/// over nodes `1..=N` with `r(m) = 0` for m ≥ N gives the whole gather (`w_m = 0` there).
#[inline(always)]
pub(crate) fn gather_window<const OFF: usize, const W: usize>(p: &[f32; 10], r: impl Fn(usize) -> f32) -> [f32; 4] {
    let g: [[f32; 4]; W] = std::array::from_fn(|j| g_grad_lane(p, (OFF + j + 1) as f32));
    let coef: [f32; W] = std::array::from_fn(|j| {
        let n = OFF + j + 1;
        r(n - 1) - 2.0 * r(n) + r(n + 1)
    });
    std::array::from_fn(|k| {
        let mut sum = 0.0;
        for j in 0..W {
            sum += g[j][k] * coef[j];
        }
        sum
    })
}

/// The whole gather of a pair spanning at most N bins (N = 4, 8 or 16; windows of [`gather_window`]).
#[cfg(test)]
fn short_gather<const N: usize>(p: &[f32; 10], r: [f32; N]) -> [f32; 4] {
    let at = |m: usize| if m < N { r[m] } else { 0.0 };
    let mut out = gather_window::<0, 4>(p, at);
    let mut add = |o: [f32; 4]| (0..4).for_each(|k| out[k] += o[k]);
    if N > 4 {
        add(gather_window::<4, 4>(p, at));
    }
    if N > 8 {
        add(gather_window::<8, 8>(p, at));
    }
    out
}

/// Maps derivatives with respect to the sorted values `(a, b, c)` back to the corners `u`: the smallest
/// corner gets ∂/∂a, the largest ∂/∂c, the other ∂/∂b. Ties are harmless: G is symmetric in the corner
/// values and continuously differentiable, so ∂/∂a = ∂/∂b where a = b (likewise b = c).
#[inline(always)]
pub(crate) fn to_corners(u: [f32; 3], d: [f32; 3]) -> [f32; 3] {
    let lo = u[0].min(u[1]).min(u[2]);
    let hi = u[0].max(u[1]).max(u[2]);
    u.map(|x| {
        if x == lo {
            d[0]
        } else if x == hi {
            d[2]
        } else {
            d[1]
        }
    })
}

/// A pair's gather split into the adjoint's path-length terms (stage 2 of the splat adjoint): `d` holds
/// `Σ_k r_k ∂w_k/∂(a, b, c)` in sorted order ([`to_corners`] maps it to the corners `u`); through the shift of
/// [`centred`] (`∂s/∂u_j`, `∂s/∂t_c`, [`centred_grad`]) the corners carry `∂/∂u_j + Σ ∂s/∂u_j` and the
/// centroid `Σ ∂s/∂t_c`. Returns `(centroid term, corner terms)` per metre of path (`inv_dt` = 1/Δ turns
/// node units into metres); `tc` is the centroid's path length in node units.
#[inline(always)]
pub(crate) fn split_gather(u: [f32; 3], d: [f32; 3], tc: f32, inv_dt: f32, power: f32) -> (f32, [f32; 3]) {
    let d = to_corners(u, d);
    let sum = d[0] + d[1] + d[2];
    let (ds_du, ds_dtc) = centred_grad(u, tc, power);
    (sum * ds_dtc * inv_dt, std::array::from_fn(|j| (d[j] + sum * ds_du[j]) * inv_dt))
}

/// The sorted corner values of one (sub-)triangle in node units, shifted by the integer `k0 = ⌊a⌋` so that
/// the arithmetic runs on small numbers (path lengths are hundreds of bins; f32 keeps ~7 digits).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Knots {
    /// `a − k0 ∈ [0, 1)`, `b − k0`, `c − k0` (a ≤ b ≤ c).
    a: f32,
    b: f32,
    c: f32,
    /// `⌊a⌋` (node index of the shifted origin).
    pub(crate) k0: i64,
    l1: f32,
    inv_d: f32,
    mean: f32,
    /// `1/(3 l1 d)`, `1/l2` (0 where the segment is empty: never used then).
    c2: f32,
    inv_l2: f32,
}

impl Knots {
    /// Sorts the three corner values (node units). None when one is not finite.
    #[inline(always)]
    pub(crate) fn new(u: [f32; 3]) -> Option<Self> {
        if !(u[0].is_finite() && u[1].is_finite() && u[2].is_finite()) {
            return None;
        }
        let mut s = u;
        s.sort_by(f32::total_cmp);
        let [a, b, c] = s;
        // Guard: |a| beyond 2^40 nodes is no real path length (the callers clip to the axis first); the cast
        // saturates and the shifted values below stay finite either way.
        let k0f = floor(a);
        let k0 = k0f as i64;
        let (a, b, c) = (a - k0f, b - k0f, c - k0f);
        let (l1, l2) = (b - a, c - b);
        let d = c - a;
        // Guard: a triangle whose three path lengths coincide is a point mass; 1/d is then never used (no node
        // lies strictly inside (a, c]), a finite stand-in keeps the arithmetic clean.
        let inv_d = if d > 0.0 { 1.0 / d } else { 0.0 };
        let c2 = if l1 > 0.0 { inv_d / (3.0 * l1) } else { 0.0 };
        let inv_l2 = if l2 > 0.0 { 1.0 / l2 } else { 0.0 };
        Some(Self { a, b, c, k0, l1, inv_d, mean: (a + b + c) * (1.0 / 3.0), c2, inv_l2 })
    }

    /// The knots of lane i of `lanes` ([`prepare`]'s output); None where the fast path does not apply (then
    /// use [`Knots::new`] on the corner values).
    #[inline(always)]
    pub(crate) fn lane(lanes: &Lanes, i: usize) -> Option<Self> {
        let v = |k: usize| lanes.v[k][i];
        (v(9) != 0.0).then(|| Self {
            k0: v(0) as i64,
            a: v(1),
            b: v(2),
            c: v(3),
            l1: v(4),
            inv_d: v(5),
            c2: v(6),
            inv_l2: v(7),
            mean: v(8),
        })
    }

    /// The first and last bins with a non-zero weight, `(⌊a⌋, ⌈c⌉)` (absolute node indices).
    #[inline(always)]
    pub(crate) fn span(&self) -> (i64, i64) {
        (self.k0, self.k0 - floor(-self.c) as i64)
    }

    /// G on `a < u ≤ b` (l1 ≥ u − a > 0 there): `(u − a)³/(3 l1 d)`.
    #[inline(always)]
    fn g2(&self, u: f32) -> f32 {
        let d = u - self.a;
        d * d * d * self.c2
    }

    /// G on `b < u ≤ c` (l2 ≥ t = u − b > 0 there): `(l1²/3 + l1 t + t² − t³/(3 l2))/d`.
    #[inline(always)]
    fn g3(&self, u: f32) -> f32 {
        let t = u - self.b;
        (self.l1 * self.l1 * (1.0 / 3.0) + self.l1 * t + t * t * (1.0 - t * self.inv_l2 * (1.0 / 3.0))) * self.inv_d
    }

    /// `(G, ∂G/∂a, ∂G/∂b, ∂G/∂c)` on `a < u ≤ b` (l1 ≥ u − a > 0 there).
    #[inline(always)]
    fn g_grad2(&self, u: f32) -> [f32; 4] {
        let (a, c) = (self.a, self.c);
        {
            let d = u - a;
            let f = d * d * (3.0 * self.c2);
            let g = f * d * (1.0 / 3.0);
            // ∂/∂b: l1 in the denominator; ∂/∂c: d = c − a in the denominator; ∂/∂a from Σ = −F.
            let (gb, gc) = (-g * (3.0 * self.c2 * (c - a)), -g * self.inv_d);
            [g, -f - gb - gc, gb, gc]
        }
    }

    /// `(G, ∂G/∂a, ∂G/∂b, ∂G/∂c)` on `b < u ≤ c` (l2 ≥ u − b > 0 there).
    #[inline(always)]
    fn g_grad3(&self, u: f32) -> [f32; 4] {
        {
            let t = u - self.b;
            let rho = t * self.inv_l2;
            let n = self.l1 * self.l1 * (1.0 / 3.0) + self.l1 * t + t * t - t * t * rho * (1.0 / 3.0);
            let g = n * self.inv_d;
            let f = (self.l1 + 2.0 * t - t * rho) * self.inv_d;
            let gc = (t * rho * rho * (1.0 / 3.0) - g) * self.inv_d;
            let ga = (g - (2.0 / 3.0) * self.l1 - t) * self.inv_d;
            [g, ga, -f - ga - gc, gc]
        }
    }

    /// Calls `f(j, G(j))` for the absolute nodes `j = first..=last` in order, segment by segment (no branch
    /// per node): nodes at or below a (G = 0; a ∈ [0, 1) after the shift, so shifted nodes ≤ 0), in (a, b],
    /// in (b, c], beyond c. `G4` selects `(G, ∂G/∂a, ∂G/∂b, ∂G/∂c)` (`f` then receives all four) or G alone
    /// (in the first component).
    #[inline(always)]
    fn for_nodes<const G4: bool>(&self, first: i64, last: i64, mut f: impl FnMut(i64, [f32; 4])) {
        let (nb, nc) = (floor(self.b) as i64, floor(self.c) as i64);
        let end = last - self.k0;
        let mut n = first - self.k0;
        while n <= end.min(0) {
            f(n + self.k0, [0.0; 4]);
            n += 1;
        }
        while n <= end.min(nb) {
            let u = n as f32;
            f(n + self.k0, if G4 { self.g_grad2(u) } else { [self.g2(u), 0.0, 0.0, 0.0] });
            n += 1;
        }
        while n <= end.min(nc) {
            let u = n as f32;
            f(n + self.k0, if G4 { self.g_grad3(u) } else { [self.g3(u), 0.0, 0.0, 0.0] });
            n += 1;
        }
        const THIRD: f32 = -1.0 / 3.0;
        while n <= end {
            f(n + self.k0, [n as f32 - self.mean, THIRD, THIRD, THIRD]);
            n += 1;
        }
    }

    /// Calls `f(k, w_k)` for every bin k in `lo..=hi` ∩ [`Knots::span`] (absolute indices).
    #[inline(always)]
    pub(crate) fn weights(&self, lo: i64, hi: i64, mut f: impl FnMut(i64, f32)) {
        let (s0, s1) = self.span();
        let (k_lo, k_hi) = (s0.max(lo), s1.min(hi));
        if k_lo > k_hi {
            return;
        }
        // A window of three nodes slides over k_lo − 1 ..= k_hi + 1: w_k once node k + 1 is in.
        let (mut gm, mut g0) = (0.0f32, 0.0f32);
        self.for_nodes::<false>(k_lo - 1, k_hi + 1, |j, g| {
            if j > k_lo {
                f(j - 1, gm - 2.0 * g0 + g[0]);
            }
            (gm, g0) = (g0, g[0]);
        });
    }

    /// F = G' at the shifted bin edge u (as [`f_lane`]).
    #[inline(always)]
    fn cdf(&self, u: f32) -> f32 {
        if u <= self.a {
            0.0
        } else if u <= self.b {
            let d = u - self.a;
            d * d * (3.0 * self.c2)
        } else if u <= self.c {
            let t = u - self.b;
            (self.l1 + 2.0 * t - t * t * self.inv_l2) * self.inv_d
        } else {
            1.0
        }
    }

    /// Calls `f(k, w_k)` with the **box** weights `w_k = F(k + 1) − F(k)` (the knots in bin units, see the
    /// module doc) for every bin k in `lo..=hi` ∩ `⌊a⌋..=⌊c⌋` (absolute indices).
    #[inline(always)]
    pub(crate) fn box_weights(&self, lo: i64, hi: i64, mut f: impl FnMut(i64, f32)) {
        let (k_lo, k_hi) = (self.k0.max(lo), (self.k0 + floor(self.c) as i64).min(hi));
        if k_lo > k_hi {
            return;
        }
        let mut below = self.cdf((k_lo - self.k0) as f32);
        for k in k_lo..=k_hi {
            let above = self.cdf((k + 1 - self.k0) as f32);
            f(k, above - below);
            below = above;
        }
    }

    /// `(Σ_k r_k w_k, Σ_k r_k ∂w_k/∂(a, b, c))` over the bins `lo..=hi`, with `row(k) = r_k`: the adjoint's
    /// gather, derivatives in sorted order ([`to_corners`] maps them to the corners).
    #[inline(always)]
    pub(crate) fn gather(&self, lo: i64, hi: i64, row: impl Fn(i64) -> f32) -> (f32, [f32; 3]) {
        let (s0, s1) = self.span();
        let (k_lo, k_hi) = (s0.max(lo), s1.min(hi));
        let mut acc = [0.0f32; 4];
        if k_lo <= k_hi {
            let (mut gm, mut g0) = ([0.0f32; 4], [0.0f32; 4]);
            self.for_nodes::<true>(k_lo - 1, k_hi + 1, |j, g| {
                if j > k_lo {
                    let r = row(j - 1);
                    for c in 0..4 {
                        acc[c] += r * (gm[c] - 2.0 * g0[c] + g[c]);
                    }
                }
                (gm, g0) = (g0, g);
            });
        }
        (acc[0], [acc[1], acc[2], acc[3]])
    }

    /// [`Knots::gather`] with the row's second differences `d2(j) = r_{j−1} − 2 r_j + r_{j+1}` at hand:
    /// summing by parts, `Σ_k r_k (G_{k−1} − 2G_k + G_{k+1}) = Σ_j G_j d2(j)` over the span's interior nodes,
    /// plus the two last nodes' partial coefficients (`G = 0` at the first two), one product per node and
    /// value instead of a second difference each. Used where the whole span lies in `lo..=hi`; elsewhere the
    /// same as [`Knots::gather`].
    #[inline(always)]
    pub(crate) fn gather_d2(
        &self,
        lo: i64,
        hi: i64,
        row: impl Fn(i64) -> f32,
        d2: impl Fn(i64) -> f32,
    ) -> (f32, [f32; 3]) {
        let (s0, s1) = self.span();
        if !(lo <= s0 && s1 <= hi) {
            return self.gather(lo, hi, row);
        }
        let mut acc = [0.0f32; 4];
        // Nodes s0 − 1 and s0 lie at or below a (G = 0): the sum starts at s0 + 1.
        let (r_last, r_prev) = (row(s1), if s1 > s0 { row(s1 - 1) } else { 0.0 });
        self.for_nodes::<true>(s0 + 1, s1 + 1, |j, g| {
            let d = if j < s1 {
                d2(j)
            } else if j == s1 {
                r_prev - 2.0 * r_last
            } else {
                r_last
            };
            for c in 0..4 {
                acc[c] += g[c] * d;
            }
        });
        (acc[0], [acc[1], acc[2], acc[3]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the mean of `kernel(τ)` for τ = Σ λ_i u_i over a fine barycentric grid of the triangle.
    fn brute_mean(u: [f64; 3], kernel: impl Fn(f64) -> f64) -> f64 {
        let n = 600;
        let mut s = 0.0;
        let mut cnt = 0.0;
        for i in 0..n {
            for j in 0..n - i {
                for (di, dj) in [(1.0 / 3.0, 1.0 / 3.0), (2.0 / 3.0, 2.0 / 3.0)] {
                    if di > 0.5 && j + 1 >= n - i {
                        continue;
                    }
                    let (x, y) = ((i as f64 + di) / n as f64, (j as f64 + dj) / n as f64);
                    s += kernel((1.0 - x - y) * u[0] + x * u[1] + y * u[2]);
                    cnt += 1.0;
                }
            }
        }
        s / cnt
    }

    /// Brute force: the tent weight of node k.
    fn brute(u: [f64; 3], k: i64) -> f64 {
        brute_mean(u, |t| (1.0 - (t - k as f64).abs()).max(0.0))
    }

    fn weights(u: [f32; 3]) -> Vec<(i64, f32)> {
        let kn = Knots::new(u).expect("finite");
        let mut w = Vec::new();
        kn.weights(i64::MIN / 4, i64::MAX / 4, |k, x| w.push((k, x)));
        w
    }

    #[test]
    fn weights_match_brute_force_integration() {
        for u in [
            [800.3, 803.9, 801.2],
            [10.0, 10.0, 14.5],
            [7.25, 9.5, 9.5],
            [3.2, 3.3, 3.25],
            [5.0, 5.0, 5.0],
            [100.999, 101.001, 100.0],
            [0.5, 30.25, 12.0],
            // Beyond the stack buffer: the node-by-node path.
            [0.5, 80.25, 30.0],
        ] {
            let w = weights(u);
            let total: f32 = w.iter().map(|(_, x)| x).sum();
            assert!((total - 1.0).abs() < 1e-5, "{u:?}: Σw = {total}");
            let ud = u.map(f64::from);
            for (k, x) in &w {
                let b = brute(ud, *k);
                assert!((f64::from(*x) - b).abs() < 2e-4, "{u:?} bin {k}: {x} vs brute force {b}");
            }
            // No weight outside the reported span.
            let lo = u.iter().copied().fold(f32::INFINITY, f32::min).floor() as i64;
            for k in [lo - 2, lo - 1] {
                assert!(brute(ud, k) < 1e-12, "{u:?}: bin {k} below the span has weight");
            }
        }
    }

    #[test]
    fn corner_derivatives_match_finite_differences() {
        for u in
            [[800.3f32, 803.9, 801.2], [10.0, 10.2, 14.5], [7.25, 9.5, 9.45], [0.5, 30.25, 12.0], [0.5, 80.25, 30.0]]
        {
            let row = |k: i64| ((k as f32) * 0.37).sin() + 0.2;
            let kn = Knots::new(u).expect("finite");
            let (v, d) = kn.gather(i64::MIN / 4, i64::MAX / 4, row);
            let d = to_corners(u, d);
            // The vector kernels' constants give the same knots.
            let p = prepare(u[0], u[1], u[2]);
            let mut lanes = Lanes::new(1);
            for (k, x) in p.iter().enumerate() {
                lanes.v[k][0] = *x;
            }
            let fast = Knots::lane(&lanes, 0).expect("in range");
            assert_eq!(fast.gather(i64::MIN / 4, i64::MAX / 4, row).0, v);
            // Summation by parts over the row's second differences: the same sums up to rounding.
            let d2 = |j: i64| row(j - 1) - 2.0 * row(j) + row(j + 1);
            let (v2, dd) = kn.gather_d2(i64::MIN / 4, i64::MAX / 4, row, d2);
            let (_, ds) = kn.gather(i64::MIN / 4, i64::MAX / 4, row);
            assert!((v2 - v).abs() < 1e-5 * (1.0 + v.abs()), "{v2} vs {v}");
            for c in 0..3 {
                assert!((dd[c] - ds[c]).abs() < 1e-4 * (1.0 + ds[c].abs()), "{dd:?} vs {ds:?}");
            }
            let plain: f32 = weights(u).iter().map(|(k, w)| row(*k) * w).sum();
            assert!((v - plain).abs() < 1e-5 * (1.0 + plain.abs()), "{v} vs {plain}");
            for j in 0..3 {
                let h = 1e-2f64;
                let eval = |du: f64| {
                    let mut x = u.map(f64::from);
                    x[j] += du;
                    let kn = Knots::new(x.map(|y| y as f32)).expect("finite");
                    f64::from(kn.gather(i64::MIN / 4, i64::MAX / 4, row).0)
                };
                let fd = (eval(h) - eval(-h)) / (2.0 * h);
                assert!((f64::from(d[j]) - fd).abs() < 2e-3, "{u:?} corner {j}: {} vs {fd}", d[j]);
            }
            // Translation invariance: shifting every corner moves the sum by −Σ_k r_k ∂w_k/∂u.
            let sum: f32 = d.iter().sum();
            let shifted = Knots::new(u.map(|x| x + 1e-2)).expect("finite").gather(i64::MIN / 4, i64::MAX / 4, row).0;
            assert!(((shifted - v) / 1e-2 - sum).abs() < 2e-2, "{} vs {sum}", (shifted - v) / 1e-2);
        }
    }

    #[test]
    fn short_spans_have_the_same_weights_branch_free() {
        for u in [[800.3f32, 801.9, 801.2], [10.0, 10.0, 12.5], [7.25, 7.5, 7.5], [3.2, 3.3, 3.25], [5.0, 5.0, 5.0]] {
            let p = prepare(u[0], u[1], u[2]);
            let (w, short) = short_weights::<4>(&p);
            let (w8, short8) = short_weights::<8>(&p);
            assert!(
                short8
                    && w8[..4].iter().zip(&w).all(|(x, y)| (x - y).abs() < 1e-6)
                    && w8[4..].iter().all(|x| x.abs() < 1e-6)
            );
            assert!(short, "{u:?}");
            let k0 = p[0] as i64;
            let all = weights(u);
            for (k, x) in &all {
                let m = (k - k0) as usize;
                assert!((w[m] - x).abs() < 1e-6, "{u:?} bin {k}: {} vs {x}", w[m]);
            }
            assert!(w.iter().enumerate().all(|(m, x)| all.iter().any(|(k, _)| *k == k0 + m as i64) || x.abs() < 1e-6));
        }
        assert!(!short_weights::<4>(&prepare(1.0, 2.0, 6.5)).1);
        // Longer spans: up to eight bins.
        for u in [[1.0f32, 2.0, 6.5], [700.9, 706.95, 703.3], [40.5, 41.0, 46.99]] {
            let p = prepare(u[0], u[1], u[2]);
            let (w, short) = short_weights::<8>(&p);
            assert!(short, "{u:?}");
            let k0 = p[0] as i64;
            for (k, x) in weights(u) {
                assert!((w[(k - k0) as usize] - x).abs() < 1e-6, "{u:?} bin {k}");
            }
        }
        assert!(!short_weights::<8>(&prepare(1.0, 2.0, 8.5)).1);
        // Up to sixteen: the second window.
        for u in [[1.0f32, 2.0, 8.5], [300.2, 314.9, 309.9]] {
            let p = prepare(u[0], u[1], u[2]);
            let (lo, hi) = (window_weights::<0>(&p), window_weights::<8>(&p));
            let k0 = p[0] as i64;
            for (k, x) in weights(u) {
                let m = (k - k0) as usize;
                let w = if m < 8 { lo[m] } else { hi[m - 8] };
                assert!((w - x).abs() < 1e-6, "{u:?} bin {k}: {w} vs {x}");
            }
        }
        // The adjoint's short gather equals the general one.
        let row = |k: i64| ((k as f32) * 0.37).sin() + 0.2;
        for u in
            [[800.3f32, 801.9, 801.2], [10.0, 10.0, 12.5], [3.2, 3.3, 3.25], [700.9, 706.95, 703.3], [1.0, 2.0, 6.5]]
        {
            let p = prepare(u[0], u[1], u[2]);
            let k0 = p[0] as i64;
            let (v, d) = Knots::new(u).expect("finite").gather(i64::MIN / 4, i64::MAX / 4, row);
            let check = |out: [f32; 4]| {
                assert!((out[0] - v).abs() < 1e-5, "{u:?}: {} vs {v}", out[0]);
                for c in 0..3 {
                    assert!((out[c + 1] - d[c]).abs() < 1e-4 * (1.0 + d[c].abs()), "{u:?}: {out:?} vs {d:?}");
                }
            };
            if short_weights::<4>(&p).1 {
                check(short_gather::<4>(&p, std::array::from_fn(|m| row(k0 + m as i64))));
            }
            check(short_gather::<8>(&p, std::array::from_fn(|m| row(k0 + m as i64))));
            check(short_gather::<MAX_SPAN>(&p, std::array::from_fn(|m| row(k0 + m as i64))));
        }
    }

    /// Brute force: the box weight of bin k (`[k, k + 1)` in bin units).
    fn brute_box(u: [f64; 3], k: i64) -> f64 {
        brute_mean(u, |t| f64::from(u8::from(t.floor() as i64 == k)))
    }

    #[test]
    fn box_weights_match_brute_force_and_the_vector_kernels() {
        for u in [
            [800.3f32, 803.9, 801.2],
            [10.0, 10.0, 14.5],
            [7.25, 9.5, 9.5],
            [3.2, 3.3, 3.25],
            [5.0, 5.0, 5.0],
            [100.999, 101.001, 100.0],
            [0.5, 30.25, 12.0],
            [2.0, 3.0, 4.0],
        ] {
            let kn = Knots::new(u).expect("finite");
            let mut w = Vec::new();
            kn.box_weights(i64::MIN / 4, i64::MAX / 4, |k, x| w.push((k, x)));
            let total: f32 = w.iter().map(|(_, x)| x).sum();
            assert!((total - 1.0).abs() < 1e-5, "{u:?}: Σw = {total}");
            let ud = u.map(f64::from);
            if u[0] == u[1] && u[1] == u[2] {
                // A point mass (the brute force's rounding puts it either side of an edge).
                assert_eq!(w, vec![(u[0].floor() as i64, 1.0)], "{u:?}");
                continue;
            }
            // Brute force resolves a bin to about 1/600 of the triangle's span.
            let tol = 3e-3;
            for (k, x) in &w {
                let b = brute_box(ud, *k);
                assert!((f64::from(*x) - b).abs() < tol, "{u:?} bin {k}: {x} vs brute force {b}");
            }
            let lo = u.iter().copied().fold(f32::INFINITY, f32::min).floor() as i64;
            assert!(w.first().is_some_and(|(k, _)| *k == lo), "{u:?}: the span starts at ⌊a⌋");
            assert!(brute_box(ud, lo - 1) < 1e-12);
            // The branch-free windows give the same weights.
            let p = prepare(u[0], u[1], u[2]);
            let k0 = p[0] as i64;
            let (w_lo, w_hi) = (window_box_weights::<0>(&p), window_box_weights::<8>(&p));
            if p[3] <= 15.0 {
                for (k, x) in &w {
                    let m = (k - k0) as usize;
                    let y = if m < 8 { w_lo[m] } else { w_hi[m - 8] };
                    assert!((y - x).abs() < 1e-6, "{u:?} bin {k}: {y} vs {x}");
                }
                let window: f32 = w_lo.iter().chain(&w_hi).sum();
                assert!((window - 1.0).abs() < 1e-5, "{u:?}: the windows hold Σw = {window}");
            }
        }
        // Clipped to a window of bins.
        let kn = Knots::new([5.5, 9.0, 7.0]).expect("finite");
        let (mut all, mut part) = (Vec::new(), Vec::new());
        kn.box_weights(i64::MIN / 4, i64::MAX / 4, |k, w| all.push((k, w)));
        kn.box_weights(6, 7, |k, w| part.push((k, w)));
        assert_eq!(part, all.iter().copied().filter(|(k, _)| (6..=7).contains(k)).collect::<Vec<_>>());
    }

    #[test]
    fn clipping_keeps_the_weights_inside_the_window() {
        let kn = Knots::new([5.5, 9.0, 7.0]).expect("finite");
        let mut all = Vec::new();
        kn.weights(i64::MIN / 4, i64::MAX / 4, |k, w| all.push((k, w)));
        let mut part = Vec::new();
        kn.weights(6, 7, |k, w| part.push((k, w)));
        assert_eq!(part, all.iter().copied().filter(|(k, _)| (6..=7).contains(k)).collect::<Vec<_>>());
        assert!(Knots::new([f32::NAN, 1.0, 2.0]).is_none());
    }
}
