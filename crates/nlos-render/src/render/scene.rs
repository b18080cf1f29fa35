//! The backend-neutral scene ([`Scene`]): what every backend's forward and adjoint passes read, built and
//! updated here (positions, visibility cache, subdivision levels, per-face factors); the vertex distribution
//! of per-triangle gradients ([`Scene::distribute`]), which both backends share.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DVec3, Vec3};
use nlos_brdf::FittedBrdf;
use nlos_transient::{Scan, TimeAxis};

use super::{Gradient, RenderParams, Sampling, Visibility, check_params};
use crate::error::{RenderError, Result};
use crate::kernel::KernelEval;
use crate::render::soa::{BLOCK, Soa};
use crate::visibility::Bvh;

/// Per-measurement wall geometry, structure of arrays.
#[derive(Debug, Clone)]
pub(in crate::render) struct Wall {
    pub(in crate::render) l: Vec<Vec3>,
    pub(in crate::render) n_l: Vec<Vec3>,
    pub(in crate::render) s: Vec<Vec3>,
    pub(in crate::render) n_s: Vec<Vec3>,
    pub(in crate::render) confocal: bool,
}

/// Triangles as structure of arrays.
#[derive(Debug, Clone, Default)]
pub(in crate::render) struct Tris {
    pub(in crate::render) v0: Vec<Vec3>,
    pub(in crate::render) e1: Vec<Vec3>,
    pub(in crate::render) e2: Vec<Vec3>,
    /// Unnormalised geometric normal `e1 × e2` (|N| = 2 × area).
    pub(in crate::render) n: Vec<Vec3>,
    /// Longest edge.
    pub(in crate::render) e_max: Vec<f32>,
    pub(in crate::render) valid: Vec<bool>,
    /// The same geometry, one array per coordinate, for the block kernels.
    pub(in crate::render) soa: Soa,
}

/// What a backend renders: one mesh topology at its current positions (triangles as structure of arrays,
/// in the block order of the CPU's kernels, which the visibility cache shares), the wall's spots per
/// measurement, the time axis and its kernel, the visibility (BVH, cache) and the per-face reflectance factors,
/// with the splat rule's subdivision levels. Backend-neutral: the CPU backend (`cpu/`) and the GPU backend
/// (`gpu/`) read it; [`Renderer`] owns it and sends each pass to a backend.
#[derive(Debug)]
pub(crate) struct Scene {
    pub(in crate::render) triangles: Vec<[u32; 3]>,
    pub(in crate::render) n_vertices: usize,
    pub(in crate::render) tris: Tris,
    pub(in crate::render) total_area: f32,
    pub(in crate::render) wall: Wall,
    pub(in crate::render) scan: Scan,
    pub(in crate::render) time: TimeAxis,
    pub(in crate::render) params: RenderParams,
    pub(in crate::render) kernel: KernelEval,
    pub(in crate::render) bvh: Option<Bvh>,
    /// Visible fraction × 255 per (measurement, triangle), block by block ([`super::cache::CacheLayout`]),
    /// triangles in the block order (`tris.soa.order`, kept by `set_positions` while the cache exists).
    pub(in crate::render) cache: Option<Vec<u8>>,
    /// Fraction of the stratified samples drawn from the glossy lobe (0: area sampling only).
    pub(in crate::render) lobe_fraction: f32,
    /// Per-triangle reflectance factors (mesh triangle order), None = all 1.
    pub(in crate::render) face_weights: Option<Vec<f32>>,
    /// Bounding box of every laser and sensor spot (the splat rule's distance bound).
    pub(in crate::render) spots: (Vec3, Vec3),
    /// Splat rule: the subdivision level of each block of `BLOCK` storage slots, and of each mesh triangle
    /// (its block's level); empty for the other rules.
    pub(in crate::render) block_levels: Vec<u32>,
    pub(in crate::render) tri_levels: Vec<u32>,
    /// Which visibility refresh the cache holds, unique in the process (the GPU backend uploads the cache
    /// again when it changes; 0: none yet).
    pub(in crate::render) vis_generation: u64,
    /// Measurements finished by the CPU's visibility and forward passes ([`Renderer::new_observed`]).
    pub(in crate::render) progress: Option<Arc<AtomicUsize>>,
    /// Seconds each task of the CPU's last adjoint pass took (its ranges of triangles): the next pass starts
    /// the longest first ([`super::cpu::longest_first`]). A schedule only: the results do not depend on it.
    pub(in crate::render) adjoint_costs: std::sync::Mutex<Vec<f64>>,
}

