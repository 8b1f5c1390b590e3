//! The bounded-error procedure of Bemporad, Garulli, Paoletti and Vicino
//! (IEEE TAC 50(10), 2005) on regression data, without the regions:
//!
//! 1. MIN PFS by greedy MAX FS ([`crate::maxfs`]): extract the `theta`
//!    satisfying the most remaining pairs, make its satisfied samples a mode,
//!    remove them, repeat. The number of modes `s` is an output.
//! 2. Refinement to a fixed point (at most [`MAX_ROUNDS`] rounds): classify
//!    every sample by the set `I_k = {i : |y_k - phi_k' theta_i| <= delta}`
//!    (one mode: assigned; several: undecidable, left out of estimation; none:
//!    infeasible, an outlier), drop modes with too few assigned samples
//!    (beta), re-estimate each mode on its assigned samples, merge the two
//!    closest modes when their relative distance is at most alpha.
//! 3. Final classification with the final parameters; undecidable samples
//!    get the majority label of their [`KNN`] nearest assigned neighbours
//!    (regressor space, standardised), restricted to their candidate modes.
//!
//! Parameter priors ([`Constraints`]): fixed values, bounds and
//! `[[equality]]` entries (one mode's parameters each) restrict every
//! mode's parameter set in MAX FS, refits and merges. Ties couple the
//! modes, which the one-mode-at-a-time extraction cannot impose: the greedy
//! stage runs with ties relaxed (a documented deviation, `docs/bounded.md`),
//! then all modes are fitted jointly under the ties on the greedy
//! classification (the *tie projection*, a joint Chebyshev LP; its error
//! may exceed delta, reported in [`Classification::tie_projection_error`]
//! and, when it does, as a warning in the model's `status`). From then on the
//! refinement re-estimates all modes jointly (accepted only when certified
//! within delta, so every later step keeps the bound), and merges fix the
//! tied parameters at their shared values (ours, `docs/bounded.md`).

use crate::constraints::{Constraints, ModeSpace, least_squares_joint};
use crate::maxfs::{MaxFsSettings, max_fs};
use crate::refit::chebyshev_joint;
use crate::samples::Samples;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// Bound on the refinement rounds (ours; the paper iterates to a fixed point).
pub const MAX_ROUNDS: usize = 30;
/// Neighbours voting for an undecidable sample (ours).
pub const KNN: usize = 5;

/// How each mode is re-estimated on its assigned samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefitKind {
    /// Chebyshev (minimax) LP: certifies `|r| <= delta` on the assigned samples.
    Linf,
    /// Least squares: not certified.
    Ls,
}

/// Settings of the procedure (the back-end's options, resolved).
#[derive(Debug, Clone, PartialEq)]
pub struct ProcedureSettings {
    /// Error bound delta, in output units.
    pub delta: f64,
    /// Thermal relaxation cycles per MAX FS.
    pub cycles: usize,
    /// Initial temperature factor.
    pub t0: f64,
    /// Merge threshold on `|theta_i - theta_j| / min(|theta_i|, |theta_j|)`.
    pub alpha: f64,
    /// Drop modes with fewer than `max(beta N, p)` assigned samples.
    pub beta: f64,
    /// Re-estimation.
    pub refit: RefitKind,
    /// Extra MAX FS starts (local least-squares fits).
    pub restarts: usize,
    /// Upper bound on the modes.
    pub max_modes: Option<usize>,
    /// Exact number of modes (a prior).
    pub exact_modes: Option<usize>,
    /// Seed of the random visiting orders.
    pub seed: u64,
    /// Stop early (best result so far) after this instant.
    pub deadline: Option<Instant>,
    /// Parameter priors (ties, fixed values, bounds); default none.
    pub constraints: Constraints,
}

/// Class of a sample after the final classification.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleClass {
    /// Explained by exactly one mode.
    Assigned,
    /// Explained by several modes; label by nearest neighbours.
    Undecidable,
    /// Explained by no mode: an outlier.
    Infeasible,
}

