//! Least squares of the PWARX mode parameters under gray-box priors:
//! ties and fixed values solved exactly, bounds through a QP.
//!
//! The `[[tie]]` and `[fixed]` entries of a [`Priors`] set make every entry
//! of the stacked parameter vector `theta = [theta_1; ..; theta_s]` of `s`
//! ordinary modes either a known value or one of `n_free` free variables
//! `z` shared by the tied entries: `theta = T z + t0` with `T` a 0/1
//! selection matrix. This is the null-space method for the equalities
//! `theta_i[p] = theta_1[p]` (ties) and `theta_i[p] = v` (fixed values)
//! (Golub & Van Loan, Matrix Computations, 6.2) with the basis written out
//! combinatorially, so ties hold to the last bit and fixed
//! values come back unchanged. The (weighted) least-squares problem of all
//! modes is then one unconstrained problem in `z`; with `[bounds]` it is the
//! box-constrained QP `min |W^(1/2) (Z z - r)|^2, lo <= z <= hi`, solved by
//! clarabel when the unconstrained minimiser leaves the box.
//!
//! General linear equalities (`[[equality]]`: `sum_p c_p theta_i[p] = v` in
//! every mode i) are written in the free variables `z` of the ties and
//! fixed values, `E z = f`, and solved by the null-space method proper:
//! `z = z0 + N w` with `z0` the minimum-norm solution and `N` an
//! orthonormal basis of `ker E` (both from faer's SVD,
//! [`crate::linalg`]). Tied parameters stay one variable (bitwise equal),
//! fixed values stay known values, the equalities hold to rounding
//! (about 1e-12 relative). The least squares are then solved in `w`; bounds
//! become the general linear inequalities `lo <= z0 + N w <= hi` of the
//! same clarabel QP. Inconsistent entries (no parameter vector satisfies
//! them) are an error naming the first `[[equality]]` that contradicts the
//! entries before it.

use crate::conic::{self, Cone, Program, Settings, SolveError, Triplets};
use crate::linalg::{self, LinalgError};
use hysid_core::priors::{Equality, Priors};
use hysid_model::regressors::{RegressorSpec, Regressors};
use nalgebra::{DMatrix, DVector};

/// What one entry of the stacked parameter vector is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Slot {
    /// The free variable `z[v]`.
    Free(usize),
    /// A known value (a `[fixed]` prior).
    Fixed(f64),
}

/// The parametrisation `theta = T z + t0` of `s` modes' stacked parameters
/// by the free variables `z`, with box bounds on `z`.
#[derive(Debug, Clone, PartialEq)]
pub struct Parametrisation {
    n_params: usize,
    slots: Vec<Slot>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    ties: bool,
    /// `[[equality]]` entries: `z = z0 + basis w`.
    reduction: Option<Reduction>,
}

/// The affine reduction `z = z0 + basis w` of the free variables by the
/// `[[equality]]` entries (`basis`: orthonormal columns).
#[derive(Debug, Clone, PartialEq)]
struct Reduction {
    z0: Vec<f64>,
    basis: DMatrix<f64>,
    /// Per free variable: whether an equality involves it.
    coupled: Vec<bool>,
}

/// Failures of the constrained estimation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimationError {
    /// The data do not match the parametrisation.
    #[error("{0}")]
    Shape(String),
    /// A dense kernel failed.
    #[error(transparent)]
    Linalg(#[from] LinalgError),
    /// The bounded QP was not solved.
    #[error("bounded least squares: {0}")]
    Solver(#[from] SolveError),
}

/// Why the constraint priors cannot parametrise the modes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PriorConflict {
    /// A `[fixed]` value outside its `[bounds]`.
    #[error("[fixed] {param} = {value} lies outside [bounds] {param} = [{low}, {high}]")]
    FixedOutsideBounds {
        /// Parameter name.
        param: String,
        /// Fixed value.
        value: f64,
        /// Lower bound.
        low: f64,
        /// Upper bound.
        high: f64,
    },
    /// An `[[equality]]` no parameter vector satisfies together with the
    /// entries before it.
    #[error(
        "[[equality]] #{entry} ({equality}) contradicts the [fixed] values, [[tie]]s and earlier [[equality]] entries{}: \
         no parameter vector satisfies them all",
        if *.entry == 1 { String::new() } else { format!(" (#1..#{})", .entry - 1) }
    )]
    ContradictoryEquality {
        /// Entry number, from 1.
        entry: usize,
        /// The entry as text ([`Equality::describe`]).
        equality: String,
    },
    /// The equalities of all modes together have no solution.
    #[error("[[equality]] entries: no parameter vector of all modes satisfies them")]
    InconsistentEqualities,
    /// No parameter vector that satisfies the equalities lies inside the
    /// bounds.
    #[error(
        "[[equality]] entries: no parameter vector that satisfies them with the [fixed] values and [[tie]]s lies inside [bounds]"
    )]
    OutsideBounds,
    /// The null-space computation failed.
    #[error(transparent)]
    Linalg(#[from] LinalgError),
}

impl Parametrisation {
    /// Every parameter of every mode free, no bounds.
    pub fn free(n_params: usize, modes: usize) -> Self {
        let n = n_params * modes;
        Self {
            n_params,
            slots: (0..n).map(Slot::Free).collect(),
            lower: vec![f64::NEG_INFINITY; n],
            upper: vec![f64::INFINITY; n],
            ties: false,
            reduction: None,
        }
    }

