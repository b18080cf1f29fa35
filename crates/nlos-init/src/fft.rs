//! 3-D FFT machinery on zero-padded volumes.
//!
//! A padded volume of `px × py × pz` (x, y, time) is transformed with a real FFT along time first (only
//! the lanes that hold data), then complex FFTs along x and y on each frequency plane. Planes are stored
//! `planes[f·py·px + iy·px + ix]` (one contiguous `py × px` plane per time frequency `f`), lanes
//! `lanes[(iy·lx + ix)·nf + f]`. Work is parallel over planes and lanes with rayon.

use std::sync::Arc;

use rayon::prelude::*;
use realfft::RealFftPlanner;
use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};

/// Sizes of a zero-padded 3-D transform.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Dims {
    /// Padded size along x.
    pub px: usize,
    /// Padded size along y.
    pub py: usize,
    /// Padded size along time.
    pub pz: usize,
    /// Time frequencies kept by the real FFT: `pz / 2 + 1`.
    pub nf: usize,
}

impl Dims {
    pub fn new(px: usize, py: usize, pz: usize) -> Self {
        Self { px, py, pz, nf: pz / 2 + 1 }
    }
    fn plane(&self) -> usize {
        self.px * self.py
    }
}

/// Frequency planes per parallel block: 8 × 8 bytes = one cache line per lane read.
const FB: usize = 8;

/// Real FFT along time of `lanes` lanes of `len <= pz` samples each (zero-padded to `pz`).
pub(crate) fn rfft_lanes(d: &Dims, data: &[f32], len: usize) -> Vec<Complex32> {
    let r2c = RealFftPlanner::<f32>::new().plan_fft_forward(d.pz);
    let n_lanes = data.len() / len;
    let mut out = vec![Complex32::new(0.0, 0.0); n_lanes * d.nf];
    out.par_chunks_mut(d.nf).zip(data.par_chunks_exact(len)).for_each_init(
        || (r2c.make_input_vec(), r2c.make_scratch_vec()),
        |(input, scratch), (o, src)| {
            input[..len].copy_from_slice(src);
            input[len..].fill(0.0);
            // Lengths match the plan by construction, so this cannot fail.
            let _ = r2c.process_with_scratch(input, o, scratch);
        },
    );
    out
}

/// Scatters lanes (`ly × lx` of them, at the origin of the padded grid) into zeroed planes.
pub(crate) fn lanes_to_planes(d: &Dims, lanes: &[Complex32], ly: usize, lx: usize) -> Vec<Complex32> {
    let plane = d.plane();
    let nf = d.nf;
    let mut planes = vec![Complex32::new(0.0, 0.0); nf * plane];
    planes.par_chunks_mut(FB * plane).enumerate().for_each(|(b, block)| {
        let f0 = b * FB;
        let nb = block.len() / plane;
        for iy in 0..ly {
            for ix in 0..lx {
                let src = &lanes[(iy * lx + ix) * nf + f0..(iy * lx + ix) * nf + f0 + nb];
                for (k, v) in src.iter().enumerate() {
                    block[k * plane + iy * d.px + ix] = *v;
                }
            }
        }
    });
    planes
}

/// Gathers the lanes of the `ly × lx` corner of the planes.
pub(crate) fn planes_to_lanes(d: &Dims, planes: &[Complex32], ly: usize, lx: usize) -> Vec<Complex32> {
    let plane = d.plane();
    let nf = d.nf;
    let mut lanes = vec![Complex32::new(0.0, 0.0); ly * lx * nf];
    lanes.par_chunks_mut(lx * nf).enumerate().for_each(|(iy, row)| {
        for f in 0..nf {
            let src = &planes[f * plane + iy * d.px..f * plane + iy * d.px + lx];
            for (ix, v) in src.iter().enumerate() {
                row[ix * nf + f] = *v;
            }
        }
    });
    lanes
}

struct PlaneFfts {
    x: Arc<dyn Fft<f32>>,
    y: Arc<dyn Fft<f32>>,
}

fn plan(d: &Dims, inverse: bool) -> PlaneFfts {
    let mut p = FftPlanner::<f32>::new();
    if inverse {
        PlaneFfts { x: p.plan_fft_inverse(d.px), y: p.plan_fft_inverse(d.py) }
    } else {
        PlaneFfts { x: p.plan_fft_forward(d.px), y: p.plan_fft_forward(d.py) }
    }
}

/// FFT along y of every column of a `py × px` plane (through a transpose into `t`).
fn fft_columns(d: &Dims, plane: &mut [Complex32], t: &mut [Complex32], fft: &dyn Fft<f32>, scratch: &mut [Complex32]) {
    let (px, py) = (d.px, d.py);
    for iy in 0..py {
        for ix in 0..px {
            t[ix * py + iy] = plane[iy * px + ix];
        }
    }
    fft.process_with_scratch(t, scratch);
    for ix in 0..px {
        for iy in 0..py {
            plane[iy * px + ix] = t[ix * py + iy];
        }
    }
}

fn scratch_len(f: &PlaneFfts) -> usize {
    f.x.get_inplace_scratch_len().max(f.y.get_inplace_scratch_len())
}

/// Forward FFT along x (rows `< rows`, the others being zero) and y of every plane, in place.
pub(crate) fn forward_xy(d: &Dims, planes: &mut [Complex32], rows: usize) {
    let f = plan(d, false);
    let zero = Complex32::new(0.0, 0.0);
    planes.par_chunks_mut(d.plane()).for_each_init(
        || (vec![zero; d.plane()], vec![zero; scratch_len(&f)]),
        |(t, scratch), plane| {
            f.x.process_with_scratch(&mut plane[..rows * d.px], scratch);
            fft_columns(d, plane, t, f.y.as_ref(), scratch);
        },
    );
}

/// Inverse (unnormalised) FFT along y and then x of every plane, in place; only rows `< rows` are
/// transformed along x (the others are left as garbage and must not be read).
pub(crate) fn inverse_xy(d: &Dims, planes: &mut [Complex32], rows: usize) {
    let f = plan(d, true);
    let zero = Complex32::new(0.0, 0.0);
    planes.par_chunks_mut(d.plane()).for_each_init(
        || (vec![zero; d.plane()], vec![zero; scratch_len(&f)]),
        |(t, scratch), plane| {
            fft_columns(d, plane, t, f.y.as_ref(), scratch);
            f.x.process_with_scratch(&mut plane[..rows * d.px], scratch);
        },
    );
}

/// Signed frequency (or offset) of index `i` on a periodic axis of `n` samples.
pub(crate) fn signed(i: usize, n: usize) -> f64 {
    if i <= n / 2 { i as f64 } else { i as f64 - n as f64 }
}
