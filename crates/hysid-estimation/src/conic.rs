//! The one wrapper around clarabel: every LP and QP of the workspace is a
//! [`Program`] solved by [`solve`] with explicit [`Settings`].
//!
//! A program is `min 1/2 x'Px + q'x  s.t.  A x + s = b, s in cones`, with
//! `P` (upper triangle) and `A` given as [`Triplets`] and the cones of the
//! rows of `A` in order ([`Cone`]). clarabel's output is off, and its
//! iteration bound and tolerances are whatever the caller's [`Settings`]
//! say (the defaults are clarabel's own).
//!
//! # Status policy
//!
//! `Solved` and `AlmostSolved` (clarabel's solution to its reduced
//! tolerances) both give a [`Solution`], whose [`SolveStatus`] tells them
//! apart; callers use `x` either way. The reduced-accuracy certificates
//! `AlmostPrimalInfeasible` and `AlmostDualInfeasible` count as their exact
//! counterparts ([`SolveError::Infeasible`], [`SolveError::Unbounded`],
//! with `reduced_accuracy` set). Every other status is a [`SolveError`]
//! naming clarabel's status and the iterations done; what a failure means
//! (an error, a fallback, "no such point") is the caller's decision.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};

/// Sparse matrix in triplet form (row, column, value); zero values are not
/// stored, and repeated positions are summed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Triplets {
    rows: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
}

impl Triplets {
    /// Adds `v` at `(r, c)` unless `v` is zero.
    pub fn push(&mut self, r: usize, c: usize, v: f64) {
        if v != 0.0 {
            self.rows.push(r);
            self.cols.push(c);
            self.vals.push(v);
        }
    }

    /// The nonzero entries of the dense matrix `m`, row by row.
    pub fn dense(m: &nalgebra::DMatrix<f64>) -> Self {
        let mut t = Self::default();
        for i in 0..m.nrows() {
            for j in 0..m.ncols() {
                t.push(i, j, m[(i, j)]);
            }
        }
        t
    }

    /// Number of stored entries.
    pub fn len(&self) -> usize {
        self.vals.len()
    }

    /// Whether no entry is stored.
    pub fn is_empty(&self) -> bool {
        self.vals.is_empty()
    }

    fn into_csc(self, m: usize, n: usize) -> CscMatrix<f64> {
        CscMatrix::new_from_triplets(m, n, self.rows, self.cols, self.vals)
    }
}

/// A cone of consecutive rows of `A x + s = b`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cone {
    /// `s = 0`: equality rows.
    Zero(usize),
    /// `s >= 0`: inequality rows `a'x <= b`.
    Nonnegative(usize),
}

impl Cone {
    fn to_clarabel(self) -> SupportedConeT<f64> {
        match self {
            Cone::Zero(n) => SupportedConeT::ZeroConeT(n),
            Cone::Nonnegative(n) => SupportedConeT::NonnegativeConeT(n),
        }
    }
}

/// A conic program `min 1/2 x'Px + q'x  s.t.  A x + s = b, s in cones`:
/// `q.len()` variables, `b.len()` rows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Program {
    /// Upper triangle of `P` (empty for an LP).
    pub p: Triplets,
    /// Linear cost.
    pub q: Vec<f64>,
    /// Constraint matrix.
    pub a: Triplets,
    /// Right-hand side.
    pub b: Vec<f64>,
    /// Cones of the rows, in row order.
    pub cones: Vec<Cone>,
}

impl Program {
    /// Number of variables.
    pub fn variables(&self) -> usize {
        self.q.len()
    }

    /// Number of constraint rows.
    pub fn rows(&self) -> usize {
        self.b.len()
    }
}

/// The clarabel settings a call site chooses; output is always off.
/// [`Settings::default`] is clarabel's default for each field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Interior-point iteration bound.
    pub max_iter: u32,
    /// Absolute duality-gap tolerance.
    pub tol_gap_abs: f64,
    /// Relative duality-gap tolerance.
    pub tol_gap_rel: f64,
    /// Feasibility tolerance.
    pub tol_feas: f64,
    /// Iterative-refinement steps per linear solve.
    pub iterative_refinement_max_iter: u32,
    /// Wall-clock limit of one solve in seconds (infinite: none); reaching
    /// it is [`SolveError::TimeLimit`].
    pub time_limit: f64,
}

