//! The phasor field on a planar wall whose denser set of points is a grid: the sum over that set is a 2-D
//! convolution at each depth, done by the angular spectrum (Liu et al., "Phasor field diffraction based
//! reconstruction for fast non-line-of-sight imaging systems", Nat. Commun. 2020, Eq. 2–4; Goodman,
//! *Introduction to Fourier Optics*, Sec. 3.10).
//!
//! Per frequency `f` of the virtual pulse's band, the filtered histograms `Ĥ_{p,d}(f)` of each sparse point
//! `p` (the laser of a one-laser capture) over the dense grid `d` are a wave field on the wall; at depth `z`
//! the field `U_{p,f}(x) = Σ_d Ĥ_{p,d}(f) · K_{f,z}(x − d)` is `F⁻¹[F[Ĥ_{p,·}(f)] · exp(i z k_z)]` with
//! `k_z = √(k² − k_x² − k_y²)`, `k = 2πf` (`4πf` for a confocal scan, whose path is `2|x − d|`): the
//! Rayleigh–Sommerfeld kernel of the first kind, `K ∝ (z / r) · (1/r − ik) · e^{ikr} / r`. The sparse
//! point's leg is a phase at each voxel, and the frequencies sum to the focused wave at the time of
//! flight of the voxel:
//!
//! `I(x) = | Σ_f e^{i2πf(|x − p| − τ₀)} Σ_p U_{p,f}(x) |`, `τ₀` the path of the first bin's centre.
//!
//! Zero-padding to twice the grid keeps the circular convolution from wrapping for offsets within the
//! grid, and the spatial frequencies whose rays leave the padded window before depth `z` are dropped
//! (the band-limited angular spectrum, Matsushima & Shimobaba, Opt. Express 2009), so no ghost of the
//! other side of the grid enters. The kernel's `1/r` and `k` and the radiometric fall-off are compensated
//! in time, as LCT does: bin `τ` weighted by `(τ/2)^(2p+1)` (`p` = 2 diffuse, 1 retroreflective) and each
//! frequency divided by `f`; exact for a point straight in front of its spots, within a few per cent over
//! the scan's extent (`|x − l|·|x − s| ≤ (τ/2)²`). The cost is one padded 2-D FFT per depth, frequency and
//! sparse point, against the direct sum's `columns × measurements` per depth.

use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;
use realfft::RealFftPlanner;
use rustfft::num_complex::{Complex32, Complex64};
use rustfft::{Fft, FftPlanner};

use nlos_transient::{Layout, Transient};

use super::{Columns, Pulse, Window, fft_len, pulse_spectrum};
use crate::error::{InitError, Result};
use crate::volume::Axis;
use nlos_brdf::Model;

/// Relative height of the pulse's spectrum below which a frequency is left out.
const BAND_FLOOR: f64 = 1e-4;

/// The wall's geometry as the angular spectrum needs it.
pub(super) struct Planar {
    /// The dense grid's size and spacing (metres, absolute).
    nx: usize,
    ny: usize,
    dx: f64,
    dy: f64,
    /// Voxel columns' wall positions (the dense grid's points), `ix + nx·iy`.
    columns: Columns,
    /// The sparse points (empty for a confocal scan).
    sparse: Vec<DVec3>,
    /// Per measurement: (sparse point, dense point).
    index: Vec<(usize, usize)>,
}

