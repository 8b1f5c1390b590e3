//! # hysid-physical
//!
//! The `physical` back-end: white-box identification of a hybrid model
//! declared by its physics, a mass-spring-friction automaton
//! ([`MechanicalModel`], `"kind": "mechanical"`, fitted as its gray-box
//! form: [`mechanical`]) or any gray-box model (`"kind": "gray_box"`,
//! [`target`]), the question the founding paper
//! leaves open (Juloski, Heemels, Ferrari-Trecate, IFAC ADHS 2003:
//! "structural models ... and their parameters (white box modelling)").
//!
//! The physical parameters are fitted by minimising the **simulation
//! (output) error** `J = mean_k (y(k) - yhat(k))^2` over the record, where
//! `yhat` is the model's event-aware free-run simulation
//! ([`mod@hysid_graybox::simulate`]) from the state estimated on the first
//! samples. The search runs in box-normalised coordinates
//! ([`parameters`]):
//!
//! 1. a global stage ([`swarm`]): argmin's particle swarm (Kennedy and
//!    Eberhart 1995), seeded with `ChaCha8Rng::seed_from_u64(ctx.seed)`, in
//!    the bounds, on the segmented (multiple-shooting) error ([`objective`];
//!    the free-run one with `segment=0`), skipped where Levenberg-Marquardt
//!    from the nominal values already fits the record to its noise
//!    ([`swarm::nominal_suffices`]);
//! 2. local stages ([`local`]), on the segmented error and then on the
//!    free-run one: Levenberg-Marquardt (Marquardt 1963,
//!    [`hysid_numerics::least_squares`], on the exact Jacobian of the runs'
//!    forward sensitivities, or central differences in the unit box) from
//!    each start (the swarm's best, the
//!    nominal values, the next best particles), then Nelder-Mead (Nelder
//!    and Mead 1965, [`hysid_numerics::nelder_mead`]: argmin's iterates,
//!    each step's second point guessed and evaluated beside the first on
//!    the free-run cost) from the best point, restarted with a fresh
//!    simplex a few times (bounded iterations each) until a run lowers
//!    nothing.
//!
//! The fitted model carries the parameters (with their bounds), the final
//! cost, and a local sensitivity / confidence estimate from the same
//! Jacobian of the residuals (Gauss-Newton covariance
//! `s^2 (J^T J)^-1`, [`sensitivity`]), in `info.diagnostics`
//! ([`PhysicalDiagnostics`]).
//!
//! Priors: `[fixed]`, `[bounds]` and `[[tie]]` on the model's parameter
//! names. `--na`/`--nb` are ignored. [`bridge`] converts the fitted model
//! into per-mode discrete-time affine (PWARX) form.

pub mod bridge;
pub mod diagnostics;
pub mod fit;
pub mod identifiability;
pub mod local;
pub mod mechanical;
pub mod objective;
pub mod parameters;
pub mod sensitivity;
pub mod stages;
pub mod swarm;
pub mod target;

pub use diagnostics::PhysicalDiagnostics;
pub use fit::{FitReport, fit_model};
pub use parameters::ParameterMap;
pub use target::{GrayBoxTarget, Simulator, Target};

use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::model::{Model, SignalNames, to_gray_box};
use hysid_core::options::{CheckOptions, Checked, OptionError, check_count};
use hysid_core::priors::{PriorKind, Priors};
use hysid_mechanical::MechanicalModel;
use hysid_model::regressors::RegressorSpec;
use std::path::Path;

/// The mounting-head model (`models/pick-and-place/head.toml`), for
/// examples and tests; the back-end fits only the file its `model` option
/// names.
pub const HEAD_MODEL_TOML: &str = include_str!("../models/head.toml");

/// The mounting-head model, parsed.
pub fn head_model() -> MechanicalModel {
    match Model::from_toml(HEAD_MODEL_TOML, "head.toml (built in)") {
        Ok(Model::Mechanical(m)) => m,
        _ => unreachable!("the built-in head model is a valid mechanical model (tested)"),
    }
}

