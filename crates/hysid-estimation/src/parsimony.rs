//! The one-standard-error rule: among the candidates whose selection-row
//! error is within one standard error of the best one's, take the simplest
//! (Breiman, Friedman, Olshen & Stone, *Classification and Regression
//! Trees*, 1984, section 3.4.3; Hastie, Tibshirani & Friedman, *The
//! Elements of Statistical Learning*, 2nd ed., 2009, section 7.10).
//!
//! Scores on a few hundred selection rows are noisy, and extra modes cost
//! a PWARX model nothing in simulation when the data do not need them: the
//! plain best score adds modes. Here a candidate `c` is as good as the best
//! one `b` when the mean of the paired differences of squared simulation
//! errors, `d_k = e_c(k)^2 - e_b(k)^2`, is at most its standard error.
//! How the standard error is taken depends on the errors ([`Dependence`]):
//!
//! - The simulation errors of a model with output lags are correlated in
//!   time, so the standard error is taken over the means of blocks of
//!   [`BLOCK`] consecutive samples (the batch-means estimate), not over
//!   single samples. Fewer than two blocks leave no estimate, and then no
//!   candidate is as good as the best but itself.
//! - A model without output lags (`na = 0`, a static map) simulates each
//!   sample from the inputs alone, so its errors are independent from
//!   sample to sample, and single samples are compared, which lets the rule
//!   act on a record of a few dozen rows. There one location measure alone
//!   misleads: a mean of squared differences is ruled by the few samples
//!   the best model misplaces near a region boundary (its standard error
//!   then admits even the affine model), while ranks hardly weigh the few
//!   large errors of a candidate that misses a small mode. So a candidate
//!   must pass both: the mean at most its single-sample standard error, and
//!   Wilcoxon's signed-rank statistic (Wilcoxon 1945, in its normal
//!   approximation with the tie correction, Lehmann, *Nonparametrics*,
//!   1975, section 3.2) at most one standard deviation above its mean under
//!   equal errors, the same one-sided level.

/// Samples per block of the batch-means standard error.
pub const BLOCK: usize = 50;

/// How the selection-row errors of the candidates depend on each other
/// in time, which decides how [`within_one_se`] compares them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dependence {
    /// Free-run errors of models with output lags: compared over blocks.
    Serial,
    /// Errors of models without output lags: compared sample by sample,
    /// by their mean and by their ranks.
    Independent,
}

impl Dependence {
    /// The dependence of the free-run errors of PWARX models with `na`
    /// output lags.
    pub fn of_output_lags(na: usize) -> Self {
        if na == 0 {
            Self::Independent
        } else {
            Self::Serial
        }
    }
}

/// Whether errors `e` are within one standard error of errors `best` (the
/// same selection rows, sample for sample): the mean of the differences
/// `e(k)^2 - best(k)^2` is at most its standard error, taken over blocks
/// of [`BLOCK`] samples for [`Dependence::Serial`] errors and over single
/// samples for [`Dependence::Independent`] ones, which must also have a
/// signed-rank statistic at most one standard deviation above its mean
/// ([`signed_rank_z`]). False when the lengths differ.
pub fn within_one_se(e: &[f64], best: &[f64], dependence: Dependence) -> bool {
    if e.len() != best.len() {
        return false;
    }
    let d = squared_differences(e, best);
    match dependence {
        Dependence::Serial => mean_within_batch_se(&d, BLOCK),
        Dependence::Independent => mean_within_batch_se(&d, 1) && signed_rank_z(&d) <= 1.0,
    }
}

/// The paired differences of squared errors, `e(k)^2 - best(k)^2`.
fn squared_differences(e: &[f64], best: &[f64]) -> Vec<f64> {
    e.iter().zip(best).map(|(a, b)| a * a - b * b).collect()
}

/// Whether the mean of `d` is at most its batch-means standard error over
/// batches of `block` consecutive samples (false with fewer than two).
fn mean_within_batch_se(d: &[f64], block: usize) -> bool {
    let means: Vec<f64> = d
        .chunks_exact(block)
        .map(|c| c.iter().sum::<f64>() / block as f64)
        .collect();
    let n = means.len();
    if n < 2 {
        return false;
    }
    let mean = means.iter().sum::<f64>() / n as f64;
    let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    mean <= (var / n as f64).sqrt()
}

