//! Spatially varying albedo: a map of log-albedo over the wall plane, fitted with the shape.
//!
//! Tsai et al. 2019's reflectance is one BRDF for the whole surface. A hidden object whose reflectance varies — the
//! printed bars of a resolution chart, a label — then has only the shape to explain its intensity
//! variations, and the fit turns them into relief (the 40 cm chart came out as bumps over 0.395–0.49 m,
//! `docs/results.md`). With a map the same variations become albedo.
//!
//! **Model.** The albedo is a function `a(x, y) = exp θ(x, y)` of the position projected onto the wall
//! (the scene is seen from the wall along its normal, +z, so every visible point has its own (x, y)):
//! `θ` is bilinear between the centres of a regular grid of cells. Each triangle t reflects with the
//! factor `w_t = a(c_t)` at its centroid c_t, on top of the BRDF (`nlos_render::Renderer::set_face_weights`).
//! Tying the albedo to wall coordinates instead of to the mesh keeps it well defined through remeshing,
//! pruning and growth, which change the faces every block.
//!
//! **Gradient.** The renderer gives dE/dw_t (`nlos_render::Gradient::faces`); with `w_t = exp θ(c_t)` and
//! `θ(c_t) = Σ_c B_tc θ_c` (bilinear weights B), `dE/dθ_c = Σ_t dE/dw_t · w_t · B_tc` ([`AlbedoMap::chain`]).
//! The factors are held fixed while the vertices move (as visibility is): a shape step does not move a face
//! to a brighter cell.
//!
//! **Gauge.** The measurement's global scale is solved in closed form at every step, so a common shift of
//! θ changes nothing; after every step θ is shifted so that its area-weighted mean over the mesh is 0
//! ([`AlbedoMap::recentre`]): the geometric mean albedo is the BRDF's own.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::{OptimError, Result};

/// Parameters of the albedo map ([`crate::ReconstructParams::albedo_map`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AlbedoMapParams {
    /// Cell size in metres (default 0.01). Detail finer than about two cells cannot be represented.
    pub cell: f64,
    /// Adam learning rate of θ = log albedo, per reflectance step (default 0.05).
    pub lr: f64,
    /// Largest |θ| (default ln 20 ≈ 3.0: albedo within a factor 20 of the mean either way). A guard: cells
    /// that see little light cannot run away.
    pub max_log: f64,
}

impl Default for AlbedoMapParams {
    fn default() -> Self {
        Self { cell: 0.01, lr: 0.05, max_log: 20f64.ln() }
    }
}

impl AlbedoMapParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for a cell size that is not finite and in (0, 1] m, a learning rate
    /// that is not finite and ≥ 0, a `max_log` that is not finite and > 0.
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value, reason| Err(OptimError::InvalidParameter { name, value, reason });
        if !(self.cell.is_finite() && self.cell > 0.0 && self.cell <= 1.0) {
            return bad("albedo_map.cell", self.cell, "the cell size must be finite and in (0, 1] metres");
        }
        if !(self.lr.is_finite() && self.lr >= 0.0) {
            return bad("albedo_map.lr", self.lr, "the learning rate must be finite and >= 0");
        }
        if !(self.max_log.is_finite() && self.max_log > 0.0) {
            return bad("albedo_map.max_log", self.max_log, "must be finite and > 0");
        }
        Ok(())
    }
}

/// Log-albedo on a grid of cells over the wall plane (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AlbedoMap {
    /// (x, y) of the centre of cell (0, 0), metres.
    pub origin: [f64; 2],
    /// Cell size, metres.
    pub cell: f64,
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// θ = ln albedo per cell, row-major (index `iy·nx + ix`).
    pub log_albedo: Vec<f64>,
}

