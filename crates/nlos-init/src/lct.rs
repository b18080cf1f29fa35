//! The light-cone transform (O'Toole, Lindell & Wetzstein, "Confocal non-line-of-sight imaging based on
//! the light-cone transform", Nature 555, 2018).
//!
//! For a confocal scan, the transient at wall point `(x', y')` is (their Eq. 2–4)
//! `τ(x', y', t) = ∭ ρ(x, y, z) / r^{2k} · δ(2r − t) dx dy dz`, `r = √((x'−x)² + (y'−y)² + z²)`,
//! with `k = 1` for retroreflective and `k = 2` for diffuse surfaces (`t` in metres of path, our convention).
//! Scaling the data by `t^{2k}` and substituting `u = t²`, `v = z²` turns this into a 3-D convolution
//! `R_t{t^{2k} τ} = h ∗ R_z{ρ}` with the shift-invariant kernel `h(x, y, u) = δ(4(x² + y²) + v − u)` (a
//! cone). Inversion: `ρ = R_z⁻¹ F⁻¹[ conj(Ĥ) / (|Ĥ|² + 1/snr) · F R_t{t^{2k} τ} ]` (their Eq. 6, a
//! Wiener filter), computed with FFTs on a volume zero-padded to twice its size in x, y and u.
//!
//! Implementation choices (following the reference `cnlos_reconstruction.m` where it is explicit):
//! - the resampling `t → u = t²` is the reference's `resamplingOperator`, written out: u-bin `i` averages
//!   the `M` fine samples `x = iM+1 … (i+1)M` of `u = x/M²`, each taking time bin `⌈√x⌉` with weight
//!   `1/√x`; its transpose resamples back (the reference's `mtxi`). We build it for any `M`, not only
//!   powers of two;
//! - the kernel has one non-zero per (x, y) column, at the u-bin nearest `4 r² M / T²` (`T = M·Δ` the
//!   path range, r from the true grid spacing), normalised to unit L2 norm as in the reference (which
//!   makes `snr` comparable with theirs); columns whose cone leaves the padded range are empty;
//! - the radiometric weight uses the bin centre `((k + ½)/M)^{2k}` instead of `linspace(0, 1, M)`;
//! - the result is clamped at 0 (`max(real(vol), 0)`), and voxel `iz` sits at depth `(iz + ½)·Δ/2`.

use rayon::prelude::*;
use realfft::RealFftPlanner;
use rustfft::num_complex::Complex32;

use nlos_brdf::Model;
use nlos_transient::Transient;

use crate::error::{InitError, Result};
use crate::fft::{self, Dims};
use crate::prep::{self, ConfocalGrid, Gate};
use crate::volume::{Axis, Volume};

/// Parameters of [`lct`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LctParams {
    /// Signal-to-noise ratio of the Wiener filter (> 0). Default 0.1; the reference code uses 0.08–0.8
    /// depending on the scene. Larger values sharpen and amplify noise.
    pub snr: f64,
    /// The reflectance model the data are weighted for: by `t` to its [`Model::distance_power`] (`t⁴` for
    /// Lambertian and GGX surfaces, `t²` for retroreflective ones). Default [`Model::Lambert`].
    pub reflectance: Model,
    /// Sum this many consecutive bins before reconstructing (≥ 1; default 1 = none). The reference
    /// merges 4 bins of the 4 ps Stanford captures (`K = 2`), which is 16× faster and as sharp.
    pub bin_merge: usize,
    /// Removal of the direct light. Default [`Gate::Auto`].
    pub gate: Gate,
    /// Ignore path lengths beyond `2 × max_depth` (metres; default `None` = the whole axis).
    pub max_depth: Option<f64>,
    /// Use the adjoint (`conj(Ĥ)`) instead of the Wiener inverse: the LCT's fast backprojection.
    pub backprojection: bool,
    /// Clamp the volume at 0, as the reference does (`max(real(vol), 0)`; default). Off, the volume is the
    /// transform's real part, signed and linear in the data: the volume of a difference is the difference of
    /// the volumes (a residual back-projected, [`crate::Method::signed_volume`]).
    pub clamp: bool,
}

