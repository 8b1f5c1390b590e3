//! The mixed-integer programs, built for `microlp` and solved by its
//! branch and bound.
//!
//! Variables: the free parameters `z` of the parametrisation of the priors
//! (every mode parameter is a `z_v` or a fixed value; ties share a `z_v`;
//! equalities add `z = z0 + N w`), boxed to `[-theta_max, theta_max]`; a
//! binary `z_ki` per sample `k` and mode `i`, `sum_i z_ki = 1`. With
//! `M_k = |y_k| + max_i sum_j |phi_kj| |theta_ij|max` the residual
//! `e_ki = y_k - phi_k' theta_i` satisfies `|e_ki| <= M_k` anywhere in the
//! box, so `z_ki = 0` switches its constraints off exactly.
//!
//! - [`Objective::L1`]: `min sum_k t_k` with `|e_ki| <= t_k + M_k (1 - z_ki)`
//!   (the l1 switched regression of Roll, Bemporad and Ljung, Automatica
//!   2004, without their hinging-hyperplane structure), optionally
//!   `t_k <= delta`.
//! - [`Objective::FewestModes`]: `min sum_i u_i` with `z_ki <= u_i`,
//!   `u_i >= u_(i+1)` and `|e_ki| <= delta + M_k (1 - z_ki)`: the exact
//!   MIN PFS partition of Bemporad et al. (TAC 2005).
//!
//! The modes are interchangeable, so sample `k` may only use modes
//! `0..=k` (symmetry breaking; every optimum has a relabelling of that
//! form).

use hysid_core::backend::Deadline;
use hysid_estimation::constrained::{Parametrisation, Slot};
use hysid_model::regressors::Regressors;
use microlp::{
    ComparisonOp, LinearExpr, OptimizationDirection, Problem, SolutionStatus, SolveOptions,
    SolveOutcome, Variable,
};

/// What the program minimises.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Objective {
    /// The sum of absolute residuals with `modes` modes, each residual at
    /// most `delta` when given.
    L1 {
        /// Modes.
        modes: usize,
        /// Bound on every residual.
        delta: Option<f64>,
    },
    /// The number of modes, at most `max_modes`, that explain every sample
    /// within `delta`.
    FewestModes {
        /// Largest mode count.
        max_modes: usize,
        /// Bound on every residual.
        delta: f64,
    },
}

/// Bounds of one solve.
#[derive(Debug, Clone)]
pub struct Limits {
    /// Box on every parameter (the big-M constants follow from it).
    pub theta_max: f64,
    /// Branch-and-bound nodes at most.
    pub node_limit: u64,
    /// The run's deadline.
    pub deadline: Deadline,
}

/// The solution of one program.
#[derive(Debug, Clone, PartialEq)]
pub struct MilpSolution {
    /// The mode of every sample.
    pub labels: Vec<usize>,
    /// The parameters of every mode.
    pub thetas: Vec<Vec<f64>>,
    /// The objective: the l1 error, or the number of modes used.
    pub objective: f64,
    /// Whether branch and bound proved the optimum (not cut short by the
    /// node limit or the deadline).
    pub proven_optimal: bool,
    /// Branch-and-bound nodes solved.
    pub nodes: u64,
    /// Whether some free parameter ended at the `theta_max` box.
    pub at_box: bool,
}

/// Why a program has no solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProgramError {
    /// No assignment satisfies the constraints.
    #[error(
        "no {modes}-mode model explains every sample within the bounds (delta, [bounds], theta_max)"
    )]
    Infeasible {
        /// The (largest) mode count.
        modes: usize,
    },
    /// The limits ended the search before any assignment was found.
    #[error("the node limit or the time budget ended branch and bound before a first solution")]
    NoSolutionWithinLimits,
    /// The solver failed.
    #[error("the MILP solver failed: {0}")]
    Solver(String),
}

