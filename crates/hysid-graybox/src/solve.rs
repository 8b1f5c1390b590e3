//! The Levenberg-Marquardt of the physics models, on finite-difference
//! Jacobians: the initial states a rule leaves unknown (estimated from a
//! record's warm-up outputs, [`crate::simulate::estimate`]) and the local
//! stages of the `physical` back-end, which fit the parameters in
//! box-normalised coordinates; on an exact Jacobian: the rest state of the
//! `steady` rule.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy)]
pub struct LmSettings<'a> {
    /// Box the points are projected onto (steps and finite differences);
    /// `None`: unbounded.
    pub bounds: Option<&'a [[f64; 2]]>,
    /// Finite-difference step, times `max(1, |x_i|)`.
    pub fd: f64,
    /// Iteration bound.
    pub iterations: usize,
    /// An accepted step whose relative decrease of the sum of squares is
    /// below this ends the solve ([`LmEnd::Converged`]).
    pub relative_tolerance: f64,
    /// Damping past which no step is tried ([`LmEnd::NoDecrease`]).
    pub max_damping: f64,
    /// Smallest damping after successful steps.
    pub min_damping: f64,
}

impl LmSettings<'_> {
    /// The settings of the initial-state and rest-state solves.
    pub fn states(iterations: usize) -> LmSettings<'static> {
        LmSettings {
            bounds: None,
            fd: 1e-7,
            iterations,
            relative_tolerance: 1e-15,
            max_damping: 1e10,
            min_damping: 1e-15,
        }
    }
}

/// Why [`levenberg_marquardt`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LmEnd {
    /// The sum of squares reached zero, or a step decreased it by less
    /// than the relative tolerance.
    Converged,
    /// No step decreased it, up to the largest damping.
    NoDecrease,
    /// The iteration bound was reached first.
    IterationLimit,
    /// The caller's stop request (a deadline) held.
    Stopped,
    /// The residuals could not be evaluated at the start.
    NotEvaluated,
}

/// What [`levenberg_marquardt`] reached.
#[derive(Debug, Clone)]
pub struct LmOutcome {
    /// The best point.
    pub x: Vec<f64>,
    /// Its sum of squares (`+inf` when the start could not be evaluated).
    pub cost: f64,
    /// Why the solve ended.
    pub end: LmEnd,
}

/// Levenberg-Marquardt (Levenberg 1944, Marquardt 1963) on the residuals
/// `res(x)` from `x0`: the damped Gauss-Newton step
/// `(J^T J + mu (diag(J^T J) + 1e-12)) dx = -J^T r` with a central
/// finite-difference Jacobian, projected onto the settings' box. The
/// damping starts at `1e-3`, is divided by 3 after a step that lowers the
/// sum of squares and multiplied by 4 after one that does not (by 10 when
/// the damped matrix is not positive definite). `stop` is asked before
/// every iteration; `evaluated(n)` is told of every `n` evaluations of
/// `res`.
pub fn levenberg_marquardt(
    res: &(dyn Fn(&[f64]) -> Option<Vec<f64>> + Sync),
    x0: &[f64],
    settings: &LmSettings<'_>,
    stop: &dyn Fn() -> bool,
    evaluated: &(dyn Fn(u64) + Sync),
) -> LmOutcome {
    let differences =
        |x: &[f64], rows: usize| jacobian(res, x, rows, settings.fd, settings.bounds, evaluated);
    descend(res, &differences, x0, settings, stop, evaluated)
}

/// [`levenberg_marquardt`] with the exact Jacobian `jac(x)` of the
/// residuals (one row per residual) instead of finite differences.
pub fn levenberg_marquardt_exact(
    res: &dyn Fn(&[f64]) -> Option<Vec<f64>>,
    jac: &dyn Fn(&[f64]) -> DMatrix<f64>,
    x0: &[f64],
    settings: &LmSettings<'_>,
    stop: &dyn Fn() -> bool,
) -> LmOutcome {
    descend(res, &|x, _| jac(x), x0, settings, stop, &|_| {})
}

/// `x` projected onto `bounds`, when there are bounds.
fn project_into(bounds: Option<&[[f64; 2]]>, x: &mut [f64]) {
    if let Some(b) = bounds {
        for (v, [lo, hi]) in x.iter_mut().zip(b) {
            *v = v.clamp(*lo, *hi);
        }
    }
}

