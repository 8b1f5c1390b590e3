//! # hysid-milp
//!
//! The `milp` back-end: exact mixed-integer programs for records of tens
//! of samples, solved by the branch and bound of the pure-Rust `microlp`.
//! It is the optimum the heuristics are checked against, not a method for
//! real records: its cost grows exponentially with the samples.
//!
//! Two problems ([`program`] has the formulations):
//!
//! - with a mode count `s` (`modes`): the least sum of absolute residuals
//!   of a switched affine model with `s` modes, every sample assigned to
//!   one mode (the l1 mixed-integer program of Roll, Bemporad and Ljung,
//!   Automatica 40, 2004, for a switched instead of a hinging-hyperplane
//!   model);
//! - with an error bound `delta`: the fewest modes that explain every
//!   sample within `delta` (the MIN PFS problem that Bemporad et al., IEEE
//!   TAC 2005, solve greedily), then the least l1 error with that many
//!   modes and every residual within `delta`.
//!
//! The regions come last, from the assignment (`hysid_estimation::regions`, as for the
//! other PWARX back-ends). `docs/milp.md` has the equations and every
//! deviation.

pub mod program;

pub use program::{Limits, MilpSolution, Objective, ProgramError};

use hysid_core::backend::{IdentifyError, RunContext};
use hysid_core::options::{CheckOptions, OptionError, check_float};
use hysid_core::priors::{ModeCountNeed, PriorKind};
use hysid_estimation::constrained::Parametrisation;
use hysid_estimation::pwarx::{ModeRule, PwarxData, PwarxFit, PwarxMethod};
use hysid_estimation::regions::RegionMethod;
use hysid_model::model::{PwarxMode, RunStatus};
use hysid_model::regressors::Regressors;
use serde::Serialize;

/// The largest mode count the fewest-modes problem tries without
/// `max_modes`, and `--auto` without `modes`.
pub const DEFAULT_MAX_MODES: usize = 4;

hysid_core::backend_options! {
    /// Options of the `milp` back-end.
    pub struct MilpOptions {
        /// Bound on every residual, data units: the fewest modes within it, then the least
        /// l1 error; none: the mode count is needed and the l1 error is minimised.
        delta: Option<f64> = None,
        /// Box |theta| <= theta_max on every parameter, data units (the big-M constants
        /// follow from it).
        theta_max: f64 = 100.0,
        /// Largest record (ordinary samples) accepted: the cost grows exponentially.
        max_samples: usize = 40,
        /// Branch-and-bound nodes per program at most; the best solution found by then is
        /// returned, marked not proven optimal.
        node_limit: usize = 2_000_000,
        /// Region estimation from the assignment (docs/regions.md): mrlp, msvm, psvc or
        /// softmax.
        regions: RegionMethod = RegionMethod::Mrlp,
    }
}

impl CheckOptions for MilpOptions {
    fn check(&self) -> Result<(), OptionError> {
        if let Some(d) = self.delta {
            check_float("delta", d, |d| d > 0.0, "must be a finite number > 0")?;
        }
        check_float(
            "theta_max",
            self.theta_max,
            |t| t > 0.0,
            "must be a finite number > 0",
        )?;
        if self.max_samples == 0 {
            return Err(OptionError::invalid("max_samples", 0, "must be at least 1"));
        }
        if self.node_limit == 0 {
            return Err(OptionError::invalid("node_limit", 0, "must be at least 1"));
        }
        Ok(())
    }
}

/// The `milp` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Milp;

