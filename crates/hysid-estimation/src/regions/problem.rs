//! A region program: the labelled points standardised on the columns the
//! regions may use ([`Prepared`]), and the solve of its LPs and QPs on the
//! one conic solver, with failures named by [`Context`].

use super::options::{RegionError, RegionOptions};
use crate::conic::{self, Program, Settings, Solution, SolveError};
use hysid_core::backend::Deadline;
use nalgebra::DMatrix;

/// Where a region program is solved, for error messages.
pub(crate) struct Context {
    pub(crate) method: &'static str,
    pub(crate) points: usize,
    pub(crate) round: usize,
    /// The solve stops here ([`RegionError::TimeLimit`]).
    pub(crate) deadline: Deadline,
}

/// The clarabel settings of every region program: an explicit bound of 300
/// iterations and 3 iterative-refinement steps per linear solve, and the time
/// left before `deadline` (the other fields are clarabel's defaults).
pub(crate) fn solver_settings(deadline: &Deadline) -> Settings {
    let time_limit = deadline
        .remaining()
        .map_or(f64::INFINITY, |d| d.as_secs_f64());
    Settings {
        max_iter: 300,
        iterative_refinement_max_iter: 3,
        time_limit,
        ..Settings::default()
    }
}

/// Solves a region program with [`solver_settings`]. A solution (`Solved`
/// or `AlmostSolved`, the policy of `crate::conic`) is returned;
/// a failure is the [`SolveError`].
pub(crate) fn solve_program(program: Program) -> Result<Solution, SolveError> {
    conic::solve(program, &solver_settings(&Deadline::none()))
}

impl RegionError {
    /// The error of a failed solve of a program with `variables` variables
    /// and `rows` rows, in the context `ctx`.
    pub(crate) fn from_solve(e: SolveError, ctx: &Context, variables: usize, rows: usize) -> Self {
        match e {
            SolveError::Setup(detail) => RegionError::SolverSetup {
                method: ctx.method,
                detail,
            },
            SolveError::TimeLimit { .. } => RegionError::TimeLimit { method: ctx.method },
            e => RegionError::Solver {
                method: ctx.method,
                status: e.status().to_string(),
                iterations: e.iterations(),
                points: ctx.points,
                variables,
                rows,
                round: ctx.round,
            },
        }
    }
}

/// [`solve_program`] with a failure as a [`RegionError`] naming `ctx`.
pub(crate) fn solve_in_context(program: Program, ctx: &Context) -> Result<Solution, RegionError> {
    let (variables, rows) = (program.variables(), program.rows());
    conic::solve(program, &solver_settings(&ctx.deadline))
        .map_err(|e| RegionError::from_solve(e, ctx, variables, rows))
}

/// Standardised, column-selected data: row-major `n x p`.
pub(crate) struct Prepared {
    pub(crate) z: Vec<f64>,
    pub(crate) n: usize,
    pub(crate) p: usize,
    /// Selected original columns.
    pub(crate) cols: Vec<usize>,
    /// Mean and scale of each selected column (`z = (x - mean) / scale`).
    pub(crate) mean: Vec<f64>,
    pub(crate) scale: Vec<f64>,
    /// Points per mode.
    pub(crate) counts: Vec<usize>,
}

impl Prepared {
    pub(crate) fn row(&self, r: usize) -> &[f64] {
        &self.z[r * self.p..(r + 1) * self.p]
    }
}

