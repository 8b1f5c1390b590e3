//! # hysid-parc
//!
//! The `parc` back-end: PARC (A. Bemporad, "A piecewise linear regression
//! and classification algorithm with application to learning and model
//! predictive control of hybrid systems", IEEE TAC 68(6), 2023), with one
//! numeric target `y(k)` and the PWARX regressor `x(k)`. The partition is
//! learned with the modes: block-coordinate descent on
//!
//! `J = sum_k [ (y(k) - theta_{d_k} . [x(k); 1])^2 + sigma' V(x(k), d_k) ]`,
//! `V(x, j) = logsumexp_h f_h(x) - f_j(x)`, `f_h(x) = omega_h . x + gamma_h`,
//!
//! with `sigma' = sigma / N`, from an initial assignment
//! ([`initial_labels`]), alternating
//!
//! 1. the local models: least squares per cluster under the priors
//!    ([`fit_local_models`]);
//! 2. the separator: a multinomial logistic regression of the labels with
//!    ridge `beta` ([`fit_separator`]);
//! 3. the assignment: every sample to the cluster of least cost
//!    ([`reassign`]); empty clusters die;
//!
//! until the cost falls by at most `cost_tol` or `max_iter` rounds. Then
//! clusters of fewer than `min_number` samples are dropped, the separator is
//! refitted, and with `fit_on_partition` the samples are reassigned by the
//! partition itself and the local models refitted per cell ([`finish`]).
//! The regions are the cells `{x : f_j(x) >= f_h(x) for all h}`: a complete
//! partition. `docs/parc.md` has the deviations.

mod steps;

pub use steps::{
    Clusters, Finished, finish, fit_local_models, fit_separator, initial_labels, reassign,
};

use hysid_core::backend::{Budget, Exhausted, IdentifyError, RunContext};
use hysid_core::options::{CheckOptions, OptionError, check_float};
use hysid_core::priors::PriorKind;
use hysid_estimation::pwarx::{ModeCount, ModeRule, PwarxData, PwarxFit, PwarxMethod};
use hysid_model::model::{PwarxMode, RunStatus};
use hysid_model::regressors::Regressors;
use serde::Serialize;

/// PARC's default number of clusters (an upper bound) when no mode count
/// is given.
pub const DEFAULT_CLUSTERS: usize = 10;

/// The largest number of clusters `--auto` tries when neither `modes` nor
/// `max_modes` is given.
pub const DEFAULT_MAX_MODES: usize = 5;

hysid_core::option_enum! {
    /// How the clusters begin.
    pub enum Init {
        /// k-means++ seeding and Lloyd iterations on the regressors, the best of 10.
        Kmeans => "kmeans",
        /// Uniformly random labels.
        Random => "random",
    }
}

hysid_core::backend_options! {
    /// Options of the `parc` back-end.
    pub struct ParcOptions {
        /// Weight sigma of the separation term; the cost uses sigma / N.
        sigma: f64 = 1.0,
        /// Ridge beta of the softmax separator: it minimises
        /// sum_k V(x(k), d_k) + (beta / 2) |omega|^2.
        beta: f64 = 1e-3,
        /// Rounds of the block-coordinate descent at most.
        max_iter: usize = 100,
        /// Stop when a round lowers the cost by at most this.
        cost_tol: f64 = 1e-4,
        /// Clusters with fewer samples are dropped at the end; none: the
        /// number of parameters of a mode (regressors + 1).
        min_number: Option<usize> = None,
        /// Reassign the samples by the final partition and refit the local
        /// models per cell, so that models and regions agree.
        fit_on_partition: bool = true,
        /// Initial assignment: kmeans or random.
        init: Init = Init::Kmeans,
    }
}

impl CheckOptions for ParcOptions {
    fn check(&self) -> Result<(), OptionError> {
        check_float(
            "sigma",
            self.sigma,
            |v| v >= 0.0,
            "must be a finite number >= 0",
        )?;
        check_float(
            "beta",
            self.beta,
            |v| v > 0.0,
            "must be a finite number > 0",
        )?;
        check_float(
            "cost_tol",
            self.cost_tol,
            |v| v >= 0.0,
            "must be a finite number >= 0",
        )?;
        if self.max_iter == 0 {
            return Err(OptionError::invalid("max_iter", 0, "must be at least 1"));
        }
        if self.min_number == Some(0) {
            return Err(OptionError::invalid("min_number", 0, "must be at least 1"));
        }
        Ok(())
    }
}

/// The `parc` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Parc;

impl PwarxMethod for Parc {
    type Options = ParcOptions;
    type Diagnostics = ParcDiagnostics;
    const MODE_RULE: ModeRule = ModeRule::Method;
    const NAME: &'static str = "parc";
    const SUMMARY: &'static str = "PARC (Bemporad 2023): local models and a softmax partition learned together by block-coordinate descent";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;
    const SEARCH: &'static str = "the number of clusters from 1 to 5 (at most --max-modes; saturation modes added), unless --modes is given; every candidate with trim = 3";
    const MAX_MODES: Option<usize> = Some(DEFAULT_MAX_MODES);

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &ParcOptions,
        ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<ParcDiagnostics>, IdentifyError> {
        fit(options, data, ctx)
    }
}

