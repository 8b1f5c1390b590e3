//! Gray-box parameter priors (`[fixed]`, `[bounds]`, `[[tie]]`;
//! `docs/priors.md`) inside the bounded-error procedure.
//!
//! The stacked parameters of the ordinary modes are parametrised by
//! [`Parametrisation::from_priors`] (`hysid_estimation::constrained`): every
//! parameter of every mode is a shared free variable or a fixed value, with
//! box bounds per free variable. The procedure uses it in two forms:
//!
//! - [`ModeSpace`]: the parameter set of **one** mode (fixed values
//!   substituted, bounds as constraints). Used by MAX FS (starts, thermal
//!   relaxation with projection, polish) and by the per-mode refits and
//!   merges. Ties are trivial for one mode; once the modes share tied
//!   values, [`ModeConstraints::mode_space`] fixes the tied parameters at the
//!   shared values, so a per-mode refit keeps the ties.
//! - [`ModeConstraints::joint`]: all modes at once, tied parameters as shared
//!   variables, for the joint Chebyshev LP ([`crate::refit::chebyshev_joint`])
//!   and the joint least squares (`hysid_estimation::constrained::fit_modes`).

use crate::refit::{self, ChebyshevFit, least_squares_joint};
use crate::samples::Samples;
use hysid_core::priors::Priors;
use hysid_estimation::constrained::{Parametrisation, PriorConflict, Slot};
use hysid_estimation::pwarx::PwarxData;
use hysid_model::regressors::RegressorSpec;

/// The parameter priors of a run that restrict the modes' parameters:
/// `[[tie]]`, `[fixed]`, `[bounds]` and `[[equality]]` of the priors, for
/// the PWARX structure of the data. The default is no constraint.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModeConstraints {
    /// Only the tie, fixed, bounds and equality entries.
    priors: Priors,
    /// The structure (`None`: no constraint at all).
    spec: Option<RegressorSpec>,
}

impl ModeConstraints {
    /// The constraints of the priors of `data` (their names were checked by
    /// [`prepare`](fn@hysid_estimation::pwarx::prepare)). A fixed value outside its bounds is an error
    /// naming it.
    pub fn new(data: &PwarxData<'_>) -> Result<Self, PriorConflict> {
        let priors = data.priors();
        let kept = Priors {
            tie: priors.tie.clone(),
            fixed: priors.fixed.clone(),
            bounds: priors.bounds.clone(),
            equality: priors.equality.clone(),
            ..Default::default()
        };
        if kept == Priors::default() {
            return Ok(Self::default());
        }
        Parametrisation::from_priors(&kept, &data.spec, 1)?;
        Ok(Self {
            priors: kept,
            spec: Some(data.spec),
        })
    }

    /// True when there is no parameter prior.
    pub fn is_free(&self) -> bool {
        self.spec.is_none()
    }

    /// True when ties couple the modes (so the procedure needs the joint
    /// estimation once there is more than one mode).
    pub fn has_ties(&self) -> bool {
        !self.priors.tie.is_empty()
    }

    /// Indices of the tied parameters.
    fn tied_params(&self) -> Vec<usize> {
        let Some(spec) = &self.spec else {
            return Vec::new();
        };
        let names = spec.param_names();
        (0..names.len())
            .filter(|&j| {
                !self.priors.fixed.contains_key(&names[j])
                    && self
                        .priors
                        .tie
                        .iter()
                        .any(|t| t.params.iter().any(|p| *p == names[j]))
            })
            .collect()
    }

    /// The parameter set of one mode, `p` parameters. With `shared`, the
    /// tied parameters are fixed at its values (the values every mode
    /// shares); without, ties are relaxed (the greedy extraction).
    pub fn mode_space(&self, p: usize, shared: Option<&[f64]>) -> ModeSpace {
        let Some(spec) = self.spec else {
            return ModeSpace::free(p);
        };
        let mut pri = self.priors.clone();
        if let Some(theta) = shared {
            let names = spec.param_names();
            for j in self.tied_params() {
                let [lo, hi] = pri
                    .bounds
                    .get(&names[j])
                    .copied()
                    .unwrap_or([f64::NEG_INFINITY, f64::INFINITY]);
                pri.fixed.insert(names[j].clone(), theta[j].clamp(lo, hi));
            }
        }
        pri.tie.clear();
        // The shared values come from a joint fit under the same priors, so
        // they satisfy the equalities and bounds; should rounding make them
        // inconsistent, the mode keeps the constraints without the ties.
        let par = Parametrisation::from_priors(&pri, &spec, 1)
            .or_else(|_| {
                let mut relaxed = self.priors.clone();
                relaxed.tie.clear();
                Parametrisation::from_priors(&relaxed, &spec, 1)
            })
            .expect("the priors were checked by ModeConstraints::new");
        let bounds = free_bounds(&par);
        ModeSpace {
            p,
            par: Some(par),
            bounds,
        }
    }

