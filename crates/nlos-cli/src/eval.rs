//! `nlos eval`: metrics of a reconstructed mesh against the ground truth: the few that say whether it worked
//! as a table ([`crate::table`]), or all of them as one JSON line with `--json`.
//!
//! Loads both meshes with [`nlos_mesh::metrics::load_for_eval`] ([`nlos_mesh::io`] readers; non-manifold
//! triangle lists are accepted unwelded) and scores them with [`nlos_mesh::metrics::evaluate`] (coverage and
//! depth error from a +z ray grid over the wall, Chamfer and Hausdorff distances, normal angular error over
//! all vertices and over those within 1 cm of the truth, [`nlos_mesh::distance::NormalError::split`]); with
//! `--map`, also the coverage picture of `nlos_report::figures::coverage_figure`.
//!
//! A run directory of `nlos reconstruct` in place of the mesh scores its start and its result side by side
//! (with `--json`, one line each, start first); a mesh inside a run directory is named by its role there.
//!
//! With `--gt-depth DEPTH [--gt-normal NORMAL]` instead of `--gt`, the reconstruction is scored against
//! ground-truth maps on a wall grid ([`nlos_mesh::map_metrics`]: the protocol of the methods that compare on
//! the Z-NLOS scenes). `--volume CAPTURE --method lct|fk` scores a volumetric reconstruction of the capture
//! (its surface: the arg-max depth of the kept columns) by the same code.
//!
//! With `--front-view CAPTURE` instead, no truth is needed: the mesh's lateral detail is scored against the
//! capture's volume ([`nlos_init::front_view`]: r and coverage against the volume's front view — LCT on a
//! confocal grid, the phasor field on any other scan, as `nlos init --volume` makes them). The volume is made
//! as the run made its start: with the run's own settings (its reflectance, its capture settings) when the mesh
//! lies in a run directory, and the command says so; `--brdf` overrides the reflectance.

use nlos_init::Method;
use nlos_optim::pipeline::{Config, Prepared};
use std::path::{Path, PathBuf};

use nlos_mesh::map_metrics::{MapGrid, MapLayout, MapMetrics, Maps, evaluate_maps, mesh_maps};
use nlos_mesh::metrics::{EvalParams, MAX_GRID, evaluate, load_for_eval};
use nlos_mesh::{MeshError, SurfaceMesh};

use crate::CliError;
use crate::progress::Step;
use crate::table::Table;
use nlos_optim::pipeline::{INIT_FILE, SETTINGS_FILE};
use nlos_report::MESH_FILE;

/// How the ground-truth map files lay out their pixels ([`MapLayout`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum GtLayout {
    /// Ours: seen from the wall as an image, row 0 at the top (largest y), column 0 at the smallest x;
    /// normals in our frame facing the wall.
    Image,
    /// The Z-NLOS ground truth as the directional LCT published it (`*_depth.mat`, `*_normal.mat`): the depth
    /// map transposed, the normal map mirrored with its vectors away from the wall.
    Dlct,
}

impl From<GtLayout> for MapLayout {
    fn from(l: GtLayout) -> Self {
        match l {
            GtLayout::Image => MapLayout::Image,
            GtLayout::Dlct => MapLayout::Dlct,
        }
    }
}

