//! The global stage: argmin's particle swarm (Kennedy and Eberhart 1995) on
//! the segmented simulation error (the free-run one with `segment=0`) in
//! the box `[0, 1]^d`, seeded with `ChaCha8Rng::seed_from_u64(seed)`.

use crate::stages::{Search, SearchFailure, Stage, StageLog, Termination};
use argmin::core::{Executor, State};
use argmin::solver::particleswarm::{Particle, ParticleSwarm};
use hysid_core::backend::IdentifyError;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// What the swarm leaves to the local stages.
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmResult {
    /// The start of the local stages: the swarm's best, or the nominal
    /// values when the swarm did not beat them.
    pub best_z: Vec<f64>,
    /// The swarm's best cost (on its own, segmented, cost).
    pub cost: Option<f64>,
    /// Further starts for the first local stage: the nominal values and the
    /// best other particles, by cost.
    pub extra_starts: Vec<Vec<f64>>,
}

/// Runs the swarm when there is something to search (`d > 0`, `particles`
/// and `swarm_iters` not 0); otherwise the nominal values are the start.
pub fn global_stage(
    search: &Search<'_>,
    nominal_z: &[f64],
    nominal_cost: f64,
    log: &mut StageLog,
) -> Result<SwarmResult, IdentifyError> {
    let options = search.options;
    let d = nominal_z.len();
    let mut result = SwarmResult {
        best_z: nominal_z.to_vec(),
        cost: None,
        extra_starts: Vec::new(),
    };
    if !(d > 0 && options.particles > 0 && options.swarm_iters > 0) {
        return Ok(result);
    }
    let progress = search.ctx.progress;
    progress.start(
        (options.particles * (options.swarm_iters + 1)) as u64,
        "physical: particle swarm",
    );
    let pso: ParticleSwarm<Vec<f64>, f64, ChaCha8Rng> =
        ParticleSwarm::new((vec![0.0; d], vec![1.0; d]), options.particles)
            .with_rng_generator(ChaCha8Rng::seed_from_u64(search.ctx.seed));
    let mut ex = Executor::new(search.problem(options.segment), pso)
        .configure(|s| s.max_iters(options.swarm_iters as u64));
    if let Some(t) = search.timeout() {
        ex = ex.timeout(t);
    }
    let res = ex
        .run()
        .map_err(|e| SearchFailure::solver(Stage::ParticleSwarm, e))?;
    progress.finish();
    let state = res.state();
    log.particle_swarm = Some(Termination::of_argmin(state.get_termination_reason()));
    search.past_deadline(log, Stage::ParticleSwarm);
    if let Some(p) = state.get_best_param() {
        result.cost = Some(p.cost);
        // The swarm's best (on its own cost) replaces the nominal start
        // when its free-run cost is lower.
        if options.segment > 0 || p.cost < nominal_cost {
            result.best_z = clamped(p);
        }
    }
    let population: Vec<&Particle<Vec<f64>, f64>> = state
        .get_population()
        .map(|ps| ps.iter().collect())
        .unwrap_or_default();
    result.extra_starts = extra_starts(&population, nominal_z, &result.best_z, options.starts);
    Ok(result)
}

/// A particle's position, clamped into the box.
fn clamped(p: &Particle<Vec<f64>, f64>) -> Vec<f64> {
    p.position.iter().map(|x| x.clamp(0.0, 1.0)).collect()
}

/// The nominal values `nominal_z` and the best particles of `population`
/// (by cost, distinct positions other than `best_z`), `starts - 1` in all.
fn extra_starts(
    population: &[&Particle<Vec<f64>, f64>],
    nominal_z: &[f64],
    best_z: &[f64],
    starts: usize,
) -> Vec<Vec<f64>> {
    let mut pop: Vec<(f64, Vec<f64>)> = population.iter().map(|p| (p.cost, clamped(p))).collect();
    pop.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut extra = vec![nominal_z.to_vec()];
    for (_, z) in pop {
        if extra.len() + 1 >= starts {
            break;
        }
        if z != best_z && !extra.contains(&z) {
            extra.push(z);
        }
    }
    extra.truncate(starts.saturating_sub(1));
    extra
}
