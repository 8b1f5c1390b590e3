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
//! Simulation errors are correlated in time, so the standard error is
//! taken over the means of blocks of [`BLOCK`] consecutive samples (the
//! batch-means estimate), not over single samples.

/// Samples per block of the batch-means standard error.
pub const BLOCK: usize = 50;

/// Whether errors `e` are within one standard error of errors `best` (the
/// same selection rows, sample for sample): the mean of
/// `e(k)^2 - best(k)^2` is at most the batch-means standard error of that
/// mean. False when the lengths differ or there are fewer than two blocks.
pub fn within_one_se(e: &[f64], best: &[f64]) -> bool {
    if e.len() != best.len() {
        return false;
    }
    let d: Vec<f64> = e.iter().zip(best).map(|(a, b)| a * a - b * b).collect();
    let means: Vec<f64> = d
        .chunks_exact(BLOCK)
        .map(|c| c.iter().sum::<f64>() / BLOCK as f64)
        .collect();
    let n = means.len();
    if n < 2 {
        return false;
    }
    let mean = means.iter().sum::<f64>() / n as f64;
    let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    mean <= (var / n as f64).sqrt()
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
) -> Option<usize> {
    let &best = ranked.first()?;
    let complexity = |i: usize| modes[i].unwrap_or(usize::MAX);
    ranked
        .iter()
        .copied()
        .filter(|&i| i == best || within_one_se(&errors[i], &errors[best]))
        .min_by_key(|&i| complexity(i))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random sequence in [-1, 1].
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    #[test]
    fn equal_errors_are_within_and_clearly_larger_ones_are_not() {
        let e = noise(500, 1);
        assert!(within_one_se(&e, &e));
        let doubled: Vec<f64> = e.iter().map(|v| 2.0 * v).collect();
        assert!(!within_one_se(&doubled, &e));
        // A slightly noisier candidate on the same rows is within.
        let other = noise(500, 2);
        let close: Vec<f64> = e.iter().zip(&other).map(|(a, b)| a + 0.01 * b).collect();
        assert!(within_one_se(&close, &e));
        // Too few rows for two blocks: never within.
        assert!(!within_one_se(&e[..60], &e[..60]));
        assert!(!within_one_se(&e[..100], &e[..99]));
    }

    #[test]
    fn the_simplest_near_best_candidate_is_chosen() {
        let best = noise(500, 1);
        let other = noise(500, 2);
        let close: Vec<f64> = best.iter().zip(&other).map(|(a, b)| a + 0.01 * b).collect();
        let far: Vec<f64> = best.iter().map(|v| 3.0 * v).collect();
        // Ranked: 0 (5 modes, best), 1 (3 modes, close), 2 (1 mode, far).
        let errors = vec![best, close, far];
        let modes = vec![Some(5), Some(3), Some(1)];
        assert_eq!(simplest_within_one_se(&[0, 1, 2], &errors, &modes), Some(1));
        assert_eq!(simplest_within_one_se(&[0, 2], &errors, &modes), Some(0));
        assert_eq!(simplest_within_one_se(&[], &errors, &modes), None);
    }
}
