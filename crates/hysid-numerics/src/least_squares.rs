//! Levenberg-Marquardt for nonlinear least squares (Levenberg 1944,
//! Marquardt 1963), the one local optimiser of hysid's least-squares
//! problems: the PWARX refinement (exact Jacobians, the priors' constraints
//! in every step), the `physical` back-end's local stages and the gray-box
//! initial states ([`Residuals`]: finite-difference or exact Jacobians,
//! each step the damped subproblem's minimum in a box). The damping update
//! is the one of Madsen, Nielsen & Tingleff, *Methods for non-linear least
//! squares problems*, 2004, section 3.2. Each step solves
//!
//! ```text
//! min_v' |J v' - (e + J v)|^2 + mu |v' - v|^2
//! ```
//!
//! (`e` the errors, `J = d y / d v` the Jacobian of the model's outputs, so
//! that the errors after a step `s` are about `e - J s`; with
//! [`Damping::Marquardt`] the damping term is `mu |D (v' - v)|^2`, `D` the
//! columns' norms) through the
//! problem's own [`LeastSquares::solve`], so that constraints on the
//! unknowns hold after every step. A step is accepted only when the cost
//! decreases; a point whose cost is not finite is never accepted. The
//! Jacobian is asked for at the start and at accepted points only: a
//! problem whose Jacobian costs many evaluations (finite differences) pays
//! nothing for a rejected step beyond its errors. At each accepted point a
//! Jacobian of more than twice as many rows as columns is factored once,
//! `J = Q R`, and every step there is solved on the `2 n` rows of `R` and
//! the damping instead of the `m + n` of `J` and the damping: the same
//! minimiser (MINPACK's `lmpar`, Moré 1978), at the cost of one small
//! system per trial.
//!
//! The descent ends by the convergence tests of MINPACK's `lmder` (Moré,
//! Garbow & Hillstrom, *User guide for MINPACK-1*, 1980, section 2.3),
//! which do not depend on the units of the data:
//!
//! - **cost**: an accepted step lowered the cost by less than
//!   [`LmSettings::cost_tolerance`] of it, and the linearisation predicted
//!   no more (`ftol`);
//! - **gradient**: the errors are nearly orthogonal to every column of the
//!   Jacobian, the cosine of their angle at most [`GRADIENT_TOLERANCE`]
//!   (`gtol`);
//! - **step**: the step is negligible against the unknowns.
//!
//! The iteration bound and the run's deadline are safety nets
//! ([`Budget`]): each ends the descent with its own [`Stop`].

use crate::box_least_squares::{self, unconstrained};
use crate::budget::{Budget, Deadline, Exhausted};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::convert::Infallible;

/// The cost test's default tolerance ([`LmSettings::new`]): a relative
/// change of `d` in the cost moves a FIT of `f` percent by `(100 - f) d /
/// 2` points: at this tolerance, by less than `1e-4` points.
pub const COST_TOLERANCE: f64 = 1e-6;

/// The gradient test: when the cosine of the angle between the errors and
/// every column of the Jacobian is at most this, the point is stationary
/// ([`Stop::Converged`]).
pub const GRADIENT_TOLERANCE: f64 = 1e-8;

/// How the step is damped: the metric of the damping term.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    /// Levenberg's `mu |v' - v|^2`, `mu` starting at `1e-3` times the
    /// largest diagonal entry of `J^T J`: for unknowns of one scale.
    Identity,
    /// Marquardt's `mu |D (v' - v)|^2`, `D` the norms of the Jacobian's
    /// columns at the current point (the diagonal of `J^T J`, plus `1e-12`,
    /// square-rooted; MINPACK's `mode = 1` keeps their running maximum
    /// instead), `mu` starting at `1e-3`: a step that does not depend on
    /// the unknowns' scales.
    Marquardt,
}

/// The bounds and the damping of a descent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmSettings {
    /// At most this many solved steps, accepted or not.
    pub iterations: usize,
    /// The cost test's relative tolerance (`ftol`).
    pub cost_tolerance: f64,
    /// The damping term's metric.
    pub damping: Damping,
}

impl LmSettings {
    /// At most `iterations` steps, the cost test at [`COST_TOLERANCE`],
    /// [`Damping::Identity`].
    pub fn new(iterations: usize) -> Self {
        Self {
            iterations,
            cost_tolerance: COST_TOLERANCE,
            damping: Damping::Identity,
        }
    }

    /// The same, with the cost test at `tolerance`.
    pub fn with_cost_tolerance(self, tolerance: f64) -> Self {
        Self {
            cost_tolerance: tolerance,
            ..self
        }
    }

