//! The plugin contract of identification back-ends, and their registry.
//!
//! A back-end implements [`Identifier`] (typed options, the priors it
//! honours, `identify`). The blanket [`Backend`] impl does what every
//! back-end needs done the same way: resolving `--set` options, refusing
//! priors the back-end does not honour, and recording provenance in the
//! model. The CLI and `compare` only see `dyn Backend` through a
//! [`Registry`].

use crate::model::{Model, SignalNames};
use crate::options::{
    BackendOptions, CheckOptions, Checked, OptionError, OptionSpec, PRESET, Settings, preset_spec,
};
use crate::priors::{ModeCountNeed, PriorError, PriorKind, Priors};
use crate::search::SearchSpace;
use hysid_model::data::{DataError, Dataset};
use hysid_model::regressors::{RegressorError, RegressorSpec};
pub use hysid_numerics::budget::{Budget, Deadline, Exhausted};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// What to identify: a record, the model orders and the priors.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// Identification record, in original units; it may join several
    /// records of the system, whose boundaries no regressor, segment or
    /// simulation of the back-end crosses.
    pub data: &'a Dataset,
    /// PWARX orders (ignored by back-ends with their own structure).
    pub orders: RegressorSpec,
    /// Prior knowledge.
    pub priors: &'a Priors,
    /// Where the priors came from, for error messages.
    pub priors_origin: Option<&'a str>,
}

/// Progress of long work; the CLI shows it with indicatif on a terminal.
pub trait Progress: Sync {
    /// A new phase of `total` steps.
    fn start(&self, _total: u64, _what: &str) {}
    /// `n` steps done.
    fn advance(&self, _n: u64) {}
    /// Phase finished.
    fn finish(&self) {}
}

/// Progress that shows nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;
impl Progress for NoProgress {}

/// Seed, progress and time budget of one run.
pub struct RunContext<'a> {
    /// Seed of every random choice of the run.
    pub seed: u64,
    /// Progress sink.
    pub progress: &'a dyn Progress,
    /// When long back-ends stop and return their best model.
    pub deadline: Deadline,
}

impl<'a> RunContext<'a> {
    /// A quiet context with `seed` and no deadline.
    pub fn quiet(seed: u64) -> RunContext<'static> {
        RunContext {
            seed,
            progress: &NoProgress,
            deadline: Deadline::none(),
        }
    }
    /// The seeds of `k` independent starts of a run: the run's own seed,
    /// then successive draws of a `ChaCha8Rng` seeded by it. The first
    /// start is the run itself, so one start changes nothing.
    pub fn start_seeds(&self, k: usize) -> Vec<u64> {
        let mut draws = ChaCha8Rng::seed_from_u64(self.seed);
        (0..k)
            .map(|i| if i == 0 { self.seed } else { draws.next_u64() })
            .collect()
    }
}

