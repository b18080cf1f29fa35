//! f-k migration (Lindell, Wetzstein & O'Toole, "Wave-based non-line-of-sight imaging using fast f-k
//! migration", ACM Trans. Graph. 38(4), SIGGRAPH 2019).
//!
//! The confocal measurements, weighted by `t²` and square-rooted (the reference's
//! `data = sqrt(data .* grid_z.^2)`), are treated as a wavefield recorded at z = 0 by sources that
//! explode at t = 0 and travel at half speed. In the Fourier domain the wavefield at depth z follows from
//! the one at the wall by Stolt's change of variables (their Eq. 9–10):
//! `Φ(k_x, k_y, k_z) = k_z / √(k_x² + k_y² + k_z²) · Ψ(k_x, k_y, f_t = √(k_x² + k_y² + k_z²) / 2)` for
//! `k_z > 0`, with `f_t` the temporal frequency in cycles per metre of path and the `k` in cycles per
//! metre of depth. The volume is `|F⁻¹ Φ|²`, unpadded.
//!
//! Discretisation: data padded to `2nx × 2ny × 2M`; time-frequency index `q` and depth-frequency index
//! `j` on the same `2M` grid relate by `q = √((MΔ)²(f_x² + f_y²) + j²)` (`Δ` the bin width, `f_x =
//! i_x / (2nx·dx)`), which is the reference's `sqrt(((N·range)/(M·width·4))²(x² + y²) + z²)` with the
//! true grid spacing; `Ψ` is interpolated linearly in `q` (zero beyond the last frequency), as the
//! reference's `interpn(…, 'linear', 0)`. Voxel `iz` sits at depth `(iz + ½)·Δ/2`.

use rayon::prelude::*;
use rustfft::FftPlanner;
use rustfft::num_complex::Complex32;

use nlos_transient::Transient;

use crate::error::Result;
use crate::fft::{self, Dims};
use crate::lct::volume_from_grid;
use crate::prep::{self, ConfocalGrid, Gate};
use crate::volume::Volume;

/// Parameters of [`fk`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FkParams {
    /// Sum this many consecutive bins before reconstructing (≥ 1; default 1 = none).
    pub bin_merge: usize,
    /// Removal of the direct light. Default [`Gate::Auto`].
    pub gate: Gate,
    /// Ignore path lengths beyond `2 × max_depth` (metres; default `None` = the whole axis).
    pub max_depth: Option<f64>,
}

impl Default for FkParams {
    fn default() -> Self {
        Self { bin_merge: 1, gate: Gate::Auto, max_depth: None }
    }
}

/// Reconstructs a volume from a confocal grid capture with f-k (Stolt) migration.
///
/// # Errors
/// As [`crate::lct()`] (the input requirements are the same).
pub fn fk(t: &Transient, params: &FkParams) -> Result<Volume> {
    let g = prep::prepare(t, "f-k migration", params.gate, params.max_depth, params.bin_merge)?;
    let data = fk_grid(&g);
    Ok(volume_from_grid(&g, data))
}

fn fk_grid(g: &ConfocalGrid) -> Vec<f32> {
    let (nx, ny) = (g.nx, g.ny);
    let m = prep::next_fast_len(g.bins);
    let d = Dims::new(2 * nx, 2 * ny, 2 * m);
    // Step 0: radiometric weight t², square root (negative counts, e.g. from background subtraction,
    // are clamped to 0 so the root stays real).
    let mut w = vec![0.0f32; nx * ny * m];
    w.par_chunks_mut(m).zip(g.data.par_chunks_exact(g.bins)).for_each(|(o, src)| {
        for (k, v) in src.iter().enumerate() {
            let tk = (k as f64 + 0.5) / m as f64;
            o[k] = (v.max(0.0) * (tk * tk) as f32).sqrt();
        }
    });
    // Step 1: FFT (real along t: the Stolt map only reads non-negative temporal frequencies).
    let lanes = fft::rfft_lanes(&d, &w, m);
    drop(w);
    let mut planes = fft::lanes_to_planes(&d, &lanes, ny, nx);
    drop(lanes);
    fft::forward_xy(&d, &mut planes, ny);
    let mut lanes = fft::planes_to_lanes(&d, &planes, d.py, d.px);
    drop(planes);
    // Step 2: Stolt interpolation, one (k_x, k_y) lane at a time.
    let (px, py, nf) = (d.px, d.py, d.nf);
    let range = m as f64 * g.delta;
    let (dx, dy) = (g.dx.abs(), g.dy.abs());
    lanes.par_chunks_mut(nf).enumerate().for_each_init(
        || vec![Complex32::new(0.0, 0.0); nf],
        |src, (c, lane)| {
            src.copy_from_slice(lane);
            let fx = fft::signed(c % px, px) / (px as f64 * dx);
            let fy = fft::signed(c / px, py) / (py as f64 * dy);
            let lateral = range * range * (fx * fx + fy * fy);
            lane[0] = Complex32::new(0.0, 0.0);
            for (j, o) in lane.iter_mut().enumerate().skip(1) {
                let q = (lateral + (j * j) as f64).sqrt();
                // j = nf − 1 is the Nyquist depth frequency, which has no positive-only counterpart: zero,
                // as the reference (whose grid ends at M − 1).
                *o = if j + 1 < nf && q <= (nf - 1) as f64 {
                    let i0 = q.floor() as usize;
                    let wt = (q - i0 as f64) as f32;
                    let v = if i0 + 1 < nf { src[i0] * (1.0 - wt) + src[i0 + 1] * wt } else { src[i0] };
                    // q ≥ j ≥ 1, so the Jacobian j/q is well defined.
                    v * (j as f64 / q) as f32
                } else {
                    Complex32::new(0.0, 0.0)
                };
            }
        },
    );
    let mut planes = fft::lanes_to_planes(&d, &lanes, py, px);
    drop(lanes);
    // Step 3: inverse FFT (complex along depth: the spectrum is one-sided), |·|², unpad.
    fft::inverse_xy(&d, &mut planes, ny);
    let lanes = fft::planes_to_lanes(&d, &planes, ny, nx);
    drop(planes);
    let ifft = FftPlanner::<f32>::new().plan_fft_inverse(d.pz);
    let scale = 1.0 / (d.px * d.py * d.pz) as f32;
    let mut out = vec![0.0f32; nx * ny * g.bins];
    out.par_chunks_mut(g.bins).zip(lanes.par_chunks(nf)).for_each_init(
        || (vec![Complex32::new(0.0, 0.0); d.pz], vec![Complex32::new(0.0, 0.0); ifft.get_inplace_scratch_len()]),
        |(buf, scratch), (o, lane)| {
            buf[..nf].copy_from_slice(lane);
            buf[nf..].fill(Complex32::new(0.0, 0.0));
            ifft.process_with_scratch(buf, scratch);
            for (a, b) in o.iter_mut().zip(buf.iter()) {
                *a = (b * scale).norm_sqr();
            }
        },
    );
    out
}
