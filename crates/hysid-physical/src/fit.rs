//! The fit: check the inputs, map the free parameters, search (particle
//! swarm, then Levenberg-Marquardt and Nelder-Mead on the segmented and the
//! free-run simulation error), then estimate the sensitivity and confidence
//! of the result, keep the parameters the rows do not identify at their
//! nominal values, and write the diagnostics.

use crate::diagnostics::{
    COST_DEFINITION, PhysicalDiagnostics, Status, SwarmSkipped, Terminations, confidence_method,
};
use crate::identifiability;
use crate::local::{Descended, LocalResult, descend_from, local_stages};
use crate::objective::{FAILED, Objective, simulation_mse, velocity_tolerances};
use crate::parameters::ParameterMap;
use crate::sensitivity::{Sensitivity, sensitivity};
use crate::stages::{Search, SearchFailure, StageLog};
use crate::swarm::{SwarmResult, global_stage, noise_floor, nominal_suffices};
use crate::target::Target;
use crate::{NominalDivergence, PhysicalError, PhysicalOptions};
use hysid_core::backend::{IdentifyError, NoProgress, Progress, RunContext};
use hysid_core::options::OptionError;
use hysid_core::priors::Priors;
use hysid_model::data::Dataset;
use hysid_model::simulate::{DivergedTo, Divergence, SimError};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// What a fit did.
#[derive(Debug, Clone, PartialEq)]
pub struct FitReport {
    /// Cost of the nominal values.
    pub nominal_cost: f64,
    /// Best cost after the swarm.
    pub swarm_cost: Option<f64>,
    /// Final cost (mean squared simulation error).
    pub cost: f64,
    /// Cost evaluations (simulations).
    pub evaluations: u64,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Per free coordinate: the standard error (NaN when not estimable).
    pub std_errors: Vec<f64>,
}

