//! The built-in scene of `cargo xtask reconstruct`: a bumpy Lambertian patch facing the wall, rendered by
//! `nlos-render` on a reduced version of the seed's setup, with Poisson photon noise from the SPAD model.

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::SurfaceMesh;
use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
use nlos_transient::sensor::{PhotonBudget, SpadModel};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

/// Geometry and capture settings of the built-in scene.
#[derive(Debug, Clone, Copy)]
pub struct BuiltinScene {
    /// Depth of the patch's flat part (metres from the wall).
    pub depth: f32,
    /// Side of the square patch (metres).
    pub size: f32,
    /// Height of the Gaussian bump toward the wall (metres).
    pub bump: f32,
    /// Width (σ) of the bump (metres).
    pub bump_sigma: f32,
    /// Grid cells per side of the ground-truth mesh.
    pub cells: usize,
    /// Scan points per side (confocal, over the seed's [−0.25, 0.25]² m).
    pub grid: usize,
    /// Time bins (of `bin_width`, from path length 0).
    pub bins: usize,
    /// Bin width, metres of path (the seed's 1.2 mm × 2).
    pub bin_width: f64,
    /// Expected detected photons per measurement (Poisson noise).
    pub photons: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for BuiltinScene {
    fn default() -> Self {
        Self {
            depth: 0.4,
            size: 0.24,
            bump: 0.04,
            bump_sigma: 0.04,
            cells: 48,
            grid: 24,
            bins: 512,
            bin_width: 0.0024,
            photons: 2000.0,
            seed: 1,
        }
    }
}

impl BuiltinScene {
    /// The ground-truth mesh, centred on the z axis, faces toward the wall (normals −z).
    pub fn mesh(&self) -> Result<SurfaceMesh, String> {
        let (h, d, b, s) = (self.size / 2.0, self.depth, self.bump, self.bump_sigma);
        let field = nlos_mesh::shapes::height_field(self.size, self.size, self.cells, self.cells, |x, y| {
            let (u, v) = (x - h, y - h);
            d - b * (-(u * u + v * v) / (2.0 * s * s)).exp()
        })
        .map_err(|e| e.to_string())?;
        let (positions, triangles) = field.to_triangles();
        let positions: Vec<Vec3> = positions.iter().map(|p| Vec3::new(p.x - h, p.y - h, p.z)).collect();
        // The height field's faces point to +z; reverse the corners so they face the wall.
        let triangles: Vec<[u32; 3]> = triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
        SurfaceMesh::from_triangles(&positions, &triangles).map_err(|e| e.to_string())
    }

    /// Renders the noise-free transient (box kernel, as a measurement) and a Poisson photon-count capture.
    pub fn capture(&self, mesh: &SurfaceMesh) -> Result<(Transient, Transient), String> {
        let scan = Scan::confocal(PointSet::wall_grid(self.grid, self.grid, 0.25, 0.25).map_err(|e| e.to_string())?);
        let time = TimeAxis::new(0.0, self.bin_width, self.bins).map_err(|e| e.to_string())?;
        let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
        let (positions, triangles) = mesh.to_triangles();
        let renderer = Renderer::new(&positions, &triangles, &scan, &time, params).map_err(|e| e.to_string())?;
        let brdf = Lambertian::new(1.0f32).map_err(|e| e.to_string())?;
        let clean = renderer.forward_transient(&brdf).map_err(|e| e.to_string())?;
        let model = SpadModel::ideal(PhotonBudget::PerMeasurement(self.photons));
        let noisy = model.simulate(&clean, self.seed).map_err(|e| e.to_string())?;
        Ok((clean, noisy))
    }
}
