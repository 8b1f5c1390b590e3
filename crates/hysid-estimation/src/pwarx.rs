//! The set-up and the assembly every PWARX back-end shares, so that a
//! back-end's `fit` holds only its method's steps.
//!
//! [`prepare`] checks the prior names against the regressors once, builds
//! the regressors of the record, splits off the samples whose target sits
//! at a known stop (Juloski, Heemels, Ferrari-Trecate 2003, section 5: the
//! saturation modes live on lower-dimensional guard sets and are not
//! identified), resolves the switching regressors and the mode count.
//! [`assemble`] turns the ordinary modes a back-end found into the model
//! file: a PWARX model, or with stops the hybrid automaton of
//! `HybridAutomaton::from_pwarx_with_stops`, with the common diagnostics
//! under their fixed names.

use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_model::data::Standardization;
use hysid_model::model::RunStatus;
use hysid_model::model::{
    Diagnostics, HybridAutomaton, ModelInfo, PwarxMode, PwarxModel, Refinement,
};
use hysid_model::regressors::{RegressorSpec, Regressors};
use serde::Serialize;

/// How many ordinary (non-saturation) modes the priors ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeCount {
    /// Exactly this many (`modes` minus the stops).
    Exact(usize),
    /// At most this many (`max_modes` minus the stops).
    AtMost(usize),
    /// The method decides.
    Free,
}

impl ModeCount {
    /// The exact count, if one is asked for.
    pub fn exact(self) -> Option<usize> {
        match self {
            ModeCount::Exact(s) => Some(s),
            _ => None,
        }
    }

    /// The largest count allowed, if bounded.
    pub fn at_most(self) -> Option<usize> {
        match self {
            ModeCount::Exact(s) | ModeCount::AtMost(s) => Some(s),
            ModeCount::Free => None,
        }
    }
}

/// The identification data of a PWARX back-end after the common set-up,
/// in data units.
#[derive(Debug, Clone)]
pub struct PwarxData<'a> {
    /// The problem as given.
    pub problem: Problem<'a>,
    /// Orders and inputs.
    pub spec: RegressorSpec,
    /// Every regression row of the record.
    pub regressors: Regressors,
    /// For every regression row, the known stop its target sits at.
    pub stop_of: Vec<Option<usize>>,
    /// The rows whose target sits at no stop: the samples the method
    /// identifies its modes from.
    pub ordinary: Vec<usize>,
    /// Ordinary modes asked for.
    pub modes: ModeCount,
    /// Regressor columns the region boundaries may use (`switching`,
    /// sorted, without repeats); `None`: all of them.
    pub switching: Option<Vec<usize>>,
}

impl PwarxData<'_> {
    /// The priors.
    pub fn priors(&self) -> &Priors {
        self.problem.priors
    }

    /// Number of known stops.
    pub fn stops(&self) -> usize {
        self.problem.priors.saturation.len()
    }

    /// The regressors and targets of the ordinary rows.
    pub fn ordinary_regressors(&self) -> Regressors {
        self.regressors.select(&self.ordinary)
    }

    /// Rows at each known stop, in prior order.
    pub fn saturated_per_stop(&self) -> Vec<usize> {
        let mut n = vec![0; self.stops()];
        for k in self.stop_of.iter().flatten() {
            n[*k] += 1;
        }
        n
    }

    /// A prior error worded with the file the priors came from.
    pub fn prior_error(&self, message: impl std::fmt::Display) -> IdentifyError {
        prior_error(&self.problem, message)
    }
}

fn prior_error(problem: &Problem<'_>, message: impl std::fmt::Display) -> IdentifyError {
    IdentifyError::BadData(match problem.priors_origin {
        Some(origin) => format!("{origin}: {message}"),
        None => format!("prior {message}"),
    })
}

/// The common set-up of `method` on `problem` (see the module doc).
pub fn prepare<'a>(problem: &Problem<'a>, method: &str) -> Result<PwarxData<'a>, IdentifyError> {
    let spec = problem.orders;
    let priors = problem.priors;
    priors
        .check_pwarx_names(&spec)
        .map_err(|e| prior_error(problem, e))?;
    let regressors = spec
        .build(problem.data)
        .map_err(|e| IdentifyError::BadData(e.to_string()))?;
    if let Some(v) = regressors
        .x
        .iter()
        .chain(regressors.y.iter())
        .find(|v| !v.is_finite())
    {
        return Err(IdentifyError::BadData(format!(
            "the data hold a non-finite value ({v})"
        )));
    }
    let stop_of = priors.saturated_samples(regressors.y.as_slice());
    let ordinary: Vec<usize> = (0..regressors.len())
        .filter(|&k| stop_of[k].is_none())
        .collect();
    if ordinary.is_empty() && !stop_of.is_empty() {
        return Err(IdentifyError::BadData(format!(
            "all {} samples sit at a known stop: no ordinary sample is left to identify",
            stop_of.len()
        )));
    }
    Ok(PwarxData {
        problem: *problem,
        spec,
        modes: mode_count(priors, method)?,
        switching: switching_columns(priors, &spec),
        regressors,
        stop_of,
        ordinary,
    })
}