/// Why identification failed.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// No back-end of that name.
    #[error("unknown method '{name}' (methods: {known})")]
    UnknownMethod {
        /// Name asked for.
        name: String,
        /// Registered names.
        known: String,
    },
    /// Bad `--set` option.
    #[error(transparent)]
    Options(#[from] OptionError),
    /// A prior that is inconsistent or not honoured.
    #[error(transparent)]
    Prior(#[from] PriorError),
    /// The record does not give the regressors (too short, wrong number
    /// of inputs...).
    #[error(transparent)]
    Regressors(#[from] RegressorError),
    /// A record could not be cut or selected.
    #[error(transparent)]
    Data(#[from] DataError),
    /// A regressor or target is NaN or infinite.
    #[error("the data hold a non-finite value ({value})")]
    NonFinite {
        /// The first such value.
        value: f64,
    },
    /// Every regression target sits at a known stop.
    #[error(
        "all {samples} samples sit at a known stop: no ordinary sample is left to identify (check the [[saturation]] entries' level, bound and tol)"
    )]
    AllAtStops {
        /// Number of regression rows.
        samples: usize,
    },
    /// A `modes` or `max_modes` prior that leaves no ordinary mode beside
    /// the stops.
    #[error(
        "prior {key} = {count}: method '{method}' needs at least {} (the count includes the {stops} \
         saturation mode(s) of the priors, and one ordinary mode)",
        .stops + 1
    )]
    NoOrdinaryMode {
        /// `modes` or `max_modes`.
        key: &'static str,
        /// Its value.
        count: usize,
        /// Back-end name.
        method: String,
        /// Number of known stops.
        stops: usize,
    },
    /// A back-end that cannot choose the mode count without a prior.
    #[error(
        "method '{method}' needs the number of modes: give the prior modes = S{}",
        if *bounded { " (or max_modes = S to choose it by hold-out simulation FIT)" } else { " (or choose it by automatic selection)" }
    )]
    NeedsModeCount {
        /// The back-end.
        method: &'static str,
        /// Whether the back-end chooses the count itself under a
        /// `max_modes` bound (else only automatic selection chooses it).
        bounded: bool,
    },
    /// A `modes` prior above the `max_modes` prior.
    #[error("prior modes = {modes} exceeds max_modes = {max}")]
    ModesExceedMax {
        /// `modes`.
        modes: usize,
        /// `max_modes`.
        max: usize,
    },
    /// Fewer regression rows than the parameters of the modes asked for.
    #[error("{rows} regressors cannot identify {modes} modes of {params} parameters")]
    TooFewRegressors {
        /// Regression rows.
        rows: usize,
        /// Modes asked for (stops included).
        modes: usize,
        /// Parameters per mode.
        params: usize,
    },
    /// A prior entry that does not fit the problem (a name the model
    /// structure lacks, constraints that cannot hold together), worded with
    /// the file the priors came from.
    #[error("{}{problem}", prior_prefix(.origin))]
    PriorMismatch {
        /// The prior file, when the priors came from one.
        origin: Option<String>,
        /// What does not fit (the back-end's typed error).
        #[source]
        problem: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Bad input particular to a back-end: its own typed error
    /// (`ArxError`, `ClusterError`, ...), reached with `downcast_ref`.
    #[error(transparent)]
    Input(Box<dyn std::error::Error + Send + Sync>),
    /// Fewer samples than the back-end needs for the problem asked
    /// (its orders, modes, free parameters or local datasets): its own
    /// typed error, reached with `downcast_ref`. A front end names the
    /// records and rows the samples came from.
    #[error(transparent)]
    TooFewSamples(Box<dyn std::error::Error + Send + Sync>),
    /// The method ran and failed (solver failure, every restart diverged...):
    /// the back-end's or the shared step's own typed error, reached with
    /// [`IdentifyError::downcast_ref`].
    #[error("{method}: {cause}")]
    Failed {
        /// Back-end (filled in by [`Backend::run`]).
        method: &'static str,
        /// What failed.
        cause: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// `"FILE: "` for priors from a file, `"prior "` otherwise.
fn prior_prefix(origin: &Option<String>) -> String {
    match origin {
        Some(o) => format!("{o}: "),
        None => "prior ".to_string(),
    }
}

impl IdentifyError {
    /// Bad input of a back-end's own kind ([`IdentifyError::Input`]).
    pub fn input(e: impl std::error::Error + Send + Sync + 'static) -> Self {
        IdentifyError::Input(Box::new(e))
    }

    /// Too few samples for the back-end ([`IdentifyError::TooFewSamples`]).
    pub fn too_few_samples(e: impl std::error::Error + Send + Sync + 'static) -> Self {
        IdentifyError::TooFewSamples(Box::new(e))
    }

    /// Whether the record gave too few samples, or none of the shape asked
    /// ([`IdentifyError::Regressors`], [`IdentifyError::TooFewRegressors`],
    /// [`IdentifyError::TooFewSamples`]): a front end names where the
    /// samples came from.
    pub fn is_sample_shortage(&self) -> bool {
        matches!(
            self,
            IdentifyError::Regressors(_)
                | IdentifyError::TooFewRegressors { .. }
                | IdentifyError::TooFewSamples(_)
        )
    }

    /// A prior that does not fit the problem ([`IdentifyError::PriorMismatch`]);
    /// `origin` is the prior file, if any.
    pub fn prior_mismatch(
        origin: Option<&str>,
        problem: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        IdentifyError::PriorMismatch {
            origin: origin.map(str::to_string),
            problem: Box::new(problem),
        }
    }

    /// The back-end's own error inside [`IdentifyError::Input`],
    /// [`IdentifyError::TooFewSamples`], [`IdentifyError::PriorMismatch`]
    /// or [`IdentifyError::Failed`], if it is an `E`.
    pub fn downcast_ref<E: std::error::Error + 'static>(&self) -> Option<&E> {
        match self {
            IdentifyError::Input(e)
            | IdentifyError::TooFewSamples(e)
            | IdentifyError::PriorMismatch { problem: e, .. }
            | IdentifyError::Failed { cause: e, .. } => e.downcast_ref(),
            _ => None,
        }
    }

    /// True for the errors of the run's set-up rather than of its data,
    /// which refuse the request whatever rows it is run on: an unknown
    /// method, a bad option, a prior file that is inconsistent, not
    /// honoured or not fitting the structure, a mode count missing or
    /// contradictory. Automatic selection reports one when every
    /// candidate is refused so.
    pub fn is_setup_error(&self) -> bool {
        matches!(
            self,
            IdentifyError::UnknownMethod { .. }
                | IdentifyError::Options(_)
                | IdentifyError::Prior(_)
                | IdentifyError::NoOrdinaryMode { .. }
                | IdentifyError::NeedsModeCount { .. }
                | IdentifyError::ModesExceedMax { .. }
                | IdentifyError::PriorMismatch { .. }
        )
    }

    /// A failure of the method itself, its typed cause; [`Backend::run`]
    /// names the method.
    pub fn failed(cause: impl std::error::Error + Send + Sync + 'static) -> Self {
        IdentifyError::Failed {
            method: "",
            cause: Box::new(cause),
        }
    }

    /// The error with the failing method named (done by [`Backend::run`];
    /// for callers of [`Identifier::identify`] outside it).
    pub fn of_method(self, name: &'static str) -> Self {
        match self {
            IdentifyError::Failed { method: "", cause } => IdentifyError::Failed {
                method: name,
                cause,
            },
            other => other,
        }
    }
}

impl IdentifyError {
    /// True when the cause is the user's input (exit code 2), false for a
    /// model-level failure (exit code 1).
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, IdentifyError::Failed { .. })
    }
}

