//! The normal-smoothing regulariser of Delaunoy & Prados ("Gradient flows for optimizing triangular
//! mesh-based surfaces: applications to 3D reconstruction problems dealing with visibility", IJCV 2011),
//! as used by Tsai et al. 2019 (Sec. 5): each face's unit normal is compared with the area-weighted mean
//! of its neighbours' normals.
//!
//! With `u_f = (v1 − v0) × (v2 − v0)` (so `A_f = |u_f|/2`, `n_f = u_f/|u_f|`) and `N(f)` the faces sharing
//! an edge with `f`:
//! ```text
//! m_f = Σ_{g∈N(f)} A_g n_g / Σ_{g∈N(f)} A_g = S_f / W_f,   S_f = Σ_g u_g,  W_f = Σ_g |u_g|
//! R   = Σ_f A_f ‖n_f − m_f‖²
//! ```
//! R is zero exactly when every face is parallel to its neighbours' mean (a flat or uniformly planar
//! patch), and invariant to translation, rotation and uniform refinement of a plane.
//!
//! **Gradient** (reverse mode, exact): with `d_f = n_f − m_f`, `a = |u_f|`,
//! ```text
//! ∂R/∂u_f  += ½‖d_f‖² n_f + (d_f − n_f (n_f·d_f))                  (through A_f and n_f)
//! ∂R/∂u_g  += G/W_f − (G·m_f / W_f) n_g,  G = −a d_f,  g ∈ N(f)      (through m_f)
//! ∂R/∂v1 += e2 × ∂R/∂u, ∂R/∂v2 += ∂R/∂u × e1, ∂R/∂v0 −= both        (u = e1 × e2)
//! ```
//! and every contribution is **added** into the vertex gradient: a vertex receives a term from every
//! incident face and from every face that has one of those as neighbour. (The original code overwrote the
//! vertex gradient with the last face's contribution; the regression test
//! `regression_vertex_gradient_overwritten_instead_of_summed` fails on such an implementation.)
//!
//! **Automatic weight** ([`auto_weight`]): Tsai et al. 2019 balance the terms by their ratio, `λ = β E_data / R`,
//! so the regulariser contributes a fixed fraction β of the data term when the weight is set. It is set at
//! the start of every shape block and held fixed within it (Adam sees one objective per block).

use glam::{DVec3, Vec3};
use std::collections::HashMap;

use crate::error::{OptimError, Result};

/// Marker for "no neighbour across this edge" in [`NormalSmoothing::neighbours`].
pub const NO_FACE: u32 = u32::MAX;

/// Checks that every triangle names vertices below `n_vertices`.
///
/// # Errors
/// [`OptimError::InvalidParameter`] (value: the largest offending vertex index) otherwise.
pub(crate) fn check_indices(n_vertices: usize, triangles: &[[u32; 3]]) -> Result<()> {
    match triangles.iter().flatten().copied().filter(|&v| v as usize >= n_vertices).max() {
        Some(v) => Err(OptimError::InvalidParameter {
            name: "triangles",
            value: f64::from(v),
            reason: "a triangle refers to a vertex that does not exist",
        }),
        None => Ok(()),
    }
}

/// The normal-smoothing regulariser for one topology (the face adjacency is precomputed).
#[derive(Debug, Clone, PartialEq)]
pub struct NormalSmoothing {
    /// Per face, the faces across its edges `(v0 v1)`, `(v1 v2)`, `(v2 v0)` ([`NO_FACE`] on the boundary).
    pub neighbours: Vec<[u32; 3]>,
    n_vertices: usize,
}

