//! The built-in scene: a bumpy Lambertian patch facing the wall, rendered by `nlos-render` on a reduced
//! version of Tsai et al. 2019's setup, with Poisson photon noise from the SPAD model.
//!
//! `cargo xtask reconstruct` (no arguments) reconstructs it; `fixtures/builtin/` holds its ground truth,
//! its capture and its LCT start (`cargo xtask fixtures` writes them from this module), so that tests and
//! examples exercise the real pipeline on a fresh clone, without the shared data.

use glam::Vec3;
use nlos_brdf::Lambertian;
use nlos_mesh::SurfaceMesh;
use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
use nlos_transient::sensor::{PhotonBudget, SpadModel};
use nlos_transient::{PointSet, Scan, TimeAxis, Transient};

use crate::{OptimError, Result};

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
    /// Scan points per side (confocal, over Tsai et al. 2019's [−0.25, 0.25]² m).
    pub grid: usize,
    /// Time bins (of `bin_width`, from path length 0).
    pub bins: usize,
    /// Bin width, metres of path (Tsai et al. 2019's 1.2 mm × 2).
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
    ///
    /// # Errors
    /// [`OptimError::Mesh`] when the settings give no valid height field (a zero or negative size or
    /// cell count).
    pub fn mesh(&self) -> Result<SurfaceMesh> {
        let (h, d, b, s) = (self.size / 2.0, self.depth, self.bump, self.bump_sigma);
        let field = nlos_mesh::shapes::height_field(self.size, self.size, self.cells, self.cells, |x, y| {
            let (u, v) = (x - h, y - h);
            d - b * (-(u * u + v * v) / (2.0 * s * s)).exp()
        })?;
        let (positions, triangles) = field.to_triangles();
        let positions: Vec<Vec3> = positions.iter().map(|p| Vec3::new(p.x - h, p.y - h, p.z)).collect();
        // The height field's faces point to +z; reverse the corners so they face the wall.
        let triangles: Vec<[u32; 3]> = triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
        Ok(SurfaceMesh::from_triangles(&positions, &triangles)?)
    }

    /// Renders the noise-free transient (box kernel, as a measurement) and a Poisson photon-count capture.
    ///
    /// # Errors
    /// [`OptimError::Transient`] for an unusable scan or time axis (zero grid, bins or bin width),
    /// [`OptimError::Render`] for a mesh the renderer refuses.
    pub fn capture(&self, mesh: &SurfaceMesh) -> Result<(Transient, Transient)> {
        let scan = Scan::confocal(PointSet::wall_grid(self.grid, self.grid, 0.25, 0.25).map_err(setup)?);
        let time = TimeAxis::new(0.0, self.bin_width, self.bins).map_err(setup)?;
        let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
        let (positions, triangles) = mesh.to_triangles();
        let renderer = Renderer::new(&positions, &triangles, &scan, &time, params)?;
        let brdf = Lambertian::new(1.0f32)?;
        let clean = renderer.forward_transient(&brdf)?;
        let model = SpadModel::ideal(PhotonBudget::PerMeasurement(self.photons));
        let noisy = model
            .simulate(&clean, self.seed)
            .map_err(|source| OptimError::Transient { context: "built-in scene: photon noise", source })?;
        Ok((clean, noisy))
    }
}

fn setup(source: nlos_transient::TransientError) -> OptimError {
    OptimError::Transient { context: "built-in scene: scan and time axis", source }
}

/// The files of `fixtures/builtin/`, in the order [`BuiltinScene::write_fixtures`] writes them.
pub const FIXTURE_FILES: [&str; 3] = ["truth.obj", "capture.hdf5", "start.obj"];

impl BuiltinScene {
    /// Writes the scene's fixtures into `dir`: the ground truth (`truth.obj`), the photon-count capture
    /// (`capture.hdf5`, y-tal HDF5) and the start `nlos reconstruct` makes from it with the default settings
    /// (`start.obj`, LCT). Every step is deterministic (seeded noise, bit-identical rendering), so the files
    /// are the same bytes on every machine: a test compares them with the committed ones.
    ///
    /// # Errors
    /// As [`Self::mesh`] and [`Self::capture`]; [`OptimError::Io`] or [`OptimError::Capture`] when a file
    /// cannot be written.
    pub fn write_fixtures(&self, dir: &std::path::Path) -> Result<[std::path::PathBuf; 3]> {
        let paths = FIXTURE_FILES.map(|name| dir.join(name));
        let io = |path: &std::path::Path| {
            let path = path.to_path_buf();
            move |source: std::io::Error| OptimError::Io { path, fix: OptimError::WRITE_FIX, source }
        };
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        let truth = self.mesh()?;
        nlos_mesh::io::save(&truth, &paths[0])?;
        let (_, noisy) = self.capture(&truth)?;
        nlos_transient::write(&noisy, &paths[1], nlos_transient::Format::Tal)
            .map_err(|source| OptimError::Capture { path: paths[1].clone(), source: Box::new(source) })?;
        let config = crate::pipeline::Config::default();
        let start = crate::pipeline::Prepared::new(noisy, &config)?.initial_surface(&config)?;
        nlos_mesh::io::save(&start, &paths[2])?;
        Ok(paths)
    }
}