/// Fits `model`'s parameters (a mechanical or a gray-box model) to `data`
/// by simulation error: the particle swarm ([`global_stage`]), then the
/// local stages ([`local_stages`]), then the [`sensitivity`] of the result.
/// Returns the fitted model (values replaced, [`PhysicalDiagnostics`] in
/// `info.diagnostics`) and a report.
pub fn fit_model<M: Target>(
    model: &M,
    data: &Dataset,
    priors: &Priors,
    options: &PhysicalOptions,
    ctx: &RunContext<'_>,
) -> Result<(M, FitReport), IdentifyError> {
    let t0 = Instant::now();
    let ts = check_inputs(model, data)?;
    let tols = velocity_tolerances(data.y(), ts);
    // The file's rule, unless `init_samples` asks for another warm-up; a
    // measured start takes the record's velocity tolerance.
    let samples = match options.init_samples {
        0 => model.warmup_samples(),
        n => Some(n),
    };
    let model = match samples {
        Some(n) => model.with_warmup(n, tols.backward).ok_or_else(|| {
            OptionError::invalid(
                "init_samples",
                n,
                "the model's initial state is given or at rest and estimates no state: it \
                 reads no warm-up to set",
            )
        })?,
        None => model.clone(),
    };
    let map = ParameterMap::new(&model, priors, data.record_count())
        .map_err(PhysicalError::Parameters)?;
    check_length(&model, &map, data)?;
    let records = data.records();
    let evals = AtomicU64::new(0);
    let search = Search {
        objective: Objective {
            segment: 0,
            velocity_tol: tols.centred,
            model: &model,
            records: &records,
            map: &map,
        },
        options,
        ctx,
        evals: &evals,
    };
    let (nominal_z, nominal_cost) = nominal_start(&search);
    let nominal = Nominal::descend(&search, nominal_z, nominal_cost, tols.resolved_noise());
    let kept = best_search(&search, &nominal)?;
    let (local, log) = (kept.local, kept.log);

    let mut values = map.values(&local.best_z);
    let cost = kept.cost;
    let evaluations = evals.load(Ordering::Relaxed);
    if cost >= FAILED {
        return Err(match nominal_failure(&model, &map, &records[0]) {
            Some(source) => IdentifyError::input(PhysicalError::ModelFails {
                file: options.model.clone(),
                source,
            }),
            None => match nominal_divergence(&model, &map, &records) {
                Some(nominal) if map.dim() == 0 => {
                    IdentifyError::input(PhysicalError::DivergesWithNothingFree {
                        file: options.model.clone(),
                        nominal,
                    })
                }
                nominal => IdentifyError::failed(SearchFailure::EveryCandidateFailed {
                    evaluations,
                    nominal,
                }),
            },
        });
    }
    // The Jacobian costs one run with sensitivities, or two runs per free
    // coordinate: not begun after the deadline.
    let sens = if ctx.deadline.passed() {
        Sensitivity::not_computed(map.dim())
    } else {
        sensitivity(
            &model,
            &map,
            &values,
            &records,
            (options.exact_jacobian, options.fd_step),
        )
    };
    let identifiability =
        identifiability::classify(&model, &map, &mut values, cost, &records, &sens);
    let status = Status::of(&log, evaluations, options.local_iters);
    let diagnostics = PhysicalDiagnostics {
        cost,
        cost_definition: COST_DEFINITION.into(),
        rmse_fit: cost.sqrt(),
        nominal_cost: (nominal_cost < FAILED).then_some(nominal_cost),
        swarm_cost: kept.swarm_cost,
        swarm_skipped: nominal.skip.as_ref().map(|(why, _)| *why),
        segmented_cost: local.segmented_cost,
        segment: local.segmented_cost.map(|_| options.segment),
        evaluations,
        termination: Terminations::of(&log),
        noise_estimate: tols.noise,
        free_parameters: (0..map.dim()).filter(|&g| !map.is_initial_state(g)).count(),
        parameters: PhysicalDiagnostics::parameters(&map, &values, &sens, &identifiability),
        initial_states: map.initial_states(&values),
        confidence_method: confidence_method(sens.jacobian).into(),
        jacobian: sens.jacobian,
        jacobian_condition: Some(sens.condition).filter(|c| c.is_finite()),
        zero_sensitivity: sens.insensitive(&map),
        at_bound: map.at_bound(&values),
        initial_states_at_bound: map.initial_states_at_bound(&values),
        swarm_kept: (options.swarms > 1 && nominal.skip.is_none()).then_some(kept.index),
    };
    let mut fitted = map.apply(&model, &values);
    let common = &mut fitted.info_mut().diagnostics;
    common.samples = Some(data.len());
    if let Some(status) = status {
        common.run_status = status.run_status();
        common.status.push(status.to_string());
    }
    *common = std::mem::take(common).with_method(&diagnostics);
    let report = FitReport {
        nominal_cost,
        swarm_cost: kept.swarm_cost,
        cost,
        evaluations,
        seconds: t0.elapsed().as_secs_f64(),
        std_errors: sens.std_errors,
    };
    Ok((fitted, report))
}

/// The fault of the model that fails its free run of `record` at the
/// file's values ([`ParameterMap::base`]), if it does: an error of the
/// model (a transition that leaves its target's invariant, an initial rule
/// it cannot meet), not a run that merely diverges.
fn nominal_failure<M: Target>(model: &M, map: &ParameterMap, record: &Dataset) -> Option<SimError> {
    let own = map.base.get(..map.parameters + model.estimated_count())?;
    match model.free_run(own, record) {
        Err(
            e @ (SimError::OutsideTargetInvariant { .. }
            | SimError::InitialState(_)
            | SimError::InvalidModel(_)),
        ) => Some(e),
        _ => None,
    }
}

/// Where the free run at the file's values ([`ParameterMap::base`]) first
/// gives a scored output that is not finite, if it does.
fn nominal_divergence<M: Target>(
    model: &M,
    map: &ParameterMap,
    records: &[Dataset],
) -> Option<NominalDivergence> {
    let states = model.estimated_count();
    records.iter().enumerate().find_map(|(i, record)| {
        let at = map.parameters + i * states;
        let mut own = map.base.get(..map.parameters)?.to_vec();
        own.extend_from_slice(map.base.get(at..at + states)?);
        let (start, y) = model.free_run(&own, record).ok()?;
        let k = (start..y.len()).find(|&k| !y[k].is_finite())?;
        let to = DivergedTo::of(y[k]);
        Some(NominalDivergence {
            record: (records.len() > 1).then_some(i + 1),
            divergence: Divergence { at: k, to },
        })
    })
}