    /// The same, damped by `damping`.
    pub fn with_damping(self, damping: Damping) -> Self {
        Self { damping, ..self }
    }
}

/// The errors of a model at a point, and their Jacobian when the problem
/// forms it with them.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Errors `y - y_model`.
    pub errors: DVector<f64>,
    /// `d y_model / d v`, one row per error; `None`: asked for by
    /// [`LeastSquares::jacobian`] when the point is accepted.
    pub jacobian: Option<DMatrix<f64>>,
    /// Sum of squared errors; `+inf` when the model cannot be evaluated
    /// (a diverging simulation).
    pub cost: f64,
}

impl Evaluation {
    /// A point where the model cannot be evaluated.
    pub fn failed() -> Self {
        Self {
            errors: DVector::zeros(0),
            jacobian: None,
            cost: f64::INFINITY,
        }
    }

    /// The errors `errors` (their cost `+inf` unless all are finite),
    /// without a Jacobian.
    pub fn of_errors(errors: Vec<f64>) -> Self {
        let cost = if errors.iter().all(|e| e.is_finite()) {
            errors.iter().map(|e| e * e).sum()
        } else {
            f64::INFINITY
        };
        Self {
            errors: DVector::from_vec(errors),
            jacobian: None,
            cost,
        }
    }
}

/// A nonlinear least-squares problem: the errors (and possibly their
/// Jacobian) at a point, the Jacobian on its own, and the damped
/// linearised step under the problem's constraints.
pub trait LeastSquares {
    /// Why an evaluation failed (not a diverging model, which costs
    /// `+inf`, but a problem that cannot be evaluated at all).
    type Error;
    /// Number of unknowns.
    fn unknowns(&self) -> usize;
    /// The errors and cost at `v`, with the Jacobian if it comes with them.
    fn evaluate(&self, v: &[f64]) -> Result<Evaluation, Self::Error>;
    /// The Jacobian `d y_model / d v` at `v`, where [`Self::evaluate`]
    /// left it out.
    fn jacobian(&self, v: &[f64]) -> Result<DMatrix<f64>, Self::Error>;
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

/// A point of the descent with its Jacobian.
#[derive(Clone)]
struct Linearisation {
    errors: DVector<f64>,
    jacobian: DMatrix<f64>,
    cost: f64,
    /// `J = Q R` ([`Reduced::of`]), when `J` has more rows than twice its
    /// columns and is finite.
    reduced: Option<Reduced>,
}

/// The linearisation reduced to the columns' dimension: `J = Q R` (Q with
/// orthonormal columns, `R` square upper triangular) and `Q^T e`. Every
/// damped step at the point minimises `|J v' - (e + J v)|^2 + |D (v' -
/// v)|^2`, which differs from `|R v' - (Q^T e + R v)|^2 + |D (v' - v)|^2`
/// by a constant (`|e|^2 - |Q^T e|^2`), so both have the same minimiser
/// under any constraints on `v'`: the steps are solved on `2 n` rows
/// instead of `m + n`, the factorisation paid once per accepted point
/// (MINPACK's `lmder` with `lmpar`, Moré 1978).
#[derive(Clone)]
struct Reduced {
    r: DMatrix<f64>,
    qt_errors: DVector<f64>,
}

impl Reduced {
    /// The reduction of `jacobian` and `errors`, when `jacobian` has more
    /// than twice as many rows as columns and is finite.
    fn of(jacobian: &DMatrix<f64>, errors: &DVector<f64>) -> Option<Self> {
        let n = jacobian.ncols();
        if n == 0 || jacobian.nrows() <= 2 * n || jacobian.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let qr = jacobian.clone().qr();
        let mut qt_errors = errors.clone();
        qr.q_tr_mul(&mut qt_errors);
        qt_errors.resize_vertically_mut(n, 0.0);
        Some(Self {
            r: qr.r(),
            qt_errors,
        })
    }
}

/// `at` with its Jacobian, asked of `problem` when `at` came without one,
/// with as many rows as `at` has errors.
fn linearised<P: LeastSquares + ?Sized>(
    problem: &P,
    v: &[f64],
    at: Evaluation,
) -> Result<Linearisation, P::Error> {
    let mut jacobian = match at.jacobian {
        Some(j) => j,
        None => problem.jacobian(v)?,
    };
    // Rows a Jacobian lacks (its residuals failed) count as zeros.
    if jacobian.nrows() != at.errors.len() {
        let columns = jacobian.ncols();
        jacobian = jacobian.resize(at.errors.len(), columns, 0.0);
    }
    Ok(Linearisation {
        reduced: Reduced::of(&jacobian, &at.errors),
        errors: at.errors,
        jacobian,
        cost: at.cost,
    })
}

/// Levenberg-Marquardt on `problem` from `v` (see the module doc), at most
/// `settings.iterations` solved steps, none begun after `deadline`.
pub fn levenberg_marquardt<P: LeastSquares + ?Sized>(
    problem: &P,
    v: Vec<f64>,
    settings: &LmSettings,
    deadline: &Deadline,
) -> Result<Descent, P::Error> {
    let mut descent = Marquardt::start(problem, v, settings, deadline)?;
    descent.advance(usize::MAX)?;
    Ok(descent.finish())
}

/// A Levenberg-Marquardt descent in progress, advanced a given number of
/// steps at a time: [`Marquardt::start`], [`Marquardt::advance`] as often
/// as wanted, [`Marquardt::finish`]. Its iterates are those of one
/// [`levenberg_marquardt`] call, however its steps are grouped, so a caller
/// can run several descents side by side and stop some between rounds.
pub struct Marquardt<'a, P: LeastSquares + ?Sized> {
    problem: &'a P,
    settings: LmSettings,
    budget: Budget<'a>,
    descent: Descent,
    /// The current point.
    v: Vec<f64>,
    /// Whether a step was accepted.
    accepted: bool,
    /// The point's linearisation and the damping, while it runs.
    running: Option<Running>,
    /// The damping's scale ([`Damping::Identity`]), or 1.
    scale: f64,
}

