//! The CPU backend (rayon, byte-identical whatever the thread count): the forward and adjoint passes
//! ([`forward`], [`adjoint`]: blocks of triangles swept over chunks of measurements), the sampling rules
//! ([`sampling`], [`lobe`]), the structure-of-arrays blocks and their vector kernels ([`super::soa`], which the scene stores its triangles in) and the
//! splat rule's closed-form time integration ([`super::splat`]). `super::gpu` is the other backend.
//!
//! The passes are methods of [`Cpu`], a view of the [`Scene`] with the instruction set of the block kernels;
//! the scene's own geometric queries (a measurement's frame, points, orientation, live visibility, levels)
//! are in [`sampling`], shared with the visibility cache.

use nlos_brdf::{AnyBrdf, FittedBrdf, Model};

use super::backend::Backend;
use super::scene::Scene;
use crate::error::Result;
use crate::render::soa::{self, Isa};
use crate::{Device, Gradient, RenderParams};

/// The CPU backend: rayon over blocks of triangles and chunks of measurements, with the block kernels of the
/// instruction set found at run time. Runs every setting of the renderer.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CpuBackend {
    /// Instruction set of the block kernels (runtime-detected).
    pub(in crate::render) isa: Isa,
}

impl CpuBackend {
    /// The backend with the best instruction set of this CPU.
    pub(in crate::render) fn detect() -> Self {
        Self { isa: Isa::detect() }
    }

    /// The passes' view of `scene`.
    pub(in crate::render) fn view<'a>(&self, scene: &'a Scene) -> Cpu<'a> {
        Cpu { scene, isa: self.isa }
    }

    /// The forward pass on the CPU, which cannot fail.
    pub(in crate::render) fn forward<B: FittedBrdf>(&self, scene: &Scene, brdf: &B) -> Vec<f32> {
        self.view(scene).forward_with(brdf, &scene.kernel)
    }

    /// The adjoint pass on the CPU.
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] for a `d_loss` of another length than the transient's.
    pub(in crate::render) fn adjoint<B: FittedBrdf>(
        &self,
        scene: &Scene,
        brdf: &B,
        d_loss: &[f32],
    ) -> Result<Gradient> {
        self.view(scene).adjoint_with(brdf, d_loss, &scene.kernel)
    }
}

/// The CPU as the renderer's backend of last resort: every setting, every model.
impl Backend for CpuBackend {
    fn device(&self) -> Device {
        Device::Cpu
    }

    fn supports(&self, _model: Model, _params: &RenderParams) -> std::result::Result<(), String> {
        Ok(())
    }

    fn forward(&self, scene: &Scene, brdf: &AnyBrdf) -> Result<Vec<f32>> {
        Ok(nlos_brdf::with_brdf!(brdf, b => CpuBackend::forward(self, scene, b)))
    }

    fn adjoint(&self, scene: &Scene, brdf: &AnyBrdf, d_loss: &[f32]) -> Result<Gradient> {
        nlos_brdf::with_brdf!(brdf, b => CpuBackend::adjoint(self, scene, b, d_loss))
    }
}

/// The CPU passes' view of a [`Scene`]: the scene's fields and queries (through `Deref`) and the instruction
/// set of the block kernels.
#[derive(Clone, Copy)]
pub(in crate::render) struct Cpu<'a> {
    scene: &'a Scene,
    pub(in crate::render) isa: Isa,
}

impl std::ops::Deref for Cpu<'_> {
    type Target = Scene;
    fn deref(&self) -> &Scene {
        self.scene
    }
}

mod adjoint;

/// Runs `work(i, task)` for every task `i` on the pool's threads, the longest first: in decreasing order of
/// `costs` (each task's seconds the last time, in task order; index order when their number differs), each
/// thread taking the next task when it finishes one (longest-processing-time scheduling), and stores the
/// seconds each took in `costs` for the next call. A pass of a few dozen tasks of unequal cost (the
/// adjoint's ranges of triangles) otherwise often ends on one thread. The results come back in task
/// order and do not depend on the order the tasks ran in.
pub(in crate::render) fn longest_first<T: Send, R: Send>(
    tasks: Vec<&mut [T]>,
    costs: &std::sync::Mutex<Vec<f64>>,
    work: impl Fn(usize, &mut [T]) -> R + Sync,
) -> Vec<R> {
    use std::sync::Mutex;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let n = tasks.len();
    let mut order: Vec<usize> = (0..n).collect();
    {
        let last = costs.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if last.len() == n {
            order.sort_by(|&a, &b| last[b].total_cmp(&last[a]));
        }
    }
    let slots: Vec<Mutex<Option<&mut [T]>>> = tasks.into_iter().map(|t| Mutex::new(Some(t))).collect();
    let done: Vec<Mutex<Option<(R, f64)>>> = (0..n).map(|_| Mutex::new(None)).collect();
    let next = AtomicUsize::new(0);
    let run = || {
        loop {
            let k = next.fetch_add(1, Ordering::Relaxed);
            let Some(&i) = order.get(k) else { break };
            let Some(task) = slots[i].lock().ok().and_then(|mut s| s.take()) else { continue };
            let clock = std::time::Instant::now();
            let r = work(i, task);
            if let Ok(mut d) = done[i].lock() {
                *d = Some((r, clock.elapsed().as_secs_f64()));
            }
        }
    };
    rayon::scope(|s| {
        for _ in 1..rayon::current_num_threads().min(n) {
            s.spawn(|_| run());
        }
        run();
    });
    let (results, seconds): (Vec<R>, Vec<f64>) = done
        .into_iter()
        .map(|d| d.into_inner().ok().flatten().expect("every task ran once (the scope waits for them)"))
        .unzip();
    *costs.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = seconds;
    results
}
mod forward;
pub(crate) mod lobe;
mod sampling;

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

#[cfg(test)]
mod tests {
    use super::longest_first;

    /// Every task runs once on its own slice, the results come back in task order whatever the order they
    /// ran in, and the seconds of each are kept for the next call (which then orders by them).
    #[test]
    fn longest_first_runs_each_task_once_and_returns_in_task_order() {
        let costs = std::sync::Mutex::new(Vec::new());
        for round in 0..3 {
            let mut data = vec![0u32; 103];
            let tasks: Vec<&mut [u32]> = data.chunks_mut(10).collect();
            let n = tasks.len();
            let out = longest_first(tasks, &costs, |i, s| {
                // unequal work: the later tasks are slower
                std::thread::sleep(std::time::Duration::from_micros(50 * i as u64));
                for x in s.iter_mut() {
                    *x += 1 + i as u32;
                }
                (i, s.len())
            });
            assert_eq!(out, (0..n).map(|i| (i, if i + 1 < n { 10 } else { 3 })).collect::<Vec<_>>(), "{round}");
            assert!(data.iter().enumerate().all(|(k, &x)| x == 1 + (k / 10) as u32), "each task once");
            let c = costs.lock().expect("not poisoned");
            assert_eq!(c.len(), n);
            assert!(c.iter().all(|&s| s > 0.0));
        }
    }
}
