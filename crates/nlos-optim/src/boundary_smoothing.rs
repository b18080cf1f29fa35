//! Boundary smoothing: a regulariser on the mesh's boundary curves, the silhouette counterpart of the
//! normal smoothing of [`crate::regularizer`].
//!
//! The normal-smoothing term sees a boundary face only through its inner neighbours, so nothing keeps the
//! boundary itself in order: boundary vertices move freely (at their own learning rate), pruning deletes
//! single boundary faces, and the remesher refines what is left. On the bunny at Tsai et al. 2019's setup the fitted mesh's
//! boundary turned by a median 51° at each vertex (a smooth outline at that edge length turns by a few
//! degrees), its length grew from 3.5 m (the LCT start) to 7.3 m, 38 % of the vertices lay on it, and
//! those vertices carried most of the normal error and of the Chamfer distance (rims curled away from the
//! wall, 2–6 cm off the object).
//!
//! For every boundary vertex `v` with boundary neighbours `a` (before it along its loop) and `b` (after):
//! ```text
//! d_v = v − ½ (a + b),        R_∂ = Σ_v ‖d_v‖²
//! ∂R_∂/∂v += 2 d_v,   ∂R_∂/∂a −= d_v,   ∂R_∂/∂b −= d_v        (each contribution added)
//! ```
//! the umbrella operator of the boundary polyline (the discrete curve Laplacian; its flow is the discrete
//! curve-shortening flow). `R_∂` is zero on a straight boundary and, for a zig-zag of amplitude `h`, grows
//! as `h²` per vertex; on a smooth outline of radius `ρ` at edge length `ℓ` it is `ℓ⁴/(4ρ²)` per vertex,
//! negligible (ℓ = 5 mm, ρ = 10 cm: 1.6·10⁻⁹ m²), so it straightens jags, not the outline. It has the unit
//! of the normal-smoothing term (m²) and the same per-element size for a jag of about a radian (`‖d‖² ≈
//! 0.1 ℓ²` vs `A_f ‖n_f − m_f‖² ≈ 0.1 ℓ²`), and is added to it with the same weight λ, times
//! [`crate::ReconstructParams::boundary_smoothing`].
//!
//! A vertex on which several boundary loops meet (a pinch) has no single pair of neighbours and is left
//! out; so are loops of fewer than three vertices.
//!
//! **The enclosed area is held.** Curve shortening also shrinks: on a circle of radius `ρ` the umbrella
//! operator points inward with `‖d_v‖ ≈ ℓ²/(2ρ)`, and on a patch that is mostly rim (a few faces on a sparse
//! spot set, where the scan spacing sets the edge length) that pull dominates the shape step, the patch
//! contracts, and pruning deletes what contracted off the data. The descent direction
//! [`BoundarySmoothing::evaluate`] returns is therefore the gradient of `R_∂` with, per closed boundary loop,
//! its component along the gradient of the loop's enclosed area removed (the discrete counterpart of Gage's
//! area-preserving curve-shortening flow, M. Gage, "On an area-preserving evolution equation for plane
//! curves", Contemp. Math. 51, 1986). For a loop `x_0 … x_{m−1}` with vector area
//! ```text
//! a = ½ Σ_i x_i × x_{i+1},   â = a/‖a‖,   ∂(â·a)/∂x_i = ½ (x_{i+1} − x_{i−1}) × â =: q_i
//! g_i ← g_i − (Σ_j g_j·q_j / Σ_j q_j·q_j) q_i
//! ```
//! so a step along it straightens jags without changing, to first order, the area the loop encloses: the
//! outline moves only where the data term moves it. A loop through a pinch is not closed and keeps the
//! plain gradient.
//!
//! **Only where the patch is mostly rim.** On a component with an interior the contraction is useful: the
//! start's outline lies outside the object (the volume's halo), the data term fits the interior, and the
//! rim's pull trims the halo. Holding the area there pushed the soap bar's rim out (depth error inside the
//! silhouette 0.26 → 0.30 mm, RMS 0.83 → 1.18 mm). So the share of the area change removed is
//! `clamp((f − HOLD_FROM) / (HOLD_FULL − HOLD_FROM), 0, 1)`, `f` the share of the loop's component's
//! vertices that lie on its boundary: none below [`HOLD_FROM`] (the soap, the bunny, the chart's bar groups:
//! a few per cent to 20 %), all from [`HOLD_FULL`] on (a patch of a few faces on a sparse spot set: 60–90 %).