impl Planar {
    /// The planar plan for `t`, when every wall point lies on z = 0 and the denser set (whose grid gave
    /// `columns`) is a regular grid; `None` otherwise (the direct sum takes it).
    pub(super) fn of(t: &Transient, columns: &Columns) -> Option<Self> {
        let scan = t.scan();
        let (lasers, sensors) = (scan.lasers(), scan.sensors());
        let flat = |p: &nlos_transient::PointSet| p.points.iter().all(|v| v.z.abs() < 1e-9);
        // A paired scan has one measurement per sparse point: one propagation each, slower than the direct sum.
        if !(flat(lasers) && flat(sensors)) || matches!(scan.pattern, nlos_transient::ScanPattern::Paired { .. }) {
            return None;
        }
        let lasers_dense = scan.lasers_are_dense();
        let dense = scan.dense_points();
        let Layout::Grid { nx, ny } = dense.layout else { return None };
        if nx != columns.nx || ny != columns.ny || dense.len() != nx * ny {
            return None;
        }
        let (dx, dy) = (columns.x.step.abs(), columns.y.step.abs());
        if scan.is_confocal() {
            let index = (0..scan.measurements()).map(|m| (0, m)).collect();
            return Some(Self { nx, ny, dx, dy, columns: *columns, sparse: Vec::new(), index });
        }
        let sparse_set = if lasers_dense { sensors } else { lasers };
        let sparse = sparse_set.points.iter().map(|p| p.as_dvec3()).collect();
        let index = (0..scan.measurements())
            .map(|m| {
                let (il, is) = scan.indices(m);
                if lasers_dense { (is, il) } else { (il, is) }
            })
            .collect();
        Some(Self { nx, ny, dx, dy, columns: *columns, sparse, index })
    }

    fn confocal(&self) -> bool {
        self.sparse.is_empty()
    }

    /// The volume's complex field, plane-major: `planes[iz·(nx·ny) + ix + nx·iy]`; its magnitudes are the
    /// volume.
    pub(super) fn focus(
        &self,
        t: &Transient,
        w: &Window,
        pulse: Pulse,
        reflectance: Model,
        z: Axis,
        nz: usize,
    ) -> Result<Vec<Complex32>> {
        let (nx, ny) = (self.nx, self.ny);
        let n_sparse = self.sparse.len().max(1);
        let (px, py) = (fft_size(2 * nx), fft_size(2 * ny));
        let band = Band::new(w, pulse);
        let fields = self.wall_fields(t, w, &band, reflectance, px, py)?;
        let mut planner = FftPlanner::<f32>::new();
        let ffts = Ffts { x: planner.plan_fft_inverse(px), y: planner.plan_fft_inverse(py) };
        // The frequencies in one contiguous range per thread; each thread sums into its own volume.
        let threads = rayon::current_num_threads().max(1);
        let chunk = band.freqs.len().div_ceil(threads).max(1);
        let columns = nx * ny;
        let planes = band
            .freqs
            .par_chunks(chunk)
            .enumerate()
            .map(|(c, freqs)| {
                let mut acc = vec![Complex32::new(0.0, 0.0); nz * columns];
                // The sparse points' phases at every voxel, stepped from one frequency to the next.
                let mut phases = (!self.confocal() && self.sparse.len() * nz * columns <= MAX_PHASE_TABLE)
                    .then(|| self.phases(freqs[0], band.df, band.tau0, z, nz));
                for (j, &f) in freqs.iter().enumerate() {
                    let jb = c * chunk + j;
                    let g = &fields[jb * n_sparse * px * py..(jb + 1) * n_sparse * px * py];
                    let wave = Wave { f, tau0: band.tau0, fields: g, phases: phases.as_ref() };
                    self.focus_frequency(&wave, &ffts, (px, py), z, &mut acc);
                    if let Some(p) = phases.as_mut() {
                        p.advance();
                    }
                }
                acc
            })
            .reduce_with(|mut a, b| {
                a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
                a
            })
            .unwrap_or_else(|| vec![Complex32::new(0.0, 0.0); nz * columns]);
        Ok(planes)
    }

    /// The phase `e^{i2πf(|x − p| − τ₀)}` of every sparse point `p` at every voxel `x`, at frequency `f`, and
    /// its factor for a step of `df`.
    fn phases(&self, f: f64, df: f64, tau0: f64, z: Axis, nz: usize) -> Phases {
        let (nx, ny) = (self.nx, self.ny);
        let n = self.sparse.len() * nz * nx * ny;
        let (mut cur, mut step) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let two_pi = 2.0 * std::f64::consts::PI;
        for p in &self.sparse {
            for iz in 0..nz {
                let dz2 = (z.at(iz) - p.z).powi(2);
                for iy in 0..ny {
                    let y = self.columns.y.at(iy) - p.y;
                    for ix in 0..nx {
                        let x = self.columns.x.at(ix) - p.x;
                        let path = (x * x + y * y + dz2).sqrt() - tau0;
                        let (a, b) = (
                            Complex64::from_polar(1.0, two_pi * f * path),
                            Complex64::from_polar(1.0, two_pi * df * path),
                        );
                        cur.push(Complex32::new(a.re as f32, a.im as f32));
                        step.push(Complex32::new(b.re as f32, b.im as f32));
                    }
                }
            }
        }
        Phases { cur, step }
    }

