//! The refit of a choice on all the identification rows (step 6 of
//! `docs/selection.md`): a new fit on more rows may end in another local
//! minimum than the fit that was scored, so a seeded choice is refitted
//! from several starts, and from its own fit on the fit rows, and the
//! start that simulates the identification rows best is kept.

use super::{Request, Trial, fit, fit_on};
use hysid_core::backend::{IdentifyError, NoProgress, RunContext};
use hysid_core::model::Model;
use hysid_core::simulate::{resolved_fit, simulate};
use hysid_model::data::Dataset;
use hysid_model::model::RefitStart;
use hysid_model::simulate::SimulationOptions;
use rayon::prelude::*;

/// `trial` fitted on all the identification rows from `plan.refit_starts`
/// starts when the seed can change its fit ([`Backend::seeded_with`](hysid_core::backend::Backend::seeded_with)),
/// from one otherwise: the run's seed,
/// then the next ones ([`RunContext::start_seeds`]), in parallel. A refit is
/// a new fit on more rows and may end in another local minimum than the
/// fit that was scored, so the choice has one start more, from its own
/// fit on the fit rows (of the last split, `scored`), which continues
/// from the model the selection rows scored: a refined candidate's
/// unrefined fit, refined on all the identification rows; a seeded
/// candidate's fit, kept as it was scored. Of the starts, the fit that
/// simulates the identification rows best is kept (the first among
/// equals), passing over those that diverge on the record played
/// backwards when any does not ([`kept_start`]), and each start is
/// recorded. When every start fails, the first start's error. No start
/// but the first begins after the deadline.
pub(super) fn refit(
    request: &Request<'_>,
    trial: &Trial<'_>,
    scored: Option<&Model>,
    ctx: &RunContext<'_>,
) -> Result<(Model, Vec<RefitStart>), IdentifyError> {
    let seeded = trial.seeded(request, request.data)?;
    let seeds = if seeded {
        request.plan.refit_starts.max(1)
    } else {
        1
    };
    let mut starts: Vec<(u64, Start<'_>)> = ctx
        .start_seeds(seeds)
        .into_iter()
        .map(|seed| (seed, Start::Afresh))
        .collect();
    match (trial.start.last(), scored) {
        (Some(unrefined), _) => starts.push((ctx.seed, Start::Refining(unrefined))),
        (None, Some(scored)) if seeded => starts.push((ctx.seed, Start::AsScored(scored))),
        _ => {}
    }
    let runs: Vec<_> = starts
        .into_par_iter()
        .enumerate()
        .map(|(k, (seed, from))| {
            let from_candidate = !matches!(from, Start::Afresh);
            if !ctx.deadline.admits(k) {
                return (seed, from_candidate, None);
            }
            let start = RunContext {
                seed,
                progress: &NoProgress,
                deadline: ctx.deadline.clone(),
            };
            let run = match from {
                Start::Afresh => fit(request, trial, request.data, None, &start),
                Start::Refining(unrefined) => {
                    fit(request, trial, request.data, Some(unrefined), &start)
                }
                Start::AsScored(model) => Ok(model.clone()),
            };
            (seed, from_candidate, Some(run))
        })
        .collect();
    let backwards = request.data.backwards();
    let mut record = Vec::with_capacity(runs.len());
    let mut models = Vec::with_capacity(runs.len());
    let mut first_error = None;
    for (seed, from_candidate, run) in runs {
        let Some(run) = run else { continue };
        let (fit_sim, diverges_backwards, error) = match run {
            Ok(model) => {
                let fit_sim = fit_on(&model, request.data, request.plan.warmup);
                let diverges = diverges(&model, &backwards);
                models.push(Some(model));
                (fit_sim, diverges, None)
            }
            Err(e) => {
                let text = e.to_string();
                first_error.get_or_insert(e);
                models.push(None);
                (None, false, Some(text))
            }
        };
        record.push(RefitStart {
            seed,
            from_candidate,
            fit_sim,
            diverges_backwards,
            kept: false,
            error,
        });
    }
    match kept_start(&record).and_then(|k| Some((k, models.swap_remove(k)?))) {
        Some((k, model)) => {
            record[k].kept = true;
            Ok((model, record))
        }
        // The first start always runs, so without a model there is an error.
        None => Err(first_error.unwrap_or_else(|| IdentifyError::failed(NoRefitStart))),
    }
}

/// The start of a refit to keep among those with a model: of the ones
/// that do not diverge on the record played backwards (of all, when each
/// does), the one that simulates the identification rows best, the first
/// among equals.
fn kept_start(starts: &[RefitStart]) -> Option<usize> {
    let fitted = |s: &RefitStart| s.error.is_none();
    let holds = starts.iter().any(|s| fitted(s) && !s.diverges_backwards);
    let mut kept: Option<(usize, f64)> = None;
    for (k, s) in starts.iter().enumerate() {
        if !fitted(s) || (holds && s.diverges_backwards) {
            continue;
        }
        let score = s.fit_sim.map_or(f64::NEG_INFINITY, resolved_fit);
        if kept.is_none_or(|(_, best)| score > best) {
            kept = Some((k, score));
        }
    }
    kept.map(|(k, _)| k)
}

/// Where a start of the refit of a choice begins ([`refit`]).
enum Start<'m> {
    /// A fit on all the identification rows from the start's seed.
    Afresh,
    /// The refined choice's unrefined fit on the fit rows, refined on all
    /// the identification rows.
    Refining(&'m Model),
    /// The choice's fit on the fit rows, as it was scored.
    AsScored(&'m Model),
}

/// The refit of a choice ran no start (the first always runs: a refit
/// asked for zero starts).
#[derive(Debug, thiserror::Error)]
#[error("no refit start ran")]
pub struct NoRefitStart;

/// Whether the free run of `model` on `data` diverges: its output leaves
/// a thousand times the scale of the measured one
/// ([`SimulationOptions::for_data`]). A simulation that fails otherwise
/// says nothing of divergence.
fn diverges(model: &Model, data: &Dataset) -> bool {
    simulate(model, data, SimulationOptions::for_data(data)).is_ok_and(|s| s.diverged_at.is_some())
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_core::simulate::validate;

    fn start(fit_sim: Option<f64>, diverges_backwards: bool) -> RefitStart {
        RefitStart {
            seed: 0,
            from_candidate: false,
            fit_sim,
            diverges_backwards,
            kept: false,
            error: None,
        }
    }

    #[test]
    fn a_start_that_diverges_backwards_is_kept_only_when_every_start_does() {
        let failed = RefitStart {
            error: Some("failed".into()),
            ..start(None, false)
        };
        let cases: [(Vec<RefitStart>, Option<usize>); 5] = [
            // The best FIT diverges backwards: the best of the others.
            (
                vec![
                    start(Some(95.0), true),
                    start(Some(80.0), false),
                    start(Some(85.0), false),
                ],
                Some(2),
            ),
            // Every start diverges: the best FIT.
            (
                vec![start(Some(70.0), true), start(Some(90.0), true)],
                Some(1),
            ),
            // Equals: the first; a start without a finite FIT still counts.
            (
                vec![
                    start(None, false),
                    start(Some(80.0), false),
                    start(Some(80.0), false),
                ],
                Some(1),
            ),
            (vec![failed.clone(), start(None, true)], Some(1)),
            (vec![failed], None),
        ];
        for (starts, kept) in cases {
            assert_eq!(kept_start(&starts), kept, "{starts:?}");
        }
    }

    /// `y(k) = 0.7 y(k-1) + 0.5 u(k-1) + 0.1` on a rising ramp from its
    /// steady state, and the same dynamics with an unstable second mode
    /// where `y(k-1)` lies above the steady state of `u(k-1)`: a rising
    /// input never takes the output there, a falling one does.
    #[test]
    fn a_mode_that_only_a_falling_input_reaches_diverges_backwards() {
        let n = 300;
        let u: Vec<f64> = (0..n)
            .map(|k| -1.0 + 2.0 * k as f64 / (n - 1) as f64)
            .collect();
        let mut y = vec![(0.5 * u[0] + 0.1) / 0.3];
        for k in 1..n {
            y.push(0.7 * y[k - 1] + 0.5 * u[k - 1] + 0.1);
        }
        let data = Dataset::siso(u, y, None).unwrap();
        // Mode 1: 0.3 y - 0.5 u <= 0.1 + 1e-3; mode 2 the rest, a1 = 1.5.
        let model = Model::from_json(
            r#"{"kind":"pwarx","na":1,"nb":1,"inputs":1,"modes":[
                {"theta":[0.7,0.5,0.1],"region":{"a":[[0.3,-0.5]],"b":[0.101]}},
                {"theta":[1.5,0.5,0.1],"region":{"a":[[-0.3,0.5]],"b":[-0.101]}}]}"#,
            "test",
        )
        .unwrap();
        assert!(!diverges(&model, &data));
        let (v, _, _) = validate(&model, &data, 0).unwrap();
        assert!(v.fit_sim > 99.999, "{}", v.fit_sim);
        assert!(diverges(&model, &data.backwards()));
    }
}
