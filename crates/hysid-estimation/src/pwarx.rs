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
    Diagnostics, HybridAutomaton, ModelInfo, PwarxMode, PwarxModel, Refinement, Trimming,
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
    /// The exact number of ordinary modes, for a back-end that cannot
    /// choose it (`method` names it in the error).
    pub fn exact_modes(&self, method: &'static str) -> Result<usize, IdentifyError> {
        self.modes.exact().ok_or(IdentifyError::NeedsModeCount {
            method,
            bounded: false,
        })
    }

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

    /// Whether the priors constrain the mode parameters (`[[tie]]`,
    /// `[fixed]`, `[bounds]` or `[[equality]]`).
    pub fn constrains_parameters(&self) -> bool {
        let p = self.priors();
        !(p.tie.is_empty() && p.fixed.is_empty() && p.bounds.is_empty() && p.equality.is_empty())
    }

    /// A prior that does not fit this problem, named with the file the
    /// priors came from ([`IdentifyError::PriorMismatch`]).
    pub fn prior_error(
        &self,
        problem: impl std::error::Error + Send + Sync + 'static,
    ) -> IdentifyError {
        IdentifyError::prior_mismatch(self.problem.priors_origin, problem)
    }
}

/// A prior entry naming a parameter or regressor the PWARX structure does
/// not have.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{entry}: unknown name '{name}' (known: {})", known.join(", "))]
pub struct UnknownName {
    /// The entry (`[[tie]] params`, `[fixed]`, `switching`, ...).
    pub entry: String,
    /// The name.
    pub name: String,
    /// The names of that kind the structure has.
    pub known: Vec<String>,
}

/// Checks the parameter names of `[[tie]]`, `[[equality]]`, `[fixed]` and
/// `[bounds]`, and the regressor names of `switching`, against `spec`.
pub fn check_names(priors: &Priors, spec: &RegressorSpec) -> Result<(), UnknownName> {
    let params = spec.param_names();
    let regs = spec.regressor_names();
    let known = |n: &str, list: &[String], entry: &str| {
        if list.iter().any(|p| p == n) {
            Ok(())
        } else {
            Err(UnknownName {
                entry: entry.to_string(),
                name: n.to_string(),
                known: list.to_vec(),
            })
        }
    };
    for t in &priors.tie {
        for p in &t.params {
            known(p, &params, "[[tie]] params")?;
        }
    }
    for (i, e) in priors.equality.iter().enumerate() {
        for p in e.coefficients.keys() {
            known(p, &params, &format!("[[equality]] #{} coefficients", i + 1))?;
        }
    }
    for p in priors.fixed.keys() {
        known(p, &params, "[fixed]")?;
    }
    for p in priors.bounds.keys() {
        known(p, &params, "[bounds]")?;
    }
    for r in &priors.switching {
        known(r, &regs, "switching")?;
    }
    Ok(())
}

/// The known stop the output value `y` sits at ([`Stop::holds`]), if any.
///
/// [`Stop::holds`]: hysid_model::model::Stop::holds
pub fn stop_at(priors: &Priors, y: f64) -> Option<usize> {
    priors.saturation.iter().position(|s| s.holds(y))
}

/// For every regression target `y(k)`, the stop it sits at: the samples a
/// back-end assigns to the saturation modes before clustering or
/// bounded-error extraction (Juloski et al. 2003, section 5).
pub fn saturated_samples(priors: &Priors, targets: &[f64]) -> Vec<Option<usize>> {
    targets.iter().map(|&y| stop_at(priors, y)).collect()
}

/// The common set-up of `method` on `problem` (see the module doc).
pub fn prepare<'a>(problem: &Problem<'a>, method: &str) -> Result<PwarxData<'a>, IdentifyError> {
    let spec = problem.orders;
    let priors = problem.priors;
    check_names(priors, &spec)
        .map_err(|e| IdentifyError::prior_mismatch(problem.priors_origin, e))?;
    let regressors = spec.build(problem.data)?;
    if let Some(&value) = regressors
        .x
        .iter()
        .chain(regressors.y.iter())
        .find(|v| !v.is_finite())
    {
        return Err(IdentifyError::NonFinite { value });
    }
    let stop_of = saturated_samples(priors, regressors.y.as_slice());
    let ordinary: Vec<usize> = (0..regressors.len())
        .filter(|&k| stop_of[k].is_none())
        .collect();
    if ordinary.is_empty() && !stop_of.is_empty() {
        return Err(IdentifyError::AllAtStops {
            samples: stop_of.len(),
        });
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
    let too_few = |key: &'static str, count: usize| IdentifyError::NoOrdinaryMode {
        key,
        count,
        method: method.to_string(),
        stops,
    };
    Ok(match (priors.modes, priors.max_modes) {
        (Some(s), _) if s <= stops => return Err(too_few("modes", s)),
        (_, Some(m)) if m <= stops => return Err(too_few("max_modes", m)),
        (Some(modes), Some(max)) if modes > max => {
            return Err(IdentifyError::ModesExceedMax { modes, max });
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
    /// The outcome of the trimmed re-estimation, when it ran
    /// ([`crate::trim::trim`]; back-ends set `None`).
    pub trimming: Option<Trimming>,
    /// The back-end's own diagnostics.
    pub diagnostics: D,
}

impl<D> PwarxFit<D> {
    /// A finished fit whose regions cover the regressor space, with no
    /// message and no refinement yet: what a back-end with a complete
    /// partition by construction returns.
    pub fn complete(modes: Vec<PwarxMode>, diagnostics: D) -> Self {
        PwarxFit {
            modes,
            regions_complete: true,
            uncovered_fraction: None,
            run_status: RunStatus::Completed,
            status: Vec::new(),
            scaling: None,
            refinement: None,
            trimming: None,
            diagnostics,
        }
    }
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
        trimming: fit.trimming,
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
            // Named here, not only by `Backend::run`, so that an automaton
            // with stops takes the record's input names.
            input_names: data.problem.data.input_names(),
            ..Default::default()
        },
    };
    with_stops(data, model)
}

