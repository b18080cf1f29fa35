//! Albedo volumes with their voxel geometry.

use crate::error::{InitError, Result};

/// A regular axis: coordinate of sample `i` is `start + i · step` (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axis {
    /// Coordinate of the first sample (voxel centre), metres.
    pub start: f64,
    /// Spacing between samples, metres (may be negative for a decreasing axis, never zero).
    pub step: f64,
}

impl Axis {
    /// Coordinate of sample `i`.
    pub fn at(&self, i: usize) -> f64 {
        self.start + i as f64 * self.step
    }
}

/// A reconstructed volume (albedo, or a method's confidence) on an `nx × ny × nz` voxel grid.
///
/// `x` and `y` follow the scan grid (voxel `(ix, iy)` lies in front of scan point `ix + nx·iy`), `z` is
/// the depth from the wall (z > 0 in the hidden scene). Data are column-major in depth, like the
/// transients they come from: voxel `(ix, iy, iz)` is `data[(ix + nx·iy)·nz + iz]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    /// Voxels along x.
    pub nx: usize,
    /// Voxels along y.
    pub ny: usize,
    /// Voxels along z (depth).
    pub nz: usize,
    /// x coordinates of the voxel centres.
    pub x: Axis,
    /// y coordinates of the voxel centres.
    pub y: Axis,
    /// Depths of the voxel centres.
    pub z: Axis,
    /// Values, `data[(ix + nx·iy)·nz + iz]`.
    pub data: Vec<f32>,
}

impl Volume {
    /// Checks sizes, finite geometry and finite values.
    ///
    /// # Errors
    /// [`InitError::BadVolume`] for an empty or inconsistent volume, [`InitError::NonFinite`] for NaN data.
    pub fn validate(&self) -> Result<()> {
        let bad = |reason: String| Err(InitError::BadVolume { reason });
        if self.nx == 0 || self.ny == 0 || self.nz == 0 {
            return bad(format!("{} × {} × {} voxels: the volume is empty", self.nx, self.ny, self.nz));
        }
        let n = self.nx.checked_mul(self.ny).and_then(|v| v.checked_mul(self.nz));
        if n != Some(self.data.len()) {
            return bad(format!("{} values for {} × {} × {} voxels", self.data.len(), self.nx, self.ny, self.nz));
        }
        for (name, a) in [("x", self.x), ("y", self.y), ("z", self.z)] {
            if !(a.start.is_finite() && a.step.is_finite() && a.step != 0.0) {
                return bad(format!(
                    "axis {name} has start {} and step {} (finite, non-zero step needed)",
                    a.start, a.step
                ));
            }
        }
        if let Some(index) = self.data.iter().position(|v| !v.is_finite()) {
            return Err(InitError::NonFinite { what: "volume", index });
        }
        Ok(())
    }

    /// The depth column of `(ix, iy)`.
    ///
    /// # Panics
    /// When `ix >= nx` or `iy >= ny`.
    pub fn column(&self, ix: usize, iy: usize) -> &[f32] {
        assert!(ix < self.nx && iy < self.ny, "column ({ix}, {iy}) outside {} × {}", self.nx, self.ny);
        let c = ix + self.nx * iy;
        &self.data[c * self.nz..(c + 1) * self.nz]
    }

    /// Maximum over depth of every column: an `nx × ny` image, x fastest (the "front view").
    pub fn max_projection(&self) -> Vec<f32> {
        if self.nz == 0 {
            return vec![0.0; self.nx * self.ny];
        }
        self.data.chunks_exact(self.nz).map(|c| c.iter().copied().fold(f32::NEG_INFINITY, f32::max)).collect()
    }

    /// Per column, the depth (voxel centre, metres) of the maximum among the voxels whose depth lies in
    /// `[min_depth, max_depth]` (either bound optional), and that maximum: two `nx × ny` images, x fastest.
    ///
    /// # Errors
    /// [`InitError::Empty`] when no voxel depth lies in the window.
    pub fn depth_map(&self, min_depth: Option<f64>, max_depth: Option<f64>) -> Result<(Vec<f32>, Vec<f32>)> {
        let inside = |iz: usize| {
            let z = self.z.at(iz);
            min_depth.is_none_or(|m| z >= m) && max_depth.is_none_or(|m| z <= m)
        };
        let range: Vec<usize> = (0..self.nz).filter(|&iz| inside(iz)).collect();
        let (Some(&lo), Some(&hi)) = (range.first(), range.last()) else {
            return Err(InitError::Empty {
                what: format!(
                    "no voxel depth lies in the window [{min_depth:?}, {max_depth:?}] m (volume: {:.4}–{:.4} m); \
                     widen the depth window",
                    self.z.at(0),
                    self.z.at(self.nz.saturating_sub(1))
                ),
            });
        };
        let mut depth = Vec::with_capacity(self.nx * self.ny);
        let mut value = Vec::with_capacity(self.nx * self.ny);
        for col in self.data.chunks_exact(self.nz) {
            let (mut best, mut arg) = (f32::NEG_INFINITY, lo);
            for (iz, &v) in col.iter().enumerate().take(hi + 1).skip(lo) {
                if v > best {
                    best = v;
                    arg = iz;
                }
            }
            depth.push(self.z.at(arg) as f32);
            value.push(best);
        }
        Ok((depth, value))
    }

    /// The volume as a NumPy `.npy` file (format 1.0, little-endian `f32`, C order, shape `(ny, nx, nz)`),
    /// so that `np.load(f)[iy, ix, iz]` is voxel `(ix, iy, iz)`.
    pub fn to_npy(&self) -> Vec<u8> {
        let dict =
            format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, {}, {}), }}", self.ny, self.nx, self.nz);
        // Header length (magic 6 + version 2 + length 2 + dict + newline) padded to a multiple of 64.
        let unpadded = 10 + dict.len() + 1;
        let pad = (64 - unpadded % 64) % 64;
        let header_len = dict.len() + pad + 1;
        let mut out = Vec::with_capacity(10 + header_len + 4 * self.data.len());
        out.extend_from_slice(b"\x93NUMPY\x01\x00");
        out.extend_from_slice(&(header_len as u16).to_le_bytes());
        out.extend_from_slice(dict.as_bytes());
        out.extend(std::iter::repeat_n(b' ', pad));
        out.push(b'\n');
        for v in &self.data {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }
}