impl Default for Settings {
    fn default() -> Self {
        let d = DefaultSettings::<f64>::default();
        Self {
            max_iter: d.max_iter,
            tol_gap_abs: d.tol_gap_abs,
            tol_gap_rel: d.tol_gap_rel,
            tol_feas: d.tol_feas,
            iterative_refinement_max_iter: d.iterative_refinement_max_iter,
            time_limit: d.time_limit,
        }
    }
}

impl Settings {
    fn to_clarabel(self) -> Result<DefaultSettings<f64>, SolveError> {
        DefaultSettingsBuilder::default()
            .verbose(false)
            .max_iter(self.max_iter)
            .tol_gap_abs(self.tol_gap_abs)
            .tol_gap_rel(self.tol_gap_rel)
            .tol_feas(self.tol_feas)
            .iterative_refinement_max_iter(self.iterative_refinement_max_iter)
            .time_limit(self.time_limit)
            .build()
            .map_err(|e| SolveError::Setup(e.to_string()))
    }
}

/// How exactly a [`Solution`] was solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveStatus {
    /// clarabel's `Solved`: within the tolerances of [`Settings`].
    Solved,
    /// clarabel's `AlmostSolved`: within its reduced tolerances.
    AlmostSolved,
}

/// A solved program.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The primal solution, one entry per variable.
    pub x: Vec<f64>,
    /// Solved or almost solved.
    pub status: SolveStatus,
    /// Interior-point iterations done.
    pub iterations: u32,
}

/// Why [`solve`] gave no solution.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SolveError {
    /// clarabel refused the problem data or the settings.
    #[error("clarabel refused the problem ({0})")]
    Setup(String),
    /// The constraints have no solution (`PrimalInfeasible`, or
    /// `AlmostPrimalInfeasible` with `reduced_accuracy`).
    #[error("clarabel stopped with status {} after {iterations} iterations", self.status())]
    Infeasible {
        /// The certificate is within clarabel's reduced tolerances only.
        reduced_accuracy: bool,
        /// Iterations done.
        iterations: u32,
    },
    /// The objective is unbounded below (`DualInfeasible`, or
    /// `AlmostDualInfeasible` with `reduced_accuracy`).
    #[error("clarabel stopped with status {} after {iterations} iterations", self.status())]
    Unbounded {
        /// The certificate is within clarabel's reduced tolerances only.
        reduced_accuracy: bool,
        /// Iterations done.
        iterations: u32,
    },
    /// The iteration bound was reached (`MaxIterations`).
    #[error("clarabel stopped with status {} after {iterations} iterations", self.status())]
    IterationLimit {
        /// Iterations done.
        iterations: u32,
    },
    /// The time limit of [`Settings::time_limit`] was reached (`MaxTime`).
    #[error("clarabel stopped with status {} after {iterations} iterations", self.status())]
    TimeLimit {
        /// Iterations done.
        iterations: u32,
    },
    /// A numerical failure (`NumericalError`).
    #[error("clarabel stopped with status {} after {iterations} iterations", self.status())]
    Numerical {
        /// Iterations done.
        iterations: u32,
    },
    /// No progress (`InsufficientProgress`).
    #[error("clarabel stopped with status {} after {iterations} iterations", self.status())]
    InsufficientProgress {
        /// Iterations done.
        iterations: u32,
    },
    /// Any other status (`Unsolved`, `CallbackTerminated`: the wrapper
    /// installs no callback and always runs the solver).
    #[error("clarabel stopped with status {status} after {iterations} iterations")]
    Other {
        /// clarabel's status.
        status: &'static str,
        /// Iterations done.
        iterations: u32,
    },
}

