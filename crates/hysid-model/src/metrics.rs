//! Scores of a model against data: FIT and RMSE, and, when the true model is
//! known, mode accuracy and
//! parameter error after matching identified modes to true modes with the
//! Hungarian method (Kuhn 1955; scipy's `linear_sum_assignment`, via `lsap`).

use serde::{Deserialize, Serialize};

/// `FIT = 100 (1 - |y - yhat| / |y - mean(y)|)` in percent. When `y` is
/// constant the ratio is undefined: FIT is 100 for an exact match and 0
/// otherwise.
pub fn fit(y: &[f64], yhat: &[f64]) -> f64 {
    pooled_fit(&[(y, yhat)])
}

/// The FIT of several records `(y, yhat)` together: the error over every
/// sample against the spread of each record about its own mean,
/// `100 (1 - sqrt(sum_r |y_r - yhat_r|^2) / sqrt(sum_r |y_r - mean(y_r)|^2))`.
/// It lies between the FITs of the records (of those with any spread);
/// one mean for all would count
/// the differences between the records' levels as spread a model explains
/// and put it above every one of them. One record: [`fit`].
pub fn pooled_fit(records: &[(&[f64], &[f64])]) -> f64 {
    let mut err = 0.0;
    for (y, yhat) in records {
        err += y
            .iter()
            .zip(*yhat)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>();
    }
    let err = err.sqrt();
    let den = spread(records.iter().map(|(y, _)| *y));
    if den <= f64::MIN_POSITIVE {
        return if err == 0.0 { 100.0 } else { 0.0 };
    }
    100.0 * (1.0 - err / den)
}

/// The denominator of [`pooled_fit`]: the root of the squared deviations
/// of each record about its own mean, summed over the records.
pub fn spread<'a>(records: impl Iterator<Item = &'a [f64]>) -> f64 {
    let mut den = 0.0;
    for y in records {
        let mean = y.iter().sum::<f64>() / y.len().max(1) as f64;
        den += y.iter().map(|a| (a - mean).powi(2)).sum::<f64>();
    }
    den.sqrt()
}

/// Whether FIT is undefined on these records' outputs: none varies about
/// its mean, so [`pooled_fit`] (and [`fit`]) can only say 100 or 0.
pub fn fit_undefined(records: &[&[f64]]) -> bool {
    spread(records.iter().copied()) <= f64::MIN_POSITIVE
}

/// Root-mean-square error, in the output's units.
pub fn rmse(y: &[f64], yhat: &[f64]) -> f64 {
    let n = y.len().max(1) as f64;
    (y.iter()
        .zip(yhat)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
}

/// Why identified modes could not be matched to true ones.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MatchError {
    /// The two label sequences differ in length.
    #[error("{truth} true labels against {identified} identified labels")]
    LabelCount {
        /// Number of true labels.
        truth: usize,
        /// Number of identified labels.
        identified: usize,
    },
    /// A true and an identified parameter vector differ in length.
    #[error(
        "true mode {truth} has {truth_len} parameters, identified mode {identified} has {identified_len}"
    )]
    ParameterCount {
        /// Index of the true mode.
        truth: usize,
        /// Its number of parameters.
        truth_len: usize,
        /// Index of the identified mode.
        identified: usize,
        /// Its number of parameters.
        identified_len: usize,
    },
    /// A parameter is NaN or infinite, so no distance is defined.
    #[error("a parameter of true mode {truth} or identified mode {identified} is not finite")]
    NonFinite {
        /// Index of the true mode.
        truth: usize,
        /// Index of the identified mode.
        identified: usize,
    },
    /// The assignment solver failed on a finite cost matrix.
    #[error("the assignment of identified to true modes failed ({0})")]
    Assignment(String),
}

/// Matching of identified modes to true modes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModeMatch {
    /// `pairs[i] = (true mode, identified mode)`.
    pub pairs: Vec<(usize, usize)>,
    /// Fraction of samples whose identified mode is matched to their true mode.
    pub accuracy: f64,
}

/// The assignment of rows to columns of the `nr x nc` row-major `cost`
/// (Hungarian method), as `(row, column)` pairs.
fn assign(
    nr: usize,
    nc: usize,
    cost: &Vec<f64>,
    maximize: bool,
) -> Result<Vec<(usize, usize)>, MatchError> {
    let (r, c) = lsap::solve(nr, nc, cost, maximize)
        .map_err(|e| MatchError::Assignment(format!("{e:?}")))?;
    Ok(r.into_iter().zip(c).collect())
}

