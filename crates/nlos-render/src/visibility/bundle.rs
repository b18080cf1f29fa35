//! Visibility of every wall point from one surface point at once: the row the visibility cache needs per
//! face (or sub-face centroid).
//!
//! The segments from a surface point `x` to the wall points of a [`WallTree`] node lie in the cone with apex
//! `x` around the node's bounding ball. A triangle can block one of them only if it reaches that cone and lies,
//! at least in part, in front of the plane through `x` that the face's normal `n` defines (segments to the points
//! the face sees leave `x` into that open half-space), and unless a plane through `x` and one of its edges leaves
//! the whole cone on its far side.
//!
//! The two trees are walked together (a dual-tree traversal): each wall node holds a list of *candidates*, BVH
//! nodes and triangles that may reach its cone. Its children keep those that reach theirs, and open a BVH node
//! that is wider than the cone where it stands (its children replace it, tested in turn). A wall node without
//! candidates is visible from `x` as a whole; a leaf's points with candidates left get one segment each, tested
//! against the candidates (a triangle directly, a BVH node by a ray through its subtree) by the ray–triangle
//! test [`Bvh::visible`] makes. Every cull is conservative, with margins above f32 rounding, so the answer is
//! the one a ray per point gives; points at grazing elevation (below [`GRAZING`]) and points near the face's
//! plane always get their own ray through the whole BVH.
//!
//! Cost: a face whose view of the wall is clear costs a cone traversal of the BVH's top instead of one ray per
//! wall point; rays are left only where a shadow boundary crosses the wall, and they start from the BVH nodes
//! already found near their path.

use glam::{Vec3, Vec3A};
use obvhs::ray::Ray;

use super::wall::WallTree;
use super::{Bvh, segment};

/// Sine of the elevation (above the face's plane) below which a point is always given its own ray: the plane
/// cull's margin [`PLANE_MARGIN`] is then within `PLANE_MARGIN / GRAZING` (0.13 mm) of `x`.
const GRAZING: f32 = 0.003;
/// Height above the face's plane (metres) up to which a triangle counts as behind it: f32 rounding of the
/// heights of the face's own neighbours, which share its edges, is about 1e-7 m within a metre of the origin.
const PLANE_MARGIN: f32 = 4e-7;
/// A point lower than this below the face's plane (metres) is behind it: its answer is not computed.
const BEHIND: f32 = 1e-5;
/// A leaf's points with more candidates than this get a ray through the whole BVH.
const DIRECT: usize = 96;
/// A BVH node is opened when its ball's radius exceeds this share of the cone's radius at its distance.
const OPEN: f32 = 1.0;
/// The flag of a candidate code that names a BVH node (else a BVH primitive).
const NODE: u32 = 1 << 31;

/// A cone with apex `x` holding every segment from `x` to a ball of wall points.
#[derive(Debug, Clone, Copy)]
struct Cone {
    axis: Vec3,
    cos: f32,
    sin: f32,
    /// Farthest distance from `x` inside the ball.
    len: f32,
    /// False when `x` is inside the ball: every direction counts.
    narrow: bool,
}

impl Cone {
    fn new(x: Vec3, centre: Vec3, radius: f32) -> Self {
        let v = centre - x;
        let d = v.length();
        let r = radius * (1.0 + 1e-4) + 1e-6;
        if !(d > r) {
            return Self { axis: Vec3::Z, cos: -1.0, sin: 1.0, len: d + r, narrow: false };
        }
        let sin = r / d;
        Self { axis: v / d, cos: (1.0 - sin * sin).sqrt(), sin, len: d + r, narrow: true }
    }
}

/// A BVH node or triangle that may block some segments from `x`, as seen from `x`: the offset `w` of its
/// bounding ball's centre, the ball's (padded) radius `r`, `|w|` and `√(|w|² − r²)` (0 when the ball holds
/// `x`), and for a triangle the three planes through `x` and each of its edges (unit normals, the triangle on
/// their non-positive side; zero where `x` is in line with the edge, and for a node). Everything a cone test
/// needs but the cone.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    /// A BVH node (`NODE | index`) or primitive.
    code: u32,
    w: Vec3,
    r: f32,
    dist: f32,
    tangent: f32,
    edges: [Vec3; 3],
}

impl Candidate {
    fn ball(code: u32, x: Vec3, (q, r): (Vec3, f32)) -> Self {
        let w = q - x;
        let r = r * (1.0 + 1e-4) + 1e-6;
        let d2 = w.length_squared();
        let tangent = if d2 > r * r { (d2 - r * r).sqrt() } else { 0.0 };
        Self { code, w, r, dist: d2.sqrt(), tangent, edges: [Vec3::ZERO; 3] }
    }