/// Builds and solves the program of `objective` on the samples of `reg`
/// under the priors of `par`.
pub fn solve(
    reg: &Regressors,
    par: &Parametrisation,
    objective: Objective,
    limits: &Limits,
) -> Result<MilpSolution, ProgramError> {
    let modes = match objective {
        Objective::L1 { modes, .. } => modes,
        Objective::FewestModes { max_modes, .. } => max_modes,
    };
    let mut p = Problem::new(OptimizationDirection::Minimize);
    let z = parameter_variables(&mut p, par, limits.theta_max);
    let magnitude = parameter_magnitudes(par, modes, limits.theta_max);
    let used: Vec<Variable> = match objective {
        Objective::FewestModes { .. } => (0..modes).map(|_| p.add_binary_var(1.0)).collect(),
        Objective::L1 { .. } => Vec::new(),
    };
    for pair in used.windows(2) {
        p.add_constraint([(pair[0], 1.0), (pair[1], -1.0)], ComparisonOp::Ge, 0.0);
    }
    let mut assignment = Vec::with_capacity(reg.len());
    let start_z: Vec<f64> = (0..par.n_free())
        .map(|v| {
            let (lo, hi) = par.free_bounds(v);
            0.0f64.clamp(lo.max(-limits.theta_max), hi.min(limits.theta_max))
        })
        .collect();
    let start_thetas = par.thetas(&start_z);
    let mut start: Vec<(Variable, f64)> = z.iter().copied().zip(start_z.iter().copied()).collect();
    for k in 0..reg.len() {
        let big_m = big_m(reg, k, &magnitude);
        let t = match objective {
            Objective::L1 { .. } => Some(p.add_var(1.0, (0.0, f64::INFINITY))),
            Objective::FewestModes { .. } => None,
        };
        let bound = match objective {
            Objective::FewestModes { delta, .. } => Some(delta),
            Objective::L1 { delta, .. } => delta,
        };
        let zk: Vec<Variable> = (0..modes.min(k + 1))
            .map(|_| p.add_binary_var(0.0))
            .collect();
        start.extend(
            zk.iter()
                .enumerate()
                .map(|(i, &v)| (v, if i == 0 { 1.0 } else { 0.0 })),
        );
        if let Some(t) = t {
            start.push((t, start_residual(reg, k, &start_thetas[0]).abs()));
        }
        p.add_constraint(
            zk.iter().map(|&v| (v, 1.0)).collect::<LinearExpr>(),
            ComparisonOp::Eq,
            1.0,
        );
        for (i, &zki) in zk.iter().enumerate() {
            let (terms, y_rest) = residual(reg, par, &z, k, i);
            // e = y_rest - terms.z: sign e <= t + M (1 - z_ki) for the l1
            // error, sign e <= delta + M (1 - z_ki) for the bound.
            for sign in [1.0, -1.0] {
                let row = |extra: Option<Variable>| {
                    let mut row: Vec<(Variable, f64)> =
                        terms.iter().map(|&(v, c)| (v, -sign * c)).collect();
                    row.push((zki, big_m));
                    row.extend(extra.map(|t| (t, -1.0)));
                    row
                };
                if let Some(t) = t {
                    p.add_constraint(row(Some(t)), ComparisonOp::Le, big_m - sign * y_rest);
                }
                if let Some(delta) = bound {
                    p.add_constraint(row(None), ComparisonOp::Le, big_m + delta - sign * y_rest);
                }
            }
            if let Some(&u) = used.get(i) {
                p.add_constraint([(zki, 1.0), (u, -1.0)], ComparisonOp::Le, 0.0);
            }
        }
        assignment.push(zk);
    }
    let mut options = SolveOptions::default();
    options.node_limit = Some(limits.node_limit);
    options.time_limit = limits.deadline.remaining();
    // Every sample in mode 0 with the parameters at 0 (or their nearest
    // bound) is an incumbent of the l1 program from the first node on,
    // unless a bound on the residuals or an equality excludes it (the
    // solver then ignores it).
    if matches!(objective, Objective::L1 { delta: None, .. }) && !par.has_equalities() {
        options.warm_start = Some(start);
    }
    let outcome = p.solve_with(options).map_err(|e| match e {
        microlp::Error::Infeasible => ProgramError::Infeasible { modes },
        e => ProgramError::Solver(e.to_string()),
    })?;
    let solution = match outcome {
        SolveOutcome::Solution(s) => s,
        SolveOutcome::Interrupted(_) => return Err(ProgramError::NoSolutionWithinLimits),
    };
    let labels: Vec<usize> = assignment
        .iter()
        .map(|zk| {
            (0..zk.len())
                .max_by(|&a, &b| {
                    solution
                        .var_value(zk[a])
                        .total_cmp(&solution.var_value(zk[b]))
                })
                .unwrap_or(0)
        })
        .collect();
    let zv: Vec<f64> = z.iter().map(|&v| solution.var_value(v)).collect();
    let at_box = zv
        .iter()
        .any(|v| v.abs() >= limits.theta_max * (1.0 - 1e-9));
    let used_modes = labels.iter().copied().max().map_or(0, |m| m + 1);
    let mut thetas = par.thetas(&zv);
    thetas.truncate(match objective {
        Objective::FewestModes { .. } => used_modes,
        Objective::L1 { .. } => modes,
    });
    Ok(MilpSolution {
        labels,
        thetas,
        objective: solution.objective(),
        proven_optimal: solution.status() == SolutionStatus::Optimal,
        nodes: solution.stats().nodes_solved,
        at_box,
    })
}

