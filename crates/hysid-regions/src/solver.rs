//! Thin helpers around clarabel: quiet settings, triplet assembly and status
//! mapping.

use crate::RegionError;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};

/// clarabel settings used everywhere: `verbose` is off (clarabel's default
/// is on) and the iteration bound is explicit.
pub(crate) fn quiet_settings() -> DefaultSettings<f64> {
    DefaultSettingsBuilder::default()
        .verbose(false)
        .max_iter(300)
        .iterative_refinement_max_iter(3)
        .build()
        .expect("static clarabel settings are valid")
}

/// Sparse matrix in triplet form.
#[derive(Default)]
pub(crate) struct Triplets {
    pub(crate) rows: Vec<usize>,
    pub(crate) cols: Vec<usize>,
    pub(crate) vals: Vec<f64>,
}

impl Triplets {
    pub(crate) fn push(&mut self, r: usize, c: usize, v: f64) {
        if v != 0.0 {
            self.rows.push(r);
            self.cols.push(c);
            self.vals.push(v);
        }
    }
    pub(crate) fn into_csc(self, m: usize, n: usize) -> CscMatrix<f64> {
        CscMatrix::new_from_triplets(m, n, self.rows, self.cols, self.vals)
    }
}

/// A conic program `min 1/2 u'Pu + q'u  s.t.  A u + s = b, s in cones`.
pub(crate) struct Program {
    pub(crate) p: Triplets,
    pub(crate) q: Vec<f64>,
    pub(crate) a: Triplets,
    pub(crate) b: Vec<f64>,
    pub(crate) cones: Vec<SupportedConeT<f64>>,
}

/// Outcome of a successful solve.
pub(crate) struct Solved {
    pub(crate) x: Vec<f64>,
    pub(crate) iterations: u32,
}

/// Context for error messages.
pub(crate) struct Context {
    pub(crate) method: &'static str,
    pub(crate) points: usize,
    pub(crate) round: usize,
}

/// Solves the program; `Solved` and `AlmostSolved` are accepted, every
/// other status becomes [`RegionError::Solver`] with context.
pub(crate) fn solve(prog: Program, ctx: &Context) -> Result<Solved, RegionError> {
    solve_with(prog, ctx, quiet_settings())
}

/// [`solve`] with given settings (the tests use a tiny iteration bound).
fn solve_with(
    prog: Program,
    ctx: &Context,
    settings: DefaultSettings<f64>,
) -> Result<Solved, RegionError> {
    let n = prog.q.len();
    let m = prog.b.len();
    let pm = prog.p.into_csc(n, n);
    let am = prog.a.into_csc(m, n);
    let mut solver = DefaultSolver::new(&pm, &prog.q, &am, &prog.b, &prog.cones, settings)
        .map_err(|e| RegionError::SolverSetup {
            method: ctx.method,
            detail: e.to_string(),
        })?;
    solver.solve();
    let sol = &solver.solution;
    match sol.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(Solved {
            x: sol.x.clone(),
            iterations: sol.iterations,
        }),
        status => Err(RegionError::Solver {
            method: ctx.method,
            status: format!("{status:?}"),
            iterations: sol.iterations,
            points: ctx.points,
            variables: n,
            rows: m,
            round: ctx.round,
        }),
    }
}

#[cfg(test)]
mod tests {
    //! The region programs are feasible by construction (soft margins) and
    //! no option reaches clarabel's iteration bound, so the failure statuses
    //! are reached here, on small programs, through the one `solve` every
    //! region method calls.
    use super::*;
    use clarabel::solver::SupportedConeT::NonnegativeConeT;

    const CTX: Context = Context {
        method: "test",
        points: 7,
        round: 2,
    };

    /// `min x1 + x2` subject to `x >= lo` and `x <= hi` (as `A x + s = b`, `s >= 0`).
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
            cones: vec![NonnegativeConeT(4)],
        }
    }

    #[test]
    fn a_feasible_program_is_solved() {
        let Ok(s) = solve(boxed(0.5, 2.0), &CTX) else {
            panic!("a feasible program failed");
        };
        assert!(s.x.iter().all(|x| (x - 0.5).abs() < 1e-6), "{:?}", s.x);
    }

    #[test]
    fn an_infeasible_program_is_an_error_naming_the_status() {
        let Err(e) = solve(boxed(2.0, 0.5), &CTX) else {
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
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .max_iter(1)
            .build()
            .unwrap();
        let Err(e) = solve_with(boxed(0.5, 2.0), &CTX, settings) else {
            panic!("one iteration solved the program");
        };
        assert!(
            e.to_string()
                .starts_with("test: clarabel stopped with status MaxIterations after 1 iterations"),
            "{e}"
        );
    }
}
