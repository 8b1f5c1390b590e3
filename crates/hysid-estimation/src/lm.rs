//! Levenberg-Marquardt for nonlinear least squares (Levenberg 1944,
//! Marquardt 1963), the local optimiser of the PWARX refinement: the damping
//! update of Madsen, Nielsen & Tingleff, *Methods for non-linear least
//! squares problems*, 2004, section 3.2. Each step solves
//!
//! ```text
//! min_v' |J v' - (e + J v)|^2 + mu |v' - v|^2
//! ```
//!
//! (`e` the errors, `J = d y / d v` the Jacobian of the model's outputs)
//! through the problem's own [`LeastSquares::solve`], so that constraints
//! on the unknowns (the priors' equalities and bounds) hold after every
//! step. A step is accepted only when the cost decreases; a point whose
//! cost is not finite is never accepted.
//!
//! The descent ends by the convergence tests of MINPACK's `lmder` (Moré,
//! Garbow & Hillstrom, *User guide for MINPACK-1*, 1980, section 2.3),
//! which do not depend on the units of the data:
//!
//! - **cost**: an accepted step lowered the cost by less than
//!   [`COST_TOLERANCE`] of it, and the linearisation predicted no more
//!   (`ftol`);
//! - **gradient**: the errors are nearly orthogonal to every column of the
//!   Jacobian, the cosine of their angle at most [`GRADIENT_TOLERANCE`]
//!   (`gtol`);
//! - **step**: the step is negligible against the unknowns.
//!
//! The iteration bound and the run's deadline are safety nets: each ends
//! the descent with its own [`Stop`].

use hysid_core::backend::{Budget, Deadline, Exhausted};
use nalgebra::{DMatrix, DVector};

/// The cost test: an accepted step that lowers the cost by less than this
/// fraction of it, when the linearisation predicted no more, ends the
/// descent ([`Stop::Converged`]). A relative change of `d` in the cost
/// moves a FIT of `f` percent by `(100 - f) d / 2` points: at this
/// tolerance, by less than `1e-4` points.
pub const COST_TOLERANCE: f64 = 1e-6;

/// The gradient test: when the cosine of the angle between the errors and
/// every column of the Jacobian is at most this, the point is stationary
/// ([`Stop::Converged`]).
pub const GRADIENT_TOLERANCE: f64 = 1e-8;

/// The errors of a model at a point and their Jacobian.
#[derive(Debug, Clone)]
pub struct Linearisation {
    /// Errors `y - y_model`.
    pub errors: DVector<f64>,
    /// `d y_model / d v`, one row per error.
    pub jacobian: DMatrix<f64>,
    /// Sum of squared errors; `+inf` when the model cannot be evaluated
    /// (a diverging simulation).
    pub cost: f64,
}

/// A nonlinear least-squares problem: the errors and their Jacobian at a
/// point, and the damped linearised step under the problem's constraints.
pub trait LeastSquares {
    /// Why an evaluation failed (not a diverging model, which costs
    /// `+inf`, but a problem that cannot be evaluated at all).
    type Error;
    /// Number of unknowns.
    fn unknowns(&self) -> usize;
    /// The errors, Jacobian and cost at `v`.
    fn linearise(&self, v: &[f64]) -> Result<Linearisation, Self::Error>;
    /// `argmin |design v - rhs|^2` under the problem's constraints; `None`
    /// when the subproblem fails (the step is then rejected).
    fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>>;
}

/// Why the descent ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// A convergence test held (cost, gradient or step; see the module
    /// doc), or the cost reached zero.
    Converged,
    /// No step of any damping decreased the cost.
    NoDescent,
    /// The iteration bound was reached first.
    IterationLimit,
    /// The run's deadline passed first.
    TimeBudget,
    /// The cost at the start is not finite: nothing was done.
    Diverged,
}

impl From<Exhausted> for Stop {
    fn from(end: Exhausted) -> Self {
        match end {
            Exhausted::IterationLimit => Stop::IterationLimit,
            Exhausted::TimeBudget => Stop::TimeBudget,
        }
    }
}

/// What [`levenberg_marquardt`] found.
#[derive(Debug, Clone)]
pub struct Descent {
    /// The unknowns reached (`None` when no step was accepted).
    pub v: Option<Vec<f64>>,
    /// Solved steps, accepted or not.
    pub iterations: usize,
    /// The cost at the start (`+inf` when the model diverges there).
    pub cost_before: f64,
    /// The cost at the end.
    pub cost_after: f64,
    /// How it ended.
    pub stop: Stop,
}

