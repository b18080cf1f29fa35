//! Where a photon-count capture's light is left unexplained, in time and over the wall: the data term's
//! excess over its noise floor split by where each bin lies against its measurement's return.
//!
//! For the expected counts `μ` of the final surface as the fit saw it and the counts `n`, each bin's excess is
//! its half-deviance above what Poisson noise alone would leave there,
//! ```text
//! e_k = [μ_k − n_k + n_k ln(n_k/μ_k)] − E_{n~Poisson(μ_k)}[same]
//! ```
//! (the second term [`nlos_optim::expected_half_deviance`]); summed, it is the fit's data term less its noise
//! floor (`nlos_optim::data_term::counts`, "Noise floor"), what a better model could still remove. Each
//! measurement's **return** is the span of its bins where the surface's own light (`μ − b`, the background
//! taken out) reaches 1 % of that measurement's brightest bin; a bin lies **before**, **within** or **after**
//! it, and a measurement where the surface makes no light has **no return**. The split says whether the
//! light left over comes before the surface's first light (a part nearer the wall), within it (the wrong
//! amount of light, or the wrong shape of the pulse), or after it (a part further back, the sensor's tail,
//! light of several bounces); the map over the spots says where on the wall.

use nlos_transient::Transient;
use nlos_viz::{Colormap, Extent, Figure, Norm, Panel, RgbImage, ScalarGrid};

use crate::error::{ReportError, Result};

/// The share of a measurement's brightest bin of surface light that starts and ends its return.
pub const RETURN_FRACTION: f64 = 0.01;

/// The excess deviance split by where the bins lie ([module docs](self)). Sums of half-deviances, in the
/// units of the fit's data term before its normalisation (the capture's total count).
#[derive(Debug, Clone, PartialEq)]
pub struct Split {
    /// Over bins before each measurement's return.
    pub before: f64,
    /// Over bins within it.
    pub within: f64,
    /// Over bins after it.
    pub after: f64,
    /// Over the measurements where the surface makes no light.
    pub no_return: f64,
    /// Per measurement, its bins' sum (in measurement order).
    pub per_measurement: Vec<f64>,
}

impl Split {
    /// The excess over every bin.
    pub fn total(&self) -> f64 {
        self.before + self.within + self.after + self.no_return
    }

    /// The four parts as shares of the total (`NaN` when the total is not positive).
    pub fn shares(&self) -> [f64; 4] {
        let t = self.total();
        [self.before, self.within, self.after, self.no_return].map(|x| if t > 0.0 { x / t } else { f64::NAN })
    }
}

/// The split of `counts` against the expected counts `mu` (the same scan and time axis), whose background is
/// `background` counts per bin.
///
/// # Errors
/// [`ReportError::InvalidOption`] when the two do not hold the same number of values.
pub fn split(counts: &Transient, mu: &Transient, background: f64) -> Result<Split> {
    if counts.data().len() != mu.data().len() || counts.bins() != mu.bins() {
        return Err(ReportError::InvalidOption {
            name: "mu",
            reason: format!("{} values against the capture's {}", mu.data().len(), counts.data().len()),
        });
    }
    let bins = counts.bins().max(1);
    let mut s = Split { before: 0.0, within: 0.0, after: 0.0, no_return: 0.0, per_measurement: Vec::new() };
    for (n_row, mu_row) in counts.data().chunks_exact(bins).zip(mu.data().chunks_exact(bins)) {
        // In the values' own precision: a bin of background alone is then exactly 0.
        let b32 = background as f32;
        let signal = |k: usize| f64::from(mu_row[k] - b32);
        let peak = (0..bins).map(signal).fold(0.0f64, f64::max);
        let lit: Vec<usize> =
            if peak > 0.0 { (0..bins).filter(|&k| signal(k) >= RETURN_FRACTION * peak).collect() } else { Vec::new() };
        let (first, last) = (lit.first().copied(), lit.last().copied());
        let mut row = 0.0;
        for (k, (&n, &m)) in n_row.iter().zip(mu_row).enumerate() {
            let (n, m) = (f64::from(n), f64::from(m).max(1e-12));
            let d = m - n + if n > 0.0 { n * (n / m).ln() } else { 0.0 };
            let e = d - nlos_optim::expected_half_deviance(m);
            row += e;
            match (first, last) {
                (Some(f), _) if k < f => s.before += e,
                (_, Some(l)) if k > l => s.after += e,
                (Some(_), Some(_)) => s.within += e,
                _ => s.no_return += e,
            }
        }
        s.per_measurement.push(row);
    }
    Ok(s)
}