/// What a back-end implements.
pub trait Identifier: Send + Sync {
    /// Typed options with documented defaults, checked once
    /// ([`CheckOptions`]) before `identify` sees them.
    type Options: BackendOptions + CheckOptions;
    /// Name used with `-m`.
    const NAME: &'static str;
    /// One-line description.
    const SUMMARY: &'static str;
    /// Prior kinds honoured; any other prior is refused before `identify`.
    const HONOURS: &'static [PriorKind];
    /// What [`Identifier::search_space`] tries, in one sentence (printed by
    /// `hysid methods`); empty when the back-end has nothing to choose.
    const SEARCH: &'static str = "";
    /// Options and diagnostics fields measured in the output's units (a
    /// residual bound, a residual). A run on standardised data
    /// (`--standardize`) divides these options by the output's standard
    /// deviation before the run and multiplies these diagnostics by it
    /// after, so the user speaks and reads data units throughout.
    const OUTPUT_UNITS: &'static [&'static str] = &[];
    /// Whether the run's seed can change the model (random starts, visiting
    /// orders). Automatic selection refits the choice of a seeded back-end
    /// from several starts and keeps the one that simulates the
    /// identification rows best; a back-end whose fit is a function of the
    /// data alone says `false`, and is refitted once.
    const SEEDED: bool = true;
    /// For a seeded back-end whose options decide whether the seed is
    /// drawn from ([`Identifier::seeded_with`]): when it is, in one phrase
    /// (printed by `hysid methods`); empty when it always is.
    const SEED_USE: &'static str = "";
    /// Whether the back-end runs the stages after a PWARX fit
    /// ([`crate::stages::Stages`]): its options include theirs, and
    /// automatic selection may set them.
    const STAGES: bool = false;
    /// The options that turn the defaults into the procedure of the
    /// back-end's paper exactly (`--set preset=paper`,
    /// [`crate::options::PRESET`]); empty when the defaults are that
    /// procedure.
    const PAPER: &'static [(&'static str, &'static str)] = &[];

    /// Whether the seed can change the model identified on `problem` with
    /// `options`: [`Identifier::SEEDED`], unless these options draw
    /// nothing at random. A run that returns `false` gives the same model
    /// for every seed, so a refit from several starts, or a median over
    /// seeds, needs that run once.
    fn seeded_with(&self, _problem: &Problem<'_>, _options: &Self::Options) -> bool {
        Self::SEEDED
    }

    /// What a fit with `options` needs of the priors' number of modes:
    /// without it, `identify` refuses the run
    /// ([`IdentifyError::NeedsModeCount`]); automatic selection chooses the
    /// count itself. The default: nothing.
    fn mode_count_need(&self, _options: &Self::Options) -> ModeCountNeed {
        ModeCountNeed::Nothing
    }

    /// The candidate settings that automatic selection (`--auto`) tries on
    /// `problem`; the default is the back-end's defaults only.
    fn search_space(&self, _problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        Ok(SearchSpace::default())
    }

    /// The signals the model fitted with `options` names (a physical model
    /// file's: those it was identified on, else those it declares), which
    /// a front end reads where the record has no `u` or `y`; none when the
    /// back-end's model names no signals. An error where the model file
    /// cannot be read, so that a front end says so before it reads data.
    fn declared_signals(&self, _options: &Self::Options) -> Result<SignalNames, IdentifyError> {
        Ok(SignalNames::default())
    }

    /// Checks `priors` against the model structure of `orders` (or of the
    /// model file `options` name) as `identify` would, without any data
    /// (the names of parameters and regressors, entries that cannot hold
    /// together), so that a front end refuses a run before anything runs;
    /// errors name `origin`, the priors' file. The default checks nothing.
    fn check_priors(
        &self,
        _options: &Self::Options,
        _priors: &Priors,
        _orders: RegressorSpec,
        _origin: Option<&str>,
    ) -> Result<(), IdentifyError> {
        Ok(())
    }

    /// Identifies a model. Provenance (method, options, seed, names) is
    /// filled in by the caller.
    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &Checked<Self::Options>,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError>;

    /// `fitted`, a model this back-end identified on `problem` with
    /// `options` except their simulation-error refinement (`refine =
    /// none`), refined as `options` ask without fitting it again; `None`
    /// when the back-end has no refinement stage after its fit (automatic
    /// selection then fits the candidate again with the refinement on).
    fn refine_fitted(
        &self,
        _problem: &Problem<'_>,
        _fitted: Model,
        _options: &Checked<Self::Options>,
        _ctx: &RunContext<'_>,
    ) -> Option<Result<Model, IdentifyError>> {
        None
    }
}

