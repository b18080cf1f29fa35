//! Colormaps and value scaling (linear, logarithmic with a floor).

use crate::error::{Result, VizError};
use crate::image::Rgb;
use crate::tables;

/// A map from `[0, 1]` to colours.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[non_exhaustive]
pub enum Colormap {
    /// matplotlib's perceptually uniform `viridis` (dark blue → green → yellow), 256 entries.
    #[default]
    Viridis,
    /// matplotlib's perceptually uniform `magma` (black → purple → orange → light yellow), 256 entries.
    Magma,
    /// Grey ramp from black to white.
    Grey,
    /// Diverging blue → light grey → red (Moreland's "cool to warm", 2009, end points and middle of
    /// ParaView's table, blended linearly): signed values drawn with a [`crate::Norm`] symmetric about 0, the
    /// middle grey at 0.
    Diverging,
    /// Discrete colours for categories: `t` picks entry `round(t · (len − 1))`, so that category `k` of
    /// `len` drawn with `Norm::linear(0, len − 1)` gets colour `k`. An empty palette draws black.
    Palette(&'static [Rgb]),
}

impl Colormap {
    /// The colour of `t`: `t` is clamped to `[0, 1]` and NaN maps to the low end. Table colormaps pick the
    /// nearest of their 256 entries.
    ///
    /// # Example
    /// ```
    /// use nlos_viz::{Colormap, Rgb};
    /// assert_eq!(Colormap::Grey.map(0.0), Rgb::BLACK);
    /// assert_eq!(Colormap::Grey.map(7.0), Rgb::WHITE);
    /// assert_eq!(Colormap::Viridis.map(0.0), Rgb::new(68, 1, 84));
    /// const THREE: [Rgb; 3] = [Rgb::RED, Rgb::GREY, Rgb::BLUE];
    /// assert_eq!(Colormap::Palette(&THREE).map(0.5), Rgb::GREY);
    /// assert_eq!(Colormap::Palette(&THREE).map(1.0), Rgb::BLUE);
    /// assert_eq!(Colormap::Diverging.map(0.5), Rgb::new(221, 221, 221));
    /// assert_eq!(Colormap::Diverging.map(1.0), Rgb::new(180, 4, 38));
    /// ```
    pub fn map(self, t: f32) -> Rgb {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        let i = (t * 255.0).round() as usize;
        match self {
            Colormap::Viridis => Rgb(tables::VIRIDIS[i]),
            Colormap::Magma => Rgb(tables::MAGMA[i]),
            Colormap::Grey => Rgb([i as u8; 3]),
            Colormap::Diverging => {
                const COOL: Rgb = Rgb([59, 76, 192]);
                const MIDDLE: Rgb = Rgb([221, 221, 221]);
                const WARM: Rgb = Rgb([180, 4, 38]);
                if t < 0.5 { COOL.lerp(MIDDLE, 2.0 * t) } else { MIDDLE.lerp(WARM, 2.0 * t - 1.0) }
            }
            Colormap::Palette(colours) => match colours.len() {
                0 => Rgb::BLACK,
                n => colours[(t * (n - 1) as f32).round() as usize],
            },
        }
    }

    /// The colormap's name (`viridis`, `magma`, `grey`, `diverging`, `palette`).
    pub fn name(self) -> &'static str {
        match self {
            Colormap::Viridis => "viridis",
            Colormap::Magma => "magma",
            Colormap::Grey => "grey",
            Colormap::Diverging => "diverging",
            Colormap::Palette(_) => "palette",
        }
    }
}

/// How data values map to `[0, 1]` before colouring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scale {
    /// `t = (v − lo) / (hi − lo)`.
    Linear,
    /// `t = (log10 v − log10 floor) / decades` with `floor = hi · 10^(−decades)`: the top of the range maps
    /// to 1 and `decades` decades below it to 0. Values at or below the floor — zeros, negatives and NaN
    /// included — map to 0.
    Log {
        /// How many decades below the maximum the colour scale reaches (> 0).
        decades: f64,
    },
}

/// A value range together with its [`Scale`]: maps data values to `[0, 1]`.
///
/// # Example
/// ```
/// use nlos_viz::{Norm, Scale};
/// let lin = Norm::auto(&[2.0, 4.0, 6.0], Scale::Linear)?;
/// assert_eq!(lin.apply(4.0), 0.5);
/// let log = Norm::auto(&[0.0, 10.0, 1000.0], Scale::Log { decades: 3.0 })?;
/// assert_eq!(log.range(), (1.0, 1000.0)); // the floor is 1000 · 10^-3
/// assert_eq!(log.apply(0.0), 0.0); // below the floor
/// assert!((log.apply(10.0) - 1.0 / 3.0).abs() < 1e-6);
/// # Ok::<(), nlos_viz::VizError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Norm {
    scale: Scale,
    lo: f64,
    hi: f64,
}