    /// Whether the ball may reach the cone (outside iff the angle between `w` and the axis exceeds
    /// θ + asin(r/|w|): cos∠ < cos θ cos β − sin θ sin β, multiplied through by |w|), unless one of the edge
    /// planes leaves the whole cone on its far side (angle to the axis below 90° − θ, with a margin).
    #[inline(always)]
    fn reaches(&self, cone: &Cone) -> bool {
        if self.tangent != 0.0 {
            if self.dist - self.r > cone.len {
                return false;
            }
            if cone.narrow && self.w.dot(cone.axis) < cone.cos * self.tangent - cone.sin * self.r {
                return false;
            }
        }
        self.code & NODE != 0 || !(cone.narrow && self.edges.iter().any(|m| m.dot(cone.axis) > cone.sin + 1e-4))
    }

    /// Whether a BVH node is wide enough, against the cone's radius where it stands, to be opened.
    #[inline(always)]
    fn wide(&self, cone: &Cone) -> bool {
        self.code & NODE != 0 && (self.tangent == 0.0 || self.r > OPEN * cone.sin * self.dist)
    }
}

/// Reused buffers of one thread.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    candidates: Vec<Candidate>,
    stack: Vec<u32>,
}

/// The query: the mesh's BVH and the wall's tree.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bundle<'a> {
    pub(crate) bvh: &'a Bvh,
    pub(crate) wall: &'a WallTree,
}

/// One query's fixed part: the apex, the face's unit normal, `n·x`, the face's own triangle.
#[derive(Debug, Clone, Copy)]
struct Apex {
    x: Vec3,
    n: Vec3,
    h0: f32,
    own: u32,
}