/// The object-safe face of a back-end, used by the registry.
pub trait Backend: Send + Sync {
    /// Name used with `-m`.
    fn name(&self) -> &'static str;
    /// One-line description.
    fn summary(&self) -> &'static str;
    /// Options with types, defaults and docs.
    fn options(&self) -> Vec<OptionSpec>;
    /// Prior kinds honoured.
    fn honours(&self) -> &'static [PriorKind];
    /// What automatic selection tries, in one sentence.
    fn search_doc(&self) -> &'static str;
    /// Options and diagnostics fields in the output's units
    /// ([`Identifier::OUTPUT_UNITS`]).
    fn output_units(&self) -> &'static [&'static str];
    /// Whether the seed can change the model ([`Identifier::SEEDED`]).
    fn seeded(&self) -> bool;
    /// When the seed is drawn from ([`Identifier::SEED_USE`]).
    fn seed_use(&self) -> &'static str;
    /// Whether the seed can change the model identified on `problem` with
    /// `settings` ([`Identifier::seeded_with`]); the errors of
    /// [`Backend::run`] for settings it refuses.
    fn seeded_with(
        &self,
        problem: &Problem<'_>,
        settings: &Settings,
    ) -> Result<bool, IdentifyError>;
    /// Whether the back-end runs the stages after a PWARX fit
    /// ([`Identifier::STAGES`]).
    fn has_stages(&self) -> bool;
    /// What a fit with `settings` needs of the priors' number of modes
    /// ([`Identifier::mode_count_need`]; nothing for settings it refuses,
    /// which [`Backend::check_settings`] names); the default: nothing.
    fn mode_count_need(&self, _settings: &Settings) -> ModeCountNeed {
        ModeCountNeed::Nothing
    }
    /// The candidate settings automatic selection tries on `problem`.
    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError>;
    /// The signals the model fitted with `settings` names
    /// ([`Identifier::declared_signals`]); the errors of [`Backend::run`]
    /// for settings it refuses or a model file it cannot read.
    fn declared_signals(&self, _settings: &Settings) -> Result<SignalNames, IdentifyError> {
        Ok(SignalNames::default())
    }
    /// Checks `priors` against the structure of `orders`, or of the model
    /// file `settings` name, without any data
    /// ([`Identifier::check_priors`]); settings it refuses are an error.
    /// The default accepts every prior: a back-end that checks in `run`.
    fn check_priors(
        &self,
        _settings: &Settings,
        _priors: &Priors,
        _orders: RegressorSpec,
        _origin: Option<&str>,
    ) -> Result<(), IdentifyError> {
        Ok(())
    }
    /// Checks `settings` as [`Backend::run`] would (keys, values, the
    /// preset and the checks across options) without touching any data.
    /// The default accepts every setting: a back-end that checks in `run`.
    fn check_settings(&self, _settings: &Settings) -> Result<(), OptionError> {
        Ok(())
    }
    /// Resolves options, checks priors, identifies, records provenance.
    fn run(
        &self,
        problem: &Problem<'_>,
        settings: &Settings,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError>;
    /// `fitted`, a model [`Backend::run`] returned on `problem` with
    /// `settings` but `refine = none`, refined as `settings` ask without
    /// fitting again ([`Identifier::refine_fitted`]), provenance recorded
    /// as by `run`; `None` when the back-end cannot.
    fn refine_fitted(
        &self,
        _problem: &Problem<'_>,
        _fitted: Model,
        _settings: &Settings,
        _ctx: &RunContext<'_>,
    ) -> Option<Result<Model, IdentifyError>> {
        None
    }
}

