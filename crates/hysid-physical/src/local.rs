//! The local stages: from each start, Levenberg-Marquardt, then argmin's
//! Nelder-Mead (Nelder and Mead 1965) restarted with a fresh simplex; first
//! on the segmented simulation error (when enabled), then on the free-run
//! one.

use crate::stages::{Search, Stage, StageLog, Termination};
use hysid_numerics::budget::Deadline;
use hysid_numerics::least_squares::{
    CentralDifferences, Damping, Descent, Exact, LeastSquares, LmSettings, Marquardt,
    ResidualJacobian, Residuals, Stop,
};
use hysid_numerics::nelder_mead;
use rayon::prelude::*;
use std::convert::Infallible;
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
    // Alone, a descent is never outpaced: its cost is the least.
    let (stop, z, cost) = descents(search, segment, &[start.to_vec()]).remove(0);
    Descended {
        stop: stop.unwrap_or(Stop::IterationLimit),
        z,
        cost,
    }
}

/// Steps a descent of [`descents`] takes between two comparisons with
/// the others.
const ROUND: usize = 5;

/// A descent whose cost is more than this many times the least cost of the
/// starts' descents after a round, and that did not halve its own cost in
/// that round, is outpaced ([`Termination::Outpaced`]): far behind and
/// crawling, in a basin it is not leaving within `lm_iters`.
const OUTPACED: f64 = 100.0;

/// [`descend_from`] from each of `starts`, side by side: in rounds of
/// [`ROUND`] steps, the descents of a round in parallel, and after each
/// round the outpaced ones stopped ([`OUTPACED`]; their stop `None`). The
/// rounds are the same for any number of threads, and a descent advanced
/// in rounds takes the steps of one run
/// ([`hysid_numerics::least_squares::Marquardt`]), so only the outpaced
/// ones end otherwise than alone. Per start: how it ended, the point it
/// reached (the start where no step was accepted) and the cost there.
fn descents(
    search: &Search<'_>,
    segment: usize,
    starts: &[Vec<f64>],
) -> Vec<(Option<Stop>, Vec<f64>, f64)> {
    let options = search.options;
    let objective = search.objective.with_segment(segment);
    let residuals = |z: &[f64]| {
        search.evals.fetch_add(1, Ordering::Relaxed);
        objective.residuals(z)
    };
    let differences = CentralDifferences {
        step: options.fd_step,
    };
    let dim = starts.first().map_or(0, Vec::len);
    let unit = vec![[0.0, 1.0]; dim];
    let settings = LmSettings::new(options.lm_iters)
        .with_cost_tolerance(LM_RELATIVE_TOLERANCE)
        .with_damping(Damping::Marquardt);
    let deadline = &search.ctx.deadline;
    let ends = if options.exact_jacobian && objective.model.exact_jacobian() {
        let jacobian = |z: &[f64]| {
            search.evals.fetch_add(1, Ordering::Relaxed);
            objective
                .jacobian(z)
                .unwrap_or_else(|| differences.of(&residuals, z, Some(&unit)))
        };
        let problem = Residuals::new(residuals, dim, Some(&unit), Exact(jacobian));
        side_by_side(&problem, starts, &settings, deadline)
    } else {
        let problem = Residuals::new(residuals, dim, Some(&unit), differences);
        side_by_side(&problem, starts, &settings, deadline)
    };
    ends.into_iter()
        .zip(starts)
        .map(|((stop, descent), start)| {
            let z = descent.v.unwrap_or_else(|| start.clone());
            let cost = objective.mse(&z);
            (stop, z, cost)
        })
        .collect()
}

