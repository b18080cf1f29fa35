//! Where the light is left unexplained: the residual back-projected by the start's own volumetric method,
//! against the same back-projection of the model's own noise.
//!
//! The capture `m` and the final rendering as the fit saw it (`μ`: `s*·I`, or the sensor fit's expected
//! counts) are turned into volumes by the same method, and the residual is `V(m) − V(μ)`: where it is
//! positive the capture holds light the mesh does not make (a part missing, or too dark), where negative the
//! mesh makes light the capture lacks (a part too far out, too bright, or where there is none). On a confocal
//! grid `V` is the LCT without its clamp at zero ([`nlos_init::Method::signed_volume`]), linear in the data,
//! so the residual is the volume of `m − μ` and its noise averages out as the back-projection sums; the other
//! methods are not linear, and their residual is the difference of their volumes as they are.
//!
//! For photon counts on a confocal grid (the linear form) the residual is judged against the model's own noise: the same back-projection of a
//! Poisson draw of `μ` minus `μ` (seed fixed), which is what the residual would be were the model exact.
//! A column of the residual's front view is coloured only where it exceeds 1.5 times the largest magnitude
//! that noise reaches within two columns of it ([`Backprojected::beyond_noise`]): light a surface could
//! explain, not light a surface would only fit to the noise.
//!
//! [`residual_figure`] draws the capture's front view (maximum over depth), the residual's front view (per
//! column, the signed value of largest magnitude) beyond the noise, the noise's own front view on the same
//! scale, and the residual's x–z slice through the row that holds most of it — in units of the capture
//! volume's peak, so that 0.2 reads "a fifth as bright as the brightest thing in the capture".

use nlos_init::{Method, Model, Volume};
use nlos_transient::Transient;
use nlos_viz::{Colormap, Extent, Figure, Norm, Panel, RgbImage, ScalarGrid, Scale};

use crate::error::{ReportError, Result};

/// The capture's and the rendering's volumes by one method, and the residual's: what [`residual_figure`]
/// draws.
#[derive(Debug, Clone)]
pub struct Backprojected {
    /// The method that made the volumes.
    pub method: Method,
    /// The capture's volume (as the method makes it: the front view's panel).
    pub measured: Volume,
    /// The rendering's volume, on the same voxels.
    pub rendered: Volume,
    /// `V(m) − V(μ)` on the same voxels: the method's signed volume of the difference where it is linear,
    /// else the difference of the two volumes.
    pub difference: Vec<f32>,
    /// The same for a Poisson draw of the rendering in place of the capture (photon counts only): the
    /// residual of an exact model.
    pub noise: Option<Vec<f32>>,
    /// Whether `difference` is the method's signed, linear volume of the difference
    /// ([`nlos_init::Method::signed_volume`]).
    pub linear: bool,
}

/// The volumes of `measured` and of `rendered` (the same scan and time axis; both gated) by `method`,
/// weighted for `reflectance` as the start's volume is, and the residual's ([module docs](self)); with
/// `noise_seed` (photon counts) and a method with a linear form, also the residual of a Poisson draw of
/// `rendered` (expected counts) drawn with that seed.
///
/// # Errors
/// [`ReportError::Init`] when the method cannot take the scan or a volume is empty;
/// [`ReportError::InvalidOption`] when the volumes do not share their voxels.
pub fn backproject(
    method: Method,
    reflectance: Model,
    measured: &Transient,
    rendered: &Transient,
    noise_seed: Option<u64>,
) -> Result<Backprojected> {
    let m = method.volume(measured, reflectance, None)?;
    let r = method.volume(rendered, reflectance, None)?;
    let same = |v: &Volume, what: &'static str| {
        if (m.nx, m.ny, m.nz) == (v.nx, v.ny, v.nz) {
            Ok(())
        } else {
            Err(ReportError::InvalidOption {
                name: what,
                reason: format!("volume {}x{}x{} against the capture's {}x{}x{}", v.nx, v.ny, v.nz, m.nx, m.ny, m.nz),
            })
        }
    };
    same(&r, "rendered")?;
    // The method's signed, linear volume of `a − μ`, where it has one.
    let signed = |a: &Transient| -> Option<Result<Vec<f32>>> {
        let diff: Vec<f32> = a.data().iter().zip(rendered.data()).map(|(x, y)| x - y).collect();
        let diff = match Transient::new(a.scan().clone(), *a.time(), diff) {
            Ok(d) => d,
            Err(e) => return Some(Err(e.into())),
        };
        method.signed_volume(&diff, reflectance).map(|v| {
            let v = v?;
            same(&v, "residual")?;
            Ok(v.data)
        })
    };
    let (difference, linear) = match signed(measured) {
        Some(v) => (v?, true),
        None => (m.data.iter().zip(&r.data).map(|(x, y)| x - y).collect(), false),
    };
    // Only the linear form is judged against the noise: a method that takes a magnitude (the phasor field)
    // smooths the draw's noise into its own floor, so the draw's residual is near zero and every column would
    // pass as beyond it (on a one-laser capture of the bunny, 4,093 of 4,096 columns).
    let noise = match noise_seed {
        Some(seed) if linear => signed(&poisson_draw(rendered, seed)?).transpose()?,
        _ => None,
    };
    Ok(Backprojected { method, measured: m, rendered: r, difference, noise, linear })
}