impl<T: Identifier> Backend for T {
    fn name(&self) -> &'static str {
        T::NAME
    }
    fn summary(&self) -> &'static str {
        T::SUMMARY
    }
    fn options(&self) -> Vec<OptionSpec> {
        let mut specs = T::Options::specs();
        specs.push(preset_spec(T::PAPER));
        specs
    }
    fn honours(&self) -> &'static [PriorKind] {
        T::HONOURS
    }
    fn search_doc(&self) -> &'static str {
        T::SEARCH
    }
    fn output_units(&self) -> &'static [&'static str] {
        T::OUTPUT_UNITS
    }
    fn seeded(&self) -> bool {
        T::SEEDED
    }
    fn seed_use(&self) -> &'static str {
        T::SEED_USE
    }
    fn check_priors(
        &self,
        settings: &Settings,
        priors: &Priors,
        orders: RegressorSpec,
        origin: Option<&str>,
    ) -> Result<(), IdentifyError> {
        let options = checked_settings::<T>(settings)?;
        Identifier::check_priors(self, &options, priors, orders, origin)
            .map_err(|e| e.of_method(T::NAME))
    }
    fn seeded_with(
        &self,
        problem: &Problem<'_>,
        settings: &Settings,
    ) -> Result<bool, IdentifyError> {
        let options = checked_options::<T>(problem, settings)?;
        Ok(Identifier::seeded_with(self, problem, &options))
    }
    fn has_stages(&self) -> bool {
        T::STAGES
    }
    fn mode_count_need(&self, settings: &Settings) -> ModeCountNeed {
        checked_settings::<T>(settings).map_or(ModeCountNeed::Nothing, |o| {
            Identifier::mode_count_need(self, &o)
        })
    }
    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        Identifier::search_space(self, problem)
    }
    fn declared_signals(&self, settings: &Settings) -> Result<SignalNames, IdentifyError> {
        let options = checked_settings::<T>(settings)?;
        Identifier::declared_signals(self, &options).map_err(|e| e.of_method(T::NAME))
    }
    fn check_settings(&self, settings: &Settings) -> Result<(), OptionError> {
        checked_settings::<T>(settings).map(|_| ())
    }
    fn run(
        &self,
        problem: &Problem<'_>,
        settings: &Settings,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let options = checked_options::<T>(problem, settings)?;
        let model = self
            .identify(problem, &options, ctx)
            .map_err(|e| e.of_method(T::NAME))?;
        Ok(with_provenance::<T>(model, problem, &options, ctx))
    }
    fn refine_fitted(
        &self,
        problem: &Problem<'_>,
        fitted: Model,
        settings: &Settings,
        ctx: &RunContext<'_>,
    ) -> Option<Result<Model, IdentifyError>> {
        let options = match checked_options::<T>(problem, settings) {
            Ok(options) => options,
            Err(e) => return Some(Err(e)),
        };
        let refined = Identifier::refine_fitted(self, problem, fitted, &options, ctx)?;
        Some(
            refined
                .map(|model| with_provenance::<T>(model, problem, &options, ctx))
                .map_err(|e| e.of_method(T::NAME)),
        )
    }
}

