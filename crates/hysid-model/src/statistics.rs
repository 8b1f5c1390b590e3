//! Order statistics of a sample: the median, the upper median, and the
//! factor that turns a median absolute deviation into a standard deviation.
//! Each function reorders its slice in place (a selection, not a full sort:
//! `O(n)`), so a caller that still needs the order passes a copy.

/// The median absolute deviation of Gaussian errors times this is their
/// standard deviation (`1 / Phi^{-1}(3/4)`; Hampel, JASA 69, 1974).
pub const MAD_TO_SIGMA: f64 = 1.482_6;

/// The median: the middle value of an odd count, the mean of the two
/// middle values of an even one; `None` for no values.
pub fn median(values: &mut [f64]) -> Option<f64> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let (lower, middle, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let middle = *middle;
    if n % 2 == 1 {
        return Some(middle);
    }
    let below = lower.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Some(0.5 * (below + middle))
}

/// The upper median: the value of rank `n / 2` (from 0) in increasing
/// order, which is the median of an odd count and the larger of the two
/// middle values of an even one; `None` for no values.
pub fn upper_median(values: &mut [f64]) -> Option<f64> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    Some(*values.select_nth_unstable_by(n / 2, f64::total_cmp).1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn small_cases() {
        assert_eq!(median(&mut []), None);
        assert_eq!(upper_median(&mut []), None);
        assert_eq!(median(&mut [3.0]), Some(3.0));
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(upper_median(&mut [4.0, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(median(&mut [5.0, -1.0, 2.0]), Some(2.0));
    }

    proptest! {
        /// Both agree with the middle of a full sort, whatever the order
        /// and the repeats of the values.
        #[test]
        fn agree_with_a_sort(mut v in prop::collection::vec(-1e3f64..1e3, 1..40)) {
            let mut sorted = v.clone();
            sorted.sort_by(f64::total_cmp);
            let n = sorted.len();
            let expected = if n % 2 == 1 {
                sorted[n / 2]
            } else {
                0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
            };
            prop_assert_eq!(upper_median(&mut v.clone()), Some(sorted[n / 2]));
            prop_assert_eq!(median(&mut v), Some(expected));
        }
    }
}