pub(crate) fn prepare(
    x: &DMatrix<f64>,
    labels: &[usize],
    modes: usize,
    opts: &RegionOptions,
) -> Result<Prepared, RegionError> {
    let (n, d) = x.shape();
    if modes == 0 {
        return Err(RegionError::NoModes);
    }
    if labels.len() != n {
        return Err(RegionError::Shape(format!(
            "{} labels for {n} regressor rows",
            labels.len()
        )));
    }
    for (row, &label) in labels.iter().enumerate() {
        if label >= modes {
            return Err(RegionError::LabelOutOfRange { row, label, modes });
        }
    }
    for col in 0..d {
        for row in 0..n {
            if !x[(row, col)].is_finite() {
                return Err(RegionError::NonFinite { row, col });
            }
        }
    }
    let mut counts = vec![0usize; modes];
    for &l in labels {
        counts[l] += 1;
    }
    if let Some(mode) = counts.iter().position(|&c| c == 0) {
        return Err(RegionError::EmptyMode { mode });
    }
    if !(opts.svm_c.is_finite() && opts.svm_c > 0.0) {
        return Err(RegionError::InvalidOption {
            key: "svm_c",
            reason: format!("must be finite and positive, got {}", opts.svm_c),
        });
    }
    let cols: Vec<usize> = match &opts.switching {
        None => (0..d).collect(),
        Some(s) => {
            let mut seen = vec![false; d];
            for &c in s {
                if c >= d || seen[c] {
                    return Err(RegionError::SwitchingColumn { col: c, dim: d });
                }
                seen[c] = true;
            }
            s.clone()
        }
    };
    let p = cols.len();
    let mut mean = vec![0.0; p];
    let mut scale = vec![1.0; p];
    if opts.standardize {
        for (k, &c) in cols.iter().enumerate() {
            let column = x.column(c);
            let m = column.iter().sum::<f64>() / n as f64;
            let var = column.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n as f64;
            let sd = var.sqrt();
            mean[k] = m;
            // Constant columns are only centred.
            scale[k] = if sd.is_finite() && sd > f64::MIN_POSITIVE * 1e10 {
                sd
            } else {
                1.0
            };
        }
    }
    let mut z = Vec::with_capacity(n * p);
    for r in 0..n {
        for (k, &c) in cols.iter().enumerate() {
            z.push((x[(r, c)] - mean[k]) / scale[k]);
        }
    }
    Ok(Prepared {
        z,
        n,
        p,
        cols,
        mean,
        scale,
        counts,
    })
}

#[cfg(test)]
mod tests {
    //! The region programs are feasible by construction (soft margins) and
    //! no option reaches the iteration bound, so the failure statuses are
    //! reached here, on a small program, through the `solve_in_context`
    //! the working-set scheme calls. The status mapping itself is tested in
    //! `crate::conic`.
    use super::*;
    use crate::conic::{Cone, Triplets};
    use crate::regions::options::RegionError;

    const CTX: Context = Context {
        method: "test",
        points: 7,
        round: 2,
        deadline: hysid_core::backend::Deadline::none(),
    };

    /// `min x1 + x2` subject to `lo <= x <= hi` (as `A x + s = b`, `s >= 0`).
    fn boxed(lo: f64, hi: f64) -> Program {
        let mut a = Triplets::default();
        for j in 0..2 {
            a.push(2 * j, j, -1.0); // -x + s = -lo
            a.push(2 * j + 1, j, 1.0); // x + s = hi
        }
        Program {
            p: Triplets::default(),
            q: vec![1.0, 1.0],
            a,
            b: vec![-lo, hi, -lo, hi],
            cones: vec![Cone::Nonnegative(4)],
        }
    }

    #[test]
    fn a_feasible_program_is_solved() {
        let s = solve_in_context(boxed(0.5, 2.0), &CTX).unwrap();
        assert!(s.x.iter().all(|x| (x - 0.5).abs() < 1e-6), "{:?}", s.x);
    }

    #[test]
    fn an_infeasible_program_is_an_error_naming_the_status() {
        let Err(e) = solve_in_context(boxed(2.0, 0.5), &CTX) else {
            panic!("an infeasible program was solved");
        };
        let m = e.to_string();
        assert!(
            matches!(&e, RegionError::Solver { status, .. } if status == "PrimalInfeasible"),
            "{m}"
        );
        assert!(
            m.starts_with("test: clarabel stopped with status PrimalInfeasible after "),
            "{m}"
        );
        assert!(
            m.contains("working set of 7 points, 2 variables, 4 rows, round 2"),
            "{m}"
        );
    }

    #[test]
    fn the_iteration_bound_is_an_error_naming_the_status() {
        let settings = Settings {
            max_iter: 1,
            ..solver_settings(&hysid_core::backend::Deadline::none())
        };
        let e = conic::solve(boxed(0.5, 2.0), &settings).unwrap_err();
        let e = RegionError::from_solve(e, &CTX, 2, 4);
        assert!(
            e.to_string()
                .starts_with("test: clarabel stopped with status MaxIterations after 1 iterations"),
            "{e}"
        );
    }

    #[test]
    fn a_refused_program_is_a_setup_error() {
        let mut prog = boxed(0.5, 2.0);
        prog.cones = vec![Cone::Nonnegative(3)];
        let Err(e) = solve_in_context(prog, &CTX) else {
            panic!("a program with inconsistent dimensions was solved");
        };
        assert!(matches!(e, RegionError::SolverSetup { .. }), "{e}");
        assert!(
            e.to_string()
                .starts_with("test: clarabel refused the problem ("),
            "{e}"
        );
    }
}
