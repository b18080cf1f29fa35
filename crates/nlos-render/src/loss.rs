//! Losses between a rendered and a measured transient, with their adjoints `dE/dI`.

use crate::error::{RenderError, Result};

/// A data term E(I; Ĩ) summed over every (measurement, bin), optionally weighted per bin.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub enum Loss {
    /// `E = ½ Σ w (Ĩ − I)²`, `dE/dI = w (I − Ĩ)` (Tsai et al. 2019, eq. 6). The default.
    #[default]
    L2,
    /// Poisson negative log-likelihood `E = Σ w (I − Ĩ ln max(I, floor))` (constant terms dropped),
    /// `dE/dI = w (1 − Ĩ/I)` where `I > floor`, `w` where clamped (the log term is constant there).
    PoissonNll {
        /// Lower clamp of the rate inside the logarithm (> 0), e.g. 1e-12.
        floor: f32,
    },
}

impl Loss {
    /// The checks of [`Loss::evaluate`]: lengths and the Poisson floor.
    fn check(&self, rendered: &[f32], measured: &[f32], weights: Option<&[f32]>) -> Result<()> {
        if measured.len() != rendered.len() {
            return Err(RenderError::LengthMismatch {
                what: "measured",
                expected: rendered.len(),
                got: measured.len(),
            });
        }
        if let Some(w) = weights
            && w.len() != rendered.len()
        {
            return Err(RenderError::LengthMismatch { what: "weights", expected: rendered.len(), got: w.len() });
        }
        if let Loss::PoissonNll { floor } = *self
            && !(floor > 0.0 && floor.is_finite())
        {
            return Err(RenderError::InvalidParameter {
                name: "PoissonNll.floor",
                value: f64::from(floor),
                reason: "must be finite and > 0",
            });
        }
        Ok(())
    }

    /// `E(s·I; Ĩ)` alone, without the adjoint or a scaled copy of `rendered`: the same value, to the bit, as
    /// [`Loss::evaluate`] of `rendered` scaled by `scale` in f32 (for callers that compare many small
    /// changes of one histogram, e.g. boundary pruning).
    ///
    /// # Errors
    /// As [`Loss::evaluate`].
    pub fn value_scaled(&self, rendered: &[f32], scale: f32, measured: &[f32], weights: Option<&[f32]>) -> Result<f64> {
        self.check(rendered, measured, weights)?;
        let wt = |i: usize| weights.map_or(1.0, |w| w[i]);
        let mut e = 0.0f64;
        match (*self, weights) {
            // Unweighted: the same terms (0.5 · 1 = 0.5 exactly) without a weight per bin.
            (Loss::L2, None) => {
                for (&r, &m) in rendered.iter().zip(measured) {
                    let r = scale * r - m;
                    e += 0.5 * f64::from(r) * f64::from(r);
                }
            }
            (Loss::L2, Some(_)) => {
                for i in 0..rendered.len() {
                    let r = scale * rendered[i] - measured[i];
                    e += 0.5 * f64::from(wt(i)) * f64::from(r) * f64::from(r);
                }
            }
            (Loss::PoissonNll { floor }, _) => {
                for i in 0..rendered.len() {
                    let (i_r, i_m) = (scale * rendered[i], measured[i]);
                    let clamped = i_r.max(floor);
                    e += f64::from(wt(i)) * (f64::from(i_r) - f64::from(i_m) * f64::from(clamped).ln());
                }
            }
        }
        Ok(e)
    }

