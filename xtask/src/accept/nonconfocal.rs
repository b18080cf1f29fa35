//! The `nonconfocal` scenario: captures that are not confocal scans, reconstructed by the default command
//! (no `--init`: `auto` takes the phasor field), on shapes that do not flatter a start which keeps only the
//! middle of an object.
//!
//! - four objects seen by one laser and a 64 × 64 sensor grid over Tsai et al. 2019's [−0.25, 0.25]² m,
//!   1,200 bins of 1.2 mm, 1,000 photons per measurement: the shared bunny and soap and two of the project's
//!   own ([`super::own_shapes`]: a figure with thin limbs; a concave dish and a ball apart from it), each with
//!   the laser at the wall's centre and at a corner-ward spot, (−0.1, 0.15) m. Judged on the start's
//!   coverage (≥ 85 %), the result's coverage within 5 mm (≥ 75 %) and depth error inside (≤ 1.0 mm);
//! - the bunny with 4 × 4 lasers × 32 × 32 sensors over the same wall (≥ 85 %, ≤ 0.6 mm);
//! - the independent renderer's one-laser capture (`reference/bunny_single_mc`), 1,000 photons drawn on it
//!   (≥ 78 %, ≤ 1.0 mm).
//!
//! Every run must take at most 10 minutes on 2 cores.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient};

use super::{
    BUNNY, Metrics, Opts, REFERENCE_DIR, Ran, Runner, SOAP, Section, TABLE_HEAD, check, own_shapes, p,
    reconstruct_args, s, shared, with_photons,
};

/// What a case reconstructs.
#[derive(Clone, Copy)]
enum Object {
    Bunny,
    Soap,
    Figure,
    DishAndBall,
}

impl Object {
    fn name(self) -> &'static str {
        match self {
            Object::Bunny => "bunny",
            Object::Soap => "soap",
            Object::Figure => "figure",
            Object::DishAndBall => "dish_and_ball",
        }
    }

    fn what(self) -> &'static str {
        match self {
            Object::Bunny => "the shared bunny",
            Object::Soap => "the shared soap",
            Object::Figure => "a figure with thin limbs (own)",
            Object::DishAndBall => "a concave dish and a ball apart from it (own)",
        }
    }

    /// The object's mesh: the shared file, or the own shape written into `out`.
    fn mesh(self, out: &Path) -> Result<PathBuf, String> {
        match self {
            Object::Bunny => Ok(shared(BUNNY)),
            Object::Soap => Ok(shared(SOAP)),
            Object::Figure => own_shapes::write(&own_shapes::figure(), &out.join("nc_figure.obj")),
            Object::DishAndBall => own_shapes::write(&own_shapes::dish_and_ball(), &out.join("nc_dish_and_ball.obj")),
        }
    }
}

/// How a case is lit and seen.
#[derive(Clone, Copy)]
enum Setup {
    /// One laser at (x, y) on the wall, 64 × 64 sensors.
    OneLaser { spot: &'static str, x: f32, y: f32 },
    /// 4 × 4 lasers × 32 × 32 sensors.
    Lasers4x4,
    /// The independent renderer's capture `bunny_single_mc`.
    Reference,
}

/// The laser at the wall's centre, and the corner-ward spot the issue names.
const CENTRE: Setup = Setup::OneLaser { spot: "centre", x: 0.0, y: 0.0 };
const CORNER: Setup = Setup::OneLaser { spot: "corner", x: -0.1, y: 0.15 };

/// One case of the scenario and its targets.
struct Case {
    object: Object,
    setup: Setup,
    /// Least coverage of the truth by the start (any hit), when judged.
    start_coverage: Option<f64>,
    coverage_within: f64,
    depth_inside_m: f64,
}

impl Case {
    fn name(&self) -> String {
        match self.setup {
            Setup::OneLaser { spot, .. } => format!("{}_{spot}", self.object.name()),
            Setup::Lasers4x4 => "lasers_4x4".into(),
            Setup::Reference => "single_mc".into(),
        }
    }

