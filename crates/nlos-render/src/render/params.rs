//! What a [`Renderer`](crate::Renderer) is asked to do: the sampling rules, visibility, the parameters and their checks, and
//! the shapes of its results.

use glam::Vec3;

use crate::error::Result;
use crate::{Kernel, RenderError};

/// The deterministic barycentric rule: triangle `t` is cut, for measurement `m`, into `n²` congruent
/// sub-triangles (n per edge) and each contributes its centroid value times its area (the centroid rule).
/// `n` is the smallest level at which a sub-triangle spans at most `max_bin_fraction` bins of path length,
/// estimated as `range/n + e²/(n² r_min)` (the range of τ over the three vertices, plus the deviation of τ
/// from linear: its Hessian has norm ≤ 2/r_min, r_min the smallest vertex–spot distance, e the longest
/// edge), clamped to `[min_level, max_level]`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DeterministicRule {
    /// Largest path-length span of a sub-triangle, in bins (> 0). Default 0.5.
    pub max_bin_fraction: f32,
    /// Smallest subdivision level n (≥ 1). Default 1.
    pub min_level: u32,
    /// Largest subdivision level n (≥ min_level); caps the cost at n² samples per (triangle, measurement).
    /// Default 64. Set `min_level = max_level` for a fixed rule (smooth in the vertices: use it for finite
    /// differences).
    pub max_level: u32,
}

impl Default for DeterministicRule {
    fn default() -> Self {
        Self { max_bin_fraction: 0.5, min_level: 1, max_level: 64 }
    }
}

impl DeterministicRule {
    /// A fixed level `n` for every (triangle, measurement).
    pub fn fixed(n: u32) -> Self {
        Self { max_bin_fraction: 1.0, min_level: n, max_level: n }
    }
}

/// Closed-form time integration per (triangle, measurement) ([`Sampling::Splat`]): triangle t is cut into
/// `n²` congruent sub-triangles (n per edge, the same cut as [`DeterministicRule`]); on each, the integrand
/// `f_s Q` is taken at the centroid and the path length τ as linear between the three corners, whose area
/// density over τ (rising from the smallest corner value to the middle one, falling to the largest) is
/// integrated against the tent kernel in closed form (`splat.rs`). The time integral is then exact however
/// many bins a sub-triangle spans; the level only has to resolve τ's curvature: `n` is the smallest level
/// at which τ departs from linear by at most `max_deviation` bins over a sub-triangle, bounded as
/// `(2/r) e²/(6 n²)` (τ's Hessian has norm ≤ 1/|x − l| + 1/|x − s| ≤ 2/r, r a lower bound of the distance
/// from the triangle to every wall spot; the linear interpolant's error on a triangle of longest edge e is
/// at most `M e²/6` for a Hessian norm ≤ M), taken as the largest over each block of 256 triangles and
/// clamped to `[1, max_level]`. With [`Kernel::Tent`] (the optimiser's: forward and adjoint) or
/// [`Kernel::Box`] (simulation: forward only, the adjoint is refused), the closed form of either.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SplatRule {
    /// Largest departure of τ from linear over a sub-triangle, in bins (> 0). Default 0.09: on the first
    /// stage's 8 mm faces at Tsai et al. 2019's setup this cuts the blocks holding the longest faces in four, which
    /// brings the bin-level error against the exact quadrature below the adaptive quadrature's at half a bin per
    /// sub-triangle (see `docs/performance.md`).
    pub max_deviation: f32,
    /// Largest subdivision level (1..=64). Default 8.
    pub max_level: u32,
}

impl Default for SplatRule {
    fn default() -> Self {
        Self { max_deviation: 0.09, max_level: 8 }
    }
}

/// How the surface integral of eq. (1) is estimated.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum Sampling {
    /// Noise-free quadrature (see [`DeterministicRule`]). The default.
    Deterministic(DeterministicRule),
    /// Tsai et al. 2019's stratified area sampling: per measurement, `samples_per_measurement` samples are spread
    /// over the mesh in proportion to triangle area (triangle t gets ⌊c_t⌋ or ⌈c_t⌉ samples, c_t = N A_t/A,
    /// randomised so the expected count is c_t), each sample weighted `A/N`, jittered (stratified along the
    /// area-preserving square-to-triangle map). Unbiased; seeded per (seed, measurement, triangle).
    Stratified {
        /// Expected samples per measurement over the whole mesh (> 0).
        samples_per_measurement: u32,
        /// Seed.
        seed: u64,
    },
    /// Closed-form time integration of each (sub-)triangle against the tent kernel (see [`SplatRule`]):
    /// noise-free, and about (span in bins + 2) operations per pair instead of the n² samples a point rule
    /// needs to resolve the same span. The optimiser's default (tent kernel); with [`Kernel::Box`] it is
    /// `nlos render`'s exact mode (forward only). Needs one of those two kernels; the steady-state
    /// passes use the same sub-triangle centroids (time does not matter there).
    Splat(SplatRule),
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling::Deterministic(DeterministicRule::default())
    }
}

/// Where [`Renderer::forward`](crate::Renderer::forward) and [`Renderer::adjoint`](crate::Renderer::adjoint) run ([`Renderer::set_device`](crate::Renderer::set_device)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// The CPU (rayon; byte-identical whatever the thread count and machine). The default.
    #[default]
    Cpu,
    /// A GPU through wgpu (feature `gpu`), software adapters (Mesa's lavapipe) included: an error where there is
    /// none or the renderer's settings have no GPU version.
    Gpu,
    /// A hardware GPU where one is found and the settings have a GPU version, else the CPU.
    Auto,
}

