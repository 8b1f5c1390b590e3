//! The restarts of k-LinReg: one restart (steps 1-4 of Lauer 2013), the
//! best of many in parallel, and how many are needed.

use crate::{KLinRegOptions, assign, refit};
use hysid_core::backend::RunContext;
use hysid_estimation::constrained::Parametrisation;
use hysid_model::regressors::Regressors;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Probability of failure that [`restart_count`] accepts (Lauer's `P_f`).
pub const FAILURE_PROBABILITY: f64 = 1e-3;

/// The restarts when the success model gives no chance (Lauer's fallback).
pub const FALLBACK_RESTARTS: usize = 100;

/// One finished restart.
#[derive(Debug, Clone, PartialEq)]
pub struct Restart {
    /// Index of the restart (its random stream).
    pub index: usize,
    /// Parameters of the modes, `[theta_j; constant]`.
    pub thetas: Vec<Vec<f64>>,
    /// Mode of every ordinary sample.
    pub labels: Vec<usize>,
    /// Mean squared residual at the end.
    pub cost: f64,
    /// The cost after each assignment (step 2), in order.
    pub costs: Vec<f64>,
}

/// Step 1: `modes` parameter vectors of `params` entries drawn uniformly in
/// `[-w_max, w_max]` (for the standardised problem, see [`run_restart`]).
pub fn draw_parameters(
    rng: &mut ChaCha8Rng,
    modes: usize,
    params: usize,
    w_max: f64,
) -> Vec<Vec<f64>> {
    (0..modes)
        .map(|_| {
            (0..params)
                .map(|_| rng.random_range(-w_max..=w_max))
                .collect()
        })
        .collect()
}

/// One restart from the random stream `index` of `seed`: draw the
/// parameters of the standardised problem (every regressor and the target
/// at zero mean and unit variance), take them to the record's units and
/// to the nearest point that honours the priors (so that no step can raise
/// the cost), then assign and refit until the assignment repeats (at most `max_iter`
/// refits). `None` when a mode is left with too few samples.
pub fn run_restart(
    reg: &Regressors,
    par: &Parametrisation,
    modes: usize,
    options: &KLinRegOptions,
    seed: u64,
    index: usize,
) -> Option<Restart> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index as u64);
    let drawn = draw_parameters(&mut rng, modes, par.n_params(), options.w_max);
    let mut thetas = par.project(&Scale::of(reg).to_original(drawn)).ok()?;
    let (mut labels, cost) = assign(reg, &thetas);
    let mut costs = vec![cost];
    for _ in 0..options.max_iter {
        thetas = refit(reg, par, &labels, modes)?;
        let (next, cost) = assign(reg, &thetas);
        costs.push(cost);
        if next == labels {
            break;
        }
        labels = next;
    }
    Some(Restart {
        index,
        cost: *costs.last().unwrap_or(&f64::INFINITY),
        thetas,
        labels,
        costs,
    })
}

/// The mean and standard deviation of every regressor and of the
/// target: step 1 draws the parameters of the standardised problem, so
/// that `w_max` means the same for any units (the assignment of step 2 is
/// unchanged by an affine change of units, so this only decides where the
/// restarts begin).
struct Scale {
    x: Vec<(f64, f64)>,
    y: (f64, f64),
}

impl Scale {
    fn of(reg: &Regressors) -> Self {
        let stats = |v: &mut dyn Iterator<Item = f64>, n: usize| {
            let v: Vec<f64> = v.collect();
            let mean = v.iter().sum::<f64>() / n.max(1) as f64;
            let var = v.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / n.max(1) as f64;
            let sd = var.sqrt();
            (mean, if sd > 0.0 && sd.is_finite() { sd } else { 1.0 })
        };
        let n = reg.x.nrows();
        Scale {
            x: (0..reg.x.ncols())
                .map(|j| stats(&mut reg.x.column(j).iter().copied(), n))
                .collect(),
            y: stats(&mut reg.y.iter().copied(), n),
        }
    }

    /// `w . [z; 1]` on standardised `z` and target as `theta . [x; 1]` in
    /// the record's units.
    fn to_original(&self, ws: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        let (my, sy) = self.y;
        ws.into_iter()
            .map(|w| {
                let d = self.x.len();
                let mut theta: Vec<f64> = (0..d).map(|j| sy * w[j] / self.x[j].1).collect();
                let shift: f64 = (0..d).map(|j| w[j] * self.x[j].0 / self.x[j].1).sum();
                theta.push(my + sy * (w[d] - shift));
                theta
            })
            .collect()
    }
}

