//! Scalar grids with physical extents, and their resampling into pixel panels.

use crate::error::{Result, VizError};

/// The physical span a grid axis covers, from the outer edge of its first cell (`start`) to the outer edge
/// of its last cell (`end`). `start > end` is allowed: the axis then runs backwards (cell 0 at the high end).
///
/// # Example
/// ```
/// use nlos_viz::Extent;
/// // 64 samples at linspace(-0.35, 0.35, 64): cells are 0.7/63 wide, the edges half a cell further out.
/// let e = Extent::from_centres(-0.35, 0.35, 64)?;
/// assert!((e.start + 0.35 + 0.7 / 63.0 / 2.0).abs() < 1e-12);
/// assert_eq!(e.min(), e.start);
/// # Ok::<(), nlos_viz::VizError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    /// Outer edge of cell 0.
    pub start: f64,
    /// Outer edge of the last cell.
    pub end: f64,
}

impl Extent {
    /// An extent from its two edges.
    ///
    /// # Errors
    /// [`VizError::InvalidGrid`] unless both are finite and differ.
    pub fn new(start: f64, end: f64) -> Result<Self> {
        if !(start.is_finite() && end.is_finite() && start != end && (end - start).is_finite()) {
            return Err(VizError::InvalidGrid {
                reason: format!("extent [{start}, {end}] must be finite with distinct ends"),
            });
        }
        Ok(Self { start, end })
    }

    /// The extent of `n` cells whose centres run from `first` to `last`, evenly spaced. With `n = 1` or
    /// `first == last` the spacing is unknown and the cell is given a width of 1 (same unit), centred.
    ///
    /// # Errors
    /// [`VizError::InvalidGrid`] when `n == 0` or a value is not finite.
    pub fn from_centres(first: f64, last: f64, n: usize) -> Result<Self> {
        if n == 0 || !first.is_finite() || !last.is_finite() {
            return Err(VizError::InvalidGrid { reason: format!("{n} cells centred {first}..{last}") });
        }
        if n == 1 || first == last {
            let c = 0.5 * (first + last);
            return Self::new(c - 0.5, c + 0.5);
        }
        let half = 0.5 * (last - first) / (n - 1) as f64;
        Self::new(first - half, last + half)
    }

    /// The smaller end.
    pub fn min(&self) -> f64 {
        self.start.min(self.end)
    }

    /// The larger end.
    pub fn max(&self) -> f64 {
        self.start.max(self.end)
    }

    /// Position of physical coordinate `v` in cell units of an axis of `n` cells (0 at `start`, `n` at `end`).
    fn to_cells(self, v: f64, n: usize) -> f64 {
        (v - self.start) / (self.end - self.start) * n as f64
    }
}

/// A borrowed 2-D grid of `nx × ny` scalar values, `x` fastest (`values[ix + nx·iy]`), with the physical
/// extent of each axis.
#[derive(Debug, Clone, Copy)]
pub struct ScalarGrid<'a> {
    values: &'a [f32],
    nx: usize,
    ny: usize,
    x: Extent,
    y: Extent,
}

impl<'a> ScalarGrid<'a> {
    /// A grid over `values`.
    ///
    /// # Errors
    /// [`VizError::InvalidGrid`] when a size is zero or `values.len() != nx × ny`.
    ///
    /// # Example
    /// ```
    /// use nlos_viz::{Extent, ScalarGrid};
    /// let v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    /// let g = ScalarGrid::new(&v, 3, 2, Extent::new(0.0, 3.0)?, Extent::new(0.0, 1.0)?)?;
    /// assert_eq!(g.get(2, 1), Some(6.0));
    /// # Ok::<(), nlos_viz::VizError>(())
    /// ```
    pub fn new(values: &'a [f32], nx: usize, ny: usize, x: Extent, y: Extent) -> Result<Self> {
        if nx == 0 || ny == 0 || nx.checked_mul(ny) != Some(values.len()) {
            return Err(VizError::InvalidGrid {
                reason: format!("{} values do not fill a {nx} × {ny} grid (need a non-empty grid)", values.len()),
            });
        }
        Ok(Self { values, nx, ny, x, y })
    }

    /// Columns.
    pub fn nx(&self) -> usize {
        self.nx
    }

    /// Rows.
    pub fn ny(&self) -> usize {
        self.ny
    }