/// The state of a [`Marquardt`] descent between its steps.
struct Running {
    current: Linearisation,
    mu: f64,
    nu: f64,
    converged: bool,
}

impl<'a, P: LeastSquares + ?Sized> Marquardt<'a, P> {
    /// The descent from `v`: its errors, and its Jacobian unless it can
    /// take no step (a start whose cost is not finite, or past the
    /// deadline).
    pub fn start(
        problem: &'a P,
        v: Vec<f64>,
        settings: &LmSettings,
        deadline: &'a Deadline,
    ) -> Result<Self, P::Error> {
        let start = problem.evaluate(&v)?;
        let mut descent = Marquardt {
            problem,
            settings: *settings,
            budget: Budget::new(settings.iterations, deadline),
            descent: Descent {
                v: None,
                iterations: 0,
                cost_before: start.cost,
                cost_after: start.cost,
                stop: Stop::IterationLimit,
            },
            v,
            accepted: false,
            running: None,
            scale: 1.0,
        };
        if !start.cost.is_finite() {
            descent.descent.stop = Stop::Diverged;
            return Ok(descent);
        }
        // No Jacobian (often the costliest evaluation) for a descent that
        // could take no step.
        if settings.iterations > 0 && deadline.passed() {
            descent.descent.stop = Stop::TimeBudget;
            return Ok(descent);
        }
        let current = linearised(problem, &descent.v, start)?;
        descent.scale = match settings.damping {
            Damping::Identity => largest_gram_diagonal(&current.jacobian).max(f64::MIN_POSITIVE),
            Damping::Marquardt => 1.0,
        };
        descent.running = Some(Running {
            converged: stationary(&current),
            mu: 1e-3 * descent.scale,
            nu: 2.0,
            current,
        });
        Ok(descent)
    }

    /// The cost at the current point.
    pub fn cost(&self) -> f64 {
        self.descent.cost_after
    }

    /// Why it ended, once it has.
    pub fn stopped(&self) -> Option<Stop> {
        self.running.is_none().then_some(self.descent.stop)
    }

    /// At most `steps` more solved steps; why the descent ended, if it has.
    pub fn advance(&mut self, steps: usize) -> Result<Option<Stop>, P::Error> {
        for _ in 0..steps {
            let Some(mut at) = self.running.take() else {
                break;
            };
            match self.step(&mut at)? {
                Some(stop) => self.descent.stop = stop,
                None => self.running = Some(at),
            }
        }
        Ok(self.stopped())
    }