/// Wilcoxon's signed-rank statistic of the paired differences `d`,
/// standardised: `(W+ - n(n+1)/4) / sd`, where `W+` sums the ranks of
/// `|d|` over the positive differences, `n` counts the non-zero ones, and
/// the variance `n(n+1)(2n+1)/24` is lowered by `(t^3 - t)/48` for every
/// group of `t` tied magnitudes (average ranks). Zero when every
/// difference is zero.
pub fn signed_rank_z(d: &[f64]) -> f64 {
    let mut nonzero: Vec<f64> = d.iter().copied().filter(|x| *x != 0.0).collect();
    nonzero.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    let n = nonzero.len();
    let (mut positive, mut ties) = (0.0, 0.0);
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        while j < n && nonzero[j].abs() == nonzero[i].abs() {
            j += 1;
        }
        // Ranks i+1 ..= j share their average.
        let rank = (i + 1 + j) as f64 / 2.0;
        positive += rank * nonzero[i..j].iter().filter(|x| **x > 0.0).count() as f64;
        let t = (j - i) as f64;
        ties += t * t * t - t;
        i = j;
    }
    let n = n as f64;
    let var = n * (n + 1.0) * (2.0 * n + 1.0) / 24.0 - ties / 48.0;
    if var <= 0.0 {
        return 0.0;
    }
    (positive - n * (n + 1.0) / 4.0) / var.sqrt()
}