/// Levenberg-Marquardt on `problem` from `v` (see the module doc), at most
/// `max_iterations` solved steps, none begun after `deadline`.
pub fn levenberg_marquardt<P: LeastSquares + ?Sized>(
    problem: &P,
    mut v: Vec<f64>,
    max_iterations: usize,
    deadline: &Deadline,
) -> Result<Descent, P::Error> {
    let mut current = problem.linearise(&v)?;
    let mut descent = Descent {
        v: None,
        iterations: 0,
        cost_before: current.cost,
        cost_after: current.cost,
        stop: Stop::IterationLimit,
    };
    if !current.cost.is_finite() {
        descent.stop = Stop::Diverged;
        return Ok(descent);
    }
    let n = problem.unknowns();
    let scale = largest_gram_diagonal(&current.jacobian).max(f64::MIN_POSITIVE);
    let mut mu = 1e-3 * scale;
    let mut nu = 2.0;
    let mut accepted = false;
    let mut converged = stationary(&current);
    let mut budget = Budget::new(max_iterations, deadline);
    loop {
        if converged || current.cost == 0.0 || n == 0 {
            descent.stop = Stop::Converged;
            break;
        }
        if let Err(end) = budget.begin() {
            descent.stop = end.into();
            break;
        }
        descent.iterations = budget.taken();
        let (design, rhs) = damped_system(&current, &v, mu);
        // A failed subproblem is a rejected step: more damping.
        let trial_v = problem.solve(&design, &rhs);
        let trial = match &trial_v {
            Some(t) => {
                let vv = DVector::from_column_slice(&v);
                let step = DVector::from_iterator(n, t.iter().zip(&v).map(|(a, b)| a - b));
                if step.norm() <= 1e-14 * (vv.norm() + 1e-14) {
                    descent.stop = Stop::Converged;
                    break;
                }
                let predicted =
                    current.cost - (&current.errors - &current.jacobian * &step).norm_squared();
                Some((problem.linearise(t)?, predicted))
            }
            None => None,
        };
        match (trial, trial_v) {
            (Some((next, predicted)), Some(t)) if next.cost < current.cost => {
                let decrease = current.cost - next.cost;
                let rho = if predicted > 0.0 {
                    decrease / predicted
                } else {
                    0.0
                };
                converged = (decrease <= COST_TOLERANCE * current.cost
                    && predicted <= COST_TOLERANCE * current.cost)
                    || stationary(&next);
                v = t;
                current = next;
                accepted = true;
                mu *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                nu = 2.0;
            }
            _ => {
                mu *= nu;
                nu *= 2.0;
                if !mu.is_finite() || mu > 1e16 * scale {
                    descent.stop = Stop::NoDescent;
                    break;
                }
            }
        }
    }
    descent.cost_after = current.cost;
    descent.v = accepted.then_some(v);
    Ok(descent)
}

/// The gradient test: every column of the Jacobian at most
/// [`GRADIENT_TOLERANCE`] in cosine from the errors (a column of zeros
/// counts as orthogonal).
fn stationary(at: &Linearisation) -> bool {
    let errors = at.errors.norm();
    at.jacobian.column_iter().all(|column| {
        let scale = column.norm() * errors;
        scale == 0.0 || column.dot(&at.errors).abs() <= GRADIENT_TOLERANCE * scale
    })
}

/// The largest diagonal entry of `J^T J`: the scale of the damping.
fn largest_gram_diagonal(j: &DMatrix<f64>) -> f64 {
    (0..j.ncols())
        .map(|c| j.column(c).norm_squared())
        .fold(0.0, f64::max)
}

