//! What a fit reports in the model's `info.diagnostics`: costs, evaluation
//! count, why each stage stopped, a status when the result may not be
//! converged, and per parameter its value, standard error, 95 % interval,
//! sensitivity and identifiability.

use crate::identifiability::Identifiability;
use crate::parameters::ParameterMap;
use crate::sensitivity::{JacobianKind, Sensitivity};
use crate::stages::{Stage, StageLog, Termination};
use hysid_model::model::RunStatus;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// Definition of [`PhysicalDiagnostics::cost`].
pub const COST_DEFINITION: &str = "mean squared free-run simulation error after the initial state";

/// Method of [`PhysicalDiagnostics::parameters`]' standard errors.
pub const CONFIDENCE_METHOD: &str = "Gauss-Newton s^2 (J^T J)^-1 from a central finite-difference Jacobian of the simulation residuals; local, and optimistic since the residuals are correlated";

/// [`CONFIDENCE_METHOD`] on the exact Jacobian of the run's forward
/// sensitivities.
pub const CONFIDENCE_METHOD_EXACT: &str = "Gauss-Newton s^2 (J^T J)^-1 from the exact Jacobian of the simulation residuals (forward sensitivities); local, and optimistic since the residuals are correlated";

/// [`PhysicalDiagnostics::confidence_method`] where the time budget ran
/// out before the Jacobian.
pub const CONFIDENCE_NOT_COMPUTED: &str =
    "none: the time budget ran out before the Jacobian of the standard errors";

/// The confidence method of a Jacobian of kind `kind`.
pub fn confidence_method(kind: JacobianKind) -> &'static str {
    match kind {
        JacobianKind::Exact => CONFIDENCE_METHOD_EXACT,
        JacobianKind::CentralDifferences => CONFIDENCE_METHOD,
        JacobianKind::NotComputed => CONFIDENCE_NOT_COMPUTED,
    }
}

/// The diagnostics of a `physical` fit (the keys of `info.diagnostics`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhysicalDiagnostics {
    /// Final cost: mean squared free-run simulation error.
    pub cost: f64,
    /// With `swarms > 1`: the search kept (0: the one seeded by the run's
    /// seed), the one of least `cost`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub swarm_kept: Option<usize>,
    /// [`COST_DEFINITION`].
    pub cost_definition: String,
    /// `sqrt(cost)`.
    pub rmse_fit: f64,
    /// Cost of the nominal values; `None` where they could not be
    /// simulated on the record.
    pub nominal_cost: Option<f64>,
    /// Best cost of the particle swarm (on its own, segmented, cost), when it ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub swarm_cost: Option<f64>,
    /// Why the swarm did not run, when [`crate::swarm::nominal_suffices`]
    /// skipped it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub swarm_skipped: Option<SwarmSkipped>,
    /// Best cost of the segmented local stage, when it ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segmented_cost: Option<f64>,
    /// Segment length of the segmented local stage, when it ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segment: Option<usize>,
    /// Simulations run.
    pub evaluations: u64,
    /// Why each stage stopped.
    pub termination: Terminations,
    /// Output noise standard deviation, estimated from second differences.
    pub noise_estimate: f64,
    /// Free coordinates (tied parameters share one).
    pub free_parameters: usize,
    /// Per non-fixed parameter name.
    pub parameters: BTreeMap<String, ParameterDiagnostics>,
    /// The initial states the model leaves unknown (`estimate`), as fitted
    /// with the parameters: nuisance parameters of this record, not written
    /// into the model (whose rule estimates them again on every record).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub initial_states: BTreeMap<String, f64>,
    /// [`confidence_method`] of `jacobian`.
    pub confidence_method: String,
    /// The Jacobian of the confidence estimate.
    #[serde(default)]
    pub jacobian: JacobianKind,
    /// `sqrt` of the condition number of `J^T J` ([`Sensitivity::condition`];
    /// `None` when not computed or infinite).
    pub jacobian_condition: Option<f64>,
    /// Parameters with zero sensitivity ([`Sensitivity::insensitive`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub zero_sensitivity: Vec<String>,
    /// Parameters at a bound ([`ParameterMap::at_bound`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub at_bound: Vec<String>,
    /// Estimated initial states at a bound of their estimate
    /// ([`ParameterMap::initial_states_at_bound`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub initial_states_at_bound: Vec<String>,
}

