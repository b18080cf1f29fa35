//! Where the light is left unexplained: the residual back-projected by the start's own volumetric method.
//!
//! The capture `m` and the final rendering as the fit saw it (`s*·I`, or the sensor fit's expected counts)
//! are each turned into a volume by the same method ([`nlos_init::Method::volume`]: the LCT on a confocal
//! grid, the phasor field otherwise), and the picture is their difference `V(m) − V(s*·I)`: where it is
//! positive the capture holds light the mesh does not make (a part missing, or too dark), where negative the
//! mesh makes light the capture lacks (a part too far out, too bright, or where there is none). Both volumes
//! go through the method as it is (the LCT and the phasor field clamp at zero), so the difference of the
//! volumes is shown rather than the volume of the difference, which clamping would cut in half.
//!
//! [`residual_figure`] draws three panels: the capture's front view (maximum over depth), the residual's
//! front view (per column, the signed value of largest magnitude) and its x–z slice through the row that
//! holds most of it — in units of the capture volume's peak, so that 0.2 reads "a fifth as bright as the
//! brightest thing in the capture".

use nlos_init::{Method, Model, Volume};
use nlos_transient::Transient;
use nlos_viz::{Colormap, Extent, Figure, Norm, Panel, RgbImage, ScalarGrid, Scale};

use crate::error::{ReportError, Result};

/// The capture's and the rendering's volumes by one method: what [`residual_figure`] draws.
#[derive(Debug, Clone)]
pub struct Backprojected {
    /// The method that made both volumes.
    pub method: Method,
    /// The capture's volume.
    pub measured: Volume,
    /// The rendering's volume, on the same voxels.
    pub rendered: Volume,
}

/// The volumes of `measured` and of `rendered` (the same scan and time axis; both gated) by `method`,
/// weighted for `reflectance` as the start's volume is.
///
/// # Errors
/// [`ReportError::Init`] when the method cannot take the scan or a volume is empty;
/// [`ReportError::InvalidOption`] when the two volumes do not share their voxels.
pub fn backproject(
    method: Method,
    reflectance: Model,
    measured: &Transient,
    rendered: &Transient,
) -> Result<Backprojected> {
    let m = method.volume(measured, reflectance, None)?;
    let r = method.volume(rendered, reflectance, None)?;
    if (m.nx, m.ny, m.nz) != (r.nx, r.ny, r.nz) {
        return Err(ReportError::InvalidOption {
            name: "rendered",
            reason: format!("volume {}x{}x{} against the capture's {}x{}x{}", r.nx, r.ny, r.nz, m.nx, m.ny, m.nz),
        });
    }
    Ok(Backprojected { method, measured: m, rendered: r })
}

impl Backprojected {
    /// `V(m) − V(s*·I)` voxel by voxel, in units of the capture volume's peak (0 everywhere when it has none).
    pub fn residual(&self) -> Vec<f32> {
        let peak = self.measured.data.iter().fold(0.0f32, |a, &v| a.max(v));
        let unit = if peak > 0.0 { 1.0 / peak } else { 0.0 };
        self.measured.data.iter().zip(&self.rendered.data).map(|(m, r)| (m - r) * unit).collect()
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
    let front_residual = signed_front_view(&residual, nz);
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
    let reach = front_residual.iter().fold(0.0f32, |a, &x| a.max(x.abs())).max(1e-3);
    let signed = Norm::linear(-f64::from(reach), f64::from(reach))?;
    let ex = Extent::from_centres(v.x.at(0), v.x.at(nx - 1), nx)?;
    let ey = Extent::from_centres(v.y.at(0), v.y.at(ny - 1), ny)?;
    let ez = Extent::from_centres(v.z.at(z0), v.z.at(z1), depths)?;
    let mut fig = Figure::new(format!("where the light is left unexplained ({} back-projection)", b.method));
    fig.notes.push(note.to_string());
    fig.notes.push(format!(
        "capture volume minus rendering volume, in units of the capture's peak; red: light the mesh does not \
         make, blue: light it makes that the capture lacks; largest {:.0} % of the peak",
        100.0 * reach
    ));
    fig.panels = vec![
        Panel::image(ScalarGrid::new(&front, nx, ny, ex, ey)?, Norm::auto(&front, Scale::Linear)?)
            .with_colormap(Colormap::Grey)
            .with_labels("x (m)", "y (m)")
            .with_title("capture, front view (max over depth)"),
        Panel::image(ScalarGrid::new(&front_residual, nx, ny, ex, ey)?, signed)
            .with_colormap(Colormap::Diverging)
            .with_labels("x (m)", "y (m)")
            .with_title("residual, front view (largest magnitude over depth)"),
        Panel::image(ScalarGrid::new(&slice, nx, depths, ex, ez)?, signed)
            .with_colormap(Colormap::Diverging)
            .with_labels("x (m)", "depth z (m)")
            .with_title(format!("residual, x–z slice at y = {:.3} m", v.y.at(row)))
            .with_colorbar("share of the capture's peak"),
    ];
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
        let b = Backprojected { method: Method::Lct, measured: m, rendered: r };
        assert_eq!(b.residual(), vec![0.0, 0.75, 0.0, 0.0, -0.5, 0.0]);
        assert_eq!(signed_front_view(&b.residual(), 3), vec![0.75, -0.5]);
        let img = residual_figure(&b, "test").unwrap();
        assert!(img.width() > 100 && img.height() > 50);
    }
}
