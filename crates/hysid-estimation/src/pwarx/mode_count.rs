//! Step 2 of the pipeline under a `max_modes` prior, for a method that
//! needs its mode count ([`ModeRule::Given`](super::ModeRule::Given)):
//! every count from one ordinary mode to the bound is identified on the
//! first three quarters of the record and scored by free-run simulation
//! FIT on the last quarter; the fewest modes within one standard error of
//! the best count ([`crate::parsimony`], the rule automatic selection
//! applies) are then identified on the whole record. The scores are
//! recorded in the model's diagnostics as `mode_choice`, pairs of the
//! count and its hold-out FIT.

use super::failure::PwarxFailure;
use super::prepare::PwarxData;
use crate::parsimony;
use hysid_core::backend::{IdentifyError, NoProgress, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::priors::Priors;
use hysid_core::simulate::{Holdout, holdout};
use hysid_model::data::RowRange;

/// Share of the record (in percent) the candidates are fitted on.
pub const FIT_PERCENT: usize = 75;

/// One mode count, fitted on the first rows and scored on the rest.
struct Scored {
    /// The count asked for, stops included.
    modes: usize,
    /// The model's own count, when it could be fitted and scored.
    modes_found: Option<usize>,
    /// Its hold-out score.
    holdout: Option<Holdout>,
}

/// The model with the count chosen as the module doc says; `max` is the
/// largest number of ordinary modes, `identify` the rest of the pipeline
/// on a problem whose priors fix the count.
pub fn choose(
    data: &PwarxData<'_>,
    max: usize,
    ctx: &RunContext<'_>,
    identify: impl Fn(&Problem<'_>, &RunContext<'_>) -> Result<Model, IdentifyError>,
) -> Result<Model, IdentifyError> {
    let problem = &data.problem;
    let cut = problem.data.len() * FIT_PERCENT / 100;
    let fit_rows = problem.data.slice(RowRange {
        start: None,
        end: Some(cut),
    })?;
    let held_out = problem.data.slice(RowRange {
        start: Some(cut),
        end: None,
    })?;
    let counts: Vec<usize> = (data.stops() + 1..=data.stops() + max).collect();
    let quiet = RunContext {
        seed: ctx.seed,
        progress: &NoProgress,
        deadline: ctx.deadline.clone(),
    };
    ctx.progress
        .start(counts.len() as u64, "choosing the mode count");
    let mut scored = Vec::with_capacity(counts.len());
    for &modes in &counts {
        let priors = with_modes(problem.priors, modes);
        let candidate = Problem {
            data: &fit_rows,
            priors: &priors,
            ..*problem
        };
        let model = identify(&candidate, &quiet);
        let score = model.ok().and_then(|m| {
            let h = holdout(&m, &held_out, 0).ok()?;
            Some((m.mode_count(), h))
        });
        scored.push(Scored {
            modes,
            modes_found: score.as_ref().map(|(n, _)| *n),
            holdout: score.map(|(_, h)| h),
        });
        ctx.progress.advance(1);
        if ctx.deadline.passed() {
            break;
        }
    }
    ctx.progress.finish();
    let best = simplest(&scored, problem.orders.na).ok_or_else(|| {
        IdentifyError::failed(PwarxFailure::NoModeCount {
            max: data.stops() + max,
        })
    })?;
    let priors = with_modes(problem.priors, best);
    let chosen = Problem {
        priors: &priors,
        ..*problem
    };
    let mut model = identify(&chosen, ctx)?;
    let record: Vec<(usize, Option<f64>)> = scored
        .iter()
        .map(|s| (s.modes, s.holdout.as_ref().map(|h| h.fit_sim)))
        .collect();
    model
        .info_mut()
        .diagnostics
        .method
        .insert("mode_choice".into(), serde_json::json!(record));
    Ok(model)
}

/// `priors` asking for exactly `modes` modes.
fn with_modes(priors: &Priors, modes: usize) -> Priors {
    Priors {
        modes: Some(modes),
        max_modes: None,
        ..priors.clone()
    }
}

/// The count of fewest modes within one standard error of the best
/// hold-out score (ties in score to the earlier, smaller count).
fn simplest(scored: &[Scored], na: usize) -> Option<usize> {
    let fit = |i: usize| scored[i].holdout.as_ref().map(|h| h.fit_sim);
    let mut ranked: Vec<usize> = (0..scored.len()).filter(|&i| fit(i).is_some()).collect();
    ranked.sort_by(|&a, &b| {
        let score = |i| fit(i).unwrap_or(f64::NEG_INFINITY);
        score(b).total_cmp(&score(a)).then(a.cmp(&b))
    });
    let errors: Vec<Vec<f64>> = scored
        .iter()
        .map(|s| {
            s.holdout
                .as_ref()
                .map_or_else(Vec::new, |h| h.errors.clone())
        })
        .collect();
    let found: Vec<Option<usize>> = scored.iter().map(|s| s.modes_found).collect();
    let dependence = parsimony::Dependence::of_output_lags(na);
    parsimony::simplest_within_one_se(&ranked, &errors, &found, dependence).map(|i| scored[i].modes)
}