impl Default for LctParams {
    fn default() -> Self {
        Self {
            snr: 0.1,
            reflectance: Model::Lambert,
            bin_merge: 1,
            gate: Gate::Auto,
            max_depth: None,
            backprojection: false,
            clamp: true,
        }
    }
}

/// The reference's `resamplingOperator` (`mtx`), one sparse row per u-bin: `(time bin, weight)`.
#[derive(Debug, Clone)]
pub(crate) struct Resampler {
    rows: Vec<Vec<(u32, f32)>>,
}

impl Resampler {
    pub fn new(m: usize) -> Self {
        let rows = (0..m)
            .map(|i| {
                let mut row: Vec<(u32, f32)> = Vec::new();
                let mut acc = 0.0f64;
                let mut col = usize::MAX;
                for x in i * m + 1..=(i + 1) * m {
                    // ⌈√x⌉ − 1 in exact integer arithmetic (isqrt), 0-based time bin < m.
                    let s = x.isqrt();
                    let c = if s * s == x { s - 1 } else { s };
                    if c != col {
                        if col != usize::MAX {
                            row.push((col as u32, (acc / m as f64) as f32));
                        }
                        col = c;
                        acc = 0.0;
                    }
                    acc += 1.0 / (x as f64).sqrt();
                }
                row.push((col as u32, (acc / m as f64) as f32));
                row
            })
            .collect();
        Self { rows }
    }

    /// `u = A · t` for one lane.
    pub fn forward(&self, t: &[f32], u: &mut [f32]) {
        for (o, row) in u.iter_mut().zip(&self.rows) {
            *o = row.iter().map(|&(c, w)| w * t[c as usize]).sum();
        }
    }

    /// `t = Aᵀ · u` for one lane.
    pub fn adjoint(&self, u: &[f32], t: &mut [f32]) {
        t.fill(0.0);
        for (&v, row) in u.iter().zip(&self.rows) {
            for &(c, w) in row {
                t[c as usize] += w * v;
            }
        }
    }
}

/// Reconstructs an albedo volume from a confocal grid capture with the light-cone transform.
///
/// The volume has the scan's `nx × ny` columns and one voxel per (merged) time bin, at depth
/// `(iz + ½)·Δ/2` (half the bin-centre path length, `Δ` the merged bin width).
///
/// # Errors
/// [`InitError::NotConfocal`], [`InitError::NotGrid`], [`InitError::BadGrid`], [`InitError::DeviceLegs`],
/// [`InitError::TimeOrigin`], [`InitError::InvalidParameter`] (snr, bin_merge, gate, max_depth),
/// [`InitError::Empty`], [`InitError::NonFinite`].
///
/// # Example
/// ```
/// use nlos_init::{lct, LctParams, Gate};
/// use nlos_transient::{PointSet, Scan, TimeAxis, Transient};
/// let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.2, 0.2)?);
/// let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.01, 64)?)?;
/// t.histogram_mut(27)[60] = 1.0;
/// let vol = lct(&t, &LctParams { gate: Gate::None, ..LctParams::default() })?;
/// assert_eq!((vol.nx, vol.ny, vol.nz), (8, 8, 64));
/// # Ok::<(), nlos_init::InitError>(())
/// ```
pub fn lct(t: &Transient, params: &LctParams) -> Result<Volume> {
    if !(params.snr.is_finite() && params.snr > 0.0) {
        return Err(InitError::InvalidParameter { name: "snr", value: params.snr, reason: "must be finite and > 0" });
    }
    let g = prep::prepare(t, "LCT", params.gate, params.max_depth, params.bin_merge)?;
    let data = lct_grid(&g, params, false);
    Ok(volume_from_grid(&g, data))
}

