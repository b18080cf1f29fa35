//! Narrow phase: continuous collision detection (CCD) for vertex–triangle and edge–edge pairs whose
//! vertices move on straight lines `x(t) = x₀ + t·(x₁ − x₀)`, `t ∈ [0, 1]`.
//!
//! # Method
//! Two primitives can only touch when their four points are coplanar (Provot 1997, "Collision and
//! self-collision handling in cloth model dedicated to design garments"; Bridson, Fedkiw & Anderson 2002,
//! "Robust treatment of collisions, contact and friction for cloth animation", §4). With
//! `u = x₁ − x₀`, `v = x₂ − x₀`, `w = x₃ − x₀` (vertex–triangle: `x₀..x₂` the triangle, `x₃` the point;
//! edge–edge: `x₀x₁` and `x₂x₃` the edges) the coplanarity condition is the cubic
//!
//! `f(t) = (u(t) × v(t)) · w(t) = c₀ + c₁t + c₂t² + c₃t³`.
//!
//! At each candidate time a proximity test (point–triangle or segment–segment distance ≤ `tol`) decides
//! whether the primitives really meet; the earliest such time is the collision time.
//!
//! Before the cubic, a conservative filter rejects pairs that provably stay apart: the distance between
//! the primitives is 1-Lipschitz in their relative position, whose speed is at most `m = max |dxᵢ − dxⱼ|`
//! over a vertex `i` of one primitive and `j` of the other, so `dist(t) ≥ max(d(0) − t·m, d(1) − (1−t)·m)`.
//! When that bound exceeds `tol` (plus a rounding slack of `2⁻⁴⁰` of the coordinate magnitude) on all of
//! `[0, 1]` the answer is `None`, exactly as the full test would give. In a mesh moving by a fraction of its
//! edge length this decides almost every candidate pair with two closest-point computations.
//!
//! # Root isolation and its tolerance
//! Everything is evaluated in `f64` from the `f32` positions (the differences of `f32` values are exact in
//! `f64`). The coefficients carry an absolute error of at most a few ulps of
//! `M = (|u₀|+|Δu|)(|v₀|+|Δv|)(|w₀|+|Δw|)`, which bounds `|f|` on `[0, 1]`; we use
//! `ftol = 64·ε_f64·M` (≈ 1.4·10⁻¹⁴·M) as the uncertainty of a computed value of `f`.
//!
//! 1. The critical points of `f` (roots of `f'`, a quadratic solved with the cancellation-free formula;
//!    a vanishing leading coefficient degrades it to a linear equation, an all-zero derivative to none)
//!    split `[0, 1]` into at most three pieces on which `f` is monotone. Degenerate and near-degenerate
//!    cubics (leading coefficients ≈ 0, i.e. quadratics, lines, constants) need no special case.
//! 2. On each monotone piece the set `{t : |f(t)| ≤ ftol}` is one interval `[tₐ, t_b]` (possibly empty),
//!    found by bracketing on `f ∓ ftol` (Illinois regula falsi with a bisection every third step, down to a
//!    width of 2⁻⁶⁰ ≈ 10⁻¹⁸, below the `f64` resolution of `t`). True contact implies exact coplanarity, hence `|f_computed| ≤ ftol`, hence a time
//!    inside one of these intervals: no root is lost to rounding, including tangential (double) roots and
//!    roots at `t = 0` or `t = 1`.
//! 3. Candidate times in each interval: its start, the sign change of `f` inside it (bisected), and —
//!    because inside a wide interval the primitives move (nearly) coplanarly and may meet *in the plane* —
//!    the roots in the interval of the in-plane collinearity quadratics (a point crossing the line of an
//!    edge of the other primitive, or the triangle inverting), isolated the same way.
//!
//! The proximity tolerance `tol` (metres) is the caller's: [`super::EvolveParams::collision_epsilon`].
//! Fully collinear motions (all four points on one line throughout) are the one case where only the
//! interval ends are tested; the evolution's final exact static check catches what could be missed there.

use glam::DVec3;

/// Number of bisection steps: `2⁻⁶⁰ ≈ 8.7·10⁻¹⁹`, finer than the spacing of `f64` near 1.
const BISECTIONS: u32 = 60;