/// A Poisson draw of expected counts `mu` (each measurement its own stream of the PCG32 generator, `seed`).
fn poisson_draw(mu: &Transient, seed: u64) -> Result<Transient> {
    let bins = mu.bins().max(1);
    let mut out = vec![0.0f32; mu.data().len()];
    for (m, (o, h)) in out.chunks_exact_mut(bins).zip(mu.data().chunks_exact(bins)).enumerate() {
        let mut rng = nlos_transient::rng::Pcg32::new(seed, m as u64);
        for (o, &l) in o.iter_mut().zip(h) {
            *o = if l > 0.0 { rng.poisson(f64::from(l)) as f32 } else { 0.0 };
        }
    }
    Ok(Transient::new(mu.scan().clone(), *mu.time(), out)?)
}

/// How far above the noise's local maximum a residual column must reach to be coloured. A new draw of the
/// same noise beats the largest of the 25 columns around it about once in 26: at a margin of 1 an exact model
/// colours 40 of 1,024 columns of a rendered plate, at 1.25 three, at 1.5 none (`tests`), where a 6 cm square
/// the model lacks is shown whole at any of these margins.
const NOISE_MARGIN: f32 = 1.5;

impl Backprojected {
    /// The capture volume's peak as a scale: `1/peak` (0 when it has none).
    fn unit(&self) -> f32 {
        let peak = self.measured.data.iter().fold(0.0f32, |a, &v| a.max(v));
        if peak > 0.0 { 1.0 / peak } else { 0.0 }
    }

    /// `V(m) − V(μ)` voxel by voxel, in units of the capture volume's peak (0 everywhere when it has none).
    pub fn residual(&self) -> Vec<f32> {
        let unit = self.unit();
        self.difference.iter().map(|d| d * unit).collect()
    }

    /// The residual of a Poisson draw of the model, in the same units (photon counts only).
    pub fn noise_residual(&self) -> Option<Vec<f32>> {
        let unit = self.unit();
        self.noise.as_ref().map(|n| n.iter().map(|d| d * unit).collect())
    }

    /// The residual's front view (per column, the signed value of largest magnitude), 0 in every column where
    /// it is within the noise: no larger than [`NOISE_MARGIN`] times the largest magnitude the noise's front
    /// view reaches within two columns. Without a noise (intensities), the front view as it is.
    pub fn beyond_noise(&self) -> Vec<f32> {
        let (nx, ny, nz) = (self.measured.nx, self.measured.ny, self.measured.nz);
        let front = signed_front_view(&self.residual(), nz);
        let Some(noise) = self.noise_residual() else { return front };
        let noise = signed_front_view(&noise, nz);
        let reach = 2usize;
        (0..nx * ny)
            .map(|c| {
                let (ix, iy) = (c % nx, c / nx);
                let mut level = 0.0f32;
                for jy in iy.saturating_sub(reach)..=(iy + reach).min(ny - 1) {
                    for jx in ix.saturating_sub(reach)..=(ix + reach).min(nx - 1) {
                        level = level.max(noise[jx + nx * jy].abs());
                    }
                }
                if front[c].abs() > NOISE_MARGIN * level { front[c] } else { 0.0 }
            })
            .collect()
    }
}

/// Per column of a volume laid out `[(ix + nx·iy)·nz + iz]`, the value of largest magnitude, with its sign.
fn signed_front_view(values: &[f32], nz: usize) -> Vec<f32> {
    values
        .chunks_exact(nz)
        .map(|c| c.iter().copied().fold(0.0f32, |a, v| if v.abs() > a.abs() { v } else { a }))
        .collect()
}

