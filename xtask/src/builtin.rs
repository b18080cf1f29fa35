//! The built-in scene: a small Lambertian square facing the wall, and its confocal transient.
//!
//! Until `nlos-render` lands this is the only synthetic scene; the transient is a midpoint quadrature of
//! the three-bounce integral (Tsai et al. 2019, eq. 1–2) over the square, for a Lambertian surface of
//! albedo 1 with the relay wall's own BRDF left out:
//! `I(t; s) = Σ_patches ρ/π · cosθ_x² · cosθ_s² / |x − s|⁴ · ΔA`, binned by the path length `2|x − s|`.

use glam::Vec3;
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// Geometry of the built-in scene.
#[derive(Debug, Clone, Copy)]
pub struct BuiltinScene {
    /// Depth of the square (metres from the wall).
    pub depth: f32,
    /// Half side of the square (metres).
    pub half_size: f32,
    /// Scan grid points per side.
    pub grid: usize,
    /// Half width of the scanned wall area (metres).
    pub wall_half_width: f64,
    /// Quadrature cells per side of the square.
    pub cells: usize,
}

impl Default for BuiltinScene {
    fn default() -> Self {
        Self { depth: 0.4, half_size: 0.1, grid: 32, wall_half_width: 0.25, cells: 200 }
    }
}

impl BuiltinScene {
    /// Renders the confocal transient on the seed's time axis (1200 bins of 1.2 mm, t0 = 0).
    pub fn render(&self) -> nlos_transient::Result<Transient> {
        let hw = self.wall_half_width;
        let scan = Scan::confocal(PointSet::wall_grid(self.grid, self.grid, hw, hw)?);
        let time = TimeAxis::new(0.0, 0.0012, 1200)?;
        let mut t = Transient::zeros(scan, time)?;
        let n = self.cells;
        let da = (2.0 * self.half_size / n as f32).powi(2);
        let normal = Vec3::NEG_Z;
        for m in 0..t.measurements() {
            let s = t.scan().lasers().points[m];
            let mut hist = vec![0.0f64; time.bins];
            for i in 0..n {
                for j in 0..n {
                    let u = -self.half_size + (i as f32 + 0.5) * 2.0 * self.half_size / n as f32;
                    let v = -self.half_size + (j as f32 + 0.5) * 2.0 * self.half_size / n as f32;
                    let x = Vec3::new(u, v, self.depth);
                    let d = s - x;
                    let r = d.length();
                    let w = d / r;
                    let cos_x = normal.dot(w).max(0.0);
                    let cos_s = (x.z / r).max(0.0);
                    let value = std::f32::consts::FRAC_1_PI * cos_x * cos_x * cos_s * cos_s / r.powi(4) * da;
                    if let Some(k) = time.bin_of(f64::from(2.0 * r)) {
                        hist[k] += f64::from(value);
                    }
                }
            }
            for (o, h) in t.histogram_mut(m).iter_mut().zip(hist) {
                *o = h as f32;
            }
        }
        Ok(t)
    }
}