/// What the restarts gave.
#[derive(Debug, Clone)]
pub struct Restarts {
    /// The restart of least cost (the lowest index among equal costs).
    pub best: Option<Restart>,
    /// Restarts run.
    pub run: usize,
    /// Restarts that failed.
    pub failed: usize,
    /// Restarts within 1e-9 (relative) of the best cost.
    pub at_best: usize,
}

/// `planned` restarts in parallel (rayon), each on its own random stream,
/// so that the result is the same for any number of threads. The first
/// restart always runs; the others not begun when the run's deadline
/// passes are skipped ([`hysid_core::backend::Deadline::admits`]).
pub fn best_restart(
    reg: &Regressors,
    par: &Parametrisation,
    modes: usize,
    planned: usize,
    options: &KLinRegOptions,
    ctx: &RunContext<'_>,
) -> Restarts {
    let outcomes: Vec<Option<Option<Restart>>> = (0..planned)
        .into_par_iter()
        .map(|i| {
            if !ctx.deadline.admits(i) {
                return None;
            }
            Some(run_restart(reg, par, modes, options, ctx.seed, i))
        })
        .collect();
    let run = outcomes.iter().filter(|o| o.is_some()).count();
    let finished: Vec<Restart> = outcomes.into_iter().flatten().flatten().collect();
    let failed = run - finished.len();
    let best = finished
        .iter()
        .min_by(|a, b| a.cost.total_cmp(&b.cost).then(a.index.cmp(&b.index)))
        .cloned();
    let at_best = best.as_ref().map_or(0, |b| {
        let tol = 1e-9 * b.cost.abs().max(f64::MIN_POSITIVE);
        finished.iter().filter(|r| r.cost - b.cost <= tol).count()
    });
    Restarts {
        best,
        run,
        failed,
        at_best,
    }
}

/// Which of Lauer's two fitted models of the success rate applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SuccessModel {
    /// Switched regression with independent regressors.
    Static,
    /// Dynamic systems (regressors of past outputs): what a PWARX record is.
    Dynamic,
}

/// Lauer's model of the probability that one restart finds the global
/// minimum, for `n` samples, `modes` modes and `params` parameters per
/// mode: `P_s = K (1 - exp(-(N - tau) / T))`, clamped to `[0, 1]`, with
/// `m = 2^modes params` and
/// - static: `K = 0.99`, `T = 2.22 m`, `tau = 0.2 m^1.4`;
/// - dynamic: `K = 1.02 - 0.023 modes`, `T = 52 sqrt(m) - 220`,
///   `tau = 1.93 m - 37`.
pub fn success_probability(model: SuccessModel, n: usize, modes: usize, params: usize) -> f64 {
    let m = (2f64).powi(modes as i32) * params as f64;
    let (k, t, tau) = match model {
        SuccessModel::Static => (0.99, 2.22 * m, 0.2 * m.powf(1.4)),
        SuccessModel::Dynamic => (
            1.02 - 0.023 * modes as f64,
            52.0 * m.sqrt() - 220.0,
            1.93 * m - 37.0,
        ),
    };
    if t <= 0.0 {
        return k.clamp(0.0, 1.0);
    }
    (k * (1.0 - (-(n as f64 - tau) / t).exp())).clamp(0.0, 1.0)
}

/// Lauer's number of restarts `r* = ceil(log P_f / log(1 - P_s))` with
/// `P_f` = [`FAILURE_PROBABILITY`] and the dynamic model of
/// [`success_probability`]: [`FALLBACK_RESTARTS`] when `P_s` is 0, one
/// when it is 1.
pub fn restart_count(n: usize, modes: usize, params: usize) -> usize {
    let p = success_probability(SuccessModel::Dynamic, n, modes, params);
    if p <= 0.0 {
        FALLBACK_RESTARTS
    } else if p >= 1.0 {
        1
    } else {
        ((FAILURE_PROBABILITY.ln() / (1.0 - p).ln()).ceil() as usize).max(1)
    }
}