    /// The parametrisation the `[[tie]]`, `[fixed]` and `[bounds]` entries of
    /// `priors` give `modes` ordinary modes with structure `spec`. A fixed
    /// value outside its bounds is an error naming the parameter. Names must
    /// have been checked with [`crate::pwarx::check_names`].
    pub fn from_priors(
        priors: &Priors,
        spec: &RegressorSpec,
        modes: usize,
    ) -> Result<Self, PriorConflict> {
        let names = spec.param_names();
        let np = names.len();
        let idx = |p: &str| names.iter().position(|n| n == p).expect("names checked");
        let tied: Vec<bool> = (0..np)
            .map(|j| {
                priors
                    .tie
                    .iter()
                    .any(|t| t.params.iter().any(|p| idx(p) == j))
            })
            .collect();
        let mut slots = Vec::with_capacity(np * modes);
        let mut lower = Vec::new();
        let mut upper = Vec::new();
        let mut shared: Vec<Option<usize>> = vec![None; np];
        for _ in 0..modes {
            for (j, name) in names.iter().enumerate() {
                let (lo, hi) = priors
                    .bounds
                    .get(name)
                    .map_or((f64::NEG_INFINITY, f64::INFINITY), |b| (b[0], b[1]));
                if let Some(&v) = priors.fixed.get(name) {
                    if v < lo || v > hi {
                        return Err(PriorConflict::FixedOutsideBounds {
                            param: name.clone(),
                            value: v,
                            low: lo,
                            high: hi,
                        });
                    }
                    slots.push(Slot::Fixed(v));
                    continue;
                }
                if tied[j]
                    && let Some(v) = shared[j]
                {
                    slots.push(Slot::Free(v));
                    continue;
                }
                let v = lower.len();
                lower.push(lo);
                upper.push(hi);
                if tied[j] {
                    shared[j] = Some(v);
                }
                slots.push(Slot::Free(v));
            }
        }
        let mut par = Self {
            n_params: np,
            slots,
            lower,
            upper,
            ties: modes > 1 && tied.iter().any(|&t| t),
            reduction: None,
        };
        if !priors.equality.is_empty() {
            par.reduction = Some(par.reduce(&priors.equality, &idx)?);
        }
        Ok(par)
    }

    /// The rows `E z = f` of `equalities` in every mode.
    fn equality_rows(
        &self,
        equalities: &[Equality],
        idx: &dyn Fn(&str) -> usize,
        modes: usize,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let nz = self.n_free();
        let mut e = DMatrix::zeros(equalities.len() * modes, nz);
        let mut f = DVector::zeros(equalities.len() * modes);
        let mut r = 0;
        for i in 0..modes {
            for eq in equalities {
                let mut rhs = eq.value;
                for (name, c) in &eq.coefficients {
                    match self.slot(i, idx(name)) {
                        Slot::Free(v) => e[(r, v)] += c,
                        Slot::Fixed(x) => rhs -= c * x,
                    }
                }
                f[r] = rhs;
                r += 1;
            }
        }
        (e, f)
    }

    /// Whether `E z = f` has a solution; returns the minimum-norm one.
    fn solve_consistent(
        e: &DMatrix<f64>,
        f: &DVector<f64>,
    ) -> Result<Option<DVector<f64>>, LinalgError> {
        let z0 = linalg::lstsq(e, f)?.theta;
        let res = (e * &z0 - f).amax();
        let scale = 1.0 + f.amax() + e.amax() * z0.amax();
        Ok((res <= 1e-9 * scale).then_some(z0))
    }

    /// The null-space reduction of the free variables by `equalities`.
    fn reduce(
        &self,
        equalities: &[Equality],
        idx: &dyn Fn(&str) -> usize,
    ) -> Result<Reduction, PriorConflict> {
        // Consistency, entry by entry (one mode suffices: every mode has the
        // same fixed values and the tied variables are shared), so that the
        // error names the first entry that contradicts those before it.
        for k in 0..equalities.len() {
            let (e, f) = self.equality_rows(&equalities[..=k], idx, 1);
            if Self::solve_consistent(&e, &f)?.is_none() {
                return Err(PriorConflict::ContradictoryEquality {
                    entry: k + 1,
                    equality: equalities[k].describe(),
                });
            }
        }
        let (e, f) = self.equality_rows(equalities, idx, self.modes());
        let z0 = Self::solve_consistent(&e, &f)?.ok_or(PriorConflict::InconsistentEqualities)?;
        let basis = linalg::null_space(&e)?;
        let z0: Vec<f64> = z0.iter().copied().collect();
        if !self.reaches_bounds(&z0, &basis) {
            return Err(PriorConflict::OutsideBounds);
        }
        let coupled = (0..e.ncols())
            .map(|v| e.column(v).iter().any(|c| *c != 0.0))
            .collect();
        Ok(Reduction { z0, basis, coupled })
    }

    /// Whether some `w` puts `z0 + basis w` inside the bounds: a linear
    /// program without objective when `z0` lies outside them. Only a
    /// certificate of infeasibility says no; a solve that ends otherwise
    /// leaves the question to the fit.
    fn reaches_bounds(&self, z0: &[f64], basis: &DMatrix<f64>) -> bool {
        if self.inside(z0) {
            return true;
        }
        if basis.ncols() == 0 {
            return false;
        }
        let (a, b) = self.bounds_in_w(z0, basis);
        let program = Program {
            q: vec![0.0; basis.ncols()],
            a: Triplets::dense(&a),
            cones: vec![Cone::Nonnegative(b.len())],
            b,
            ..Program::default()
        };
        !matches!(
            conic::solve(program, &Settings::default()),
            Err(SolveError::Infeasible { .. })
        )
    }

    /// The bounds on `z = z0 + N w` as inequalities `A w <= b` in `w`: the
    /// rows `N_v w <= hi_v - z0_v` and `-N_v w <= z0_v - lo_v` of the
    /// bounded free variables, in that order.
    fn bounds_in_w(&self, z0: &[f64], basis: &DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
        let mut rows = Vec::new();
        let mut b = Vec::new();
        let limits = z0.iter().zip(&self.lower).zip(&self.upper);
        for (v, ((&z, &lo), &hi)) in limits.enumerate() {
            if hi.is_finite() {
                rows.push(basis.row(v).iter().copied().collect::<Vec<f64>>());
                b.push(hi - z);
            }
            if lo.is_finite() {
                rows.push(basis.row(v).iter().map(|x| -x).collect());
                b.push(z - lo);
            }
        }
        let a = DMatrix::from_fn(rows.len(), basis.ncols(), |i, j| rows[i][j]);
        (a, b)
    }

    /// Whether `[[equality]]` entries reduce the free variables
    /// (`z = z0 + N w`).
    pub fn has_equalities(&self) -> bool {
        self.reduction.is_some()
    }

    /// Degrees of freedom: the number of variables `w` of the reduction
    /// (`n_free()` without equalities).
    pub fn n_dof(&self) -> usize {
        self.reduction
            .as_ref()
            .map_or(self.n_free(), |r| r.basis.ncols())
    }

