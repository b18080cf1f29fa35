//! Rim rounding: a surface from a volume's front view turned back toward its boundary, as a smooth closed
//! object's visible surface is.
//!
//! Seen along +z, a smooth object's visible surface meets its silhouette where the surface normal turns
//! perpendicular to the line of sight (the occluding contour; Koenderink, "What does the occluding contour
//! tell us about solid shape?", Perception 13, 1984): near its boundary the surface recedes steeply. A
//! depth map taken from a volume's column maxima does not: the lateral blur of the volumetric methods gives
//! the outer columns the depth of the brighter, nearer interior, so the mesh ends in a flat rim in front of
//! the receding flanks (on the bunny at Tsai et al. 2019's setup the LCT start's silhouette band is 17 mm off against 2 mm
//! inside). The optimiser's pruning then deletes that rim (its light arrives early) instead of bending it back.
//!
//! [`round_rim`] moves every vertex within `R` of the mesh's boundary (distance `d` along the mesh's edges,
//! measured in the wall plane) away from the wall by
//! ```text
//! Δz(d) = R − √(R² − (R − d)²)        (d < R; 0 beyond)
//! ```
//! the profile of a quarter circle of radius `R` that is vertical at the boundary (`Δz(0) = R`) and meets
//! the surface tangentially at `d = R`.
//!
//! Why it is an option, off by default: with R = 20 mm it is better on every metric on the soap bar and
//! gains coverage and Chamfer distance on the bunnies, but there it costs 0.1–1.2 mm of mean depth error
//! (docs/accuracy.md). Use it where a start's rim visibly stands in front of the object
//! ([`crate::SurfaceParams::rim_radius`]).

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

use glam::Vec3;

use crate::error::{InitError, Result};

/// Moves the vertices within `radius` (metres) of the mesh's boundary away from the wall along +z by the
/// quarter-circle profile of the module docs; returns how many moved.
///
/// The distance to the boundary is the shortest path along the triangles' edges, with edge lengths taken
/// in the wall plane (x, y). Boundary edges are those used by one triangle only; a mesh without boundary
/// (closed) is left unchanged. Vertices that no triangle uses are left unchanged.
///
/// # Errors
/// [`InitError::InvalidParameter`] for a radius that is not finite and > 0, and
/// [`InitError::InvalidParameter`] (`triangles`) for a triangle naming a vertex beyond `positions`.
///
/// # Examples
/// ```
/// use glam::Vec3;
/// // One quad, all four corners on the boundary: each recedes by the full radius.
/// let mut p = vec![Vec3::new(0.0, 0.0, 0.4), Vec3::new(0.1, 0.0, 0.4), Vec3::new(0.1, 0.1, 0.4), Vec3::new(0.0, 0.1, 0.4)];
/// let moved = nlos_init::round_rim(&mut p, &[[0, 2, 1], [0, 3, 2]], 0.02)?;
/// assert_eq!(moved, 4);
/// assert!(p.iter().all(|q| (q.z - 0.42).abs() < 1e-6));
/// # Ok::<(), nlos_init::InitError>(())
/// ```
pub fn round_rim(positions: &mut [Vec3], triangles: &[[u32; 3]], radius: f64) -> Result<usize> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(InitError::InvalidParameter {
            name: "rim_radius",
            value: radius,
            reason: "the rounding radius is a length in metres, finite and > 0",
        });
    }
    let n = positions.len();
    if let Some(&v) = triangles.iter().flatten().find(|&&v| v as usize >= n) {
        return Err(InitError::InvalidParameter {
            name: "triangles",
            value: f64::from(v),
            reason: "a triangle names a vertex beyond the positions",
        });
    }
    // Undirected edges with the number of triangles using each.
    let mut uses: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3);
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for &(a, b) in uses.keys() {
        neighbours[a as usize].push(b);
        neighbours[b as usize].push(a);
    }
    // Multi-source Dijkstra from the boundary vertices, cut off at the radius.
    let mut dist = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for (&(a, b), &count) in &uses {
        if count == 1 {
            for v in [a, b] {
                dist[v as usize] = 0.0;
                heap.push(Item(0.0, v));
            }
        }
    }
    while let Some(Item(d, v)) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        let p = positions[v as usize];
        for &u in &neighbours[v as usize] {
            let q = positions[u as usize];
            let nd = d + f64::from((q.x - p.x).hypot(q.y - p.y));
            if nd < dist[u as usize] && nd < radius {
                dist[u as usize] = nd;
                heap.push(Item(nd, u));
            }
        }
    }
    let mut moved = 0;
    for (p, &d) in positions.iter_mut().zip(&dist) {
        if d < radius {
            let s = radius - d;
            // Guard: s ≤ radius, so the root's argument is ≥ 0 up to rounding.
            p.z += (radius - (radius * radius - s * s).max(0.0).sqrt()) as f32;
            moved += 1;
        }
    }
    Ok(moved)
}