impl PhysicalDiagnostics {
    /// The diagnostics of a `physical` fit as its model file holds them
    /// (the method's fields of `d`); `None` for another back-end's.
    pub fn of(d: &hysid_model::model::Diagnostics) -> Option<Self> {
        let fields = serde_json::Map::from_iter(d.method.clone());
        serde_json::from_value(serde_json::Value::Object(fields)).ok()
    }

    /// What a user should be told about the fit beside its model, one
    /// line each: parameters and estimated initial states that ended at a
    /// bound (the record may ask for values outside them), parameters the
    /// identification rows do not determine, and parameters without a
    /// standard error.
    pub fn warnings(&self) -> Vec<String> {
        let with = |names: &[String]| {
            let values: Vec<String> = names
                .iter()
                .map(|n| {
                    let value = (self.parameters.get(n).map(|p| p.value))
                        .or_else(|| self.initial_states.get(n).copied());
                    value.map_or_else(|| n.clone(), |v| format!("{n} = {v}"))
                })
                .collect();
            values.join(", ")
        };
        let named = |kind: Identifiability| -> Vec<String> {
            (self.parameters.iter())
                .filter(|(_, p)| p.identifiability == Some(kind))
                .map(|(n, _)| n.clone())
                .collect()
        };
        let mut out = Vec::new();
        // A parameter without effect is kept at its file value, which may
        // be a bound: it is named once, as without effect.
        let at_bound: Vec<String> = (self.at_bound.iter())
            .filter(|n| {
                let p = self.parameters.get(*n);
                p.is_none_or(|p| p.identifiability != Some(Identifiability::NotIdentifiable))
            })
            .cloned()
            .collect();
        if !at_bound.is_empty() {
            out.push(format!(
                "{} ended at a bound: the record may ask for a value outside the bounds (widen them, or check the model and its units)",
                with(&at_bound)
            ));
        }
        if !self.initial_states_at_bound.is_empty() {
            out.push(format!(
                "the estimated initial state {} ended at a bound of its estimate: the record may ask for a value outside it",
                with(&self.initial_states_at_bound)
            ));
        }
        let unseen = named(Identifiability::NotIdentifiable);
        if !unseen.is_empty() {
            out.push(format!(
                "{}: no effect on the identification rows; kept at the file's values",
                unseen.join(", ")
            ));
        }
        let no_error = named(Identifiability::NoStandardError);
        if !no_error.is_empty() {
            let why = match self.jacobian {
                JacobianKind::NotComputed => "the time budget ran out before the Jacobian",
                _ => {
                    "a singular Jacobian: parameters that act only together, such as a product, or a failed perturbed run"
                }
            };
            out.push(format!(
                "{}: no standard error ({why})",
                no_error.join(", ")
            ));
        }
        out
    }
}

/// The swarm was skipped: Levenberg-Marquardt from the nominal values
/// ended at a free-run cost `nominal_descent_cost` of at most `noise_floor`
/// (`swarm_skip` times the estimated noise variance).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SwarmSkipped {
    /// Free-run cost at the end of Levenberg-Marquardt from the nominal values.
    pub nominal_descent_cost: f64,
    /// The cost below which the swarm is skipped.
    pub noise_floor: f64,
}

/// Why each stage stopped: the termination of the swarm, how many runs of
/// each local method ended each way, and the last local run's.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Terminations {
    /// The particle swarm, when it ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub particle_swarm: Option<Termination>,
    /// Levenberg-Marquardt runs per termination.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub levenberg_marquardt: BTreeMap<Termination, u64>,
    /// Nelder-Mead runs per termination.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub nelder_mead: BTreeMap<Termination, u64>,
    /// The last local run (the final Nelder-Mead run, on the free-run
    /// cost), which decides whether the result counts as converged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_local_run: Option<Termination>,
}

impl Terminations {
    /// The counts of `log`.
    pub fn of(log: &StageLog) -> Self {
        let counts = |runs: &[Termination]| {
            let mut m = BTreeMap::new();
            for &t in runs {
                *m.entry(t).or_insert(0) += 1;
            }
            m
        };
        Terminations {
            particle_swarm: log.particle_swarm,
            levenberg_marquardt: counts(&log.levenberg_marquardt),
            nelder_mead: counts(&log.nelder_mead),
            last_local_run: log.nelder_mead.last().copied(),
        }
    }
}