    /// Adds frequency `wave.f`'s focused wave at every depth to `acc` (plane-major, `acc[iz·columns + c]`);
    /// `wave.phases` holds the sparse points' phases at `f` (else they are computed here).
    fn focus_frequency(&self, wave: &Wave<'_>, ffts: &Ffts, (px, py): (usize, usize), z: Axis, acc: &mut [Complex32]) {
        let Wave { f, tau0, fields: g, phases } = *wave;
        let (nx, ny) = (self.nx, self.ny);
        let columns = nx * ny;
        let nz = acc.len() / columns;
        let k = if self.confocal() { 4.0 } else { 2.0 } * std::f64::consts::PI * f;
        // Per spatial frequency: k_z, and the depth beyond which its rays leave the padded window.
        let (lx, ly) = ((px - nx) as f64 * self.dx, (py - ny) as f64 * self.dy);
        let mut kz = vec![0.0f64; px * py];
        let mut z_limit = vec![0.0f64; px * py];
        for iy in 0..py {
            let ky = spatial_frequency(iy, py, self.dy);
            for ix in 0..px {
                let kx = spatial_frequency(ix, px, self.dx);
                let k2 = k * k - kx * kx - ky * ky;
                if k2 > 0.0 {
                    let q = k2.sqrt();
                    kz[iy * px + ix] = q;
                    let lim_x = if kx == 0.0 { f64::INFINITY } else { lx * q / kx.abs() };
                    let lim_y = if ky == 0.0 { f64::INFINITY } else { ly * q / ky.abs() };
                    z_limit[iy * px + ix] = lim_x.min(lim_y);
                }
            }
        }
        let mut transfer: Vec<Complex64> = kz.iter().map(|&q| Complex64::from_polar(1.0, q * z.start)).collect();
        let step: Vec<Complex64> = kz.iter().map(|&q| Complex64::from_polar(1.0, q * z.step)).collect();
        let mut buf = vec![Complex32::new(0.0, 0.0); px * py];
        let mut column = vec![Complex32::new(0.0, 0.0); py];
        let mut scratch =
            vec![Complex32::new(0.0, 0.0); ffts.x.get_inplace_scratch_len().max(ffts.y.get_inplace_scratch_len())];
        let two_pi_f = 2.0 * std::f64::consts::PI * f;
        let time_phase = Complex64::from_polar(1.0, -two_pi_f * tau0);
        for iz in 0..nz {
            let depth = z.at(iz);
            let plane = &mut acc[iz * columns..(iz + 1) * columns];
            for (sp, gs) in g.chunks_exact(px * py).enumerate() {
                for i in 0..px * py {
                    buf[i] = if kz[i] > 0.0 && depth <= z_limit[i] {
                        let t = transfer[i];
                        gs[i] * Complex32::new(t.re as f32, t.im as f32)
                    } else {
                        Complex32::new(0.0, 0.0)
                    };
                }
                ifft2(&mut buf, (px, py), (nx, ny), ffts, &mut column, &mut scratch);
                if self.confocal() {
                    let ph = Complex32::new(time_phase.re as f32, time_phase.im as f32);
                    for iy in 0..ny {
                        for ix in 0..nx {
                            plane[ix + nx * iy] += ph * buf[iy * px + ix];
                        }
                    }
                } else if let Some(ph) = phases {
                    let row = &ph.cur[(sp * nz + iz) * columns..(sp * nz + iz + 1) * columns];
                    for iy in 0..ny {
                        let (out, phase) = (&mut plane[nx * iy..nx * (iy + 1)], &row[nx * iy..nx * (iy + 1)]);
                        for ((o, p), b) in out.iter_mut().zip(phase).zip(&buf[iy * px..iy * px + nx]) {
                            *o += p * b;
                        }
                    }
                } else {
                    let p = self.sparse[sp];
                    for iy in 0..ny {
                        let y = self.columns.y.at(iy) - p.y;
                        for ix in 0..nx {
                            let x = self.columns.x.at(ix) - p.x;
                            let r = (x * x + y * y + (depth - p.z).powi(2)).sqrt();
                            let ph = Complex64::from_polar(1.0, two_pi_f * (r - tau0));
                            plane[ix + nx * iy] += Complex32::new(ph.re as f32, ph.im as f32) * buf[iy * px + ix];
                        }
                    }
                }
            }
            for (t, s) in transfer.iter_mut().zip(&step) {
                *t *= s;
            }
        }
    }