impl Bundle<'_> {
    /// For every wall point `p` of the tree with `n·(p − x) > −1e-5 m` (`n` a unit normal of the plane of the
    /// mesh triangle `own`, through `x`): whether the segment from `x` to `p` is free of the mesh, as
    /// [`Bvh::visible`]`(x, p, own)` answers. `out` is indexed by the caller's point numbers; points farther
    /// behind the plane are set false.
    pub(crate) fn visible_from(&self, x: Vec3, n: Vec3, own: u32, out: &mut [bool], scratch: &mut Scratch) {
        let apex = Apex { x, n, h0: n.dot(x), own };
        let root = self.wall.nodes[0];
        let cone = Cone::new(x, root.centre, root.radius);
        scratch.candidates.clear();
        if !self.bvh.bin.nodes.is_empty() {
            self.open(NODE, &apex, &cone, scratch);
        }
        let all = scratch.candidates.len();
        self.descend(0, 0..all, &apex, out, scratch);
    }

    /// Pushes onto the candidates what of BVH node `code` (`NODE | index`) may reach `cone`: the node itself,
    /// or, where it is wide, its children's candidates; a leaf's triangles one by one.
    fn open(&self, code: u32, apex: &Apex, cone: &Cone, scratch: &mut Scratch) {
        let bin = &self.bvh.bin;
        let stack = &mut scratch.stack;
        stack.clear();
        stack.push(code & !NODE);
        while let Some(k) = stack.pop() {
            let node = &bin.nodes[k as usize];
            let aabb = node.aabb();
            let (lo, hi) = (Vec3::from(aabb.min), Vec3::from(aabb.max));
            let (centre, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
            // The box's highest corner above the plane.
            if apex.n.dot(centre) - apex.h0 + apex.n.abs().dot(half) <= PLANE_MARGIN {
                continue;
            }
            let cand = Candidate::ball(NODE | k, apex.x, self.bvh.node_balls[k as usize]);
            if !cand.reaches(cone) {
                continue;
            }
            if node.is_leaf() {
                let first = node.first_index as usize;
                for &prim in &bin.primitive_indices[first..first + node.prim_count as usize] {
                    if let Some(c) = self.triangle(prim, apex, cone) {
                        scratch.candidates.push(c);
                    }
                }
            } else if cand.wide(cone) {
                stack.extend([node.first_index, node.first_index + 1]);
            } else {
                scratch.candidates.push(cand);
            }
        }
    }

    /// BVH primitive `prim` as a candidate, if it is not the face's own triangle, rises more than
    /// [`PLANE_MARGIN`] above the face's plane and may reach `cone`.
    #[inline]
    fn triangle(&self, prim: u32, apex: &Apex, cone: &Cone) -> Option<Candidate> {
        if self.bvh.ids[prim as usize] == apex.own {
            return None;
        }
        let t = &self.bvh.tris[prim as usize];
        let v = [Vec3::from(t.v0), Vec3::from(t.v1), Vec3::from(t.v2)];
        let top = apex.n.dot(v[0]).max(apex.n.dot(v[1])).max(apex.n.dot(v[2])) - apex.h0;
        if top <= PLANE_MARGIN {
            return None;
        }
        let mut cand = Candidate::ball(prim, apex.x, self.bvh.spheres[prim as usize]);
        if !cand.reaches(cone) {
            return None;
        }
        let [a, b, c] = v.map(|p| p - apex.x);
        let plane = |p: Vec3, q: Vec3, r: Vec3| {
            let m = p.cross(q);
            let len = m.length();
            // Guard: x in line with the edge (or a zero edge): no plane.
            if !(len > 1e-12) {
                return Vec3::ZERO;
            }
            let m = m / len;
            if m.dot(r) > 0.0 { -m } else { m }
        };
        cand.edges = [plane(a, b, c), plane(b, c, a), plane(c, a, b)];
        cand.reaches(cone).then_some(cand)
    }

    /// Answers the points of wall node `k`, whose candidates are `candidates[range]` (the buffer grows past
    /// `range.end` with the children's).
    fn descend(&self, k: usize, range: std::ops::Range<usize>, apex: &Apex, out: &mut [bool], scratch: &mut Scratch) {
        let node = self.wall.nodes[k];
        if apex.n.dot(node.centre - apex.x) + node.radius < -BEHIND {
            for &i in &self.wall.index[node.start as usize..node.end as usize] {
                out[i as usize] = false;
            }
            return;
        }
        if node.child != 0 && !range.is_empty() {
            for child in [node.child as usize, node.child as usize + 1] {
                let c = self.wall.nodes[child];
                let cone = Cone::new(apex.x, c.centre, c.radius);
                let start = scratch.candidates.len();
                for i in range.clone() {
                    let cand = scratch.candidates[i];
                    if !cand.reaches(&cone) {
                        continue;
                    }
                    if cand.wide(&cone) {
                        let first = self.bvh.bin.nodes[(cand.code & !NODE) as usize].first_index;
                        for k in [first, first + 1] {
                            self.open(NODE | k, apex, &cone, scratch);
                        }
                    } else {
                        scratch.candidates.push(cand);
                    }
                }
                let end = scratch.candidates.len();
                self.descend(child, start..end, apex, out, scratch);
                scratch.candidates.truncate(start);
            }
            return;
        }
        for pos in node.start as usize..node.end as usize {
            let p = self.wall.points[pos];
            let slot = &mut out[self.wall.index[pos] as usize];
            let d = p - apex.x;
            let h = apex.n.dot(d);
            *slot = if h < -BEHIND {
                false
            } else if h <= GRAZING * d.length() || range.len() > DIRECT {
                self.bvh.visible(apex.x, p, apex.own)
            } else if range.is_empty() {
                true
            } else {
                match segment(apex.x, p) {
                    None => true,
                    Some(ray) => !scratch.candidates[range.clone()]
                        .iter()
                        .any(|c| self.cuts(c.code, &ray, apex.own, &mut scratch.stack)),
                }
            };
        }
    }

    /// Whether candidate `code` (a BVH primitive, or a node: a ray through its subtree) cuts the segment `ray`.
    fn cuts(&self, code: u32, ray: &Ray, own: u32, stack: &mut Vec<u32>) -> bool {
        if code & NODE == 0 {
            return self.bvh.blocks(code, ray);
        }
        let bin = &self.bvh.bin;
        stack.clear();
        stack.push(code & !NODE);
        while let Some(k) = stack.pop() {
            let node = &bin.nodes[k as usize];
            if !hits_box(node.aabb().min, node.aabb().max, ray) {
                continue;
            }
            if node.is_leaf() {
                let first = node.first_index as usize;
                for &prim in &bin.primitive_indices[first..first + node.prim_count as usize] {
                    if self.bvh.ids[prim as usize] != own && self.bvh.blocks(prim, ray) {
                        return true;
                    }
                }
            } else {
                stack.extend([node.first_index, node.first_index + 1]);
            }
        }
        false
    }
}

/// The slab test of a box padded by a relative 1e-5 and 1e-6 m (f32 rounding must not lose a triangle on
/// its face) against the segment `ray` (t in `[0, tmax]`).
#[inline(always)]
fn hits_box(min: Vec3A, max: Vec3A, ray: &Ray) -> bool {
    let pad = (max - min) * 1e-5 + Vec3A::splat(1e-6);
    let t1 = (min - pad - ray.origin) * ray.inv_direction;
    let t2 = (max + pad - ray.origin) * ray.inv_direction;
    let (near, far) = (t1.min(t2).max_element(), t1.max(t2).min_element());
    far >= near && far >= 0.0 && near <= ray.tmax
}
