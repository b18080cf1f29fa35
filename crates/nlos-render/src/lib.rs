//! # nlos-render
//!
//! Forward and adjoint (reverse-mode) transient renderer of a triangle mesh for non-line-of-sight surface
//! reconstruction, after Tsai, Sankaranarayanan & Gkioulekas, "Beyond Volumetric Albedo — A Surface
//! Optimization Framework for Non-Line-of-Sight Imaging", CVPR 2019 (equation numbers below are theirs).
//! It takes plain positions `&[Vec3]` and triangles `&[[u32; 3]]` and knows no file formats.
//!
//! ```
//! use glam::Vec3;
//! use nlos_brdf::Lambertian;
//! use nlos_render::{Renderer, RenderParams};
//! use nlos_transient::{PointSet, Scan, TimeAxis};
//! let scan = Scan::confocal(PointSet::wall_grid(4, 4, 0.2, 0.2)?);
//! let time = TimeAxis::new(0.0, 0.01, 200)?;
//! // A small square at z = 0.5 facing the wall (normal (v1−v0)×(v2−v0) = −z).
//! let p = [Vec3::new(-0.1, -0.1, 0.5), Vec3::new(0.1, 0.1, 0.5), Vec3::new(0.1, -0.1, 0.5), Vec3::new(-0.1, 0.1, 0.5)];
//! let r = Renderer::new(&p, &[[0, 1, 2], [0, 3, 1]], &scan, &time, RenderParams::default())?;
//! let brdf = Lambertian::new(1.0f32)?;
//! let data = r.forward(&brdf);
//! assert!(data.iter().sum::<f32>() > 0.0);
//! let grad = r.adjoint(&brdf, &vec![1.0; data.len()])?; // d(Σ I)/d(vertices)
//! assert_eq!(grad.vertices.len(), 4);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! ## The model (eq. 1–5)
//! For a measurement with laser spot `l` (wall normal `n_l`) and sensor spot `s` (wall normal `n_s`),
//! ```text
//! I_k(l, s) = ∫_S K_k(τ(x)) f(x) v(x,l) v(x,s) dA(x),          τ(x) = |x − l| + |x − s|     (1), (4)
//! f(x) = f_s(ω_l, ω_s, n) · ⟨−ω_l, n_l⟩⟨ω_l, n⟩/|x − l|² · ⟨−ω_s, n_s⟩⟨ω_s, n⟩/|x − s|²         (2)
//! ```
//! with `ω_l = (l − x)/|l − x|`, `ω_s = (s − x)/|s − x|`, every cosine clamped at 0, and `K_k` the
//! temporal kernel of bin k ([`Kernel`]: the box of eq. (3), or a differentiable tent / Gaussian). Faces are
//! one-sided: triangle `(v0, v1, v2)` reflects only when `l` and `s` are both on the side of its geometric
//! normal `N = (v1 − v0) × (v2 − v0)` ([`RenderParams::two_sided`] lifts this). Only three-bounce paths
//! `l → x → s` are modelled (no interreflection).
//!
//! Glossy surfaces: [`Renderer::set_lobe_sampling`] adds multiple importance sampling of the GGX lobe to the
//! stratified mode (balance heuristic, unbiased; `tests/mis.rs`).
//!
//! ## Steady state
//! [`Renderer::forward_steady`], [`Renderer::adjoint_steady`] and [`Renderer::loss_and_gradient_steady`] give
//! the time-integrated intensity `S(l, s) = ∫_S f v v dA` (eq. 1 without the kernel; one value per measurement)
//! and its gradient, with the same samples and visibility as the transient: the method applies to any radiometric
//! measurement (Tsai et al. 2019). `S` is the time sum of the transient when the time axis holds every path.
//!
//! ## Scale convention
//! The relay wall is Lambertian and its own BRDF factors (`ρ_w/π` at l and at s) are **left out**: a unit
//! transient is "f integrated", nothing more. The shared reference data
//! (`shared/data/reference/README.md`, section 3) include `(ρ_w/π)²` with `ρ_w = 1`, so for the same
//! surface BRDF **reference = ours / π²** (for a Lambertian ρ = 1 surface, `f_s = 1/π` and the reference is
//! `π⁻³ ∫ cos²θ_s cos²θ_x / r⁴ dA`; ours is `π⁻¹ ∫ …`). The tests check this factor against the references.
//!
//! ## Discretisation
//! Per triangle, with `x(u, v) = v0 + u e1 + v e2` (`e1 = v1 − v0`, `e2 = v2 − v0`) and area `A = |N|/2`,
//! `∫_t h dA = A ∫∫ h(x(u,v)) 2 du dv`, estimated as `A Σ_i w_i h(x(u_i, v_i))` with `Σ w_i = 1`
//! ([`Sampling::Deterministic`]: centroids of `n²` sub-triangles; [`Sampling::Stratified`]: jittered
//! area samples). Writing everything in the unnormalised `a = l − x`, `b = s − x`, `N`:
//! ```text
//! A · f = f_s(a, b, N) · Q,   Q = c_l p_l c_s p_s / (2 |N| |a|⁴ |b|⁴)
//! c_l = −n_l·a, p_l = N·a, c_s = −n_s·b, p_s = N·b
//! ```
//! (the area `|N|/2` times the two unit-normal cosines `p/(|N| r)` leaves one `1/|N|`).
//!
//! ## Gradients (Proposition 1, complete)
//! The adjoint pass receives `a_k = dE/dI_k` and, per sample, gathers `A_val = Σ_k a_k K_k(τ)` and
//! `A_der = Σ_k a_k dK_k/dτ` with the SAME kernel as the forward pass. With `h = f_s Q` and the samples'
//! barycentric coordinates held fixed (so the integration domain moves with the vertices, which turns the
//! area change into the `1/|N|` and `|N|`-terms of Q), visibility held fixed:
//! ```text
//! dE/da = w [A_val (f_s ∂Q/∂a + Q ∂f_s/∂ω_l) + h A_der a/|a|]          (likewise b)
//! dE/dN = w A_val (f_s ∂Q/∂N + Q ∂f_s/∂n)
//! ∂Q/∂a = c_s p_s/(2|N||a|⁴|b|⁴) (c_l N − p_l n_l) − 4 Q a/|a|²
//! ∂Q/∂N = c_l c_s (p_s a + p_l b)/(2|N||a|⁴|b|⁴) − Q N/|N|²
//! ```
//! and then `dE/dx = −(dE/da + dE/db)` distributed to the vertices with weights `(1−u−v, u, v)` (the
//! position term), `dE/de1 = e2 × dE/dN`, `dE/de2 = dE/dN × e1` (the normal and area terms; `e1 = v1 − v0`,
//! `e2 = v2 − v0`). The BRDF gradients `∂f_s/∂ω_l, ∂f_s/∂ω_s, ∂f_s/∂n` of `nlos_brdf` are with respect to
//! the raw vectors, so they chain straight into `a, b, N`. The original implementation dropped the
//! `∂/∂N` term and used different kernels in the two passes; both are fixed here.
//!
//! ## The optimiser's rule: closed-form time integration ([`Sampling::Splat`])
//! A point rule must cut a face until each piece spans a fraction of a bin: on the optimiser's first stage
//! (8 mm faces at 0.4 m, 1.2 mm bins, spans of about 10 bins) that is up to 64 samples per (face,
//! measurement). The splat rule instead takes the integrand at the centroid and τ linear over the face, whose
//! area density over τ is a hat (rising from the smallest corner value to the middle one, falling to the
//! largest), and integrates it against the tent kernel in closed form (`render/splat.rs`: a piecewise cubic, its
//! second differences are the bin weights; their derivatives with respect to the three corner path lengths
//! are closed form too). Two first-order corrections shift the hat: τ's convexity (the face's exact mean
//! path length for a quadratic τ) and the fall-off of the distance factor across the face. A face is cut
//! further only where τ's curvature needs it ([`SplatRule`]). The vector kernels compute each pair's centroid
//! value, corner path lengths and closed-form constants, and the weights (forward) or gathers (adjoint) of
//! pairs that span at most 4, 8 or 16 bins (chosen per block: the shortest that covers seven in eight of its
//! pairs); a scalar loop handles longer spans, over the bins they span (about span + 2 of them). The adjoint's gather sums the adjoint rows' second differences
//! against the same piecewise cubic. `benches/loop_cost.rs` times the optimiser's exact configuration;
//! docs/performance.md has the figures (per-step time and bin-level error of every rule).
//!
//! ## On a GPU (feature `gpu`)
//! [`GpuRenderer`] runs the splat rule's forward and adjoint passes (tent kernel, cached or no visibility,
//! Lambertian or retroreflective) as wgpu compute shaders; [`Renderer::set_device`] makes a renderer use the
//! process's GPU for [`Renderer::forward`], [`Renderer::adjoint`] and the loss-and-gradient. The shaders follow
//! the splat kernels below term for term; sums are deterministic without float atomics (the forward pass in
//! 64-bit fixed point per bin, the adjoint per triangle in a fixed order), so a GPU run repeats bit for bit on
//! its device and agrees with the CPU to f32 rounding (`tests/gpu.rs`). Timings: docs/performance.md.
//!
//! The source follows the backends: `render/` holds the [`Renderer`] (geometry, settings, the passes' entry
//! points and the choice of device), `render/cpu/` the CPU backend (the passes over blocks of triangles,
//! the sampling rules, the vector kernels, the splat rule's time integration) and `render/gpu/` the GPU
//! backend with its shader.
//!
//! ## Performance
//! Triangles are stored as structure of arrays (`f32` per coordinate), grouped by normal direction into
//! blocks of 256; a block whose bounds (componentwise range of the unit normals, smallest plane offset)
//! prove that every triangle faces away from the spot, with a 1 mm margin, is skipped before any per-triangle
//! work (exact: `block_culling_is_exact`). Fixed deterministic rules (`min_level = max_level`, e.g.
//! [`DeterministicRule::fixed`]) run block kernels that the compiler vectorises across triangles
//! (straight-line loops, selects and bit masks instead of branches, no float→int casts: the tent kernel's
//! bin comes from the 1.5·2²³ rounding trick), compiled twice — for baseline x86-64 (SSE2) and, selected at
//! run time after `is_x86_feature_detected!`, for AVX2 + FMA (8 lanes; same bits, unit-tested). With the tent
//! kernel the bins and weights are computed in the vector loops and the histograms and adjoint rows are
//! padded by a zero bin at each end, so the scalar scatter/gather has no bounds logic; shadow rays run in a
//! separate scalar pass. Adaptive rules and [`Sampling::Stratified`] run the same arithmetic pair by pair.
//! The adjoint's stage 3 uses one division per pair and, for confocal scans, one expression for
//! `dE/da + dE/db`. The visibility cache is stored in block order (read contiguously).
//!
//! Fixed rules also pack: for a group of nearby measurements (a forward tile of 8; an adjoint flush group
//! of 16) the triangles of a block that may face some spot of the group (a bound over the group's box of
//! spots, with the same 1 mm margin) are gathered contiguously once, and the vector kernels sweep only them
//! for each measurement of the group. On the bunny about half of a block's triangles face away from any
//! one spot although the block as a whole does not; without packing the kernels, the orientation test and
//! the scatter/gather did that work for nothing. Packing changes no bits (sums run in the same order).
//!
//! Parallel with rayon and lock-free: the forward pass over tiles of 8 measurements (each task owns its
//! histograms) × blocks of triangles; the adjoint over about 32 ranges of triangles (each task owns their
//! accumulators: f32 over at most 16 measurements, then f64; the ranges depend on the mesh only, so the
//! gradient does not depend on the thread count). Every reduction is over fixed chunks summed in chunk
//! order: forward, adjoint and loss are bit-identical whatever rayon's schedule (`tests/determinism.rs`
//! compares pools of 1, 2 and 3 threads).
//!
//! What these rules cost on a 2-core machine, against the original renderer, and how close the kernels come
//! to the machine's arithmetic peak: docs/performance.md ("The point rules' kernels").
//!
//! Memory at Tsai et al. 2019's scale (100k vertices / 200k faces, 4096 measurements × 1200 bins;
//! `examples/memory.rs`): peak RSS 128 MiB for construction + forward + loss + adjoint without visibility
//! (transient, measurement, adjoint and its padded copy are 19.7 MB each; per-triangle f64 sums 19 MB); the
//! visibility cache adds one byte per (triangle, measurement), 0.82 GB, so about 0.95 GB in cached mode:
//! under the 2 GB budget either way.
//!
//! Accuracy of the rule (`examples/accuracy.rs`, 64 measurements against a fine deterministic reference):
//! `fixed(1)` has a relative bin-level (voxel) error of 1.9 % on the full bunny (10k faces: 4.8 %), Tsai et al. 2019's
//! stratified sampling at 20,000 samples per measurement 11 % (6 %). Gradient checks use five-point
//! differences at h = 5e-4 m: the f32 rendering noise of a difference quotient grows as 1/h below
//! h = 2e-4 m and a central difference's truncation as h² above 1e-3 m (`fd_step_study` in
//! `tests/gradients.rs`).
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate: it is also true for NaN, which is how non-finite values fall into the skip
// branches.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod brdf;
pub mod error;
pub mod kernel;
pub mod loss;
pub mod render;
mod visibility;

pub use error::{RenderError, Result};
pub use kernel::Kernel;
pub use loss::Loss;
pub use nlos_brdf::{AnyBrdf, FittedBrdf, with_brdf};
#[cfg(feature = "gpu")]
pub use render::gpu::GpuRenderer;
pub use render::{
    DeterministicRule, Device, Gradient, LossAndGradient, RenderParams, Renderer, RowSpan, Sampling, SplatRule,
    Visibility, describe_device, gpu_support, silence_display_probe,
};