hysid_core::backend_options! {
    /// Options of the `physical` back-end.
    pub struct PhysicalOptions {
        /// Path of the model file (TOML or JSON, a mechanical or a gray-box model) whose
        /// parameters are fitted; required (the pick-and-place head:
        /// models/pick-and-place/head.toml).
        model: String = String::new(),
        /// Particles of the swarm (global stage); 0 skips the global stage.
        particles: usize = 24,
        /// The swarm is skipped where Levenberg-Marquardt from the nominal values ends by
        /// its own tests at a free-run cost of at most this multiple of the estimated
        /// output noise variance: the nominal start already explains the record to its
        /// noise. 0: the swarm always runs.
        swarm_skip: f64 = 1.5,
        /// Independent searches (swarm, then the local stages), each from its own seed
        /// (the first from the run's seed); the one of least free-run cost on the rows is
        /// kept. The cost is multimodal on real records, and the seed picks the minimum.
        swarms: usize = 1,
        /// Iterations of the swarm.
        swarm_iters: usize = 40,
        /// Iterations of each Nelder-Mead run (local refinement).
        local_iters: usize = 400,
        /// Nelder-Mead runs at most, each restarted from the previous best with a fresh
        /// simplex, until one lowers nothing; 0: the local stages are Levenberg-Marquardt
        /// alone.
        restarts: usize = 3,
        /// Segment length (samples) of the multiple-shooting cost used by the swarm and
        /// the first local stage: each segment is simulated from the state measured at
        /// its start, which smooths the cost; 0: free-run cost only.
        segment: usize = 100,
        /// Starts of the first local stage: the swarm's best, the nominal values and the
        /// next best particles.
        starts: usize = 6,
        /// Iterations of the Levenberg-Marquardt step that opens each local stage; 0
        /// skips it.
        lm_iters: usize = 30,
        /// Levenberg-Marquardt and the confidence estimate use the exact Jacobian of the
        /// residuals, from the runs' forward sensitivities, where the model gives one (a
        /// model without a fitted delay); false, or a model without one: central
        /// differences of `fd_step`.
        exact_jacobian: bool = true,
        /// Initial simplex size, as a fraction of each parameter's range.
        simplex: f64 = 0.05,
        /// Samples used to estimate the initial state (position and velocity) of the
        /// simulation from the measured outputs; the cost is scored after them. 0: the
        /// model file's rule (its `samples`, or its given state).
        init_samples: usize = 0,
        /// Step (fraction of each range) of the central finite-difference Jacobians of
        /// the Levenberg-Marquardt stages and of the sensitivity and confidence estimate,
        /// where they are not exact (`exact_jacobian`).
        fd_step: f64 = 1e-3,
    }
}

/// Largest `swarms` accepted.
pub const MAX_SWARMS: usize = 100;

impl CheckOptions for PhysicalOptions {
    fn check(&self) -> Result<(), OptionError> {
        if self.model.trim().is_empty() {
            return Err(OptionError::Missing {
                key: "model",
                method: Physical::NAME,
                what: "the file of the model whose parameters it fits (docs/gray-box-models.md)",
                forms: &["FILE", "models/pick-and-place/head.toml"],
            });
        }
        if !(1..=MAX_SWARMS).contains(&self.swarms) {
            return Err(OptionError::invalid(
                "swarms",
                self.swarms,
                format!("must be in 1..={MAX_SWARMS}"),
            ));
        }
        check_count("particles", self.particles, 0)?;
        check_count("starts", self.starts, 0)?;
        check_count("restarts", self.restarts, 0)?;
        if !(self.swarm_skip.is_finite() && self.swarm_skip >= 0.0) {
            return Err(OptionError::invalid(
                "swarm_skip",
                self.swarm_skip,
                "must be a finite number >= 0",
            ));
        }
        if !(self.simplex > 0.0 && self.simplex <= 1.0) {
            return Err(OptionError::invalid(
                "simplex",
                self.simplex,
                "must be in (0, 1]",
            ));
        }
        if !(self.fd_step > 0.0 && self.fd_step < 0.5) {
            return Err(OptionError::invalid(
                "fd_step",
                self.fd_step,
                "must be in (0, 0.5)",
            ));
        }
        Ok(())
    }
}

