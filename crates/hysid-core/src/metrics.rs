//! Scores of a model against data (`docs/cli.md`, `hysid validate`):
//! FIT and RMSE of free-run simulation and one-step prediction, coverage of
//! the partition, and, when the true model is known, mode accuracy and
//! parameter error after matching identified modes to true modes with the
//! Hungarian method (Kuhn 1955; scipy's `linear_sum_assignment`, via `lsap`).

use crate::data::Dataset;
use crate::model::Model;
use crate::simulate::{SimError, Simulation, SimulationOptions, predict, simulate};
use serde::{Deserialize, Serialize};

/// `FIT = 100 (1 - |y - yhat| / |y - mean(y)|)` in percent. When `y` is
/// constant the ratio is undefined: FIT is 100 for an exact match and 0
/// otherwise.
pub fn fit(y: &[f64], yhat: &[f64]) -> f64 {
    let n = y.len().max(1) as f64;
    let mean = y.iter().sum::<f64>() / n;
    let err: f64 = y
        .iter()
        .zip(yhat)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let den: f64 = y.iter().map(|a| (a - mean).powi(2)).sum::<f64>().sqrt();
    if den <= f64::MIN_POSITIVE {
        return if err == 0.0 { 100.0 } else { 0.0 };
    }
    100.0 * (1.0 - err / den)
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

/// What `hysid validate --json` prints (`docs/cli.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationReport {
    /// Samples scored.
    pub n: usize,
    /// Samples left out at the start.
    pub warmup: usize,
    /// FIT of free-run simulation, percent.
    pub fit_sim: f64,
    /// RMSE of free-run simulation.
    pub rmse_sim: f64,
    /// FIT of one-step prediction, percent.
    pub fit_pred: f64,
    /// RMSE of one-step prediction.
    pub rmse_pred: f64,
    /// Fraction of scored (measured) regressors inside some region.
    pub coverage: f64,
    /// Fraction of scored simulation steps inside some region.
    pub coverage_sim: f64,
    /// Sample where the simulation diverged, if it did.
    pub diverged_at: Option<usize>,
    /// Scored samples per mode in the simulation (by mode index).
    pub mode_counts: Vec<usize>,
}

/// Scores `model` on `data`, leaving out the first `warmup` samples (and
/// any before the simulation can start).
pub fn validate(
    model: &Model,
    data: &Dataset,
    warmup: usize,
) -> Result<(ValidationReport, Simulation, Simulation), SimError> {
    let opts = SimulationOptions::for_data(data);
    let sim = simulate(model, data, opts)?;
    let pred = predict(model, data, opts)?;
    let first = warmup.max(sim.start).max(pred.start);
    let n_all = data.len();
    if first >= n_all {
        return Err(SimError::TooShort {
            samples: n_all,
            needed: first,
        });
    }
    let y = &data.y()[first..];
    let frac = |s: &Simulation| {
        s.covered[first..].iter().filter(|&&c| c).count() as f64 / (n_all - first) as f64
    };
    let mut mode_counts = vec![0; model.mode_count()];
    for q in sim.modes[first..].iter().flatten() {
        if let Some(c) = mode_counts.get_mut(*q) {
            *c += 1;
        }
    }
    let report = ValidationReport {
        n: n_all - first,
        warmup,
        fit_sim: fit(y, &sim.y[first..]),
        rmse_sim: rmse(y, &sim.y[first..]),
        fit_pred: fit(y, &pred.y[first..]),
        rmse_pred: rmse(y, &pred.y[first..]),
        coverage: frac(&pred),
        coverage_sim: frac(&sim),
        diverged_at: sim.diverged_at,
        mode_counts,
    };
    Ok((report, sim, pred))
}

/// Matching of identified modes to true modes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModeMatch {
    /// `pairs[i] = (true mode, identified mode)`.
    pub pairs: Vec<(usize, usize)>,
    /// Fraction of samples whose identified mode is matched to their true mode.
    pub accuracy: f64,
}

