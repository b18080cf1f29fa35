//! Views of a transient for display: the sensor grid, its time-summed image and x–t slices.
//!
//! For an exhaustive scan with a sensor grid, the views sum over the laser points, so that each sensor
//! point gets one histogram (what a camera at the sensor grid would record under all the lasers at once).

use crate::error::{Result, TransientError};
use crate::scan::ScanPattern;
use crate::transient::Transient;

impl Transient {
    /// `(nx, ny)` of the sensor points when they form a grid (the scan points of a confocal scan).
    pub fn sensor_grid(&self) -> Option<(usize, usize)> {
        self.scan().sensors().grid_dims()
    }

    /// The time-summed value of each sensor grid point, `nx × ny` with x fastest (summed over the laser
    /// points of an exhaustive scan). Accumulated in `f64`.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when the sensor points are not a grid.
    ///
    /// # Example
    /// ```
    /// use nlos_transient::{PointSet, Scan, TimeAxis, Transient};
    /// let scan = Scan::confocal(PointSet::wall_grid(3, 2, 0.1, 0.1)?);
    /// let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.01, 4)?)?;
    /// t.histogram_mut(4).copy_from_slice(&[1.0, 2.0, 0.0, 0.5]);
    /// assert_eq!(t.time_summed_image()?, vec![0.0, 0.0, 0.0, 0.0, 3.5, 0.0]);
    /// # Ok::<(), nlos_transient::TransientError>(())
    /// ```
    pub fn time_summed_image(&self) -> Result<Vec<f32>> {
        let (nx, ny) = self.sensor_grid().ok_or_else(not_grid)?;
        let mut acc = vec![0.0f64; nx * ny];
        for (m, h) in self.histograms().enumerate() {
            let (_, is) = self.scan().indices(m);
            acc[is] += h.iter().map(|&v| f64::from(v)).sum::<f64>();
        }
        Ok(acc.into_iter().map(|v| v as f32).collect())
    }

    /// The x–t slice through sensor grid row `iy`: `nx` histograms, one per column `ix` in order, each of
    /// [`Transient::bins`] values (`out[ix · bins + k]`); summed over the laser points of an exhaustive
    /// scan.
    ///
    /// # Errors
    /// [`TransientError::InvalidArgument`] when the sensor points are not a grid or `iy >= ny`.
    ///
    /// # Example
    /// ```
    /// use nlos_transient::{PointSet, Scan, TimeAxis, Transient};
    /// let scan = Scan::confocal(PointSet::wall_grid(2, 2, 0.1, 0.1)?);
    /// let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.01, 3)?)?;
    /// t.histogram_mut(3).copy_from_slice(&[1.0, 2.0, 3.0]); // ix = 1, iy = 1
    /// assert_eq!(t.grid_row_slice(1)?, vec![0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);
    /// assert!(t.grid_row_slice(2).is_err());
    /// # Ok::<(), nlos_transient::TransientError>(())
    /// ```
    pub fn grid_row_slice(&self, iy: usize) -> Result<Vec<f32>> {
        let (nx, ny) = self.sensor_grid().ok_or_else(not_grid)?;
        if iy >= ny {
            return Err(TransientError::InvalidArgument {
                name: "row",
                reason: format!("row {iy} is outside the sensor grid's rows 0..{ny}"),
            });
        }
        let bins = self.bins();
        let row = nx * iy..nx * (iy + 1);
        match &self.scan().pattern {
            // A paired scan's measurement m has sensor spot m, as a confocal scan's.
            ScanPattern::Confocal(_) | ScanPattern::Paired { .. } => {
                Ok(self.data()[row.start * bins..row.end * bins].to_vec())
            }
            ScanPattern::Exhaustive { lasers, sensors } => {
                let ns = sensors.len();
                let mut acc = vec![0.0f64; nx * bins];
                for il in 0..lasers.len() {
                    for (ix, is) in row.clone().enumerate() {
                        let h = self.histogram(il * ns + is);
                        for (a, &v) in acc[ix * bins..(ix + 1) * bins].iter_mut().zip(h) {
                            *a += f64::from(v);
                        }
                    }
                }
                Ok(acc.into_iter().map(|v| v as f32).collect())
            }
        }
    }
}

fn not_grid() -> TransientError {
    TransientError::InvalidArgument {
        name: "scan",
        reason: "the sensor points are a list, not a grid; use summed_histogram for a list".into(),
    }
}

#[cfg(test)]
mod tests {
    use crate::{PointSet, Scan, TimeAxis, Transient};
    use glam::Vec3;

    fn exhaustive() -> Transient {
        let lasers = PointSet::list(vec![Vec3::ZERO, Vec3::X * 0.1]);
        let sensors = PointSet::wall_grid(2, 2, 0.1, 0.1).expect("grid");
        let mut t = Transient::zeros(Scan::exhaustive(lasers, sensors), TimeAxis::new(0.0, 0.01, 2).expect("axis"))
            .expect("transient");
        for m in 0..t.measurements() {
            t.histogram_mut(m).copy_from_slice(&[m as f32, 1.0]);
        }
        t
    }

    #[test]
    fn exhaustive_views_sum_over_lasers() {
        let t = exhaustive();
        assert_eq!(t.sensor_grid(), Some((2, 2)));
        // Sensor is gets m = is (laser 0) and m = 4 + is (laser 1): sums (is + 1) + (4 + is + 1).
        assert_eq!(t.time_summed_image().expect("image"), vec![6.0, 8.0, 10.0, 12.0]);
        // Row 1 = sensors 2, 3: bin 0 = 2 + 6, 3 + 7; bin 1 = 2 each.
        assert_eq!(t.grid_row_slice(1).expect("slice"), vec![8.0, 2.0, 10.0, 2.0]);
    }

    #[test]
    fn confocal_image_matches_time_summed() {
        let mut t = Transient::zeros(
            Scan::confocal(PointSet::wall_grid(3, 3, 0.2, 0.2).expect("grid")),
            TimeAxis::new(0.0, 0.01, 5).expect("axis"),
        )
        .expect("transient");
        for (i, v) in t.data_mut().iter_mut().enumerate() {
            *v = (i % 7) as f32;
        }
        assert_eq!(t.time_summed_image().expect("image"), t.time_summed());
        let slice = t.grid_row_slice(2).expect("slice");
        assert_eq!(slice, t.data()[6 * 5..9 * 5]);
    }

    #[test]
    fn lists_and_bad_rows_are_errors() {
        let t = Transient::zeros(
            Scan::confocal(PointSet::list(vec![Vec3::ZERO, Vec3::Y])),
            TimeAxis::new(0.0, 0.01, 5).expect("axis"),
        )
        .expect("transient");
        assert_eq!(t.sensor_grid(), None);
        assert!(t.time_summed_image().is_err());
        assert!(t.grid_row_slice(0).is_err());
        assert!(exhaustive().grid_row_slice(usize::MAX).is_err());
    }
}
