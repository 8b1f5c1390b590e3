//! Step 1 of the pipeline: the set-up every PWARX back-end shares.
//! [`prepare`] checks the prior names against the regressors once, builds
//! the regressors of the record, splits off the samples whose target sits
//! at a known stop (Juloski, Heemels, Ferrari-Trecate 2003, section 5: the
//! saturation modes live on lower-dimensional guard sets and are not
//! identified), and resolves the switching regressors and the mode count.

use crate::constrained::Parametrisation;
use hysid_core::backend::{IdentifyError, Problem};
use hysid_core::priors::Priors;
use hysid_model::regressors::{RegressorSpec, Regressors};

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
#[error("{entry}: unknown name '{}' (known: {})", name.escape_debug(), known.join(", "))]
pub struct UnknownName {
    /// The entry (`[[tie]] params`, `[fixed]`, `switching`, ...).
    pub entry: String,
    /// The name.
    pub name: String,
    /// The names of that kind the structure has.
    pub known: Vec<String>,
}

/// A `modes` prior that a method with a fixed number of ordinary modes
/// ([`super::PwarxMethod::ORDINARY_MODES`]) cannot meet.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "modes = {modes}: method '{method}' identifies exactly {} ordinary mode{}{}",
    if *.ordinary == 1 { "one".to_string() } else { .ordinary.to_string() },
    if *.ordinary == 1 { "" } else { "s" },
    if *.stops > 0 { format!(" (modes = {} with the {} saturation mode(s))", .ordinary + .stops, .stops) } else { String::new() }
)]
pub struct FixedModeCount {
    /// The method.
    pub method: &'static str,
    /// The prior's `modes`, stops included.
    pub modes: usize,
    /// The ordinary modes the method identifies.
    pub ordinary: usize,
    /// The known stops.
    pub stops: usize,
}

impl FixedModeCount {
    /// The prior `modes` of `priors` against `ordinary`, the ordinary modes
    /// `method` always identifies (`None`: it has no fixed count).
    pub fn check(
        method: &'static str,
        ordinary: Option<usize>,
        priors: &Priors,
    ) -> Result<(), Self> {
        let stops = priors.saturation.len();
        match (ordinary, priors.modes) {
            (Some(ordinary), Some(modes)) if modes != ordinary + stops => Err(FixedModeCount {
                method,
                modes,
                ordinary,
                stops,
            }),
            _ => Ok(()),
        }
    }
}

/// The checks of `priors` that need no data: their names against the
/// structure of `spec` ([`check_names`]), and fixed values, bounds and
/// equalities that can hold together ([`Parametrisation::from_priors`]);
/// errors name `origin`, the priors' file.
pub fn check_priors(
    priors: &Priors,
    spec: &RegressorSpec,
    origin: Option<&str>,
) -> Result<(), IdentifyError> {
    check_names(priors, spec).map_err(|e| IdentifyError::prior_mismatch(origin, e))?;
    Parametrisation::from_priors(priors, spec, 1)
        .map_err(|e| IdentifyError::prior_mismatch(origin, e))?;
    Ok(())
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

/// The share of the output's range that a sample may lie past a known stop
/// (beyond the stop's tolerance) before the prior is taken to contradict
/// the record: noise past a stop counts as at the stop, a level inside the
/// record's range or a stop on the wrong side does not.
pub const PAST_STOP_SHARE: f64 = 0.05;

/// A record that lies far past a known stop: the prior contradicts the data
/// (a `max` stop given for a `min` one, or a level inside the record's
/// range).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "[[saturation]] #{entry} (level {level}, bound \"{bound}\"): {past} of {samples} output \
     samples lie past it by more than {limit:.4} (its tol, or 5 % of the record's range), the \
     farthest by {farthest:.4}; a \"{bound}\" stop is never passed: check its bound and level"
)]
pub struct PastStop {
    /// The entry, counted from 1.
    pub entry: usize,
    /// Its level.
    pub level: f64,
    /// Its bound, as written (`max`, `min`).
    pub bound: &'static str,
    /// The distance allowed past it: its tolerance, or
    /// [`PAST_STOP_SHARE`] of the record's range if larger.
    pub limit: f64,
    /// Samples past it by more than `limit`.
    pub past: usize,
    /// Samples checked.
    pub samples: usize,
    /// The largest distance past the level.
    pub farthest: f64,
}

