//! Levenberg-Marquardt (Levenberg 1944, Marquardt 1963) on residuals in the
//! normalised box `[0, 1]^d`, with a central finite-difference Jacobian.

use crate::stages::Termination;
use hysid_core::backend::Deadline;
use nalgebra::{DMatrix, DVector};
use std::sync::atomic::{AtomicU64, Ordering};

/// Levenberg-Marquardt (Marquardt 1963) on residuals `res(z)` in the
/// normalised box `[0, 1]^d` (steps projected onto it), with a central
/// finite-difference Jacobian of step `fd`; at most `iters` iterations.
/// The damping `mu` (on the diagonal of `J^T J`) starts at `1e-3`, is
/// divided by 3 after a successful step and multiplied by 4 after a
/// failed one. Every residual evaluation is counted in `evals`.
///
/// Returns the best point, its sum of squares and why it stopped.
pub fn levenberg_marquardt(
    res: &dyn Fn(&[f64]) -> Option<Vec<f64>>,
    z0: &[f64],
    fd: f64,
    iters: usize,
    deadline: &Deadline,
    evals: &AtomicU64,
) -> (Vec<f64>, f64, Termination) {
    let sse = |e: &[f64]| e.iter().map(|x| x * x).sum::<f64>();
    let mut z = z0.to_vec();
    let Some(mut r) = res(&z) else {
        return (z, f64::INFINITY, Termination::Other);
    };
    evals.fetch_add(1, Ordering::Relaxed);
    let mut cost = sse(&r);
    let mut mu = 1e-3;
    let mut jac: Option<DMatrix<f64>> = None;
    let mut stop = Termination::MaxIterations;
    for _ in 0..iters {
        if deadline.passed() {
            stop = Termination::TimeBudget;
            break;
        }
        let j = jac.get_or_insert_with(|| jacobian(res, &z, r.len(), fd, evals));
        let Some(step) = damped_step(j, &r, mu) else {
            mu *= 10.0;
            continue;
        };
        let zn: Vec<f64> = z
            .iter()
            .zip(step.iter())
            .map(|(a, b)| (a + b).clamp(0.0, 1.0))
            .collect();
        evals.fetch_add(1, Ordering::Relaxed);
        match res(&zn) {
            Some(rn) if sse(&rn) < cost => {
                let improvement = (cost - sse(&rn)) / cost.max(f64::MIN_POSITIVE);
                z = zn;
                r = rn;
                cost = sse(&r);
                mu = (mu / 3.0).max(1e-12);
                jac = None;
                if improvement < 1e-9 {
                    stop = Termination::Converged;
                    break;
                }
            }
            _ => {
                mu *= 4.0;
                if mu > 1e8 {
                    stop = Termination::NoDecrease;
                    break;
                }
            }
        }
    }
    (z, cost, stop)
}

/// Central finite-difference Jacobian (`rows` residuals) of `res` at `z`,
/// each step clipped to the box; a column whose residuals fail stays zero.
fn jacobian(
    res: &dyn Fn(&[f64]) -> Option<Vec<f64>>,
    z: &[f64],
    rows: usize,
    fd: f64,
    evals: &AtomicU64,
) -> DMatrix<f64> {
    let d = z.len();
    let mut j = DMatrix::zeros(rows, d);
    for c in 0..d {
        let (mut zp, mut zm) = (z.to_vec(), z.to_vec());
        zp[c] = (z[c] + fd).min(1.0);
        zm[c] = (z[c] - fd).max(0.0);
        evals.fetch_add(2, Ordering::Relaxed);
        let (Some(rp), Some(rm)) = (res(&zp), res(&zm)) else {
            continue;
        };
        let h = zp[c] - zm[c];
        for k in 0..rows.min(rp.len()).min(rm.len()) {
            j[(k, c)] = (rp[k] - rm[k]) / h;
        }
    }
    j
}

/// The damped Gauss-Newton step `-(J^T J + mu (diag(J^T J) + 1e-12))^-1 J^T r`
/// (`None` when the damped matrix is not positive definite).
fn damped_step(j: &DMatrix<f64>, r: &[f64], mu: f64) -> Option<DVector<f64>> {
    let jtj = j.transpose() * j;
    let g = j.transpose() * DVector::from_column_slice(r);
    let mut a = jtj.clone();
    for c in 0..jtj.ncols() {
        a[(c, c)] += mu * (jtj[(c, c)] + 1e-12);
    }
    let ch = a.cholesky()?;
    Some(ch.solve(&(-g)))
}
