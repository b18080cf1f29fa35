//! The wall points of a scan (laser and sensor spots) grouped in a k-d tree, so that visibility from one
//! surface point can be settled for a whole group of spots at once ([`super::bundle::Bundle`]).

use glam::Vec3;

/// Largest number of points in a leaf.
const LEAF: usize = 8;

/// A node: the points at tree positions `start..end`, inside the sphere (`centre`, `radius`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Node {
    pub(crate) centre: Vec3,
    pub(crate) radius: f32,
    pub(crate) start: u32,
    pub(crate) end: u32,
    /// The first of the two children (the second follows it); 0 for a leaf (the root is never a child).
    pub(crate) child: u32,
}

/// A k-d tree over a set of wall points: median splits along the widest axis down to [`LEAF`] points.
#[derive(Debug, Clone)]
pub(crate) struct WallTree {
    /// The points in tree order.
    pub(crate) points: Vec<Vec3>,
    /// `index[i]`: the caller's number of the point at tree position `i`.
    pub(crate) index: Vec<u32>,
    /// `nodes[0]` is the root.
    pub(crate) nodes: Vec<Node>,
}

impl WallTree {
    /// The tree of `points` (at least one).
    pub(crate) fn new(points: &[Vec3]) -> Self {
        let mut index: Vec<u32> = (0..points.len() as u32).collect();
        let mut nodes = vec![bounds(points, &index, 0, points.len())];
        let mut todo = vec![0usize];
        while let Some(k) = todo.pop() {
            let (start, end) = (nodes[k].start as usize, nodes[k].end as usize);
            if end - start <= LEAF {
                continue;
            }
            let slice = &mut index[start..end];
            let (lo, hi) = slice.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &i| {
                (lo.min(points[i as usize]), hi.max(points[i as usize]))
            });
            let ext = hi - lo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = slice.len() / 2;
            slice.select_nth_unstable_by(mid, |&a, &b| points[a as usize][axis].total_cmp(&points[b as usize][axis]));
            let child = nodes.len();
            nodes[k].child = child as u32;
            nodes.push(bounds(points, &index, start, start + mid));
            nodes.push(bounds(points, &index, start + mid, end));
            todo.extend([child, child + 1]);
        }
        let points = index.iter().map(|&i| points[i as usize]).collect();
        Self { points, index, nodes }
    }
}

/// The leaf node of the points `index[start..end]`: the centre of their box and the farthest point's distance.
fn bounds(points: &[Vec3], index: &[u32], start: usize, end: usize) -> Node {
    let of = |i: &u32| points[*i as usize];
    let (lo, hi) = index[start..end]
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), i| (lo.min(of(i)), hi.max(of(i))));
    let centre = 0.5 * (lo + hi);
    let radius = index[start..end].iter().map(|i| (of(i) - centre).length()).fold(0.0f32, f32::max);
    Node { centre, radius, start: start as u32, end: end as u32, child: 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_point_once_and_inside_its_nodes() {
        let points: Vec<Vec3> = (0..37 * 23)
            .map(|i| Vec3::new((i % 37) as f32 * 0.01, (i / 37) as f32 * 0.02, 0.001 * (i % 5) as f32))
            .collect();
        let tree = WallTree::new(&points);
        let mut seen = vec![false; points.len()];
        for &i in &tree.index {
            assert!(!seen[i as usize]);
            seen[i as usize] = true;
        }
        assert!(seen.iter().all(|&s| s));
        for node in &tree.nodes {
            for p in &tree.points[node.start as usize..node.end as usize] {
                assert!((*p - node.centre).length() <= node.radius * (1.0 + 1e-6));
            }
            if node.child == 0 {
                assert!((node.end - node.start) as usize <= LEAF);
            } else {
                let (a, b) = (tree.nodes[node.child as usize], tree.nodes[node.child as usize + 1]);
                assert_eq!((a.start, a.end, b.end), (node.start, b.start, node.end));
            }
        }
        for (pos, &i) in tree.index.iter().enumerate() {
            assert_eq!(tree.points[pos], points[i as usize]);
        }
    }
}