/// The `physical` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Physical;

impl Identifier for Physical {
    type Options = PhysicalOptions;
    const NAME: &'static str = "physical";
    const SUMMARY: &'static str = "physical parameters of a mechanical or gray-box hybrid model (--set model=FILE) by simulation error: swarm + Levenberg-Marquardt + Nelder-Mead";
    const HONOURS: &'static [PriorKind] = &[PriorKind::Fixed, PriorKind::Bounds, PriorKind::Tie];

    fn declared_signals(&self, options: &PhysicalOptions) -> Result<SignalNames, IdentifyError> {
        let file = options.model.trim();
        if file.is_empty() {
            return Ok(SignalNames::default());
        }
        let model = Model::load(Path::new(file)).map_err(|e| {
            IdentifyError::Options(OptionError::invalid("model", &options.model, e.to_string()))
        })?;
        Ok(model.signal_names())
    }

    fn check_priors(
        &self,
        options: &PhysicalOptions,
        priors: &Priors,
        _orders: RegressorSpec,
        origin: Option<&str>,
    ) -> Result<(), IdentifyError> {
        if options.model.trim().is_empty() {
            return Ok(());
        }
        let (target, _) = target_of(options, priors, origin)?;
        // The priors name parameters, not the records' initial states: one
        // record checks them as any number would.
        ParameterMap::new(&target, priors, 1)
            .map(|_| ())
            .map_err(|p| IdentifyError::prior_mismatch(origin, p))
    }

    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &Checked<PhysicalOptions>,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let (target, back_into) = target_of(options, problem.priors, problem.priors_origin)?;
        let (fitted, _) = fit_model(&target, problem.data, problem.priors, options, ctx)
            .map_err(|e| in_file(e, options, problem.priors_origin))?;
        Ok(match back_into {
            Some(m) => Model::Mechanical(mechanical::fitted(m, fitted.model)),
            None => Model::GrayBox(fitted.model),
        })
    }
}

/// The gray-box model the model file of `options` is fitted as, and the
/// mechanical model to write the fit back into where the file holds one
/// (checked under `priors`, named by `origin`).
fn target_of(
    options: &PhysicalOptions,
    priors: &Priors,
    origin: Option<&str>,
) -> Result<(GrayBoxTarget, Option<MechanicalModel>), IdentifyError> {
    let model = Model::load(Path::new(options.model.trim())).map_err(|e| {
        IdentifyError::Options(OptionError::invalid("model", &options.model, e.to_string()))
    })?;
    let model_error = |e: Box<dyn std::error::Error + Send + Sync>| {
        in_file(PhysicalError::Model(e).into(), options, origin)
    };
    // A mechanical model is fitted as its gray-box form and written
    // back (`mechanical`).
    let (gray, back_into) = match model {
        Model::Mechanical(m) => {
            let m = mechanical::with_warmup(m, options.init_samples);
            mechanical::check_under_priors(&m, priors)
                .map_err(|p| IdentifyError::prior_mismatch(origin, p))?;
            (to_gray_box(&m).map_err(|e| model_error(e.into()))?, Some(m))
        }
        Model::GrayBox(g) => (g, None),
        other => {
            return Err(IdentifyError::Options(OptionError::invalid(
                "model",
                &options.model,
                format!(
                    "a '{}' model; the physical method fits a 'mechanical' or a 'gray_box' one",
                    other.kind()
                ),
            )));
        }
    };
    let target = GrayBoxTarget::new(gray).map_err(|e| model_error(e.into()))?;
    Ok((target, back_into))
}