/// The candidate to choose: among `ranked` (candidate indices, best
/// selection score first) those whose errors are within one standard
/// error of the first one's, the one of fewest modes (`modes[i]`), the
/// better ranked among equals. `errors[i]` are candidate `i`'s simulation
/// errors on the selection rows.
pub fn simplest_within_one_se(
    ranked: &[usize],
    errors: &[Vec<f64>],
    modes: &[Option<usize>],
    dependence: Dependence,
) -> Option<usize> {
    let &best = ranked.first()?;
    let complexity = |i: usize| modes[i].unwrap_or(usize::MAX);
    ranked
        .iter()
        .copied()
        .filter(|&i| i == best || within_one_se(&errors[i], &errors[best], dependence))
        .min_by_key(|&i| complexity(i))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_testkit::uniform;

    /// `e` with neighbouring samples swapped (0 and 1, 2 and 3, ...): the
    /// same errors on other rows, so the differences of squared errors
    /// cancel pair by pair, exactly.
    fn swapped_pairs(e: &[f64]) -> Vec<f64> {
        let mut s = e.to_vec();
        for pair in s.chunks_exact_mut(2) {
            pair.swap(0, 1);
        }
        s
    }

    #[test]
    fn equal_errors_are_within_and_clearly_larger_ones_are_not() {
        let e = uniform(500, 1);
        let serial = Dependence::Serial;
        assert!(within_one_se(&e, &e, serial));
        let doubled: Vec<f64> = e.iter().map(|v| 2.0 * v).collect();
        assert!(!within_one_se(&doubled, &e, serial));
        // The same errors on other rows: within.
        assert!(within_one_se(&swapped_pairs(&e), &e, serial));
        // Too few rows for two blocks: never within.
        assert!(!within_one_se(&e[..60], &e[..60], serial));
        assert!(!within_one_se(&e[..100], &e[..99], serial));
    }

    /// Over 200 draws, a candidate whose errors are the best's plus 1 % of
    /// independent noise (differences that are noise, with a mean of a
    /// tenth of their standard error) is within in most draws: the one-sided
    /// level of one standard error is 84 % for each test. One with half the
    /// best's noise on top (the mean about five standard errors up) is
    /// never within.
    #[test]
    fn noisier_candidates_are_within_at_the_level_of_one_standard_error() {
        for dependence in [Dependence::Serial, Dependence::Independent] {
            let (mut close, mut noisy) = (0, 0);
            for draw in 0..200 {
                let best = uniform(500, 2 * draw);
                let other = uniform(500, 2 * draw + 1);
                let plus = |s: f64| -> Vec<f64> {
                    best.iter().zip(&other).map(|(a, b)| a + s * b).collect()
                };
                close += usize::from(within_one_se(&plus(0.01), &best, dependence));
                noisy += usize::from(within_one_se(&plus(0.5), &best, dependence));
            }
            assert!(
                (120..=190).contains(&close),
                "{dependence:?}: {close} of 200"
            );
            assert_eq!(noisy, 0, "{dependence:?}");
        }
    }

    #[test]
    fn the_signed_rank_statistic_matches_hand_computed_values() {
        // Ranks 1, 2, 3, 4; W+ = 1 + 3 + 4 = 8, mean 5, variance 7.5.
        let z = signed_rank_z(&[1.0, -2.0, 3.0, 4.0]);
        assert!((z - 3.0 / 7.5f64.sqrt()).abs() < 1e-12, "{z}");
        // A tie shares ranks 1 and 2 (1.5 each) and a zero is left out:
        // W+ = 1.5 + 3 = 4.5, mean 3, variance 3.5 - (8 - 2)/48.
        let z = signed_rank_z(&[1.0, 0.0, -1.0, 2.0]);
        assert!(
            (z - 1.5 / (3.5f64 - 6.0 / 48.0).sqrt()).abs() < 1e-12,
            "{z}"
        );
        assert_eq!(signed_rank_z(&[0.0, 0.0]), 0.0);
        assert_eq!(signed_rank_z(&[]), 0.0);
    }

    #[test]
    fn independent_errors_are_compared_by_mean_and_ranks_on_short_records() {
        let independent = Dependence::Independent;
        let best = uniform(24, 1);
        // Equal errors: within, however short the record.
        assert!(within_one_se(&best, &best, independent));
        // A split mode: equal errors but for two samples, one better, one
        // worse. Within.
        let mut split = best.clone();
        split[3] *= 1.5;
        split[17] *= 0.5;
        assert!(within_one_se(&split, &best, independent));
        // Larger on every sample: not within.
        let larger: Vec<f64> = best.iter().map(|v| 1.2 * v).collect();
        assert!(!within_one_se(&larger, &best, independent));
        // Larger on every sample but one, where the best has a boundary
        // error ten times the rest: the mean of squared differences is
        // negative (the candidate looks better), the ranks say worse.
        let mut spiked = best.clone();
        spiked[5] = 10.0;
        let mut candidate: Vec<f64> = best.iter().map(|v| 1.2 * v).collect();
        candidate[5] = best[5];
        let d = squared_differences(&candidate, &spiked);
        assert!(d.iter().sum::<f64>() < 0.0);
        assert!(signed_rank_z(&d) > 1.0);
        assert!(!within_one_se(&candidate, &spiked, independent));
        // A missed small mode on 60 rows: the best's errors on other rows
        // (differences that cancel pair by pair) but for three samples with
        // errors ten times the best's largest. Three ranks of 57 move the
        // rank statistic by two thirds of its standard deviation; the mean
        // moves by more than its standard error.
        let base = uniform(60, 2);
        let mut missed = swapped_pairs(&base);
        for k in [2, 9, 20] {
            missed[k] = 10.0;
            missed[k ^ 1] = base[k ^ 1];
        }
        let d = squared_differences(&missed, &base);
        assert!(signed_rank_z(&d) <= 1.0, "{}", signed_rank_z(&d));
        assert!(!within_one_se(&missed, &base, independent));
        // The block rule cannot act on 24 samples.
        assert!(!within_one_se(&split, &best, Dependence::Serial));
    }

    #[test]
    fn the_simplest_near_best_candidate_is_chosen() {
        let best = uniform(500, 1);
        let close = swapped_pairs(&best);
        let far: Vec<f64> = best.iter().map(|v| 3.0 * v).collect();
        // Ranked: 0 (5 modes, best), 1 (3 modes, close), 2 (1 mode, far).
        let errors = vec![best, close, far];
        let modes = vec![Some(5), Some(3), Some(1)];
        for dependence in [Dependence::Serial, Dependence::Independent] {
            let choose =
                |ranked: &[usize]| simplest_within_one_se(ranked, &errors, &modes, dependence);
            assert_eq!(choose(&[0, 1, 2]), Some(1));
            assert_eq!(choose(&[0, 2]), Some(0));
            assert_eq!(choose(&[]), None);
        }
    }
}