use glam::{DVec3, Vec3};
use std::collections::HashMap;

use crate::error::{OptimError, Result};
use crate::regularizer::check_indices;

/// Share of a component's vertices on its boundary below which its loops' area is not held.
pub const HOLD_FROM: f64 = 0.25;

/// Share of a component's vertices on its boundary from which its loops' area is held fully.
pub const HOLD_FULL: f64 = 0.5;

/// The boundary-smoothing regulariser for one topology (the boundary chains are precomputed).
#[derive(Debug, Clone, PartialEq)]
pub struct BoundarySmoothing {
    /// Per boundary vertex `v`, `[a, v, b]`: its neighbours before and after it along its boundary loop.
    pub chains: Vec<[u32; 3]>,
    /// The closed boundary loops, each with the share of its area change a step removes (module docs).
    loops: Vec<(Vec<u32>, f64)>,
    n_vertices: usize,
}

impl BoundarySmoothing {
    /// Finds the boundary loops of `triangles` (edges used by one triangle) over `n_vertices` vertices.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a vertex index out of range.
    pub fn new(n_vertices: usize, triangles: &[[u32; 3]]) -> Result<Self> {
        check_indices(n_vertices, triangles)?;
        let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3);
        for t in triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        // A boundary half-edge a → b has no twin b → a. Count per vertex how many leave and enter it.
        let (mut next, mut prev) = (vec![u32::MAX; n_vertices], vec![u32::MAX; n_vertices]);
        let (mut outs, mut ins) = (vec![0u8; n_vertices], vec![0u8; n_vertices]);
        for &(a, b) in directed.keys() {
            if !directed.contains_key(&(b, a)) {
                next[a as usize] = b;
                prev[b as usize] = a;
                outs[a as usize] = outs[a as usize].saturating_add(1);
                ins[b as usize] = ins[b as usize].saturating_add(1);
            }
        }
        let mut chains: Vec<[u32; 3]> = (0..n_vertices)
            .filter(|&v| outs[v] == 1 && ins[v] == 1 && prev[v] != next[v])
            .map(|v| [prev[v], v as u32, next[v]])
            .collect();
        chains.sort_unstable_by_key(|c| c[1]);
        let hold = hold_weights(n_vertices, triangles, &outs);
        let loops = closed_loops(&chains, n_vertices)
            .into_iter()
            .map(|lp| {
                let h = hold[lp[0] as usize];
                (lp, h)
            })
            .collect();
        Ok(Self { chains, loops, n_vertices })
    }

    /// `R_∂` and its descent direction for every vertex: the gradient with each closed loop's area-changing
    /// component removed (module docs); zero off the boundary.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] when `positions` does not have the length the chains were built for.
    pub fn evaluate(&self, positions: &[Vec3]) -> Result<(f64, Vec<Vec3>)> {
        let (value, mut grad) = self.gradient(positions)?;
        let p = |i: u32| positions[i as usize].as_dvec3();
        for (lp, hold) in self.loops.iter().filter(|(_, h)| *h > 0.0) {
            let m = lp.len();
            let area: DVec3 = (0..m).map(|i| p(lp[i]).cross(p(lp[(i + 1) % m]))).sum::<DVec3>() * 0.5;
            // A loop folded onto itself (zero vector area) has no area to hold.
            let Some(n) = area.try_normalize() else { continue };
            let q: Vec<DVec3> = (0..m).map(|i| 0.5 * (p(lp[(i + 1) % m]) - p(lp[(i + m - 1) % m])).cross(n)).collect();
            let qq: f64 = q.iter().map(|q| q.length_squared()).sum();
            if qq <= 0.0 {
                continue;
            }
            let gq: f64 = lp.iter().zip(&q).map(|(&v, q)| grad[v as usize].dot(*q)).sum();
            for (&v, q) in lp.iter().zip(&q) {
                grad[v as usize] -= (hold * gq / qq) * *q;
            }
        }
        Ok((value, grad.into_iter().map(|g| g.as_vec3()).collect()))
    }

    /// `R_∂` and its plain gradient (f64), before the area is held.
    fn gradient(&self, positions: &[Vec3]) -> Result<(f64, Vec<DVec3>)> {
        if positions.len() != self.n_vertices {
            return Err(OptimError::LengthMismatch {
                what: "positions",
                expected: self.n_vertices,
                got: positions.len(),
            });
        }
        let mut grad = vec![DVec3::ZERO; positions.len()];
        let mut value = 0.0;
        let p = |i: u32| positions[i as usize].as_dvec3();
        for &[a, v, b] in &self.chains {
            let d = p(v) - 0.5 * (p(a) + p(b));
            value += d.length_squared();
            grad[v as usize] += 2.0 * d;
            grad[a as usize] -= d;
            grad[b as usize] -= d;
        }
        Ok((value, grad))
    }
}