impl PwarxMethod for Milp {
    type Options = MilpOptions;
    type Diagnostics = MilpDiagnostics;
    const MODE_RULE: ModeRule = ModeRule::Method;
    const NAME: &'static str = "milp";
    const SEEDED: bool = false;
    const SUMMARY: &'static str = "exact mixed-integer switched regression (l1 with a mode count, or the fewest modes within delta) for records of tens of samples; then regions";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;
    const OUTPUT_UNITS: &'static [&'static str] = &["delta", "theta_max", "l1_error"];
    const SEARCH: &'static str = "the mode count from 1 to 4 (at most --max-modes; saturation modes added), unless --modes is given; every candidate with trim = 3";
    const MAX_MODES: Option<usize> = Some(DEFAULT_MAX_MODES);

    /// Without `delta` the least-l1 program needs the mode count itself.
    fn mode_count_need(options: &MilpOptions) -> ModeCountNeed {
        match options.delta {
            Some(_) => ModeCountNeed::Nothing,
            None => ModeCountNeed::Count,
        }
    }

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &MilpOptions,
        ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<MilpDiagnostics>, IdentifyError> {
        fit(options, data, ctx)
    }
}

/// What the `milp` back-end reports besides the common diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct MilpDiagnostics {
    /// The sum of absolute residuals of the final program.
    pub l1_error: f64,
    /// With `delta`: the fewest modes within it.
    pub fewest_modes: Option<usize>,
    /// Whether every program's optimum was proven.
    pub proven_optimal: bool,
    /// Branch-and-bound nodes of all programs.
    pub nodes: u64,
    /// Whether some parameter ended at the `theta_max` box (then the box,
    /// not the data, decided it).
    pub at_box: bool,
    /// Fraction of the samples inside their own mode's region.
    pub region_training_accuracy: f64,
}

/// The method's steps: the program(s) of the options, the regions from
/// the optimal assignment.
pub fn fit(
    options: &MilpOptions,
    data: &PwarxData<'_>,
    ctx: &RunContext<'_>,
) -> Result<PwarxFit<MilpDiagnostics>, IdentifyError> {
    let reg = data.ordinary_regressors();
    check_sample_count(options, &reg)?;
    check_box(options.theta_max, data)?;
    let limits = Limits {
        theta_max: options.theta_max,
        node_limit: options.node_limit as u64,
        deadline: ctx.deadline.clone(),
    };
    let (modes, fewest) = match options.delta {
        Some(delta) => {
            let max_modes = data.modes.at_most().unwrap_or(DEFAULT_MAX_MODES);
            let s = fewest_modes(data, &reg, max_modes, delta, &limits)?;
            (data.modes.exact().unwrap_or(s.thetas.len()), Some(s))
        }
        None => (data.exact_modes(Milp::NAME)?, None),
    };
    let mut best = least_l1(data, &reg, modes, options.delta, &limits)?;
    let dropped = drop_empty_modes(&mut best);
    let partition = hysid_estimation::regions::for_pwarx(
        options.regions,
        data,
        &reg,
        &best.labels,
        best.thetas.len(),
    )?;
    let proven = best.proven_optimal && fewest.as_ref().is_none_or(|s| s.proven_optimal);
    let diagnostics = MilpDiagnostics {
        l1_error: best.objective,
        fewest_modes: fewest.as_ref().map(|s| s.thetas.len()),
        proven_optimal: proven,
        nodes: best.nodes + fewest.as_ref().map_or(0, |s| s.nodes),
        at_box: best.at_box,
        region_training_accuracy: partition.training_accuracy,
    };
    Ok(PwarxFit {
        modes: PwarxMode::unnamed(best.thetas, partition.regions),
        regions_complete: partition.complete,
        uncovered_fraction: None,
        run_status: if proven {
            RunStatus::Completed
        } else if ctx.deadline.passed() {
            RunStatus::TimeBudget
        } else {
            RunStatus::IterationLimit
        },
        status: status_lines(proven, dropped, modes),
        scaling: None,
        refinement: None,
        trimming: None,
        diagnostics,
    })
}

/// Removes the modes that explain no sample (an optimum may leave one
/// empty when fewer modes fit as well, and an incumbent cut short by the
/// node limit often does), relabelling the others in order; returns how
/// many were removed.
pub fn drop_empty_modes(solution: &mut MilpSolution) -> usize {
    let modes = solution.thetas.len();
    let mut count = vec![0usize; modes];
    for &q in &solution.labels {
        count[q] += 1;
    }
    let mut new_index = vec![usize::MAX; modes];
    let mut kept = Vec::new();
    for (i, theta) in solution.thetas.iter().enumerate() {
        if count[i] > 0 {
            new_index[i] = kept.len();
            kept.push(theta.clone());
        }
    }
    for q in &mut solution.labels {
        *q = new_index[*q];
    }
    solution.thetas = kept;
    modes - solution.thetas.len()
}