impl AlbedoMap {
    /// A uniform map (θ = 0) covering the (x, y) bounding box of `positions` with `margin` metres to spare
    /// on every side. Points outside the map take the value of its nearest edge.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] for an invalid cell size, no or non-finite positions, or a map of
    /// more than 4 million cells.
    pub fn covering(positions: &[Vec3], cell: f64, margin: f64) -> Result<Self> {
        AlbedoMapParams { cell, ..AlbedoMapParams::default() }.validate()?;
        if positions.is_empty() || positions.iter().any(|p| !p.is_finite()) {
            return Err(OptimError::InvalidParameter {
                name: "albedo_map",
                value: positions.len() as f64,
                reason: "the map needs finite mesh positions to cover (value = their count)",
            });
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in positions {
            for (k, c) in [f64::from(p.x), f64::from(p.y)].into_iter().enumerate() {
                lo[k] = lo[k].min(c - margin);
                hi[k] = hi[k].max(c + margin);
            }
        }
        let n = |k: usize| (((hi[k] - lo[k]) / cell).ceil() as usize).max(1);
        let (nx, ny) = (n(0), n(1));
        if nx.saturating_mul(ny) > 4_000_000 {
            return Err(OptimError::InvalidParameter {
                name: "albedo_map.cell",
                value: cell,
                reason: "the map would have more than 4 million cells: use a larger cell",
            });
        }
        Ok(Self { origin: [lo[0] + 0.5 * cell, lo[1] + 0.5 * cell], cell, nx, ny, log_albedo: vec![0.0; nx * ny] })
    }

    /// Checks a map read back from a file (a checkpoint): at least one cell each way, one value per cell,
    /// a finite positive cell size, finite origin and values. [`AlbedoMap::covering`] makes only valid maps.
    ///
    /// # Errors
    /// [`OptimError::InvalidParameter`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value, reason| Err(OptimError::InvalidParameter { name, value, reason });
        if self.nx == 0 || self.ny == 0 || self.nx.saturating_mul(self.ny) != self.log_albedo.len() {
            return bad(
                "albedo.log_albedo",
                self.log_albedo.len() as f64,
                "needs nx, ny >= 1 and nx·ny values (value = their count)",
            );
        }
        if !(self.cell.is_finite() && self.cell > 0.0) {
            return bad("albedo.cell", self.cell, "the cell size must be finite and > 0");
        }
        if let Some(v) = self.origin.iter().chain(&self.log_albedo).find(|v| !v.is_finite()) {
            return bad("albedo", *v, "the origin and the log-albedo values must be finite");
        }
        Ok(())
    }

    /// The four bilinear taps `(cell index, weight)` at (x, y), weights summing to 1 (clamped at the edges).
    pub fn taps(&self, x: f64, y: f64) -> [(usize, f64); 4] {
        let axis = |v: f64, o: f64, n: usize| -> (usize, usize, f64) {
            let u = ((v - o) / self.cell).clamp(0.0, (n - 1) as f64);
            // Guard: a NaN coordinate clamps to NaN; send it to cell 0 with weight 1.
            let u = if u.is_nan() { 0.0 } else { u };
            let i0 = (u.floor() as usize).min(n - 1);
            let i1 = (i0 + 1).min(n - 1);
            (i0, i1, u - i0 as f64)
        };
        let (x0, x1, fx) = axis(x, self.origin[0], self.nx);
        let (y0, y1, fy) = axis(y, self.origin[1], self.ny);
        let at = |ix: usize, iy: usize| iy * self.nx + ix;
        [
            (at(x0, y0), (1.0 - fx) * (1.0 - fy)),
            (at(x1, y0), fx * (1.0 - fy)),
            (at(x0, y1), (1.0 - fx) * fy),
            (at(x1, y1), fx * fy),
        ]
    }

    /// θ at (x, y).
    pub fn log_albedo_at(&self, x: f64, y: f64) -> f64 {
        self.taps(x, y).iter().map(|&(c, w)| w * self.log_albedo[c]).sum()
    }

    fn centroid(positions: &[Vec3], t: &[u32; 3]) -> (f64, f64) {
        let c = (positions[t[0] as usize] + positions[t[1] as usize] + positions[t[2] as usize]) / 3.0;
        (f64::from(c.x), f64::from(c.y))
    }