/// Mode accuracy: the identified labels are matched to the true labels by
/// the assignment that maximises agreement (Hungarian method), then the
/// fraction of agreeing samples is returned.
pub fn mode_accuracy(truth: &[usize], identified: &[usize]) -> Result<ModeMatch, MatchError> {
    if truth.len() != identified.len() {
        return Err(MatchError::LabelCount {
            truth: truth.len(),
            identified: identified.len(),
        });
    }
    let nt = truth.iter().max().map_or(0, |m| m + 1);
    let ni = identified.iter().max().map_or(0, |m| m + 1);
    let mut count = vec![0.0; nt * ni];
    for (&t, &i) in truth.iter().zip(identified) {
        count[t * ni + i] += 1.0;
    }
    let pairs = assign(nt, ni, &count, true)?;
    let agree: f64 = pairs.iter().map(|&(t, i)| count[t * ni + i]).sum();
    Ok(ModeMatch {
        pairs,
        accuracy: agree / truth.len().max(1) as f64,
    })
}

/// Parameter error after matching.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterMatch {
    /// `pairs[i] = (true mode, identified mode)`.
    pub pairs: Vec<(usize, usize)>,
    /// `|theta_id - theta_true| / |theta_true|` per pair.
    pub relative_errors: Vec<f64>,
    /// Largest of `relative_errors` (infinite when a true mode is unmatched).
    pub max_relative_error: f64,
}

