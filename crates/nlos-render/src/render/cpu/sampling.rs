//! Where the renderer samples a triangle: the wall frame of a measurement, points and their orientation,
//! live visibility, the subdivision level of the point rules and of the splat rule's blocks, and the
//! stratified samples.

use glam::Vec3;
use nlos_transient::rng::SplitMix64;

use crate::kernel::KernelEval;
use crate::render::soa::{BLOCK, Frame, TentAxis};
use crate::render::{Lobe, Scene, subtriangles};
use crate::{DeterministicRule, Sampling};

impl Scene {
    #[inline(always)]
    pub(in crate::render) fn frame(&self, m: usize) -> Frame {
        Frame { l: self.wall.l[m], n_l: self.wall.n_l[m], s: self.wall.s[m], n_s: self.wall.n_s[m] }
    }

    #[inline(always)]
    pub(in crate::render) fn point(&self, t: usize, u: f32, v: f32) -> Vec3 {
        self.tris.v0[t] + u * self.tris.e1[t] + v * self.tris.e2[t]
    }

    /// +1 when l and s are both on the front side of triangle t, −1 when both behind and two-sided, else
    /// None. Exact for the whole face: N·(l − x) does not depend on x in the plane.
    #[inline(always)]
    pub(in crate::render) fn orientation(&self, t: usize, fr: &Frame) -> Option<f32> {
        if !self.tris.valid[t] {
            return None;
        }
        let (n, v0) = (self.tris.n[t], self.tris.v0[t]);
        let (dl, ds) = (n.dot(fr.l - v0), n.dot(fr.s - v0));
        if dl > 0.0 && ds > 0.0 {
            Some(1.0)
        } else if self.params.two_sided && dl < 0.0 && ds < 0.0 {
            Some(-1.0)
        } else {
            None
        }
    }

    #[inline(always)]
    pub(in crate::render) fn visible_live(&self, x: Vec3, t: usize, fr: &Frame) -> bool {
        match &self.bvh {
            None => true,
            Some(b) => b.visible(x, fr.l, t as u32) && (self.wall.confocal || b.visible(x, fr.s, t as u32)),
        }
    }

    /// Calls `f(u, v, w)` for the `n²` sub-triangle centroids of level n (barycentric coordinates u along
    /// e1, v along e2; weight `w = 1/n²`, the fraction of the triangle's area).
    #[inline(always)]
    pub(in crate::render) fn centroids(&self, n: u32, mut f: impl FnMut(f32, f32, f32)) {
        subtriangles(n, |s| f(s.centroid.0, s.centroid.1, s.w));
    }

    /// Deterministic level for (t, m): see [`DeterministicRule`].
    #[inline(always)]
    pub(in crate::render) fn level(&self, rule: &DeterministicRule, t: usize, fr: &Frame) -> u32 {
        if rule.min_level >= rule.max_level {
            return rule.max_level;
        }
        let v = [self.tris.v0[t], self.tris.v0[t] + self.tris.e1[t], self.tris.v0[t] + self.tris.e2[t]];
        let (mut lo, mut hi, mut r_min) = (f32::INFINITY, 0.0f32, f32::INFINITY);
        for p in v {
            let (a, b) = ((fr.l - p).length(), (fr.s - p).length());
            lo = lo.min(a + b);
            hi = hi.max(a + b);
            r_min = r_min.min(a).min(b);
        }
        let tol = rule.max_bin_fraction * self.time.bin_width as f32;
        // Guard: a vertex on a wall spot (r_min = 0) would make the curvature bound infinite; the clamp to
        // max_level below handles it, and 1e-6 m keeps the arithmetic finite.
        let curv = self.tris.e_max[t] * self.tris.e_max[t] / r_min.max(1e-6);
        let range = hi - lo;
        // Smallest n with tol·n² − range·n − curv ≥ 0.
        let n = (range + (range * range + 4.0 * tol * curv).sqrt()) / (2.0 * tol);
        if !(n < rule.max_level as f32) { rule.max_level } else { (n.ceil() as u32).max(rule.min_level) }
    }