/// The split drawn: each spot's excess over the wall (a grid of `nx × ny` spots spanning `x` and `y`), with
/// the split in time as notes.
///
/// # Errors
/// Drawing errors; [`ReportError::InvalidOption`] when the split is not one value per spot of the grid.
pub fn unexplained_figure(s: &Split, nx: usize, ny: usize, x: Extent, y: Extent) -> Result<RgbImage> {
    if s.per_measurement.len() != nx * ny {
        return Err(ReportError::InvalidOption {
            name: "split",
            reason: format!("{} measurements on a {nx} x {ny} grid", s.per_measurement.len()),
        });
    }
    let values: Vec<f32> = s.per_measurement.iter().map(|&v| v as f32).collect();
    let reach = values.iter().fold(0.0f32, |a, &v| a.max(v.abs())).max(1e-6);
    let [before, within, after, none] = s.shares().map(|x| 100.0 * x);
    let mut fig = Figure::new("where the light is left unexplained: the data term above its noise floor");
    fig.notes.push(format!(
        "{:.4e} of half-deviance above the noise in all: {before:.0} % before each spot's return, {within:.0} % \
         within it, {after:.0} % after it, {none:.0} % at spots where the surface makes no light",
        s.total()
    ));
    fig.notes.push("red: more misfit than Poisson noise leaves; blue: less (the fit took some noise)".into());
    fig.panels = vec![
        Panel::image(ScalarGrid::new(&values, nx, ny, x, y)?, Norm::linear(-f64::from(reach), f64::from(reach))?)
            .with_colormap(Colormap::Diverging)
            .with_labels("x (m)", "y (m)")
            .with_title("per spot, summed over its bins")
            .with_colorbar("half-deviance above the noise"),
    ];
    Ok(fig.render()?)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nlos_transient::{PointSet, Scan, TimeAxis};

    fn transient(rows: &[[f32; 6]]) -> Transient {
        let scan = Scan::confocal(PointSet::wall_grid(rows.len(), 1, 0.25, 0.25).unwrap());
        Transient::new(scan, TimeAxis::new(0.0, 0.01, 6).unwrap(), rows.iter().flatten().copied().collect()).unwrap()
    }

    #[test]
    fn splits_the_excess_by_where_each_bin_lies_against_its_return() {
        // Background 0.1 per bin; spot 0 returns in bins 2–3, spot 1 has no return.
        let mu = transient(&[[0.1, 0.1, 10.1, 5.1, 0.1, 0.1], [0.1; 6]]);
        // Counts equal to μ's where the model is right: 4 photons before spot 0's return, 6 after it, 3 at spot 1.
        let n = transient(&[[4.0, 0.0, 10.0, 5.0, 0.0, 6.0], [0.0, 3.0, 0.0, 0.0, 0.0, 0.0]]);
        let s = split(&n, &mu, 0.1).unwrap();
        let excess = |m: f64, c: f64| {
            m - c + if c > 0.0 { c * (c / m).ln() } else { 0.0 } - nlos_optim::expected_half_deviance(m)
        };
        let close = |a: f64, b: f64| (a - b).abs() < 1e-5 * (1.0 + b.abs()); // μ is stored in f32
        assert!(close(s.before, excess(0.1, 4.0) + excess(0.1, 0.0)), "{s:?}");
        assert!(close(s.within, excess(10.1, 10.0) + excess(5.1, 5.0)), "{s:?}");
        assert!(close(s.after, excess(0.1, 0.0) + excess(0.1, 6.0)), "{s:?}");
        assert!(close(s.no_return, excess(0.1, 3.0) + 5.0 * excess(0.1, 0.0)), "{s:?}");
        assert!(close(s.per_measurement.iter().sum::<f64>(), s.total()));
        assert!(s.before > 0.0 && s.after > s.before, "the stray photons are the misfit: {s:?}");
        let img = unexplained_figure(&s, 2, 1, Extent::new(0.0, 1.0).unwrap(), Extent::new(0.0, 1.0).unwrap());
        assert!(img.unwrap().width() > 100);
    }
}
