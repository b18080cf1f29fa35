//! The `nonconfocal` scenario: captures that are not confocal scans, reconstructed by the default command
//! (no `--init`: `auto` takes the phasor field).
//!
//! - the shared bunny seen by one laser at the wall's centre and a 64 × 64 sensor grid over Tsai et al.
//!   2019's [−0.25, 0.25]² m, 1,200 bins of 1.2 mm, 1,000 photons per measurement (≤ 10 minutes);
//! - the same bunny with 4 × 4 lasers × 32 × 32 sensors over the same wall (≤ 15 minutes);
//! - the independent renderer's one-laser capture (`reference/bunny_single_mc`), 1,000 photons drawn on it.
//!
//! Each is judged on coverage within 5 mm (≥ 80 %) and the depth error inside the silhouette (≤ 0.5 mm).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::Vec3;
use nlos_transient::{Format, PointSet, Scan, TimeAxis, Transient};

use super::{BUNNY, Metrics, Opts, REFERENCE_DIR, Ran, Runner, Section, TABLE_HEAD, check, p, reconstruct_args, s};
use super::{shared, with_photons};

/// One case of the scenario.
struct Case {
    name: &'static str,
    what: &'static str,
    time_limit_s: f64,
}

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
    let bunny = shared(BUNNY);
    let reference = shared(REFERENCE_DIR);
    let mut text = String::new();
    let mut pass = true;
    let cases = [
        Case { name: "one_laser", what: "one laser at the wall's centre, 64 × 64 sensors", time_limit_s: 600.0 },
        Case { name: "lasers_4x4", what: "4 × 4 lasers × 32 × 32 sensors", time_limit_s: 900.0 },
        Case {
            name: "single_mc",
            what: "the independent renderer's one-laser capture (bunny_single_mc: laser at (0.051, −0.051) m, \
                   64 × 64 sensors)",
            time_limit_s: 600.0,
        },
    ];
    for case in &cases {
        let (clean, gt) = match case.name {
            "one_laser" => {
                let one = PointSet::list(vec![Vec3::ZERO]);
                let setup = setup(&r.out.join("nc_one_laser_setup.hdf5"), one, wall(64)?)?;
                (r.clean_render(&bunny, "nc_one_laser", &[s("--setup"), p(&setup)])?.0, bunny.clone())
            }
            "lasers_4x4" => {
                let setup = setup(&r.out.join("nc_lasers_4x4_setup.hdf5"), wall(4)?, wall(32)?)?;
                (r.clean_render(&bunny, "nc_lasers_4x4", &[s("--setup"), p(&setup)])?.0, bunny.clone())
            }
            _ => (reference.join("bunny_single_mc.json"), reference.join("bunny_world.obj")),
        };
        let capture = r.out.join(format!("nc_{}_{}ph.hdf5", case.name, opts.photons));
        with_photons(&clean, opts.photons, opts.photon_seed, &capture)?;
        let run_dir = r.out.join(format!("nc_{}", case.name));
        let (init, result, ran) = run_case(r, opts, &capture, &gt, &run_dir)?;
        let _ = writeln!(
            text,
            "\n#### {}\n\n{TABLE_HEAD}\n{}\n{}\n\nreconstruction: {:.0} s wall, {:.0} s CPU (children); run directory \
             `{}`\n",
            case.what,
            init.row("phasor-field start"),
            result.row("result"),
            ran.wall_s,
            ran.cpu_s,
            run_dir.display()
        );
        check(
            &mut text,
            &mut pass,
            &format!("coverage within 5 mm {:.1} % ≥ 80 %", result.coverage_within * 100.0),
            result.coverage_within >= 0.8,
        );
        check(
            &mut text,
            &mut pass,
            &format!("depth error inside the silhouette {:.2} mm ≤ 0.5 mm", result.depth_interior * 1e3),
            result.depth_interior <= 0.5e-3,
        );
        if !opts.quick {
            check(
                &mut text,
                &mut pass,
                &format!("reconstruction {:.0} s ≤ {:.0} s", ran.wall_s, case.time_limit_s),
                ran.wall_s <= case.time_limit_s,
            );
        }
    }
    let _ = writeln!(
        text,
        "- captures: {} photons per measurement (Poisson, seed {}) drawn on `nlos render`'s exact transients of \
         the shared bunny and on the independent render",
        opts.photons, opts.photon_seed
    );
    Ok(Section { text, pass })
}
