//! # hysid-klinreg
//!
//! The `klinreg` back-end: k-LinReg (F. Lauer, "Estimating the probability
//! of success of a simple algorithm for switched linear regression",
//! Nonlinear Analysis: Hybrid Systems 8, 2013), then the regions.
//!
//! The problem is `min_W sum_k min_j (y(k) - theta_j . [x(k); 1])^2` over
//! the parameters `W = [theta_1 .. theta_s]` of `s` modes. One restart:
//!
//! 1. draw `W` uniformly in `[-w_max, w_max]` ([`draw_parameters`]);
//! 2. give every sample the mode of least squared residual ([`assign`]);
//! 3. fit every mode by least squares on its samples, under the priors
//!    ([`refit`]); a mode left with fewer samples than parameters fails
//!    the restart;
//! 4. repeat 2-3 until the assignment no longer changes (at most
//!    `max_iter` times).
//!
//! Neither step can raise the cost (step 2 minimises it over the labels for
//! fixed `W`, step 3 over `W` for fixed labels), so each restart ends in a
//! local minimum; the restart of least cost is kept ([`best_restart`]). The
//! number of restarts is Lauer's `r*` ([`restart_count`]) unless given. The
//! regions come last, from the final assignment (`hysid_estimation::regions`, as for
//! the other PWARX back-ends; Lauer's paper stops at the switched model).
//! `docs/klinreg.md` has the equations and every deviation.

mod restarts;

pub use restarts::{
    FAILURE_PROBABILITY, FALLBACK_RESTARTS, Restart, Restarts, SuccessModel, best_restart,
    draw_parameters, restart_count, run_restart, success_probability,
};

use hysid_core::backend::{IdentifyError, RunContext};
use hysid_core::options::{CheckOptions, OptionError, check_count, check_float};
use hysid_core::priors::PriorKind;
use hysid_estimation::constrained::{Parametrisation, fit_modes_on, normal_equations};
use hysid_estimation::pwarx::{PwarxData, PwarxFit, PwarxMethod};
use hysid_estimation::regions::RegionMethod;
use hysid_model::model::{PwarxMode, RunStatus};
use hysid_model::regressors::Regressors;

use serde::Serialize;

/// The largest mode count `--auto` tries when none is given.
pub const DEFAULT_MAX_MODES: usize = 5;

/// The fewest restarts `restarts = 0` runs. Lauer's model of the success
/// rate of one restart is optimistic here: on random switched regressions
/// of the size it predicts 0.985 for, one restart of this implementation
/// succeeds 0.65 of the time (`docs/klinreg.md`), so his `r*` (2 there)
/// would miss the global minimum about once in eight problems.
pub const DEFAULT_MIN_RESTARTS: usize = 20;

hysid_core::backend_options! {
    /// Options of the `klinreg` back-end.
    pub struct KLinRegOptions {
        /// Random restarts; 0: Lauer's r* (the count that reaches the global
        /// minimum with probability 0.999 by his model of the success rate),
        /// but at least 20.
        restarts: usize = 0,
        /// Half-width of the box the initial parameters of the standardised
        /// problem are drawn from.
        w_max: f64 = 1.0,
        /// Assignment/refit iterations per restart at most.
        max_iter: usize = 100,
        /// Region estimation from the final assignment (docs/regions.md): mrlp,
        /// msvm, psvc or softmax.
        regions: RegionMethod = RegionMethod::Mrlp,
    }
}

impl CheckOptions for KLinRegOptions {
    fn check(&self) -> Result<(), OptionError> {
        check_float(
            "w_max",
            self.w_max,
            // The draw's width, 2 w_max, must be finite too.
            |w| w > 0.0 && w <= 1e300,
            "must be a number > 0 and at most 1e300",
        )?;
        if self.max_iter == 0 {
            return Err(OptionError::invalid("max_iter", 0, "must be at least 1"));
        }
        check_count("restarts", self.restarts, 0)
    }
}

/// The `klinreg` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct KLinReg;

impl PwarxMethod for KLinReg {
    type Options = KLinRegOptions;
    type Diagnostics = KLinRegDiagnostics;
    const NAME: &'static str = "klinreg";
    const SUMMARY: &'static str = "k-LinReg (Lauer 2013): assignment to the mode of least residual and least squares per mode, from random starts; then regions";
    const HONOURS: &'static [PriorKind] = &[
        PriorKind::Modes,
        PriorKind::MaxModes,
        PriorKind::Saturation,
        PriorKind::Tie,
        PriorKind::Fixed,
        PriorKind::Bounds,
        PriorKind::Equality,
        PriorKind::Switching,
    ];
    const SEARCH: &'static str = "the mode count from 1 to 5 (at most --max-modes; saturation modes added), unless --modes is given; every candidate with trim = 3";
    const MAX_MODES: Option<usize> = Some(DEFAULT_MAX_MODES);

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &KLinRegOptions,
        ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<KLinRegDiagnostics>, IdentifyError> {
        fit(options, data, ctx)
    }
}

/// What the `klinreg` back-end reports besides the common diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct KLinRegDiagnostics {
    /// Restarts run (fewer than planned when the time budget ended them).
    pub restarts: usize,
    /// Restarts planned (the option, or Lauer's r*).
    pub restarts_planned: usize,
    /// Restarts that failed (a mode left with too few samples).
    pub restarts_failed: usize,
    /// Restarts that ended within 1e-9 (relative) of the best cost: Lauer
    /// advises checking that the best cost repeats.
    pub restarts_at_best: usize,
    /// Index of the kept restart.
    pub best_restart: usize,
    /// Mean squared residual of the kept restart (the k-LinReg cost / N).
    pub cost: f64,
    /// Assignment/refit iterations of the kept restart.
    pub iterations: usize,
    /// Lauer's success probability of one restart for this problem size
    /// (his model for dynamic systems).
    pub success_probability: f64,
    /// Fraction of the assigned samples inside their own mode's region.
    pub region_training_accuracy: f64,
}

