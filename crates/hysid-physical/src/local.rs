//! The local stages: from each start, Levenberg-Marquardt, then argmin's
//! Nelder-Mead (Nelder and Mead 1965) restarted with a fresh simplex; first
//! on the segmented simulation error (when enabled), then on the free-run
//! one.

use crate::stages::{Search, Stage, StageLog, Termination};
use hysid_numerics::least_squares::{
    CentralDifferences, Damping, Exact, LmSettings, ResidualJacobian, Residuals, Stop, descend,
};
use hysid_numerics::nelder_mead;
use rayon::prelude::*;
use std::sync::atomic::Ordering;

/// The cost test of the Levenberg-Marquardt stage: a step that lowers the
/// cost by less than this fraction of it, as predicted, ends the stage
/// ([`Termination::Converged`]).
const LM_RELATIVE_TOLERANCE: f64 = 1e-9;

/// A Levenberg-Marquardt descent: how it ended, the point it reached and
/// the cost there.
#[derive(Debug, Clone, PartialEq)]
pub struct Descended {
    /// How it ended.
    pub stop: Stop,
    /// The point it reached.
    pub z: Vec<f64>,
    /// The cost there (on the cost it descended).
    pub cost: f64,
}

/// Levenberg-Marquardt from `start` on the residuals of segments of
/// `segment` samples (0: free run) in the unit box, at most `lm_iters`
/// iterations, none begun after the deadline; on the exact Jacobian of
/// the runs' sensitivities where the model gives one and `exact_jacobian`
/// is set (a run with sensitivities counts as one simulation), else on
/// central differences of `fd_step`.
pub fn descend_from(search: &Search<'_>, segment: usize, start: &[f64]) -> Descended {
    let options = search.options;
    let objective = search.objective.with_segment(segment);
    let residuals = |z: &[f64]| {
        search.evals.fetch_add(1, Ordering::Relaxed);
        objective.residuals(z)
    };
    let differences = CentralDifferences {
        step: options.fd_step,
    };
    let unit = vec![[0.0, 1.0]; start.len()];
    let descent = if options.exact_jacobian && objective.model.exact_jacobian() {
        let jacobian = |z: &[f64]| {
            search.evals.fetch_add(1, Ordering::Relaxed);
            objective
                .jacobian(z)
                .unwrap_or_else(|| differences.of(&residuals, z, Some(&unit)))
        };
        levenberg_marquardt(search, start, &unit, residuals, Exact(jacobian))
    } else {
        levenberg_marquardt(search, start, &unit, residuals, differences)
    };
    let z = descent.v.unwrap_or_else(|| start.to_vec());
    let cost = objective.mse(&z);
    Descended {
        stop: descent.stop,
        z,
        cost,
    }
}

/// [`descend`] on `residuals` from `start` in the box `unit`, with the
/// Jacobian `jacobian`, under the search's settings.
fn levenberg_marquardt<F, J>(
    search: &Search<'_>,
    start: &[f64],
    unit: &[[f64; 2]],
    residuals: F,
    jacobian: J,
) -> hysid_numerics::least_squares::Descent
where
    F: Fn(&[f64]) -> Option<Vec<f64>>,
    J: ResidualJacobian<F>,
{
    let problem = Residuals::new(residuals, start.len(), Some(unit), jacobian);
    let settings = LmSettings::new(search.options.lm_iters)
        .with_cost_tolerance(LM_RELATIVE_TOLERANCE)
        .with_damping(Damping::Marquardt);
    descend(&problem, start.to_vec(), &settings, &search.ctx.deadline)
}

/// What the local stages found.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalResult {
    /// The best coordinates of the last (free-run) stage.
    pub best_z: Vec<f64>,
    /// The best cost of the segmented stage, when it ran.
    pub segmented_cost: Option<f64>,
}

/// Runs the local stages from `best_z` (the first stage also from
/// `extra_starts`) when there is something to search (`d > 0`, and
/// Levenberg-Marquardt or Nelder-Mead to run: `lm_iters`, or `local_iters`
/// and `restarts`, not 0); each stage starts from the best point of the
/// previous one. `free_run_only`: the free-run stage alone.
pub fn local_stages(
    search: &Search<'_>,
    best_z: Vec<f64>,
    extra_starts: &[Vec<f64>],
    free_run_only: bool,
    log: &mut StageLog,
) -> LocalResult {
    let options = search.options;
    let mut result = LocalResult {
        best_z,
        segmented_cost: None,
    };
    let d = search.objective.map.dim();
    let nelder_mead = options.local_iters > 0 && options.restarts > 0;
    if !(d > 0 && (options.lm_iters > 0 || nelder_mead)) {
        return result;
    }
    // The segmented cost (when enabled), then the free run.
    let stages: Vec<usize> = if options.segment > 0 && !free_run_only {
        vec![options.segment, 0]
    } else {
        vec![0]
    };
    search.ctx.progress.start(
        (options.local_iters * options.restarts * stages.len()) as u64,
        "physical: Nelder-Mead",
    );
    for (i, &segment) in stages.iter().enumerate() {
        // The first stage starts from every start, the later ones from the best.
        let from = &result.best_z;
        let starts: Vec<Vec<f64>> = if i == 0 {
            std::iter::once(from.clone())
                .chain(extra_starts.iter().cloned())
                .collect()
        } else {
            vec![from.clone()]
        };
        let best = local_stage(search, segment, from, starts, log);
        result.best_z = best.z;
        if segment > 0 {
            result.segmented_cost = Some(best.cost);
        }
    }
    search.ctx.progress.finish();
    result
}