    /// One solved step from `at` (or the test that ends the descent
    /// before it).
    fn step(&mut self, at: &mut Running) -> Result<Option<Stop>, P::Error> {
        let n = self.problem.unknowns();
        if at.converged || at.current.cost == 0.0 || n == 0 {
            return Ok(Some(Stop::Converged));
        }
        if let Err(end) = self.budget.begin() {
            return Ok(Some(end.into()));
        }
        self.descent.iterations = self.budget.taken();
        let (design, rhs) = damped_system(&at.current, &self.v, at.mu, self.settings.damping);
        // A failed subproblem is a rejected step: more damping.
        let trial_v = self.problem.solve(&design, &rhs);
        let trial = match &trial_v {
            Some(t) => {
                let vv = DVector::from_column_slice(&self.v);
                let step = DVector::from_iterator(n, t.iter().zip(&self.v).map(|(a, b)| a - b));
                if step.norm() <= 1e-14 * (vv.norm() + 1e-14) {
                    return Ok(Some(Stop::Converged));
                }
                let predicted = at.current.cost
                    - (&at.current.errors - &at.current.jacobian * &step).norm_squared();
                Some((self.problem.evaluate(t)?, predicted))
            }
            None => None,
        };
        match (trial, trial_v) {
            (Some((next, predicted)), Some(t)) if next.cost < at.current.cost => {
                let decrease = at.current.cost - next.cost;
                let rho = if predicted > 0.0 {
                    decrease / predicted
                } else {
                    0.0
                };
                let next = linearised(self.problem, &t, next)?;
                let tolerance = self.settings.cost_tolerance * at.current.cost;
                at.converged =
                    (decrease <= tolerance && predicted <= tolerance) || stationary(&next);
                self.descent.cost_after = next.cost;
                self.accepted = true;
                self.v = t;
                at.current = next;
                at.mu *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                at.nu = 2.0;
            }
            _ => {
                at.mu *= at.nu;
                at.nu *= 2.0;
                if !at.mu.is_finite() || at.mu > 1e16 * self.scale {
                    return Ok(Some(Stop::NoDescent));
                }
            }
        }
        Ok(None)
    }

    /// What the descent found; one still running ends at its iteration
    /// bound's [`Stop::IterationLimit`] (its steps cut short by the caller).
    pub fn finish(self) -> Descent {
        Descent {
            v: self.accepted.then_some(self.v),
            ..self.descent
        }
    }
}

/// [`levenberg_marquardt`] on a problem whose evaluations cannot fail
/// ([`Residuals`]).
pub fn descend<P: LeastSquares<Error = Infallible> + ?Sized>(
    problem: &P,
    v: Vec<f64>,
    settings: &LmSettings,
    deadline: &Deadline,
) -> Descent {
    match levenberg_marquardt(problem, v, settings, deadline) {
        Ok(descent) => descent,
        Err(never) => match never {},
    }
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
/// `[J; sqrt(mu) D] v' = [e + J v; sqrt(mu) D v]` (`D = I` for
/// [`Damping::Identity`]).
fn damped_system(
    at: &Linearisation,
    v: &[f64],
    mu: f64,
    damping: Damping,
) -> (DMatrix<f64>, DVector<f64>) {
    let n = v.len();
    let vv = DVector::from_column_slice(v);
    let (top, target) = match &at.reduced {
        Some(reduced) => (&reduced.r, &reduced.qt_errors + &reduced.r * &vv),
        None => (&at.jacobian, &at.errors + &at.jacobian * &vv),
    };
    let rows = top.nrows();
    let sm = mu.sqrt();
    let mut design = DMatrix::zeros(rows + n, n);
    design.rows_mut(0, rows).copy_from(top);
    let mut rhs = DVector::zeros(rows + n);
    rhs.rows_mut(0, rows).copy_from(&target);
    for c in 0..n {
        let d = match damping {
            Damping::Identity => sm,
            Damping::Marquardt => sm * (at.jacobian.column(c).norm_squared() + 1e-12).sqrt(),
        };
        design[(rows + c, c)] = d;
        rhs[rows + c] = d * v[c];
    }
    (design, rhs)
}

/// The problem of driving residuals `r(x)` (a closure; `None` where they
/// cannot be evaluated) to zero in least squares, the steps solved in an
/// optional box ([`box_least_squares::in_box`]), with the Jacobian
/// `d r / d x` formed by `J` ([`CentralDifferences`] or [`Exact`]).
pub struct Residuals<'a, F, J> {
    residuals: F,
    unknowns: usize,
    bounds: Option<&'a [[f64; 2]]>,
    jacobian: J,
}

impl<'a, F: Fn(&[f64]) -> Option<Vec<f64>>, J: ResidualJacobian<F>> Residuals<'a, F, J> {
    /// The residuals `residuals` of `unknowns` unknowns, in `bounds` when
    /// given, their Jacobian by `jacobian`.
    pub fn new(residuals: F, unknowns: usize, bounds: Option<&'a [[f64; 2]]>, jacobian: J) -> Self {
        Self {
            residuals,
            unknowns,
            bounds,
            jacobian,
        }
    }
}