/// Mode accuracy: the identified labels are matched to the true labels by
/// the assignment that maximises agreement (Hungarian method), then the
/// fraction of agreeing samples is returned.
pub fn mode_accuracy(truth: &[usize], identified: &[usize]) -> ModeMatch {
    let nt = truth.iter().max().map_or(0, |m| m + 1);
    let ni = identified.iter().max().map_or(0, |m| m + 1);
    let mut count = vec![0.0; nt * ni];
    for (&t, &i) in truth.iter().zip(identified) {
        count[t * ni + i] += 1.0;
    }
    let pairs: Vec<(usize, usize)> = match lsap::solve(nt, ni, &count, true) {
        Ok((r, c)) => r.into_iter().zip(c).collect(),
        Err(_) => vec![],
    };
    let agree: f64 = pairs.iter().map(|&(t, i)| count[t * ni + i]).sum();
    ModeMatch {
        pairs,
        accuracy: agree / truth.len().max(1) as f64,
    }
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
pub fn parameter_error(truth: &[Vec<f64>], identified: &[Vec<f64>]) -> ParameterMatch {
    let (nt, ni) = (truth.len(), identified.len());
    let rel = |t: &[f64], i: &[f64]| -> f64 {
        let d = t
            .iter()
            .zip(i)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        let n = t.iter().map(|a| a * a).sum::<f64>().sqrt();
        d / n.max(f64::MIN_POSITIVE)
    };
    let mut cost = vec![0.0; nt * ni];
    for t in 0..nt {
        for i in 0..ni {
            cost[t * ni + i] = rel(&truth[t], &identified[i]);
        }
    }
    let pairs: Vec<(usize, usize)> = match lsap::solve(nt, ni, &cost, false) {
        Ok((r, c)) => r.into_iter().zip(c).collect(),
        Err(_) => vec![],
    };
    let relative_errors: Vec<f64> = pairs.iter().map(|&(t, i)| cost[t * ni + i]).collect();
    let max_relative_error = if pairs.len() < nt {
        f64::INFINITY
    } else {
        relative_errors.iter().fold(0.0, |a: f64, &b| a.max(b))
    };
    ParameterMatch {
        pairs,
        relative_errors,
        max_relative_error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
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

        /// Relabelling the identified modes leaves the mode accuracy unchanged.
        #[test]
        fn accuracy_is_label_invariant(t in proptest::collection::vec(0usize..3, 1..60), perm in Just([2usize, 0, 1])) {
            let relabelled: Vec<usize> = t.iter().map(|&m| perm[m]).collect();
            prop_assert_eq!(mode_accuracy(&t, &relabelled).accuracy, 1.0);
        }
    }

    #[test]
    fn fit_of_mean_is_zero_and_constant_reference() {
        let y = [1.0, 2.0, 3.0];
        assert!((fit(&y, &[2.0, 2.0, 2.0])).abs() < 1e-12);
        assert_eq!(fit(&[1.0, 1.0], &[1.0, 1.0]), 100.0);
        assert_eq!(fit(&[1.0, 1.0], &[1.0, 2.0]), 0.0);
    }

    #[test]
    fn parameter_matching_finds_permutation() {
        let truth = vec![vec![1.0, 0.0], vec![0.0, 1.0], vec![1.0, 1.0]];
        let id = vec![vec![1.0, 1.01], vec![1.0, 0.0], vec![0.0, 0.98]];
        let m = parameter_error(&truth, &id);
        assert!(
            m.pairs.contains(&(0, 1)) && m.pairs.contains(&(1, 2)) && m.pairs.contains(&(2, 0))
        );
        assert!(m.max_relative_error < 0.021);
        assert!(
            parameter_error(&truth, &id[..2])
                .max_relative_error
                .is_infinite()
        );
    }
}
