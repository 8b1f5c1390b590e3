//! MAX FS of the complementary inequality pairs `|y_k - phi_k' theta| <= delta`
//! by randomized thermal relaxation (Amaldi and Mattavelli, "The MIN PFS
//! problem and piecewise linear model estimation", Discrete Applied
//! Mathematics 118, 2002; used by Bemporad et al. 2005, section III).
//!
//! One call finds a `theta` satisfying as many pairs of the given samples as
//! it can. Cycle `c = 0 .. C-1` runs at temperature `T_c = (1 - c/C) T0` and
//! visits the samples in a fresh random order; a sample with violation
//! `v = |r_k| - delta > 0` (`r_k = y_k - phi_k' theta`) moves `theta` by
//!
//! `theta += sign(r_k) * lambda_c(v) * T_c * phi_k / |phi_k|^2`,
//! `lambda_c(v) = (T_c / T0) * exp(-v / T_c)`,
//!
//! so that the residual of sample k moves by `lambda_c(v) T_c` towards the
//! slab: the step decays with the violation (samples far away probably
//! belong to another mode) and with the temperature, while nearly satisfied
//! samples pull hardest. `lambda_c` is Amaldi and Mattavelli's; the
//! normalisation `phi_k / |phi_k|^2` and the factor `T_c` (output units) are
//! ours, and make the step independent of the units of `phi` and `y`. The
//! iterate satisfying the most pairs (counted after each cycle) is kept.
//!
//! Ours as well (documented in `docs/bounded.md`):
//! - starts: the least-squares fit of the samples (as in the paper's
//!   recollection) and the best of `restarts` least-squares fits of random
//!   local neighbourhoods ([`LOCAL_FACTOR`]` * p` nearest samples in
//!   standardised regressor space), ranked after a least-squares polish;
//!   both are relaxed and the better result wins. From the least-squares
//!   start alone the relaxation often freezes at a compromise between two
//!   modes (B1, N = 300: 27 of 176 samples instead of 98, for every `t0` in
//!   {0.5, 1, 2, 5} and `cycles` in {50, 100, 400} we tried);
//! - `T0 = t0 * max(median |r_k(start)|, delta)`;
//! - after each relaxation a least-squares *polish* alternates "refit on the
//!   satisfied set" and "recompute the satisfied set" (at most
//!   [`POLISH_ITERATIONS`] times, the best set kept); the winning start is
//!   polished again with the Chebyshev fit, under which the satisfied set can
//!   only grow (the minimax fit of a feasible set is feasible on it).
//!
//! Parameter priors ([`ModeSpace`]): every fit above is done within
//! the mode's parameter set (fixed values substituted, bounds through the
//! QP/LP), and the relaxation step moves only the free parameters,
//! normalised by the norm of their regressors, then projects onto the bounds
//! (ours).

use crate::constraints::ModeSpace;
use crate::samples::{Samples, dot};
use hysid_model::statistics::upper_median;
use rand::Rng;
use rand::seq::SliceRandom;

/// Bound on the polish iterations after the relaxation.
pub const POLISH_ITERATIONS: usize = 20;
/// Size of the local neighbourhood of a restart, in multiples of `p`.
pub const LOCAL_FACTOR: usize = 3;

/// Settings of one MAX FS solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaxFsSettings {
    /// Error bound.
    pub delta: f64,
    /// Relaxation cycles `C`.
    pub cycles: usize,
    /// Initial temperature as a multiple of `max(median |r_LS|, delta)`.
    pub t0: f64,
    /// Polish the winner with the Chebyshev fit (true) or not.
    pub chebyshev_polish: bool,
    /// Starts besides the least-squares one: least-squares fits of random
    /// local neighbourhoods.
    pub restarts: usize,
}

/// A feasible subsystem: parameters and the samples they satisfy.
#[derive(Debug, Clone, PartialEq)]
pub struct FeasibleSubsystem {
    /// Parameters.
    pub theta: Vec<f64>,
    /// Satisfied samples (subset of the input indices, increasing).
    pub members: Vec<usize>,
}

/// Greedy MAX FS on samples `idx` (see the module documentation).
pub fn max_fs<R: Rng>(
    s: &Samples,
    idx: &[usize],
    set: &MaxFsSettings,
    space: &ModeSpace,
    rng: &mut R,
) -> FeasibleSubsystem {
    let p = s.p;
    let delta = set.delta;
    let mut order: Vec<usize> = idx.to_vec();
    // The least-squares start, and the best local start after a
    // least-squares polish (cheap), are relaxed.
    let mut starts: Vec<Vec<f64>> = Vec::with_capacity(2);
    if let Some(ls) = space.least_squares(s, idx) {
        starts.push(ls);
    }
    let mut best_local: Option<(usize, Vec<f64>)> = None;
    for _ in 0..set.restarts {
        let Some(start) = local_start(s, idx, space, rng) else {
            continue;
        };
        let (count, theta) = polish(s, idx, start, delta, false, space);
        if best_local.as_ref().is_none_or(|b| count > b.0) {
            best_local = Some((count, theta));
        }
    }
    starts.extend(best_local.map(|b| b.1));
    let mut best: Option<(usize, Vec<f64>)> = None;
    for start in &starts {
        let theta = relax(s, idx, start, set, space, &mut order, rng);
        let (count, theta) = polish(s, idx, theta, delta, false, space);
        if best.as_ref().is_none_or(|b| count > b.0) {
            best = Some((count, theta));
        }
    }
    let mut theta = best.map(|b| b.1).unwrap_or_else(|| vec![0.0; p]);
    space.project_exact(&mut theta);
    let theta = if set.chebyshev_polish {
        polish(s, idx, theta, delta, true, space).1
    } else {
        theta
    };
    let members = s.satisfied(idx, &theta, delta);
    FeasibleSubsystem { theta, members }
}