/// Arguments of `nlos eval`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The reconstructed mesh (OBJ, PLY or GLB, detected from its content), or a run directory of `nlos
    /// reconstruct`: its start and its result, side by side.
    #[arg(required_unless_present = "volume")]
    mesh: Option<PathBuf>,
    /// Print every metric as one JSON line per mesh (start first for a run directory) instead of the table.
    #[arg(long)]
    json: bool,
    /// The ground-truth mesh (OBJ, PLY or GLB).
    #[arg(
        long,
        value_name = "GT",
        required_unless_present_any = ["gt_depth", "front_view"],
        conflicts_with_all = ["gt_depth", "front_view"]
    )]
    gt: Option<PathBuf>,
    /// Score the mesh's lateral detail against this capture's volume instead of a truth: Pearson's r of the
    /// volume's front view and the mesh's (+z rays from the scan grid; a hit counts 1) over the object's
    /// region, and the share of the volume's bright pixels the mesh covers (`nlos_init::front_view`).
    #[arg(long, value_name = "CAPTURE", conflicts_with_all = ["gt_depth", "volume"])]
    front_view: Option<PathBuf>,
    /// The reflectance the volume of --front-view is weighted for (the same choice as the reconstruction's
    /// --brdf) [default: the run's, for a mesh in a run directory; else lambert].
    #[arg(long, value_parser = crate::choices::brdf_parser(), requires = "front_view")]
    brdf: Option<nlos_init::Model>,
    /// Ground-truth depth map (.npy, .mat or one-channel .exr, metres along +z from the wall; 0, NaN or Inf: no
    /// surface) on the wall grid of --extent (or of --wall), laid out as --gt-layout says.
    #[arg(long, value_name = "DEPTH")]
    gt_depth: Option<PathBuf>,
    /// Ground-truth normal map (.npy, .mat or R, G, B .exr, × 3: unit x, y, z; NaN: no normal) on the depth
    /// map's grid; scored where both maps and the reconstruction have a value (`normal_pixels`).
    #[arg(long, value_name = "NORMAL", requires = "gt_depth")]
    gt_normal: Option<PathBuf>,
    /// How the map files lay out their pixels: `image` (row 0 at the top, largest y; column 0 at the smallest
    /// x; normals facing the wall) or `dlct` (the Z-NLOS maps as published).
    #[arg(long, value_enum, default_value = "image", requires = "gt_depth")]
    gt_layout: GtLayout,
    /// The maps' wall rectangle `x0,x1,y0,y1` in metres (pixel edges) [default: -0.25,0.25,-0.25,0.25].
    #[arg(long, value_name = "X0,X1,Y0,Y1", allow_hyphen_values = true, value_parser = parse_extent)]
    extent: Option<[f32; 4]>,
    /// Place the maps on this capture's wall grid instead of --extent: their first and last pixel centres on
    /// the outermost points of its full scan grid (a Z-NLOS `.mat`'s `cameraGridSize`, so a subsampled file
    /// places the full-size maps). --volume implies it.
    #[arg(long, value_name = "CAPTURE", conflicts_with = "extent", requires = "gt_depth")]
    wall: Option<PathBuf>,
    /// Depth tolerance of "coverage within" (metres).
    #[arg(long, default_value_t = 0.005, value_name = "METRES")]
    threshold: f64,
    /// Score a volumetric reconstruction of this capture instead of a mesh.
    #[arg(long, value_name = "CAPTURE", conflicts_with = "mesh")]
    volume: Option<PathBuf>,
    /// The volumetric method of --volume.
    #[arg(long, value_parser = crate::choices::method_parser(), default_value = "lct")]
    method: Method,
    /// Rays per side of the grid over the wall's scan area [−0.25, 0.25]² m (1 to 4096), with --gt.
    #[arg(long, default_value_t = 128, value_name = "N")]
    grid: usize,
    /// Also draw the coverage picture as this PNG (with --gt, or with --gt-depth on its map's grid): the
    /// pixels coloured by hit within 5 mm, hit but further apart, missed and extra (as the run report's
    /// `coverage.png`).
    #[arg(long, value_name = "PNG")]
    map: Option<PathBuf>,
}

fn parse_extent(s: &str) -> Result<[f32; 4], String> {
    let v: Vec<f32> = s.split(',').filter_map(|t| t.trim().parse().ok()).collect();
    match v.as_slice() {
        &[x0, x1, y0, y1] if v.iter().all(|x| x.is_finite()) && x0 < x1 && y0 < y1 => Ok([x0, x1, y0, y1]),
        _ => Err(format!("`{s}` is not x0,x1,y0,y1 in metres with x0 < x1 and y0 < y1")),
    }
}

/// Reads a mesh; errors name the file.
fn load(path: &Path) -> Result<SurfaceMesh, CliError> {
    load_for_eval(path).map_err(|e| match e {
        // these already name the file
        MeshError::Io { .. } | MeshError::Format { .. } => CliError::Input(e.to_string()),
        other => CliError::Input(format!("{}: {other}", path.display())),
    })
}

/// The file of a run directory that holds its result with the fields (`albedo`) the front view counts.
const RESULT_PLY: &str = "mesh.ply";

/// The run directory `mesh` lies in: its folder, when that holds a run's settings ([`SETTINGS_FILE`]).
fn run_dir_of(mesh: &Path) -> Option<&Path> {
    let dir = mesh.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    dir.join(SETTINGS_FILE).is_file().then_some(dir)
}