impl<F: Fn(&[f64]) -> Option<Vec<f64>>, J: ResidualJacobian<F>> LeastSquares
    for Residuals<'_, F, J>
{
    type Error = Infallible;

    fn unknowns(&self) -> usize {
        self.unknowns
    }

    fn evaluate(&self, x: &[f64]) -> Result<Evaluation, Self::Error> {
        Ok((self.residuals)(x).map_or_else(Evaluation::failed, Evaluation::of_errors))
    }

    /// `-d r / d x`: the errors are the residuals, the model's outputs
    /// their negatives.
    fn jacobian(&self, x: &[f64]) -> Result<DMatrix<f64>, Self::Error> {
        Ok(-self.jacobian.of(&self.residuals, x, self.bounds))
    }

    /// The damped step in the box ([`box_least_squares::in_box`]), where
    /// there is one.
    fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
        match self.bounds {
            Some(bounds) => box_least_squares::in_box(design, rhs, bounds),
            None => unconstrained(design, rhs),
        }
    }
}

/// How a [`Residuals`] problem forms the Jacobian `d r / d x` of its
/// residuals `F` (one row per residual).
pub trait ResidualJacobian<F> {
    /// The Jacobian at `x`, the points it evaluates kept in `bounds`.
    fn of(&self, residuals: &F, x: &[f64], bounds: Option<&[[f64; 2]]>) -> DMatrix<f64>;
}

/// Central differences of step `step max(1, |x_i|)`, the columns
/// evaluated in parallel.
#[derive(Debug, Clone, Copy)]
pub struct CentralDifferences {
    /// The relative step.
    pub step: f64,
}

impl<F: Fn(&[f64]) -> Option<Vec<f64>> + Sync> ResidualJacobian<F> for CentralDifferences {
    /// `(r(x + h e_c) - r(x - h e_c)) / width`, the perturbed points
    /// projected onto the box (`width` their distance); a column whose
    /// residuals fail, or whose points coincide, stays zero.
    fn of(&self, residuals: &F, x: &[f64], bounds: Option<&[[f64; 2]]>) -> DMatrix<f64> {
        let columns: Vec<Option<Vec<f64>>> = (0..x.len())
            .into_par_iter()
            .map(|c| {
                let h = self.step * x[c].abs().max(1.0);
                let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
                xp[c] += h;
                xm[c] -= h;
                project_into(bounds, &mut xp);
                project_into(bounds, &mut xm);
                let width = xp[c] - xm[c];
                if width <= 0.0 {
                    return None;
                }
                let (rp, rm) = (residuals(&xp)?, residuals(&xm)?);
                Some(rp.iter().zip(&rm).map(|(p, m)| (p - m) / width).collect())
            })
            .collect();
        let rows = columns.iter().flatten().map(Vec::len).max().unwrap_or(0);
        let mut j = DMatrix::zeros(rows, x.len());
        for (c, column) in columns.into_iter().enumerate() {
            for (k, v) in column.into_iter().flatten().enumerate() {
                j[(k, c)] = v;
            }
        }
        j
    }
}

/// The exact Jacobian, a closure of the point.
#[derive(Debug, Clone, Copy)]
pub struct Exact<G>(pub G);

impl<F, G: Fn(&[f64]) -> DMatrix<f64>> ResidualJacobian<F> for Exact<G> {
    fn of(&self, _: &F, x: &[f64], _: Option<&[[f64; 2]]>) -> DMatrix<f64> {
        (self.0)(x)
    }
}