    /// Each (frequency, sparse point)'s weighted, filtered field over the dense grid, zero-padded to
    /// `px × py` and 2-D Fourier transformed: `fields[((jb·n_sparse + sp)·py + iy)·px + ix]`.
    fn wall_fields(
        &self,
        t: &Transient,
        w: &Window,
        band: &Band,
        reflectance: Model,
        px: usize,
        py: usize,
    ) -> Result<Vec<Complex32>> {
        let (nx, ny) = (self.nx, self.ny);
        let n_sparse = self.sparse.len().max(1);
        let power = reflectance.distance_power() as i32 + 1;
        // Time weights (module docs): (τ/2)^(2p+1) at each bin's centre.
        let weights: Vec<f32> = (0..w.len)
            .map(|k| {
                let tau = w.t0 + (w.first + k) as f64 * w.delta + 0.5 * w.delta;
                (0.5 * tau).max(0.0).powi(power) as f32
            })
            .collect();
        let r2c = RealFftPlanner::<f32>::new().plan_fft_forward(band.n);
        let nb = band.freqs.len();
        // Band spectra per measurement: spectra[m·nb + jb].
        let mut spectra = vec![Complex32::new(0.0, 0.0); t.measurements() * nb];
        let bad = std::sync::atomic::AtomicUsize::new(usize::MAX);
        spectra.par_chunks_mut(nb).enumerate().for_each_init(
            || (r2c.make_input_vec(), r2c.make_output_vec()),
            |(input, spectrum), (m, out)| {
                let h = &t.histogram(m)[w.first..w.first + w.len];
                if let Some(i) = h.iter().position(|v| !v.is_finite()) {
                    bad.fetch_min(m * t.bins() + w.first + i, std::sync::atomic::Ordering::Relaxed);
                    return;
                }
                for ((i, v), wt) in input.iter_mut().zip(h).zip(&weights) {
                    *i = v * wt;
                }
                input[w.len..].fill(0.0);
                // Lengths match the plan by construction, so this cannot fail.
                let _ = r2c.process(input, spectrum);
                for ((o, &j), &g) in out.iter_mut().zip(&band.bins).zip(&band.gain) {
                    *o = spectrum[j] * g;
                }
            },
        );
        if let Some(index) = Some(bad.into_inner()).filter(|&i| i != usize::MAX) {
            return Err(InitError::NonFinite { what: "transient data", index });
        }
        let mut planner = FftPlanner::<f32>::new();
        let (fx, fy) = (planner.plan_fft_forward(px), planner.plan_fft_forward(py));
        let mut fields = vec![Complex32::new(0.0, 0.0); nb * n_sparse * px * py];
        let index = &self.index;
        fields.par_chunks_mut(px * py).enumerate().for_each_init(
            || vec![Complex32::new(0.0, 0.0); py],
            |column, (i, field)| {
                let (jb, sp) = (i / n_sparse, i % n_sparse);
                for (m, &(s, d)) in index.iter().enumerate() {
                    if s == sp {
                        field[(d / nx) * px + d % nx] = spectra[m * nb + jb];
                    }
                }
                for row in field.chunks_exact_mut(px).take(ny) {
                    fx.process(row);
                }
                for ix in 0..px {
                    for (iy, c) in column.iter_mut().enumerate() {
                        *c = field[iy * px + ix];
                    }
                    fy.process(column);
                    for (iy, c) in column.iter().enumerate() {
                        field[iy * px + ix] = *c;
                    }
                }
            },
        );
        Ok(fields)
    }
}