/// The meshes the argument names, each with the name of its column: a run directory's start and result
/// (the result's PLY where there is one), or one mesh, named by its role where it lies in a run directory.
///
/// # Errors
/// [`CliError::Input`] for a folder that holds no run.
fn columns(path: &Path) -> Result<Vec<(String, PathBuf)>, CliError> {
    if path.is_dir() {
        if !path.join(SETTINGS_FILE).is_file() {
            return Err(CliError::Input(format!(
                "{}: a folder, but not a run directory of `nlos reconstruct` (it has no {SETTINGS_FILE}); name a \
                 mesh file or a run directory",
                path.display()
            )));
        }
        let ply = path.join(RESULT_PLY);
        let result = if ply.is_file() { ply } else { path.join(MESH_FILE) };
        return Ok(vec![("start".into(), path.join(INIT_FILE)), ("result".into(), result)]);
    }
    let file = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let name = match (run_dir_of(path).is_some(), file.as_str()) {
        (true, INIT_FILE) => "start".into(),
        (true, MESH_FILE | RESULT_PLY) => "result".into(),
        _ if file.is_empty() => "reconstruction".into(),
        _ => file,
    };
    Ok(vec![(name, path.to_owned())])
}

/// The reconstructions to score, with their column names and files: the meshes of [`columns`], or the
/// surface of the volume of `--volume`.
fn reconstructions(args: &Args) -> Result<Vec<(String, PathBuf, SurfaceMesh)>, CliError> {
    if let Some(capture) = &args.volume {
        let name = format!("{} volume", args.method.name());
        return Ok(vec![(name, capture.clone(), volume_surface(capture, args.method)?)]);
    }
    let step = Step::spinner("eval: reading the reconstruction");
    let list = columns(args.mesh.as_deref().unwrap_or(Path::new("")))?
        .into_iter()
        .map(|(name, path)| load(&path).map(|mesh| (name, path, mesh)))
        .collect::<Result<Vec<_>, _>>()?;
    step.finish();
    Ok(list)
}

/// The surface of a capture's volumetric reconstruction: the arg-max depth of the columns kept by the
/// settings for compact objects (`SurfaceParams::object`, as `nlos reconstruct`'s LCT start), for LCT and
/// f-k alike, so that both are scored by the same extraction. (With Otsu's threshold alone f-k keeps 6 % of
/// the bunny at Tsai et al. 2019's setup's pixels, the compact-object settings 25 %.)
pub(crate) fn volume_surface(capture: &Path, method: Method) -> Result<SurfaceMesh, CliError> {
    let t = nlos_transient::read(capture).map_err(CliError::input)?;
    let fail = |e: String| CliError::Input(format!("{}: {e}", capture.display()));
    // Prepared as `nlos reconstruct` prepares a capture (gate, last return, the depth the start may reach).
    let prepared = Prepared::new(t, &Config::default()).map_err(|e| fail(e.to_string()))?;
    let volume = prepared.volume(method, nlos_init::Model::Lambert, None).map_err(|e| fail(e.to_string()))?;
    // The LCT start's extraction (compact-object settings, max depth, the step allowed by the spacing).
    let surface = prepared.surface_params(Method::Lct);
    Ok(nlos_init::volume_to_surface(&volume, &surface).map_err(|e| fail(e.to_string()))?.mesh)
}

/// What the volume of `--front-view` is made with for the mesh `mesh`: the run's settings where it lies in a
/// run directory, else the defaults; the reflectance it is weighted for (`--brdf` over the run's), and a note
/// of where that came from.
///
/// # Errors
/// [`CliError::Input`] for a run's settings file that cannot be read.
fn front_view_settings(
    mesh: &Path,
    brdf: Option<nlos_init::Model>,
) -> Result<(Config, nlos_init::Model, String), CliError> {
    let run = run_dir_of(mesh);
    let config = match run {
        Some(dir) => nlos_optim::pipeline::saved_config(dir)
            .map_err(|e| CliError::Input(format!("{}: {e}", dir.join(SETTINGS_FILE).display())))?
            .unwrap_or_default(),
        None => Config::default(),
    };
    Ok(match (brdf, run) {
        (Some(m), _) => (config, m, format!("weighted for {m}, from --brdf")),
        (None, Some(dir)) => {
            let m = config.reflectance.model;
            let note = format!("weighted for {m}, the run's reflectance in {}", dir.join(SETTINGS_FILE).display());
            (config, m, note)
        }
        (None, None) => (config, nlos_init::Model::Lambert, "weighted for lambert: no run directory, no --brdf".into()),
    })
}