/// Bracket width at which root isolation stops: `2⁻⁶⁰`.
const MIN_WIDTH: f64 = 1.0 / (1u64 << 60) as f64;

/// Relative uncertainty of a computed cubic value, in units of the magnitude bound `M` (see module docs).
const FTOL_REL: f64 = 64.0 * f64::EPSILON;

#[inline]
fn eval(c: &[f64; 4], t: f64) -> f64 {
    ((c[3] * t + c[2]) * t + c[1]) * t + c[0]
}

/// Real roots of `a·t² + b·t + c` (Numerical Recipes' cancellation-free form). A zero `a` gives the linear
/// root, all-zero coefficients none (a constant has no isolated roots).
fn quadratic_roots(a: f64, b: f64, c: f64) -> ([f64; 2], usize) {
    if a == 0.0 {
        if b == 0.0 {
            return ([0.0; 2], 0);
        }
        return ([-c / b, 0.0], 1);
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        // No real extremum (or a double one lost to rounding: harmless, it is not a sign change of f').
        return ([0.0; 2], 0);
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        // b = 0 and disc = 0 ⇒ c = 0: double root at 0
        return ([0.0, 0.0], 1);
    }
    let (r0, r1) = (q / a, c / q);
    if r0 <= r1 { ([r0, r1], 2) } else { ([r1, r0], 2) }
}

/// Splits `[lo, hi]` at the critical points of the polynomial `c` (degree ≤ 3): `f` is monotone on each
/// piece. Returns the breakpoints, sorted, `lo` and `hi` included.
fn monotone_breakpoints(c: &[f64; 4], lo: f64, hi: f64) -> ([f64; 4], usize) {
    let (r, n) = quadratic_roots(3.0 * c[3], 2.0 * c[2], c[1]);
    let mut bp = [lo, hi, hi, hi];
    let mut k = 1;
    for &x in &r[..n] {
        // NaN-safe: a non-finite root fails both comparisons
        if x > lo && x < hi && x > bp[k - 1] {
            bp[k] = x;
            k += 1;
        }
    }
    bp[k] = hi;
    (bp, k + 1)
}

/// On `[l, r]` where `f` is monotone, the first `t` with `g(t) := s·f(t) ≥ level` given `g(l) < level ≤
/// g(r)` (`s = ±1` orients it increasing): the bracket `[l, r]` shrinks by the Illinois variant of regula
/// falsi (superlinear on smooth pieces), with a plain bisection every third step, so that the `3·60` steps
/// allowed include the 60 halvings of pure bisection; it stops at a width of `2⁻⁶⁰` (or when no `f64` lies
/// between the ends) and returns the right end, so `g(r) ≥ level` always holds.
fn bisect_level(c: &[f64; 4], s: f64, level: f64, mut l: f64, mut r: f64) -> f64 {
    let g = |t: f64| s * eval(c, t) - level;
    let (mut gl, mut gr) = (g(l), g(r));
    let mut side = 0i8;
    for step in 0..3 * BISECTIONS {
        if r - l <= MIN_WIDTH {
            break;
        }
        let mid = 0.5 * (l + r);
        let m = if step % 3 == 2 || !(gl < 0.0 && gr >= 0.0) {
            mid
        } else {
            let t = l + (r - l) * (gl / (gl - gr));
            // NaN-safe: a non-finite or outside secant point falls back to the midpoint
            if t > l && t < r { t } else { mid }
        };
        if m <= l || m >= r {
            break;
        }
        let gm = g(m);
        if gm >= 0.0 {
            r = m;
            gr = gm;
            if side == 1 {
                gl *= 0.5;
            }
            side = 1;
        } else {
            l = m;
            gl = gm;
            if side == -1 {
                gr *= 0.5;
            }
            side = -1;
        }
    }
    r
}

/// A piece of `[lo, hi]` where `|f| ≤ ftol`, with the sign-change root inside it if there is one.
#[derive(Debug, Clone, Copy, PartialEq)]
struct NearZero {
    start: f64,
    end: f64,
    root: Option<f64>,
}