impl SolveError {
    /// clarabel's name of the status (`"Setup"` for a refused problem).
    pub fn status(&self) -> &'static str {
        match self {
            SolveError::Setup(_) => "Setup",
            SolveError::Infeasible {
                reduced_accuracy: false,
                ..
            } => "PrimalInfeasible",
            SolveError::Infeasible {
                reduced_accuracy: true,
                ..
            } => "AlmostPrimalInfeasible",
            SolveError::Unbounded {
                reduced_accuracy: false,
                ..
            } => "DualInfeasible",
            SolveError::Unbounded {
                reduced_accuracy: true,
                ..
            } => "AlmostDualInfeasible",
            SolveError::IterationLimit { .. } => "MaxIterations",
            SolveError::TimeLimit { .. } => "MaxTime",
            SolveError::Numerical { .. } => "NumericalError",
            SolveError::InsufficientProgress { .. } => "InsufficientProgress",
            SolveError::Other { status, .. } => status,
        }
    }

    /// Interior-point iterations done (0 for a refused problem).
    pub fn iterations(&self) -> u32 {
        match *self {
            SolveError::Setup(_) => 0,
            SolveError::Infeasible { iterations, .. }
            | SolveError::Unbounded { iterations, .. }
            | SolveError::IterationLimit { iterations }
            | SolveError::TimeLimit { iterations }
            | SolveError::Numerical { iterations }
            | SolveError::InsufficientProgress { iterations }
            | SolveError::Other { iterations, .. } => iterations,
        }
    }

    /// Whether clarabel certified (exactly or to its reduced tolerances)
    /// that the program is infeasible or unbounded.
    pub fn is_certificate(&self) -> bool {
        matches!(
            self,
            SolveError::Infeasible { .. } | SolveError::Unbounded { .. }
        )
    }
}

/// Solves `program` with `settings` under the status policy of the module.
pub fn solve(program: Program, settings: &Settings) -> Result<Solution, SolveError> {
    let n = program.variables();
    let m = program.rows();
    let settings = settings.to_clarabel()?;
    let p = program.p.into_csc(n, n);
    let a = program.a.into_csc(m, n);
    let cones: Vec<SupportedConeT<f64>> = program.cones.iter().map(|c| c.to_clarabel()).collect();
    let mut solver = DefaultSolver::new(&p, &program.q, &a, &program.b, &cones, settings)
        .map_err(|e| SolveError::Setup(e.to_string()))?;
    solver.solve();
    let sol = &solver.solution;
    let iterations = sol.iterations;
    let status = match sol.status {
        SolverStatus::Solved => SolveStatus::Solved,
        SolverStatus::AlmostSolved => SolveStatus::AlmostSolved,
        status => return Err(failure(status, iterations)),
    };
    Ok(Solution {
        x: sol.x.clone(),
        status,
        iterations,
    })
}

/// The [`SolveError`] of a status other than `Solved` and `AlmostSolved`.
fn failure(status: SolverStatus, iterations: u32) -> SolveError {
    match status {
        SolverStatus::PrimalInfeasible => SolveError::Infeasible {
            reduced_accuracy: false,
            iterations,
        },
        SolverStatus::AlmostPrimalInfeasible => SolveError::Infeasible {
            reduced_accuracy: true,
            iterations,
        },
        SolverStatus::DualInfeasible => SolveError::Unbounded {
            reduced_accuracy: false,
            iterations,
        },
        SolverStatus::AlmostDualInfeasible => SolveError::Unbounded {
            reduced_accuracy: true,
            iterations,
        },
        SolverStatus::MaxIterations => SolveError::IterationLimit { iterations },
        SolverStatus::MaxTime => SolveError::TimeLimit { iterations },
        SolverStatus::NumericalError => SolveError::Numerical { iterations },
        SolverStatus::InsufficientProgress => SolveError::InsufficientProgress { iterations },
        SolverStatus::Unsolved => SolveError::Other {
            status: "Unsolved",
            iterations,
        },
        SolverStatus::CallbackTerminated => SolveError::Other {
            status: "CallbackTerminated",
            iterations,
        },
        SolverStatus::Solved | SolverStatus::AlmostSolved => {
            unreachable!("solved statuses give a Solution")
        }
    }
}

#[cfg(test)]
mod tests {
    //! The workspace's programs are feasible by construction and stay well
    //! inside their iteration bounds, so the failure statuses are reached
    //! here on small programs.
    use super::*;

    /// `min c'x` subject to `lo <= x_j <= hi` for both variables (as
    /// `A x + s = b`, `s >= 0`).
    fn boxed(c: [f64; 2], lo: f64, hi: f64) -> Program {
        let mut a = Triplets::default();
        for j in 0..2 {
            a.push(2 * j, j, -1.0); // -x + s = -lo
            a.push(2 * j + 1, j, 1.0); // x + s = hi
        }
        Program {
            p: Triplets::default(),
            q: c.to_vec(),
            a,
            b: vec![-lo, hi, -lo, hi],
            cones: vec![Cone::Nonnegative(4)],
        }
    }

