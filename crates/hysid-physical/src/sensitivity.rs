//! Local sensitivity and confidence of the fitted parameters: the Jacobian
//! of the free-run simulation output with respect to each free coordinate
//! (in physical units), exact from the run's forward sensitivities where
//! the model gives them, else by central differences, the Gauss-Newton
//! covariance `s^2 (J^T J)^-1` (the linear approximation of nonlinear
//! least squares: Bates and Watts 1988, *Nonlinear Regression Analysis and
//! Its Applications*, ch. 2), and which parameters the record does not
//! identify.

use crate::objective::{free_run_residuals, residual_jacobian};
use crate::parameters::ParameterMap;
use crate::target::Simulator;
use hysid_model::data::Dataset;
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Per free coordinate: standard error and scaled sensitivity; and the
/// condition of the Jacobian.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensitivity {
    /// Standard error (NaN when not estimable).
    pub std_errors: Vec<f64>,
    /// RMS change of the output per relative change of the parameter
    /// (NaN when the Jacobian could not be computed).
    pub sensitivity: Vec<f64>,
    /// Whether the coordinate changes the output over its range (`true`
    /// where the Jacobian could not be computed: not known to have none).
    pub effect: Vec<bool>,
    /// `sqrt` of the condition number of `J^T J` over the columns kept
    /// (infinite when singular, NaN when not computed).
    pub condition: f64,
    /// How the Jacobian was computed.
    pub jacobian: JacobianKind,
}

/// How a Jacobian of the residuals is computed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JacobianKind {
    /// From the runs' forward sensitivities.
    Exact,
    /// By central differences.
    #[default]
    CentralDifferences,
    /// Not computed: the time budget ran out before it.
    NotComputed,
}

impl Sensitivity {
    /// Nothing estimable, for `d` free coordinates.
    fn undefined(d: usize) -> Self {
        Sensitivity {
            std_errors: vec![f64::NAN; d],
            sensitivity: vec![f64::NAN; d],
            effect: vec![true; d],
            condition: f64::NAN,
            jacobian: JacobianKind::CentralDifferences,
        }
    }

    /// Nothing computed, for `d` free coordinates: the time budget ran
    /// out before the Jacobian.
    pub fn not_computed(d: usize) -> Self {
        Sensitivity {
            jacobian: JacobianKind::NotComputed,
            ..Self::undefined(d)
        }
    }

    /// Names of the parameters (and estimated initial states) with no
    /// effect on the simulated output under a small change: not
    /// identifiable from this record (a stop never reached), or a threshold
    /// (static friction) that no small change flips.
    pub fn insensitive(&self, map: &ParameterMap) -> Vec<String> {
        map.groups
            .iter()
            .zip(&self.effect)
            .filter(|(_, effect)| !**effect)
            .flat_map(|(g, _)| g.iter().map(|&i| map.names[i].clone()))
            .collect()
    }
}

/// The sensitivity and Gauss-Newton standard errors of the free
/// coordinates of `map` at the parameter values `values`: on the exact
/// Jacobian where `exact` and the model gives one
/// ([`residual_jacobian`]), else on central differences of `step` times
/// each coordinate's range.
pub fn sensitivity(
    model: &dyn Simulator,
    map: &ParameterMap,
    values: &[f64],
    records: &[Dataset],
    (exact, step): (bool, f64),
) -> Sensitivity {
    let d = map.dim();
    let exact = exact
        .then(|| residual_jacobian(model, values, records, 0, 0.0))
        .flatten();
    let (kind, r0, jac) = match exact {
        // d yhat / d theta = - d r / d theta
        Some((r0, jacobian)) => (JacobianKind::Exact, r0, -map.grouped(&jacobian)),
        None => {
            let Some(r0) = free_run_residuals(model, values, records) else {
                return Sensitivity::undefined(d);
            };
            let Some(jac) = output_jacobian(model, map, values, records, step, r0.len()) else {
                return Sensitivity::undefined(d);
            };
            (JacobianKind::CentralDifferences, r0, jac)
        }
    };
    let n = r0.len();
    let sse: f64 = r0.iter().map(|e| e * e).sum();
    let s2 = sse / (n.saturating_sub(d).max(1)) as f64;
    let ranges: Vec<f64> = (map.bounds.iter())
        .map(|[lo, hi]| {
            Some(hi - lo)
                .filter(|w| w.is_finite() && *w > 0.0)
                .unwrap_or(1.0)
        })
        .collect();
    let (std_errors, condition, effect) = gauss_newton_errors(&jac, &ranges, s2);
    // Scaled sensitivity: RMS change of the output per relative change of the parameter.
    let sensitivity = (0..d)
        .map(|j| {
            let x = values[map.groups[j][0]];
            jac.column(j).norm() / (n as f64).sqrt() * x.abs()
        })
        .collect();
    Sensitivity {
        std_errors,
        sensitivity,
        effect,
        condition,
        jacobian: kind,
    }
}