/// The inverse 2-D FFT of `buf` (`px × py`, row-major), computed only as far as the `nx × ny` corner
/// that is read back: all columns, then the first `ny` rows.
fn ifft2(
    buf: &mut [Complex32],
    (px, py): (usize, usize),
    (_nx, ny): (usize, usize),
    ffts: &Ffts,
    column: &mut [Complex32],
    scratch: &mut [Complex32],
) {
    for ix in 0..px {
        for (iy, c) in column.iter_mut().enumerate() {
            *c = buf[iy * px + ix];
        }
        ffts.y.process_with_scratch(column, scratch);
        for (iy, c) in column.iter().enumerate().take(ny) {
            buf[iy * px + ix] = *c;
        }
    }
    debug_assert_eq!(column.len(), py);
    for row in buf.chunks_exact_mut(px).take(ny) {
        ffts.x.process_with_scratch(row, scratch);
    }
}

/// The largest phase table ([`Phases`]) a thread keeps, in complex values (64 MiB each for the phases and
/// their steps); beyond it the phases are computed at every frequency.
const MAX_PHASE_TABLE: usize = 1 << 23;

/// The sparse points' phases at every voxel (`[(sp·nz + iz)·columns + c]`) at one frequency, and the factor
/// that takes each to the next frequency of the band (consecutive FFT frequencies, `df` apart).
struct Phases {
    cur: Vec<Complex32>,
    step: Vec<Complex32>,
}

impl Phases {
    fn advance(&mut self) {
        for (c, s) in self.cur.iter_mut().zip(&self.step) {
            *c *= s;
        }
    }
}

/// The inverse FFT plans along x and y.
struct Ffts {
    x: Arc<dyn Fft<f32>>,
    y: Arc<dyn Fft<f32>>,
}

/// One frequency of the virtual wave as [`Planar::focus`] sums it: the frequency `f` (cycles per metre of
/// path), the band's time origin `tau0`, its fields on the wall (`n_sparse × px × py`) and, where tabulated,
/// the sparse points' phases at `f`.
struct Wave<'a> {
    f: f64,
    tau0: f64,
    fields: &'a [Complex32],
    phases: Option<&'a Phases>,
}

/// The frequencies of the virtual pulse's band on the time FFT's grid.
struct Band {
    /// The time FFT's length.
    n: usize,
    /// Their indices on the real FFT's output.
    bins: Vec<usize>,
    /// Their frequencies (cycles per metre of path).
    freqs: Vec<f64>,
    /// The pulse's spectrum there, divided by the frequency and the FFT's length (module docs).
    gain: Vec<Complex32>,
    /// The path of the first bin's centre (metres).
    tau0: f64,
    /// The spacing of the FFT's frequencies (cycles per metre): consecutive entries of `freqs` are this apart.
    df: f64,
}

impl Band {
    fn new(w: &Window, pulse: Pulse) -> Self {
        let Pulse { wavelength, sigma } = pulse;
        let n = fft_len(w.len, sigma, w.delta);
        let fc = 1.0 / wavelength;
        let (mut bins, mut freqs, mut gain) = (Vec::new(), Vec::new(), Vec::new());
        for j in 1..n / 2 {
            let f = j as f64 / (n as f64 * w.delta);
            let g = pulse_spectrum(f, fc, sigma);
            if g >= BAND_FLOOR {
                bins.push(j);
                freqs.push(f);
                gain.push(Complex32::new((g / (f * n as f64)) as f32, 0.0));
            }
        }
        let tau0 = w.t0 + (w.first as f64 + 0.5) * w.delta;
        Self { n, bins, freqs, gain, tau0, df: 1.0 / (n as f64 * w.delta) }
    }
}

/// The angular spatial frequency of FFT index `i` of `n` samples `d` apart.
fn spatial_frequency(i: usize, n: usize, d: f64) -> f64 {
    let j = if i <= n / 2 { i as f64 } else { i as f64 - n as f64 };
    2.0 * std::f64::consts::PI * j / (n as f64 * d)
}

/// The smallest size ≥ `n` whose factors are 2, 3 and 5 (rustfft's fast sizes).
fn fft_size(n: usize) -> usize {
    (n..)
        .find(|&m| {
            let mut m = m;
            for p in [2, 3, 5] {
                while m % p == 0 {
                    m /= p;
                }
            }
            m == 1
        })
        .unwrap_or(n)
}
