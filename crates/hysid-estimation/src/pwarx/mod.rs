//! The PWARX pipeline: what every PWARX back-end runs, with the method's
//! own steps in the middle.
//!
//! ```text
//! prepare -> [mode count] -> fit -> trim -> refine -> assemble
//! ```
//!
//! 1. [`prepare()`]: the regressors, the samples at known stops set aside,
//!    the prior names checked, the mode count resolved.
//! 2. The mode count: given by the priors (`modes`), chosen by the method
//!    itself ([`ModeRule::Method`], the bounded-error procedure), or under
//!    `max_modes` by the pipeline ([`mode_count::choose`]: hold-out
//!    simulation FIT and the one-standard-error rule).
//! 3. [`PwarxMethod::fit`]: the method's steps, from the prepared data to
//!    the ordinary modes' parameters and regions (a method that assigns
//!    samples to modes estimates the regions with
//!    [`crate::regions::for_pwarx`]).
//! 4. The stages after the fit ([`stages`]), typed by
//!    [`hysid_core::stages::Stages`]: the trimmed re-estimation ([`trim`]),
//!    then the simulation-error refinement ([`refine`]).
//! 5. [`assemble()`]: the PWARX model, or with known stops the hybrid
//!    automaton with a mode on each stop's guard set, and the common
//!    diagnostics.
//!
//! A PWARX back-end is a [`PwarxMethod`]; [`Pwarx`] makes it an
//! [`Identifier`] (one registration line: `.with(Pwarx(Method))`).

pub mod assemble;
mod failure;
pub mod mode_count;
pub mod prepare;
pub mod refine;
pub mod stages;
pub mod standardize;
pub mod trim;

pub use assemble::{PwarxFit, assemble};
pub use failure::PwarxFailure;
pub use prepare::{
    ModeCount, PwarxData, UnknownName, check_names, prepare, saturated_samples, stop_at,
};
pub use standardize::{StandardizeError, run_standardized};

use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::{BackendOptions, CheckOptions, Checked, OptionError, OptionSpec};
use hysid_core::priors::{ModeCountNeed, PriorKind, Priors};
use hysid_core::search::SearchSpace;
use hysid_core::stages::{AUTO_TRIM, Stages};
use hysid_model::regressors::RegressorSpec;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};

/// Who chooses the number of ordinary modes when the priors do not fix
/// it with `modes`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeRule {
    /// The method needs the count: under `max_modes` the pipeline chooses
    /// it ([`mode_count::choose`]); without a bound the run is refused.
    Given,
    /// The method chooses it (the bounded-error procedure, from its error
    /// bound), or has a fixed count (the affine model).
    Method,
}

/// What a PWARX method contributes to the pipeline: its name, options and
/// search space, and its steps from the prepared data to the ordinary
/// modes. Everything before and after is the pipeline's.
pub trait PwarxMethod: Send + Sync {
    /// The method's own options (the stages' options are added by
    /// [`PwarxOptions`]).
    type Options: BackendOptions + CheckOptions;
    /// What the method reports besides the common diagnostics.
    type Diagnostics: Serialize;
    /// Name used with `-m`.
    const NAME: &'static str;
    /// One-line description.
    const SUMMARY: &'static str;
    /// Prior kinds honoured.
    const HONOURS: &'static [PriorKind];
    /// What automatic selection tries ([`Identifier::SEARCH`]).
    const SEARCH: &'static str = "";
    /// With the default [`PwarxMethod::search_space`], the most modes
    /// automatic selection tries when the priors give no count; `None`: no
    /// search of the mode count.
    const MAX_MODES: Option<usize> = None;
    /// Options and diagnostics in output units ([`Identifier::OUTPUT_UNITS`]).
    const OUTPUT_UNITS: &'static [&'static str] = &[];
    /// Whether the seed can change the fit ([`Identifier::SEEDED`]).
    const SEEDED: bool = true;
    /// When the options decide ([`Identifier::SEED_USE`]).
    const SEED_USE: &'static str = "";
    /// Who chooses the mode count.
    const MODE_RULE: ModeRule = ModeRule::Given;
    /// The number of ordinary modes the method always identifies, where it
    /// has one (the affine model's one): a `modes` prior asking for
    /// another is refused before any data are read
    /// ([`prepare::FixedModeCount`]).
    const ORDINARY_MODES: Option<usize> = None;
    /// What a fit with `options` needs of the priors' number of modes
    /// ([`Identifier::mode_count_need`]): by default, `modes` or
    /// `max_modes` where [`Self::MODE_RULE`] is [`ModeRule::Given`].
    fn mode_count_need(_options: &Self::Options) -> ModeCountNeed {
        match Self::MODE_RULE {
            ModeRule::Given => ModeCountNeed::CountOrBound,
            ModeRule::Method => ModeCountNeed::Nothing,
        }
    }
    /// The options that make the method its paper's procedure
    /// ([`Identifier::PAPER`]).
    const PAPER: &'static [(&'static str, &'static str)] = &[];

    /// Whether the seed can change the fit with `options` under `priors`
    /// ([`Identifier::seeded_with`]; the stages after the fit draw
    /// nothing at random).
    fn seeded_with(&self, _priors: &Priors, _options: &Self::Options) -> bool {
        Self::SEEDED
    }

    /// The candidates automatic selection tries ([`Identifier::search_space`]);
    /// by default, with [`PwarxMethod::MAX_MODES`], every mode count from 1
    /// (the affine model) to it, the known stops added, each with the
    /// trimmed re-estimation at [`AUTO_TRIM`], and without, nothing.
    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        Ok(match Self::MAX_MODES {
            Some(max_modes) => SearchSpace::default()
                .with(Stages::TRIM, [AUTO_TRIM])
                .with_mode_counts(problem.priors, max_modes),
            None => SearchSpace::default(),
        })
    }

    /// The method's steps: the ordinary modes of `data` (their number is
    /// `data.modes`, exact unless [`PwarxMethod::MODE_RULE`] is
    /// [`ModeRule::Method`]).
    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &Self::Options,
        ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<Self::Diagnostics>, IdentifyError>;
}