/// The nominal point and its free-run cost: the model's parameter values
/// and, for the initial states it estimates, their starting guesses or,
/// where lower in cost, the states each record's warm-up outputs give at
/// those values ([`crate::target::Simulator::warmup_states`]).
fn nominal_start(search: &Search<'_>) -> (Vec<f64>, f64) {
    let (map, records) = (search.objective.map, search.objective.records);
    let guesses = map.coords(&map.base);
    let cost = search.objective.mse(&guesses);
    let parameters = &map.base[..map.parameters];
    let warmup: Option<Vec<f64>> = records
        .iter()
        .map(|r| search.objective.model.warmup_states(parameters, r))
        .collect::<Option<Vec<Vec<f64>>>>()
        .map(|states| states.concat());
    let Some(states) = warmup.filter(|s| s.len() == map.names.len() - map.parameters) else {
        return (guesses, cost);
    };
    let mut values = map.base.clone();
    values[map.parameters..].copy_from_slice(&states);
    let z = map.coords(&values);
    let warm = search.objective.mse(&z);
    if warm < cost {
        (z, warm)
    } else {
        (guesses, cost)
    }
}

/// The nominal values' free-run cost must lie within this factor of the
/// floor of [`nominal_suffices`] (an RMS error within 10 times the noise's)
/// for the descent that may skip the swarm to be tried; farther, it is
/// taken to be out of reach, and no fit pays for the descent.
const NOMINAL_REACH: f64 = 100.0;

/// The nominal values, their cost and, where [`nominal_suffices`] skips
/// the swarm, why and the descent the local stages go on from.
struct Nominal {
    z: Vec<f64>,
    cost: f64,
    skip: Option<(SwarmSkipped, Descended)>,
}

impl Nominal {
    /// Levenberg-Marquardt from `z` on the free-run cost, tried when the
    /// swarm and Levenberg-Marquardt would both run and the rule may skip
    /// the swarm: `swarm_skip > 0`, a noise estimate above rounding
    /// ([`crate::objective::VelocityTolerances::resolved_noise`]), and the
    /// nominal cost `cost` within [`NOMINAL_REACH`] of the floor.
    fn descend(search: &Search<'_>, z: Vec<f64>, cost: f64, noise: f64) -> Self {
        let o = search.options;
        let swarm = !z.is_empty() && o.particles > 0 && o.swarm_iters > 0;
        let floor = noise_floor(noise, o.swarm_skip);
        let within_reach = floor > 0.0 && cost <= NOMINAL_REACH * floor;
        let skip = (swarm && o.lm_iters > 0 && within_reach)
            .then(|| descend_from(search, 0, &z))
            .and_then(|d| Some((nominal_suffices(&d, floor)?, d)));
        Nominal { z, cost, skip }
    }
}

/// One search of [`best_search`]: the swarm's best cost, the local stages
/// from its best points, why each stopped, and the free-run cost of the
/// result.
struct SearchRun {
    index: usize,
    swarm_cost: Option<f64>,
    local: LocalResult,
    log: StageLog,
    cost: f64,
}