/// The volume of `capture` the front view is scored against: the one `Method::for_scan` picks, from the capture
/// prepared as `nlos reconstruct` prepares it with `config`, weighted for `brdf`.
fn front_view_volume(capture: &Path, config: &Config, brdf: nlos_init::Model) -> Result<nlos_init::Volume, CliError> {
    let step = Step::spinner(format!("eval: the volume of {}", capture.display()));
    let t = nlos_transient::read(capture).map_err(CliError::input)?;
    let fail = |e: String| CliError::Input(format!("{}: {e}", capture.display()));
    let (method, _) = Method::for_scan(t.scan());
    let prepared = Prepared::new(t, config).map_err(|e| fail(e.to_string()))?;
    let volume = prepared.volume(method, brdf, None).map_err(|e| fail(e.to_string()))?;
    step.finish();
    Ok(volume)
}

/// The front-view detail of the mesh file `mesh` against `volume` (of `capture`; [`nlos_init::front_view`]).
/// A hit counts the albedo of the nearest corner where the file has one (PLY's `albedo`), else 1.
fn front_view(mesh: &Path, volume: &nlos_init::Volume, capture: &Path) -> Result<nlos_init::FrontViewDetail, CliError> {
    let bytes = std::fs::read(mesh).map_err(|e| CliError::Input(format!("{}: {e}", mesh.display())))?;
    let soup =
        nlos_mesh::io::read_any(&bytes, &mesh.display().to_string()).map_err(|e| CliError::Input(e.to_string()))?;
    nlos_init::front_view_detail(volume, &soup.positions, &soup.triangles, soup.albedo.as_deref()).map_err(|e| {
        CliError::Input(format!("the front view of {} against {}: {e}", mesh.display(), capture.display()))
    })
}

/// A map file as (values in C order, shape): `.npy`, `.mat` (its only numeric variable) or `.exr` (one
/// channel, or R, G, B).
pub(crate) fn read_map(path: &Path) -> Result<(Vec<f32>, Vec<usize>), CliError> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let read = match ext.as_str() {
        "mat" => nlos_transient::formats::mat::read_array(path, None).map(|(v, dims, _)| (v, dims)),
        "exr" => nlos_transient::formats::exr::read_image(path),
        _ => nlos_transient::formats::npy::read_npy_map(path),
    };
    read.map_err(CliError::input)
}

/// Where the maps lie on the wall.
#[derive(Debug, Clone)]
pub(crate) enum MapPlace {
    /// The rectangle `x0, x1, y0, y1` of the pixels' outer edges.
    Extent([f32; 4]),
    /// The wall grid of a capture ([`capture_wall`]).
    Wall(PathBuf),
}

/// The rectangle of `capture`'s full scan grid, from one outermost point to the other (a Z-NLOS `.mat`'s
/// `cameraGridSize`, else the points' own bounds): where a map of that grid has its outer pixel centres
/// ([`MapGrid::spanning`]).
pub(crate) fn capture_wall(capture: &Path) -> Result<[f32; 4], CliError> {
    let wall = match nlos_transient::detect(capture).map_err(CliError::input)? {
        nlos_transient::Format::ZNlosMat => {
            nlos_transient::formats::mat::znlos_wall(capture).map_err(CliError::input)?
        }
        _ => None,
    };
    Ok(match wall {
        Some(r) => r,
        None => {
            let t = nlos_transient::read(capture).map_err(CliError::input)?;
            let (lo, hi) = t.scan().sensors().bounds().unwrap_or_default();
            [lo.x, hi.x, lo.y, hi.y]
        }
    })
}