    /// Extent of the x axis.
    pub fn x_extent(&self) -> Extent {
        self.x
    }

    /// Extent of the y axis.
    pub fn y_extent(&self) -> Extent {
        self.y
    }

    /// The values, x fastest.
    pub fn values(&self) -> &'a [f32] {
        self.values
    }

    /// Value of cell `(ix, iy)`, or `None` outside the grid.
    pub fn get(&self, ix: usize, iy: usize) -> Option<f32> {
        (ix < self.nx && iy < self.ny).then(|| self.values[ix + self.nx * iy])
    }
}

/// How a grid is sampled into pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interp {
    /// The cell under the pixel centre (blocky; honest about the sampling).
    #[default]
    Nearest,
    /// Bilinear interpolation between cell centres, clamped at the borders.
    Bilinear,
    /// The mean of the cells the pixel covers, weighted by overlap (for shrinking without aliasing).
    Area,
}

/// Taps `(cell, weight)` along one axis for output pixel `p` of `n_out`, covering physical `[lo, hi]`.
fn taps(ext: Extent, n: usize, lo: f64, hi: f64, p: usize, n_out: usize, interp: Interp) -> Vec<(usize, f64)> {
    let phys = |f: f64| lo + (hi - lo) * f / n_out as f64;
    let last = (n - 1) as f64;
    match interp {
        Interp::Nearest => {
            let c = ext.to_cells(phys(p as f64 + 0.5), n).floor().clamp(0.0, last);
            vec![(c as usize, 1.0)]
        }
        Interp::Bilinear => {
            let c = (ext.to_cells(phys(p as f64 + 0.5), n) - 0.5).clamp(0.0, last);
            let i0 = c.floor();
            let f = c - i0;
            let i0 = i0 as usize;
            if f > 0.0 && i0 + 1 < n { vec![(i0, 1.0 - f), (i0 + 1, f)] } else { vec![(i0, 1.0)] }
        }
        Interp::Area => {
            let a = ext.to_cells(phys(p as f64), n);
            let b = ext.to_cells(phys(p as f64 + 1.0), n);
            let (a, b) = (a.min(b).clamp(0.0, n as f64), a.max(b).clamp(0.0, n as f64));
            let mut v = Vec::new();
            let mut i = a.floor();
            while i < b && i < n as f64 {
                let w = b.min(i + 1.0) - a.max(i);
                if w > 0.0 {
                    v.push((i as usize, w));
                }
                i += 1.0;
            }
            if v.is_empty() {
                // The pixel lies outside the grid or is degenerate: use the nearest cell.
                let c = ext.to_cells(phys(p as f64 + 0.5), n).floor().clamp(0.0, last);
                v.push((c as usize, 1.0));
            }
            v
        }
    }
}