/// Matches identified parameter vectors to true ones (minimum total
/// relative distance, Hungarian method) and reports the relative errors.
pub fn parameter_error(
    truth: &[Vec<f64>],
    identified: &[Vec<f64>],
) -> Result<ParameterMatch, MatchError> {
    let (nt, ni) = (truth.len(), identified.len());
    let mut cost = vec![0.0; nt * ni];
    for (t, tv) in truth.iter().enumerate() {
        for (i, iv) in identified.iter().enumerate() {
            if tv.len() != iv.len() {
                return Err(MatchError::ParameterCount {
                    truth: t,
                    truth_len: tv.len(),
                    identified: i,
                    identified_len: iv.len(),
                });
            }
            let d = tv.iter().zip(iv).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
            let n = tv.iter().map(|a| a * a).sum::<f64>().sqrt();
            let rel = d.sqrt() / n.max(f64::MIN_POSITIVE);
            if !rel.is_finite() {
                return Err(MatchError::NonFinite {
                    truth: t,
                    identified: i,
                });
            }
            cost[t * ni + i] = rel;
        }
    }
    let pairs = assign(nt, ni, &cost, false)?;
    let relative_errors: Vec<f64> = pairs.iter().map(|&(t, i)| cost[t * ni + i]).collect();
    let max_relative_error = if pairs.len() < nt {
        f64::INFINITY
    } else {
        relative_errors.iter().fold(0.0, |a: f64, &b| a.max(b))
    };
    Ok(ParameterMatch {
        pairs,
        relative_errors,
        max_relative_error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The pooled FIT of records lies between the records' own FITs,
        /// whatever their levels (offset by up to 1e3 from each other: one
        /// mean for all would put it above them), and is [`fit`] for one.
        #[test]
        fn the_pooled_fit_lies_between_the_records_fits(
            records in proptest::collection::vec(
                (proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 3..40), -1e3f64..1e3),
                1..5,
            ),
        ) {
            let signals: Vec<(Vec<f64>, Vec<f64>)> = records
                .iter()
                .map(|(pairs, level)| pairs.iter().map(|&(y, e)| (y + level, y + level + 0.5 * e)).unzip())
                .collect();
            let pairs: Vec<(&[f64], &[f64])> =
                signals.iter().map(|(y, yhat)| (y.as_slice(), yhat.as_slice())).collect();
            let own: Vec<f64> = pairs.iter().map(|(y, yhat)| fit(y, yhat)).collect();
            let pooled = pooled_fit(&pairs);
            let (low, high) = own.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &f| (l.min(f), h.max(f)));
            prop_assert!(pooled >= low - 1e-9 && pooled <= high + 1e-9, "{} not in [{}, {}]", pooled, low, high);
            if pairs.len() == 1 {
                prop_assert_eq!(pooled.to_bits(), own[0].to_bits());
            }
        }

        /// FIT of a perfect prediction is 100; RMSE is 0.
        #[test]
        fn perfect_prediction_scores_100(y in proptest::collection::vec(-1e3f64..1e3, 2..50)) {
            prop_assert_eq!(fit(&y, &y), 100.0);
            prop_assert_eq!(rmse(&y, &y), 0.0);
        }

        /// FIT is invariant under affine rescaling of y and yhat together.
        #[test]
        fn fit_is_affine_invariant(y in proptest::collection::vec(-10.0f64..10.0, 3..30), s in 0.1f64..10.0, o in -5.0f64..5.0) {
            let yhat: Vec<f64> = y.iter().map(|v| 0.9 * v + 0.1).collect();
            let ys: Vec<f64> = y.iter().map(|v| s * v + o).collect();
            let yhs: Vec<f64> = yhat.iter().map(|v| s * v + o).collect();
            let (a, b) = (fit(&y, &yhat), fit(&ys, &yhs));
            prop_assert!((a - b).abs() < 1e-6 * (1.0 + a.abs()));
        }

        /// Relabelling the identified modes leaves the mode accuracy
        /// unchanged, for an imperfect labelling and any permutation; a
        /// relabelled copy of the truth scores 1.
        #[test]
        fn accuracy_is_label_invariant(
            pairs in proptest::collection::vec((0usize..3, 0usize..3), 1..60),
            perm in Just([0usize, 1, 2]).prop_shuffle(),
        ) {
            let (t, x): (Vec<usize>, Vec<usize>) = pairs.into_iter().unzip();
            let relabelled: Vec<usize> = x.iter().map(|&m| perm[m]).collect();
            let (a, b) = (mode_accuracy(&t, &x).unwrap(), mode_accuracy(&t, &relabelled).unwrap());
            prop_assert_eq!(a.accuracy, b.accuracy);
            let copy: Vec<usize> = t.iter().map(|&m| perm[m]).collect();
            prop_assert_eq!(mode_accuracy(&t, &copy).unwrap().accuracy, 1.0);
        }
    }

    #[test]
    fn fit_of_mean_is_zero_and_constant_reference() {
        let y = [1.0, 2.0, 3.0];
        assert!((fit(&y, &[2.0, 2.0, 2.0])).abs() < 1e-12);
        assert_eq!(fit(&[1.0, 1.0], &[1.0, 1.0]), 100.0);
        assert_eq!(fit(&[1.0, 1.0], &[1.0, 2.0]), 0.0);
        assert!(fit_undefined(&[&[1.0, 1.0], &[3.0]]));
        // One record that varies defines the pooled FIT.
        assert!(!fit_undefined(&[&[1.0, 1.0], &[3.0, 3.5]]));
        assert!(!fit_undefined(&[&y]));
    }

    #[test]
    fn parameter_matching_finds_permutation() {
        let truth = vec![vec![1.0, 0.0], vec![0.0, 1.0], vec![1.0, 1.0]];
        let id = vec![vec![1.0, 1.01], vec![1.0, 0.0], vec![0.0, 0.98]];
        let m = parameter_error(&truth, &id).unwrap();
        assert!(
            m.pairs.contains(&(0, 1)) && m.pairs.contains(&(1, 2)) && m.pairs.contains(&(2, 0))
        );
        assert!(m.max_relative_error < 0.021);
        assert!(
            parameter_error(&truth, &id[..2])
                .unwrap()
                .max_relative_error
                .is_infinite()
        );
    }

    #[test]
    fn a_matching_that_cannot_be_made_is_an_error() {
        let truth = vec![vec![1.0, 0.0], vec![0.0, 1.0]];
        let nan = vec![vec![f64::NAN, 0.0], vec![0.0, 1.0]];
        assert_eq!(
            parameter_error(&truth, &nan),
            Err(MatchError::NonFinite {
                truth: 0,
                identified: 0
            })
        );
        assert!(matches!(
            parameter_error(&truth, &[vec![1.0, 0.0, 0.0]]),
            Err(MatchError::ParameterCount { .. })
        ));
        assert_eq!(
            mode_accuracy(&[0, 1, 1], &[0, 1]),
            Err(MatchError::LabelCount {
                truth: 3,
                identified: 2
            })
        );
    }
}