/// The ground-truth maps of `depth_file` (and `normal_file`), laid out as `layout`, placed on the wall by
/// `place`.
pub(crate) fn truth_maps(
    depth_file: &Path,
    normal_file: Option<&Path>,
    layout: MapLayout,
    place: &MapPlace,
) -> Result<Maps, CliError> {
    let bad = |file: &Path, what: String| CliError::Input(format!("{}: {what}", file.display()));
    let (depth, shape) = read_map(depth_file)?;
    let &[rows, cols] = shape.as_slice() else {
        return Err(bad(depth_file, format!("a depth map is rows × columns, found shape {shape:?}")));
    };
    let (depth, width, height) = layout.depth_to_image(&depth, [rows, cols]);
    let grid = match place {
        MapPlace::Extent([x0, x1, y0, y1]) => MapGrid { width, height, x_range: [*x0, *x1], y_range: [*y0, *y1] },
        MapPlace::Wall(capture) => MapGrid::spanning(width, height, capture_wall(capture)?),
    };
    // 0, negative, NaN and Inf (the readers' NaN) are "no surface".
    let depth: Vec<f32> = depth.into_iter().map(|z| if z > 0.0 { z } else { f32::NAN }).collect();
    let normals = match normal_file {
        None => None,
        Some(file) => {
            let (n, nshape) = read_map(file)?;
            let &[nr, nc, 3] = nshape.as_slice() else {
                return Err(bad(
                    file,
                    format!("a normal map is rows × columns × 3 (the last axis holds x, y, z), found shape {nshape:?}"),
                ));
            };
            let (normals, nw, nh) = layout.normals_to_image(&n, [nr, nc]);
            if (nw, nh) != (width, height) {
                return Err(bad(
                    file,
                    format!(
                        "the normal map is {nr} × {nc} × 3; the depth map {} needs {height} × {width} × 3 (in either \
                         layout the normal map is stored as rows of our image)",
                        depth_file.display(),
                    ),
                ));
            }
            Some(normals)
        }
    };
    let maps = Maps { grid, depth, normals };
    let name = normal_file.map_or_else(|| depth_file.display().to_string(), |n| n.display().to_string());
    maps.validate(&name).map_err(|e| CliError::Input(e.to_string()))?;
    Ok(maps)
}

/// Scores `reconstruction` (named `what` in errors) against the maps `truth`.
pub(crate) fn score_maps(
    reconstruction: &SurfaceMesh,
    what: &str,
    truth: &Maps,
    threshold: f64,
) -> Result<MapMetrics, CliError> {
    score_rendered(&reconstruction_maps(reconstruction, what, truth)?, truth, threshold)
}

/// The reconstruction's depth and normal maps (`nlos_mesh::map_metrics::mesh_maps`: a +z ray per pixel) on the
/// grid of `truth`.
fn reconstruction_maps(reconstruction: &SurfaceMesh, what: &str, truth: &Maps) -> Result<Maps, CliError> {
    mesh_maps(reconstruction, &truth.grid).map_err(|e| CliError::Input(format!("{what}: {e}")))
}

/// Scores the reconstruction's maps `rec` against the maps `truth`.
fn score_rendered(rec: &Maps, truth: &Maps, threshold: f64) -> Result<MapMetrics, CliError> {
    evaluate_maps(rec, truth, threshold).map_err(|e| CliError::Input(e.to_string()))
}

/// The coverage picture of the reconstructions' maps `recs` (name, maps) against depth maps
/// (`--gt-depth … --map`), on the maps' grid: one panel per reconstruction.
fn map_coverage_figure(recs: &[(String, Maps)], truth: (&Maps, &Path), png: &Path) -> Result<(), CliError> {
    let (truth, depth_file) = truth;
    let grid = &truth.grid;
    if grid.width != grid.height {
        return Err(CliError::Input(format!(
            "--map: the coverage picture needs a square depth map; {} is {} x {}",
            depth_file.display(),
            grid.width,
            grid.height
        )));
    }
    // The maps' row 0 is the top (largest y); the picture's is the bottom.
    let bottom_up = |d: &[f32]| -> Vec<f32> { d.chunks(grid.width).rev().flatten().copied().collect() };
    let view = nlos_report::figures::DepthView { grid: grid.width, x_range: grid.x_range, y_range: grid.y_range };
    let depths: Vec<Vec<f32>> = recs.iter().map(|(_, m)| bottom_up(&m.depth)).collect();
    let panels: Vec<(&str, &[f32])> = recs.iter().zip(&depths).map(|((n, _), d)| (n.as_str(), d.as_slice())).collect();
    let fig = nlos_report::figures::coverage_figure(&panels, &bottom_up(&truth.depth), &view)
        .map_err(|e| CliError::Failure(format!("drawing the coverage picture: {e}")))?;
    fig.save_png(png).map_err(|e| CliError::Failure(format!("cannot write {}: {e}", png.display())))
}

/// Prints `metrics` as one JSON line each, or as the table `table` makes of them.
fn print<M: serde::Serialize>(args: &Args, metrics: &[M], table: impl FnOnce() -> Table) -> Result<(), CliError> {
    if args.json {
        for m in metrics {
            let line = serde_json::to_string(m).map_err(|e| CliError::Failure(format!("encoding JSON: {e}")))?;
            outln!("{line}");
        }
    } else {
        outln!("{}", table());
    }
    Ok(())
}