/// The descent of [`levenberg_marquardt`], with the Jacobian of `jac(x,
/// rows)`.
fn descend(
    res: &dyn Fn(&[f64]) -> Option<Vec<f64>>,
    jac: &dyn Fn(&[f64], usize) -> DMatrix<f64>,
    x0: &[f64],
    settings: &LmSettings<'_>,
    stop: &dyn Fn() -> bool,
    evaluated: &dyn Fn(u64),
) -> LmOutcome {
    let sse = |e: &[f64]| e.iter().map(|v| v * v).sum::<f64>();
    let mut x = x0.to_vec();
    let Some(mut r) = res(&x) else {
        return LmOutcome {
            x,
            cost: f64::INFINITY,
            end: LmEnd::NotEvaluated,
        };
    };
    evaluated(1);
    let mut cost = sse(&r);
    let mut mu = 1e-3;
    let mut jacobian_at: Option<DMatrix<f64>> = None;
    let mut end = LmEnd::IterationLimit;
    for _ in 0..settings.iterations {
        if cost == 0.0 {
            end = LmEnd::Converged;
            break;
        }
        if stop() {
            end = LmEnd::Stopped;
            break;
        }
        let j = jacobian_at.get_or_insert_with(|| jac(&x, r.len()));
        let Some(step) = damped_step(j, &r, mu) else {
            mu *= 10.0;
            continue;
        };
        let mut xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
        project_into(settings.bounds, &mut xn);
        evaluated(1);
        match res(&xn).map(|rn| (sse(&rn), rn)) {
            Some((next, rn)) if next < cost => {
                let decrease = (cost - next) / cost;
                (x, r, cost) = (xn, rn, next);
                mu = (mu / 3.0).max(settings.min_damping);
                jacobian_at = None;
                if decrease < settings.relative_tolerance {
                    end = LmEnd::Converged;
                    break;
                }
            }
            _ => {
                mu *= 4.0;
                if mu > settings.max_damping {
                    end = LmEnd::NoDecrease;
                    break;
                }
            }
        }
    }
    LmOutcome { x, cost, end }
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

/// Central finite-difference Jacobian (`rows` residuals) of `res` at `x`
/// (step `fd max(1, |x_i|)`), the perturbed points projected onto
/// `bounds`; a column whose residuals fail stays zero. The columns are
/// evaluated in parallel, each on its own.
fn jacobian(
    res: &(dyn Fn(&[f64]) -> Option<Vec<f64>> + Sync),
    x: &[f64],
    rows: usize,
    fd: f64,
    bounds: Option<&[[f64; 2]]>,
    evaluated: &(dyn Fn(u64) + Sync),
) -> DMatrix<f64> {
    let columns: Vec<Option<Vec<f64>>> = (0..x.len())
        .into_par_iter()
        .map(|c| {
            let h = fd * x[c].abs().max(1.0);
            let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
            xp[c] += h;
            xm[c] -= h;
            project_into(bounds, &mut xp);
            project_into(bounds, &mut xm);
            let width = xp[c] - xm[c];
            if width <= 0.0 {
                return None;
            }
            evaluated(2);
            let (rp, rm) = (res(&xp)?, res(&xm)?);
            let n = rows.min(rp.len()).min(rm.len());
            Some((0..n).map(|k| (rp[k] - rm[k]) / width).collect())
        })
        .collect();
    let mut j = DMatrix::zeros(rows, x.len());
    for (c, column) in columns.into_iter().enumerate() {
        for (k, v) in column.into_iter().flatten().enumerate() {
            j[(k, c)] = v;
        }
    }
    j
}

#[cfg(test)]
mod tests {
    use super::{LmEnd, LmSettings, levenberg_marquardt, levenberg_marquardt_exact};
    use nalgebra::DMatrix;

    #[test]
    fn levenberg_marquardt_solves_a_nonlinear_system_and_keeps_to_its_bounds() {
        // x^2 = 2, x y = 3: x = sqrt 2, y = 3 / sqrt 2.
        let res = |x: &[f64]| Some(vec![x[0] * x[0] - 2.0, x[0] * x[1] - 3.0]);
        let free = LmSettings::states(100);
        let o = levenberg_marquardt(&res, &[1.0, 1.0], &free, &|| false, &|_| {});
        assert!(o.cost < 1e-24, "{}", o.cost);
        assert!((o.x[0] - 2f64.sqrt()).abs() < 1e-12);
        assert!((o.x[1] - 3.0 / 2f64.sqrt()).abs() < 1e-12);
        let boxed = LmSettings {
            bounds: Some(&[[0.0, 1.2], [0.0, 5.0]]),
            ..free
        };
        let o = levenberg_marquardt(&res, &[1.0, 1.0], &boxed, &|| false, &|_| {});
        assert!(o.x[0] <= 1.2 && o.x[0] > 1.19, "{:?}", o.x);
        // The same system on its exact Jacobian reaches the same root.
        let jac = |x: &[f64]| DMatrix::from_row_slice(2, 2, &[2.0 * x[0], 0.0, x[1], x[0]]);
        let o = levenberg_marquardt_exact(&res, &jac, &[1.0, 1.0], &free, &|| false);
        assert!(o.cost < 1e-24, "{o:?}");
        assert!((o.x[0] - 2f64.sqrt()).abs() < 1e-12);
        assert!((o.x[1] - 3.0 / 2f64.sqrt()).abs() < 1e-12);
        // A wrong Jacobian gives steps that do not descend.
        let wrong = |_: &[f64]| DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, -1.0]);
        let o = levenberg_marquardt_exact(&res, &wrong, &[1.0, 1.0], &free, &|| false);
        assert!(o.cost > 1e-6, "{o:?}");
    }

    #[test]
    fn a_stop_request_and_a_failing_start_end_the_solve() {
        let res = |x: &[f64]| Some(vec![x[0] - 1.0]);
        let s = LmSettings::states(10);
        let o = levenberg_marquardt(&res, &[0.0], &s, &|| true, &|_| {});
        assert_eq!((o.end, o.x[0]), (LmEnd::Stopped, 0.0));
        let o = levenberg_marquardt(&|_: &[f64]| None, &[0.0], &s, &|| false, &|_| {});
        assert_eq!(o.end, LmEnd::NotEvaluated);
        assert!(o.cost.is_infinite());
        let count = std::sync::atomic::AtomicU64::new(0);
        let o = levenberg_marquardt(&res, &[0.0], &s, &|| false, &|n| {
            count.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        });
        assert_eq!(o.end, LmEnd::Converged);
        // The start, two per Jacobian column, one per trial step.
        let count = count.into_inner();
        assert!(count >= 4, "{count}");
    }
}