impl Scene {
    /// Validates the inputs and builds the geometry (and the BVH and cache the visibility mode needs); see
    /// [`super::Renderer::new_observed`].
    ///
    /// # Errors
    /// As [`super::Renderer::new`].
    pub(in crate::render) fn new(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        scan: &Scan,
        time: &TimeAxis,
        params: RenderParams,
        progress: Option<Arc<AtomicUsize>>,
    ) -> Result<Self> {
        scan.validate().map_err(|e| RenderError::InvalidSetup(e.to_string()))?;
        time.validate().map_err(|e| RenderError::InvalidSetup(e.to_string()))?;
        if scan.measurements() == 0 {
            return Err(RenderError::InvalidSetup("the scan has no measurements".into()));
        }
        check_params(&params)?;
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                if v as usize >= positions.len() {
                    return Err(RenderError::IndexOutOfRange { triangle: t, vertex: v, vertices: positions.len() });
                }
            }
        }
        let m = scan.measurements();
        let mut wall = Wall {
            l: Vec::with_capacity(m),
            n_l: Vec::with_capacity(m),
            s: Vec::with_capacity(m),
            n_s: Vec::with_capacity(m),
            confocal: scan.is_confocal(),
        };
        for i in 0..m {
            let g = scan.measurement(i);
            wall.l.push(g.laser);
            wall.n_l.push(g.laser_normal);
            wall.s.push(g.sensor);
            wall.n_s.push(g.sensor_normal);
        }
        let mut r = Self {
            triangles: triangles.to_vec(),
            n_vertices: positions.len(),
            tris: Tris::default(),
            total_area: 0.0,
            wall,
            scan: scan.clone(),
            time: *time,
            params,
            kernel: KernelEval::new(params.kernel, time.t0, time.bin_width, time.bins),
            bvh: None,
            cache: None,
            lobe_fraction: 0.0,
            face_weights: None,
            spots: spot_box(scan),
            block_levels: Vec::new(),
            tri_levels: Vec::new(),
            vis_generation: 0,
            progress,
            adjoint_costs: std::sync::Mutex::new(Vec::new()),
        };
        r.set_positions(positions)?;
        if matches!(params.visibility, Visibility::Cached { .. }) {
            r.refresh_visibility();
        }
        Ok(r)
    }

    /// Moves the vertices (same topology). With [`Visibility::Live`] the BVH is rebuilt; with
    /// [`Visibility::Cached`] the cache is kept (visibility held fixed) until [`Renderer::refresh_visibility`].
    ///
    /// # Errors
    /// [`RenderError::TopologyChanged`] for a different vertex count, [`RenderError::NonFiniteVertex`].
    pub(in crate::render) fn set_positions(&mut self, positions: &[Vec3]) -> Result<()> {
        if positions.len() != self.n_vertices {
            return Err(RenderError::TopologyChanged { expected: self.n_vertices, got: positions.len() });
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(RenderError::NonFiniteVertex { index: i, value: positions[i].to_array() });
        }
        let nt = self.triangles.len();
        let mut tris = Tris {
            v0: Vec::with_capacity(nt),
            e1: Vec::with_capacity(nt),
            e2: Vec::with_capacity(nt),
            n: Vec::with_capacity(nt),
            e_max: Vec::with_capacity(nt),
            valid: Vec::with_capacity(nt),
            soa: Soa::default(),
        };
        let mut area = 0.0f64;
        for &[a, b, c] in &self.triangles {
            let (p0, p1, p2) = (positions[a as usize], positions[b as usize], positions[c as usize]);
            let (e1, e2) = (p1 - p0, p2 - p0);
            let n = e1.cross(e2);
            let len = n.length();
            // Guard: a zero-area (or overflowing) face has no integral and no defined normal: skipped.
            let valid = len > 0.0 && len.is_finite();
            if valid {
                area += 0.5 * f64::from(len);
            }
            tris.v0.push(p0);
            tris.e1.push(e1);
            tris.e2.push(e2);
            tris.n.push(n);
            tris.e_max.push(e1.length().max(e2.length()).max((p2 - p1).length()));
            tris.valid.push(valid);
        }
        // The visibility cache is stored in the block order, which is therefore kept while the cache is.
        let keep = (self.cache.is_some() && matches!(self.params.visibility, Visibility::Cached { .. }))
            .then(|| std::mem::take(&mut self.tris.soa.order));
        tris.soa = Soa::new(&tris.v0, &tris.e1, &tris.e2, &tris.n, &tris.valid, keep);
        self.tris = tris;
        self.total_area = area as f32;
        if self.params.visibility == Visibility::Live {
            self.bvh = Bvh::build(&self.tris.v0, &self.tris.e1, &self.tris.e2, &self.tris.valid);
        }
        self.update_levels();
        Ok(())
    }

    /// Each triangle's level under the splat rule ([`SplatRule`]) at the positions of `t` (mesh order), None
    /// for the other rules.
    fn splat_levels(&self, t: &Tris) -> Option<Vec<u32>> {
        let Sampling::Splat(rule) = self.params.sampling else { return None };
        let tol = rule.max_deviation * self.time.bin_width as f32;
        let (lo, hi) = self.spots;
        let level = |i: usize| -> u32 {
            if !t.valid[i] {
                return 1;
            }
            let e = t.e_max[i];
            let r = [t.v0[i], t.v0[i] + t.e1[i], t.v0[i] + t.e2[i]]
                .iter()
                .map(|p| (lo - *p).max(*p - hi).max(Vec3::ZERO).length())
                .fold(f32::INFINITY, f32::min)
                - e;
            // Guard: a triangle touching a spot's box has no useful bound: the finest level (1e-4 m keeps the
            // arithmetic finite).
            let deviation = (2.0 / r.max(1e-4)) * e * e / 6.0;
            let n = (deviation / tol).sqrt().ceil();
            if n < rule.max_level as f32 { (n as u32).max(1) } else { rule.max_level }
        };
        Some((0..t.valid.len()).map(level).collect())
    }

    /// The splat rule's levels ([`SplatRule`]) for the current positions and block order: a block runs the
    /// largest level of its triangles.
    fn update_levels(&mut self) {
        let Some(level) = self.splat_levels(&self.tris) else { return };
        let order = &self.tris.soa.order;
        self.block_levels =
            order.chunks(BLOCK).map(|blk| blk.iter().map(|&i| level[i as usize]).max().unwrap_or(1)).collect();
        let mut tri = vec![1u32; order.len()];
        for (slot, &i) in order.iter().enumerate() {
            tri[i as usize] = self.block_levels[slot / BLOCK];
        }
        self.tri_levels = tri;
    }

    /// Rebuilds the BVH at the current positions and, in [`Visibility::Cached`] mode, recomputes the cache.
    pub(in crate::render) fn refresh_visibility(&mut self) {
        if self.params.visibility == Visibility::Off {
            return;
        }
        self.bvh = Bvh::build(&self.tris.v0, &self.tris.e1, &self.tris.e2, &self.tris.valid);
        let Visibility::Cached { level } = self.params.visibility else { return };
        // Regroup the triangles by their current normals; the cache is stored in that order (slot i: mesh
        // triangle order[i]), so the block kernels read it contiguously.
        let t = &self.tris;
        self.tris.soa = Soa::new(&t.v0, &t.e1, &t.e2, &t.n, &t.valid, None);
        self.update_levels();
        let cache = self.visibility_cache(level);
        self.cache = Some(cache);
        // Unique across renderers: a renderer made after another one was dropped may sit at its address.
        static REFRESHES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        self.vis_generation = REFRESHES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Adds `n` finished measurements to the progress counter, if any.
    pub(in crate::render) fn count_done(&self, n: usize) {
        if let Some(p) = &self.progress {
            p.fetch_add(n, Ordering::Relaxed);
        }
    }

    /// Glossy-lobe sampling's share; see [`super::Renderer::set_lobe_sampling`].
    ///
    /// # Errors
    /// [`RenderError::InvalidParameter`] unless `0 ≤ lobe_fraction < 1`.
    pub(in crate::render) fn set_lobe_sampling(&mut self, lobe_fraction: f32) -> Result<()> {
        if !(0.0..1.0).contains(&lobe_fraction) {
            return Err(RenderError::InvalidParameter {
                name: "lobe_fraction",
                value: f64::from(lobe_fraction),
                reason: "must be in [0, 1)",
            });
        }
        self.lobe_fraction = lobe_fraction;
        Ok(())
    }

    /// Per-face reflectance factors; see [`super::Renderer::set_face_weights`].
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`], [`RenderError::InvalidParameter`].
    pub(in crate::render) fn set_face_weights(&mut self, weights: Option<&[f32]>) -> Result<()> {
        if let Some(w) = weights {
            if w.len() != self.triangles.len() {
                return Err(RenderError::LengthMismatch {
                    what: "face weights",
                    expected: self.triangles.len(),
                    got: w.len(),
                });
            }
            if let Some(bad) = w.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                return Err(RenderError::InvalidParameter {
                    name: "face weight",
                    value: f64::from(*bad),
                    reason: "must be finite and ≥ 0 (a reflectance factor)",
                });
            }
        }
        self.face_weights = weights.map(<[f32]>::to_vec);
        Ok(())
    }

    /// Triangle t's reflectance factor (1 without factors).
    #[inline(always)]
    pub(in crate::render) fn face_weight(&self, t: usize) -> f32 {
        self.face_weights.as_ref().map_or(1.0, |w| w[t])
    }

    /// Number of skipped degenerate triangles.
    pub(in crate::render) fn degenerate_triangles(&self) -> usize {
        self.tris.valid.iter().filter(|v| !**v).count()
    }

    /// Number of values of a transient (measurements × bins).
    pub(in crate::render) fn len(&self) -> usize {
        self.wall.l.len() * self.time.bins
    }

    /// The gradient from the per-slot sums of the adjoint (`Σ (1−u−v) dE/dx, Σ u dE/dx, Σ v dE/dx, sign·Σ dE/dN`
    /// per storage slot) and the summed BRDF parameter terms: the edge terms and the vertex distribution, serial in
    /// slot order (deterministic), and the per-face weights' derivatives.
    pub(in crate::render) fn distribute<B: FittedBrdf>(&self, per_tri: &[[f64; 12]], dp: [f64; 4]) -> Gradient {
        let nt = self.tris.v0.len();
        // Distribution to the vertices (serial, in triangle order: deterministic). N = sign·(e1 × e2) and the
        // sums carry the sign: dE/de1 = e2 × G_N, dE/de2 = G_N × e1.
        let mut dv = vec![DVec3::ZERO; self.n_vertices];
        let mut faces = vec![0.0f32; nt];
        for (slot, g) in per_tri.iter().enumerate() {
            let t = self.mesh_triangle(slot);
            let v3 = |k: usize| DVec3::new(g[k], g[k + 1], g[k + 2]);
            let (g0, g1, g2, g_n) = (v3(0), v3(3), v3(6), v3(9));
            let (e1, e2) = (self.tris.e1[t].as_dvec3(), self.tris.e2[t].as_dvec3());
            // The triangle's integrand w_t·f_s(n̂)·Q(N) is homogeneous of degree 1 in N = e1 × e2 (Q holds
            // (N·a)(N·b)/|N|, f_s sees N only through n̂ = N/|N|) and the time kernel does not see N, so by
            // Euler's theorem N·dE/dN = Σ (dE/dI)·(the triangle's contribution) = w_t·dE/dw_t.
            let w = self.face_weight(t);
            if w > 0.0 {
                faces[t] = (e1.cross(e2).dot(g_n) / f64::from(w)) as f32;
            }
            let (d_e1, d_e2) = (e2.cross(g_n), g_n.cross(e1));
            let [i0, i1, i2] = self.triangles[t];
            dv[i0 as usize] += g0 - d_e1 - d_e2;
            dv[i1 as usize] += g1 + d_e1;
            dv[i2 as usize] += g2 + d_e2;
        }
        Gradient {
            vertices: dv.iter().map(|g| g.as_vec3()).collect(),
            brdf: dp[..B::PARAM_NAMES.len()].iter().map(|g| *g as f32).collect(),
            faces,
        }
    }
}

/// Componentwise bounding box of every laser and sensor spot of the scan.
fn spot_box(scan: &Scan) -> (Vec3, Vec3) {
    (0..scan.measurements()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), i| {
        let g = scan.measurement(i);
        (lo.min(g.laser).min(g.sensor), hi.max(g.laser).max(g.sensor))
    })
}
