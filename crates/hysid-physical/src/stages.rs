//! What the stages of the search share: the search context (objective,
//! options, run context, evaluation counter), the time budget, and why each
//! run of each stage stopped.

use crate::objective::{Objective, SimulationCost};
use crate::{NominalDivergence, PhysicalOptions};
use argmin::core::TerminationReason;
use hysid_core::backend::{IdentifyError, RunContext};
use serde::{Deserialize, Serialize};
use std::sync::atomic::AtomicU64;
use std::time::Duration;

/// Why an iterative stage of the fit stopped (recorded per stage in the
/// model's `info.diagnostics.method["termination"]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The stage's own convergence test held (Nelder-Mead: the simplex's
    /// cost spread below its tolerance; Levenberg-Marquardt: a relative
    /// decrease below 1e-9).
    Converged,
    /// Levenberg-Marquardt: no step decreased the cost, even with a
    /// damping of 1e8 (a local minimum, or a flat or failing simulation).
    NoDecrease,
    /// The iteration limit of the stage (`swarm_iters`, `lm_iters`,
    /// `local_iters`) was reached first.
    MaxIterations,
    /// `--time-budget` ran out.
    TimeBudget,
    /// Levenberg-Marquardt: stopped beside the descents of the stage's
    /// other starts, far behind the best of them and crawling (more than
    /// 100 times its cost after a round of 5 steps in which its own cost
    /// did not halve).
    Outpaced,
    /// Anything else (argmin's other reasons; a start whose simulation failed).
    Other,
}

impl Termination {
    /// The name written in the diagnostics.
    pub fn as_str(self) -> &'static str {
        match self {
            Termination::Converged => "converged",
            Termination::NoDecrease => "no_decrease",
            Termination::MaxIterations => "max_iterations",
            Termination::TimeBudget => "time_budget",
            Termination::Outpaced => "outpaced",
            Termination::Other => "other",
        }
    }

    /// The termination of an argmin run, from its reason.
    pub(crate) fn of_argmin(r: Option<&TerminationReason>) -> Self {
        match r {
            Some(TerminationReason::SolverConverged | TerminationReason::TargetCostReached) => {
                Termination::Converged
            }
            Some(TerminationReason::MaxItersReached) => Termination::MaxIterations,
            Some(TerminationReason::Timeout) => Termination::TimeBudget,
            _ => Termination::Other,
        }
    }
}

/// A stage of the search.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// The global stage: argmin's particle swarm.
    ParticleSwarm,
    /// The Levenberg-Marquardt run from each start of a local stage.
    LevenbergMarquardt,
    /// The Nelder-Mead restarts of a local stage.
    NelderMead,
}

impl Stage {
    /// The stage's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Stage::ParticleSwarm => "particle swarm",
            Stage::LevenbergMarquardt => "Levenberg-Marquardt",
            Stage::NelderMead => "Nelder-Mead",
        }
    }
}

/// A search that ran and failed, carried by
/// [`hysid_core::backend::IdentifyError::Failed`].
#[derive(Debug, thiserror::Error)]
pub enum SearchFailure {
    /// argmin's solver of a stage returned an error.
    #[error("{}: {cause}", .stage.name())]
    Solver {
        /// The stage.
        stage: Stage,
        /// argmin's error.
        cause: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Every simulation of the search failed or diverged.
    #[error("{}", every_candidate_failed(*evaluations, nominal))]
    EveryCandidateFailed {
        /// Simulations run.
        evaluations: u64,
        /// Where the run at the file's values diverges, if it does.
        nominal: Option<NominalDivergence>,
    },
    /// No search ran (no swarm asked for).
    #[error("no search ran")]
    NoSearch,
}

/// [`SearchFailure::EveryCandidateFailed`]'s message, with the run at the
/// file's values where it diverges.
fn every_candidate_failed(evaluations: u64, nominal: &Option<NominalDivergence>) -> String {
    let head = format!("every candidate simulation failed or diverged ({evaluations} simulations)");
    match nominal {
        Some(n) => format!("{head}: at the model's own values, {n}"),
        None => format!("{head}: the model cannot follow this record"),
    }
}

impl SearchFailure {
    /// The failure of `stage`'s argmin solver.
    pub fn solver(stage: Stage, cause: argmin::core::Error) -> IdentifyError {
        IdentifyError::failed(SearchFailure::Solver {
            stage,
            cause: cause.into(),
        })
    }
}

/// Why each run of each stage stopped, in order, and the stage during
/// which the time budget ran out, if it did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StageLog {
    /// The particle swarm, when it ran.
    pub particle_swarm: Option<Termination>,
    /// Every Levenberg-Marquardt run.
    pub levenberg_marquardt: Vec<Termination>,
    /// Every Nelder-Mead run; the last one (on the free-run cost) decides
    /// whether the result counts as converged.
    pub nelder_mead: Vec<Termination>,
    /// The first stage found past the deadline.
    pub cut_short: Option<Stage>,
}

/// The context every stage runs in.
pub struct Search<'a> {
    /// The simulation error (its `segment` is set per stage).
    pub objective: Objective<'a>,
    /// The back-end's options.
    pub options: &'a PhysicalOptions,
    /// Seed, progress and deadline.
    pub ctx: &'a RunContext<'a>,
    /// Simulations run so far (argmin's cost calls and Levenberg-Marquardt's).
    pub evals: &'a AtomicU64,
}

impl Search<'_> {
    /// argmin's problem: the objective on segments of `segment` samples
    /// (0: free run), counting evaluations.
    pub fn problem(&self, segment: usize) -> SimulationCost<'_> {
        SimulationCost {
            objective: self.objective.with_segment(segment),
            progress: self.ctx.progress,
            evals: self.evals,
            deadline: &self.ctx.deadline,
        }
    }

    /// Time left before the deadline, for argmin's executor.
    pub fn timeout(&self) -> Option<Duration> {
        self.ctx.deadline.remaining()
    }

    /// Whether the deadline has passed; if so, `stage` is recorded in
    /// `log` as cut short (unless an earlier stage was).
    pub fn past_deadline(&self, log: &mut StageLog, stage: Stage) -> bool {
        let past = self.ctx.deadline.passed();
        if past {
            log.cut_short.get_or_insert(stage);
        }
        past
    }
}