/// `x` projected onto `bounds`, when there are bounds.
fn project_into(bounds: Option<&[[f64; 2]]>, x: &mut [f64]) {
    if let Some(b) = bounds {
        for (v, [lo, hi]) in x.iter_mut().zip(b) {
            *v = v.clamp(*lo, *hi);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::strategy::{Just, Strategy};

    fn none() -> Deadline {
        Deadline::none()
    }

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
        fn evaluate(&self, v: &[f64]) -> Result<Evaluation, ()> {
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
            Ok(Evaluation {
                errors,
                jacobian: Some(jacobian),
                cost,
            })
        }
        fn jacobian(&self, v: &[f64]) -> Result<DMatrix<f64>, ()> {
            Ok(self.evaluate(v)?.jacobian.unwrap_or_default())
        }
        fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
            unconstrained(design, rhs)
        }
    }

    #[test]
    fn a_nonlinear_fit_converges_to_the_truth() {
        let t: Vec<f64> = (0..5).map(|k| k as f64 * 0.25).collect();
        let y = t.iter().map(|t| (0.7 * t).exp() - 0.3).collect();
        let problem = Exponential { t, y, s: 1.0 };
        let d =
            levenberg_marquardt(&problem, vec![0.0, 0.0], &LmSettings::new(100), &none()).unwrap();
        assert_eq!(d.stop, Stop::Converged);
        let v = d.v.unwrap();
        assert!(
            (v[0] - 0.7).abs() < 1e-8 && (v[1] + 0.3).abs() < 1e-8,
            "{v:?}"
        );
        assert!(d.cost_after < 1e-16 && d.cost_before > 0.5);
        let short =
            levenberg_marquardt(&problem, vec![0.0, 0.0], &LmSettings::new(1), &none()).unwrap();
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
        let d =
            levenberg_marquardt(&problem, vec![0.0, 0.0], &LmSettings::new(1000), &none()).unwrap();
        assert_eq!(d.stop, Stop::Converged);
        assert!(d.iterations < 100, "{}", d.iterations);
        let at = problem.evaluate(d.v.as_ref().unwrap()).unwrap();
        let jacobian = at.jacobian.unwrap();
        let gradient = jacobian.transpose() * &at.errors;
        assert!(
            gradient.amax() <= 1e-3 * jacobian.norm() * at.errors.norm(),
            "{gradient}"
        );
        let passed = Deadline::at(std::time::Instant::now());
        let cut =
            levenberg_marquardt(&problem, vec![0.0, 0.0], &LmSettings::new(1000), &passed).unwrap();
        assert_eq!((cut.stop, cut.iterations), (Stop::TimeBudget, 0));
        assert!(cut.v.is_none());
        // Past the deadline, no Jacobian is formed: the start's residuals
        // are the one evaluation.
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let counted = |x: &[f64]| {
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            system(x)
        };
        let differences = CentralDifferences { step: 1e-7 };
        let cut = descend(
            &Residuals::new(counted, 2, None, differences),
            vec![1.0, 1.0],
            &LmSettings::new(100),
            &passed,
        );
        assert_eq!((cut.stop, calls.into_inner()), (Stop::TimeBudget, 1));
    }

    /// `x^2 = 2, x y = 3`: `x = sqrt 2`, `y = 3 / sqrt 2`.
    fn system(x: &[f64]) -> Option<Vec<f64>> {
        Some(vec![x[0] * x[0] - 2.0, x[0] * x[1] - 3.0])
    }

    #[test]
    fn residuals_reach_their_root_on_finite_differences_and_keep_to_a_box() {
        let free = Residuals::new(system, 2, None, CentralDifferences { step: 1e-7 });
        let settings = LmSettings::new(100).with_cost_tolerance(1e-15);
        let d = levenberg_marquardt(&free, vec![1.0, 1.0], &settings, &none()).unwrap();
        let x = d.v.unwrap();
        assert!(d.cost_after < 1e-24, "{}", d.cost_after);
        assert!((x[0] - 2f64.sqrt()).abs() < 1e-12 && (x[1] - 3.0 / 2f64.sqrt()).abs() < 1e-12);
        let bounds = [[0.0, 1.2], [0.0, 5.0]];
        let boxed = Residuals::new(system, 2, Some(&bounds), CentralDifferences { step: 1e-7 });
        let x = levenberg_marquardt(&boxed, vec![1.0, 1.0], &settings, &none())
            .unwrap()
            .v
            .unwrap();
        assert!(x[0] <= 1.2 && x[0] > 1.19, "{x:?}");
    }

    #[test]
    fn an_exact_jacobian_reaches_the_same_root_and_a_wrong_one_does_not_descend() {
        let jacobian = |x: &[f64]| DMatrix::from_row_slice(2, 2, &[2.0 * x[0], 0.0, x[1], x[0]]);
        let exact = Residuals::new(system, 2, None, Exact(jacobian));
        let settings = LmSettings::new(100).with_cost_tolerance(1e-15);
        let d = levenberg_marquardt(&exact, vec![1.0, 1.0], &settings, &none()).unwrap();
        let x = d.v.unwrap();
        assert!(d.cost_after < 1e-24, "{}", d.cost_after);
        assert!((x[0] - 2f64.sqrt()).abs() < 1e-12 && (x[1] - 3.0 / 2f64.sqrt()).abs() < 1e-12);
        let wrong = |_: &[f64]| DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, -1.0]);
        let wrong = Residuals::new(system, 2, None, Exact(wrong));
        let d = levenberg_marquardt(&wrong, vec![1.0, 1.0], &settings, &none()).unwrap();
        assert!(d.cost_after > 1e-6, "{d:?}");
        assert_eq!(d.stop, Stop::NoDescent);
    }

    #[test]
    fn a_failing_start_diverges_and_failing_columns_stay_zero() {
        let never = Residuals::new(|_: &[f64]| None, 1, None, CentralDifferences { step: 1e-7 });
        let d = levenberg_marquardt(&never, vec![0.0], &LmSettings::new(10), &none()).unwrap();
        assert_eq!((d.stop, d.iterations), (Stop::Diverged, 0));
        assert!(d.cost_before.is_infinite() && d.v.is_none());
        // Residuals that fail right of 0.5: the column at 0.5 fails, the
        // descent still moves the other unknown to its root.
        let half = |x: &[f64]| (x[0] <= 0.5).then(|| vec![x[0] - 0.2, x[1] - 3.0]);
        let problem = Residuals::new(half, 2, None, CentralDifferences { step: 1e-3 });
        let j = problem.jacobian(&[0.5, 0.0]).unwrap();
        assert_eq!((j[(0, 0)], j[(1, 0)]), (0.0, 0.0));
        assert!((j[(1, 1)] + 1.0).abs() < 1e-9, "{j}");
        let d = levenberg_marquardt(&problem, vec![0.0, 0.0], &LmSettings::new(50), &none());
        let x = d.unwrap().v.unwrap();
        assert!(
            (x[0] - 0.2).abs() < 1e-9 && (x[1] - 3.0).abs() < 1e-9,
            "{x:?}"
        );
    }

    /// Counts the evaluations, those that lowered the least cost seen
    /// (the accepted points), and the Jacobians asked for.
    struct Counted<'a> {
        inner: Exponential,
        counts: &'a std::cell::RefCell<(usize, usize, usize, f64)>,
    }

    impl LeastSquares for Counted<'_> {
        type Error = ();
        fn unknowns(&self) -> usize {
            2
        }
        fn evaluate(&self, v: &[f64]) -> Result<Evaluation, ()> {
            let mut at = self.inner.evaluate(v)?;
            at.jacobian = None;
            let mut c = self.counts.borrow_mut();
            c.0 += 1;
            if at.cost < c.3 {
                c.1 += 1;
                c.3 = at.cost;
            }
            Ok(at)
        }
        fn jacobian(&self, v: &[f64]) -> Result<DMatrix<f64>, ()> {
            self.counts.borrow_mut().2 += 1;
            self.inner.jacobian(v)
        }
        fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
            unconstrained(design, rhs)
        }
    }

    /// A Jacobian asked for separately is asked at the start and at each
    /// accepted point, never at a rejected one, and the descent takes the
    /// same steps as with the Jacobian given beside the errors.
    #[test]
    fn a_separate_jacobian_is_asked_at_accepted_points_only() {
        let t: Vec<f64> = (0..9).map(|k| k as f64 * 0.25).collect();
        let y: Vec<f64> = t.iter().map(|t| (2.0 * t).exp() + 0.4).collect();
        let inner = Exponential { t, y, s: 1.0 };
        let settings = LmSettings::new(200);
        let with = levenberg_marquardt(&inner, vec![-1.0, 0.0], &settings, &none()).unwrap();
        let counts = std::cell::RefCell::new((0, 0, 0, f64::INFINITY));
        let counted = Counted {
            inner,
            counts: &counts,
        };
        let lazy = levenberg_marquardt(&counted, vec![-1.0, 0.0], &settings, &none()).unwrap();
        assert_eq!((lazy.stop, lazy.iterations), (with.stop, with.iterations));
        assert_eq!(lazy.v, with.v);
        let (evaluations, improvements, jacobians, _) = *counts.borrow();
        assert_eq!(jacobians, improvements, "{:?}", counts.borrow());
        assert!(
            evaluations > improvements,
            "no step was rejected: {:?}",
            counts.borrow()
        );
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
            let a = levenberg_marquardt(&base, vec![0.0, 0.0], &LmSettings::new(200), &none()).unwrap();
            let b = levenberg_marquardt(&scaled, vec![0.0, 0.0], &LmSettings::new(200), &none()).unwrap();
            proptest::prop_assert_eq!((a.stop, a.iterations), (b.stop, b.iterations));
            proptest::prop_assert_eq!(a.stop, Stop::Converged);
            for (p, q) in a.v.unwrap().iter().zip(b.v.unwrap()) {
                proptest::prop_assert!((p - q).abs() <= 1e-6 * (1.0 + p.abs()), "{} {}", p, q);
            }
        }

        /// A descent advanced a few steps at a time takes the steps of one
        /// call, to the bit: the same point, cost, count and stop, and after
        /// each round of `round` steps its cost is the least so far.
        #[test]
        fn a_descent_in_rounds_is_the_descent_in_one_call(
            round in 1usize..7,
            bound in 0usize..40,
            start in proptest::collection::vec(-2.0f64..2.0, 2),
            noise in proptest::collection::vec(-0.1f64..0.1, 9),
        ) {
            let t: Vec<f64> = (0..9).map(|k| k as f64 * 0.25).collect();
            let y = t.iter().zip(&noise).map(|(t, e)| (0.7 * t).exp() - 0.3 + e).collect();
            let problem = Exponential { t, y, s: 1.0 };
            let settings = LmSettings::new(bound).with_damping(Damping::Marquardt);
            let whole = levenberg_marquardt(&problem, start.clone(), &settings, &none()).unwrap();
            let deadline = none();
            let mut rounds = Marquardt::start(&problem, start, &settings, &deadline).unwrap();
            let mut costs = vec![rounds.cost()];
            for _ in 0..=bound {
                let stop = rounds.advance(round).unwrap();
                costs.push(rounds.cost());
                proptest::prop_assert_eq!(stop, rounds.stopped());
                if stop.is_some() {
                    break;
                }
            }
            proptest::prop_assert!(costs.windows(2).all(|c| c[1] <= c[0]), "{:?}", costs);
            let parts = rounds.finish();
            proptest::prop_assert_eq!((parts.stop, parts.iterations), (whole.stop, whole.iterations));
            proptest::prop_assert_eq!(parts.cost_after.to_bits(), whole.cost_after.to_bits());
            proptest::prop_assert_eq!(parts.v, whole.v);
        }

        /// The damped step solved on the reduced rows (`R`, `Q^T e`) is the
        /// step solved on all of them, unconstrained and in a box that cuts
        /// it, for both dampings.
        #[test]
        fn the_reduced_step_is_the_full_step(
            (rows, columns, entries) in (1usize..6).prop_flat_map(|n| {
                ((2 * n + 1)..40usize).prop_flat_map(move |m| {
                    (Just(m), Just(n), proptest::collection::vec(-1.0f64..1.0, m * n + m + n))
                })
            }),
            mu in 1e-8f64..10.0,
            marquardt in proptest::bool::ANY,
        ) {
            let jacobian = DMatrix::from_column_slice(rows, columns, &entries[..rows * columns]);
            let errors = DVector::from_column_slice(&entries[rows * columns..rows * columns + rows]);
            let v = entries[rows * columns + rows..].to_vec();
            let reduced = Reduced::of(&jacobian, &errors);
            proptest::prop_assert!(reduced.is_some());
            let full = Linearisation { errors, jacobian, cost: 0.0, reduced: None };
            let small = Linearisation { reduced, ..full.clone() };
            let damping = if marquardt { Damping::Marquardt } else { Damping::Identity };
            let (a, b) = (damped_system(&full, &v, mu, damping), damped_system(&small, &v, mu, damping));
            proptest::prop_assert_eq!(b.0.nrows(), 2 * columns);
            let close = |p: &[f64], q: &[f64]| p.iter().zip(q).all(|(p, q)| (p - q).abs() <= 1e-8 * (1.0 + p.abs()));
            let (p, q) = (unconstrained(&a.0, &a.1).unwrap(), unconstrained(&b.0, &b.1).unwrap());
            proptest::prop_assert!(close(&p, &q), "{:?} {:?}", p, q);
            // A box around v of half the free step's largest move.
            let half = 0.5 * p.iter().zip(&v).map(|(p, v)| (p - v).abs()).fold(0.0, f64::max);
            let bounds: Vec<[f64; 2]> = v.iter().map(|v| [v - half, v + half]).collect();
            let p = box_least_squares::in_box(&a.0, &a.1, &bounds).unwrap();
            let q = box_least_squares::in_box(&b.0, &b.1, &bounds).unwrap();
            proptest::prop_assert!(close(&p, &q), "{:?} {:?}", p, q);
        }
    }
}