pub(crate) fn volume_from_grid(g: &ConfocalGrid, data: Vec<f32>) -> Volume {
    Volume {
        nx: g.nx,
        ny: g.ny,
        nz: g.bins,
        x: Axis { start: g.x0, step: g.dx },
        y: Axis { start: g.y0, step: g.dy },
        z: Axis { start: 0.25 * g.delta, step: 0.5 * g.delta },
        data,
    }
}

/// The LCT pipeline; with `laplacian`, the negative second difference along u is taken before resampling
/// back to t (filtered backprojection, see [`crate::fbp()`]).
pub(crate) fn lct_grid(g: &ConfocalGrid, params: &LctParams, laplacian: bool) -> Vec<f32> {
    let (nx, ny) = (g.nx, g.ny);
    // Pad the time axis to a fast FFT size; the extra bins are zero and extend the range T.
    let m = prep::next_fast_len(g.bins);
    let d = Dims::new(2 * nx, 2 * ny, 2 * m);
    let power = params.reflectance.distance_power() as i32;
    let resampler = Resampler::new(m);
    // Steps 1–2: radiometric weight and t → u resampling, one lane per scan point.
    let mut u = vec![0.0f32; nx * ny * m];
    u.par_chunks_mut(m).zip(g.data.par_chunks_exact(g.bins)).for_each_init(
        || vec![0.0f32; m],
        |tl, (ul, src)| {
            for (k, o) in tl.iter_mut().enumerate() {
                let w = ((k as f64 + 0.5) / m as f64).powi(power) as f32;
                *o = if k < src.len() { src[k] * w } else { 0.0 };
            }
            resampler.forward(tl, ul);
        },
    );
    // Step 3: FFT convolution with the (inverse) kernel.
    let lanes = fft::rfft_lanes(&d, &u, m);
    drop(u);
    let mut planes = fft::lanes_to_planes(&d, &lanes, ny, nx);
    drop(lanes);
    fft::forward_xy(&d, &mut planes, ny);
    let kernel = psf_spectrum(&d, g.dx.abs(), g.dy.abs(), m, g.delta);
    let inv_snr = (1.0 / params.snr) as f32;
    let backprojection = params.backprojection;
    planes.par_chunks_mut(4096).zip(kernel.par_chunks(4096)).for_each(|(x, h)| {
        for (a, b) in x.iter_mut().zip(h) {
            let filt = if backprojection { b.conj() } else { b.conj() / (b.norm_sqr() + inv_snr) };
            *a *= filt;
        }
    });
    drop(kernel);
    fft::inverse_xy(&d, &mut planes, ny);
    let mut lanes = fft::planes_to_lanes(&d, &planes, ny, nx);
    drop(planes);
    // Step 4: inverse real FFT along u, unpad, resample back to t, clamp.
    let c2r = RealFftPlanner::<f32>::new().plan_fft_inverse(d.pz);
    let scale = 1.0 / (d.px * d.py * d.pz) as f32;
    let mut out = vec![0.0f32; nx * ny * g.bins];
    let clamp = params.clamp;
    out.par_chunks_mut(g.bins).zip(lanes.par_chunks_mut(d.nf)).for_each_init(
        || (c2r.make_output_vec(), c2r.make_scratch_vec(), vec![0.0f32; m], vec![0.0f32; m]),
        |(real, scratch, ul, tl), (o, lane)| {
            // The product of Hermitian spectra is Hermitian: the DC and Nyquist terms are real up to
            // rounding, and the c2r transform requires them exactly real.
            lane[0].im = 0.0;
            lane[d.nf - 1].im = 0.0;
            let _ = c2r.process_with_scratch(lane, real, scratch);
            for (a, b) in ul.iter_mut().zip(real.iter()) {
                *a = b * scale;
            }
            if laplacian {
                // −∂²/∂u² as the square of the central difference, (2v[i] − v[i−2] − v[i+2]) / 4: it
                // passes no Nyquist component (the three-point rule amplifies it fourfold, which turns
                // the discretisation ripple of the backprojection into a spurious comb). Undefined (0)
                // within two bins of either end, where a zero extension would make a spike.
                tl.fill(0.0);
                for i in 2..m.saturating_sub(2) {
                    tl[i] = 0.25 * (2.0 * ul[i] - ul[i - 2] - ul[i + 2]);
                }
                ul.copy_from_slice(tl);
            }
            resampler.adjoint(ul, tl);
            for (a, &b) in o.iter_mut().zip(tl.iter()) {
                *a = if clamp { b.max(0.0) } else { b };
            }
        },
    );
    out
}