/// `y_k - theta . [x_k; 1]`.
fn start_residual(reg: &Regressors, k: usize, theta: &[f64]) -> f64 {
    let d = reg.x.ncols();
    reg.y[k] - theta[d] - (0..d).map(|j| theta[j] * reg.x[(k, j)]).sum::<f64>()
}

/// The free parameters `z`, boxed by their prior bounds and `theta_max`,
/// tied to `z0 + N w` when there are equalities.
fn parameter_variables(p: &mut Problem, par: &Parametrisation, theta_max: f64) -> Vec<Variable> {
    let mut z = Vec::with_capacity(par.n_free());
    for v in 0..par.n_free() {
        let (lo, hi) = par.free_bounds(v);
        // `fit` refuses a bound outside the box first; here it would leave
        // the variable an empty range, which microlp answers as infeasible.
        let (lo, hi) = (lo.max(-theta_max), hi.min(theta_max));
        z.push(p.add_var(0.0, (lo, hi)));
    }
    if par.has_equalities() {
        let (z0, basis) = par.affine();
        let w: Vec<Variable> = (0..basis.ncols())
            .map(|_| p.add_var(0.0, (f64::NEG_INFINITY, f64::INFINITY)))
            .collect();
        for (v, &zv) in z.iter().enumerate() {
            let mut row = vec![(zv, 1.0)];
            row.extend(w.iter().enumerate().map(|(l, &wl)| (wl, -basis[(v, l)])));
            p.add_constraint(row, ComparisonOp::Eq, z0[v]);
        }
    }
    z
}

/// `|theta_ij|` at most, per mode and parameter: the fixed value, or the
/// box.
fn parameter_magnitudes(par: &Parametrisation, modes: usize, theta_max: f64) -> Vec<Vec<f64>> {
    (0..modes)
        .map(|i| {
            (0..par.n_params())
                .map(|j| match par.slot(i, j) {
                    Slot::Fixed(x) => x.abs(),
                    Slot::Free(_) => theta_max,
                })
                .collect()
        })
        .collect()
}

/// `M_k = |y_k| + max_i sum_j |phi_kj| |theta_ij|max`.
fn big_m(reg: &Regressors, k: usize, magnitude: &[Vec<f64>]) -> f64 {
    let d = reg.x.ncols();
    let worst = magnitude
        .iter()
        .map(|m| (0..d).map(|j| reg.x[(k, j)].abs() * m[j]).sum::<f64>() + m[d])
        .fold(0.0, f64::max);
    reg.y[k].abs() + worst
}

/// The residual `e_ki = y_rest - sum terms` of sample `k` in mode `i`:
/// the free parameters' coefficients and `y_k` minus the fixed
/// parameters' part.
fn residual(
    reg: &Regressors,
    par: &Parametrisation,
    z: &[Variable],
    k: usize,
    i: usize,
) -> (Vec<(Variable, f64)>, f64) {
    let d = reg.x.ncols();
    let mut coefficient = vec![0.0; z.len()];
    let mut y_rest = reg.y[k];
    for j in 0..=d {
        let phi = if j < d { reg.x[(k, j)] } else { 1.0 };
        match par.slot(i, j) {
            Slot::Free(v) => coefficient[v] += phi,
            Slot::Fixed(x) => y_rest -= phi * x,
        }
    }
    let terms = coefficient
        .iter()
        .enumerate()
        .filter(|(_, c)| **c != 0.0)
        .map(|(v, &c)| (z[v], c))
        .collect();
    (terms, y_rest)
}