/// The near-zero set `{t ∈ [lo, hi] : |f(t)| ≤ ftol}` of a polynomial of degree ≤ 3 as at most three
/// intervals (one per monotone piece), in increasing order.
fn near_zero_intervals(c: &[f64; 4], ftol: f64, lo: f64, hi: f64, out: &mut Vec<NearZero>) {
    let (bp, n) = monotone_breakpoints(c, lo, hi);
    for k in 0..n - 1 {
        let (l, r) = (bp[k], bp[k + 1]);
        let (fl, fr) = (eval(c, l), eval(c, r));
        // orient the piece so that s·f increases from l to r
        let s = if fr >= fl { 1.0 } else { -1.0 };
        let (gl, gr) = (s * fl, s * fr);
        if gr < -ftol || gl > ftol {
            continue; // the piece stays on one side, away from zero
        }
        let start = if gl >= -ftol { l } else { bisect_level(c, s, -ftol, l, r) };
        let end = if gr <= ftol { r } else { bisect_level(c, s, ftol, l, r) };
        let root = if gl < 0.0 && gr > 0.0 { Some(bisect_level(c, s, 0.0, l, r)) } else { None };
        out.push(NearZero { start, end: end.max(start), root });
    }
}

/// Coefficients of `(u(t) × v(t)) · w(t)` for `u(t) = u0 + t·du` etc. (Bridson et al. 2002, eq. 1).
fn triple_cubic(u0: DVec3, du: DVec3, v0: DVec3, dv: DVec3, w0: DVec3, dw: DVec3) -> [f64; 4] {
    [
        u0.cross(v0).dot(w0),
        du.cross(v0).dot(w0) + u0.cross(dv).dot(w0) + u0.cross(v0).dot(dw),
        du.cross(dv).dot(w0) + du.cross(v0).dot(dw) + u0.cross(dv).dot(dw),
        du.cross(dv).dot(dw),
    ]
}

/// Coefficients (degree 2) of `n · (u(t) × v(t))` for a fixed direction `n`.
fn cross_quadratic(n: DVec3, u0: DVec3, du: DVec3, v0: DVec3, dv: DVec3) -> [f64; 4] {
    [n.dot(u0.cross(v0)), n.dot(du.cross(v0) + u0.cross(dv)), n.dot(du.cross(dv)), 0.0]
}

/// A moving point: position at `t = 0` and its displacement over the step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moving {
    /// Position at `t = 0`.
    pub x0: DVec3,
    /// Displacement `x₁ − x₀`.
    pub dx: DVec3,
}

impl Moving {
    /// From the two `f32` end positions (exact in `f64`).
    #[inline]
    pub fn new(x0: glam::Vec3, x1: glam::Vec3) -> Self {
        let x0 = x0.as_dvec3();
        Self { x0, dx: x1.as_dvec3() - x0 }
    }
    /// Position at time `t`.
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        self.x0 + t * self.dx
    }
    /// Relative motion `other − self`.
    #[inline]
    fn rel(&self, other: &Moving) -> (DVec3, DVec3) {
        (other.x0 - self.x0, other.dx - self.dx)
    }
}