/// `d yhat / d theta` (`n` rows, one column per free coordinate), by
/// central differences of `step` times the coordinate's range, clipped to
/// its bounds; a coordinate with no room to move keeps a zero column.
/// `None` when a perturbed simulation fails. The columns are simulated in
/// parallel, each on its own.
fn output_jacobian(
    model: &dyn Simulator,
    map: &ParameterMap,
    values: &[f64],
    records: &[Dataset],
    step: f64,
    n: usize,
) -> Option<DMatrix<f64>> {
    let columns: Vec<Option<Option<Vec<f64>>>> = map
        .groups
        .par_iter()
        .zip(&map.bounds)
        .map(|(g, [lo, hi])| {
            let h = step * (hi - lo).max(1e-12);
            let x = values[g[0]];
            let (xp, xm) = ((x + h).min(*hi), (x - h).max(*lo));
            if xp <= xm {
                return Some(None);
            }
            let set = |val: f64| {
                let mut v = values.to_vec();
                for &i in g {
                    v[i] = val;
                }
                v
            };
            let rp = free_run_residuals(model, &set(xp), records)?;
            let rm = free_run_residuals(model, &set(xm), records)?;
            // d yhat / d theta = - d r / d theta
            Some(Some((0..n).map(|k| -(rp[k] - rm[k]) / (xp - xm)).collect()))
        })
        .collect();
    let mut jac = DMatrix::zeros(n, map.dim());
    for (j, column) in columns.into_iter().enumerate() {
        if let Some(column) = column? {
            jac.column_mut(j).copy_from_slice(&column);
        }
    }
    Some(jac)
}

/// Gauss-Newton standard errors `sqrt(s2 diag((J^T J)^-1))` and the
/// condition of `J^T J`, over the columns of `jac` with an effect on the
/// output: a column whose change of the output over its coordinate's range
/// (`ranges`, in the coordinate's unit) is below `1e-9` of the largest has
/// none (e.g. a stop never reached), and is not identifiable from this
/// record: left out, its error undefined (NaN). Whether `J^T J` is singular
/// (parameters that act only together, as a product), and its condition,
/// are judged on the columns scaled to unit norm (`J^T J` of the parameters
/// in any units alike); the columns with a part in its null space have no
/// error (NaN), and every other column keeps its own
/// ([`singular_errors`]).
fn gauss_newton_errors(jac: &DMatrix<f64>, ranges: &[f64], s2: f64) -> (Vec<f64>, f64, Vec<bool>) {
    let (n, d) = jac.shape();
    let norms: Vec<f64> = (0..d).map(|j| jac.column(j).norm()).collect();
    let effect: Vec<f64> = (0..d).map(|j| norms[j] * ranges[j]).collect();
    let top = effect.iter().copied().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..d)
        .filter(|&j| effect[j] > 1e-9 * top && top > 0.0)
        .collect();
    let kept = (0..d).map(|j| keep.contains(&j)).collect();
    let mut std_errors = vec![f64::NAN; d];
    if keep.is_empty() {
        return (std_errors, f64::NAN, kept);
    }
    // J D^-1 with D the column norms: (J^T J)^-1 = D^-1 (D^-1 J^T J D^-1)^-1 D^-1.
    let scaled = DMatrix::from_fn(n, keep.len(), |k, c| jac[(k, keep[c])] / norms[keep[c]]);
    let jtj = scaled.transpose() * &scaled;
    let sv = jtj.clone().svd(false, false).singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let condition = if smin > 0.0 {
        (smax / smin).sqrt()
    } else {
        f64::INFINITY
    };
    let variances: Vec<f64> = if smin > SINGULAR * smax {
        match hysid_estimation::linalg::pinv(&jtj) {
            Ok(inv) => (0..keep.len()).map(|c| inv[(c, c)]).collect(),
            Err(_) => vec![f64::NAN; keep.len()],
        }
    } else {
        singular_errors(jtj)
    };
    for (c, variance) in variances.into_iter().enumerate() {
        if variance.is_finite() {
            let j = keep[c];
            std_errors[j] = (s2 * variance).max(0.0).sqrt() / norms[j];
        }
    }
    (std_errors, condition, kept)
}