/// A [`PwarxMethod`] run through the pipeline: the [`Identifier`] that is
/// registered.
#[derive(Debug, Clone, Copy, Default)]
pub struct Pwarx<M>(pub M);

/// The options of a PWARX back-end: the method's own, then the stages'.
/// Each key belongs to one of the two; `--set` sets either.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct PwarxOptions<O> {
    /// The method's options.
    #[serde(flatten)]
    pub method: O,
    /// The stages after the fit.
    #[serde(flatten)]
    pub stages: Stages,
}

impl<'de, O: BackendOptions> Deserialize<'de> for PwarxOptions<O> {
    /// The stages' keys go to [`Stages`], the others to the method's
    /// options (each refusing keys it does not know).
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let mut method = toml::Table::deserialize(deserializer)?;
        let mut stages = toml::Table::new();
        for spec in Stages::specs() {
            if let Some(v) = method.remove(spec.key) {
                stages.insert(spec.key.to_string(), v);
            }
        }
        Ok(Self {
            method: O::deserialize(toml::Value::Table(method)).map_err(D::Error::custom)?,
            stages: Stages::deserialize(toml::Value::Table(stages)).map_err(D::Error::custom)?,
        })
    }
}

impl<O: BackendOptions> BackendOptions for PwarxOptions<O> {
    fn specs() -> Vec<OptionSpec> {
        let mut specs = O::specs();
        specs.extend(Stages::specs());
        specs
    }
}

impl<O: CheckOptions> CheckOptions for PwarxOptions<O> {
    fn check(&self) -> Result<(), OptionError> {
        self.method.check()?;
        self.stages.check()
    }
}

impl<M: PwarxMethod> Identifier for Pwarx<M> {
    type Options = PwarxOptions<M::Options>;
    const NAME: &'static str = M::NAME;
    const SUMMARY: &'static str = M::SUMMARY;
    const HONOURS: &'static [PriorKind] = M::HONOURS;
    const SEARCH: &'static str = M::SEARCH;
    const OUTPUT_UNITS: &'static [&'static str] = M::OUTPUT_UNITS;
    const SEEDED: bool = M::SEEDED;
    const SEED_USE: &'static str = M::SEED_USE;
    const STAGES: bool = true;
    const PAPER: &'static [(&'static str, &'static str)] = M::PAPER;

    fn seeded_with(&self, problem: &Problem<'_>, options: &Self::Options) -> bool {
        self.0.seeded_with(problem.priors, &options.method)
    }

    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        self.0.search_space(problem)
    }

    fn check_priors(
        &self,
        _options: &Self::Options,
        priors: &Priors,
        orders: RegressorSpec,
        origin: Option<&str>,
    ) -> Result<(), IdentifyError> {
        prepare::check_priors(priors, &orders, origin)?;
        // Not named by the file: `--modes` may have set the count.
        prepare::FixedModeCount::check(M::NAME, M::ORDINARY_MODES, priors)
            .map_err(|e| IdentifyError::prior_mismatch(None, e))
    }

    fn mode_count_need(&self, options: &Self::Options) -> ModeCountNeed {
        M::mode_count_need(&options.method)
    }

    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &Checked<Self::Options>,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let data = prepare(problem, M::NAME)?;
        match (M::MODE_RULE, data.modes) {
            (ModeRule::Given, ModeCount::AtMost(max)) => {
                mode_count::choose(&data, max, ctx, |problem, ctx| {
                    self.run_pipeline(&prepare(problem, M::NAME)?, options, ctx)
                })
            }
            (ModeRule::Given, ModeCount::Free) => Err(IdentifyError::NeedsModeCount {
                method: M::NAME,
                bounded: true,
            }),
            _ => self.run_pipeline(&data, options, ctx),
        }
    }

    fn refine_fitted(
        &self,
        problem: &Problem<'_>,
        fitted: Model,
        options: &Checked<Self::Options>,
        ctx: &RunContext<'_>,
    ) -> Option<Result<Model, IdentifyError>> {
        Some(stages::refine_fitted(
            problem,
            M::NAME,
            fitted,
            &options.stages,
            &ctx.deadline,
        ))
    }
}

impl<M: PwarxMethod> Pwarx<M> {
    /// Steps 3 to 5 on prepared data whose mode count is settled.
    fn run_pipeline(
        &self,
        data: &PwarxData<'_>,
        options: &PwarxOptions<M::Options>,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let fit = self.0.fit(data, &options.method, ctx)?;
        let fit = stages::run(data, fit, &options.stages, &ctx.deadline)?;
        Ok(assemble(data, fit))
    }
}