/// Closest point on triangle `(a, b, c)` to `p` (Ericson, *Real-Time Collision Detection* §5.1.5) in
/// `f64`: returns the distance and the barycentric weights of the closest point.
pub fn point_triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (f64, [f64; 3]) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    let bary = 'r: {
        if d1 <= 0.0 && d2 <= 0.0 {
            break 'r [1.0, 0.0, 0.0];
        }
        let bp = p - b;
        let d3 = ab.dot(bp);
        let d4 = ac.dot(bp);
        if d3 >= 0.0 && d4 <= d3 {
            break 'r [0.0, 1.0, 0.0];
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            // Guard: d1 − d3 = |ab|² > 0 unless ab is degenerate (then any point of it is as close).
            let den = d1 - d3;
            let v = if den > 0.0 { d1 / den } else { 0.0 };
            break 'r [1.0 - v, v, 0.0];
        }
        let cp = p - c;
        let d5 = ab.dot(cp);
        let d6 = ac.dot(cp);
        if d6 >= 0.0 && d5 <= d6 {
            break 'r [0.0, 0.0, 1.0];
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let den = d2 - d6;
            let w = if den > 0.0 { d2 / den } else { 0.0 };
            break 'r [1.0 - w, 0.0, w];
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let den = (d4 - d3) + (d5 - d6);
            let w = if den > 0.0 { (d4 - d3) / den } else { 0.0 };
            break 'r [0.0, 1.0 - w, w];
        }
        let sum = va + vb + vc;
        // Guard: a degenerate triangle reaching the face region (sum ≤ 0 or not finite): the edge tests
        // cover it, so the closest of the three edges is exact; fall back to them.
        if !(sum > 0.0 && sum.is_finite()) {
            let cands = [
                segment_segment_distance(p, p, a, b),
                segment_segment_distance(p, p, b, c),
                segment_segment_distance(p, p, c, a),
            ];
            let (k, best) = cands
                .iter()
                .enumerate()
                .min_by(|x, y| x.1.0.total_cmp(&y.1.0))
                .map(|(k, x)| (k, *x))
                .unwrap_or((0, cands[0]));
            let u = best.2;
            break 'r match k {
                0 => [1.0 - u, u, 0.0],
                1 => [0.0, 1.0 - u, u],
                _ => [u, 0.0, 1.0 - u],
            };
        }
        let v = vb / sum;
        let w = vc / sum;
        [1.0 - v - w, v, w]
    };
    let q = a * bary[0] + b * bary[1] + c * bary[2];
    ((p - q).length(), bary)
}

