//! Tick selection: "nice" steps of 1, 2 or 5 × 10^k, and their labels.

/// The smallest step of the form 1, 2 or 5 × 10^k that splits `span` into at most `max_ticks` intervals.
/// Returns `None` when `span` is not finite and positive.
///
/// # Example
/// ```
/// assert_eq!(nlos_viz::nice_step(0.7, 5), Some(0.2));
/// assert_eq!(nlos_viz::nice_step(2048.0, 4), Some(1000.0));
/// ```
pub fn nice_step(span: f64, max_ticks: usize) -> Option<f64> {
    if !(span.is_finite() && span > 0.0) {
        return None;
    }
    let raw = span / max_ticks.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0].into_iter().map(|m| m * mag).find(|&s| s >= raw * (1.0 - 1e-9))
}

/// Tick values: the multiples of [`nice_step`] that lie in `[min, max]` (a relative tolerance of 1e-9 of
/// the step keeps the ends). At most `max_ticks + 1` values; empty when the range is not finite and
/// increasing.
///
/// # Example
/// ```
/// let t = nlos_viz::nice_ticks(-0.35, 0.35, 4);
/// assert_eq!(t, vec![-0.2, 0.0, 0.2]);
/// ```
pub fn nice_ticks(min: f64, max: f64, max_ticks: usize) -> Vec<f64> {
    let Some(step) = (min < max && min.is_finite()).then(|| nice_step(max - min, max_ticks)).flatten() else {
        return Vec::new();
    };
    let first = (min / step - 1e-9).ceil();
    let last = (max / step + 1e-9).floor();
    if !(first.is_finite() && last.is_finite()) || last - first > 1e4 {
        return Vec::new();
    }
    let mut out = Vec::new();
    let mut k = first;
    while k <= last {
        // Multiply rather than accumulate, and snap −0 to 0.
        let v = k * step;
        out.push(if v == 0.0 { 0.0 } else { v });
        k += 1.0;
    }
    out
}

/// The powers of ten in `[min, max]` (both > 0), for logarithmic axes.
///
/// # Example
/// ```
/// assert_eq!(nlos_viz::log_ticks(0.05, 300.0), vec![0.1, 1.0, 10.0, 100.0]);
/// ```
pub fn log_ticks(min: f64, max: f64) -> Vec<f64> {
    if !(min > 0.0 && max >= min && max.is_finite()) {
        return Vec::new();
    }
    let (a, b) = ((min.log10() - 1e-9).ceil() as i32, (max.log10() + 1e-9).floor() as i32);
    (a..=b).take(400).map(|k| 10f64.powi(k)).collect()
}