/// `model`, the ordinary modes, as the model file holds it: itself, or
/// with known stops the automaton with a mode on each stop's guard set.
fn with_stops(data: &PwarxData<'_>, model: PwarxModel) -> Model {
    if data.stops() == 0 {
        Model::Pwarx(model)
    } else {
        let stops = &data.priors().saturation;
        Model::HybridAutomaton(HybridAutomaton::from_pwarx_with_stops(&model, stops))
    }
}

/// The pipeline of a PWARX back-end whose `fit` estimates the ordinary
/// modes: the common set-up ([`prepare`]), `fit`, the trimmed
/// re-estimation ([`crate::trim::trim`]) and the simulation-error
/// refinement the options ask for ([`crate::refine::refine`]), and the
/// model with the known stops ([`assemble`]).
pub fn identify<D: Serialize>(
    problem: &Problem<'_>,
    method: &str,
    refinement: &crate::refine::RefineSettings,
    fit: impl FnOnce(&PwarxData<'_>) -> Result<PwarxFit<D>, IdentifyError>,
) -> Result<Model, IdentifyError> {
    let data = prepare(problem, method)?;
    let fit = finish(&data, fit(&data)?, refinement)?;
    Ok(assemble(&data, fit))
}

/// The stages after a back-end's fit, as its options ask: the trimmed
/// re-estimation ([`crate::trim::trim`]), then the simulation-error
/// refinement ([`crate::refine::refine`]).
pub fn finish<D>(
    data: &PwarxData<'_>,
    fit: PwarxFit<D>,
    settings: &crate::refine::RefineSettings,
) -> Result<PwarxFit<D>, IdentifyError> {
    let fit = crate::trim::trim(data, fit, settings.trim)?;
    crate::refine::refine(data, fit, settings)
}

/// `fitted`, a model [`identify`] returned on `problem` without a
/// refinement, refined as `refinement` asks without fitting it again:
/// the same model as [`identify`] with that refinement gives, since the
/// refinement starts from the fit alone. Automatic selection refines its
/// candidates' own fits this way. A model of another kind than
/// [`assemble`] writes, or one refined already, is refused.
pub fn refine_fitted(
    problem: &Problem<'_>,
    method: &str,
    fitted: Model,
    refinement: &crate::refine::RefineSettings,
) -> Result<Model, IdentifyError> {
    let data = prepare(problem, method)?;
    let mut pwarx = match fitted {
        Model::Pwarx(p) => p,
        Model::HybridAutomaton(a) => a.ordinary_pwarx().ok_or_else(|| {
            IdentifyError::failed("refinement: the automaton was not built from a PWARX model")
        })?,
        other => {
            return Err(IdentifyError::failed(format!(
                "refinement: a {} model is not a PWARX fit",
                other.kind()
            )));
        }
    };
    let diagnostics = &mut pwarx.info.diagnostics;
    if diagnostics.refinement.is_some() {
        return Err(IdentifyError::failed(
            "refinement: the model was refined when it was fitted",
        ));
    }
    let fit = PwarxFit {
        modes: std::mem::take(&mut pwarx.modes),
        regions_complete: diagnostics.regions_complete.unwrap_or(true),
        uncovered_fraction: diagnostics.uncovered_fraction_of_data_box,
        run_status: diagnostics.run_status,
        status: std::mem::take(&mut diagnostics.status),
        scaling: None,
        refinement: None,
        trimming: None,
        diagnostics: (),
    };
    let fit = crate::refine::refine(&data, fit, refinement)?;
    pwarx.modes = fit.modes;
    diagnostics.regions_complete = Some(fit.regions_complete);
    diagnostics.uncovered_fraction_of_data_box = fit.uncovered_fraction;
    diagnostics.run_status = fit.run_status;
    diagnostics.status = fit.status;
    diagnostics.refinement = fit.refinement;
    Ok(with_stops(&data, pwarx))
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
        return Err(IdentifyError::input(StandardizeError::PriorsInDataUnits));
    }
    // Scaling multiplies a tied a_i or b_i by one factor in every mode, so
    // such ties survive; the offset c maps to a combination of all the
    // parameters of its mode, so a tie on c would not.
    if p.tie.iter().any(|t| t.params.iter().any(|n| n == "c")) {
        return Err(IdentifyError::input(StandardizeError::TieOnOffset));
    }
    let scale = Standardization::of(problem.data);
    let scaled = scale.apply(problem.data);
    let inner = Problem {
        data: &scaled,
        ..*problem
    };
    let units = backend.output_units();
    let sigma = scale.output.std;
    let scaled_settings = in_output_units(settings, units, 1.0 / sigma);
    match backend.run(&inner, &scaled_settings, ctx)? {
        Model::Pwarx(m) => {
            let mut m = m.to_original_units(&scale);
            let info = &mut m.info;
            for key in units {
                if let Some(v) = info.diagnostics.method.get_mut(*key) {
                    rescale_json(v, sigma);
                }
                let given = settings.get(key).and_then(|v| v.parse::<f64>().ok());
                if let (Some(v), Some(x)) = (info.options.get_mut(*key), given) {
                    *v = serde_json::json!(x);
                }
            }
            Ok(Model::Pwarx(m))
        }
        other => Err(IdentifyError::input(StandardizeError::ModelKind {
            method: backend.name(),
            kind: other.kind(),
        })),
    }
}