    /// The reflectance factor `w_t = exp θ(c_t)` of every triangle (c_t its centroid).
    pub fn face_weights(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<f32> {
        triangles
            .iter()
            .map(|t| {
                let (x, y) = Self::centroid(positions, t);
                self.log_albedo_at(x, y).exp() as f32
            })
            .collect()
    }

    /// dE/dθ per cell from dE/dw_t per triangle (`d_faces`, `nlos_render::Gradient::faces`):
    /// `Σ_t dE/dw_t · w_t · B_tc`.
    ///
    /// # Panics
    /// If `d_faces` does not hold one value per triangle.
    pub fn chain(&self, positions: &[Vec3], triangles: &[[u32; 3]], d_faces: &[f32]) -> Vec<f64> {
        assert_eq!(d_faces.len(), triangles.len(), "one dE/dw per triangle");
        let mut g = vec![0.0; self.log_albedo.len()];
        for (t, &d) in triangles.iter().zip(d_faces) {
            let (x, y) = Self::centroid(positions, t);
            let taps = self.taps(x, y);
            let w = taps.iter().map(|&(c, b)| b * self.log_albedo[c]).sum::<f64>().exp();
            for (c, b) in taps {
                g[c] += f64::from(d) * w * b;
            }
        }
        g
    }

    /// Adds `delta` to θ, clamped to `±max_log`.
    ///
    /// # Panics
    /// If `delta` does not hold one value per cell.
    pub fn add(&mut self, delta: &[f64], max_log: f64) {
        assert_eq!(delta.len(), self.log_albedo.len(), "one update per cell");
        for (t, d) in self.log_albedo.iter_mut().zip(delta) {
            *t = (*t + d).clamp(-max_log, max_log);
        }
    }

    /// Shifts θ so that its area-weighted mean over the mesh's triangles is 0 (the gauge; see the module
    /// docs). A mesh without area leaves θ as it is.
    pub fn recentre(&mut self, positions: &[Vec3], triangles: &[[u32; 3]]) {
        let (mut sum, mut area) = (0.0f64, 0.0f64);
        for t in triangles {
            let (a, b, c) = (positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]);
            let da = 0.5 * f64::from((b - a).cross(c - a).length());
            let (x, y) = Self::centroid(positions, t);
            sum += da * self.log_albedo_at(x, y);
            area += da;
        }
        if area > 0.0 && sum.is_finite() {
            let mean = sum / area;
            self.log_albedo.iter_mut().for_each(|t| *t -= mean);
        }
    }