impl NormalSmoothing {
    /// Builds the edge adjacency of `triangles` over `n_vertices` vertices. A non-manifold edge (more than
    /// two faces) links each face to the first other face found.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a vertex index out of range.
    pub fn new(n_vertices: usize, triangles: &[[u32; 3]]) -> Result<Self> {
        check_indices(n_vertices, triangles)?;
        let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::with_capacity(triangles.len() * 2);
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.entry((a.min(b), a.max(b))).or_default().push(f as u32);
            }
        }
        let neighbours = triangles
            .iter()
            .enumerate()
            .map(|(f, t)| {
                let mut nb = [NO_FACE; 3];
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    if let Some(fs) = edges.get(&(a.min(b), a.max(b))) {
                        nb[k] = fs.iter().copied().find(|&g| g != f as u32).unwrap_or(NO_FACE);
                    }
                }
                nb
            })
            .collect();
        Ok(Self { neighbours, n_vertices })
    }

    /// `(R, ∂R/∂positions)` (module docs). Computed in f64.
    ///
    /// # Errors
    /// [`OptimError::LengthMismatch`] when `positions` or `triangles` do not match the topology.
    pub fn evaluate(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<(f64, Vec<Vec3>)> {
        if positions.len() != self.n_vertices {
            return Err(OptimError::LengthMismatch {
                what: "positions",
                expected: self.n_vertices,
                got: positions.len(),
            });
        }
        if triangles.len() != self.neighbours.len() {
            return Err(OptimError::LengthMismatch {
                what: "triangles",
                expected: self.neighbours.len(),
                got: triangles.len(),
            });
        }
        let (r, du) = self.face_terms(positions, triangles);
        let p = |i: u32| positions[i as usize].as_dvec3();
        let mut grad = vec![DVec3::ZERO; positions.len()];
        for (f, t) in triangles.iter().enumerate() {
            let (p0, p1, p2) = (p(t[0]), p(t[1]), p(t[2]));
            let (e1, e2) = (p1 - p0, p2 - p0);
            let (d1, d2) = (e2.cross(du[f]), du[f].cross(e1));
            // Summed (+=), never assigned: each vertex collects the terms of all its faces.
            grad[t[0] as usize] -= d1 + d2;
            grad[t[1] as usize] += d1;
            grad[t[2] as usize] += d2;
        }
        Ok((r, grad.iter().map(|g| g.as_vec3()).collect()))
    }

    /// `R` and `∂R/∂u_f` per face (zero for degenerate faces).
    fn face_terms(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> (f64, Vec<DVec3>) {
        let nf = triangles.len();
        let p = |i: u32| positions[i as usize].as_dvec3();
        let mut u = Vec::with_capacity(nf);
        let mut len = Vec::with_capacity(nf);
        for t in triangles {
            let (p0, p1, p2) = (p(t[0]), p(t[1]), p(t[2]));
            let uf = (p1 - p0).cross(p2 - p0);
            u.push(uf);
            len.push(uf.length());
        }
        // Guard: a degenerate face (|u| ≈ 0) has no normal: it neither contributes a term nor counts as a
        // neighbour, and receives no gradient (|u| is not differentiable at 0).
        let ok = |g: usize| len[g] > 1e-30 && len[g].is_finite();
        let mut du = vec![DVec3::ZERO; nf];
        let mut r = 0.0f64;
        for f in 0..nf {
            if !ok(f) {
                continue;
            }
            let (mut s, mut w) = (DVec3::ZERO, 0.0f64);
            for &g in &self.neighbours[f] {
                if g != NO_FACE && ok(g as usize) {
                    s += u[g as usize];
                    w += len[g as usize];
                }
            }
            if w <= 0.0 {
                continue;
            }
            let a = len[f];
            let n = u[f] / a;
            let m = s / w;
            let d = n - m;
            let d2 = d.length_squared();
            r += 0.5 * a * d2;
            du[f] += 0.5 * d2 * n + (d - n * n.dot(d));
            let gm = -a * d;
            let gmm = gm.dot(m) / w;
            for &g in &self.neighbours[f] {
                if g != NO_FACE && ok(g as usize) {
                    let g = g as usize;
                    du[g] += gm / w - gmm * (u[g] / len[g]);
                }
            }
        }
        (r, du)
    }
}

/// The automatic regulariser weight `λ = β · E_data / max(R, ε_R)` (module docs), with the guard
/// `ε_R = 1e-2 · total_area`: a nearly flat mesh (R → 0, e.g. a planar initialisation) would otherwise get an
/// unbounded λ that freezes it; `1e-2 · area` is the R of an RMS normal deviation of 0.1 rad (6°) from the
/// neighbours' mean, so below that roughness the weight stops growing.
/// Returns 0 when the data term is not positive and finite.
pub fn auto_weight(beta: f64, data: f64, reg: f64, total_area: f64) -> f64 {
    let floor = (1e-2 * total_area).max(f64::MIN_POSITIVE);
    let l = beta * data / reg.max(floor);
    if l.is_finite() && l > 0.0 { l } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random number in [-1, 1).
    fn hash(i: u32) -> f32 {
        let x = i.wrapping_mul(2_654_435_761).rotate_left(13).wrapping_mul(0x9E37_79B9);
        (x >> 8) as f32 / (1u32 << 23) as f32 - 1.0
    }

    /// A 5×4 grid of quads (interior vertices of valence 6), with heights from `h`.
    fn grid(h: impl Fn(usize) -> f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let (nx, ny) = (5usize, 4usize);
        let mut p = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                let k = p.len();
                p.push(Vec3::new(i as f32 * 0.1 + 0.01 * hash(3 * k as u32), j as f32 * 0.1, h(k)));
            }
        }
        let id = |i: usize, j: usize| (i + (nx + 1) * j) as u32;
        let mut t = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (p, t)
    }

    fn check_fd(p: &[Vec3], t: &[[u32; 3]]) {
        let reg = NormalSmoothing::new(p.len(), t).expect("valid");
        let (_, g) = reg.evaluate(p, t).expect("ok");
        let h = 1e-3f32;
        for v in 0..p.len() {
            for k in 0..3 {
                let mut pp = p.to_vec();
                pp[v][k] += h;
                let rp = reg.evaluate(&pp, t).expect("ok").0;
                pp[v][k] -= 2.0 * h;
                let rm = reg.evaluate(&pp, t).expect("ok").0;
                let fd = (rp - rm) / (2.0 * f64::from(h));
                let an = f64::from(g[v][k]);
                assert!((fd - an).abs() < 2e-3 * (1.0 + fd.abs()), "vertex {v} axis {k}: fd {fd} analytic {an}");
            }
        }
    }

    #[test]
    fn gradient_matches_finite_differences_on_a_bumpy_grid() {
        let (p, t) = grid(|k| 0.03 * hash(k as u32 + 77));
        check_fd(&p, &t);
    }

    /// The buggy scatter of the original code: `g[v] = …` (the last face wins) instead of `g[v] += …`.
    fn overwriting_gradient(reg: &NormalSmoothing, p: &[Vec3], t: &[[u32; 3]]) -> Vec<Vec3> {
        let (_, du) = reg.face_terms(p, t);
        let mut g = vec![Vec3::ZERO; p.len()];
        for (f, tri) in t.iter().enumerate() {
            let (e1, e2) = (
                (p[tri[1] as usize] - p[tri[0] as usize]).as_dvec3(),
                (p[tri[2] as usize] - p[tri[0] as usize]).as_dvec3(),
            );
            let (d1, d2) = (e2.cross(du[f]), du[f].cross(e1));
            g[tri[0] as usize] = (-(d1 + d2)).as_vec3();
            g[tri[1] as usize] = d1.as_vec3();
            g[tri[2] as usize] = d2.as_vec3();
        }
        g
    }

    /// The original implementation assigned each face's contribution to its vertices instead of adding it,
    /// so a vertex kept only the last incident face's term. On a mesh whose interior vertices belong to six
    /// faces, the summed gradient equals the finite difference at every vertex; the overwriting one does not.
    #[test]
    fn regression_vertex_gradient_overwritten_instead_of_summed() {
        let (p, t) = grid(|k| 0.05 * hash(k as u32 * 5 + 1));
        assert!((0..p.len()).any(|v| t.iter().filter(|f| f.contains(&(v as u32))).count() == 6));
        check_fd(&p, &t);
        let reg = NormalSmoothing::new(p.len(), &t).expect("valid");
        let (_, good) = reg.evaluate(&p, &t).expect("ok");
        let bad = overwriting_gradient(&reg, &p, &t);
        let worst = good.iter().zip(&bad).map(|(a, b)| (*a - *b).length() / (1e-6 + a.length())).fold(0.0, f32::max);
        assert!(worst > 0.1, "the overwriting gradient should be far from the true one (rel. diff {worst})");
    }

    #[test]
    fn flat_mesh_has_zero_regulariser_and_gradient() {
        // Tilted plane z = 0.3 x − 0.2 y + 0.5, irregular in-plane positions.
        let (mut p, t) = grid(|_| 0.0);
        for q in &mut p {
            q.z = 0.3 * q.x - 0.2 * q.y + 0.5;
        }
        let reg = NormalSmoothing::new(p.len(), &t).expect("valid");
        let (r, g) = reg.evaluate(&p, &t).expect("ok");
        assert!(r.abs() < 1e-12, "R = {r}");
        assert!(g.iter().all(|x| x.length() < 1e-5), "max |g| = {}", g.iter().map(|x| x.length()).fold(0.0, f32::max));
    }

    #[test]
    fn auto_weight_balances_and_guards() {
        assert!((auto_weight(0.1, 2.0, 4.0, 1.0) - 0.05).abs() < 1e-15);
        // Flat mesh: R = 0 → floored, finite.
        assert!((auto_weight(0.1, 2.0, 0.0, 1.0) - 0.1 * 2.0 / 1e-2).abs() < 1e-9);
        assert_eq!(auto_weight(0.1, f64::NAN, 1.0, 1.0), 0.0);
    }

    #[test]
    fn rejects_bad_indices_and_lengths() {
        assert!(NormalSmoothing::new(2, &[[0, 1, 2]]).is_err());
        let reg = NormalSmoothing::new(3, &[[0, 1, 2]]).expect("valid");
        assert!(reg.evaluate(&[Vec3::ZERO; 2], &[[0, 1, 2]]).is_err());
    }
}