/// Spectrum (planes layout) of the LCT kernel on the padded grid, computed analytically along u: a
/// column with its single non-zero at u-bin `q` has the real-FFT lane `a·exp(−2πi q f / pz)`.
fn psf_spectrum(d: &Dims, dx: f64, dy: f64, m: usize, delta: f64) -> Vec<Complex32> {
    let (px, py) = (d.px, d.py);
    // u-bin of the cone at lateral offset r: u = (t/T)² with T = m·Δ, shifted by 4r²/T², times m bins.
    let shift = |ix: usize, iy: usize| {
        let (ox, oy) = (fft::signed(ix, px) * dx, fft::signed(iy, py) * dy);
        let q = (4.0 * (ox * ox + oy * oy) / (m as f64 * delta * delta)).round();
        (q < d.pz as f64).then_some(q as usize)
    };
    let count =
        (0..py).flat_map(|iy| (0..px).map(move |ix| (ix, iy))).filter(|&(ix, iy)| shift(ix, iy).is_some()).count();
    // The zero-offset column always contributes, so count ≥ 1.
    let a = 1.0 / (count.max(1) as f64).sqrt();
    // Twiddle table e^{−2πi k/pz}: the phase of bin f is entry (q·f mod pz), reduced in integers so it
    // stays exact (no sin/cos per voxel).
    let twiddle: Vec<Complex32> = (0..d.pz)
        .map(|k| {
            let phase = -2.0 * std::f64::consts::PI * k as f64 / d.pz as f64;
            Complex32::new((a * phase.cos()) as f32, (a * phase.sin()) as f32)
        })
        .collect();
    // Written straight into the planes layout (one py × px plane per frequency f), which saves a
    // lanes-sized buffer and its transpose. Columns whose cone leaves the range stay zero.
    let shifts: Vec<Option<usize>> = (0..px * py).map(|c| shift(c % px, c / px)).collect();
    let plane = px * py;
    let mut planes = vec![Complex32::new(0.0, 0.0); d.nf * plane];
    planes.par_chunks_mut(plane).enumerate().for_each(|(f, pl)| {
        for (v, q) in pl.iter_mut().zip(&shifts) {
            if let Some(q) = q {
                // (q·f) mod pz in integers: exact phase, no sin/cos per voxel.
                *v = twiddle[(q * f) % d.pz];
            }
        }
    });
    fft::forward_xy(d, &mut planes, py);
    planes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampler_rows_cover_every_fine_sample() {
        let m = 16;
        let r = Resampler::new(m);
        // Σ over all rows and entries of the weights = Σ_x 1/√x / m.
        let total: f64 = r.rows.iter().flatten().map(|&(_, w)| w as f64).sum();
        let expect: f64 = (1..=m * m).map(|x| 1.0 / (x as f64).sqrt()).sum::<f64>() / m as f64;
        assert!((total - expect).abs() < 1e-4 * expect);
        // u-bin i maps to time bins near √(i/m)·m.
        for (i, row) in r.rows.iter().enumerate() {
            let lo = ((i * m + 1) as f64).sqrt().ceil() as u32 - 1;
            assert_eq!(row[0].0, lo);
        }
    }
}