    /// The joint parametrisation of `modes` modes (tied parameters shared)
    /// with the bounds of each free variable; `None` without constraints.
    pub fn joint(&self, modes: usize) -> Option<(Parametrisation, Vec<(f64, f64)>)> {
        let spec = self.spec?;
        let par = Parametrisation::from_priors(&self.priors, &spec, modes)
            .expect("fixed values within bounds were checked in ModeConstraints::new");
        let bounds = free_bounds(&par);
        Some((par, bounds))
    }

    /// Least squares of every mode on its samples `groups` under the
    /// priors: jointly when they constrain the parameters (so ties hold),
    /// mode by mode otherwise. `None` when a fit fails.
    pub fn least_squares_modes(&self, s: &Samples, groups: &[Vec<usize>]) -> Option<Vec<Vec<f64>>> {
        match self.joint(groups.len()) {
            Some((par, _)) => least_squares_joint(s, &par, groups),
            None => groups.iter().map(|g| refit::least_squares(s, g)).collect(),
        }
    }
}

/// Bounds of each free variable of `par` (a tied variable has the bounds
/// of its parameter, the same in every mode).
fn free_bounds(par: &Parametrisation) -> Vec<(f64, f64)> {
    (0..par.n_free()).map(|v| par.free_bounds(v)).collect()
}

/// The parameter set of one mode: every parameter free or fixed, free
/// ones boxed (see [`ModeConstraints::mode_space`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ModeSpace {
    p: usize,
    /// `None`: every parameter free and unbounded (the unconstrained
    /// procedure, unchanged).
    par: Option<Parametrisation>,
    bounds: Vec<(f64, f64)>,
}

impl ModeSpace {
    /// No constraint on `p` parameters.
    pub fn free(p: usize) -> Self {
        Self {
            p,
            par: None,
            bounds: Vec::new(),
        }
    }

    /// True when unconstrained.
    pub fn is_free(&self) -> bool {
        self.par.is_none()
    }

    /// Which parameters move in the thermal relaxation (not fixed).
    pub fn movable(&self) -> Vec<bool> {
        match &self.par {
            None => vec![true; self.p],
            Some(par) => (0..self.p)
                .map(|j| matches!(par.slot(0, j), Slot::Free(_)))
                .collect(),
        }
    }

    /// Projects `theta` onto the set: fixed values substituted, free values
    /// clamped to their bounds (the projection step of the relaxation).
    /// With `[[equality]]` entries: the orthogonal projection onto the
    /// equalities, alternated with the clamp to the bounds and ending with
    /// the equalities (so they hold exactly, the bounds to the alternation's
    /// accuracy; [`ModeSpace::project_exact`] solves the projection QP).
    pub fn project(&self, theta: &mut [f64]) {
        let Some(par) = &self.par else { return };
        if !par.has_equalities() {
            for (j, t) in theta.iter_mut().enumerate() {
                match par.slot(0, j) {
                    Slot::Fixed(c) => *t = c,
                    Slot::Free(v) => *t = t.clamp(self.bounds[v].0, self.bounds[v].1),
                }
            }
            return;
        }
        let mut z = vec![0.0; par.n_free()];
        for (j, t) in theta.iter().enumerate() {
            if let Slot::Free(v) = par.slot(0, j) {
                z[v] = *t;
            }
        }
        par.project_equalities(&mut z);
        for _ in 0..50 {
            let mut moved = false;
            for (zv, &(lo, hi)) in z.iter_mut().zip(&self.bounds) {
                let c = zv.clamp(lo, hi);
                moved |= c != *zv;
                *zv = c;
            }
            if !moved {
                break;
            }
            par.project_equalities(&mut z);
        }
        for (j, t) in theta.iter_mut().enumerate() {
            *t = match par.slot(0, j) {
                Slot::Fixed(c) => c,
                Slot::Free(v) => z[v],
            };
        }
    }

    /// [`ModeSpace::project`], exact with equalities and bounds together
    /// (the nearest point by the QP of `hysid_estimation::constrained`).
    pub fn project_exact(&self, theta: &mut [f64]) {
        if let Some(par) = &self.par
            && par.has_equalities()
            && par.has_bounds()
            && let Ok(t) = par.project(&[theta.to_vec()])
            && let Some(t) = t.into_iter().next()
        {
            theta.copy_from_slice(&t);
            return;
        }
        self.project(theta);
    }

    /// Least squares on `idx` within the set (fixed values exact, bounds
    /// by the QP of `fit_modes`).
    pub fn least_squares(&self, s: &Samples, idx: &[usize]) -> Option<Vec<f64>> {
        let Some(par) = &self.par else {
            return refit::least_squares(s, idx);
        };
        if idx.is_empty() {
            return None;
        }
        let t = least_squares_joint(s, par, &[idx.to_vec()])?;
        t.into_iter().next()
    }

    /// Chebyshev fit on `idx` within the set.
    pub fn chebyshev(&self, s: &Samples, idx: &[usize]) -> Option<ChebyshevFit> {
        let Some(par) = &self.par else {
            return refit::chebyshev(s, idx);
        };
        let f = refit::chebyshev_joint(s, par, &self.bounds, &[idx.to_vec()])?;
        Some(ChebyshevFit {
            theta: f.thetas.into_iter().next()?,
            max_residual: f.max_residual,
        })
    }
}