/// Checks the regression targets against every known stop: none may lie
/// past it by more than its tolerance or [`PAST_STOP_SHARE`] of the
/// targets' range, whichever is larger ([`PastStop`]).
pub fn check_stops(priors: &Priors, targets: &[f64]) -> Result<(), PastStop> {
    let (low, high) = targets
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &y| {
            (l.min(y), h.max(y))
        });
    let range = (high - low).max(0.0);
    for (i, stop) in priors.saturation.iter().enumerate() {
        let limit = stop.tolerance().max(PAST_STOP_SHARE * range);
        let (past, farthest) = targets
            .iter()
            .map(|&y| stop.beyond(y))
            .filter(|&d| d > limit)
            .fold((0, 0.0), |(n, far), d| (n + 1, f64::max(far, d)));
        if past > 0 {
            return Err(PastStop {
                entry: i + 1,
                level: stop.level,
                bound: stop.bound.name(),
                limit,
                past,
                samples: targets.len(),
                farthest,
            });
        }
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
    // The record's length first: the orders size the names checked next.
    let regressors = spec.build(problem.data)?;
    check_names(priors, &spec)
        .map_err(|e| IdentifyError::prior_mismatch(problem.priors_origin, e))?;
    if let Some(&value) = regressors
        .x
        .iter()
        .chain(regressors.y.iter())
        .find(|v| !v.is_finite())
    {
        return Err(IdentifyError::NonFinite { value });
    }
    check_stops(priors, regressors.y.as_slice())
        .map_err(|e| IdentifyError::prior_mismatch(problem.priors_origin, e))?;
    let stop_of = saturated_samples(priors, regressors.y.as_slice());
    let ordinary: Vec<usize> = (0..regressors.len())
        .filter(|&k| stop_of[k].is_none())
        .collect();
    if ordinary.is_empty() && !stop_of.is_empty() {
        return Err(IdentifyError::AllAtStops {
            samples: stop_of.len(),
        });
    }
    let modes = mode_count(priors, method)?;
    check_identifiable(
        modes,
        ordinary.len(),
        spec.n_params(),
        priors.saturation.len(),
    )?;
    Ok(PwarxData {
        problem: *problem,
        spec,
        modes,
        switching: switching_columns(priors, &spec),
        regressors,
        stop_of,
        ordinary,
    })
}

/// An exact count of ordinary modes whose parameters (`params` each) the
/// `ordinary` samples cannot all determine is the user's input, refused
/// before any back-end runs.
fn check_identifiable(
    modes: ModeCount,
    ordinary: usize,
    params: usize,
    stops: usize,
) -> Result<(), IdentifyError> {
    match modes.exact() {
        Some(s) if s.checked_mul(params).is_none_or(|need| need > ordinary) => {
            Err(IdentifyError::TooFewRegressors {
                rows: ordinary,
                modes: s.saturating_add(stops),
                params,
            })
        }
        _ => Ok(()),
    }
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
        // A control or invisible character in a name is shown, not sent to
        // the terminal.
        for (name, shown) in [
            ("\\u001b[31mc", "'\\u{1b}[31mc'"),
            ("a1\\u200b", "'a1\\u{200b}'"),
        ] {
            let text = format!("[fixed]\n\"{name}\" = 0.0\n");
            let p = Priors::from_toml(&text, "p.toml").unwrap();
            let e = check_names(&p, &RegressorSpec::new(1, 1, 1)).unwrap_err();
            assert!(e.to_string().contains(shown), "{e}");
        }
    }

    #[test]
    fn a_record_far_past_a_stop_contradicts_it() {
        let stop = |level: f64, bound: &str| {
            Priors::from_toml(
                &format!("[[saturation]]\nlevel = {level}\nbound = \"{bound}\"\n"),
                "p",
            )
            .unwrap()
        };
        // A record on [0, 25] resting at both ends, with noise of 0.1 past
        // them: 5 % of its range is 1.26.
        let record = [0.0, -0.1, 3.0, 12.0, 24.0, 25.0, 25.1];
        assert_eq!(check_stops(&stop(25.0, "max"), &record), Ok(()));
        assert_eq!(check_stops(&stop(0.0, "min"), &record), Ok(()));
        let wrong_side = check_stops(&stop(0.0, "max"), &record).unwrap_err();
        assert_eq!((wrong_side.past, wrong_side.farthest), (5, 25.1));
        let inside = check_stops(&stop(12.0, "max"), &record).unwrap_err();
        assert_eq!((inside.entry, inside.past, inside.bound), (1, 3, "max"));
        // Just within 5 % of the range past a stop, and just beyond.
        assert_eq!(check_stops(&stop(23.9, "max"), &record), Ok(()));
        assert!(check_stops(&stop(23.8, "max"), &record).is_err());
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