/// How v(x, l) v(x, s) of eq. (1) is evaluated. In the adjoint pass visibility is always held fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub enum Visibility {
    /// Everything visible (convex scenes, or to ignore occlusion).
    Off,
    /// A shadow ray per sample (toward l, and toward s when not confocal). The default.
    #[default]
    Live,
    /// A visible fraction per (triangle, measurement), from the `level²` sub-triangle centroids, stored as
    /// a byte and multiplied into every sample of that pair. Computed by [`Renderer::new`](crate::Renderer::new) and
    /// [`Renderer::refresh_visibility`](crate::Renderer::refresh_visibility) only; [`Renderer::set_positions`](crate::Renderer::set_positions) keeps it (refresh after remeshing or
    /// large moves), and with it the grouping of the triangles into blocks (made from the normals at the last
    /// refresh), so results depend on the positions at the last refresh as well as on the current ones.
    /// Memory: one byte per (triangle, measurement). Each centroid's view of the whole wall is one query (the
    /// wall's spots in a k-d tree walked with the BVH, a group of spots settled where no triangle reaches the
    /// cone of its segments), which gives what a shadow ray per centroid and spot gives, entry by entry, at
    /// 5–13× less cost (docs/performance.md, "The visibility cache").
    Cached {
        /// Sub-triangle level of the visibility rays (≥ 1; 1 = one ray at the centroid).
        level: u32,
    },
}

/// Parameters of a [`Renderer`](crate::Renderer) (defaults: tent kernel, deterministic default rule, live visibility,
/// one-sided faces).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct RenderParams {
    /// Temporal kernel, used in both passes.
    pub kernel: Kernel,
    /// Surface sampling.
    pub sampling: Sampling,
    /// Visibility.
    pub visibility: Visibility,
    /// Whether back faces reflect too (default false: a face reflects only when l and s are both on the
    /// side of its geometric normal `(v1−v0)×(v2−v0)`).
    pub two_sided: bool,
}

/// The non-zero part of one measurement's histogram ([`Renderer::forward_triangle`](crate::Renderer::forward_triangle)): bins
/// `first_bin .. first_bin + values.len()` of measurement `measurement`.
#[derive(Debug, Clone, PartialEq)]
pub struct RowSpan {
    /// Measurement (row of the transient).
    pub measurement: usize,
    /// First bin of `values`.
    pub first_bin: usize,
    /// The histogram values from `first_bin` on (the first and last are non-zero).
    pub values: Vec<f32>,
}

/// dE/d(vertex positions) and dE/d(BRDF parameters) from the adjoint pass.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradient {
    /// One gradient per vertex.
    pub vertices: Vec<Vec3>,
    /// One per BRDF parameter, in the order of [`FittedBrdf::PARAM_NAMES`](nlos_brdf::FittedBrdf::PARAM_NAMES).
    pub brdf: Vec<f32>,
    /// One per mesh triangle: dE/dw_t, the derivative with respect to the triangle's reflectance factor
    /// ([`Renderer::set_face_weights`](crate::Renderer::set_face_weights); 1 when none are set) at its current value. 0 for degenerate
    /// triangles and for triangles whose factor is 0 (they are skipped, so nothing is sampled on them).
    pub faces: Vec<f32>,
}

/// What [`Renderer::loss_and_gradient`](crate::Renderer::loss_and_gradient) returns.
#[derive(Debug, Clone, PartialEq)]
pub struct LossAndGradient {
    /// The loss E (summed in f64).
    pub loss: f64,
    /// dE/d(vertices), dE/d(BRDF parameters).
    pub gradient: Gradient,
    /// The rendered transient, measurement-major (steady-state: one value per measurement).
    pub rendered: Vec<f32>,
}

/// Checks the parameters' ranges.
pub(super) fn check_params(p: &RenderParams) -> Result<()> {
    let bad = |name, value: f64, reason| Err(RenderError::InvalidParameter { name, value, reason });
    if let Kernel::Gaussian { fwhm_bins } = p.kernel
        && !(fwhm_bins > 0.0 && fwhm_bins.is_finite())
    {
        return bad("Kernel::Gaussian.fwhm_bins", f64::from(fwhm_bins), "must be finite and > 0 bins");
    }
    match p.sampling {
        Sampling::Deterministic(r) => {
            if !(r.max_bin_fraction > 0.0 && r.max_bin_fraction.is_finite()) {
                return bad("max_bin_fraction", f64::from(r.max_bin_fraction), "must be finite and > 0");
            }
            if r.min_level == 0 || r.max_level < r.min_level || r.max_level > 4096 {
                return bad("max_level", f64::from(r.max_level), "need 1 ≤ min_level ≤ max_level ≤ 4096");
            }
        }
        Sampling::Stratified { samples_per_measurement, .. } => {
            if samples_per_measurement == 0 {
                return bad("samples_per_measurement", 0.0, "must be > 0");
            }
        }
        Sampling::Splat(r) => {
            if !(r.max_deviation > 0.0 && r.max_deviation.is_finite()) {
                return bad("SplatRule.max_deviation", f64::from(r.max_deviation), "must be finite and > 0 bins");
            }
            if !(1..=64).contains(&r.max_level) {
                return bad("SplatRule.max_level", f64::from(r.max_level), "must be in 1..=64");
            }
            if !matches!(p.kernel, Kernel::Tent | Kernel::Box) {
                return bad(
                    "Sampling::Splat",
                    0.0,
                    "integrates the tent or the box kernel in closed form: use Kernel::Tent or Kernel::Box (or a \
                     Deterministic rule)",
                );
            }
        }
    }
    if let Visibility::Cached { level } = p.visibility
        && !(1..=64).contains(&level)
    {
        return bad("Visibility::Cached.level", f64::from(level), "must be in 1..=64");
    }
    Ok(())
}