/// One free parameter's estimate (tied parameters share it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterDiagnostics {
    /// Fitted value.
    pub value: f64,
    /// Standard error, when estimable.
    pub std_error: Option<f64>,
    /// `|std_error / value|`, when estimable and the value is not 0.
    pub relative_std_error: Option<f64>,
    /// `value -+ 1.96 std_error`, when estimable.
    pub ci95: Option<[f64; 2]>,
    /// RMS change of the output per relative change of the parameter
    /// (`None` when not finite).
    pub sensitivity: Option<f64>,
    /// What the identification rows determine about it (why a standard
    /// error is missing).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identifiability: Option<Identifiability>,
}

impl ParameterDiagnostics {
    /// From the value `value`, standard error `se` (NaN: not estimable),
    /// sensitivity `sensitivity` and what the rows determine.
    pub fn new(value: f64, se: f64, sensitivity: f64, identifiability: Identifiability) -> Self {
        let estimable = se.is_finite();
        ParameterDiagnostics {
            value,
            std_error: estimable.then_some(se),
            relative_std_error: (estimable && value != 0.0).then(|| (se / value).abs()),
            ci95: estimable.then_some([value - 1.96 * se, value + 1.96 * se]),
            sensitivity: Some(sensitivity).filter(|s| s.is_finite()),
            identifiability: Some(identifiability),
        }
    }
}

/// Why a fit's result may not be converged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The time budget ran out during `stage`, after `evaluations` simulations.
    TimeBudget {
        /// The stage cut short.
        stage: Stage,
        /// Simulations run.
        evaluations: u64,
    },
    /// The last Nelder-Mead run stopped at its iteration limit `local_iters`.
    IterationLimit {
        /// The limit.
        local_iters: usize,
    },
}

impl Status {
    /// The status of a fit whose stages ended as `log` says: the time
    /// budget first, then the last local run's iteration limit.
    pub fn of(log: &StageLog, evaluations: u64, local_iters: usize) -> Option<Self> {
        if let Some(stage) = log.cut_short {
            Some(Status::TimeBudget { stage, evaluations })
        } else if log.nelder_mead.last() == Some(&Termination::MaxIterations) {
            Some(Status::IterationLimit { local_iters })
        } else {
            None
        }
    }
}

impl Status {
    /// How the run ended.
    pub fn run_status(self) -> RunStatus {
        match self {
            Status::TimeBudget { .. } => RunStatus::TimeBudget,
            Status::IterationLimit { .. } => RunStatus::IterationLimit,
        }
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Status::TimeBudget { stage, evaluations } => write!(
                f,
                "time budget reached during the {} stage after {evaluations} simulations: best parameters found by then",
                stage.name()
            ),
            Status::IterationLimit { local_iters } => write!(
                f,
                "iteration limit reached: the last Nelder-Mead run stopped at local_iters = {local_iters} before its convergence test held; the parameters may not be converged (raise local_iters)"
            ),
        }
    }
}

impl PhysicalDiagnostics {
    /// Per parameter name, the estimate of its free coordinate in `map` at
    /// `values`, with the standard errors and sensitivities of `sens`.
    pub fn parameters(
        map: &ParameterMap,
        values: &[f64],
        sens: &Sensitivity,
        identifiability: &[Identifiability],
    ) -> BTreeMap<String, ParameterDiagnostics> {
        let mut out = BTreeMap::new();
        for (gi, g) in map.groups.iter().enumerate() {
            if map.is_initial_state(gi) {
                continue;
            }
            let entry = ParameterDiagnostics::new(
                values[g[0]],
                sens.std_errors[gi],
                sens.sensitivity[gi],
                identifiability[gi],
            );
            for &i in g {
                out.insert(map.names[i].clone(), entry.clone());
            }
        }
        out
    }