/// A heap entry ordered by smallest distance first.
#[derive(PartialEq)]
struct Item(f64, u32);
impl Eq for Item {}
impl Ord for Item {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}
impl PartialOrd for Item {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat `n × n`-cell grid of side `side` at depth `z`, two triangles per cell.
    fn grid(n: u32, side: f32, z: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let h = side / n as f32;
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                p.push(Vec3::new(i as f32 * h, j as f32 * h, z));
            }
        }
        let at = |i: u32, j: u32| i + (n + 1) * j;
        let mut t = Vec::new();
        for j in 0..n {
            for i in 0..n {
                t.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
                t.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            }
        }
        (p, t)
    }

    #[test]
    fn the_profile_is_a_quarter_circle_from_the_boundary_inward() {
        // 10 cells of 1 cm: the vertex k cells from the nearest side is k cm from the boundary.
        let (mut p, t) = grid(10, 0.1, 0.4);
        let before = p.clone();
        let r = 0.025;
        round_rim(&mut p, &t, r).expect("valid");
        for (v, (q, b)) in p.iter().zip(&before).enumerate() {
            let (i, j) = (v as u32 % 11, v as u32 / 11);
            let d = 0.01 * f64::from(i.min(j).min(10 - i).min(10 - j));
            let want = if d < r { r - (r * r - (r - d).powi(2)).sqrt() } else { 0.0 };
            assert!((f64::from(q.z - b.z) - want).abs() < 1e-6, "at {b}: moved {} not {want}", q.z - b.z);
            assert_eq!((q.x, q.y), (b.x, b.y), "only depth changes");
        }
        // The analytic special cases: the boundary recedes by R, d = R not at all.
        assert!((p[0].z - 0.425).abs() < 1e-6);
        assert_eq!(p[(3 + 11 * 5) as usize].z, 0.4);
    }

    #[test]
    fn a_closed_mesh_and_a_far_interior_are_unchanged() {
        // A tetrahedron has no boundary.
        let mut p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let t = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        assert_eq!(round_rim(&mut p, &t, 0.5).expect("valid"), 0);
        assert_eq!(p, vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]);
        // A radius below one edge length moves the boundary only.
        let (mut q, t) = grid(4, 0.4, 0.3);
        assert_eq!(round_rim(&mut q, &t, 0.05).expect("valid"), 16);
        assert_eq!(q.iter().filter(|v| v.z == 0.3).count(), 9);
    }

    #[test]
    fn bad_radius_and_indices_are_typed_errors() {
        let (mut p, t) = grid(2, 0.1, 0.4);
        for r in [0.0, -0.01, f64::NAN, f64::INFINITY] {
            assert!(matches!(round_rim(&mut p, &t, r), Err(InitError::InvalidParameter { name: "rim_radius", .. })));
        }
        assert!(matches!(
            round_rim(&mut p, &[[0, 1, 99]], 0.01),
            Err(InitError::InvalidParameter { name: "triangles", .. })
        ));
    }
}
