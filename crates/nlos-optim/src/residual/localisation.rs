//! Whether a candidate patch explains a localised return ([`localisation`]), not a background or a tail.

use nlos_render::RowSpan;

/// The residual's contrast a patch needs to be kept ([`localisation`]): its light must match the residual
/// at its own place at least this many times better than shifted just before or just after it.
pub const LOCALISED_CONTRAST: f64 = 2.0;

/// The shortest shift of [`localisation`]'s comparisons, metres of path: about three widths of a SPAD's
/// timing response (the Stanford captures' falls to half in 11 mm), so that the blur of the patch's own
/// return does not reach the shifted windows.
pub const LOCALISATION_SHIFT: f64 = 0.03;

/// How much better a patch's light matches the residual at its own place than just before or after it:
/// `a₀ / max(a₋, a₊)` with `a₀ = Σ_m Σ_k I_p[m,k] r[m,k]` and `a_± = Σ_m Σ_k I_p[m,k] r[m,k ± D_m]`, `I_p` the
/// patch's rendered light, `r` the residual, `D_m` the length of row `m`'s span of the patch's light but at
/// least [`LOCALISATION_SHIFT`] (rows whose shifted spans leave the axis do not count). Infinite when
/// `a₀ > 0` and neither shifted match is positive; 0 when `a₀ ≤ 0`.
///
/// A surface the fit lacks leaves its own return in the residual, concentrated where its light falls:
/// `a₀` is its light's energy and the shifted matches hold only what the residual has nearby, so the
/// contrast is large. What is not a surface — a background the model lacks (flat in time: contrast ≈ 1),
/// a sensor's diffusion tail or the slow decay after a return (falling: `a₋ > a₀`, contrast < 1) — matches
/// as well or better when shifted, and a patch that explains it with surface (on the preprocessed S and U,
/// surfaces half a metre behind the letters explained their late tail) is refused below
/// [`LOCALISED_CONTRAST`].
pub fn localisation<'a>(
    spans: impl Iterator<Item = &'a [RowSpan]>,
    residual: &[f32],
    bins: usize,
    bin_width: f64,
) -> f64 {
    // The patch's light per row, as (first bin, values), summed over its faces.
    let mut rows: std::collections::BTreeMap<usize, (usize, Vec<f64>)> = std::collections::BTreeMap::new();
    for span in spans.flatten() {
        let end = span.first_bin + span.values.len();
        let row = rows.entry(span.measurement).or_insert_with(|| (span.first_bin, Vec::new()));
        // Grow the row's window to cover this span.
        if span.first_bin < row.0 {
            let mut grown = vec![0.0; row.0 - span.first_bin];
            grown.extend_from_slice(&row.1);
            row.1 = grown;
            row.0 = span.first_bin;
        }
        if end > row.0 + row.1.len() {
            row.1.resize(end - row.0, 0.0);
        }
        for (i, &v) in span.values.iter().enumerate() {
            row.1[span.first_bin - row.0 + i] += f64::from(v);
        }
    }
    let min_shift = (LOCALISATION_SHIFT / bin_width).ceil() as usize;
    let (mut a0, mut before, mut after) = (0.0, 0.0, 0.0);
    for (&m, (first, light)) in &rows {
        let shift = light.len().max(min_shift);
        if *first < shift || first + light.len() + shift > bins {
            continue;
        }
        let r = &residual[m * bins..(m + 1) * bins];
        for (i, &p) in light.iter().enumerate() {
            let k = first + i;
            a0 += p * f64::from(r[k]);
            before += p * f64::from(r[k - shift]);
            after += p * f64::from(r[k + shift]);
        }
    }
    let shifted = before.max(after);
    if a0 <= 0.0 {
        0.0
    } else if shifted <= 0.0 {
        f64::INFINITY
    } else {
        a0 / shifted
    }
}