/// Closest points of segments `p1q1` and `p2q2` (Ericson §5.1.9) in `f64`: the distance and the
/// parameters `s`, `u` of the closest points `p1 + s(q1 − p1)`, `p2 + u(q2 − p2)`. Degenerate segments
/// (points) and parallel ones are handled.
pub fn segment_segment_distance(p1: DVec3, q1: DVec3, p2: DVec3, q2: DVec3) -> (f64, f64, f64) {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.length_squared();
    let e = d2.length_squared();
    let f = d2.dot(r);
    // Guard: squared lengths below this (relative to the configuration) count as points.
    let tiny = 1e-30 * (1.0 + a + e + r.length_squared());
    let (s, u) = if a <= tiny && e <= tiny {
        (0.0, 0.0)
    } else if a <= tiny {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(r);
        if e <= tiny {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            // Guard: parallel segments (denom ≈ 0): pick s = 0 and let the clamping below find u.
            let mut s = if denom > 1e-14 * a * e { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
            let mut u = (b * s + f) / e;
            if u < 0.0 {
                u = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if u > 1.0 {
                u = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, u)
        }
    };
    let c1 = p1 + d1 * s;
    let c2 = p2 + d2 * u;
    ((c1 - c2).length(), s, u)
}

/// The largest-magnitude vector among `cands` (used as a plane normal for in-plane tests).
fn dominant(cands: &[DVec3]) -> DVec3 {
    cands.iter().copied().fold(DVec3::ZERO, |acc, n| if n.length_squared() > acc.length_squared() { n } else { acc })
}

/// Pushes onto `out` the candidate times of the near-zero intervals of `f` in `[0, 1]` and, inside each,
/// the roots of the in-plane quadratics `quads(n)` for the interval's plane normal `n`.
///
/// The plane normal is the largest of the primitives' cross products at the interval's start, middle and
/// end, so that a configuration that is collinear at one of those instants still gets a plane.
fn candidate_times(
    f: &[f64; 4],
    ftol: f64,
    quads: impl Fn(DVec3) -> Vec<[f64; 4]>,
    normal: impl Fn(f64) -> DVec3,
    out: &mut Vec<f64>,
) {
    let mut ivs = Vec::with_capacity(3);
    near_zero_intervals(f, ftol, 0.0, 1.0, &mut ivs);
    let mut sub = Vec::with_capacity(3);
    for iv in ivs {
        out.push(iv.start);
        if let Some(r) = iv.root {
            out.push(r);
        }
        if iv.end > iv.start {
            out.push(iv.end);
            let n = dominant(&[normal(iv.start), normal(0.5 * (iv.start + iv.end)), normal(iv.end)]);
            for q in quads(n) {
                let m = q.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                sub.clear();
                // only exact sign changes and touching zeros of the quadratic matter here
                near_zero_intervals(&q, FTOL_REL * m, iv.start, iv.end, &mut sub);
                for s in &sub {
                    out.push(s.start);
                    if let Some(r) = s.root {
                        out.push(r);
                    }
                }
            }
        }
    }
    out.sort_by(f64::total_cmp);
    out.dedup();
}

/// Magnitude bound `M` of the triple product on `[0, 1]` (module docs).
fn magnitude(u0: DVec3, du: DVec3, v0: DVec3, dv: DVec3, w0: DVec3, dw: DVec3) -> f64 {
    (u0.length() + du.length()) * (v0.length() + dv.length()) * (w0.length() + dw.length())
}

/// Whether the primitives provably stay farther apart than `tol` over the whole step, from their distances
/// `d0`, `d1` at `t = 0` and `t = 1` and a bound `m` on the speed of their relative motion: the distance is
/// 1-Lipschitz in the relative position, so `dist(t) ≥ max(d0 − t·m, d1 − (1 − t)·m)`, whose minimum over
/// `[0, 1]` is at the crossing of the two lines. `slack` absorbs the rounding of the `f64` distances.
#[inline]
fn provably_apart(d0: f64, d1: f64, m: f64, tol: f64, slack: f64) -> bool {
    let lower = if m > 0.0 {
        let t = ((d0 - d1 + m) / (2.0 * m)).clamp(0.0, 1.0);
        (d0 - t * m).max(d1 - (1.0 - t) * m)
    } else {
        d0.min(d1)
    };
    lower > tol + slack
}

/// Largest `|dxᵢ − dxⱼ|` over `i` in `left`, `j` in `right`: bounds the speed of the relative position
/// `Σ αᵢ xᵢ − Σ βⱼ xⱼ` of any two convex combinations.
#[inline]
fn relative_speed(left: &[&Moving], right: &[&Moving]) -> f64 {
    let mut m2 = 0.0f64;
    for l in left {
        for r in right {
            m2 = m2.max((l.dx - r.dx).length_squared());
        }
    }
    m2.sqrt()
}

/// Rounding slack of a distance between points of these moving primitives: `2⁻⁴⁰` of their largest
/// coordinate magnitude (the `f64` closest-point computations err by a few ulps of it).
#[inline]
fn distance_slack(ms: &[&Moving]) -> f64 {
    let big = ms.iter().fold(0.0f64, |acc, m| acc.max(m.x0.abs().max_element()).max((m.x0 + m.dx).abs().max_element()));
    big * (1.0 / (1u64 << 40) as f64)
}

/// Earliest time in `[0, 1]` at which moving point `p` comes within `tol` of moving triangle `(a, b, c)`
/// at a coplanar configuration (see the module docs), or `None`.
///
/// A conservative filter runs first: pairs whose distances at `t = 0` and `t = 1` and relative speed prove
/// them apart by more than `tol` throughout return `None` without the cubic (the common case in a mesh).
pub fn vertex_triangle_ccd(p: &Moving, a: &Moving, b: &Moving, c: &Moving, tol: f64) -> Option<f64> {
    let d0 = point_triangle_distance(p.x0, a.x0, b.x0, c.x0).0;
    let d1 = point_triangle_distance(p.at(1.0), a.at(1.0), b.at(1.0), c.at(1.0)).0;
    let m = relative_speed(&[p], &[a, b, c]);
    if provably_apart(d0, d1, m, tol, distance_slack(&[p, a, b, c])) {
        return None;
    }
    let (u0, du) = a.rel(b);
    let (v0, dv) = a.rel(c);
    let (w0, dw) = a.rel(p);
    let f = triple_cubic(u0, du, v0, dv, w0, dw);
    if !f.iter().all(|x| x.is_finite()) {
        return None;
    }
    let ftol = FTOL_REL * magnitude(u0, du, v0, dv, w0, dw);
    let mut times = Vec::with_capacity(8);
    let normal = |tm: f64| {
        let (pa, pb, pc, pp) = (a.at(tm), b.at(tm), c.at(tm), p.at(tm));
        dominant(&[(pb - pa).cross(pc - pa), (pb - pa).cross(pp - pa), (pc - pb).cross(pp - pb)])
    };
    let quads = |n: DVec3| {
        // point vs the line of each edge, and the triangle's own in-plane orientation
        let (bc0, bcd) = b.rel(c);
        let (bp0, bpd) = b.rel(p);
        let (ca0, cad) = c.rel(a);
        let (cp0, cpd) = c.rel(p);
        vec![
            cross_quadratic(n, u0, du, w0, dw),
            cross_quadratic(n, bc0, bcd, bp0, bpd),
            cross_quadratic(n, ca0, cad, cp0, cpd),
            cross_quadratic(n, u0, du, v0, dv),
        ]
    };
    candidate_times(&f, ftol, quads, normal, &mut times);
    times.into_iter().find(|&t| point_triangle_distance(p.at(t), a.at(t), b.at(t), c.at(t)).0 <= tol)
}

/// Earliest time in `[0, 1]` at which moving segments `ab` and `cd` come within `tol` of each other at a
/// coplanar configuration, or `None`. Filtered first like [`vertex_triangle_ccd`].
pub fn edge_edge_ccd(a: &Moving, b: &Moving, c: &Moving, d: &Moving, tol: f64) -> Option<f64> {
    let d0 = segment_segment_distance(a.x0, b.x0, c.x0, d.x0).0;
    let d1 = segment_segment_distance(a.at(1.0), b.at(1.0), c.at(1.0), d.at(1.0)).0;
    let m = relative_speed(&[a, b], &[c, d]);
    if provably_apart(d0, d1, m, tol, distance_slack(&[a, b, c, d])) {
        return None;
    }
    let (u0, du) = a.rel(b);
    let (v0, dv) = a.rel(c);
    let (w0, dw) = a.rel(d);
    let f = triple_cubic(u0, du, v0, dv, w0, dw);
    if !f.iter().all(|x| x.is_finite()) {
        return None;
    }
    let ftol = FTOL_REL * magnitude(u0, du, v0, dv, w0, dw);
    let mut times = Vec::with_capacity(8);
    let normal = |tm: f64| {
        let (pa, pb, pc, pd) = (a.at(tm), b.at(tm), c.at(tm), d.at(tm));
        dominant(&[(pb - pa).cross(pc - pa), (pb - pa).cross(pd - pa), (pd - pc).cross(pa - pc)])
    };
    let quads = |n: DVec3| {
        let (cd0, cdd) = c.rel(d);
        let (ca0, cad) = c.rel(a);
        let (cb0, cbd) = c.rel(b);
        // each endpoint against the other segment's line
        vec![
            cross_quadratic(n, u0, du, v0, dv),
            cross_quadratic(n, u0, du, w0, dw),
            cross_quadratic(n, cd0, cdd, ca0, cad),
            cross_quadratic(n, cd0, cdd, cb0, cbd),
        ]
    };
    candidate_times(&f, ftol, quads, normal, &mut times);
    times.into_iter().find(|&t| segment_segment_distance(a.at(t), b.at(t), c.at(t), d.at(t)).0 <= tol)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_roots_are_stable() {
        let (r, n) = quadratic_roots(1.0, -1e8, 1.0);
        assert_eq!(n, 2);
        assert!((r[0] - 1e-8).abs() < 1e-20 && (r[1] - 1e8).abs() < 1e-4);
        assert_eq!(quadratic_roots(0.0, 2.0, -1.0), ([0.5, 0.0], 1));
        assert_eq!(quadratic_roots(0.0, 0.0, 1.0).1, 0);
    }

    #[test]
    fn near_zero_intervals_of_a_double_root() {
        // (t − 0.5)² · 4 = 4t² − 4t + 1: touches zero at 0.5 without a sign change
        let c = [1.0, -4.0, 4.0, 0.0];
        let mut out = Vec::new();
        near_zero_intervals(&c, 1e-12, 0.0, 1.0, &mut out);
        assert!(out.iter().any(|iv| iv.start <= 0.5 + 1e-6 && iv.end >= 0.5 - 1e-6), "{out:?}");
        // the zero polynomial is near zero everywhere
        out.clear();
        near_zero_intervals(&[0.0; 4], 0.0, 0.0, 1.0, &mut out);
        assert_eq!(out, vec![NearZero { start: 0.0, end: 1.0, root: None }]);
    }
}
