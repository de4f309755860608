//! Summary statistics of error lists, in one place: RMS, maximum, nearest-rank percentiles
//! ([`ErrorStats`]) and medians ([`median`]).
//!
//! Conventions, written once here:
//! - Errors are non-negative magnitudes (`|d − g|`, texels, …); the caller takes the absolute
//!   value (or a wrapped distance) before.
//! - An empty list gives all-zero statistics with `count = 0` (the caller reports the count, so
//!   "nothing measured" is visible and no NaN is produced).
//! - Percentiles use the **nearest rank**: the value of rank `⌈q·n⌉` (1-based, clamped to
//!   `[1, n]`) of the sorted list.
//! - Medians ([`median`]) state how an even count is resolved ([`EvenMedian`]): timings take the
//!   upper middle value, a time that was measured (`fit-bench`, `ellipsoid-bench`, pyramid
//!   lookups); quad-tree fusion takes the mean of the two middle estimates.
//! - Sums of squares are taken in list order (chunk by chunk for [`ErrorStats::of_chunks`]), so a
//!   figure does not depend on the thread count.

use serde::Serialize;

/// Error statistics of a list of error magnitudes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Root mean square error.
    pub rms: f64,
    /// Largest error.
    pub max: f64,
    /// 99th percentile (nearest rank).
    pub p99: f64,
    /// Number of errors measured.
    pub count: usize,
}

impl ErrorStats {
    /// Statistics of `errors` (reordered in place by the percentile selection).
    /// Cost: one pass and one selection, O(n).
    pub fn of(errors: Vec<f64>) -> Self {
        Self::of_chunks(vec![errors])
    }

    /// Statistics of the concatenation of `chunks` (e.g. one chunk per z-slice computed in
    /// parallel); the sum of squares is summed per chunk, then over the chunks in order.
    /// Cost: one pass, one concatenation and one selection, O(n).
    pub fn of_chunks(chunks: Vec<Vec<f64>>) -> Self {
        let count: usize = chunks.iter().map(Vec::len).sum();
        if count == 0 {
            return Self::default();
        }
        let sum_sq: f64 = chunks
            .iter()
            .map(|c| c.iter().map(|e| e * e).sum::<f64>())
            .sum();
        let max = chunks
            .iter()
            .map(|c| c.iter().copied().fold(0.0, f64::max))
            .fold(0.0, f64::max);
        let mut errors = if chunks.len() == 1 {
            chunks.into_iter().next().unwrap_or_default()
        } else {
            chunks.concat()
        };
        Self {
            rms: (sum_sq / count as f64).sqrt(),
            max,
            p99: percentile(&mut errors, 0.99),
            count,
        }
    }
}

/// Root mean square of `errors` (`0` for an empty list). Cost: one pass.
pub fn rms(errors: impl IntoIterator<Item = f64>) -> f64 {
    let (sum_sq, n) = errors
        .into_iter()
        .fold((0.0, 0usize), |(s, n), e| (s + e * e, n + 1));
    if n == 0 {
        0.0
    } else {
        (sum_sq / n as f64).sqrt()
    }
}

/// Nearest-rank `q`-quantile of `values` (`q ∈ [0, 1]`; reorders `values`); `0` for an empty
/// list. NaN sorts last ([`f64::total_cmp`]). Cost: one selection, O(n).
pub fn percentile(values: &mut [f64], q: f64) -> f64 {
    let n = values.len();
    if n == 0 {
        return 0.0;
    }
    let rank = ((q * n as f64).ceil() as usize).clamp(1, n) - 1;
    *values.select_nth_unstable_by(rank, f64::total_cmp).1
}

/// How a median of an even number of values is taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EvenMedian {
    /// The upper of the two middle values, `sorted[n/2]` (always one of the values: used for
    /// timings, where it is a time that was measured).
    Upper,
    /// The mean of the two middle values.
    Mean,
}

/// Median of `values` (reorders them; NaN sorts last by [`f64::total_cmp`]); `None` for an
/// empty list. `even` chooses the convention for an even count. Cost: O(n log n) (a sort).
pub fn median(values: &mut [f64], even: EvenMedian) -> Option<f64> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(match even {
        EvenMedian::Mean if n.is_multiple_of(2) => 0.5 * (values[n / 2 - 1] + values[n / 2]),
        _ => values[n / 2],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn error_stats_match_brute_force() {
        let errors: Vec<f64> = (1..=200).map(|i| f64::from(i) * 0.5).collect();
        let s = ErrorStats::of(errors.clone());
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / 200.0).sqrt();
        assert_relative_eq!(s.rms, rms, max_relative = 1e-15);
        assert_relative_eq!(s.max, 100.0);
        // Nearest rank ⌈0.99·200⌉ = 198: the 198th smallest value.
        assert_relative_eq!(s.p99, 99.0);
        assert_eq!(s.count, 200);
        // Chunked: same figures, whatever the split.
        let c = ErrorStats::of_chunks(vec![errors[..70].to_vec(), errors[70..].to_vec()]);
        assert_relative_eq!(c.rms, s.rms, max_relative = 1e-14);
        assert_eq!((c.max, c.p99, c.count), (s.max, s.p99, s.count));
    }

    #[test]
    fn empty_lists_give_zeros_not_nan() {
        assert_eq!(ErrorStats::of(vec![]), ErrorStats::default());
        assert_eq!(ErrorStats::of_chunks(vec![vec![], vec![]]).count, 0);
        assert_eq!(rms([]), 0.0);
        assert_eq!(percentile(&mut [], 0.5), 0.0);
        assert_eq!(median(&mut [], EvenMedian::Upper), None);
    }

    #[test]
    fn rms_and_percentile_of_small_lists() {
        assert_relative_eq!(rms([3.0, 4.0]), (12.5f64).sqrt());
        let mut v = [5.0, 1.0, 4.0, 2.0, 3.0];
        assert_relative_eq!(percentile(&mut v, 0.0), 1.0);
        assert_relative_eq!(percentile(&mut v, 0.5), 3.0);
        assert_relative_eq!(percentile(&mut v, 1.0), 5.0);
    }

    #[test]
    fn median_conventions() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0], EvenMedian::Upper), Some(2.0));
        assert_eq!(median(&mut [3.0, 1.0, 2.0], EvenMedian::Mean), Some(2.0));
        assert_eq!(
            median(&mut [4.0, 1.0, 3.0, 2.0], EvenMedian::Upper),
            Some(3.0)
        );
        assert_eq!(
            median(&mut [4.0, 1.0, 3.0, 2.0], EvenMedian::Mean),
            Some(2.5)
        );
        assert_eq!(median(&mut [7.0], EvenMedian::Mean), Some(7.0));
    }
}