    /// The affine map `z = z0 + N w` of the free variables (identity
    /// without equalities): `(z0, N)`, `N` with orthonormal columns.
    pub fn affine(&self) -> (Vec<f64>, DMatrix<f64>) {
        match &self.reduction {
            Some(r) => (r.z0.clone(), r.basis.clone()),
            None => (
                vec![0.0; self.n_free()],
                DMatrix::identity(self.n_free(), self.n_free()),
            ),
        }
    }

    /// The bounds `(lo, hi)` of the free variable `z[v]`.
    pub fn free_bounds(&self, v: usize) -> (f64, f64) {
        (self.lower[v], self.upper[v])
    }

    /// Moves every free variable of `z` that no equality involves into
    /// its bounds: an interior-point solution may end a rounding error
    /// outside them, and clamping such a variable changes no other
    /// constraint.
    pub fn clamp_to_bounds(&self, z: &mut [f64]) {
        for (v, zv) in z.iter_mut().enumerate() {
            let coupled = self.reduction.as_ref().is_some_and(|r| r.coupled[v]);
            if !coupled {
                *zv = zv.clamp(self.lower[v], self.upper[v]);
            }
        }
    }

    /// Projects free variables `z` onto the equalities (orthogonally, in
    /// `z`): `z0 + N N' (z - z0)`. Identity without equalities.
    pub fn project_equalities(&self, z: &mut [f64]) {
        let Some(r) = &self.reduction else { return };
        let d = DVector::from_iterator(z.len(), z.iter().zip(&r.z0).map(|(a, b)| a - b));
        let w = r.basis.transpose() * d;
        let p = &r.basis * w;
        for (v, zv) in z.iter_mut().enumerate() {
            *zv = r.z0[v] + p[v];
        }
    }

    /// Parameters per mode (`theta_i` of `[phi; 1]`).
    pub fn n_params(&self) -> usize {
        self.n_params
    }

    /// Number of modes.
    pub fn modes(&self) -> usize {
        self.slots.len() / self.n_params.max(1)
    }

    /// Number of free variables.
    pub fn n_free(&self) -> usize {
        self.lower.len()
    }

    /// Whether every parameter of every mode is free: no tie, fixed value,
    /// equality or bound (the modes are then independent least squares).
    pub fn is_free(&self) -> bool {
        self.n_free() == self.modes() * self.n_params
            && !self.has_equalities()
            && !self.has_bounds()
    }

    /// Whether the modes are coupled by ties (so they must be estimated
    /// together).
    pub fn couples_modes(&self) -> bool {
        self.ties
    }

    /// Whether some free variable has a finite bound.
    pub fn has_bounds(&self) -> bool {
        self.lower.iter().chain(&self.upper).any(|b| b.is_finite())
    }

    /// The slot of parameter `j` of mode `i`.
    pub fn slot(&self, mode: usize, j: usize) -> Slot {
        self.slots[mode * self.n_params + j]
    }

    /// The mode parameter vectors for the free variables `z`.
    pub fn thetas(&self, z: &[f64]) -> Vec<Vec<f64>> {
        self.slots
            .chunks(self.n_params)
            .map(|mode| {
                mode.iter()
                    .map(|s| match *s {
                        Slot::Free(v) => z[v],
                        Slot::Fixed(x) => x,
                    })
                    .collect()
            })
            .collect()
    }

    /// Projects `z` onto the bounds.
    fn clamp(&self, z: &mut [f64]) {
        for ((v, lo), hi) in z.iter_mut().zip(&self.lower).zip(&self.upper) {
            *v = v.clamp(*lo, *hi);
        }
    }

    fn inside(&self, z: &[f64]) -> bool {
        z.iter()
            .zip(&self.lower)
            .zip(&self.upper)
            .all(|((v, lo), hi)| v >= lo && v <= hi)
    }
}

/// The samples of one mode: regressors `phi` (rows, without the affine
/// column), targets `y` and optional non-negative weights.
#[derive(Debug, Clone, Copy)]
pub struct ModeSamples<'a> {
    /// Regressors, one row per sample (`n_params - 1` columns; the affine
    /// term is added here).
    pub phi: &'a DMatrix<f64>,
    /// Targets.
    pub y: &'a [f64],
    /// Weights (`None`: all one).
    pub weights: Option<&'a [f64]>,
}

