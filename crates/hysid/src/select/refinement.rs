//! The refined candidates: the best candidate of every mode count
//! refined on simulation error (the mode parameters, then the region
//! boundaries too), starting from its own fits, and scored as candidates
//! of their own.

use super::{Part, Request, Scored, Trial, affine_index, ranking, score_all};
use hysid_core::backend::RunContext;
use hysid_core::model::Model;
use hysid_core::search::Setup;
use hysid_core::stages::{Refine, Stages};
use hysid_model::model::{RefinementChoice, ScoredCandidate};

/// The refinements tried, in order: the mode parameters on simulation
/// error, then also the region boundaries (for two or more modes).
pub const REFINEMENTS: [Refine; 2] = [Refine::Sim, Refine::SimRegions];

/// `trial` with the refinement `refine`, starting from `fits`, its models
/// on the fit rows, when its back-end runs the stages after a PWARX fit
/// and the user did not set the refinement.
pub(super) fn refined<'a>(trial: &Trial<'a>, fits: &[Model], refine: Refine) -> Option<Trial<'a>> {
    let settings = &trial.setup.settings;
    if !trial.backend.has_stages() || Stages::refine_given(settings).is_some() {
        return None;
    }
    let mut values = trial.values.clone();
    values.push((Stages::REFINE.into(), refine.as_str().into()));
    Some(Trial {
        backend: trial.backend,
        values,
        setup: Setup {
            settings: Stages::with_refine(settings, refine),
            ..trial.setup.clone()
        },
        start: fits.to_vec(),
    })
}

/// The refinements worth scoring: for every mode count, the back-end's
/// candidate of best selection FIT with each of [`REFINEMENTS`]
/// (the region stage only for two or more modes and no known stops, where
/// it can run). Every choice the one-standard-error rule can make among
/// the unrefined candidates is the best of its mode count, so each can be
/// compared refined. Each starts from the candidate's own fits.
pub(super) fn refinement_trials<'a>(
    request: &Request<'a>,
    trials: &[Trial<'a>],
    scored: &[Scored],
) -> Vec<Trial<'a>> {
    let own = affine_index(request, trials.len()).unwrap_or(trials.len());
    let mut counts = std::collections::BTreeSet::new();
    let mut out = Vec::new();
    let candidates = scored.iter().map(|s| &s.candidate);
    for i in ranking(candidates).into_iter().filter(|&i| i < own) {
        let Some(modes) = scored[i].candidate.modes.filter(|&m| counts.insert(m)) else {
            continue;
        };
        let regions_can_move = modes > 1 && request.setup.priors.saturation.is_empty();
        let tried = &REFINEMENTS[..if regions_can_move { 2 } else { 1 }];
        out.extend(
            tried
                .iter()
                .filter_map(|&r| refined(&trials[i], &scored[i].fits, r)),
        );
    }
    out
}

/// `scored`, the scored `trials`, with the [`refinement_trials`] scored
/// and added to both, as candidates of their own, after the back-end's
/// candidates and before the affine reference, which stays last.
pub(super) fn add_refined<'a>(
    request: &Request<'a>,
    trials: &mut Vec<Trial<'a>>,
    mut scored: Vec<Scored>,
    parts: &[Part],
    ctx: &RunContext<'_>,
) -> Vec<Scored> {
    let extra = refinement_trials(request, trials, &scored);
    if extra.is_empty() {
        return scored;
    }
    let extra_scored = score_all(request, &extra, parts, ctx, "refining");
    let at = affine_index(request, trials.len()).unwrap_or(trials.len());
    trials.splice(at..at, extra);
    scored.splice(at..at, extra_scored);
    scored
}

/// The refined candidates made from the chosen one's unrefined options,
/// with the one chosen marked `kept` (none when the unrefined candidate,
/// or another, was chosen).
pub(super) fn refinement_record(
    scored: &[ScoredCandidate],
    chosen: usize,
) -> Vec<RefinementChoice> {
    let unrefined = |c: &ScoredCandidate| -> Vec<(String, String)> {
        c.values
            .iter()
            .filter(|(k, _)| k != Stages::REFINE)
            .cloned()
            .collect()
    };
    let origin = unrefined(&scored[chosen]);
    scored
        .iter()
        .enumerate()
        .filter(|(_, c)| c.method == scored[chosen].method && unrefined(c) == origin)
        .filter_map(|(i, c)| {
            let (_, value) = c.values.iter().find(|(k, _)| k == Stages::REFINE)?;
            Some(RefinementChoice {
                refine: value.clone(),
                fit_sim: c.fit_sim,
                kept: i == chosen,
            })
        })
        .collect()
}
