//! The one entry point of identification: an [`Identify`] request, checked
//! once, whose [`Identify::run`] returns the model. The `hysid` program,
//! the Python package and experiments are front ends over it; each words
//! the typed [`Error`] with its own argument names.

use crate::select::{self, AgainstAffine, GivenBesideGrid, Plan, Request, SelectError};
use hysid_core::backend::{
    Backend, Deadline, IdentifyError, NoProgress, Problem, Progress, Registry, RunContext,
};
use hysid_core::model::Model;
use hysid_core::options::{MAX_COUNT, Settings};
use hysid_core::priors::{InconsistentPrior, Priors};
use hysid_core::search::{SearchSpace, Setup};
use hysid_core::simulate::{OutsideRegions, UnreadDefinitions, simulate};
use hysid_estimation::pwarx::run_standardized;
use hysid_model::data::{Dataset, RowRange};
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::SimulationOptions;
use hysid_physical::diagnostics::PhysicalDiagnostics;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// How the options are settled.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Mode {
    /// As given (the back-end's defaults for the rest).
    #[default]
    Plain,
    /// As given, on standardised data; the model in original units.
    Standardized,
    /// Chosen on selection rows inside the identification rows
    /// ([`crate::select`]).
    Auto(Auto),
}

/// What automatic selection is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub struct Auto {
    /// Selection rows, in rows of the file; `None`: the default split.
    pub select_rows: Option<RowRange>,
    /// Rolling-origin folds instead of one split.
    pub folds: Option<usize>,
    /// For data that join several records: hold out the last `K` records
    /// for selection.
    pub select_records: Option<usize>,
    /// Starts of the refit of the choice (at least 1).
    pub refit_starts: usize,
    /// The user's grid, replacing the back-end's search space.
    pub grid: Option<SearchSpace>,
}

impl Default for Auto {
    fn default() -> Self {
        Self {
            select_rows: None,
            folds: None,
            select_records: None,
            refit_starts: select::DEFAULT_REFIT_STARTS,
            grid: None,
        }
    }
}

/// One identification: a back-end, a record and what is known.
#[derive(Debug, Clone)]
pub struct Identify<'a> {
    /// The back-end's name (`hysid methods`).
    pub method: String,
    /// The identification record (several records joined, or one).
    pub data: &'a Dataset,
    /// Row of the file where `data` starts (selection rows are given in
    /// rows of the file).
    pub first_row: usize,
    /// Output lags.
    pub na: usize,
    /// Input lags.
    pub nb: usize,
    /// Prior knowledge.
    pub priors: Priors,
    /// Where the priors came from (a file), for messages.
    pub priors_origin: Option<String>,
    /// The mode count, overriding the priors' `modes`.
    pub modes: Option<usize>,
    /// The largest mode count, overriding the priors' `max_modes`.
    pub max_modes: Option<usize>,
    /// The back-end's options (`--set`).
    pub options: Settings,
    /// Seed of every random choice.
    pub seed: u64,
    /// A time budget in seconds.
    pub time_budget: Option<f64>,
    /// A flag that stops the run when raised (Ctrl-C in Python).
    pub stop: Option<Arc<AtomicBool>>,
    /// Samples at the start of a scored record left out of its score.
    pub warmup: usize,
    /// How the options are settled.
    pub mode: Mode,
}

/// What a request produced.
#[derive(Debug, Clone)]
pub struct Identified {
    /// The model, its provenance, diagnostics and (for automatic
    /// selection) the selection record in `info`.
    pub model: Model,
}

/// A request field that is out of range, named as the library names it;
/// each front end words it with its own argument name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// The mode count.
    Modes,
    /// The largest mode count.
    MaxModes,
    /// The time budget.
    TimeBudget,
    /// The refit's starts.
    RefitStarts,
}

/// Why a request could not be run.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A field out of range.
    #[error("{field:?} = {value}: {what}")]
    Field {
        /// The field.
        field: Field,
        /// Its value, as given.
        value: String,
        /// What a valid value is.
        what: String,
    },
    /// The mode counts given contradict each other or the priors.
    #[error("{problem}")]
    Modes {
        /// The mode count given.
        modes: Option<usize>,
        /// The largest mode count given.
        max_modes: Option<usize>,
        /// What is inconsistent.
        problem: InconsistentPrior,
    },
    /// The back-end refused the problem or failed.
    #[error(transparent)]
    Identify(#[from] IdentifyError),
    /// Automatic selection could not choose.
    #[error(transparent)]
    Select(#[from] SelectError),
    /// A record of several that no free-run score could read.
    #[error("record {record} has {0}", record = .0.record)]
    ShortRecord(ShortRecord),
}

/// A record of several no longer than the warm-up every free-run score
/// leaves out (the affine comparison, `--auto`'s scores and refit): it
/// could never be scored. Shown without the record, which each front end
/// names its own way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "{samples} sample(s), no more than the warm-up of {warmup} that every free-run score leaves out: give more rows or a shorter warm-up"
)]
pub struct ShortRecord {
    /// The record, from 1.
    pub record: usize,
    /// Its samples.
    pub samples: usize,
    /// The warm-up.
    pub warmup: usize,
}