    /// `(E, dE/dI)` for `rendered` against `measured`, `weights` per (measurement, bin) if given. E is summed
    /// in f64.
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] if the lengths differ; [`RenderError::InvalidParameter`] for a
    /// non-positive or non-finite Poisson floor.
    pub fn evaluate(&self, rendered: &[f32], measured: &[f32], weights: Option<&[f32]>) -> Result<(f64, Vec<f32>)> {
        self.check(rendered, measured, weights)?;
        let wt = |i: usize| weights.map_or(1.0, |w| w[i]);
        let mut e = 0.0f64;
        let mut adj = vec![0.0f32; rendered.len()];
        match *self {
            Loss::L2 => {
                for i in 0..rendered.len() {
                    let r = rendered[i] - measured[i];
                    e += 0.5 * f64::from(wt(i)) * f64::from(r) * f64::from(r);
                    adj[i] = self.d_bin(rendered[i], measured[i], wt(i));
                }
            }
            Loss::PoissonNll { floor } => {
                for i in 0..rendered.len() {
                    let (i_r, i_m) = (rendered[i], measured[i]);
                    let clamped = i_r.max(floor);
                    e += f64::from(wt(i)) * (f64::from(i_r) - f64::from(i_m) * f64::from(clamped).ln());
                    adj[i] = self.d_bin(i_r, i_m, wt(i));
                }
            }
        }
        Ok((e, adj))
    }

    /// `dE/dI` of one bin: rendered `i_r`, measured `i_m`, weight `w`.
    #[inline(always)]
    fn d_bin(&self, i_r: f32, i_m: f32, w: f32) -> f32 {
        match *self {
            Loss::L2 => w * (i_r - i_m),
            Loss::PoissonNll { floor } => w * if i_r > floor { 1.0 - i_m / i_r } else { 1.0 },
        }
    }

    /// `factor · s · dE/dI` at `I = s · rendered` (`s` = `scale`), in parallel over the bins: the bits of
    /// [`Loss::evaluate`]'s adjoint on the scaled copy, multiplied by `scale` and then by `factor` (the chain
    /// rule through a fixed scale, and a normaliser), without the copy or the sum. The value is
    /// [`Loss::value_scaled`].
    ///
    /// # Errors
    /// As [`Loss::evaluate`].
    pub fn gradient_scaled(
        &self,
        rendered: &[f32],
        scale: f32,
        measured: &[f32],
        weights: Option<&[f32]>,
        factor: f32,
    ) -> Result<Vec<f32>> {
        use rayon::prelude::*;
        self.check(rendered, measured, weights)?;
        const CHUNK: usize = 1 << 14;
        let mut d = vec![0.0f32; rendered.len()];
        d.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            let at = c * CHUNK;
            let (r, m) = (&rendered[at..at + out.len()], &measured[at..at + out.len()]);
            match weights {
                Some(w) => {
                    let w = &w[at..at + out.len()];
                    for i in 0..out.len() {
                        out[i] = self.d_bin(scale * r[i], m[i], w[i]) * scale * factor;
                    }
                }
                None => {
                    for i in 0..out.len() {
                        out[i] = self.d_bin(scale * r[i], m[i], 1.0) * scale * factor;
                    }
                }
            }
        });
        Ok(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `value_scaled` gives the bits of `evaluate` on the scaled copy, for both losses, with and without
    /// weights; bad lengths are typed errors.
    #[test]
    fn value_scaled_matches_evaluate_bitwise() {
        let r: Vec<f32> = (0..257).map(|i| ((i as f32) * 0.37).sin().abs() * 3.0).collect();
        let m: Vec<f32> = (0..257).map(|i| ((i * 7 % 11) as f32) * 0.9).collect();
        let w: Vec<f32> = (0..257).map(|i| 0.5 + (i % 3) as f32).collect();
        let s = 1.7f32;
        let scaled: Vec<f32> = r.iter().map(|x| s * x).collect();
        for loss in [Loss::L2, Loss::PoissonNll { floor: 1e-6 }] {
            for weights in [None, Some(&w[..])] {
                let a = loss.evaluate(&scaled, &m, weights).expect("ok").0;
                let b = loss.value_scaled(&r, s, &m, weights).expect("ok");
                assert_eq!(a.to_bits(), b.to_bits(), "{loss:?}");
            }
            // gradient_scaled: the bits of evaluate's adjoint on the scaled copy, times s, times a factor
            let factor = 0.3f32;
            for weights in [None, Some(&w[..])] {
                let (_, adj) = loss.evaluate(&scaled, &m, weights).expect("ok");
                let g = loss.gradient_scaled(&r, s, &m, weights, factor).expect("ok");
                for (a, b) in adj.iter().zip(&g) {
                    assert_eq!((a * s * factor).to_bits(), b.to_bits(), "{loss:?}");
                }
            }
            assert!(loss.gradient_scaled(&r[1..], s, &m, None, factor).is_err());
            assert!(loss.value_scaled(&r[1..], s, &m, None).is_err());
            assert!(loss.value_scaled(&r, s, &m, Some(&w[1..])).is_err());
        }
    }
}
