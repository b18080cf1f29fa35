//! Intensities with the noise of an independent Monte Carlo renderer: captures without photon counts, for
//! the `holes` scenario's fixtures "as intensities".
//!
//! The noise is measured from the reference pair of the Lambertian square (`../shared/data/reference`:
//! `plane_mc`, a transient path tracer at 262,144 samples per pixel, against `plane_quadrature`, exact to
//! about 1e-6): on every bin the exact value `q` is non-zero, with `M` the largest exact value,
//! - its spread: `var(mc − q) = a · M² · (q / M)^p`, fitted by least squares in logarithms over 20 bins of
//!   equal count of `q` (the square gives p ≈ 1.2: between a photon count's `p = 1` and a relative error's 2);
//! - its shape: the residuals divided by that spread, `z = (mc − q) / σ(q)`, kept as measured — heavy-tailed
//!   (kurtosis about 400: a path tracer's fireflies), which a Gaussian would not reproduce.
//!
//! A clean render `I` gets, on each bin with `I > 0`, `max(0, I + σ(I) · z)` with `σ` taken at the render's
//! own largest value and `z` drawn from the measured ones (SplitMix64, seeded): no value is an integer count
//! and none is negative, as in the reference. Bins where the clean render is 0 stay 0.

use std::path::Path;

use nlos_transient::Transient;
use nlos_transient::rng::SplitMix64;

/// The measured noise of the reference path tracer (module docs).
pub(super) struct McNoise {
    /// `a` and `p` of `var = a · M² · (q / M)^p`.
    a: f64,
    p: f64,
    /// The residuals in units of their spread.
    z: Vec<f64>,
}

/// The reference pair the noise is measured from, under the shared data's root.
pub(super) const REFERENCE: [&str; 2] = ["reference/plane_mc.hdf5", "reference/plane_quadrature.hdf5"];

impl McNoise {
    /// Measures the noise from the path tracer's transient `mc` and the exact one `exact` of the same scene.
    pub(super) fn measure(mc: &Path, exact: &Path) -> Result<Self, String> {
        let read = |p: &Path| nlos_transient::read(p).map_err(|e| format!("{}: {e}", p.display()));
        let (mc, exact) = (read(mc)?, read(exact)?);
        if mc.data().len() != exact.data().len() {
            return Err(format!("the reference pair differs in size: {} and {}", mc.data().len(), exact.data().len()));
        }
        let m = exact.data().iter().copied().fold(0.0f32, f32::max) as f64;
        let pairs: Vec<(f64, f64)> = exact
            .data()
            .iter()
            .zip(mc.data())
            .filter(|(q, _)| **q > 0.0)
            .map(|(&q, &v)| (f64::from(q) / m, f64::from(v - q) / m))
            .collect();
        if pairs.len() < 1000 {
            return Err("the reference pair has fewer than 1,000 non-zero bins".into());
        }
        let mut sorted = pairs.clone();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut xs, mut ys) = (Vec::new(), Vec::new());
        for chunk in sorted.chunks(sorted.len().div_ceil(20)) {
            let n = chunk.len() as f64;
            let mean = chunk.iter().map(|c| c.0).sum::<f64>() / n;
            let d_mean = chunk.iter().map(|c| c.1).sum::<f64>() / n;
            let var = chunk.iter().map(|c| (c.1 - d_mean).powi(2)).sum::<f64>() / n;
            if mean > 0.0 && var > 0.0 {
                xs.push(mean.ln());
                ys.push(var.ln());
            }
        }
        let n = xs.len() as f64;
        let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
        let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
        let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
        let p = sxy / sxx;
        let a = (my - p * mx).exp();
        if !(p.is_finite() && a.is_finite() && a > 0.0) {
            return Err(format!("the reference pair's spread did not fit: a {a}, p {p}"));
        }
        let z = pairs.iter().map(|&(q, d)| d / (a * q.powf(p)).sqrt()).collect();
        Ok(Self { a, p, z })
    }

    /// `var = a · M² · (q / M)^p`: the fitted `a` and `p`.
    pub(super) fn law(&self) -> (f64, f64) {
        (self.a, self.p)
    }

    /// The clean capture at `clean` with this noise (module docs), written to `out` in the format of its
    /// extension.
    pub(super) fn apply(&self, clean: &Path, seed: u64, out: &Path) -> Result<(), String> {
        let t = nlos_transient::read(clean).map_err(|e| format!("{}: {e}", clean.display()))?;
        let m = f64::from(t.data().iter().copied().fold(0.0f32, f32::max));
        let mut rng = SplitMix64::new(seed);
        let data: Vec<f32> = t
            .data()
            .iter()
            .map(|&v| {
                if v <= 0.0 {
                    return v;
                }
                let q = f64::from(v) / m;
                let z = self.z[rng.below(self.z.len())];
                (m * (q + (self.a * q.powf(self.p)).sqrt() * z)).max(0.0) as f32
            })
            .collect();
        let noisy = Transient::new(t.scan().clone(), *t.time(), data).map_err(|e| e.to_string())?;
        let format = nlos_transient::Format::for_writing_extension(out).unwrap_or(nlos_transient::Format::Tal);
        nlos_transient::write(&noisy, out, format).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nlos_transient::{PointSet, Scan, TimeAxis};

    fn write(values: Vec<f32>, path: &Path) {
        let scan = Scan::confocal(PointSet::wall_grid(16, 16, 0.25, 0.25).expect("grid"));
        let t = Transient::new(scan, TimeAxis::new(0.0, 0.0012, 100).expect("axis"), values).expect("transient");
        nlos_transient::write(&t, path, nlos_transient::Format::Tal).expect("written");
    }

    /// A pair made with a known law (`a` 1e-3, `p` 1.5, uniform residuals) gives that law back, and the noise
    /// it adds keeps zeros, never goes negative and leaves no integer counts.
    #[test]
    fn the_law_of_a_known_pair_is_measured_and_applied() {
        let dir = std::env::temp_dir().join(format!("nlos-mc-noise-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let mut rng = SplitMix64::new(7);
        let n = 16 * 16 * 100;
        let exact: Vec<f32> = (0..n).map(|i| if i % 10 == 0 { 0.0 } else { 0.01 + rng.next_f32() * 2.0 }).collect();
        let m = 2.01f64;
        let mc: Vec<f32> = exact
            .iter()
            .map(|&q| {
                let z = f64::from(rng.range_f32(-1.0, 1.0)) * 3f64.sqrt();
                let q = f64::from(q);
                if q == 0.0 { 0.0 } else { (q + m * (1e-3 * (q / m).powf(1.5)).sqrt() * z) as f32 }
            })
            .collect();
        let (mc_path, exact_path, out) = (dir.join("mc.hdf5"), dir.join("exact.hdf5"), dir.join("noisy.hdf5"));
        write(mc, &mc_path);
        write(exact.clone(), &exact_path);
        let noise = McNoise::measure(&mc_path, &exact_path).expect("measured");
        let (a, p) = noise.law();
        assert!((p - 1.5).abs() < 0.05 && (a / 1e-3 - 1.0).abs() < 0.1, "a {a}, p {p}");
        noise.apply(&exact_path, 1, &out).expect("applied");
        let noisy = nlos_transient::read(&out).expect("read");
        for (v, q) in noisy.data().iter().zip(&exact) {
            assert!(*v >= 0.0 && (*q != 0.0 || *v == 0.0), "{v} from {q}");
        }
        assert!(!nlos_transient::sensor::is_integer_counts(noisy.data()));
        assert_ne!(noisy.data(), &exact[..]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