/// `modes` and `max_modes` count every mode, the stops included; the
/// ordinary modes are what is left, at least one.
fn mode_count(priors: &Priors, method: &str) -> Result<ModeCount, IdentifyError> {
    let stops = priors.saturation.len();
    let too_few = |key: &str, s: usize| {
        IdentifyError::BadData(format!(
            "prior {key} = {s}: method '{method}' needs at least {} (the count includes the {stops} \
             saturation mode(s) of the priors, and one ordinary mode)",
            stops + 1
        ))
    };
    Ok(match (priors.modes, priors.max_modes) {
        (Some(s), _) if s <= stops => return Err(too_few("modes", s)),
        (_, Some(m)) if m <= stops => return Err(too_few("max_modes", m)),
        (Some(s), Some(m)) if s > m => {
            return Err(IdentifyError::BadData(format!(
                "prior modes = {s} exceeds max_modes = {m}"
            )));
        }
        (Some(s), _) => ModeCount::Exact(s - stops),
        (None, Some(m)) => ModeCount::AtMost(m - stops),
        (None, None) => ModeCount::Free,
    })
}

/// The regressor columns named by `switching`, sorted, without repeats.
fn switching_columns(priors: &Priors, spec: &RegressorSpec) -> Option<Vec<usize>> {
    if priors.switching.is_empty() {
        return None;
    }
    let names = spec.regressor_names();
    let mut cols: Vec<usize> = priors
        .switching
        .iter()
        .filter_map(|r| names.iter().position(|n| n == r))
        .collect();
    cols.sort_unstable();
    cols.dedup();
    Some(cols)
}

/// What a PWARX back-end's `fit` returns: its ordinary modes in data units
/// and how the run went.
#[derive(Debug, Clone)]
pub struct PwarxFit<D> {
    /// The ordinary modes: parameters and regions.
    pub modes: Vec<PwarxMode>,
    /// Whether the regions cover the regressor space.
    pub regions_complete: bool,
    /// Fraction of the identification regressors' box in no region, when
    /// the regions leave holes.
    pub uncovered_fraction: Option<f64>,
    /// How the run ended.
    pub run_status: RunStatus,
    /// Messages for the user (why the run was cut short, warnings).
    pub status: Vec<String>,
    /// How the back-end saw the data, when it worked in standardised units
    /// (recorded in the model's `info.scaling`).
    pub scaling: Option<Standardization>,
    /// The outcome of the simulation-error refinement, when it ran
    /// ([`crate::refine::refine`]; back-ends set `None`).
    pub refinement: Option<Refinement>,
    /// The back-end's own diagnostics.
    pub diagnostics: D,
}

/// The model of `fit` on `data`: a PWARX model, or with known stops the
/// automaton with a mode on each stop's guard set; the common diagnostics
/// filled in.
pub fn assemble<D: Serialize>(data: &PwarxData<'_>, fit: PwarxFit<D>) -> Model {
    let stops = data.stops();
    let diagnostics = Diagnostics {
        run_status: fit.run_status,
        status: fit.status,
        samples: Some(data.regressors.len()),
        modes: Some(fit.modes.len() + stops),
        regions_complete: Some(fit.regions_complete),
        uncovered_fraction_of_data_box: fit.uncovered_fraction,
        saturated_per_stop: (stops > 0).then(|| data.saturated_per_stop()),
        refinement: fit.refinement,
        ..Default::default()
    }
    .with_method(&fit.diagnostics);
    let model = PwarxModel {
        na: data.spec.na,
        nb: data.spec.nb,
        inputs: data.spec.inputs,
        modes: fit.modes,
        info: ModelInfo {
            diagnostics,
            scaling: fit.scaling,
            ..Default::default()
        },
    };
    if stops == 0 {
        Model::Pwarx(model)
    } else {
        let stops: Vec<_> = data.priors().saturation.clone();
        Model::HybridAutomaton(HybridAutomaton::from_pwarx_with_stops(&model, &stops))
    }
}

/// Runs `backend` on standardised data (zero mean, unit standard deviation
/// per signal) and returns the model in original units, with the statistics
/// recorded in `info.scaling`. Priors holding values in data units
/// (`[[saturation]]`, `[fixed]`, `[bounds]`, `[[equality]]`) and ties on the offset `c`
/// are refused here: their meaning would change with the scaling.
pub fn run_standardized(
    backend: &dyn Backend,
    problem: &Problem<'_>,
    settings: &Settings,
    ctx: &RunContext<'_>,
) -> Result<Model, IdentifyError> {
    let p = problem.priors;
    if !p.saturation.is_empty()
        || !p.fixed.is_empty()
        || !p.bounds.is_empty()
        || !p.equality.is_empty()
    {
        return Err(IdentifyError::BadData(
            "--standardize cannot be combined with priors in data units ([[saturation]], [fixed], [bounds], [[equality]])".into(),
        ));
    }
    // Scaling multiplies a tied a_i or b_i by one factor in every mode, so
    // such ties survive; the offset c maps to a combination of all the
    // parameters of its mode, so a tie on c would not.
    if p.tie.iter().any(|t| t.params.iter().any(|n| n == "c")) {
        return Err(IdentifyError::BadData(
            "--standardize cannot be combined with a [[tie]] on the offset c (it does not survive the back-transform)".into(),
        ));
    }
    let scale = Standardization::of(problem.data);
    let scaled = scale.apply(problem.data);
    let inner = Problem {
        data: &scaled,
        ..*problem
    };
    match backend.run(&inner, settings, ctx)? {
        Model::Pwarx(m) => Ok(Model::Pwarx(m.to_original_units(&scale))),
        other => Err(IdentifyError::BadData(format!(
            "--standardize: method '{}' returns a {} model, which cannot be mapped back to original units",
            backend.name(),
            other.kind()
        ))),
    }
}