impl Norm {
    /// A linear map of `[lo, hi]` to `[0, 1]`.
    ///
    /// # Errors
    /// [`VizError::InvalidArgument`] unless both are finite and `lo < hi`.
    pub fn linear(lo: f64, hi: f64) -> Result<Self> {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(VizError::InvalidArgument {
                name: "range",
                reason: format!("[{lo}, {hi}] must be finite with lo < hi"),
            });
        }
        Ok(Self { scale: Scale::Linear, lo, hi })
    }

    /// A logarithmic map with top `hi` and floor `hi · 10^(−decades)`.
    ///
    /// # Errors
    /// [`VizError::InvalidArgument`] unless `hi` is finite and positive and `decades` finite and positive.
    pub fn log(hi: f64, decades: f64) -> Result<Self> {
        if !(hi.is_finite() && hi > 0.0 && decades.is_finite() && decades > 0.0) {
            return Err(VizError::InvalidArgument {
                name: "log range",
                reason: format!("top {hi} and decades {decades} must be finite and > 0"),
            });
        }
        let lo = hi * 10f64.powf(-decades);
        if lo <= 0.0 || !lo.is_finite() {
            return Err(VizError::InvalidArgument { name: "decades", reason: format!("{decades} decades underflow") });
        }
        Ok(Self { scale: Scale::Log { decades }, lo, hi })
    }

    /// The range of the finite values of `values` with `scale`. Degenerate data never fail: an empty or
    /// constant linear range becomes `[v, v + 1]`, and a log range whose maximum is not positive becomes
    /// `[10^(−decades), 1]`.
    ///
    /// # Errors
    /// [`VizError::InvalidArgument`] when a log scale's `decades` is not finite and positive.
    pub fn auto(values: &[f32], scale: Scale) -> Result<Self> {
        let finite = values.iter().copied().filter(|v| v.is_finite()).map(f64::from);
        let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        match scale {
            Scale::Linear => {
                if !(lo.is_finite() && hi.is_finite()) {
                    return Self::linear(0.0, 1.0);
                }
                if hi > lo { Self::linear(lo, hi) } else { Self::linear(lo, lo + 1.0) }
            }
            Scale::Log { decades } => Self::log(if hi > 0.0 && hi.is_finite() { hi } else { 1.0 }, decades),
        }
    }

    /// The scale.
    pub fn scale(&self) -> Scale {
        self.scale
    }

    /// `(low, high)` in data units: for a log scale the low end is the floor.
    pub fn range(&self) -> (f64, f64) {
        (self.lo, self.hi)
    }

    /// Maps `v` to `[0, 1]` (clamped; NaN maps to 0).
    pub fn apply(&self, v: f64) -> f32 {
        let t = match self.scale {
            Scale::Linear => (v - self.lo) / (self.hi - self.lo),
            Scale::Log { decades } => {
                if v.is_nan() || v <= self.lo {
                    0.0
                } else {
                    (v / self.lo).log10() / decades
                }
            }
        };
        if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) as f32 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colormap_endpoints() {
        assert_eq!(Colormap::Viridis.map(0.0), Rgb::new(68, 1, 84));
        assert_eq!(Colormap::Viridis.map(1.0), Rgb::new(253, 231, 37));
        assert_eq!(Colormap::Magma.map(0.0), Rgb::new(0, 0, 4));
        assert_eq!(Colormap::Magma.map(1.0), Rgb::new(252, 253, 191));
        assert_eq!(Colormap::Grey.map(0.0), Rgb::BLACK);
        assert_eq!(Colormap::Grey.map(1.0), Rgb::WHITE);
        assert_eq!(Colormap::Viridis.map(f32::NAN), Colormap::Viridis.map(0.0));
        assert_eq!(Colormap::Magma.map(-3.0), Colormap::Magma.map(0.0));
    }

    #[test]
    fn perceptual_maps_brighten_monotonically() {
        for cm in [Colormap::Viridis, Colormap::Magma, Colormap::Grey] {
            let lum = |t: f32| {
                let Rgb([r, g, b]) = cm.map(t);
                0.2126 * f32::from(r) + 0.7152 * f32::from(g) + 0.0722 * f32::from(b)
            };
            for i in 0..20 {
                assert!(lum(i as f32 / 20.0) < lum((i + 1) as f32 / 20.0), "{} at {i}", cm.name());
            }
        }
    }

    #[test]
    fn scales() {
        let n = Norm::linear(-1.0, 1.0).expect("norm");
        assert_eq!((n.apply(-1.0), n.apply(0.0), n.apply(1.0), n.apply(9.0)), (0.0, 0.5, 1.0, 1.0));
        let l = Norm::log(100.0, 2.0).expect("norm");
        assert_eq!(l.range(), (1.0, 100.0));
        assert_eq!((l.apply(-5.0), l.apply(1.0), l.apply(100.0)), (0.0, 0.0, 1.0));
        assert!((l.apply(10.0) - 0.5).abs() < 1e-6);
        assert!(Norm::linear(1.0, 1.0).is_err());
        assert!(Norm::log(0.0, 2.0).is_err());
        assert!(Norm::log(1.0, f64::NAN).is_err());
        // Degenerate data do not fail.
        assert_eq!(Norm::auto(&[], Scale::Linear).expect("norm").range(), (0.0, 1.0));
        assert_eq!(Norm::auto(&[3.0, 3.0], Scale::Linear).expect("norm").range(), (3.0, 4.0));
        assert_eq!(Norm::auto(&[0.0, -1.0], Scale::Log { decades: 1.0 }).expect("norm").range(), (0.1, 1.0));
    }
}
