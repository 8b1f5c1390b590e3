//! The global stage: argmin's particle swarm (Kennedy and Eberhart 1995) on
//! the segmented simulation error (the free-run one with `segment=0`) in
//! the box `[0, 1]^d`, seeded with `ChaCha8Rng::seed_from_u64(seed)`; and
//! the rule that skips it where the nominal values need no global search.

use crate::diagnostics::SwarmSkipped;
use crate::local::Descended;
use crate::stages::{Search, SearchFailure, Stage, StageLog, Termination};
use argmin::core::{Executor, State};
use argmin::solver::particleswarm::{Particle, ParticleSwarm};
use hysid_core::backend::IdentifyError;
use hysid_numerics::least_squares::Stop;
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

impl SwarmResult {
    /// The local stages start from `descended`'s end alone (the swarm
    /// skipped).
    pub fn skipped(descended: &Descended) -> Self {
        SwarmResult {
            best_z: descended.z.clone(),
            cost: None,
            extra_starts: Vec::new(),
        }
    }
}

/// The cost below which [`nominal_suffices`] skips the swarm: `factor`
/// times the output noise variance `noise^2`
/// ([`crate::objective::VelocityTolerances::noise`]).
pub fn noise_floor(noise: f64, factor: f64) -> f64 {
    factor * noise * noise
}

/// The rule that skips the swarm: Levenberg-Marquardt from the nominal
/// values on the free-run cost (`descended`) ended by its own tests
/// (converged, or no step lowers the cost) at a cost of at most `floor`
/// ([`noise_floor`]). The free-run cost of the parameters that made a
/// record is about its noise variance, and no search lowers it by more
/// than the noise allows, so the swarm could only find another parameter
/// set of about the same cost. A floor of 0 (`factor = 0`, or no noise)
/// never skips.
pub fn nominal_suffices(descended: &Descended, floor: f64) -> Option<SwarmSkipped> {
    let ended = matches!(descended.stop, Stop::Converged | Stop::NoDescent);
    (floor > 0.0 && ended && descended.cost <= floor).then_some(SwarmSkipped {
        nominal_descent_cost: descended.cost,
        noise_floor: floor,
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    fn descended(stop: Stop, cost: f64) -> Descended {
        Descended {
            stop,
            z: vec![0.4],
            cost,
        }
    }

    #[test]
    fn the_swarm_is_skipped_only_after_a_descent_that_ended_at_the_noise() {
        // noise 0.1: the floor of factor 1.5 is 0.015.
        let skip =
            |stop, cost, factor| nominal_suffices(&descended(stop, cost), noise_floor(0.1, factor));
        let s = skip(Stop::Converged, 0.012, 1.5).unwrap();
        assert_eq!(s.nominal_descent_cost, 0.012);
        assert!((s.noise_floor - 0.015).abs() < 1e-15);
        assert!(skip(Stop::NoDescent, 0.012, 1.5).is_some());
        // Above the floor, or a descent its tests did not end.
        assert!(skip(Stop::Converged, 0.016, 1.5).is_none());
        for stop in [Stop::IterationLimit, Stop::TimeBudget, Stop::Diverged] {
            assert!(skip(stop, 0.001, 1.5).is_none(), "{stop:?}");
        }
        // Factor 0 never skips, a perfect fit included.
        assert!(skip(Stop::Converged, 0.0, 0.0).is_none());
        let skipped = SwarmResult::skipped(&descended(Stop::Converged, 0.0));
        assert_eq!(skipped.best_z, vec![0.4]);
        assert!(skipped.extra_starts.is_empty());
    }
}