/// Least-squares fit of the `LOCAL_FACTOR * p` samples nearest (standardised
/// regressor space) to a random sample of `idx`.
fn local_start<R: Rng>(
    s: &Samples,
    idx: &[usize],
    space: &ModeSpace,
    rng: &mut R,
) -> Option<Vec<f64>> {
    let p = s.p;
    let local = (LOCAL_FACTOR * p).min(idx.len());
    if local < p || idx.is_empty() {
        return None;
    }
    let centre = idx[rng.random_range(0..idx.len())];
    let inv = &s.inv_std;
    let c = s.row(centre);
    let mut dist: Vec<(f64, usize)> = idx
        .iter()
        .map(|&k| {
            let row = s.row(k);
            let d: f64 = (0..p - 1).map(|j| ((row[j] - c[j]) * inv[j]).powi(2)).sum();
            (d, k)
        })
        .collect();
    dist.select_nth_unstable_by(local - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let near: Vec<usize> = dist[..local].iter().map(|&(_, k)| k).collect();
    space.least_squares(s, &near)
}

/// Thermal relaxation from `start`; returns the best iterate.
fn relax<R: Rng>(
    s: &Samples,
    idx: &[usize],
    start: &[f64],
    set: &MaxFsSettings,
    space: &ModeSpace,
    order: &mut [usize],
    rng: &mut R,
) -> Vec<f64> {
    let delta = set.delta;
    let count = |theta: &[f64]| {
        idx.iter()
            .filter(|&&k| s.residual(k, theta).abs() <= delta)
            .count()
    };
    let mut abs_r: Vec<f64> = idx.iter().map(|&k| s.residual(k, start).abs()).collect();
    let mut best = (count(start), start.to_vec());
    if abs_r.is_empty() || best.0 == idx.len() {
        return best.1;
    }
    let median = upper_median(&mut abs_r).unwrap_or(0.0);
    let t0 = set.t0 * median.max(delta);
    let mut theta = start.to_vec();
    let movable = space.movable();
    let constrained = !space.is_free();
    let cycles = set.cycles.max(1);
    for c in 0..cycles {
        let tc = (1.0 - c as f64 / cycles as f64) * t0;
        order.shuffle(rng);
        for &k in order.iter() {
            let phi = s.row(k);
            let r = s.y[k] - dot(phi, &theta);
            let v = r.abs() - delta;
            if v <= 0.0 {
                continue;
            }
            let nn: f64 = phi
                .iter()
                .zip(&movable)
                .filter(|(_, m)| **m)
                .map(|(x, _)| x * x)
                .sum();
            if nn <= 0.0 {
                continue;
            }
            // lambda_c(v) T_c: the residual of sample k moves by eta.
            let eta = (tc / t0) * (-v / tc).exp() * tc;
            let step = r.signum() * eta / nn;
            for ((t, x), m) in theta.iter_mut().zip(phi).zip(&movable) {
                if *m {
                    *t += step * x;
                }
            }
            if constrained {
                space.project(&mut theta);
            }
        }
        if theta.iter().any(|t| !t.is_finite()) {
            theta.clone_from(&best.1);
            continue;
        }
        let n = count(&theta);
        if n > best.0 {
            best = (n, theta.clone());
        }
    }
    best.1
}

/// Alternates "refit on the satisfied set" and "recompute the satisfied
/// set" (at most [`POLISH_ITERATIONS`] times); returns the best count and
/// parameters. With the Chebyshev fit the set never shrinks.
fn polish(
    s: &Samples,
    idx: &[usize],
    theta: Vec<f64>,
    delta: f64,
    chebyshev_fit: bool,
    space: &ModeSpace,
) -> (usize, Vec<f64>) {
    let p = s.p;
    let mut members = s.satisfied(idx, &theta, delta);
    let mut theta = theta;
    for _ in 0..POLISH_ITERATIONS {
        if members.len() < p {
            break;
        }
        let next = if chebyshev_fit {
            space.chebyshev(s, &members).map(|f| f.theta)
        } else {
            space.least_squares(s, &members)
        };
        let Some(next) = next else { break };
        let grown = s.satisfied(idx, &next, delta);
        let better = grown.len() > members.len();
        if better || (chebyshev_fit && grown.len() == members.len()) {
            members = grown;
            theta = next;
        }
        if !better {
            break;
        }
    }
    (members.len(), theta)
}