/// The damped step as one least-squares system,
/// `[J; sqrt(mu) I] v' = [e + J v; sqrt(mu) v]`.
fn damped_system(at: &Linearisation, v: &[f64], mu: f64) -> (DMatrix<f64>, DVector<f64>) {
    let (rows, n) = (at.jacobian.nrows(), v.len());
    let vv = DVector::from_column_slice(v);
    let target = &at.errors + &at.jacobian * &vv;
    let sm = mu.sqrt();
    let mut design = DMatrix::zeros(rows + n, n);
    design.rows_mut(0, rows).copy_from(&at.jacobian);
    let mut rhs = DVector::zeros(rows + n);
    rhs.rows_mut(0, rows).copy_from(&target);
    for c in 0..n {
        design[(rows + c, c)] = sm;
        rhs[rows + c] = sm * v[c];
    }
    (design, rhs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `y = s (exp(a t) + b)` at the points `t`, unconstrained; `s` is the
    /// unit of the outputs (1 unless a test changes it).
    struct Exponential {
        t: Vec<f64>,
        y: Vec<f64>,
        s: f64,
    }

    impl LeastSquares for Exponential {
        type Error = ();
        fn unknowns(&self) -> usize {
            2
        }
        fn linearise(&self, v: &[f64]) -> Result<Linearisation, ()> {
            let errors = DVector::from_iterator(
                self.t.len(),
                self.t
                    .iter()
                    .zip(&self.y)
                    .map(|(t, y)| y - self.s * ((v[0] * t).exp() + v[1])),
            );
            let mut jacobian = DMatrix::zeros(self.t.len(), 2);
            for (k, t) in self.t.iter().enumerate() {
                jacobian[(k, 0)] = self.s * t * (v[0] * t).exp();
                jacobian[(k, 1)] = self.s;
            }
            let cost = errors.norm_squared();
            Ok(Linearisation {
                errors,
                jacobian,
                cost,
            })
        }
        fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
            let qr = design.clone().qr();
            let x = qr.r().solve_upper_triangular(&(qr.q().transpose() * rhs))?;
            Some(x.iter().copied().collect())
        }
    }

    #[test]
    fn a_nonlinear_fit_converges_to_the_truth() {
        let t: Vec<f64> = (0..5).map(|k| k as f64 * 0.25).collect();
        let y = t.iter().map(|t| (0.7 * t).exp() - 0.3).collect();
        let problem = Exponential { t, y, s: 1.0 };
        let d = levenberg_marquardt(&problem, vec![0.0, 0.0], 100, &Deadline::none()).unwrap();
        assert_eq!(d.stop, Stop::Converged);
        let v = d.v.unwrap();
        assert!(
            (v[0] - 0.7).abs() < 1e-8 && (v[1] + 0.3).abs() < 1e-8,
            "{v:?}"
        );
        assert!(d.cost_after < 1e-16 && d.cost_before > 0.5);
        let short = levenberg_marquardt(&problem, vec![0.0, 0.0], 1, &Deadline::none()).unwrap();
        assert_eq!((short.stop, short.iterations), (Stop::IterationLimit, 1));
    }

    /// With errors that no point removes, the descent ends by a
    /// convergence test well before its bound, at a point where the
    /// gradient is small against the errors; a deadline already passed
    /// ends it before the first step.
    #[test]
    fn a_residual_fit_converges_before_its_bound_and_a_deadline_stops_it() {
        let t: Vec<f64> = (0..9).map(|k| k as f64 * 0.25).collect();
        let y = t
            .iter()
            .enumerate()
            .map(|(k, t)| (0.7 * t).exp() - 0.3 + if k % 2 == 0 { 0.05 } else { -0.05 })
            .collect();
        let problem = Exponential { t, y, s: 1.0 };
        let d = levenberg_marquardt(&problem, vec![0.0, 0.0], 1000, &Deadline::none()).unwrap();
        assert_eq!(d.stop, Stop::Converged);
        assert!(d.iterations < 100, "{}", d.iterations);
        let at = problem.linearise(d.v.as_ref().unwrap()).unwrap();
        let gradient = at.jacobian.transpose() * &at.errors;
        assert!(
            gradient.amax() <= 1e-3 * at.jacobian.norm() * at.errors.norm(),
            "{gradient}"
        );
        let passed = Deadline::at(std::time::Instant::now());
        let cut = levenberg_marquardt(&problem, vec![0.0, 0.0], 1000, &passed).unwrap();
        assert_eq!((cut.stop, cut.iterations), (Stop::TimeBudget, 0));
        assert!(cut.v.is_none());
    }

    proptest::proptest! {
        /// The convergence tests do not depend on the outputs' unit: the
        /// same record in another unit takes the same steps and ends the
        /// same way at the same point.
        #[test]
        fn the_descent_does_not_depend_on_the_unit_of_the_outputs(
            unit in -6i32..6,
            noise in proptest::collection::vec(-0.1f64..0.1, 9),
        ) {
            let t: Vec<f64> = (0..9).map(|k| k as f64 * 0.25).collect();
            let y: Vec<f64> = t.iter().zip(&noise).map(|(t, e)| (0.7 * t).exp() - 0.3 + e).collect();
            let s = 10f64.powi(unit);
            let base = Exponential { t: t.clone(), y: y.clone(), s: 1.0 };
            let scaled = Exponential { t, y: y.iter().map(|y| s * y).collect(), s };
            let a = levenberg_marquardt(&base, vec![0.0, 0.0], 200, &Deadline::none()).unwrap();
            let b = levenberg_marquardt(&scaled, vec![0.0, 0.0], 200, &Deadline::none()).unwrap();
            proptest::prop_assert_eq!((a.stop, a.iterations), (b.stop, b.iterations));
            proptest::prop_assert_eq!(a.stop, Stop::Converged);
            for (p, q) in a.v.unwrap().iter().zip(b.v.unwrap()) {
                proptest::prop_assert!((p - q).abs() <= 1e-6 * (1.0 + p.abs()), "{} {}", p, q);
            }
        }
    }
}