/// Result of the procedure.
#[derive(Debug, Clone, PartialEq)]
pub struct Classification {
    /// Parameters of each mode.
    pub thetas: Vec<Vec<f64>>,
    /// Mode of each sample (`None` for infeasible samples).
    pub labels: Vec<Option<usize>>,
    /// Class of each sample.
    pub classes: Vec<SampleClass>,
    /// Modes extracted by the greedy MIN PFS, before refinement.
    pub greedy_modes: usize,
    /// Refinement rounds run.
    pub rounds: usize,
    /// True when the refinement reached a fixed point within [`MAX_ROUNDS`].
    pub converged: bool,
    /// Merges done.
    pub merged: usize,
    /// Modes dropped (too few samples).
    pub dropped: usize,
    /// Largest `|residual|` of each mode over the samples labelled with it.
    pub max_residual: Vec<f64>,
    /// True when the deadline cut the procedure short.
    pub stopped_by_deadline: bool,
    /// With ties and several greedy modes: the largest residual of the
    /// joint fit under the ties on the greedy classification. Above delta,
    /// some greedy samples were no longer explained within delta and went
    /// through the refinement again (possibly ending infeasible).
    pub tie_projection_error: Option<f64>,
}

impl Classification {
    /// Number of samples of a class.
    pub fn count(&self, c: SampleClass) -> usize {
        self.classes.iter().filter(|&&x| x == c).count()
    }
}

/// Why the procedure failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProcedureError {
    /// Fewer samples than parameters.
    #[error("{samples} samples for {params} parameters per mode: need more samples")]
    TooFewSamples {
        /// Samples.
        samples: usize,
        /// Parameters per mode.
        params: usize,
    },
    /// Bad setting.
    #[error("{0}")]
    Setting(String),
    /// Prior `modes = s` cannot be met at this delta.
    #[error(
        "delta = {delta} explains the data with {found} mode(s), fewer than the prior modes = {wanted}: lower delta"
    )]
    TooFewModes {
        /// Delta used.
        delta: f64,
        /// Modes found.
        found: usize,
        /// Modes wanted.
        wanted: usize,
    },
    /// No mode found at all.
    #[error("no mode explains at least {min} samples within delta = {delta}")]
    NoMode {
        /// Delta used.
        delta: f64,
        /// Minimum mode size.
        min: usize,
    },
}

fn past(deadline: Option<Instant>) -> bool {
    deadline.is_some_and(|d| Instant::now() >= d)
}

/// Smallest admissible mode size: `max(ceil(beta N), p)`.
pub fn min_mode_size(n: usize, p: usize, beta: f64) -> usize {
    ((beta * n as f64).ceil() as usize).max(p).max(1)
}

