//! Typed element handles (pmp's `Vertex`, `Halfedge`, `Edge`, `Face`).
//!
//! A handle is a `u32` index into the mesh's arrays; `u32::MAX` is the invalid sentinel (`Id::INVALID`,
//! also `Default`). Handles are plain indices: they stay valid across operations except where an
//! operation's documentation says otherwise, and [`crate::SurfaceMesh::garbage_collect`] renumbers all
//! of them (it returns the remap).

macro_rules! handle {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Debug)]
        pub struct $name(pub u32);

        impl $name {
            /// The invalid sentinel.
            pub const INVALID: Self = Self(u32::MAX);

            /// Handle for array index `i` (indices at or above `u32::MAX` give [`Self::INVALID`]).
            #[inline]
            pub fn new(i: usize) -> Self {
                Self(u32::try_from(i).unwrap_or(u32::MAX))
            }

            /// The array index.
            #[inline]
            pub fn idx(self) -> usize {
                self.0 as usize
            }

            /// Whether this is not the invalid sentinel (says nothing about deletion).
            #[inline]
            pub fn is_valid(self) -> bool {
                self.0 != u32::MAX
            }
        }

        impl Default for $name {
            fn default() -> Self {
                Self::INVALID
            }
        }
    };
}

handle!(
    /// A vertex.
    VertexId
);
handle!(
    /// A halfedge. Halfedges come in pairs: `2e` and `2e + 1` belong to edge `e` and are each other's
    /// opposite.
    HalfedgeId
);
handle!(
    /// An (undirected) edge: a pair of halfedges.
    EdgeId
);
handle!(
    /// A triangle.
    FaceId
);

impl HalfedgeId {
    /// The opposite halfedge (same edge, other direction).
    #[inline]
    pub fn opposite(self) -> HalfedgeId {
        HalfedgeId(self.0 ^ 1)
    }

    /// The edge this halfedge belongs to.
    #[inline]
    pub fn edge(self) -> EdgeId {
        EdgeId(self.0 >> 1)
    }
}

impl EdgeId {
    /// Halfedge `i` (0 or 1) of this edge.
    #[inline]
    pub fn halfedge(self, i: u32) -> HalfedgeId {
        HalfedgeId((self.0 << 1) | (i & 1))
    }
}