/// The status lines of a run: cut short, modes dropped.
fn status_lines(proven: bool, dropped: usize, modes: usize) -> Vec<String> {
    let mut lines = Vec::new();
    if !proven {
        lines.push(
            "branch and bound stopped before proving the optimum: the best solution found".into(),
        );
    }
    if dropped > 0 {
        lines.push(format!(
            "{dropped} of the {modes} modes explain no sample in the solution and were dropped"
        ));
    }
    lines
}

/// Every `[bounds]` prior of a parameter that is not fixed meets the box
/// `[-theta_max, theta_max]` the program bounds the free parameters by
/// (fixed values are not variables of the program, and need not).
fn check_box(theta_max: f64, data: &PwarxData<'_>) -> Result<(), IdentifyError> {
    let priors = data.priors();
    let outside = (priors.bounds.iter())
        .filter(|(param, _)| !priors.fixed.contains_key(*param))
        .find(|(_, [low, high])| *low > theta_max || *high < -theta_max);
    match outside {
        Some((param, &[low, high])) => Err(data.prior_error(MilpError::BoundOutsideBox {
            param: param.clone(),
            low,
            high,
            theta_max,
        })),
        None => Ok(()),
    }
}

/// The record must be small: the program has a binary per sample and
/// mode.
fn check_sample_count(options: &MilpOptions, reg: &Regressors) -> Result<(), IdentifyError> {
    if reg.len() > options.max_samples {
        return Err(IdentifyError::input(MilpError::TooManySamples {
            samples: reg.len(),
            max_samples: options.max_samples,
        }));
    }
    Ok(())
}

/// The exact fewest modes (at most `max_modes`) within `delta`.
pub fn fewest_modes(
    data: &PwarxData<'_>,
    reg: &Regressors,
    max_modes: usize,
    delta: f64,
    limits: &Limits,
) -> Result<MilpSolution, IdentifyError> {
    let par = parametrisation(data, max_modes)?;
    program::solve(
        reg,
        &par,
        Objective::FewestModes { max_modes, delta },
        limits,
    )
    .map_err(program_error)
}

/// The least l1 error with `modes` modes (every residual within `delta`
/// when given).
pub fn least_l1(
    data: &PwarxData<'_>,
    reg: &Regressors,
    modes: usize,
    delta: Option<f64>,
    limits: &Limits,
) -> Result<MilpSolution, IdentifyError> {
    let par = parametrisation(data, modes)?;
    program::solve(reg, &par, Objective::L1 { modes, delta }, limits).map_err(program_error)
}

fn parametrisation(data: &PwarxData<'_>, modes: usize) -> Result<Parametrisation, IdentifyError> {
    Parametrisation::from_priors(data.priors(), &data.spec, modes).map_err(|e| data.prior_error(e))
}

fn program_error(e: ProgramError) -> IdentifyError {
    IdentifyError::failed(e)
}

/// Why a `milp` run cannot start.
#[derive(Debug, thiserror::Error)]
pub enum MilpError {
    /// The record is too large for an exact program.
    #[error(
        "{samples} ordinary samples exceed option max_samples = {max_samples}: the exact program grows exponentially with the samples (raise max_samples, or use a heuristic back-end)"
    )]
    TooManySamples {
        /// Ordinary samples.
        samples: usize,
        /// The option.
        max_samples: usize,
    },
    /// A `[bounds]` prior outside the parameters' box.
    #[error(
        "[bounds] {param} = [{low}, {high}] lies outside [-theta_max, theta_max] = [-{theta_max}, {theta_max}]: raise option theta_max"
    )]
    BoundOutsideBox {
        /// The parameter.
        param: String,
        /// Its lower bound.
        low: f64,
        /// Its upper bound.
        high: f64,
        /// The option.
        theta_max: f64,
    },
}