/// What the `parc` back-end reports besides the common diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct ParcDiagnostics {
    /// Clusters at the start (the mode count, or its bound).
    pub clusters_initial: usize,
    /// Modes at the end.
    pub clusters_final: usize,
    /// Rounds of the descent.
    pub iterations: usize,
    /// The cost after each round (fit plus separation terms).
    pub cost: Vec<f64>,
    /// Samples in dropped clusters or cells (PARC's outliers).
    pub outliers: usize,
}

impl ParcOptions {
    /// The smallest cluster kept: `min_number`, else one more than the
    /// regressors.
    fn smallest_cluster(&self, reg: &Regressors) -> usize {
        self.min_number.unwrap_or(reg.x.ncols() + 1)
    }
}

/// The method's steps: the number of clusters, the initial assignment, the
/// descent (local models, separator, assignment), the clean-up.
pub fn fit(
    options: &ParcOptions,
    data: &PwarxData<'_>,
    ctx: &RunContext<'_>,
) -> Result<PwarxFit<ParcDiagnostics>, IdentifyError> {
    let reg = data.ordinary_regressors();
    let (k, exact) = cluster_count(data, reg.len() / options.smallest_cluster(&reg));
    let mut clusters = Clusters::new(initial_labels(options, &reg, k, ctx.seed));
    let mut cost = Vec::new();
    let mut cut_short = false;
    let mut scores: Option<Vec<Vec<f64>>> = None;
    let mut budget = Budget::new(options.max_iter, &ctx.deadline);
    loop {
        if let Err(end) = budget.begin() {
            cut_short = end == Exhausted::TimeBudget;
            break;
        }
        clusters.drop_empty();
        let thetas = fit_local_models(data, &reg, &clusters, false)?;
        let separator = fit_separator(options, data, &reg, &clusters, scores.as_deref())?;
        let round = reassign(options, &reg, &thetas, &separator, &mut clusters);
        scores = Some(separator);
        let decrease = cost.last().map_or(f64::INFINITY, |c: &f64| c - round);
        cost.push(round);
        if decrease <= options.cost_tol || clusters.live() == 1 {
            break;
        }
    }
    let end = finish(options, data, &reg, clusters)?;
    let modes = end.thetas.len();
    if let Some(s) = exact
        && modes != s
    {
        return Err(ParcError::ModeCount {
            asked: s,
            found: modes,
        }
        .into());
    }
    let diagnostics = ParcDiagnostics {
        clusters_initial: k,
        clusters_final: modes,
        iterations: cost.len(),
        cost,
        outliers: end.outliers,
    };
    let mut fit = PwarxFit::complete(PwarxMode::unnamed(end.thetas, end.regions), diagnostics);
    if cut_short {
        fit.run_status = RunStatus::TimeBudget;
        fit.status
            .push("time budget reached: the clusters of the last finished round".into());
    }
    Ok(fit)
}

/// PARC's number of clusters: `modes` exactly, `max_modes` as the bound
/// (clusters may die), no more than `fit`, the clusters the samples can
/// fill to `min_number` each (at least one); else [`DEFAULT_CLUSTERS`]
/// as the bound.
fn cluster_count(data: &PwarxData<'_>, fit: usize) -> (usize, Option<usize>) {
    match data.modes {
        ModeCount::Exact(s) => (s, Some(s)),
        ModeCount::AtMost(s) => (s.min(fit.max(1)), None),
        ModeCount::Free => (DEFAULT_CLUSTERS, None),
    }
}

/// Why a PARC run failed.
#[derive(Debug, thiserror::Error)]
pub enum ParcError {
    /// Clusters died below an exact mode count.
    #[error(
        "exactly {asked} modes were asked for, but {found} clusters survived (empty or below min_number): \
         give max_modes = {asked} to allow fewer, or lower min_number"
    )]
    ModeCount {
        /// Modes asked for.
        asked: usize,
        /// Modes left.
        found: usize,
    },
    /// The local least squares failed.
    #[error("local models: {0}")]
    LocalModels(hysid_estimation::constrained::EstimationError),
    /// Every cluster fell below `min_number` samples.
    #[error("local models: every cluster has fewer than min_number = {min_number} samples")]
    EveryClusterTooSmall {
        /// The option's value.
        min_number: usize,
    },
    /// Every cell of the separator's partition fell below `min_number`
    /// samples.
    #[error(
        "local models: every cell of the partition has fewer than min_number = {min_number} samples"
    )]
    EveryCellTooSmall {
        /// The option's value.
        min_number: usize,
    },
    /// The separator could not be fitted.
    #[error("separator: {0}")]
    Separator(hysid_estimation::regions::RegionError),
}

impl From<ParcError> for IdentifyError {
    fn from(e: ParcError) -> Self {
        IdentifyError::failed(e)
    }
}
