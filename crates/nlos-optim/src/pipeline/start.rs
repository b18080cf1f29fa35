//! The start of a prepared capture ([`Prepared::initial_surface`]): the volume of the method the settings
//! name or `auto` chooses ([`nlos_init::Method`]), on the capture every start shares ([`Prepared::full`]),
//! and its surface, extracted no deeper than [`Prepared::surface_depth`] and with steps between columns
//! allowed by the scan's spacing.

use super::*;

impl Prepared {
    /// The volume of `method` on [`Prepared::full`] (gated, rebinned, cut at an explicit max depth: the
    /// preparation every start shares), weighted for `reflectance` ([`Method::volume`]; `snr` replaces the
    /// LCT's Wiener SNR). `nlos reconstruct`, `nlos init`,
    /// `nlos eval --volume` and the Python package take their volumes here.
    ///
    /// # Errors
    /// [`OptimError::Init`] when the method fails (not a confocal grid, an empty volume).
    pub fn volume(&self, method: Method, reflectance: Model, snr: Option<f64>) -> Result<Volume> {
        Ok(method.volume(&self.full, reflectance, snr)?)
    }

    /// The phasor field's volume of [`Prepared::full`] with `params` (its gate and max depth are the
    /// preparation's: those of `params` are ignored).
    ///
    /// # Errors
    /// [`OptimError::Init`] for parameters out of range or an empty volume ([`nlos_init::pf()`]).
    pub fn pf_volume(&self, params: &PfParams) -> Result<Volume> {
        Ok(pf(&self.full, &PfParams { gate: Gate::None, max_depth: None, ..*params })?)
    }

    /// The surface extraction of `method`'s start: the settings for compact objects for LCT and the phasor
    /// field ([`SurfaceParams::object`]: Otsu's threshold alone keeps only the brightest columns, about half
    /// the bunny's silhouette from the LCT, a fifth from the one-laser phasor field), the plain extraction
    /// otherwise; no voxel beyond [`Prepared::surface_depth`].
    ///
    /// The largest depth step between neighbouring columns that still joins them grows with the scan's
    /// spacing: at least the extraction's own (5 cm), and what a surface at [`MAX_START_SLOPE`] to the wall
    /// makes between two columns. On the 64 × 64 captures over 0.5–2 m (spacing 8–31 mm) that is the fixed
    /// 5 cm up to 18 mm and 8.6 cm at 31 mm; on the published 8 × 8 Z-NLOS bunny (12.5 cm) a fixed 5 cm tore
    /// every cell of its sloping surface apart but two.
    pub fn surface_params(&self, method: Method) -> SurfaceParams {
        let base = method.surface_params();
        let spacing = wall_spacing(self.full.scan());
        let max_depth_jump = base.max_depth_jump.map(|j| j.max(MAX_START_SLOPE * spacing));
        SurfaceParams { max_depth: base.max_depth.or(self.surface_depth), max_depth_jump, ..base }
    }

    /// The initial surface: a volumetric reconstruction of [`Prepared::full`] turned into a mesh
    /// ([`Prepared::volume`], [`Prepared::surface_params`]), or the mesh file of [`InitMethod::Mesh`]; of
    /// two candidates ([`StartRim::Choose`]), the first ([`Prepared::start_candidates`]).
    ///
    /// # Errors
    /// [`OptimError::Init`] when the volume or its surface fails, [`OptimError::Mesh`] for an unreadable mesh.
    pub fn initial_surface(&self, config: &Config) -> Result<SurfaceMesh> {
        let mut candidates = self.start_candidates(config)?;
        Ok(candidates.swap_remove(0).1)
    }

    /// The starts the run may begin from, each with the rim it was given: one, or two when
    /// [`Config::init_rim`] resolves to [`StartRim::Choose`] for a volume whose extraction sets a rim
    /// apart ([`nlos_init::SurfaceParams::core_fraction`]): the receding rim first, then the measured one
    /// (every column at its own depth, each region grown relative to its own peak:
    /// [`nlos_init::GrowReference::Region`]), both from the same volume; one when the two are the same
    /// surface (a volume without a dim rim). A method whose extraction sets no rim apart (f-k, FBP,
    /// carving) and a mesh file are one start each, as they are ([`StartRim::Measured`]).
    ///
    /// # Errors
    /// As [`Prepared::initial_surface`].
    pub fn start_candidates(&self, config: &Config) -> Result<Vec<(StartRim, SurfaceMesh)>> {
        let method = match &config.init {
            InitMethod::Auto => Method::for_scan(self.full.scan()).0,
            InitMethod::Volume(method) => *method,
            InitMethod::Mesh(file) => return Ok(vec![(StartRim::Measured, nlos_mesh::io::load(file)?)]),
        };
        let volume = self.volume(method, config.reflectance.model, None)?;
        let receding = self.surface_params(method);
        // The volume as measured, without the convex object's priors: no core, so every column stays at its
        // own depth, and each part grown down its own flanks (a ball beside a brighter dish kept a third of
        // its pixels when grown relative to the dish's peak).
        let measured = SurfaceParams { core_fraction: None, grow_reference: GrowReference::Region, ..receding };
        let rims = match (config.init_rim.resolve(method, self.full.scan()), receding.core_fraction) {
            // The method's own extraction: it has no rim to place.
            (_, None) => vec![(StartRim::Measured, receding)],
            (StartRim::Measured, _) => vec![(StartRim::Measured, measured)],
            (StartRim::Choose, Some(_)) => vec![(StartRim::Receding, receding), (StartRim::Measured, measured)],
            _ => vec![(StartRim::Receding, receding)],
        };
        let mut starts: Vec<(StartRim, SurfaceMesh)> = rims
            .into_iter()
            .map(|(rim, params)| Ok((rim, volume_to_surface(&volume, &params)?.mesh)))
            .collect::<Result<_>>()?;
        // A volume whose every kept column is core gives the same surface twice: one run is enough.
        if starts.len() == 2 && starts[0].1.to_triangles() == starts[1].1.to_triangles() {
            starts.truncate(1);
        }
        Ok(starts)
    }
}

/// The steepest slope (depth per lateral metre, 70°) of the start's surface between two neighbouring
/// columns ([`Prepared::surface_params`]).
pub const MAX_START_SLOPE: f64 = 2.75;

/// The spacing of the wall points that resolve the scene laterally (metres): the spacing of the denser of
/// the laser and sensor sets (the scan points of a confocal scan, the sensor grid of a one-laser capture, the
/// pairs of a paired scan; [`nlos_transient::PointSet::spacing`], a list's from its bounding box), 0 when
/// it has none. The general-NLOS capture's 4,096 pairs over 1.5 × 1.8 m are 26 mm apart: its first edge is
/// 23 mm, not 14 mm from its bins, and its start 3,200 faces rather than 8,600.
pub(super) fn wall_spacing(scan: &nlos_transient::Scan) -> f64 {
    scan.dense_points().spacing().unwrap_or(0.0)
}
