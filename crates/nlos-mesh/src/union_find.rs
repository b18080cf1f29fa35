//! Union–find (disjoint sets) over vertex indices, with path halving; for groupings that have no half-edge
//! mesh to walk (a collision's impact zones, the components of a triangle list).

/// Disjoint sets over `0..n`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub fn new(n: usize) -> Self {
        Self { parent: (0..n as u32).collect() }
    }

    /// The representative of `v`'s set (the smallest index in it: [`Self::union`] keeps the smaller root).
    ///
    /// # Panics
    /// When `v` is not below the `n` the sets were made for (an index bug in the caller).
    pub fn find(&mut self, mut v: u32) -> u32 {
        while self.parent[v as usize] != v {
            let g = self.parent[self.parent[v as usize] as usize];
            self.parent[v as usize] = g;
            v = g;
        }
        v
    }

    /// Merges the sets of `a` and `b`.
    pub fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_merge_and_keep_their_smallest_member() {
        let mut u = UnionFind::new(6);
        u.union(4, 2);
        u.union(5, 4);
        u.union(0, 1);
        assert_eq!([u.find(5), u.find(4), u.find(2)], [2, 2, 2]);
        assert_eq!([u.find(1), u.find(0), u.find(3)], [0, 0, 3]);
    }
}