/// The descents of [`descents`] on `problem`: how each ended (`None`:
/// outpaced) and what it found.
fn side_by_side<P>(
    problem: &P,
    starts: &[Vec<f64>],
    settings: &LmSettings,
    deadline: &Deadline,
) -> Vec<(Option<Stop>, Descent)>
where
    P: LeastSquares<Error = Infallible> + Sync,
{
    let start = |v: &Vec<f64>| match Marquardt::start(problem, v.clone(), settings, deadline) {
        Ok(descent) => descent,
        Err(never) => match never {},
    };
    let mut running: Vec<(Marquardt<'_, P>, Option<Stop>, bool)> = starts
        .par_iter()
        .map(|v| {
            let descent = start(v);
            let stop = descent.stopped();
            (descent, stop, false)
        })
        .collect();
    // Every round advances each running descent by ROUND steps or ends
    // it, so at most `lm_iters / ROUND + 1` rounds run.
    while running
        .iter()
        .any(|(_, stop, outpaced)| stop.is_none() && !outpaced)
    {
        running
            .par_iter_mut()
            .filter(|(_, stop, outpaced)| stop.is_none() && !outpaced)
            .for_each(|(descent, stop, outpaced)| {
                let before = descent.cost();
                *stop = match descent.advance(ROUND) {
                    Ok(stop) => stop,
                    Err(never) => match never {},
                };
                // Stashed in `outpaced` until the round's least cost is known.
                *outpaced = stop.is_none() && descent.cost() > 0.5 * before;
            });
        let least = running
            .iter()
            .map(|(descent, ..)| descent.cost())
            .fold(f64::INFINITY, f64::min);
        for (descent, _, outpaced) in &mut running {
            *outpaced = *outpaced && descent.cost() > OUTPACED * least;
        }
    }
    running
        .into_iter()
        .map(|(descent, stop, outpaced)| (if outpaced { None } else { stop }, descent.finish()))
        .collect()
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
    // The starts descend side by side; their outcomes are offered in start
    // order, so the result is the same for any number of threads. No
    // descent begins after the deadline.
    let at_start: Vec<f64> = starts.par_iter().map(|z| objective.mse(z)).collect();
    let descended = options.lm_iters > 0 && !starts.is_empty();
    let mut outcomes = if descended && !search.ctx.deadline.passed() {
        descents(search, segment, &starts)
    } else {
        Vec::new()
    }
    .into_iter();
    for (start, cost) in starts.into_iter().zip(at_start) {
        best.offer(start, cost);
        let Some((stop, z, cost)) = outcomes.next() else {
            continue;
        };
        log.levenberg_marquardt.push(match stop {
            Some(Stop::Converged) => Termination::Converged,
            Some(Stop::NoDescent) => Termination::NoDecrease,
            Some(Stop::IterationLimit) => Termination::MaxIterations,
            Some(Stop::TimeBudget) => Termination::TimeBudget,
            Some(Stop::Diverged) => Termination::Other,
            None => Termination::Outpaced,
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

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// Two basins in `(x, y)`: left of `x = 0` residuals linear in a
    /// minimum of cost 0 at `(-5, 0)`; right of it Rosenbrock's valley
    /// shifted to `x = 4`, whose floor costs 100 (a constant residual of
    /// 10), and which a descent follows in many small steps.
    fn two_basins(v: &[f64]) -> Option<Vec<f64>> {
        let (x, y) = (v[0], v[1]);
        Some(if x < 0.0 {
            vec![x + 5.0, y, 0.0]
        } else {
            let u = x - 3.0;
            vec![10.0 * (y - u * u), 1.0 - u, 10.0]
        })
    }

    /// The Jacobian of [`two_basins`].
    fn jacobian(v: &[f64]) -> DMatrix<f64> {
        if v[0] < 0.0 {
            DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 0.0, 0.0])
        } else {
            let u = v[0] - 3.0;
            DMatrix::from_row_slice(3, 2, &[-20.0 * u, 10.0, -1.0, 0.0, 0.0, 0.0])
        }
    }

    /// [`side_by_side`] from `starts` on [`two_basins`], on `threads` threads.
    fn run(starts: &[Vec<f64>], threads: usize) -> Vec<(Option<Stop>, Descent)> {
        let problem = Residuals::new(two_basins, 2, None, Exact(jacobian));
        let settings = LmSettings::new(30)
            .with_cost_tolerance(LM_RELATIVE_TOLERANCE)
            .with_damping(Damping::Marquardt);
        let deadline = Deadline::none();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| side_by_side(&problem, starts, &settings, &deadline))
    }

    #[test]
    fn a_descent_far_behind_and_crawling_is_outpaced_after_a_round() {
        let (good, valley) = (vec![-1.0, 2.0], vec![1.8, 1.0]);
        let alone = run(std::slice::from_ref(&valley), 1);
        // Alone, the valley's descent takes more than a round and is never
        // outpaced (its own cost is the least).
        let (stop, descent) = &alone[0];
        assert!(
            stop.is_some() && descent.iterations > ROUND,
            "{stop:?} {descent:?}"
        );
        let both = run(&[valley.clone(), good.clone()], 1);
        let (stop, descent) = &both[0];
        assert_eq!((*stop, descent.iterations), (None, ROUND), "{descent:?}");
        assert!(descent.cost_after >= 100.0);
        // The start that wins descends as it does alone, to the bit.
        let (stop, descent) = &both[1];
        let lone = &run(std::slice::from_ref(&good), 1)[0];
        assert_eq!(*stop, Some(Stop::Converged));
        assert_eq!(
            (stop, &descent.v, descent.iterations),
            (&lone.0, &lone.1.v, lone.1.iterations)
        );
        assert!(descent.cost_after < 1e-20);
        // The rounds, and so the outcomes, do not depend on the threads.
        for threads in [2, 3] {
            let again = run(&[valley.clone(), good.clone()], threads);
            for ((s, d), (t, e)) in both.iter().zip(&again) {
                assert_eq!((s, &d.v, d.iterations), (t, &e.v, e.iterations));
            }
        }
    }
}