    /// The entries of `info.diagnostics`, one per field (absent options
    /// and empty lists left out).
    pub fn into_map(self) -> BTreeMap<String, serde_json::Value> {
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(m)) => m.into_iter().collect(),
            _ => unreachable!("a struct of numbers, strings, lists and maps is a JSON object"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn log() -> StageLog {
        StageLog {
            particle_swarm: Some(Termination::MaxIterations),
            levenberg_marquardt: vec![
                Termination::Converged,
                Termination::NoDecrease,
                Termination::Converged,
            ],
            nelder_mead: vec![Termination::Converged, Termination::MaxIterations],
            cut_short: None,
        }
    }

    #[test]
    fn terminations_are_counted_per_stage_under_their_names() {
        let t = serde_json::to_value(Terminations::of(&log())).unwrap();
        assert_eq!(
            t,
            json!({
                "particle_swarm": "max_iterations",
                "levenberg_marquardt": {"converged": 2, "no_decrease": 1},
                "nelder_mead": {"converged": 1, "max_iterations": 1},
                "last_local_run": "max_iterations",
            })
        );
        let empty = serde_json::to_value(Terminations::of(&StageLog::default())).unwrap();
        assert_eq!(empty, json!({}));
    }

    #[test]
    fn the_status_puts_the_time_budget_before_the_iteration_limit() {
        let mut l = log();
        assert_eq!(
            Status::of(&l, 7, 400),
            Some(Status::IterationLimit { local_iters: 400 })
        );
        l.cut_short = Some(Stage::LevenbergMarquardt);
        let s = Status::of(&l, 7, 400).unwrap();
        assert_eq!(
            s.to_string(),
            "time budget reached during the Levenberg-Marquardt stage after 7 simulations: best parameters found by then"
        );
        l.cut_short = None;
        l.nelder_mead.push(Termination::Converged);
        assert_eq!(Status::of(&l, 7, 400), None);
    }

    #[test]
    fn diagnostics_round_trip_and_leave_out_what_is_absent() {
        let d = PhysicalDiagnostics {
            cost: 0.25,
            cost_definition: COST_DEFINITION.into(),
            rmse_fit: 0.5,
            nominal_cost: Some(1.0),
            swarm_cost: None,
            swarm_skipped: None,
            segmented_cost: None,
            segment: None,
            evaluations: 12,
            termination: Terminations::of(&log()),
            noise_estimate: 0.0,
            free_parameters: 2,
            parameters: [
                (
                    "a".to_string(),
                    ParameterDiagnostics::new(2.0, 0.5, 1.5, Identifiability::Estimated),
                ),
                (
                    "b".to_string(),
                    ParameterDiagnostics::new(
                        0.0,
                        f64::NAN,
                        f64::NAN,
                        Identifiability::NoStandardError,
                    ),
                ),
            ]
            .into(),
            initial_states: BTreeMap::new(),
            confidence_method: CONFIDENCE_METHOD.into(),
            jacobian: JacobianKind::CentralDifferences,
            jacobian_condition: None,
            zero_sensitivity: vec![],
            at_bound: vec!["b".into()],
            initial_states_at_bound: vec![],
            swarm_kept: None,
        };
        let map = d.clone().into_map();
        let keys: Vec<&str> = map.keys().map(|k| k.as_str()).collect();
        assert_eq!(
            keys,
            [
                "at_bound",
                "confidence_method",
                "cost",
                "cost_definition",
                "evaluations",
                "free_parameters",
                "jacobian",
                "jacobian_condition",
                "noise_estimate",
                "nominal_cost",
                "parameters",
                "rmse_fit",
                "termination"
            ]
        );
        assert_eq!(
            map["parameters"]["a"],
            json!({"value": 2.0, "std_error": 0.5, "relative_std_error": 0.25, "ci95": [1.02, 2.98], "sensitivity": 1.5, "identifiability": "estimated"})
        );
        assert_eq!(
            map["parameters"]["b"],
            json!({"value": 0.0, "std_error": null, "relative_std_error": null, "ci95": null, "sensitivity": null, "identifiability": "no_standard_error"})
        );
        let back: PhysicalDiagnostics =
            serde_json::from_value(serde_json::Value::Object(map.into_iter().collect())).unwrap();
        assert_eq!(back, d);
        // Read back from a model's diagnostics, and told as warnings.
        let common = hysid_model::model::Diagnostics::default().with_method(&d);
        assert_eq!(PhysicalDiagnostics::of(&common), Some(d.clone()));
        assert_eq!(
            d.warnings(),
            [
                "b = 0 ended at a bound: the record may ask for a value outside the bounds (widen them, or check the model and its units)",
                "b: no standard error (a singular Jacobian: parameters that act only together, such as a product, or a failed perturbed run)",
            ]
        );
        assert_eq!(
            PhysicalDiagnostics::of(&hysid_model::model::Diagnostics::default()),
            None
        );
    }
}