/// `options.swarms` independent searches (the particle swarm, then the
/// local stages from its best points), the first seeded by the run's seed
/// and each next one by the next draw of a `ChaCha8Rng` seeded by it
/// ([`RunContext::start_seeds`]); the
/// one of least free-run cost is kept (the first among equals). Several
/// searches run in parallel, each on its own seed, so the one kept does
/// not depend on the thread count; the progress then counts searches. No
/// search but the first starts after the deadline. Where the swarm is
/// skipped, one search.
fn best_search(search: &Search<'_>, nominal: &Nominal) -> Result<SearchRun, IdentifyError> {
    // Without the swarm every search would run the same local stages.
    let searches = if nominal.skip.is_some() {
        1
    } else {
        search.options.swarms
    };
    let seeds = search.ctx.start_seeds(searches);
    if let [seed] = seeds[..] {
        return one_search(search, 0, seed, search.ctx.progress, nominal);
    }
    let progress = search.ctx.progress;
    progress.start(seeds.len() as u64, "searches");
    let runs: Vec<Option<Result<SearchRun, IdentifyError>>> = seeds
        .par_iter()
        .enumerate()
        .map(|(index, &seed)| {
            if !search.ctx.deadline.admits(index) {
                return None;
            }
            let run = one_search(search, index, seed, &NoProgress, nominal);
            progress.advance(1);
            Some(run)
        })
        .collect();
    progress.finish();
    let mut best: Option<SearchRun> = None;
    for run in runs.into_iter().flatten() {
        let run = run?;
        if best.as_ref().is_none_or(|b| run.cost < b.cost) {
            best = Some(run);
        }
    }
    best.ok_or_else(|| IdentifyError::failed(SearchFailure::NoSearch))
}

/// Search number `index` of [`best_search`], on `seed`, reporting to
/// `progress`; where [`Nominal::skip`] says so, without the swarm and the
/// segmented local stage.
fn one_search(
    search: &Search<'_>,
    index: usize,
    seed: u64,
    progress: &dyn Progress,
    nominal: &Nominal,
) -> Result<SearchRun, IdentifyError> {
    let ctx = RunContext {
        seed,
        progress,
        deadline: search.ctx.deadline.clone(),
    };
    let run = Search {
        objective: search.objective,
        options: search.options,
        ctx: &ctx,
        evals: search.evals,
    };
    let mut log = StageLog::default();
    let (swarm, free_run_only) = match &nominal.skip {
        Some((_, descent)) => (SwarmResult::skipped(descent), true),
        None => (
            global_stage(&run, &nominal.z, nominal.cost, &mut log)?,
            false,
        ),
    };
    let local = local_stages(
        &run,
        swarm.best_z,
        &swarm.extra_starts,
        free_run_only,
        &mut log,
    );
    let values = run.objective.map.values(&local.best_z);
    let cost = simulation_mse(run.objective.model, &values, run.objective.records);
    Ok(SearchRun {
        index,
        swarm_cost: swarm.cost,
        local,
        log,
        cost,
    })
}

/// Checks the model, the record and the options against each other;
/// returns the sampling time.
fn check_inputs(model: &impl Target, data: &Dataset) -> Result<f64, IdentifyError> {
    model.check().map_err(PhysicalError::Model)?;
    if data.inputs.len() != model.inputs() {
        return Err(PhysicalError::InputCount {
            model: model.inputs(),
            data: data.inputs.len(),
        }
        .into());
    }
    let Some(ts) = data.ts else {
        return Err(PhysicalError::NoSamplingTime.into());
    };
    model
        .substeps(ts)
        .map_err(|e| PhysicalError::Model(e.into()))?;
    Ok(ts)
}

/// Checks that the data have a sample per free parameter, plus one, after
/// the initial state, and that every record of a joined dataset has a
/// sample after its own.
fn check_length(
    model: &impl Target,
    map: &ParameterMap,
    data: &Dataset,
) -> Result<(), IdentifyError> {
    let d = map.dim();
    let initial = model.warmup_samples().unwrap_or(0);
    if data.record_count() > 1
        && let Some((i, r)) = data
            .record_ranges()
            .into_iter()
            .enumerate()
            .find(|(_, r)| r.len() <= initial.max(1))
    {
        return Err(PhysicalError::ShortRecord {
            record: i + 1,
            samples: r.len(),
            initial,
        }
        .into());
    }
    let needed = initial + d + 1;
    if data.len() < needed {
        return Err(PhysicalError::TooFewSamples {
            samples: data.len(),
            params: d,
            warmup: initial,
            needed,
        }
        .into());
    }
    Ok(())
}