impl<'a> Identify<'a> {
    /// A request for `method` on `data` with every other field at its
    /// default: orders 2 and 2, no priors, the back-end's options, seed 0.
    pub fn new(method: &str, data: &'a Dataset) -> Self {
        Self {
            method: method.to_string(),
            data,
            first_row: 0,
            na: 2,
            nb: 2,
            priors: Priors::default(),
            priors_origin: None,
            modes: None,
            max_modes: None,
            options: Settings::default(),
            seed: 0,
            time_budget: None,
            stop: None,
            warmup: 10,
            mode: Mode::Plain,
        }
    }

    /// With output lags `na` and input lags `nb`.
    pub fn orders(self, na: usize, nb: usize) -> Self {
        Self { na, nb, ..self }
    }

    /// With `modes` modes.
    pub fn modes(self, modes: usize) -> Self {
        Self {
            modes: Some(modes),
            ..self
        }
    }

    /// With at most `max_modes` modes.
    pub fn max_modes(self, max_modes: usize) -> Self {
        Self {
            max_modes: Some(max_modes),
            ..self
        }
    }

    /// With seed `seed`.
    pub fn seed(self, seed: u64) -> Self {
        Self { seed, ..self }
    }

    /// With the prior knowledge `priors` (a prior file:
    /// [`Priors::load`]).
    pub fn priors(self, priors: Priors) -> Self {
        Self { priors, ..self }
    }

    /// With the back-end's option `key` set to `value`, as `--set
    /// key=value` sets it (replacing a value given before); checked by
    /// [`Identify::run`] against the back-end's options.
    pub fn set(self, key: &str, value: &str) -> Self {
        Self {
            options: self.options.with(key, value),
            ..self
        }
    }

    /// With the options chosen on selection rows ([`Mode::Auto`], as
    /// `hysid identify --auto` with its defaults).
    pub fn auto(self) -> Self {
        Self {
            mode: Mode::Auto(Auto::default()),
            ..self
        }
    }

    /// Ending by `seconds` ([`Field::TimeBudget`]: a positive number).
    pub fn time_budget(self, seconds: f64) -> Self {
        Self {
            time_budget: Some(seconds),
            ..self
        }
    }

    /// The priors with the mode counts given, checked.
    pub fn resolved_priors(&self) -> Result<Priors, Error> {
        let mut priors = self.priors.clone();
        for (field, value, prior) in [
            (Field::Modes, self.modes, &mut priors.modes),
            (Field::MaxModes, self.max_modes, &mut priors.max_modes),
        ] {
            if let Some(s) = value {
                if s == 0 {
                    return Err(Error::Field {
                        field,
                        value: s.to_string(),
                        what: "must be at least 1".into(),
                    });
                }
                *prior = Some(s);
            }
        }
        if self.modes.is_some() || self.max_modes.is_some() {
            priors.check().map_err(|problem| Error::Modes {
                modes: self.modes,
                max_modes: self.max_modes,
                problem,
            })?;
        }
        Ok(priors)
    }

    /// When the run must end.
    fn deadline(&self) -> Result<Deadline, Error> {
        let deadline = match self.time_budget {
            Some(t) => Deadline::after_seconds(t).ok_or(Error::Field {
                field: Field::TimeBudget,
                value: t.to_string(),
                what: "must be a positive number of seconds".into(),
            })?,
            None => Deadline::none(),
        };
        Ok(match &self.stop {
            Some(flag) => deadline.with_stop(Arc::clone(flag)),
            None => deadline,
        })
    }

    /// Runs the request with the back-ends of `registry`, quietly.
    pub fn run(&self, registry: &Registry) -> Result<Identified, Error> {
        self.run_with(registry, &NoProgress)
    }

    /// Runs the request, showing progress on `progress`.
    pub fn run_with(
        &self,
        registry: &Registry,
        progress: &dyn Progress,
    ) -> Result<Identified, Error> {
        let backend = registry.require(&self.method)?;
        let priors = self.resolved_priors()?;
        self.check_records()?;
        let ctx = RunContext {
            seed: self.seed,
            progress,
            deadline: self.deadline()?,
        };
        let problem = self.problem(&priors);
        let model = match &self.mode {
            Mode::Plain => backend.run(&problem, &self.options, &ctx)?,
            Mode::Standardized => run_standardized(backend, &problem, &self.options, &ctx)?,
            Mode::Auto(auto) => {
                let request = self.selection(registry, backend, &problem, auto)?;
                select::select(&request, &ctx)?
            }
        };
        Ok(Identified { model })
    }