/// Eigenvalues of `J^T J` at most this times the largest are zero: its
/// null space (the rounding of `J^T J` alone reaches `1e-14` of it; a
/// condition of `J` above `1e6` leaves no error worth quoting).
const SINGULAR: f64 = 1e-12;

/// A part of a unit vector in the null space above this: the column acts
/// with others.
const IN_NULL_SPACE: f64 = 1e-6;

/// For a singular `jtj = J^T J`, per column: `diag((J^T J)^+)` where the
/// column has no part in the null space (the variance of a combination the
/// data determine: the column is orthogonal to every direction they do
/// not), NaN where it has one.
fn singular_errors(jtj: DMatrix<f64>) -> Vec<f64> {
    let k = jtj.ncols();
    let eig = jtj.symmetric_eigen();
    let top = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let null = |i: usize| eig.eigenvalues[i] <= SINGULAR * top;
    (0..k)
        .map(|c| {
            let in_null = (0..k)
                .filter(|&i| null(i))
                .map(|i| eig.eigenvectors[(c, i)].powi(2))
                .sum::<f64>()
                .sqrt();
            if in_null > IN_NULL_SPACE {
                return f64::NAN;
            }
            (0..k)
                .filter(|&i| !null(i))
                .map(|i| eig.eigenvectors[(c, i)].powi(2) / eig.eigenvalues[i])
                .sum()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two columns that act only together (the second twice the first)
    /// have no error; a column orthogonal to them keeps its own, the error
    /// of a fit without them; a regular Jacobian gives every column one.
    #[test]
    fn only_the_columns_that_act_together_lose_their_errors() {
        let n = 8;
        let a = |k: usize| if k.is_multiple_of(2) { 1.0 } else { -1.0 };
        let b = |k: usize| (k / 2) as f64 + 1.0;
        // `a` sums to zero against `b`'s pairs: the columns are orthogonal.
        let jac = DMatrix::from_fn(n, 3, |k, c| match c {
            0 => a(k),
            1 => b(k),
            _ => 2.0 * b(k),
        });
        let (errors, condition, _) = gauss_newton_errors(&jac, &[1.0; 3], 4.0);
        assert!(condition.is_infinite() || condition > 1e6, "{condition}");
        assert!(
            (errors[0] - 2.0 / (n as f64).sqrt()).abs() < 1e-12,
            "{errors:?}"
        );
        assert!(errors[1].is_nan() && errors[2].is_nan(), "{errors:?}");
        let regular = DMatrix::from_fn(n, 2, |k, c| if c == 0 { a(k) } else { b(k) });
        let (errors, _, _) = gauss_newton_errors(&regular, &[1.0; 2], 4.0);
        assert!(errors.iter().all(|e| e.is_finite()), "{errors:?}");
        assert!(
            (errors[0] - 2.0 / (n as f64).sqrt()).abs() < 1e-12,
            "{errors:?}"
        );
    }

    /// A parameter written in other units (its column 1e-7 times as large,
    /// its range 1e7 times as wide) gets the same verdict, the same
    /// condition and its error in its own units: the columns are judged
    /// together whatever their units. Unscaled, `J^T J` of these columns
    /// spans 1e-14 and would have been called singular.
    #[test]
    fn the_verdict_does_not_depend_on_the_units() {
        let n = 12;
        let column = |k: usize, c: usize| match c {
            0 => (k as f64 * 0.7).sin(),
            1 => (k as f64 * 0.3).cos(),
            _ => 1.0 + 0.1 * k as f64,
        };
        let jac = DMatrix::from_fn(n, 3, column);
        let (errors, condition, effect) = gauss_newton_errors(&jac, &[1.0; 3], 4.0);
        assert!(errors.iter().all(|e| e.is_finite()), "{errors:?}");
        assert_eq!(effect, [true; 3]);
        let units = 1e-7;
        let rescaled =
            DMatrix::from_fn(n, 3, |k, c| column(k, c) * if c == 0 { units } else { 1.0 });
        let (other, other_condition, _) =
            gauss_newton_errors(&rescaled, &[1.0 / units, 1.0, 1.0], 4.0);
        assert!(
            (other_condition / condition - 1.0).abs() < 1e-9,
            "{other_condition} {condition}"
        );
        for (c, (e, o)) in errors.iter().zip(&other).enumerate() {
            let expected = if c == 0 { e / units } else { *e };
            assert!(
                (o / expected - 1.0).abs() < 1e-9,
                "column {c}: {o} against {expected}"
            );
        }
    }
}