/// `settings` with their preset written out, resolved into `T`'s checked
/// options, with the priors checked against those `T` honours.
fn checked_options<T: Identifier>(
    problem: &Problem<'_>,
    settings: &Settings,
) -> Result<Checked<T::Options>, IdentifyError> {
    let options = checked_settings::<T>(settings)?;
    problem
        .priors
        .ensure_honoured(T::NAME, T::HONOURS, problem.priors_origin)?;
    Ok(options)
}

/// `settings` with their preset written out, resolved into `T`'s checked
/// options.
fn checked_settings<T: Identifier>(
    settings: &Settings,
) -> Result<Checked<T::Options>, OptionError> {
    let settings = settings.with_preset(T::PAPER)?;
    let options = settings
        .resolve::<T::Options>(T::NAME)
        .map_err(|e| match e {
            // `preset` is taken above; the list names it with the others.
            OptionError::Unknown { key, method, known } => OptionError::Unknown {
                key,
                method,
                known: format!("{known}, {PRESET}"),
            },
            other => other,
        })?;
    Checked::new(options)
}

/// `model` with its provenance: the method, options, seed and names.
fn with_provenance<T: Identifier>(
    mut model: Model,
    problem: &Problem<'_>,
    options: &Checked<T::Options>,
    ctx: &RunContext<'_>,
) -> Model {
    let info = model.info_mut();
    info.method = T::NAME.to_string();
    info.options = options.to_map();
    info.seed = Some(ctx.seed);
    info.input_names = problem.data.input_names();
    info.output_name = problem.data.output.name.clone();
    info.ts = problem.data.ts;
    model
}