/// The method's steps: the mode count, the restarts (steps 1-4 of Lauer
/// 2013, in parallel, the least cost kept), the regions from the kept
/// assignment.
pub fn fit(
    options: &KLinRegOptions,
    data: &PwarxData<'_>,
    ctx: &RunContext<'_>,
) -> Result<PwarxFit<KLinRegDiagnostics>, IdentifyError> {
    let modes = data.exact_modes(KLinReg::NAME)?;
    let reg = data.ordinary_regressors();
    let par = Parametrisation::from_priors(data.priors(), &data.spec, modes)
        .map_err(|e| data.prior_error(e))?;
    let planned = match options.restarts {
        0 => restart_count(reg.x.nrows(), modes, par.n_params()).max(DEFAULT_MIN_RESTARTS),
        r => r,
    };
    let outcome = best_restart(&reg, &par, modes, planned, options, ctx);
    let mut best = outcome.best.ok_or(KLinRegError::EveryRestartFailed {
        restarts: outcome.run,
        modes,
    })?;
    if let Some(thetas) = constrained_least_squares(&reg, &par, &best.labels, modes) {
        best.thetas = thetas;
    }
    let partition =
        hysid_estimation::regions::for_pwarx(options.regions, data, &reg, &best.labels, modes)?;
    let run_status = if outcome.run < planned {
        RunStatus::TimeBudget
    } else {
        RunStatus::Completed
    };
    let status = if outcome.run < planned {
        vec![format!(
            "time budget reached after {} of {planned} restarts: the best of them",
            outcome.run
        )]
    } else {
        Vec::new()
    };
    let diagnostics = KLinRegDiagnostics {
        restarts: outcome.run,
        restarts_planned: planned,
        restarts_failed: outcome.failed,
        restarts_at_best: outcome.at_best,
        best_restart: best.index,
        cost: best.cost,
        iterations: best.costs.len(),
        success_probability: success_probability(
            SuccessModel::Dynamic,
            reg.x.nrows(),
            modes,
            par.n_params(),
        ),
        region_training_accuracy: partition.training_accuracy,
    };
    Ok(PwarxFit {
        modes: PwarxMode::unnamed(best.thetas, partition.regions),
        regions_complete: partition.complete,
        uncovered_fraction: None,
        run_status,
        status,
        scaling: None,
        refinement: None,
        trimming: None,
        diagnostics,
    })
}

/// Step 3: least squares per mode on its samples, under the priors
/// (`hysid_estimation::constrained`: ties, fixed values and equalities
/// exact, bounds by a QP). Without any parameter prior the modes are
/// independent and each is solved from its normal equations
/// (`hysid_estimation::constrained::normal_equations`), one pass over the
/// samples; the kept restart is refitted by
/// [`constrained_least_squares`]. `None` when a mode
/// has fewer samples than parameters or the fit fails: the restart fails.
pub fn refit(
    reg: &Regressors,
    par: &Parametrisation,
    labels: &[usize],
    modes: usize,
) -> Option<Vec<Vec<f64>>> {
    let mut counts = vec![0usize; modes];
    for &q in labels {
        counts[q] += 1;
    }
    if counts.iter().any(|&c| c < par.n_params()) {
        return None;
    }
    if par.is_free() {
        return normal_equations(reg, labels.iter().copied().enumerate(), modes);
    }
    constrained_least_squares(reg, par, labels, modes)
}

/// Least squares of every mode under the priors, jointly
/// (`hysid_estimation::constrained::fit_modes`).
pub fn constrained_least_squares(
    reg: &Regressors,
    par: &Parametrisation,
    labels: &[usize],
    modes: usize,
) -> Option<Vec<Vec<f64>>> {
    let mut rows: Vec<Vec<usize>> = vec![Vec::new(); modes];
    for (k, &q) in labels.iter().enumerate() {
        rows[q].push(k);
    }
    fit_modes_on(par, reg, &rows).ok()
}

/// Step 2: every sample to the mode of least squared residual (the lowest
/// index on a tie); returns the labels and the mean squared residual.
pub fn assign(reg: &Regressors, thetas: &[Vec<f64>]) -> (Vec<usize>, f64) {
    let (n, d) = (reg.x.nrows(), reg.x.ncols());
    let mut labels = Vec::with_capacity(n);
    let mut total = 0.0;
    for k in 0..n {
        let mut best = (0, f64::INFINITY);
        for (q, theta) in thetas.iter().enumerate() {
            let e = reg.y[k] - theta[d] - (0..d).map(|j| theta[j] * reg.x[(k, j)]).sum::<f64>();
            let e2 = e * e;
            if e2 < best.1 {
                best = (q, e2);
            }
        }
        labels.push(best.0);
        total += best.1;
    }
    (labels, total / n.max(1) as f64)
}

/// Why a k-LinReg run cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum KLinRegError {
    /// Every restart left some mode with too few samples.
    #[error(
        "every one of the {restarts} restart(s) left one of the {modes} modes with fewer samples than parameters: fewer modes, or more restarts"
    )]
    EveryRestartFailed {
        /// Restarts run.
        restarts: usize,
        /// Modes asked for.
        modes: usize,
    },
}

impl From<KLinRegError> for IdentifyError {
    fn from(e: KLinRegError) -> Self {
        IdentifyError::failed(e)
    }
}