/// `settings` with the numeric values of the `units` keys multiplied by
/// `factor` (other values, such as `delta=auto`, unchanged).
fn in_output_units(settings: &Settings, units: &[&str], factor: f64) -> Settings {
    let pairs = settings
        .pairs()
        .iter()
        .map(|(k, v)| match v.parse::<f64>() {
            Ok(x) if units.contains(&k.as_str()) => (k.clone(), format!("{:e}", x * factor)),
            _ => (k.clone(), v.clone()),
        })
        .collect();
    Settings::from_pairs(pairs)
}

/// Multiplies every number in `v` (a number or an array of them) by `factor`.
fn rescale_json(v: &mut serde_json::Value, factor: f64) {
    match v {
        serde_json::Value::Number(n) => {
            if let Some(x) = n
                .as_f64()
                .and_then(|x| serde_json::Number::from_f64(x * factor))
            {
                *n = x;
            }
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(|x| rescale_json(x, factor)),
        _ => {}
    }
}

/// Why [`run_standardized`] refuses a run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StandardizeError {
    /// Priors holding values in data units.
    #[error(
        "--standardize cannot be combined with priors in data units ([[saturation]], [fixed], [bounds], [[equality]])"
    )]
    PriorsInDataUnits,
    /// A `[[tie]]` on the offset `c`.
    #[error(
        "--standardize cannot be combined with a [[tie]] on the offset c (it does not survive the back-transform)"
    )]
    TieOnOffset,
    /// A back-end whose model has no original-units form.
    #[error(
        "--standardize: method '{method}' returns a {kind} model, which cannot be mapped back to original units"
    )]
    ModelKind {
        /// Back-end name.
        method: &'static str,
        /// Kind of the model it returned.
        kind: &'static str,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked_against_the_structure() {
        let p = Priors::from_toml(
            "switching = [\"y1\"]\n[[tie]]\nparams = [\"a1\", \"a2\"]\n[[equality]]\ncoefficients = { a1 = 1.0, a2 = 1.0 }\n[fixed]\nc = 0.0\n",
            "p.toml",
        )
        .unwrap();
        check_names(&p, &RegressorSpec::new(2, 2, 1)).unwrap();
        let e = check_names(&p, &RegressorSpec::new(1, 1, 1)).unwrap_err();
        assert_eq!(e.name, "a2");
        assert_eq!(
            e.to_string(),
            "[[tie]] params: unknown name 'a2' (known: a1, b1, c)"
        );
        let mut p = p;
        p.tie.clear();
        let e = check_names(&p, &RegressorSpec::new(1, 2, 1)).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("[[equality]] #1 coefficients: unknown name 'a2'"),
            "{e}"
        );
    }

    #[test]
    fn saturated_samples_by_level_side_and_tolerance() {
        let sat = Priors::from_toml(
            "[[saturation]]\nlevel = 25.0\nbound = \"max\"\ntol = 0.005\n[[saturation]]\nlevel = 0.0\nbound = \"min\"\n",
            "p",
        )
        .unwrap();
        assert_eq!(stop_at(&sat, 24.996), Some(0));
        assert_eq!(stop_at(&sat, 25.3), Some(0), "beyond the stop counts");
        assert_eq!(stop_at(&sat, 24.9), None);
        assert_eq!(stop_at(&sat, -0.1), Some(1));
        assert_eq!(stop_at(&sat, 1e-5), None, "default tolerance is 1e-6");
        assert_eq!(
            saturated_samples(&sat, &[3.0, 25.0, 0.0]),
            vec![None, Some(0), Some(1)]
        );
    }
}