/// Per vertex, the share of its boundary loops' area change a step removes: 0 on a component with fewer
/// than [`HOLD_FROM`] of its vertices on its boundary, 1 from [`HOLD_FULL`] on, linear between (module docs).
fn hold_weights(n_vertices: usize, triangles: &[[u32; 3]], boundary_outs: &[u8]) -> Vec<f64> {
    let mut sets = nlos_mesh::UnionFind::new(n_vertices);
    let mut used = vec![false; n_vertices];
    for t in triangles {
        for &v in t {
            used[v as usize] = true;
            sets.union(t[0], v);
        }
    }
    let (mut all, mut rim) = (vec![0usize; n_vertices], vec![0usize; n_vertices]);
    for v in (0..n_vertices).filter(|&v| used[v]) {
        let r = sets.find(v as u32) as usize;
        all[r] += 1;
        rim[r] += usize::from(boundary_outs[v] > 0);
    }
    (0..n_vertices)
        .map(|v| {
            let r = sets.find(v as u32) as usize;
            let f = rim[r] as f64 / all[r].max(1) as f64;
            ((f - HOLD_FROM) / (HOLD_FULL - HOLD_FROM)).clamp(0.0, 1.0)
        })
        .collect()
}

/// The closed loops the chains form (each vertex once, in boundary order); a loop through a pinch vertex,
/// which has no chain, does not close and is left out.
fn closed_loops(chains: &[[u32; 3]], n_vertices: usize) -> Vec<Vec<u32>> {
    let mut next = vec![u32::MAX; n_vertices];
    for &[_, v, b] in chains {
        next[v as usize] = b;
    }
    let mut seen = vec![false; n_vertices];
    let mut loops = Vec::new();
    for &[_, start, _] in chains {
        if seen[start as usize] {
            continue;
        }
        let mut lp = vec![start];
        seen[start as usize] = true;
        let mut v = next[start as usize];
        while v != start && v != u32::MAX && !seen[v as usize] {
            seen[v as usize] = true;
            lp.push(v);
            v = next[v as usize];
        }
        if v == start && lp.len() >= 3 {
            loops.push(lp);
        }
    }
    loops
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An n × n vertex grid in the plane z = 0.4, spacing 1 cm, with `h(i)` added to vertex i's position.
    fn grid(n: usize, h: impl Fn(usize) -> Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..n {
            for i in 0..n {
                p.push(Vec3::new(0.01 * i as f32, 0.01 * j as f32, 0.4) + h(i + n * j));
            }
        }
        let mut t = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (i + n * j) as u32;
                let n = n as u32;
                t.push([v, v + 1, v + n + 1]);
                t.push([v, v + n + 1, v + n]);
            }
        }
        (p, t)
    }

    #[test]
    fn straight_boundary_is_zero_and_a_bump_costs_one_and_a_half_h_squared() {
        let (p, t) = grid(5, |_| Vec3::ZERO);
        let reg = BoundarySmoothing::new(p.len(), &t).expect("chains");
        // The 16 outer vertices; the 4 corners turn by 90° and cost (½ · 1 cm · √2)² = 0.5 cm² each.
        assert_eq!(reg.chains.len(), 16);
        let (r, g) = reg.evaluate(&p).expect("value");
        assert!((r - 4.0 * 0.5e-4).abs() < 1e-9, "{r}");
        assert!(g[12] == Vec3::ZERO, "interior vertex");
        // Vertex 2 (middle of the bottom edge) pushed out by h: it costs h², its two neighbours (h/2)² each.
        let h = 0.003f32;
        let (q, _) = grid(5, |i| if i == 2 { Vec3::new(0.0, -h, 0.0) } else { Vec3::ZERO });
        let (r2, g2) = reg.gradient(&q).expect("value");
        let expect = 1.5 * f64::from(h).powi(2);
        assert!((r2 - r - expect).abs() < 1e-9, "{} vs {expect}", r2 - r);
        // ∂R/∂v₂ = 2 d₂ − d₁ − d₃ = 2δ + δ/2 + δ/2 = 3δ, δ = −h along y.
        assert!((g2[2].y - (-3.0 * f64::from(h))).abs() < 1e-6, "{:?}", g2[2]);
    }

    #[test]
    fn gradient_matches_finite_differences_on_a_jagged_boundary() {
        let jag = |i: usize| {
            let s = (i as f32 * 12.9898).sin() * 43758.547;
            let r = s - s.floor() - 0.5;
            Vec3::new(0.004 * r, -0.003 * r, 0.006 * (r * 7.0).sin())
        };
        let (p, t) = grid(6, jag);
        let reg = BoundarySmoothing::new(p.len(), &t).expect("chains");
        let (_, g) = reg.gradient(&p).expect("value");
        let eps = 1e-4f32;
        for v in [0usize, 1, 3, 5, 6, 11, 30, 35, 14] {
            for k in 0..3 {
                let mut plus = p.clone();
                let mut minus = p.clone();
                plus[v][k] += eps;
                minus[v][k] -= eps;
                let fd = (reg.evaluate(&plus).expect("value").0 - reg.evaluate(&minus).expect("value").0)
                    / (2.0 * f64::from(eps));
                let an = g[v][k];
                assert!((fd - an).abs() <= 1e-3 * an.abs().max(1e-4), "vertex {v} axis {k}: fd {fd} analytic {an}");
            }
        }
    }

    /// The vector area of a mesh's one boundary loop.
    fn loop_area(reg: &BoundarySmoothing, p: &[Vec3]) -> DVec3 {
        assert_eq!(reg.loops.len(), 1);
        let lp = &reg.loops[0].0;
        let m = lp.len();
        (0..m).map(|i| p[lp[i] as usize].as_dvec3().cross(p[lp[(i + 1) % m] as usize].as_dvec3())).sum::<DVec3>() * 0.5
    }

    #[test]
    fn a_step_holds_the_enclosed_area_and_still_straightens_a_jag() {
        // A fan of 12 triangles: its rim a regular 12-gon of radius 5 cm, which plain curve shortening shrinks.
        let m = 12u32;
        let mut p = vec![Vec3::new(0.0, 0.0, 0.5)];
        p.extend((0..m).map(|i| {
            let phi = std::f32::consts::TAU * i as f32 / m as f32;
            Vec3::new(0.05 * phi.cos(), 0.05 * phi.sin(), 0.5)
        }));
        let t: Vec<[u32; 3]> = (0..m).map(|i| [0, 1 + i, 1 + (i + 1) % m]).collect();
        let reg = BoundarySmoothing::new(p.len(), &t).expect("chains");
        assert_eq!(reg.loops[0].0.len(), 12);
        let step = |g: &[Vec3]| -> Vec<Vec3> { p.iter().zip(g).map(|(p, g)| *p - 0.1 * *g).collect() };
        let a0 = loop_area(&reg, &p).length();
        let (_, plain) = reg.gradient(&p).expect("value");
        let plain: Vec<Vec3> = plain.iter().map(|g| g.as_vec3()).collect();
        let (_, held) = reg.evaluate(&p).expect("value");
        let (a_plain, a_held) = (loop_area(&reg, &step(&plain)).length(), loop_area(&reg, &step(&held)).length());
        assert!(a0 - a_plain > 1e-3 * a0, "plain curve shortening shrinks: {a0} → {a_plain}");
        assert!((a_held - a0).abs() < 1e-3 * (a0 - a_plain), "held: {a0} → {a_held} (plain {a_plain})");
        // On a circle all of the flow is the shrinking: nothing is left to move.
        assert!(held.iter().all(|g| g.length() < 1e-6), "{held:?}");
        // A bump on a grid's straight edge: the held direction still pulls it back in and lowers R_∂.
        let h = 0.003f32;
        let (q, t) = grid(5, |i| if i == 2 { Vec3::new(0.0, -h, 0.0) } else { Vec3::ZERO });
        let reg = BoundarySmoothing::new(q.len(), &t).expect("chains");
        let (r0, g) = reg.evaluate(&q).expect("value");
        assert!(g[2].y < -2.0 * h, "{:?}", g[2]);
        let moved: Vec<Vec3> = q.iter().zip(&g).map(|(p, g)| *p - 0.1 * *g).collect();
        assert!(reg.evaluate(&moved).expect("value").0 < r0, "the held step lowers R_∂");
    }

    #[test]
    fn a_patch_with_an_interior_shrinks_as_plain_curve_shortening() {
        // 20 × 20 vertices, 76 on the boundary (19 %, below HOLD_FROM): the plain gradient, jag or not.
        let jag = |i: usize| if i % 7 == 3 { Vec3::new(0.002, -0.001, 0.0) } else { Vec3::ZERO };
        let (p, t) = grid(20, jag);
        let reg = BoundarySmoothing::new(p.len(), &t).expect("chains");
        assert_eq!(reg.loops.len(), 1);
        assert_eq!(reg.loops[0].1, 0.0);
        let (_, held) = reg.evaluate(&p).expect("value");
        let (_, plain) = reg.gradient(&p).expect("value");
        assert!(held.iter().zip(&plain).all(|(h, g)| (h.as_dvec3() - *g).length() < 1e-9));
        // 8 × 8 (28 of 64 on the boundary, 44 %): held in part, between the two.
        let (p, t) = grid(8, |_| Vec3::ZERO);
        let w = BoundarySmoothing::new(p.len(), &t).expect("chains").loops[0].1;
        let expect = (28.0 / 64.0 - HOLD_FROM) / (HOLD_FULL - HOLD_FROM);
        assert!((w - expect).abs() < 1e-12, "{w} vs {expect}");
    }

    #[test]
    fn closed_surface_has_no_boundary_and_bad_input_is_an_error() {
        // A tetrahedron: no boundary, nothing to smooth.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let t = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let reg = BoundarySmoothing::new(4, &t).expect("chains");
        assert!(reg.chains.is_empty());
        assert_eq!(reg.evaluate(&p).expect("value").0, 0.0);
        assert!(BoundarySmoothing::new(3, &t).is_err());
        assert!(matches!(reg.evaluate(&p[..3]), Err(OptimError::LengthMismatch { .. })));
    }
}