/// Runs the procedure on `s`.
pub fn run(s: &Samples, set: &ProcedureSettings) -> Result<Classification, ProcedureError> {
    let n = s.len();
    let p = s.p;
    if !(set.delta.is_finite() && set.delta > 0.0) {
        return Err(ProcedureError::Setting(format!(
            "delta = {} must be a finite number > 0",
            set.delta
        )));
    }
    if n < p {
        return Err(ProcedureError::TooFewSamples {
            samples: n,
            params: p,
        });
    }
    let cap = match (set.max_modes, set.exact_modes) {
        (Some(a), Some(b)) => a.min(b),
        (a, b) => a.or(b).unwrap_or(usize::MAX),
    }
    .max(1);
    let floor = set.exact_modes.unwrap_or(1);
    let min_size = min_mode_size(n, p, set.beta);
    let mut rng = ChaCha8Rng::seed_from_u64(set.seed);
    let mfs = MaxFsSettings {
        delta: set.delta,
        cycles: set.cycles,
        t0: set.t0,
        chebyshev_polish: set.refit == RefitKind::Linf,
        restarts: set.restarts,
    };
    let mut stopped = false;
    let relaxed = set.constraints.mode_space(p, None);

    // 1. Greedy MIN PFS (ties relaxed).
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut remaining: Vec<usize> = (0..n).collect();
    let mut thetas: Vec<Vec<f64>> = Vec::new();
    while thetas.len() < cap && remaining.len() >= min_size {
        if past(set.deadline) && !thetas.is_empty() {
            stopped = true;
            break;
        }
        let fs = max_fs(s, &remaining, &mfs, &relaxed, &mut rng);
        if fs.members.len() < min_size {
            break;
        }
        let mut taken = vec![false; n];
        for &k in &fs.members {
            taken[k] = true;
        }
        remaining.retain(|&k| !taken[k]);
        thetas.push(fs.theta);
        groups.push(fs.members);
    }
    if thetas.is_empty() {
        return Err(ProcedureError::NoMode {
            delta: set.delta,
            min: min_size,
        });
    }
    let greedy_modes = thetas.len();
    // 1b. Tie projection: all modes jointly under the ties.
    let tied = set.constraints.has_ties() && thetas.len() > 1;
    let mut tie_projection_error = None;
    if tied {
        let projected =
            joint_fit(s, &set.constraints, &groups, set.refit, f64::INFINITY).or_else(|| {
                let (par, _) = set.constraints.joint(groups.len())?;
                least_squares_joint(s, &par, &groups)
            });
        let Some(projected) = projected else {
            return Err(ProcedureError::Setting(
                "the joint fit under the [[tie]] priors failed".into(),
            ));
        };
        thetas = projected;
        tie_projection_error = Some(
            groups
                .iter()
                .zip(&thetas)
                .map(|(g, t)| crate::refit::max_residual(s, g, t))
                .fold(0.0, f64::max),
        );
    }
    let space = |thetas: &[Vec<f64>]| {
        if tied {
            set.constraints
                .mode_space(p, thetas.first().map(Vec::as_slice))
        } else {
            relaxed.clone()
        }
    };

    // 2. Refinement.
    let mut prev: Option<Vec<Option<usize>>> = None;
    let (mut rounds, mut converged, mut merged, mut dropped) = (0, false, 0, 0);
    while rounds < MAX_ROUNDS {
        if past(set.deadline) {
            stopped = true;
            break;
        }
        rounds += 1;
        let assigned = assign(s, &thetas, set.delta);
        let mut counts = vec![0usize; thetas.len()];
        for i in assigned.iter().flatten() {
            counts[*i] += 1;
        }
        // Drop the smallest mode below the minimum size (one per round).
        if thetas.len() > floor
            && let Some((i, _)) = counts
                .iter()
                .enumerate()
                .filter(|&(_, &c)| c < min_size)
                .min_by_key(|&(i, &c)| (c, i))
        {
            thetas.remove(i);
            dropped += 1;
            prev = None;
            continue;
        }
        if prev.as_ref() == Some(&assigned) {
            // Same assignment as after the previous re-estimation: the
            // re-estimate would be the same, a fixed point.
            converged = true;
            break;
        }
        // Re-estimate each mode on its assigned samples (with ties: all
        // modes jointly, when every mode has at least p samples).
        if tied {
            let members: Vec<Vec<usize>> = (0..thetas.len())
                .map(|i| (0..n).filter(|&k| assigned[k] == Some(i)).collect())
                .collect();
            if members.iter().all(|g| g.len() >= p)
                && let Some(t) = joint_fit(s, &set.constraints, &members, set.refit, set.delta)
            {
                thetas = t;
            }
        } else {
            for (i, theta) in thetas.iter_mut().enumerate() {
                let members: Vec<usize> = (0..n).filter(|&k| assigned[k] == Some(i)).collect();
                if members.len() < p {
                    continue;
                }
                if let Some(t) = refit(s, &members, set.refit, set.delta, &relaxed) {
                    *theta = t;
                }
            }
        }
        // Merge the closest pair within alpha whose union stays certified
        // (one merge per round).
        if thetas.len() > floor
            && let Some((i, j, t)) = mergeable_pair(s, &thetas, &assigned, set, &space(&thetas))
        {
            thetas[i] = t;
            thetas.remove(j);
            merged += 1;
            prev = None;
            continue;
        }
        prev = Some(assigned);
    }
    // 3. Final classification; a mode left without samples (possible when
    // the round bound stopped the refinement) is removed, since no region
    // can be estimated for it.
    let (mut labels, mut classes) = final_labels(s, &thetas, set.delta);
    for _ in 0..thetas.len() {
        let mut counts = vec![0usize; thetas.len()];
        for l in labels.iter().flatten() {
            counts[*l] += 1;
        }
        let Some(empty) = counts.iter().position(|&c| c == 0) else {
            break;
        };
        if thetas.len() == 1 {
            break;
        }
        thetas.remove(empty);
        dropped += 1;
        (labels, classes) = final_labels(s, &thetas, set.delta);
    }
    if let Some(want) = set.exact_modes
        && thetas.len() < want
    {
        return Err(ProcedureError::TooFewModes {
            delta: set.delta,
            found: thetas.len(),
            wanted: want,
        });
    }
    let mut maxr = vec![0.0; thetas.len()];
    for (k, l) in labels.iter().enumerate() {
        if let Some(i) = *l {
            maxr[i] = f64::max(maxr[i], s.residual(k, &thetas[i]).abs());
        }
    }
    Ok(Classification {
        thetas,
        labels,
        classes,
        greedy_modes,
        rounds,
        converged,
        merged,
        dropped,
        max_residual: maxr,
        stopped_by_deadline: stopped,
        tie_projection_error,
    })
}