    #[test]
    fn a_feasible_program_is_solved() {
        let s = solve(boxed([1.0, 1.0], 0.5, 2.0), &Settings::default()).unwrap();
        assert_eq!(s.status, SolveStatus::Solved);
        assert!(s.x.iter().all(|x| (x - 0.5).abs() < 1e-6), "{:?}", s.x);
        assert!(s.iterations > 0);
    }

    #[test]
    fn equality_rows_and_a_quadratic_cost() {
        // min 1/2 (x1^2 + x2^2) subject to x1 + x2 = 1: x = (1/2, 1/2).
        let mut p = Triplets::default();
        p.push(0, 0, 1.0);
        p.push(1, 1, 1.0);
        let mut a = Triplets::default();
        a.push(0, 0, 1.0);
        a.push(0, 1, 1.0);
        let prog = Program {
            p,
            q: vec![0.0, 0.0],
            a,
            b: vec![1.0],
            cones: vec![Cone::Zero(1)],
        };
        let s = solve(prog, &Settings::default()).unwrap();
        assert!(s.x.iter().all(|x| (x - 0.5).abs() < 1e-7), "{:?}", s.x);
    }

    #[test]
    fn an_infeasible_program_is_infeasible() {
        let e = solve(boxed([1.0, 1.0], 2.0, 0.5), &Settings::default()).unwrap_err();
        assert!(
            matches!(
                e,
                SolveError::Infeasible {
                    reduced_accuracy: false,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.is_certificate());
        assert_eq!(e.status(), "PrimalInfeasible");
        let m = e.to_string();
        assert!(
            m.starts_with("clarabel stopped with status PrimalInfeasible after "),
            "{m}"
        );
    }

    #[test]
    fn an_unbounded_program_is_unbounded() {
        // min -x1 - x2 subject to x >= 0 only.
        let mut a = Triplets::default();
        a.push(0, 0, -1.0);
        a.push(1, 1, -1.0);
        let prog = Program {
            p: Triplets::default(),
            q: vec![-1.0, -1.0],
            a,
            b: vec![0.0, 0.0],
            cones: vec![Cone::Nonnegative(2)],
        };
        let e = solve(prog, &Settings::default()).unwrap_err();
        assert!(
            matches!(
                e,
                SolveError::Unbounded {
                    reduced_accuracy: false,
                    ..
                }
            ),
            "{e:?}"
        );
        assert_eq!(e.status(), "DualInfeasible");
    }

    #[test]
    fn the_iteration_bound_is_an_iteration_limit() {
        let settings = Settings {
            max_iter: 1,
            ..Settings::default()
        };
        let e = solve(boxed([1.0, 1.0], 0.5, 2.0), &settings).unwrap_err();
        assert_eq!(e, SolveError::IterationLimit { iterations: 1 });
        assert!(!e.is_certificate());
        assert_eq!(
            e.to_string(),
            "clarabel stopped with status MaxIterations after 1 iterations"
        );
    }

    #[test]
    fn inconsistent_dimensions_are_refused() {
        let mut prog = boxed([1.0, 1.0], 0.5, 2.0);
        prog.cones = vec![Cone::Nonnegative(3)];
        let e = solve(prog, &Settings::default()).unwrap_err();
        assert!(matches!(e, SolveError::Setup(_)), "{e:?}");
        assert_eq!(e.iterations(), 0);
        assert!(e.to_string().starts_with("clarabel refused the problem ("));
    }

    #[test]
    fn default_settings_are_clarabels() {
        let d = DefaultSettings::<f64>::default();
        let s = Settings::default().to_clarabel().unwrap();
        assert!(!s.verbose);
        assert_eq!(
            (s.max_iter, s.tol_gap_abs, s.tol_gap_rel, s.tol_feas),
            (d.max_iter, d.tol_gap_abs, d.tol_gap_rel, d.tol_feas)
        );
        assert_eq!(
            s.iterative_refinement_max_iter,
            d.iterative_refinement_max_iter
        );
    }
}
