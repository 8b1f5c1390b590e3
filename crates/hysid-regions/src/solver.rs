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
    let n = prog.q.len();
    let m = prog.b.len();
    let pm = prog.p.into_csc(n, n);
    let am = prog.a.into_csc(m, n);
    let mut solver = DefaultSolver::new(&pm, &prog.q, &am, &prog.b, &prog.cones, quiet_settings())
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
