//! The data term one histogram at a time ([`RowTerm`]): what boundary pruning and the residual patches
//! evaluate when they test a face's share, implemented by [`super::DataTerm`] (a sum over bins) and
//! [`super::SensorRows`] (through the timing response).

use nlos_render::RowSpan;

use crate::error::Result;

/// The data term of one histogram as boundary pruning and growth see it: `value(m, row, window)` is
/// histogram m's data term for the rendered histogram `row` (all of it, at the block's scale), summed over
/// the bins whose terms a change of the bins `window` can reach — the window itself for a term that is a
/// sum over bins (`DataTerm`), widened by the timing response's support for the sensor fit — so that for
/// two renderings that differ only inside `window`, the difference of the two values is the change of the
/// whole data term. `0..bins` gives the whole term. A face's share spans a few dozen of the bins: the tests
/// of [`crate::prune_boundary`] cost that, not the histograms' length.
///
/// Any `Fn(m, row, window) -> Result<f64>` is one ([`RowLoss`] is the trait object).
pub trait RowTerm: Sync {
    /// Histogram `m`'s data term for `row`, over the bins a change of `window` reaches (trait docs).
    ///
    /// # Errors
    /// Those of the data term (a row of the wrong length).
    fn value(&self, m: usize, row: &[f32], window: std::ops::Range<usize>) -> Result<f64>;

    /// `E_m(row + k·share) − E_m(row)` for each `k` of `ks`, the share's values starting at its
    /// `first_bin` (its `measurement` is not read: `m` is). The default evaluates [`RowTerm::value`] on
    /// shifted copies, clamped at 0 (f32 cancellation can leave −ε where a deleted face was the only
    /// light); a term that is linear in the rendering before its non-linearity (the sensor fit's
    /// convolution) does better by transforming the share once.
    ///
    /// # Errors
    /// As [`RowTerm::value`].
    fn changes(&self, m: usize, row: &[f32], share: &RowSpan, ks: &[f32]) -> Result<Vec<f64>> {
        // Clamped to the row: a share starting past its end changes nothing (an empty window).
        let end = (share.first_bin + share.values.len()).min(row.len());
        let window = share.first_bin.min(end)..end;
        let now = self.value(m, row, window.clone())?;
        // The row shifted inside the window only: restored there after each k (not copied whole per k).
        let mut shifted = row.to_vec();
        ks.iter()
            .map(|&k| {
                for ((x, v), r) in shifted[window.clone()].iter_mut().zip(&share.values).zip(&row[window.clone()]) {
                    *x = (*r + k * v).max(0.0);
                }
                let change = self.value(m, &shifted, window.clone())? - now;
                shifted[window.clone()].copy_from_slice(&row[window.clone()]);
                Ok(change)
            })
            .collect()
    }
    /// Told that `spans` (a face's share) were added to (`add`) or taken from the rendering that later calls
    /// pass as `row`, for a term that keeps something of the rendering between calls ([`SensorRows`]'s
    /// `J I`). The default keeps nothing.
    ///
    /// [`SensorRows`]: crate::SensorRows
    ///
    /// # Errors
    /// Those of the term (a share outside its histograms).
    fn applied(&self, spans: &[RowSpan], add: bool) -> Result<()> {
        let _ = (spans, add);
        Ok(())
    }
}

impl<F> RowTerm for F
where
    F: Fn(usize, &[f32], std::ops::Range<usize>) -> Result<f64> + Sync,
{
    fn value(&self, m: usize, row: &[f32], window: std::ops::Range<usize>) -> Result<f64> {
        self(m, row, window)
    }
}

/// The data term as [`crate::prune_boundary`] and [`crate::residual`] take it ([`RowTerm`]).
pub type RowLoss<'a> = dyn RowTerm + 'a;
