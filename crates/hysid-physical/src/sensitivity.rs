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
}

impl Sensitivity {
    /// Nothing estimable, for `d` free coordinates.
    fn undefined(d: usize) -> Self {
        Sensitivity {
            std_errors: vec![f64::NAN; d],
            sensitivity: vec![f64::NAN; d],
            condition: f64::NAN,
            jacobian: JacobianKind::CentralDifferences,
        }
    }

    /// Names of the parameters (and estimated initial states) with no
    /// effect on the simulated output under a small change: not
    /// identifiable from this record (a stop never reached), or a threshold
    /// (static friction) that no small change flips.
    pub fn insensitive(&self, map: &ParameterMap) -> Vec<String> {
        map.groups
            .iter()
            .zip(&self.sensitivity)
            .filter(|(_, s)| **s == 0.0)
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
    let (std_errors, condition) = gauss_newton_errors(&jac, s2);
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
/// output. Columns with none (e.g. a stop never reached) are not
/// identifiable from this record: left out, their error undefined (NaN).
fn gauss_newton_errors(jac: &DMatrix<f64>, s2: f64) -> (Vec<f64>, f64) {
    let (n, d) = jac.shape();
    let norms: Vec<f64> = (0..d).map(|j| jac.column(j).norm()).collect();
    let top = norms.iter().copied().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..d)
        .filter(|&j| norms[j] > 1e-9 * top && top > 0.0)
        .collect();
    let mut std_errors = vec![f64::NAN; d];
    if keep.is_empty() {
        return (std_errors, f64::NAN);
    }
    let jk = DMatrix::from_fn(n, keep.len(), |k, c| jac[(k, keep[c])]);
    let jtj = jk.transpose() * &jk;
    let sv = jtj.clone().svd(false, false).singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let condition = if smin > 0.0 {
        (smax / smin).sqrt()
    } else {
        f64::INFINITY
    };
    if let Ok(inv) = hysid_estimation::linalg::pinv(&jtj)
        && smin > 1e-14 * smax
    {
        for (c, &j) in keep.iter().enumerate() {
            std_errors[j] = (s2 * inv[(c, c)]).max(0.0).sqrt();
        }
    }
    (std_errors, condition)
}