/// `e` with a model file's structural problems naming the file (the
/// `model` option) and priors that do not fit its parameters naming the
/// prior file `origin`.
fn in_file(e: IdentifyError, options: &PhysicalOptions, origin: Option<&str>) -> IdentifyError {
    match e.downcast_ref::<PhysicalError>() {
        Some(PhysicalError::Model(problem)) => IdentifyError::Options(OptionError::invalid(
            "model",
            options.model.trim(),
            problem.to_string(),
        )),
        Some(PhysicalError::Parameters(p)) => IdentifyError::prior_mismatch(origin, p.clone()),
        _ => e,
    }
}

/// Where the free run at a model file's own values diverges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NominalDivergence {
    /// The record, counted from 1, where the data hold several.
    pub record: Option<usize>,
    /// Where and how the output diverged.
    pub divergence: hysid_model::simulate::Divergence,
}

impl std::fmt::Display for NominalDivergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(r) = self.record {
            write!(f, "on record {r}, ")?;
        }
        self.divergence.fmt(f)
    }
}

/// Bad input of the `physical` back-end (an [`IdentifyError::Input`]).
#[derive(Debug, thiserror::Error)]
pub enum PhysicalError {
    /// The mechanical model is inconsistent, or its internal step does not
    /// fit the sampling time.
    #[error("model: {0}")]
    Model(Box<dyn std::error::Error + Send + Sync>),
    /// Model and record with different numbers of inputs.
    #[error("the model has {model} input(s), the data {data}")]
    InputCount {
        /// Inputs of the model.
        model: usize,
        /// Inputs of the record.
        data: usize,
    },
    /// A record without sampling time.
    #[error(
        "the physical method needs the sampling time: name the record's time column (--time NAME; \
         't' when left out) or give the sampling time (--ts SECONDS; in Python, ts=)"
    )]
    NoSamplingTime,
    /// No simulation of the search ran, and the model's own values fail on
    /// the first record with a fault of the model (a transition into a
    /// mode whose invariant it leaves, a rule it cannot meet).
    #[error(
        "{}the model fails on this record at its own values: {source}",
        if file.is_empty() { String::new() } else { format!("{file}: ") }
    )]
    ModelFails {
        /// The model file (`model`; empty for the built-in head).
        file: String,
        /// The fault.
        source: hysid_model::simulate::SimError,
    },
    /// Nothing in the model is free to fit, and its free run diverges.
    #[error(
        "{}nothing in the model is free to fit, and at its own values, {nominal}",
        if file.is_empty() { String::new() } else { format!("{file}: ") }
    )]
    DivergesWithNothingFree {
        /// The model file (`model`; empty for the built-in head).
        file: String,
        /// Where the free run diverges.
        nominal: NominalDivergence,
    },
    /// Fewer samples than the free parameters and the initial state need.
    #[error(
        "{samples} samples for {params} free parameters and the initial state: need at least \
         {needed}{}",
        if *warmup > 0 {
            format!(" (its warm-up reads {warmup}: the model file's rule, or init_samples)")
        } else {
            String::new()
        }
    )]
    TooFewSamples {
        /// Samples of the record.
        samples: usize,
        /// Free parameters.
        params: usize,
        /// The samples the initial state reads.
        warmup: usize,
        /// Samples needed.
        needed: usize,
    },
    /// A record of a joined dataset with no sample after its initial state.
    #[error("record {record} has {samples} samples; the initial state reads {initial}: need more")]
    ShortRecord {
        /// The record, counted from 1.
        record: usize,
        /// Its samples.
        samples: usize,
        /// Samples the initial state reads.
        initial: usize,
    },
    /// Priors that do not fit the model's parameters.
    #[error(transparent)]
    Parameters(#[from] parameters::ParameterError),
}

impl From<PhysicalError> for IdentifyError {
    fn from(e: PhysicalError) -> Self {
        match e {
            PhysicalError::TooFewSamples { .. } => IdentifyError::too_few_samples(e),
            e => IdentifyError::input(e),
        }
    }
}