/// The three panels of the residual ([module docs](self)); `note` goes under the title (what was rendered).
///
/// # Errors
/// Drawing errors; [`ReportError::InvalidOption`] for a volume without voxels.
pub fn residual_figure(b: &Backprojected, note: &str) -> Result<RgbImage> {
    let v = &b.measured;
    if v.nx == 0 || v.ny == 0 || v.nz == 0 {
        return Err(ReportError::InvalidOption { name: "volume", reason: "no voxels".into() });
    }
    let (nx, ny, nz) = (v.nx, v.ny, v.nz);
    let residual = b.residual();
    let peak = v.data.iter().fold(0.0f32, |a, &x| a.max(x));
    let unit = if peak > 0.0 { 1.0 / peak } else { 0.0 };
    let front: Vec<f32> = v.max_projection().iter().map(|x| x * unit).collect();
    let front_residual = b.beyond_noise();
    let front_noise = b.noise_residual().map(|n| signed_front_view(&n, nz));
    // The row (fixed y) holding most of the residual's energy, as an x–z slice: z up the page.
    let energy =
        |iy: usize| -> f64 { residual[iy * nx * nz..(iy + 1) * nx * nz].iter().map(|&x| f64::from(x).powi(2)).sum() };
    let row = (0..ny).max_by(|&a, &b| energy(a).total_cmp(&energy(b))).unwrap_or(ny / 2);
    // Depths: those of the columns' peaks where a column of either volume reaches a fifth of the capture's
    // peak, 5 cm more each side.
    let mut peaks = (0..nx * ny).flat_map(|c| {
        [&v.data, &b.rendered.data].into_iter().filter_map(move |d| {
            let col = &d[c * nz..(c + 1) * nz];
            let (iz, top) = col.iter().enumerate().fold((0, 0.0f32), |a, (i, &x)| if x > a.1 { (i, x) } else { a });
            (top * unit >= 0.2).then_some(iz)
        })
    });
    let margin = (0.05 / v.z.step.abs()).ceil() as usize;
    let (z0, z1) = match peaks.next() {
        Some(first) => {
            let (lo, hi) = peaks.fold((first, first), |(lo, hi), iz| (lo.min(iz), hi.max(iz)));
            (lo.saturating_sub(margin), (hi + margin).min(nz - 1))
        }
        None => (0, nz - 1),
    };
    let depths = z1 - z0 + 1;
    let mut slice = vec![0.0f32; nx * depths];
    for ix in 0..nx {
        for (k, iz) in (z0..=z1).enumerate() {
            slice[ix + nx * k] = residual[(ix + nx * row) * nz + iz];
        }
    }
    let all = signed_front_view(&residual, nz);
    let reach = all.iter().chain(front_noise.iter().flatten()).fold(0.0f32, |a, &x| a.max(x.abs())).max(1e-3);
    let signed = Norm::linear(-f64::from(reach), f64::from(reach))?;
    let ex = Extent::from_centres(v.x.at(0), v.x.at(nx - 1), nx)?;
    let ey = Extent::from_centres(v.y.at(0), v.y.at(ny - 1), ny)?;
    let ez = Extent::from_centres(v.z.at(z0), v.z.at(z1), depths)?;
    let mut fig = Figure::new(format!("where the light is left unexplained ({} back-projection)", b.method));
    fig.notes.push(note.to_string());
    let form = if b.linear {
        "the volume of the capture minus the rendering (signed, linear)"
    } else {
        "the capture's volume minus the rendering's"
    };
    fig.notes.push(format!(
        "{form}, in units of the capture's peak; red: light the mesh does not make, blue: light it makes that \
         the capture lacks; largest {:.0} % of the peak",
        100.0 * reach
    ));
    let beyond = front_residual.iter().filter(|&&x| x != 0.0).count();
    if front_noise.is_some() {
        fig.notes.push(format!(
            "coloured where the residual exceeds the model's own Poisson noise within two columns: {beyond} of {} \
             columns ({:.0} %)",
            nx * ny,
            100.0 * beyond as f64 / (nx * ny).max(1) as f64
        ));
    }
    fig.panels = vec![
        Panel::image(ScalarGrid::new(&front, nx, ny, ex, ey)?, Norm::auto(&front, Scale::Linear)?)
            .with_colormap(Colormap::Grey)
            .with_labels("x (m)", "y (m)")
            .with_title("capture, front view (max over depth)"),
        Panel::image(ScalarGrid::new(&front_residual, nx, ny, ex, ey)?, signed)
            .with_colormap(Colormap::Diverging)
            .with_labels("x (m)", "y (m)")
            .with_title(if front_noise.is_some() {
                "residual beyond the noise, front view"
            } else {
                "residual, front view (largest magnitude over depth)"
            }),
    ];
    if let Some(n) = &front_noise {
        fig.panels.push(
            Panel::image(ScalarGrid::new(n, nx, ny, ex, ey)?, signed)
                .with_colormap(Colormap::Diverging)
                .with_labels("x (m)", "y (m)")
                .with_title("the model's own noise, front view"),
        );
    }
    fig.panels.push(
        Panel::image(ScalarGrid::new(&slice, nx, depths, ex, ez)?, signed)
            .with_colormap(Colormap::Diverging)
            .with_labels("x (m)", "depth z (m)")
            .with_title(format!("residual, x–z slice at y = {:.3} m", v.y.at(row)))
            .with_colorbar("share of the capture's peak"),
    );
    Ok(fig.render()?)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nlos_init::Axis;

    fn volume(data: Vec<f32>, nx: usize, ny: usize, nz: usize) -> Volume {
        let axis = |_: usize| Axis { start: 0.0, step: 0.01 };
        Volume { nx, ny, nz, x: axis(nx), y: axis(ny), z: axis(nz), data }
    }

    #[test]
    fn the_residual_is_the_difference_of_the_volumes_in_units_of_the_capture_peak() {
        // 2 × 1 columns of 3 voxels: the capture peaks at 4 in column 0; the rendering makes column 1's light.
        let m = volume(vec![0.0, 4.0, 0.0, 0.0, 0.0, 0.0], 2, 1, 3);
        let r = volume(vec![0.0, 1.0, 0.0, 0.0, 2.0, 0.0], 2, 1, 3);
        let difference = m.data.iter().zip(&r.data).map(|(a, b)| a - b).collect();
        let b = Backprojected { method: Method::Lct, measured: m, rendered: r, difference, noise: None, linear: false };
        assert_eq!(b.residual(), vec![0.0, 0.75, 0.0, 0.0, -0.5, 0.0]);
        assert_eq!(signed_front_view(&b.residual(), 3), vec![0.75, -0.5]);
        let img = residual_figure(&b, "test").unwrap();
        assert!(img.width() > 100 && img.height() > 50);
    }
    /// Expected counts of a 0.24 m plate at 0.35 m (and of a 6 cm square 5 cm in front of it, with `extra`),
    /// on a 32 × 32 confocal scan, about 40 counts at the brightest bin, gated at 0.3 m of path.
    fn plate_counts(extra: bool) -> Transient {
        use nlos_render::{Kernel, RenderParams, Renderer, Visibility};
        use nlos_transient::{PointSet, Scan, TimeAxis};
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        let mut quad = |x0: f32, y0: f32, w: f32, z: f32| {
            let b = positions.len() as u32;
            for (dx, dy) in [(0.0, 0.0), (w, 0.0), (0.0, w), (w, w)] {
                positions.push(glam::Vec3::new(x0 + dx, y0 + dy, z));
            }
            triangles.extend([[b, b + 2, b + 1], [b + 1, b + 2, b + 3]]);
        };
        for j in 0..6 {
            for i in 0..6 {
                quad(-0.12 + 0.04 * i as f32, -0.12 + 0.04 * j as f32, 0.04, 0.35);
            }
        }
        if extra {
            quad(0.1, 0.1, 0.06, 0.3);
        }
        let scan = Scan::confocal(PointSet::wall_grid(32, 32, 0.25, 0.25).unwrap());
        let time = TimeAxis::new(0.0, 0.004, 256).unwrap();
        let params = RenderParams { kernel: Kernel::Box, visibility: Visibility::Off, ..RenderParams::default() };
        let r = Renderer::new(&positions, &triangles, &scan, &time, params).unwrap();
        let t = r.forward_transient(&nlos_brdf::Lambertian::new(1.0f32).unwrap()).unwrap();
        let peak = t.data().iter().fold(0.0f32, |a, &v| a.max(v));
        let data = t.data().iter().map(|v| v * 40.0 / peak).collect();
        Transient::new(t.scan().clone(), *t.time(), data).unwrap().gate(0.3).unwrap()
    }

    /// A capture the model explains exactly (a Poisson draw of its own expected counts) shows nothing beyond
    /// the noise; one with a part the model lacks shows that part.
    #[test]
    fn only_light_beyond_the_models_noise_is_coloured() {
        let model = plate_counts(false);
        let exact = poisson_draw(&model, 7).unwrap();
        let b = backproject(Method::Lct, Model::Lambert, &exact, &model, Some(1)).unwrap();
        let beyond = b.beyond_noise().iter().filter(|&&x| x != 0.0).count();
        assert_eq!(beyond, 0, "columns beyond the noise of an exact model");
        let missing = poisson_draw(&plate_counts(true), 7).unwrap();
        let b = backproject(Method::Lct, Model::Lambert, &missing, &model, Some(1)).unwrap();
        let fv = b.beyond_noise();
        // The square spans x, y in [0.1, 0.16]: scan columns 22–25 of 32 (spacing 0.5/31 m).
        let inside = |c: usize| (22..=25).contains(&(c % 32)) && (22..=25).contains(&(c / 32));
        let found = (0..1024).filter(|&c| inside(c) && fv[c] > 0.0).count();
        assert!(found >= 12, "{found} of the missing square's 16 columns shown");
        // The plain difference of clamped volumes would not be signed-linear; this one is: V(a) − V(a) = 0.
        let same = backproject(Method::Lct, Model::Lambert, &model, &model, None).unwrap();
        assert!(same.difference.iter().all(|&x| x == 0.0));
    }
}