/// Runs `nlos eval`.
pub(crate) fn run(args: &Args) -> Result<(), CliError> {
    if let Some(png) = &args.map {
        if !png.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            return Err(CliError::Input(format!("--map {}: the picture is a PNG image; name it .png", png.display())));
        }
        crate::check_output(png, "--map")?;
    }
    if let Some(capture) = &args.front_view {
        let meshes = columns(args.mesh.as_deref().unwrap_or(Path::new("")))?;
        let (config, brdf, note) = front_view_settings(&meshes[0].1, args.brdf)?;
        eprintln!("eval: the volume {note}");
        let volume = front_view_volume(capture, &config, brdf)?;
        let detail = meshes.iter().map(|(_, m)| front_view(m, &volume, capture)).collect::<Result<Vec<_>, _>>()?;
        let names = meshes.into_iter().map(|(n, _)| n).collect();
        return print(args, &detail, || Table::front_view(names, &detail, &capture.display().to_string(), &note));
    }
    let recs = reconstructions(args)?;
    if let Some(depth_file) = &args.gt_depth {
        let place = match (&args.wall, &args.volume, args.extent) {
            (Some(capture), _, _) | (None, Some(capture), None) => MapPlace::Wall(capture.clone()),
            (None, _, extent) => MapPlace::Extent(extent.unwrap_or([-0.25, 0.25, -0.25, 0.25])),
        };
        let truth = truth_maps(depth_file, args.gt_normal.as_deref(), args.gt_layout.into(), &place)?;
        // One ray per pixel serves the scores and the picture.
        let maps = recs
            .iter()
            .map(|(name, path, mesh)| {
                Ok((name.clone(), reconstruction_maps(mesh, &path.display().to_string(), &truth)?))
            })
            .collect::<Result<Vec<_>, CliError>>()?;
        let metrics =
            maps.iter().map(|(_, m)| score_rendered(m, &truth, args.threshold)).collect::<Result<Vec<_>, _>>()?;
        if let Some(png) = &args.map {
            map_coverage_figure(&maps, (&truth, depth_file), png)?;
        }
        let names = maps.into_iter().map(|(n, _)| n).collect();
        return print(args, &metrics, || Table::maps(names, &metrics, &depth_file.display().to_string()));
    }
    let gt = args.gt.as_deref().unwrap_or(Path::new(""));
    if args.grid == 0 || args.grid > MAX_GRID {
        return Err(CliError::Input(format!("--grid {} is out of range; use 1 to {MAX_GRID}", args.grid)));
    }
    // either may be non-manifold (scanned or exported models): see `load_for_eval`
    let ground_truth = load(gt)?;
    let params = EvalParams { grid: args.grid, coverage_threshold: args.threshold, ..EvalParams::default() };
    let mut metrics = Vec::with_capacity(recs.len());
    for (_, path, mesh) in &recs {
        let step = Step::spinner(format!(
            "eval: {} faces against {} faces of the truth",
            mesh.n_faces(),
            ground_truth.n_faces()
        ));
        metrics
            .push(evaluate(mesh, &ground_truth, &params).map_err(|e| {
                CliError::Input(format!("evaluating {} against {}: {e}", path.display(), gt.display()))
            })?);
        step.finish();
    }
    if let Some(png) = &args.map {
        let view =
            nlos_report::figures::DepthView { grid: params.grid, x_range: params.x_range, y_range: params.y_range };
        let panels: Vec<(&str, &[f32])> =
            recs.iter().zip(&metrics).map(|((n, _, _), m)| (n.as_str(), m.depth_reconstruction.as_slice())).collect();
        let truth_depth = metrics.first().map_or(&[][..], |m| m.depth_ground_truth.as_slice());
        let fig = nlos_report::figures::coverage_figure(&panels, truth_depth, &view)
            .map_err(|e| CliError::Failure(format!("drawing the coverage picture: {e}")))?;
        fig.save_png(png).map_err(|e| CliError::Failure(format!("cannot write {}: {e}", png.display())))?;
    }
    let names = recs.into_iter().map(|(n, _, _)| n).collect();
    print(args, &metrics, || Table::meshes(names, &metrics, &gt.display().to_string()))
}