    /// Calls `f(u, v, w)` for every sample of (t, m); `w` is the sample's weight as a fraction of the
    /// triangle's area (the estimator of `∫_t h dA` is `A_t Σ w h(x)`). `lobe`: the BRDF's lobe roughness
    /// (see [`Renderer::set_lobe_sampling`]); `sign`: the pair's orientation.
    #[inline(always)]
    pub(in crate::render) fn samples(
        &self,
        m: usize,
        t: usize,
        fr: &Frame,
        lobe: Option<f32>,
        sign: f32,
        mut f: impl FnMut(f32, f32, f32),
    ) {
        match self.params.sampling {
            Sampling::Deterministic(rule) => {
                let n = self.level(&rule, t, fr);
                self.centroids(n, f);
            }
            // The splat rule's sub-triangle centroids (reached only with a kernel the closed form does not
            // cover, where it is the fixed centroid rule of the triangle's level).
            Sampling::Splat(_) => self.centroids(self.tri_levels.get(t).copied().unwrap_or(1), f),
            Sampling::Stratified { samples_per_measurement, seed } => {
                let area = 0.5 * self.tris.n[t].length();
                let c = samples_per_measurement as f32 * area / self.total_area;
                // Guard: c is finite and > 0 for a valid triangle (total_area ≥ area > 0).
                if !(c > 0.0) {
                    return;
                }
                let mut rng = SplitMix64::keyed(seed, m as u64, t as u64);
                let lobe = match lobe {
                    Some(alpha) if self.lobe_fraction > 0.0 && self.wall.confocal && alpha > 0.0 => {
                        Some(Lobe::new(alpha, sign * self.tris.n[t], fr.l))
                    }
                    _ => None,
                };
                // The lobe's share of the samples: `lobe_fraction` scaled by Ω_t/(Ω_t + Ω_lobe), the solid angle
                // Ω_t of the triangle seen from l against the lobe's Ω_lobe = 4πα² (a lobe wider than the
                // triangle is better served by area sampling). A function of the geometry only (held fixed
                // when differentiating, as the weights are).
                let (c1, c2) = match (&lobe, lobe.map(|_| self.tris.v0[t] + (self.tris.e1[t] + self.tris.e2[t]) / 3.0))
                {
                    (Some(l), Some(centroid)) => {
                        let d = fr.l - centroid;
                        let r2 = d.length_squared();
                        let omega_t = area * l.n.dot(d).max(0.0) / (r2 * r2.sqrt());
                        let omega_lobe = 4.0 * std::f32::consts::PI * l.alpha2;
                        let phi = self.lobe_fraction * omega_t / (omega_t + omega_lobe);
                        let phi = if phi.is_finite() { phi } else { 0.0 };
                        ((1.0 - phi) * c, phi * c)
                    }
                    _ => (c, 0.0),
                };
                // The balance-heuristic weight of a sample at x, as a fraction of the area: 1/(c₁ + c₂ A p₂(x))
                // (= 1/c without the lobe).
                let weight = |u: f32, v: f32| match &lobe {
                    Some(l) => 1.0 / (c1 + c2 * area * l.pdf(self.point(t, u, v))),
                    None => 1.0 / c1,
                };
                let base = c1.floor();
                let n = base as u32 + u32::from(rng.next_f32() < c1 - base);
                // Weights are held constant when differentiating (sampling weights, not part of the
                // integrand); the random counts have expectation c₁, c₂, so the estimator is unbiased.
                let inv_n = 1.0 / n.max(1) as f32;
                for i in 0..n {
                    // Stratified along the first coordinate of the area-preserving map
                    // (r1, r2) ↦ (√r1 (1 − r2), √r1 r2).
                    let r1 = (i as f32 + rng.next_f32()) * inv_n;
                    let r2 = rng.next_f32();
                    let sr = r1.sqrt();
                    let (u, v) = (sr * (1.0 - r2), sr * r2);
                    f(u, v, weight(u, v));
                }
                let Some(lobe) = lobe else { return };
                let base = c2.floor();
                let n2 = base as u32 + u32::from(rng.next_f32() < c2 - base);
                let (v0, e1, e2) = (self.tris.v0[t], self.tris.e1[t], self.tris.e2[t]);
                let inv_n2 = 1.0 / n2.max(1) as f32;
                for i in 0..n2 {
                    // Stratified along the lobe's polar coordinate, like the area samples.
                    let (r1, r2) = ((i as f32 + rng.next_f32()) * inv_n2, rng.next_f32());
                    if let Some((u, v)) = lobe.sample(r1, r2, v0, e1, e2) {
                        f(u, v, weight(u, v));
                    }
                }
            }
        }
    }

    /// The mesh triangle at storage slot `slot` of the block kernels' layout.
    #[inline(always)]
    pub(in crate::render) fn mesh_triangle(&self, slot: usize) -> usize {
        self.tris.soa.order[slot] as usize
    }

    /// The fixed level when the sampling is the deterministic rule with `min_level = max_level` (the block
    /// kernels' case), else None.
    #[inline(always)]
    pub(in crate::render) fn fixed_level(&self) -> Option<u32> {
        match self.params.sampling {
            Sampling::Deterministic(rule) if rule.min_level >= rule.max_level => Some(rule.max_level),
            _ => None,
        }
    }

    /// Whether the sampling runs the packed block kernels: the fixed deterministic rule and the splat rule.
    #[inline(always)]
    pub(in crate::render) fn packed_rule(&self) -> bool {
        self.fixed_level().is_some() || matches!(self.params.sampling, Sampling::Splat(_))
    }

    /// The subdivision level of the block starting at slot `t0` for the packed rules (1 for the others).
    #[inline(always)]
    pub(in crate::render) fn block_level(&self, t0: usize) -> u32 {
        match self.params.sampling {
            Sampling::Splat(_) => self.block_levels.get(t0 / BLOCK).copied().unwrap_or(1),
            _ => self.fixed_level().unwrap_or(1),
        }
    }

    /// The splat's time axis when the splat rule applies (splat sampling and the tent or box kernel `k`,
    /// not the steady state).
    #[inline(always)]
    pub(in crate::render) fn splat_axis(&self, k: &KernelEval) -> Option<TentAxis> {
        match self.params.sampling {
            Sampling::Splat(_) => k.tent().or_else(|| k.box_axis()),
            _ => None,
        }
    }

    /// The tent kernel's block constants when the fast path applies (fixed deterministic rule, tent kernel).
    #[inline(always)]
    pub(in crate::render) fn tent_path(&self, k: &KernelEval) -> Option<TentAxis> {
        self.fixed_level().and(k.tent())
    }
}