/// Re-estimates on `members`; with the Chebyshev fit, the result is only
/// accepted when it certifies `max |r| <= bound` (else `None`: keep the old
/// parameters, which satisfy the bound on these samples by construction).
fn refit(
    s: &Samples,
    members: &[usize],
    kind: RefitKind,
    bound: f64,
    space: &ModeSpace,
) -> Option<Vec<f64>> {
    match kind {
        RefitKind::Linf => {
            let f = space.chebyshev(s, members)?;
            (f.max_residual <= bound || bound.is_infinite()).then_some(f.theta)
        }
        RefitKind::Ls => space.least_squares(s, members),
    }
}

/// Joint re-estimation of all modes on `groups` under the ties: the joint
/// Chebyshev LP, accepted only when it certifies `bound`, or joint least
/// squares (`refit = ls`, not certified).
fn joint_fit(
    s: &Samples,
    c: &Constraints,
    groups: &[Vec<usize>],
    kind: RefitKind,
    bound: f64,
) -> Option<Vec<Vec<f64>>> {
    let (par, bounds) = c.joint(groups.len())?;
    match kind {
        RefitKind::Linf => {
            let f = chebyshev_joint(s, &par, &bounds, groups)?;
            (f.max_residual <= bound || bound.is_infinite()).then_some(f.thetas)
        }
        RefitKind::Ls => least_squares_joint(s, &par, groups),
    }
}

/// `Some(i)` when exactly mode `i` explains sample k within delta.
fn assign(s: &Samples, thetas: &[Vec<f64>], delta: f64) -> Vec<Option<usize>> {
    (0..s.len())
        .map(|k| {
            let mut found = None;
            for (i, t) in thetas.iter().enumerate() {
                if s.residual(k, t).abs() <= delta {
                    if found.is_some() {
                        return None;
                    }
                    found = Some(i);
                }
            }
            found
        })
        .collect()
}