    fn what(&self) -> String {
        match self.setup {
            Setup::OneLaser { x, y, .. } => {
                format!("{}, one laser at ({x}, {y}) m, 64 × 64 sensors", self.object.what())
            }
            Setup::Lasers4x4 => format!("{}, 4 × 4 lasers × 32 × 32 sensors", self.object.what()),
            Setup::Reference => "the independent renderer's one-laser capture (bunny_single_mc: laser at \
                                 (0.051, −0.051) m, 64 × 64 sensors)"
                .into(),
        }
    }
}

/// The scenario's cases in the order they run.
fn cases() -> Vec<Case> {
    let one_laser = |object, setup| Case {
        object,
        setup,
        start_coverage: Some(0.85),
        coverage_within: 0.75,
        depth_inside_m: 1.0e-3,
    };
    let mut cases: Vec<Case> = [Object::Bunny, Object::Soap, Object::Figure, Object::DishAndBall]
        .into_iter()
        .flat_map(|o| [one_laser(o, CENTRE), one_laser(o, CORNER)])
        .collect();
    cases.push(Case {
        object: Object::Bunny,
        setup: Setup::Lasers4x4,
        start_coverage: None,
        coverage_within: 0.85,
        depth_inside_m: 0.6e-3,
    });
    cases.push(Case {
        object: Object::Bunny,
        setup: Setup::Reference,
        start_coverage: None,
        coverage_within: 0.78,
        depth_inside_m: 1.0e-3,
    });
    cases
}

/// The longest a run may take (seconds of wall time on 2 cores).
const TIME_LIMIT_S: f64 = 600.0;

/// The setup of `lasers` × `sensors` over Tsai et al. 2019's wall and time axis, written as a y-tal file of
/// zeros for `nlos render --setup`.
fn setup(out: &Path, lasers: PointSet, sensors: PointSet) -> Result<PathBuf, String> {
    let axis = TimeAxis::new(0.0, 0.0012, 1200).map_err(|e| e.to_string())?;
    let t = Transient::zeros(Scan::exhaustive(lasers, sensors), axis).map_err(|e| e.to_string())?;
    nlos_transient::write(&t, out, Format::Tal).map_err(|e| e.to_string())?;
    Ok(out.to_path_buf())
}

/// The default command on `capture`, then `nlos eval` of its start and result against `gt`.
fn run_case(
    r: &mut Runner,
    opts: &Opts,
    capture: &Path,
    gt: &Path,
    run_dir: &Path,
) -> Result<(Metrics, Metrics, Ran), String> {
    let _ = std::fs::remove_dir_all(run_dir);
    let mut a = vec![s("reconstruct"), p(capture), s("--out"), p(run_dir), s("--seed"), s("1"), s("--quiet")];
    a.extend([s("--gt"), p(gt)]);
    a.extend(reconstruct_args(opts));
    let ran = r.nlos(&a)?;
    let init = r.eval(&run_dir.join("init.obj"), gt)?;
    let result = r.eval(&run_dir.join("mesh.obj"), gt)?;
    Ok((init, result, ran))
}

pub(super) fn nonconfocal(r: &mut Runner, opts: &Opts) -> Result<Section, String> {
    let wall = |n| PointSet::wall_grid(n, n, 0.25, 0.25).map_err(|e| e.to_string());
    let reference = shared(REFERENCE_DIR);
    let mut text = String::new();
    let mut pass = true;
    let mut summary =
        String::from("\n| case | start covers | within 5 mm | depth inside (mm) | run (s) |\n|---|---|---|---|---|\n");
    for case in cases() {
        let name = case.name();
        let (clean, gt) = match case.setup {
            Setup::OneLaser { x, y, .. } => {
                let setup = setup(
                    &r.out.join(format!("nc_{name}_setup.hdf5")),
                    PointSet::list(vec![Vec3::new(x, y, 0.0)]),
                    wall(64)?,
                )?;
                let mesh = case.object.mesh(&r.out)?;
                (r.clean_render(&mesh, &format!("nc_{name}"), &[s("--setup"), p(&setup)])?.0, mesh)
            }
            Setup::Lasers4x4 => {
                let setup = setup(&r.out.join("nc_lasers_4x4_setup.hdf5"), wall(4)?, wall(32)?)?;
                let mesh = case.object.mesh(&r.out)?;
                (r.clean_render(&mesh, "nc_lasers_4x4", &[s("--setup"), p(&setup)])?.0, mesh)
            }
            Setup::Reference => (reference.join("bunny_single_mc.json"), reference.join("bunny_world.obj")),
        };
        let capture = r.out.join(format!("nc_{name}_{}ph.hdf5", opts.photons));
        with_photons(&clean, opts.photons, opts.photon_seed, &capture)?;
        let run_dir = r.out.join(format!("nc_{name}"));
        let (init, result, ran) = run_case(r, opts, &capture, &gt, &run_dir)?;
        let _ = writeln!(
            text,
            "\n#### {}\n\n{TABLE_HEAD}\n{}\n{}\n\nreconstruction: {:.0} s wall, {:.0} s CPU (children); run directory \
             `{}`\n",
            case.what(),
            init.row("phasor-field start"),
            result.row("result"),
            ran.wall_s,
            ran.cpu_s,
            run_dir.display()
        );
        let _ = writeln!(
            summary,
            "| {name} | {:.1} % | {:.1} % | {:.2} | {:.0} |",
            init.coverage * 100.0,
            result.coverage_within * 100.0,
            result.depth_interior * 1e3,
            ran.wall_s
        );
        if let Some(least) = case.start_coverage {
            check(
                &mut text,
                &mut pass,
                &format!("the start covers {:.1} % of the truth ≥ {:.0} %", init.coverage * 100.0, least * 100.0),
                init.coverage >= least,
            );
        }
        check(
            &mut text,
            &mut pass,
            &format!(
                "coverage within 5 mm {:.1} % ≥ {:.0} %",
                result.coverage_within * 100.0,
                case.coverage_within * 100.0
            ),
            result.coverage_within >= case.coverage_within,
        );
        check(
            &mut text,
            &mut pass,
            &format!(
                "depth error inside the silhouette {:.2} mm ≤ {:.1} mm",
                result.depth_interior * 1e3,
                case.depth_inside_m * 1e3
            ),
            result.depth_interior <= case.depth_inside_m,
        );
        if !opts.quick {
            check(
                &mut text,
                &mut pass,
                &format!("reconstruction {:.0} s ≤ {TIME_LIMIT_S:.0} s", ran.wall_s),
                ran.wall_s <= TIME_LIMIT_S,
            );
        }
    }
    let _ = writeln!(
        text,
        "{summary}\n- captures: {} photons per measurement (Poisson, seed {}) drawn on `nlos render`'s exact \
         transients and on the independent render",
        opts.photons, opts.photon_seed
    );
    Ok(Section { text, pass })
}