/// Samples `grid` into a `width × height` raster covering the grid's full extent, `x` increasing to the
/// right. Row 0 is the top: the high end of y when `y_down` is false (the usual plot orientation), the
/// low end when it is true. Returns `width × height` values, row-major; non-finite cells are skipped by
/// the weighting (a pixel with only non-finite cells is NaN).
///
/// # Errors
/// [`VizError::InvalidSize`] when `width` or `height` is zero or their product overflows.
///
/// # Example
/// ```
/// use nlos_viz::{resample, Extent, Interp, ScalarGrid};
/// let v = [0.0, 1.0, 2.0, 3.0]; // 2 × 2, y up: row iy = 1 ends on top
/// let g = ScalarGrid::new(&v, 2, 2, Extent::new(0.0, 1.0)?, Extent::new(0.0, 1.0)?)?;
/// assert_eq!(resample(&g, 2, 2, Interp::Nearest, false)?, vec![2.0, 3.0, 0.0, 1.0]);
/// assert_eq!(resample(&g, 1, 1, Interp::Area, false)?, vec![1.5]);
/// # Ok::<(), nlos_viz::VizError>(())
/// ```
pub fn resample(grid: &ScalarGrid<'_>, width: usize, height: usize, interp: Interp, y_down: bool) -> Result<Vec<f32>> {
    if width == 0 || height == 0 || width.checked_mul(height).is_none() {
        return Err(VizError::InvalidSize { width, height, reason: "a raster needs at least one pixel".into() });
    }
    let (x, y) = (grid.x, grid.y);
    let xt: Vec<_> = (0..width).map(|p| taps(x, grid.nx, x.min(), x.max(), p, width, interp)).collect();
    // Pixel rows run top to bottom: physical y from max to min unless y_down.
    let (ylo, yhi) = if y_down { (y.min(), y.max()) } else { (y.max(), y.min()) };
    let yt: Vec<_> = (0..height).map(|p| taps(y, grid.ny, ylo, yhi, p, height, interp)).collect();
    let mut out = Vec::with_capacity(width * height);
    for ty in &yt {
        for tx in &xt {
            let (mut acc, mut wsum) = (0.0f64, 0.0f64);
            for &(iy, wy) in ty {
                for &(ix, wx) in tx {
                    let v = grid.values[ix + grid.nx * iy];
                    if v.is_finite() {
                        acc += f64::from(v) * wx * wy;
                        wsum += wx * wy;
                    }
                }
            }
            out.push(if wsum > 0.0 { (acc / wsum) as f32 } else { f32::NAN });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(v: &[f32], nx: usize, ny: usize) -> ScalarGrid<'_> {
        let e = |n: usize| Extent::new(0.0, n as f64).expect("extent");
        ScalarGrid::new(v, nx, ny, e(nx), e(ny)).expect("grid")
    }

    #[test]
    fn nearest_upsamples_blocks() {
        let v = [1.0, 2.0];
        let out = resample(&grid(&v, 2, 1), 4, 1, Interp::Nearest, false).expect("resample");
        assert_eq!(out, vec![1.0, 1.0, 2.0, 2.0]);
    }

    #[test]
    fn bilinear_interpolates_between_centres() {
        let v = [0.0, 4.0];
        let out = resample(&grid(&v, 2, 1), 4, 1, Interp::Bilinear, false).expect("resample");
        // Pixel centres at cells 0.25, 0.75, 1.25, 1.75 → offsets from cell centre 0.5: clamp, .25, .75, clamp.
        assert_eq!(out, vec![0.0, 1.0, 3.0, 4.0]);
    }

    #[test]
    fn area_averages_and_conserves_mean() {
        let v: Vec<f32> = (0..12).map(|i| i as f32).collect();
        let out = resample(&grid(&v, 1, 12), 1, 3, Interp::Area, true).expect("resample");
        assert_eq!(out, vec![1.5, 5.5, 9.5]);
    }

    #[test]
    fn reversed_extent_mirrors() {
        let v = [1.0, 2.0, 3.0];
        let g = ScalarGrid::new(&v, 3, 1, Extent::new(3.0, 0.0).expect("e"), Extent::new(0.0, 1.0).expect("e"))
            .expect("grid");
        assert_eq!(resample(&g, 3, 1, Interp::Nearest, false).expect("resample"), vec![3.0, 2.0, 1.0]);
    }

    #[test]
    fn y_orientation() {
        let v = [1.0, 2.0];
        let g = grid(&v, 1, 2);
        assert_eq!(resample(&g, 1, 2, Interp::Nearest, false).expect("r"), vec![2.0, 1.0]);
        assert_eq!(resample(&g, 1, 2, Interp::Nearest, true).expect("r"), vec![1.0, 2.0]);
    }

    #[test]
    fn bad_input_is_an_error() {
        let v = [1.0, 2.0, 3.0];
        let e = Extent::new(0.0, 1.0).expect("extent");
        assert!(ScalarGrid::new(&v, 2, 2, e, e).is_err());
        assert!(ScalarGrid::new(&v, 0, 3, e, e).is_err());
        assert!(Extent::new(1.0, 1.0).is_err());
        assert!(Extent::new(0.0, f64::INFINITY).is_err());
        assert!(Extent::from_centres(0.0, 1.0, 0).is_err());
        assert_eq!(Extent::from_centres(2.0, 2.0, 1).expect("e"), Extent { start: 1.5, end: 2.5 });
        assert!(resample(&grid(&v, 3, 1), 0, 1, Interp::Nearest, false).is_err());
        let nan = [f32::NAN, 1.0];
        let out = resample(&grid(&nan, 2, 1), 2, 1, Interp::Nearest, false).expect("resample");
        assert!(out[0].is_nan() && out[1] == 1.0);
    }
}