/// The label of tick value `v` on an axis whose ticks are `step` apart: just enough decimals to tell
/// neighbouring ticks apart, and scientific notation (`2.5e6`) for steps of 10^5 and up or below 10^-4.
///
/// # Example
/// ```
/// use nlos_viz::format_tick;
/// assert_eq!(format_tick(0.2, 0.1), "0.2");
/// assert_eq!(format_tick(-0.0, 0.1), "0");
/// assert_eq!(format_tick(1.25, 0.05), "1.25");
/// assert_eq!(format_tick(1500.0, 500.0), "1500");
/// assert_eq!(format_tick(2.5e6, 5e5), "2.5e6");
/// ```
pub fn format_tick(v: f64, step: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let step = step.abs();
    if v == 0.0 || !(step.is_finite() && step > 0.0) {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let step_exp = step.log10().floor();
    if !(1e-4..1e5).contains(&step) {
        let v_exp = v.abs().log10().floor();
        let decimals = (v_exp - step_exp).clamp(0.0, 15.0) as usize;
        let s = format!("{v:.decimals$e}");
        return trim_mantissa(&s);
    }
    // Decimals: enough for the step's leading digit (0.05 → 2, 0.2 → 1, 1 → 0, 2.5 → 1).
    let mut decimals = (-step_exp).max(0.0) as usize;
    while decimals < 12
        && ((step * 10f64.powi(decimals as i32)).round() - step * 10f64.powi(decimals as i32)).abs() > 1e-6
    {
        decimals += 1;
    }
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') { "0".into() } else { s }
}

/// Removes trailing zeros of a mantissa: `2.50e6` → `2.5e6`, `3.0e2` → `3e2`.
fn trim_mantissa(s: &str) -> String {
    match s.split_once('e') {
        Some((m, e)) if m.contains('.') => {
            let m = m.trim_end_matches('0').trim_end_matches('.');
            format!("{m}e{e}")
        }
        _ => s.into(),
    }
}

/// The label of a power-of-ten tick on a log axis: plain for 10^-2 … 10^4, `1e-3` style otherwise.
///
/// # Example
/// ```
/// assert_eq!(nlos_viz::format_log_tick(100.0), "100");
/// assert_eq!(nlos_viz::format_log_tick(0.01), "0.01");
/// assert_eq!(nlos_viz::format_log_tick(1e6), "1e6");
/// ```
pub fn format_log_tick(v: f64) -> String {
    if !(v > 0.0 && v.is_finite()) {
        return format!("{v}");
    }
    let k = v.log10().round() as i32;
    if (-2..=4).contains(&k) { format_tick(v, 10f64.powi(k)) } else { format!("1e{k}") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_1_2_5() {
        assert_eq!(nice_step(1.0, 10), Some(0.1));
        assert_eq!(nice_step(1.0, 4), Some(0.5));
        assert_eq!(nice_step(1.0, 6), Some(0.2));
        assert_eq!(nice_step(7.0, 7), Some(1.0));
        assert_eq!(nice_step(2.458, 5), Some(0.5));
        assert_eq!(nice_step(3e6, 3), Some(1e6));
        assert_eq!(nice_step(0.0, 3), None);
        assert_eq!(nice_step(f64::NAN, 3), None);
        assert_eq!(nice_step(1.0, 0), Some(1.0));
        for span in [0.003, 0.7, 1.0, 13.0, 999.0, 1234.5] {
            for n in 1..12 {
                let s = nice_step(span, n).expect("step");
                assert!(span / s <= n as f64 + 1e-9, "{span} {n} {s}");
                let m = s / 10f64.powf(s.log10().floor());
                assert!([1.0, 2.0, 5.0].iter().any(|x| (x - m).abs() < 1e-9), "{s}");
            }
        }
    }

    #[test]
    fn ticks_cover_range() {
        assert_eq!(nice_ticks(0.0, 1.0, 5), vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
        assert_eq!(nice_ticks(-0.36, 0.36, 6), vec![-0.2, 0.0, 0.2]);
        let t = nice_ticks(-0.36, 0.36, 8);
        assert_eq!(t.len(), 7);
        assert!(t.iter().zip([-0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3]).all(|(a, b)| (a - b).abs() < 1e-12));
        assert_eq!(nice_ticks(0.0, 2.4576, 5), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        assert!(nice_ticks(1.0, 1.0, 5).is_empty());
        assert!(nice_ticks(2.0, 1.0, 5).is_empty());
        assert!(nice_ticks(f64::NEG_INFINITY, 1.0, 5).is_empty());
        assert!(nice_ticks(0.0, 1e300, usize::MAX).len() <= 10_001);
    }

    #[test]
    fn labels() {
        assert_eq!(format_tick(0.6000000000000001, 0.2), "0.6");
        assert_eq!(format_tick(-0.3, 0.1), "-0.3");
        assert_eq!(format_tick(-1e-17, 0.1), "0");
        assert_eq!(format_tick(2.0, 0.5), "2.0");
        assert_eq!(format_tick(3e6, 1e6), "3e6");
        assert_eq!(format_tick(0.00002, 0.00001), "2e-5");
        assert_eq!(format_tick(40.0, 20.0), "40");
        assert_eq!(format_log_tick(1e-3), "1e-3");
        assert_eq!(format_log_tick(1.0), "1");
    }
}