/// Relative distance `|theta_i - theta_j| / min(|theta_i|, |theta_j|)`.
pub fn relative_distance(a: &[f64], b: &[f64]) -> f64 {
    let norm = |t: &[f64]| t.iter().map(|x| x * x).sum::<f64>().sqrt();
    let d: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt();
    let m = norm(a).min(norm(b));
    if m > 0.0 {
        d / m
    } else if d == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

/// The closest pair (i < j) within alpha whose merged re-estimate is
/// acceptable, with that re-estimate. With the Chebyshev refit the merge is
/// accepted only when the union of the two modes' assigned samples stays
/// within delta (so merging never turns explained samples into outliers;
/// ours, see `docs/bounded.md`); with least squares every pair within alpha
/// is merged (the paper's rule).
fn mergeable_pair(
    s: &Samples,
    thetas: &[Vec<f64>],
    assigned: &[Option<usize>],
    set: &ProcedureSettings,
    space: &ModeSpace,
) -> Option<(usize, usize, Vec<f64>)> {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for i in 0..thetas.len() {
        for j in i + 1..thetas.len() {
            let rel = relative_distance(&thetas[i], &thetas[j]);
            if rel <= set.alpha {
                pairs.push((rel, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    for (_, i, j) in pairs {
        let members: Vec<usize> = (0..s.len())
            .filter(|&k| assigned[k] == Some(i) || assigned[k] == Some(j))
            .collect();
        let bound = if set.refit == RefitKind::Linf {
            set.delta
        } else {
            f64::INFINITY
        };
        match refit(s, &members, set.refit, bound, space) {
            Some(t) => return Some((i, j, t)),
            None if set.refit == RefitKind::Ls => return Some((i, j, thetas[i].clone())),
            None => {}
        }
    }
    None
}

/// Final labels: assigned, undecidable (kNN among candidates), infeasible.
fn final_labels(
    s: &Samples,
    thetas: &[Vec<f64>],
    delta: f64,
) -> (Vec<Option<usize>>, Vec<SampleClass>) {
    let n = s.len();
    let d = s.p - 1;
    let cands: Vec<Vec<usize>> = (0..n)
        .map(|k| {
            (0..thetas.len())
                .filter(|&i| s.residual(k, &thetas[i]).abs() <= delta)
                .collect()
        })
        .collect();
    let mut labels: Vec<Option<usize>> =
        cands.iter().map(|c| (c.len() == 1).then(|| c[0])).collect();
    let classes: Vec<SampleClass> = cands
        .iter()
        .map(|c| match c.len() {
            0 => SampleClass::Infeasible,
            1 => SampleClass::Assigned,
            _ => SampleClass::Undecidable,
        })
        .collect();
    // Standardised regressors for the neighbour search.
    let inv = &s.inv_std;
    let assigned: Vec<usize> = (0..n)
        .filter(|&k| classes[k] == SampleClass::Assigned)
        .collect();
    for k in 0..n {
        if classes[k] != SampleClass::Undecidable {
            continue;
        }
        let c = &cands[k];
        let mut near: Vec<(f64, usize)> = assigned
            .iter()
            .filter_map(|&m| {
                let l = labels[m]?;
                c.contains(&l).then(|| {
                    let dist: f64 = (0..d)
                        .map(|j| ((s.row(k)[j] - s.row(m)[j]) * inv[j]).powi(2))
                        .sum();
                    (dist, l)
                })
            })
            .collect();
        let pick = if near.is_empty() {
            // No assigned neighbour among the candidates: smallest residual.
            *c.iter()
                .min_by(|&&a, &&b| {
                    s.residual(k, &thetas[a])
                        .abs()
                        .total_cmp(&s.residual(k, &thetas[b]).abs())
                })
                .expect("undecidable has candidates")
        } else {
            let kk = KNN.min(near.len());
            near.select_nth_unstable_by(kk - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let mut votes = vec![0usize; thetas.len()];
            for &(_, l) in &near[..kk] {
                votes[l] += 1;
            }
            // Most votes; ties to the nearest voter's mode.
            let top = *votes.iter().max().expect("modes");
            near[..kk].sort_by(|a, b| a.0.total_cmp(&b.0));
            near[..kk]
                .iter()
                .find(|&&(_, l)| votes[l] == top)
                .map(|&(_, l)| l)
                .expect("a voter")
        };
        labels[k] = Some(pick);
    }
    (labels, classes)
}