/// What `hysid methods --json` prints of one back-end: its name, options
/// (with types, defaults and docs), the priors it honours and what
/// automatic selection tries.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MethodDescription {
    /// Name used with `-m`.
    pub name: &'static str,
    /// One-line description.
    pub summary: &'static str,
    /// Options with types, defaults and docs.
    pub options: Vec<OptionSpec>,
    /// Prior kinds honoured.
    pub priors: &'static [PriorKind],
    /// What automatic selection tries, in one sentence.
    pub search: &'static str,
    /// Whether the seed can change the model ([`Identifier::SEEDED`]).
    pub seeded: bool,
    /// When it does, where the options decide ([`Identifier::SEED_USE`]).
    pub seed_use: &'static str,
}

impl MethodDescription {
    /// The description of `backend`.
    pub fn of(backend: &dyn Backend) -> Self {
        Self {
            name: backend.name(),
            summary: backend.summary(),
            options: backend.options(),
            priors: backend.honours(),
            search: backend.search_doc(),
            seeded: backend.seeded(),
            seed_use: backend.seed_use(),
        }
    }
}

/// The registered back-ends, in registration order.
#[derive(Default)]
pub struct Registry {
    backends: Vec<Box<dyn Backend>>,
}

impl Registry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a back-end (builder style).
    pub fn with(mut self, backend: impl Backend + 'static) -> Self {
        assert!(
            self.get(backend.name()).is_none(),
            "back-end '{}' registered twice",
            backend.name()
        );
        self.backends.push(Box::new(backend));
        self
    }

    /// The back-ends.
    pub fn iter(&self) -> impl Iterator<Item = &dyn Backend> {
        self.backends.iter().map(|b| b.as_ref())
    }

    /// The description of every back-end, in registration order.
    pub fn describe(&self) -> Vec<MethodDescription> {
        self.iter().map(MethodDescription::of).collect()
    }

    /// Registered names.
    pub fn names(&self) -> Vec<&'static str> {
        self.iter().map(|b| b.name()).collect()
    }

    /// The back-end named `name`.
    pub fn get(&self, name: &str) -> Option<&dyn Backend> {
        self.iter().find(|b| b.name() == name)
    }

    /// The back-end named `name`, or an error listing the known ones.
    pub fn require(&self, name: &str) -> Result<&dyn Backend, IdentifyError> {
        self.get(name).ok_or_else(|| IdentifyError::UnknownMethod {
            name: name.to_string(),
            known: self.names().join(", "),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("[fixed]: unknown name 'a9'")]
    struct Unknown;

    #[test]
    fn typed_variants_keep_their_wording() {
        let e = IdentifyError::prior_mismatch(Some("p.toml"), Unknown);
        assert_eq!(e.to_string(), "p.toml: [fixed]: unknown name 'a9'");
        assert!(e.downcast_ref::<Unknown>().is_some() && e.is_bad_input());
        let e = IdentifyError::prior_mismatch(None, Unknown);
        assert_eq!(e.to_string(), "prior [fixed]: unknown name 'a9'");
        let e = IdentifyError::NoOrdinaryMode {
            key: "modes",
            count: 2,
            method: "cluster".into(),
            stops: 2,
        };
        assert_eq!(
            e.to_string(),
            "prior modes = 2: method 'cluster' needs at least 3 (the count includes the 2 \
             saturation mode(s) of the priors, and one ordinary mode)"
        );
        // A mode count the priors contradict refuses the request on any rows.
        assert!(e.is_setup_error());
        let e = IdentifyError::input(Unknown);
        assert_eq!(e.to_string(), "[fixed]: unknown name 'a9'");
        let e = IdentifyError::failed(Unknown).of_method("arx");
        assert_eq!(e.to_string(), "arx: [fixed]: unknown name 'a9'");
        assert!(e.downcast_ref::<Unknown>().is_some() && !e.is_bad_input());
    }
}