    /// Whether the seed can change the model [`Identify::run`] returns
    /// ([`Backend::seeded_with`]; with [`Mode::Auto`], of any candidate:
    /// [`select::seeded`]). When it cannot, one seed stands for all.
    pub fn seeded(&self, registry: &Registry) -> Result<bool, Error> {
        let backend = registry.require(&self.method)?;
        let priors = self.resolved_priors()?;
        let problem = self.problem(&priors);
        Ok(match &self.mode {
            Mode::Plain | Mode::Standardized => backend.seeded_with(&problem, &self.options)?,
            Mode::Auto(auto) => {
                select::seeded(&self.selection(registry, backend, &problem, auto)?)?
            }
        })
    }

    /// Refuses, when the data join several records, one that no free-run
    /// score could read past the warm-up ([`Error::ShortRecord`]).
    fn check_records(&self) -> Result<(), Error> {
        let ranges = self.data.record_ranges();
        if ranges.len() < 2 {
            return Ok(());
        }
        match ranges.iter().position(|r| r.len() <= self.warmup) {
            Some(i) => Err(Error::ShortRecord(ShortRecord {
                record: i + 1,
                samples: ranges[i].len(),
                warmup: self.warmup,
            })),
            None => Ok(()),
        }
    }

    /// How `auto` splits the identification rows.
    fn plan(&self, auto: &Auto) -> Plan {
        Plan {
            select: auto.select_rows,
            folds: auto.folds,
            select_records: auto.select_records,
            warmup: self.warmup,
            first_row: self.first_row,
            refit_starts: auto.refit_starts,
        }
    }

    /// Checks, without fitting anything, that an automatic selection's
    /// selection rows, folds or held-out records split the data
    /// ([`select::splits`]); nothing to check in the other modes.
    pub fn check_selection(&self) -> Result<(), SelectError> {
        match &self.mode {
            Mode::Auto(auto) => select::splits(self.data, &self.plan(auto)).map(|_| ()),
            Mode::Plain | Mode::Standardized => Ok(()),
        }
    }

    /// The record, orders and `priors` of the request.
    fn problem<'p>(&'p self, priors: &'p Priors) -> Problem<'p> {
        Problem {
            data: self.data,
            orders: RegressorSpec::new(self.na, self.nb, self.data.inputs.len()),
            priors,
            priors_origin: self.priors_origin.as_deref(),
        }
    }

    /// `grid`, the user's, refused where an axis is also fixed (by a given
    /// option, or `modes` by the exact mode count of the priors: the grid
    /// would override it) and where a point's orders cannot hold the
    /// priors' names (as `sweep` refuses them).
    fn checked_grid(
        &self,
        backend: &dyn Backend,
        grid: &SearchSpace,
        problem: &Problem<'_>,
    ) -> Result<SearchSpace, Error> {
        let priors = problem.priors;
        let given = GivenBesideGrid {
            options: &self.options,
            modes: self.modes,
            prior_modes: priors.modes,
            priors_origin: self.priors_origin.as_deref(),
            orders: [None, None],
        };
        given.check(grid)?;
        let setup = Setup {
            orders: problem.orders,
            priors: priors.clone(),
            settings: self.options.clone(),
        };
        for (_, point) in select::candidate_setups(backend, &setup, grid)? {
            backend.check_priors(
                &point.settings,
                &point.priors,
                point.orders,
                problem.priors_origin,
            )?;
        }
        Ok(grid.clone())
    }

    /// The automatic selection `auto` asks for on `problem`: the grid
    /// given or the back-end's search space, the split and the refit.
    fn selection<'p>(
        &'p self,
        registry: &'p Registry,
        backend: &'p dyn Backend,
        problem: &Problem<'p>,
        auto: &Auto,
    ) -> Result<Request<'p>, Error> {
        if !(1..=MAX_COUNT).contains(&auto.refit_starts) {
            return Err(Error::Field {
                field: Field::RefitStarts,
                value: auto.refit_starts.to_string(),
                what: format!("must be in 1..={MAX_COUNT}"),
            });
        }
        // Three ways of choosing the selection rows: one at a time.
        if let (Some(folds), Some(_)) = (auto.folds, auto.select_rows) {
            return Err(SelectError::Folds {
                folds,
                reason: "not with selection rows: give one of the two".into(),
            }
            .into());
        }
        if let (Some(records), true) = (
            auto.select_records,
            auto.folds.is_some() || auto.select_rows.is_some(),
        ) {
            return Err(SelectError::Records {
                records,
                reason: "not with selection rows or folds: give one of the three".into(),
            }
            .into());
        }
        let space = match &auto.grid {
            Some(grid) => self.checked_grid(backend, grid, problem)?,
            None => backend.search_space(problem)?.without_given(&self.options),
        };
        let plan = self.plan(auto);
        let affine = crate::affine_reference(registry, backend.name())
            .filter(|_| affine_is_candidate(problem.priors));
        Ok(Request::from_problem(
            backend,
            affine,
            problem,
            self.options.clone(),
            space,
            plan,
        ))
    }
}