    /// The albedo (exp θ) per cell, row-major, for pictures.
    pub fn albedo(&self) -> Vec<f64> {
        self.log_albedo.iter().map(|t| t.exp()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = vec![
            Vec3::new(-0.1, -0.1, 0.4),
            Vec3::new(0.1, -0.1, 0.4),
            Vec3::new(0.1, 0.1, 0.4),
            Vec3::new(-0.1, 0.1, 0.4),
        ];
        (p, vec![[0, 2, 1], [0, 3, 2]])
    }

    #[test]
    fn taps_interpolate_linear_functions_exactly() {
        let (p, _) = quad();
        let mut m = AlbedoMap::covering(&p, 0.03, 0.01).expect("valid");
        for iy in 0..m.ny {
            for ix in 0..m.nx {
                let (x, y) = (m.origin[0] + ix as f64 * m.cell, m.origin[1] + iy as f64 * m.cell);
                m.log_albedo[iy * m.nx + ix] = 0.3 * x - 2.0 * y + 0.1;
            }
        }
        for &(x, y) in &[(0.0, 0.0), (0.031, -0.07), (-0.09, 0.095)] {
            let taps = m.taps(x, y);
            assert!((taps.iter().map(|t| t.1).sum::<f64>() - 1.0).abs() < 1e-12);
            assert!((m.log_albedo_at(x, y) - (0.3 * x - 2.0 * y + 0.1)).abs() < 1e-12, "({x}, {y})");
        }
        // Outside the map: the nearest edge's value; NaN: a finite value, no panic.
        let edge = m.log_albedo_at(m.origin[0] - 5.0, 0.0);
        assert!((edge - m.log_albedo_at(m.origin[0], 0.0)).abs() < 1e-12);
        assert!(m.log_albedo_at(f64::NAN, 0.0).is_finite());
    }

    #[test]
    fn chain_matches_finite_differences() {
        // E(θ) = Σ_t c_t w_t(θ) with fixed c_t: dE/dw_t = c_t.
        let (p, t) = quad();
        let mut m = AlbedoMap::covering(&p, 0.05, 0.0).expect("valid");
        for (i, v) in m.log_albedo.iter_mut().enumerate() {
            *v = 0.1 * (i as f64).sin();
        }
        let c = [0.7f32, -1.3];
        let e = |m: &AlbedoMap| -> f64 {
            m.face_weights(&p, &t).iter().zip(&c).map(|(w, c)| f64::from(*w) * f64::from(*c)).sum()
        };
        let g = m.chain(&p, &t, &c);
        let mut nonzero = 0;
        for (k, &gk) in g.iter().enumerate() {
            let h = 1e-3;
            let (mut a, mut b) = (m.clone(), m.clone());
            a.log_albedo[k] += h;
            b.log_albedo[k] -= h;
            let fd = (e(&a) - e(&b)) / (2.0 * h);
            // The factors are f32: the difference quotient carries ~1e-4 relative rounding.
            assert!((fd - gk).abs() < 1e-3 * fd.abs().max(1e-3), "cell {k}: fd {fd} chain {gk}");
            nonzero += usize::from(gk != 0.0);
        }
        assert!(nonzero >= 2);
    }

    #[test]
    fn recentre_sets_the_area_weighted_mean_to_zero_and_add_clamps() {
        let (p, t) = quad();
        let mut m = AlbedoMap::covering(&p, 0.02, 0.0).expect("valid");
        m.add(&vec![0.5; m.log_albedo.len()], 3.0);
        m.log_albedo[0] = 1.0;
        m.recentre(&p, &t);
        let w = m.face_weights(&p, &t);
        let mean_log = (f64::from(w[0]).ln() + f64::from(w[1]).ln()) / 2.0; // equal areas
        assert!(mean_log.abs() < 1e-6, "{mean_log}");
        m.add(&vec![10.0; m.log_albedo.len()], 3.0);
        assert!(m.log_albedo.iter().all(|x| *x <= 3.0));
    }

    #[test]
    fn bad_parameters_are_typed_errors() {
        let (p, _) = quad();
        for cell in [0.0, -1.0, f64::NAN, 2.0] {
            assert!(matches!(AlbedoMap::covering(&p, cell, 0.0), Err(OptimError::InvalidParameter { .. })));
        }
        assert!(AlbedoMap::covering(&[], 0.01, 0.0).is_err());
        assert!(AlbedoMap::covering(&[Vec3::NAN], 0.01, 0.0).is_err());
        assert!(AlbedoMap::covering(&p, 1e-5, 0.0).is_err(), "too many cells");
        assert!(AlbedoMapParams { lr: -1.0, ..Default::default() }.validate().is_err());
        assert!(AlbedoMapParams { max_log: 0.0, ..Default::default() }.validate().is_err());
        // Maps read back from a file: empty, inconsistent or non-finite ones are refused.
        let good = AlbedoMap::covering(&p, 0.05, 0.0).expect("valid");
        assert!(good.validate().is_ok());
        for broken in [
            AlbedoMap { nx: 0, log_albedo: vec![], ..good.clone() },
            AlbedoMap { log_albedo: vec![0.0; 1], ..good.clone() },
            AlbedoMap { cell: 0.0, ..good.clone() },
            AlbedoMap { origin: [f64::NAN, 0.0], ..good.clone() },
        ] {
            assert!(matches!(broken.validate(), Err(OptimError::InvalidParameter { .. })), "{broken:?}");
        }
    }
}