/// The best point of a stage so far.
struct Best {
    z: Vec<f64>,
    cost: f64,
}

impl Best {
    /// Keeps `z` when its cost is lower; whether it did.
    fn offer(&mut self, z: Vec<f64>, cost: f64) -> bool {
        let lower = cost < self.cost;
        if lower {
            self.cost = cost;
            self.z = z;
        }
        lower
    }
}

/// One local stage on segments of `segment` samples (0: free run):
/// Levenberg-Marquardt from each of `starts`, then the Nelder-Mead
/// restarts from the best point found. A restart that does not lower the
/// best cost ends the restarts: the next would start from the same point
/// with the same simplex and repeat it.
fn local_stage(
    search: &Search<'_>,
    segment: usize,
    from: &[f64],
    starts: Vec<Vec<f64>>,
    log: &mut StageLog,
) -> Best {
    let options = search.options;
    let objective = search.objective.with_segment(segment);
    let mut best = Best {
        z: from.to_vec(),
        cost: objective.mse(from),
    };
    // The starts run in parallel; their outcomes are offered in start
    // order, so the result is the same for any number of threads. No
    // descent begins after the deadline.
    let deadline = &search.ctx.deadline;
    let outcomes: Vec<_> = starts
        .par_iter()
        .map(|start| {
            let at_start = objective.mse(start);
            let descent = (options.lm_iters > 0 && !deadline.passed()).then(|| {
                let d = descend_from(search, segment, start);
                (d.stop, d.z, d.cost)
            });
            (at_start, descent)
        })
        .collect();
    let descended = options.lm_iters > 0 && !starts.is_empty();
    for (start, (at_start, descent)) in starts.into_iter().zip(outcomes) {
        best.offer(start, at_start);
        let Some((end, z, cost)) = descent else {
            continue;
        };
        log.levenberg_marquardt.push(match end {
            Stop::Converged => Termination::Converged,
            Stop::NoDescent => Termination::NoDecrease,
            Stop::IterationLimit => Termination::MaxIterations,
            Stop::TimeBudget => Termination::TimeBudget,
            Stop::Diverged => Termination::Other,
        });
        best.offer(z, cost);
    }
    if descended {
        search.past_deadline(log, Stage::LevenbergMarquardt);
    }
    for _ in 0..options.restarts {
        if search.past_deadline(log, Stage::NelderMead) {
            break;
        }
        let (stop, z) = nelder_mead(search, segment, &best.z);
        search.past_deadline(log, Stage::NelderMead);
        log.nelder_mead.push(stop);
        let c = objective.mse(&z);
        if !best.offer(z, c) {
            break;
        }
    }
    best
}

/// One Nelder-Mead run of at most `local_iters` iterations from a fresh
/// simplex at `z`, none begun after the deadline: why it stopped and its
/// best point, clamped into the box. Where the cost's evaluation runs on
/// one core (the free run of one record), the run guesses each step's
/// second point and evaluates it beside the first
/// ([`hysid_numerics::nelder_mead`]); the iterates, and the evaluations
/// counted, are the same.
fn nelder_mead(search: &Search<'_>, segment: usize, z: &[f64]) -> (Termination, Vec<f64>) {
    let objective = search.objective.with_segment(segment);
    let progress = search.ctx.progress;
    let cost = |z: &[f64]| {
        progress.advance(1);
        objective.penalised(z)
    };
    let settings = nelder_mead::Settings {
        max_iterations: search.options.local_iters,
        sd_tolerance: 1e-12,
        speculate: segment == 0 && objective.records.len() == 1,
    };
    let simplex = simplex(z, search.options.simplex);
    let found = nelder_mead::minimise(&cost, simplex, &settings, &search.ctx.deadline);
    search
        .evals
        .fetch_add(found.evaluations as u64, Ordering::Relaxed);
    let stop = match found.stop {
        nelder_mead::Stop::Converged => Termination::Converged,
        nelder_mead::Stop::IterationLimit => Termination::MaxIterations,
        nelder_mead::Stop::TimeBudget => Termination::TimeBudget,
    };
    (stop, found.x.iter().map(|x| x.clamp(0.0, 1.0)).collect())
}

/// The initial simplex at `z`: `z` and, per coordinate, `z` moved by
/// `size` inwards (so the simplex stays in the box).
fn simplex(z: &[f64], size: f64) -> Vec<Vec<f64>> {
    let mut simplex = vec![z.to_vec()];
    for j in 0..z.len() {
        let mut p = z.to_vec();
        p[j] += if p[j] + size <= 1.0 { size } else { -size };
        simplex.push(p);
    }
    simplex
}
