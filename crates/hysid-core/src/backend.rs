//! The plugin contract of identification back-ends, and their registry.
//!
//! A back-end implements [`Identifier`] (typed options, the priors it
//! honours, `identify`). The blanket [`Backend`] impl does what every
//! back-end needs done the same way: resolving `--set` options, refusing
//! priors the back-end does not honour, and recording provenance in the
//! model. The CLI and `compare` only see `dyn Backend` through a
//! [`Registry`].

use crate::model::Model;
use crate::options::{BackendOptions, CheckOptions, Checked, OptionError, OptionSpec, Settings};
use crate::priors::{PriorError, PriorKind, Priors};
use crate::search::SearchSpace;
use hysid_model::data::Dataset;
use hysid_model::regressors::RegressorSpec;
use std::time::Instant;

/// What to identify: a record, the model orders and the priors.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// Identification record, in original units.
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
    /// When set, long back-ends stop and return their best model by then.
    pub deadline: Option<Instant>,
}

impl<'a> RunContext<'a> {
    /// A quiet context with `seed` and no deadline.
    pub fn quiet(seed: u64) -> RunContext<'static> {
        RunContext {
            seed,
            progress: &NoProgress,
            deadline: None,
        }
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
    /// The data do not allow the requested identification (too short,
    /// wrong number of inputs, fewer samples than parameters...).
    #[error("{0}")]
    BadData(String),
    /// The method ran and failed (solver failure, every restart diverged...).
    #[error("{method}: {message}")]
    Failed {
        /// Back-end (filled in by [`Backend::run`]).
        method: &'static str,
        /// What happened.
        message: String,
    },
}

impl IdentifyError {
    /// A failure of the method itself; [`Backend::run`] names the method.
    pub fn failed(message: impl Into<String>) -> Self {
        IdentifyError::Failed {
            method: "",
            message: message.into(),
        }
    }

    /// The error with the failing method named (done by [`Backend::run`];
    /// for callers of [`Identifier::identify`] outside it).
    pub fn of_method(self, name: &'static str) -> Self {
        match self {
            IdentifyError::Failed {
                method: "",
                message,
            } => IdentifyError::Failed {
                method: name,
                message,
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

    /// The candidate settings that automatic selection (`--auto`) tries on
    /// `problem`; the default is the back-end's defaults only.
    fn search_space(&self, _problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        Ok(SearchSpace::default())
    }

    /// Identifies a model. Provenance (method, options, seed, names) is
    /// filled in by the caller.
    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &Checked<Self::Options>,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError>;
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
    /// The candidate settings automatic selection tries on `problem`.
    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError>;
    /// Resolves options, checks priors, identifies, records provenance.
    fn run(
        &self,
        problem: &Problem<'_>,
        settings: &Settings,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError>;
}

impl<T: Identifier> Backend for T {
    fn name(&self) -> &'static str {
        T::NAME
    }
    fn summary(&self) -> &'static str {
        T::SUMMARY
    }
    fn options(&self) -> Vec<OptionSpec> {
        T::Options::specs()
    }
    fn honours(&self) -> &'static [PriorKind] {
        T::HONOURS
    }
    fn search_doc(&self) -> &'static str {
        T::SEARCH
    }
    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        Identifier::search_space(self, problem)
    }
    fn run(
        &self,
        problem: &Problem<'_>,
        settings: &Settings,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let options = Checked::new(settings.resolve::<T::Options>(T::NAME)?)?;
        problem
            .priors
            .ensure_honoured(T::NAME, T::HONOURS, problem.priors_origin)?;
        let mut model = self
            .identify(problem, &options, ctx)
            .map_err(|e| e.of_method(T::NAME))?;
        let info = model.info_mut();
        info.method = T::NAME.to_string();
        info.options = options.to_map();
        info.seed = Some(ctx.seed);
        info.input_names = problem.data.input_names();
        info.output_name = problem.data.output.name.clone();
        info.ts = problem.data.ts;
        Ok(model)
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