/// Minimises `sum_i sum_k w_ik (y_ik - [phi_ik 1] theta_i)^2` over the
/// parameters of all modes under the parametrisation `par` (ties and
/// fixed values exact, bounds through a box-constrained QP). Returns one
/// parameter vector per mode. A mode without samples gets the
/// minimum-norm values of its untied free parameters (zero, clamped to the
/// bounds).
pub fn fit_modes(
    par: &Parametrisation,
    samples: &[ModeSamples<'_>],
) -> Result<Vec<Vec<f64>>, EstimationError> {
    let np = par.n_params;
    if samples.len() != par.modes() {
        return Err(EstimationError::Shape(format!(
            "{} sample sets for {} modes",
            samples.len(),
            par.modes()
        )));
    }
    let rows: usize = samples.iter().map(|m| m.y.len()).sum();
    let nz = par.n_free();
    let mut z_mat = DMatrix::zeros(rows, nz);
    let mut r = DVector::zeros(rows);
    let mut row = 0;
    for (i, m) in samples.iter().enumerate() {
        if m.phi.nrows() != m.y.len()
            || m.phi.ncols() + 1 != np
            || m.weights.is_some_and(|w| w.len() != m.y.len())
        {
            return Err(EstimationError::Shape(format!(
                "mode {}: {}x{} regressors, {} targets, {} parameters",
                i + 1,
                m.phi.nrows(),
                m.phi.ncols(),
                m.y.len(),
                np
            )));
        }
        for k in 0..m.y.len() {
            let w = m.weights.map_or(1.0, |w| w[k]);
            if !(w.is_finite() && w >= 0.0) {
                return Err(EstimationError::Shape(format!(
                    "mode {}: weight {w} of sample {k} is not finite and non-negative",
                    i + 1
                )));
            }
            let sw = w.sqrt();
            let mut target = m.y[k];
            for j in 0..np {
                let x = if j + 1 == np { 1.0 } else { m.phi[(k, j)] };
                match par.slot(i, j) {
                    Slot::Free(v) => z_mat[(row, v)] += sw * x,
                    Slot::Fixed(c) => target -= c * x,
                }
            }
            r[row] = sw * target;
            row += 1;
        }
    }
    let z = solve_in_z(par, &z_mat, &r)?;
    Ok(par.thetas(&z))
}

/// Unconstrained least squares of every mode from its normal equations
/// `(sum phi phi^T) theta = sum phi y`, `phi = [x; 1]`, accumulated in one
/// pass over the `(row, mode)` pairs of `assigned` and solved by Cholesky
/// (`None` when a Gram matrix is singular). For a [`Parametrisation`] that
/// [`Parametrisation::is_free`], it minimises what [`fit_modes`] does, with
/// the conditioning squared: enough inside iterations, which then refit
/// their result by [`fit_modes`].
pub fn normal_equations(
    reg: &Regressors,
    assigned: impl Iterator<Item = (usize, usize)>,
    modes: usize,
) -> Option<Vec<Vec<f64>>> {
    let d = reg.x.ncols();
    let p = d + 1;
    let mut gram = vec![DMatrix::<f64>::zeros(p, p); modes];
    let mut rhs = vec![DVector::<f64>::zeros(p); modes];
    let mut phi = vec![1.0; p];
    for (k, q) in assigned {
        for (j, v) in phi.iter_mut().take(d).enumerate() {
            *v = reg.x[(k, j)];
        }
        let (g, r) = (&mut gram[q], &mut rhs[q]);
        for i in 0..p {
            r[i] += phi[i] * reg.y[k];
            for j in i..p {
                g[(i, j)] += phi[i] * phi[j];
            }
        }
    }
    gram.into_iter()
        .zip(rhs)
        .map(|(mut g, r)| {
            g.fill_lower_triangle_with_upper_triangle();
            g.cholesky().map(|c| c.solve(&r).iter().copied().collect())
        })
        .collect()
}

/// [`fit_modes`] on the rows `rows[i]` of `reg` for mode `i`, unweighted.
pub fn fit_modes_on(
    par: &Parametrisation,
    reg: &Regressors,
    rows: &[Vec<usize>],
) -> Result<Vec<Vec<f64>>, EstimationError> {
    let parts: Vec<(DMatrix<f64>, Vec<f64>)> = rows
        .iter()
        .map(|r| {
            let s = reg.select(r);
            (s.x, s.y.iter().copied().collect())
        })
        .collect();
    let samples: Vec<ModeSamples<'_>> = parts
        .iter()
        .map(|(phi, y)| ModeSamples {
            phi,
            y,
            weights: None,
        })
        .collect();
    fit_modes(par, &samples)
}

/// `min |Z z - r|^2` over the free variables `z` of `par` under its
/// equalities (null-space method: `z = z0 + N w`, least squares in `w`)
/// and its bounds (the box-constrained QP when the minimiser leaves the
/// box). Every estimate of the mode parameters goes through here: the
/// ordinary fit ([`fit_modes`]), the projection ([`Parametrisation::project`])
/// and the damped steps of the simulation-error refinement
/// ([`crate::pwarx::refine`]).
pub fn solve_in_z(
    par: &Parametrisation,
    z_mat: &DMatrix<f64>,
    r: &DVector<f64>,
) -> Result<Vec<f64>, EstimationError> {
    let Some(red) = &par.reduction else {
        let mut z: Vec<f64> = linalg::lstsq(z_mat, r)?.theta.iter().copied().collect();
        if !par.inside(&z) {
            z = bounded_lstsq(par, z_mat, r)?;
        }
        return Ok(z);
    };
    let z0 = DVector::from_column_slice(&red.z0);
    let design = z_mat * &red.basis;
    let rhs = r - z_mat * &z0;
    let z_of = |w: &DVector<f64>| -> Vec<f64> { (&z0 + &red.basis * w).iter().copied().collect() };
    let w = if design.ncols() == 0 {
        DVector::zeros(0)
    } else {
        linalg::lstsq(&design, &rhs)?.theta
    };
    let z = z_of(&w);
    if par.inside(&z) || design.ncols() == 0 {
        return Ok(z);
    }
    let (a, b) = par.bounds_in_w(&red.z0, &red.basis);
    let w = qp_lstsq(&design, &rhs, &a, &b)?;
    Ok(z_of(&DVector::from_vec(w)))
}

/// `min |D x - r|^2` subject to `A x <= b`, the QP
/// `min 1/2 x' (D'D) x - (D'r)' x` on clarabel, in variables scaled by the
/// column norms of `D`; where clarabel stalls at its strict and at its own
/// tolerances, [`whitened_qp`].
fn qp_lstsq(
    design: &DMatrix<f64>,
    r: &DVector<f64>,
    a_in: &DMatrix<f64>,
    b: &[f64],
) -> Result<Vec<f64>, EstimationError> {
    let (d, p, q) = scaled_objective(design, r);
    let mut a_s = a_in.clone();
    for (v, dv) in d.iter().enumerate() {
        a_s.column_mut(v).scale_mut(*dv);
    }
    let a = Triplets::dense(&a_s);
    let m = b.len();
    let settings = Settings {
        max_iter: 200,
        tol_gap_abs: 1e-12,
        tol_gap_rel: 1e-12,
        tol_feas: 1e-12,
        ..Settings::default()
    };
    let program = Program {
        p,
        q,
        a,
        b: b.to_vec(),
        cones: vec![Cone::Nonnegative(m)],
    };
    // Where the strict tolerances make no progress (an active bound that an
    // equality pins, the minimiser on the box's face), clarabel's own
    // tolerances end the solve.
    let sol = match conic::solve(program.clone(), &settings) {
        Err(conic::SolveError::InsufficientProgress { .. }) => {
            let settings = Settings {
                max_iter: 200,
                ..Settings::default()
            };
            match conic::solve(program, &settings) {
                Err(e @ conic::SolveError::InsufficientProgress { .. }) => {
                    return whitened_qp(design, r, a_in, b).ok_or(e.into());
                }
                solved => solved?,
            }
        }
        solved => solved?,
    };
    Ok(sol.x.iter().zip(&d).map(|(x, dv)| x * dv).collect())
}

/// [`qp_lstsq`]'s problem in the variables `v = R x` of the QR
/// factorisation `D = Q R`: `min |v - Q'r|^2` subject to `A R^-1 v <= b`,
/// whose objective is the identity however nearly collinear the columns
/// of `D` are (where they nearly are, the interior point stalls on the
/// Gram matrix `D'D`). `None` when `D` has fewer rows than columns, `R`
/// is singular, the solve fails, or its point breaks a constraint by more
/// than the solver's tolerance.
fn whitened_qp(
    design: &DMatrix<f64>,
    r: &DVector<f64>,
    a_in: &DMatrix<f64>,
    b: &[f64],
) -> Option<Vec<f64>> {
    let n = design.ncols();
    if design.nrows() < n {
        return None;
    }
    let qr = design.clone().qr();
    let rr = qr.r();
    let c = qr.q().transpose() * r;
    let top = rr.diagonal().amax();
    if top.is_nan() || top <= 0.0 || rr.diagonal().iter().any(|v| v.abs() <= 1e-14 * top) {
        return None;
    }
    // G = A R^-1, row by row: R' g = a.
    let g = rr
        .transpose()
        .solve_lower_triangular(&a_in.transpose())?
        .transpose();
    let mut p = Triplets::default();
    for i in 0..n {
        p.push(i, i, 1.0);
    }
    let program = Program {
        p,
        q: c.iter().map(|v| -v).collect(),
        a: Triplets::dense(&g),
        b: b.to_vec(),
        cones: vec![Cone::Nonnegative(b.len())],
    };
    let settings = Settings {
        max_iter: 200,
        ..Settings::default()
    };
    let v = DVector::from_vec(conic::solve(program, &settings).ok()?.x);
    let x = rr.solve_upper_triangular(&v)?;
    let feasible = (a_in * &x)
        .iter()
        .zip(b)
        .all(|(ax, bi)| ax.is_finite() && *ax <= bi + 1e-7 * (1.0 + bi.abs()));
    feasible.then(|| x.iter().copied().collect())
}

impl Parametrisation {
    /// The point of the parameter set nearest to `thetas` (one vector per
    /// mode; least squares over the free parameters): ties, fixed values and
    /// equalities exact, bounds through the QP.
    pub fn project(&self, thetas: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, EstimationError> {
        Ok(self.thetas(&self.free_values(thetas)?))
    }

    /// The free variables `z` of [`Parametrisation::project`]`(thetas)`.
    pub fn free_values(&self, thetas: &[Vec<f64>]) -> Result<Vec<f64>, EstimationError> {
        let np = self.n_params;
        if thetas.len() != self.modes() || thetas.iter().any(|t| t.len() != np) {
            return Err(EstimationError::Shape(format!(
                "{} parameter vectors for {} modes of {np} parameters",
                thetas.len(),
                self.modes()
            )));
        }
        let mut rows: Vec<(usize, f64)> = Vec::new();
        for (i, t) in thetas.iter().enumerate() {
            for (j, x) in t.iter().enumerate() {
                if let Slot::Free(v) = self.slot(i, j) {
                    rows.push((v, *x));
                }
            }
        }
        let mut z_mat = DMatrix::zeros(rows.len(), self.n_free());
        let mut r = DVector::zeros(rows.len());
        for (k, (v, x)) in rows.iter().enumerate() {
            z_mat[(k, *v)] = 1.0;
            r[k] = *x;
        }
        solve_in_z(self, &z_mat, &r)
    }

    /// The finite bounds of the free variables as rows `A z <= b`: per
    /// variable, its upper bound, then its lower one.
    fn box_rows(&self) -> (DMatrix<f64>, Vec<f64>) {
        let mut rows: Vec<(usize, f64, f64)> = Vec::new();
        for v in 0..self.n_free() {
            if self.upper[v].is_finite() {
                rows.push((v, 1.0, self.upper[v]));
            }
            if self.lower[v].is_finite() {
                rows.push((v, -1.0, -self.lower[v]));
            }
        }
        let mut a = DMatrix::zeros(rows.len(), self.n_free());
        let b = rows.iter().map(|r| r.2).collect();
        for (i, &(v, sign, _)) in rows.iter().enumerate() {
            a[(i, v)] = sign;
        }
        (a, b)
    }
}

/// `min |Z z - r|^2` subject to `lo <= z <= hi`, as the QP
/// `min 1/2 z' (Z'Z) z - (Z'r)' z` on clarabel, in variables scaled by the
/// column norms of `Z` ([`whitened_qp`] where clarabel stalls). The result
/// is clamped to the box (clarabel's interior point stays within its
/// tolerance of it).
fn bounded_lstsq(
    par: &Parametrisation,
    z_mat: &DMatrix<f64>,
    r: &DVector<f64>,
) -> Result<Vec<f64>, EstimationError> {
    let (d, p, q) = scaled_objective(z_mat, r);
    let (box_a, b) = par.box_rows();
    let mut scaled = box_a.clone();
    for (v, dv) in d.iter().enumerate() {
        scaled.column_mut(v).scale_mut(*dv);
    }
    let a = Triplets::dense(&scaled);
    let m = b.len();
    let settings = Settings {
        max_iter: 200,
        tol_gap_abs: 1e-12,
        tol_gap_rel: 1e-12,
        ..Settings::default()
    };
    let program = Program {
        p,
        q,
        a,
        b: b.clone(),
        cones: vec![Cone::Nonnegative(m)],
    };
    let mut z: Vec<f64> = match conic::solve(program, &settings) {
        Ok(sol) => sol.x.iter().zip(&d).map(|(x, dv)| x * dv).collect(),
        Err(e @ conic::SolveError::InsufficientProgress { .. }) => {
            whitened_qp(z_mat, r, &box_a, &b).ok_or(e)?
        }
        Err(e) => return Err(e.into()),
    };
    par.clamp(&mut z);
    Ok(z)
}

/// The least-squares objective `|M x - r|^2` as clarabel's QP in scaled
/// variables `x = D xi`, `D = diag(1 / |M_col|)` (1 for empty columns):
/// returns `D`'s diagonal, `P = (MD)'(MD)` (upper triangle) and
/// `q = -(MD)' r`.
fn scaled_objective(m: &DMatrix<f64>, r: &DVector<f64>) -> (Vec<f64>, Triplets, Vec<f64>) {
    let d: Vec<f64> = (0..m.ncols())
        .map(|v| {
            let n = m.column(v).norm();
            if n > 0.0 { 1.0 / n } else { 1.0 }
        })
        .collect();
    let mut ms = m.clone();
    for (v, dv) in d.iter().enumerate() {
        ms.column_mut(v).scale_mut(*dv);
    }
    let h = ms.transpose() * &ms;
    let q = (ms.transpose() * r).iter().map(|v| -v).collect();
    (d, gram_upper(&h), q)
}

/// The upper triangle of the Gram matrix `h` as clarabel's `P`, with a
/// tiny ridge (1e-12) on empty diagonal entries: an empty column keeps `P`
/// definite there.
fn gram_upper(h: &DMatrix<f64>) -> Triplets {
    let n = h.ncols();
    let mut p = Triplets::default();
    for c in 0..n {
        for r in 0..=c {
            let mut v = h[(r, c)];
            if r == c && v == 0.0 {
                v = 1e-12;
            }
            p.push(r, c, v);
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn priors(text: &str) -> Priors {
        Priors::from_toml(text, "p.toml").unwrap()
    }

    /// Two ARX(1,1) modes, y = a y1 + b u1 + c.
    fn two_modes(theta: [[f64; 3]; 2], n: usize) -> Vec<(DMatrix<f64>, Vec<f64>)> {
        theta
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let phi = DMatrix::from_fn(n, 2, |k, j| {
                    ((k * 7 + j * 3 + i * 11) % 13) as f64 / 6.0 - 1.0
                });
                let y = (0..n)
                    .map(|k| t[0] * phi[(k, 0)] + t[1] * phi[(k, 1)] + t[2])
                    .collect();
                (phi, y)
            })
            .collect()
    }

    fn samples(d: &[(DMatrix<f64>, Vec<f64>)]) -> Vec<ModeSamples<'_>> {
        d.iter()
            .map(|(phi, y)| ModeSamples {
                phi,
                y,
                weights: None,
            })
            .collect()
    }

    #[test]
    fn free_parametrisation_recovers_each_mode() {
        let d = two_modes([[0.5, 1.0, 0.2], [-0.3, 2.0, -1.0]], 30);
        let t = fit_modes(&Parametrisation::free(3, 2), &samples(&d)).unwrap();
        for (got, want) in t.iter().zip([[0.5, 1.0, 0.2], [-0.3, 2.0, -1.0]]) {
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 1e-10, "{t:?}");
            }
        }
    }

    /// A variable no equality involves is moved into its bounds; one an
    /// equality involves is left for the equality to hold.
    #[test]
    fn clamping_keeps_the_equalities() {
        let text = "[bounds]\na1 = [1.9, 1.94]\nb1 = [0.0, 1.0]\n[[equality]]\ncoefficients = { b1 = 1.0, c = 1.0 }\nvalue = 2.0\n";
        let par =
            Parametrisation::from_priors(&priors(text), &RegressorSpec::new(1, 1, 1), 1).unwrap();
        // Free variables in the order a1, b1, c: a1 just past its bound,
        // b1 past its own but on the equality with c.
        let mut z = vec![1.940_000_000_3, 1.1, 0.9];
        par.clamp_to_bounds(&mut z);
        assert_eq!(z, [1.94, 1.1, 0.9]);
        let free = Parametrisation::from_priors(
            &priors("[bounds]\nb1 = [0.0, 1.0]\n"),
            &RegressorSpec::new(1, 1, 1),
            1,
        )
        .unwrap();
        let mut z = vec![0.3, 1.1, -2.0];
        free.clamp_to_bounds(&mut z);
        assert_eq!(z, [0.3, 1.0, -2.0]);
    }

    #[test]
    fn fixed_outside_bounds_is_an_error() {
        let p = priors("[fixed]\nb1 = 5.0\n[bounds]\nb1 = [0.0, 1.0]\n");
        let e = Parametrisation::from_priors(&p, &RegressorSpec::new(1, 1, 1), 2).unwrap_err();
        assert_eq!(
            e.to_string(),
            "[fixed] b1 = 5 lies outside [bounds] b1 = [0, 1]"
        );
    }

    /// Equalities that determine a parameter at a value outside its bounds
    /// are refused when the priors are read, not fitted through.
    #[test]
    fn equalities_determining_values_outside_the_bounds_are_an_error() {
        let text = "[fixed]\nc = 0.0\n[[equality]]\ncoefficients = { b1 = 1.0, c = 1.0 }\nvalue = 0.9\n[bounds]\nb1 = [0.0, 0.05]\n";
        let e = Parametrisation::from_priors(&priors(text), &RegressorSpec::new(0, 1, 1), 2)
            .unwrap_err();
        assert_eq!(e, PriorConflict::OutsideBounds);
        // Inside the bounds, the same entries parametrise the modes.
        let inside = text.replace("value = 0.9", "value = 0.01");
        assert!(
            Parametrisation::from_priors(&priors(&inside), &RegressorSpec::new(0, 1, 1), 2).is_ok()
        );
    }

    /// Equalities whose solutions all lie outside the bounds, with
    /// parameters left free, are refused too; where some solution lies
    /// inside them (though the minimum-norm one does not), they are not.
    #[test]
    fn equalities_with_no_solution_inside_the_bounds_are_an_error() {
        let spec = RegressorSpec::new(1, 1, 1);
        let refused =
            "[bounds]\na1 = [0.0, 1.0]\n[[equality]]\ncoefficients = { a1 = 1.0 }\nvalue = 5.0\n";
        let e = Parametrisation::from_priors(&priors(refused), &spec, 2).unwrap_err();
        assert_eq!(e, PriorConflict::OutsideBounds);
        // a1 + b1 = 5 has the minimum-norm solution a1 = b1 = 2.5, outside
        // a1's bounds, and a1 = 1, b1 = 4 inside them.
        let reachable = "[bounds]\na1 = [0.0, 1.0]\n[[equality]]\ncoefficients = { a1 = 1.0, b1 = 1.0 }\nvalue = 5.0\n";
        assert!(Parametrisation::from_priors(&priors(reachable), &spec, 2).is_ok());
        // With b1 bounded too, no solution is left.
        let squeezed = reachable.replace("a1 = [0.0, 1.0]", "a1 = [0.0, 1.0]\nb1 = [0.0, 3.0]");
        let e = Parametrisation::from_priors(&priors(&squeezed), &spec, 2).unwrap_err();
        assert_eq!(e, PriorConflict::OutsideBounds);
    }

    #[test]
    fn bounds_bind_exactly() {
        // True b = 2 in both modes, bound b1 <= 1.5: the QP puts b1 on it.
        let d = two_modes([[0.5, 2.0, 0.0], [-0.3, 2.0, 0.0]], 40);
        let p = priors("[bounds]\nb1 = [0.0, 1.5]\n");
        let par = Parametrisation::from_priors(&p, &RegressorSpec::new(1, 1, 1), 2).unwrap();
        assert!(par.has_bounds() && !par.couples_modes());
        let t = fit_modes(&par, &samples(&d)).unwrap();
        for m in &t {
            assert!((m[1] - 1.5).abs() < 1e-6 && m[1] <= 1.5, "{t:?}");
        }
    }

    /// The QP of a fit on the simulated saturation record under the
    /// example prior of docs/priors.md: nearly collinear columns
    /// (correlation 0.99997), on which clarabel stalls on the Gram matrix
    /// at either tolerance. The solution is the least squares over the active set
    /// that meets the KKT conditions, found here by trying every set.
    #[test]
    fn a_qp_of_nearly_collinear_columns_is_solved() {
        let h = DMatrix::from_row_slice(
            4,
            4,
            &[
                151395.6179741964,
                107037.84415284837,
                74689.74173896738,
                -76688.54859666529,
                107037.84415284837,
                75679.65408656538,
                52807.03830240525,
                -54220.02705669356,
                74689.74173896738,
                52807.03830240525,
                36849.23478769268,
                -37835.07902819053,
                -76688.54859666529,
                -54220.02705669356,
                -37835.07902819053,
                38847.502647487854,
            ],
        );
        let g = DVector::from_column_slice(&[
            151411.73343238846,
            107046.5542243961,
            74695.60492663589,
            -76694.94843860381,
        ]);
        let design = h.clone().cholesky().unwrap().l().transpose();
        let r = design.transpose().solve_lower_triangular(&g).unwrap();
        let (c, d) = (0.5000000000000001, 0.35355339059327373);
        let a = DMatrix::from_row_slice(
            4,
            4,
            &[
                0.0, c, -d, d, 0.0, -c, d, -d, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0, -0.5, -0.5,
            ],
        );
        let b = [1000.0, 0.0, 1000.0, 0.0];
        let whitened = DVector::from_vec(whitened_qp(&design, &r, &a, &b).unwrap());
        let x = DVector::from_vec(qp_lstsq(&design, &r, &a, &b).unwrap());
        let cost = |x: &DVector<f64>| (&design * x - &r).norm_squared();
        // Every active set: the least squares on it, kept where feasible.
        let mut best = f64::INFINITY;
        for set in 0u32..16 {
            let rows: Vec<usize> = (0..4).filter(|i| set & (1 << i) != 0).collect();
            let k = rows.len();
            let mut kkt = DMatrix::zeros(4 + k, 4 + k);
            kkt.view_mut((0, 0), (4, 4)).copy_from(&h);
            let mut rhs = DVector::zeros(4 + k);
            rhs.rows_mut(0, 4).copy_from(&g);
            for (j, &i) in rows.iter().enumerate() {
                for v in 0..4 {
                    kkt[(4 + j, v)] = a[(i, v)];
                    kkt[(v, 4 + j)] = a[(i, v)];
                }
                rhs[4 + j] = b[i];
            }
            let Some(sol) = kkt.lu().solve(&rhs) else {
                continue;
            };
            let y = sol.rows(0, 4).into_owned();
            if (&a * &y).iter().zip(&b).all(|(l, r)| *l <= r + 1e-7) {
                best = best.min(cost(&y));
            }
        }
        // Both feasible and optimal within the solver's tolerance of the
        // objective's scale.
        let scale = r.norm_squared();
        for x in [&x, &whitened] {
            assert!((&a * x).iter().zip(&b).all(|(l, r)| *l <= r + 1e-6), "{x}");
            assert!(cost(x) <= best + 1e-7 * scale, "{} against {best}", cost(x));
        }
        // Fewer rows than columns: no change of variables, no answer.
        let short = design.rows(0, 3).into_owned();
        assert!(whitened_qp(&short, &r.rows(0, 3).into_owned(), &a, &b).is_none());
    }

    #[test]
    fn inconsistent_equalities_name_the_entry() {
        let p = priors(
            "[fixed]\na1 = 0.5\n[[equality]]\ncoefficients = { a1 = 1.0, b1 = 1.0 }\nvalue = 1.0\n\
             [[equality]]\ncoefficients = { b1 = 2.0 }\nvalue = 3.0\n",
        );
        let e = Parametrisation::from_priors(&p, &RegressorSpec::new(1, 1, 1), 2).unwrap_err();
        assert_eq!(
            e.to_string(),
            "[[equality]] #2 (2 b1 = 3) contradicts the [fixed] values, [[tie]]s and earlier \
             [[equality]] entries (#1..#1): no parameter vector satisfies them all"
        );
        // Redundant but consistent entries are fine.
        let p = priors(
            "[[equality]]\ncoefficients = { a1 = 1.0, b1 = 1.0 }\nvalue = 1.0\n\
             [[equality]]\ncoefficients = { a1 = 2.0, b1 = 2.0 }\nvalue = 2.0\n",
        );
        let par = Parametrisation::from_priors(&p, &RegressorSpec::new(1, 1, 1), 2).unwrap();
        assert_eq!(par.n_dof(), 4);
    }

    proptest! {
        /// Random `[[equality]]` entries with ties, fixed values and bounds:
        /// every equality holds to 1e-9 in every mode, ties bitwise, fixed
        /// values unchanged, bounds within the QP tolerance.
        #[test]
        fn random_equalities_hold(
            c1 in prop::collection::vec(-2.0f64..2.0, 3),
            v1 in -1.0f64..1.0,
            c2 in prop::collection::vec(-2.0f64..2.0, 3),
            v2 in -1.0f64..1.0,
            noise in 0.0f64..0.5,
            with_tie in any::<bool>(),
            with_bound in any::<bool>(),
        ) {
            let names = ["a1", "b1", "c"];
            let eq = |c: &[f64], v: f64| {
                let terms: Vec<String> = names.iter().zip(c).map(|(n, x)| format!("{n} = {x:?}")).collect();
                format!("[[equality]]\ncoefficients = {{ {} }}\nvalue = {v:?}\n", terms.join(", "))
            };
            let mut text = eq(&c1, v1);
            // The second equality only on b1, c (with a tie on a1 the
            // system stays consistent).
            text += &eq(&[0.0, c2[1], c2[2]], v2);
            if with_tie {
                text += "[[tie]]\nparams = [\"a1\"]\n";
            }
            if with_bound {
                text += "[bounds]\nb1 = [-0.5, 0.5]\n";
            }
            let p = priors(&text);
            let mut d = two_modes([[0.5, 1.0, 0.2], [-0.3, 2.0, -1.0]], 30);
            for (k, y) in d[0].1.iter_mut().enumerate() {
                *y += noise * (((k * 37) % 11) as f64 / 5.0 - 1.0);
            }
            let par = match Parametrisation::from_priors(&p, &RegressorSpec::new(1, 1, 1), 2) {
                Ok(par) => par,
                // Random coefficients can be (nearly) contradictory: the
                // error must name an entry.
                Err(e) => {
                    prop_assert!(e.to_string().contains("[[equality]]"), "{}", e);
                    return Ok(());
                }
            };
            let t = match fit_modes(&par, &samples(&d)) {
                Ok(t) => t,
                Err(EstimationError::Solver(_)) if with_bound => return Ok(()), // infeasible box
                Err(e) => return Err(TestCaseError::fail(e.to_string())),
            };
            for m in &t {
                for (c, v) in [(&c1[..], v1), (&[0.0, c2[1], c2[2]][..], v2)] {
                    let lhs: f64 = m.iter().zip(c).map(|(x, y)| x * y).sum();
                    let scale = 1.0 + m.iter().map(|x| x.abs()).fold(0.0, f64::max);
                    prop_assert!((lhs - v).abs() <= 1e-9 * scale, "{:?}: {} != {}", t, lhs, v);
                }
                if with_bound {
                    prop_assert!(m[1] >= -0.5 - 1e-7 && m[1] <= 0.5 + 1e-7, "{:?}", t);
                }
            }
            if with_tie {
                prop_assert_eq!(t[0][0].to_bits(), t[1][0].to_bits());
            }
            // The projection lands in the set too.
            let proj = par.project(&[vec![1.0, 1.0, 1.0], vec![-1.0, 0.0, 2.0]]).unwrap();
            for m in &proj {
                let lhs: f64 = m.iter().zip(&c1).map(|(x, y)| x * y).sum();
                prop_assert!((lhs - v1).abs() <= 1e-9 * (1.0 + m.iter().map(|x| x.abs()).fold(0.0, f64::max)));
            }
        }
    }

    proptest! {
        /// Ties hold to 1e-9 (here: exactly), fixed values come back
        /// unchanged, bounds are respected, with a consistent truth the
        /// fit is exact, and no other parameters the priors admit (the
        /// estimate moved by `step`, `b1` kept in its box) fit better.
        #[test]
        fn priors_hold_in_the_estimate(
            a in -0.9f64..0.9, b1 in -2.0f64..2.0, b2 in -2.0f64..2.0,
            c in -1.0f64..1.0, noise in prop_oneof![Just(0.0), 0.0f64..0.5],
            lo in -3.0f64..0.0, step in prop::collection::vec(-0.1f64..0.1, 3),
        ) {
            let mut d = two_modes([[a, b1, c], [a, b2, c]], 25);
            for (k, y) in d[1].1.iter_mut().enumerate() {
                *y += noise * (((k * 37) % 11) as f64 / 5.0 - 1.0);
            }
            let p = priors(&format!(
                "[[tie]]\nparams = [\"a1\"]\n[fixed]\nc = {c}\n[bounds]\nb1 = [{lo}, 0.5]\n"
            ));
            let par = Parametrisation::from_priors(&p, &RegressorSpec::new(1, 1, 1), 2).unwrap();
            prop_assert!(par.couples_modes());
            prop_assert_eq!(par.n_free(), 1 + 2);
            let t = fit_modes(&par, &samples(&d)).unwrap();
            prop_assert_eq!(t[0][0].to_bits(), t[1][0].to_bits());
            prop_assert_eq!(t[0][2].to_bits(), c.to_bits());
            prop_assert_eq!(t[1][2].to_bits(), c.to_bits());
            for m in &t {
                prop_assert!(m[1] >= lo && m[1] <= 0.5);
            }
            if noise == 0.0 && b1 >= lo && b1 <= 0.5 && b2 >= lo && b2 <= 0.5 {
                prop_assert!((t[0][1] - b1).abs() < 1e-8 && (t[1][1] - b2).abs() < 1e-8);
            }
            let cost = |t: &[Vec<f64>]| -> f64 {
                (d.iter().zip(t))
                    .map(|((phi, y), m)| {
                        (0..y.len())
                            .map(|k| (y[k] - m[0] * phi[(k, 0)] - m[1] * phi[(k, 1)] - m[2]).powi(2))
                            .sum::<f64>()
                    })
                    .sum()
            };
            let moved: Vec<Vec<f64>> = (t.iter())
                .map(|m| {
                    let b = (m[1] + step[1]).clamp(lo, 0.5);
                    vec![m[0] + step[0], b, m[2]]
                })
                .collect();
            let mut other = moved.clone();
            other[1][1] = t[1][1] + step[2];
            other[1][1] = other[1][1].clamp(lo, 0.5);
            for admitted in [moved, other] {
                prop_assert!(
                    cost(&t) <= cost(&admitted) * (1.0 + 1e-9) + 1e-12,
                    "{} > {} at {:?}", cost(&t), cost(&admitted), admitted
                );
            }
        }
    }
}