impl Identified {
    /// The model's free-run FIT on the identification record beside the
    /// affine ARX model's of the same orders and priors fitted on it;
    /// `None` when the model has no ARX orders, is that reference itself,
    /// or was chosen by automatic selection among candidates that held the
    /// affine model (which compared it already).
    pub fn against_affine(&self, request: &Identify<'_>) -> Option<AgainstAffine> {
        let priors = request.resolved_priors().ok()?;
        if self.model.info().selection.is_some() && affine_is_candidate(&priors) {
            return None;
        }
        crate::against_affine(&self.model, request.data, &priors, request.warmup)
    }

    /// What every front end tells about a `physical` fit beside its model:
    /// its diagnostics' warnings
    /// (`hysid_physical::diagnostics::PhysicalDiagnostics::warnings`: values
    /// at a bound, parameters the rows do not determine or without a
    /// standard error), the definitions no expression reads
    /// ([`UnreadDefinitions`]), then those of the fitted model's run on the
    /// identification rows of `request` (a divergence, the Zeno bound,
    /// samples outside their mode's invariant); empty for the other
    /// back-ends.
    pub fn fit_warnings(&self, request: &Identify<'_>) -> Vec<String> {
        if !matches!(self.model, Model::GrayBox(_) | Model::Mechanical(_)) {
            return Vec::new();
        }
        let mut warnings = PhysicalDiagnostics::of(&self.model.info().diagnostics)
            .map(|d| d.warnings())
            .unwrap_or_default();
        warnings.extend(UnreadDefinitions::of(&self.model).map(|u| u.to_string()));
        if let Ok(sim) = simulate(&self.model, request.data, SimulationOptions::default()) {
            warnings.extend(OutsideRegions::of(&self.model, &sim).map(|o| o.to_string()));
            warnings.extend(sim.warnings().iter().map(ToString::to_string));
        }
        warnings
    }

    /// The warning every front end gives when the model simulates its
    /// identification rows below the affine model ([`Self::against_affine`]),
    /// saying so when automatic selection could not hold the affine model
    /// among its candidates; `None` otherwise.
    pub fn affine_warning(&self, request: &Identify<'_>) -> Option<String> {
        let c = self.against_affine(request).filter(AgainstAffine::below)?;
        let warning = c.warning("its identification rows");
        Some(match self.model.info().selection {
            Some(_) => format!(
                "{warning}; the mode count is the prior's, so the affine model was not a candidate"
            ),
            None => warning,
        })
    }
}

/// Whether automatic selection holds the affine model (one ordinary mode)
/// among its candidates under `priors`: not when they fix another mode
/// count, which is the user's knowledge.
fn affine_is_candidate(priors: &Priors) -> bool {
    priors
        .modes
        .is_none_or(|s| s == priors.saturation.len() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_testkit::{Noise, b1};

    /// Under an exact mode count the affine model is not a candidate of
    /// automatic selection, the model written has that count, and the
    /// comparison with the affine model is left to the front end; without
    /// one the affine model is a candidate and was compared already.
    #[test]
    fn an_exact_mode_count_keeps_the_affine_model_out_of_the_candidates() {
        let record = b1(300, 4.0, Noise::Uniform(0.05), 1).data;
        let registry = crate::registry();
        let request = |modes: Option<usize>| Identify {
            modes,
            max_modes: modes.is_none().then_some(3),
            ..Identify::new("cluster", &record)
                .orders(1, 1)
                .set("refine", "none")
                .auto()
                .seed(1)
        };
        for modes in [Some(3), None] {
            let request = request(modes);
            let identified = request.run(&registry).unwrap();
            let selection = identified.model.info().selection.clone().unwrap();
            let affine = selection.candidates.iter().any(|c| c.method == "arx");
            assert_eq!(affine, modes.is_none(), "{modes:?}");
            assert_eq!(
                identified.against_affine(&request).is_some(),
                modes.is_some()
            );
            if let Some(s) = modes {
                assert_eq!(identified.model.mode_count(), s);
            }
        }
    }
}
