//! The CPU backend (rayon, byte-identical whatever the thread count): the forward and adjoint passes
//! ([`forward`], [`adjoint`]: blocks of triangles swept over chunks of measurements), the sampling rules
//! ([`sampling`], [`lobe`]), the structure-of-arrays blocks and their vector kernels ([`soa`]) and the
//! splat rule's closed-form time integration ([`splat`]). `super::gpu` is the other backend.

use super::*;

mod adjoint;
mod forward;
pub(crate) mod lobe;
mod sampling;
pub(crate) mod soa;
pub(crate) mod splat;

/// What every call of a pass reads besides the renderer: the BRDF and the time kernel — the point rules'
/// [`crate::kernel::KernelEval`] or the splat rule's [`soa::TentAxis`].
pub(in crate::render) struct Pass<'a, B, K> {
    pub(in crate::render) brdf: &'a B,
    pub(in crate::render) kernel: &'a K,
}

impl<B, K> Clone for Pass<'_, B, K> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<B, K> Copy for Pass<'_, B, K> {}

/// A tile of the packed rules: the block of triangles starting at storage slot `t0`, those of its triangles
/// that may reflect for the tile's measurements (`pk`), and the level of the block's sub-triangles.
#[derive(Clone, Copy)]
pub(in crate::render) struct Tile<'a> {
    pub(in crate::render) t0: usize,
    pub(in crate::render) pk: &'a soa::Packed,
    pub(in crate::render) level: u32,
}

/// One (triangle, measurement) pair that reflects: mesh triangle `t`, measurement `m` and its frame, the
/// triangle's orientation sign and its cached visible fraction (both non-zero).
#[derive(Clone, Copy)]
pub(in crate::render) struct Pair<'a> {
    pub(in crate::render) m: usize,
    pub(in crate::render) t: usize,
    pub(in crate::render) fr: &'a soa::Frame,
    pub(in crate::render) sign: f32,
    pub(in crate::render) vis: f32,
}

/// Measurement `m`'s adjoint row `d` (dE/dI; padded by a zero bin at each end on the tent paths) and, for the
/// splat rule, its second differences `d2` (empty otherwise).
#[derive(Clone, Copy)]
pub(in crate::render) struct Row<'a> {
    pub(in crate::render) m: usize,
    pub(in crate::render) d: &'a [f32],
    pub(in crate::render) d2: &'a [f32],
}
