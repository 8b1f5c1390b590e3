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
//! Parameter priors ([`ModeConstraints`]): fixed values, bounds and
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

use crate::constraints::{ModeConstraints, ModeSpace};
use crate::maxfs::{MaxFsSettings, max_fs};
use crate::refit::chebyshev_joint;
use crate::refit::least_squares_joint;
use crate::samples::Samples;
use crate::split;
use hysid_core::backend::{Budget, Deadline, Exhausted};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

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
    pub deadline: Deadline,
    /// Parameter priors (ties, fixed values, bounds); default none.
    pub constraints: ModeConstraints,
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
    /// Modes added by splitting a mode whose samples lie on pieces that
    /// another mode separates ([`crate::split`]).
    pub split: usize,
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
        "delta = {delta} explains the data with {found} mode(s), fewer than the prior modes = {wanted}{}: {}",
        if *.infeasible > 0 { format!(", and leaves {} of {} samples in no mode", .infeasible, .samples) } else { String::new() },
        if *.stopped_by_deadline {
            "the time budget ended the mode extraction before more were found; give it more time"
        } else if *.constrained && *.infeasible > 0 {
            "lower delta, or check the priors on the modes' parameters ([fixed], [bounds], [[tie]], [[equality]]): they may exclude the modes of the data"
        } else {
            "lower delta"
        }
    )]
    TooFewModes {
        /// Delta used.
        delta: f64,
        /// Modes found.
        found: usize,
        /// Modes wanted.
        wanted: usize,
        /// Samples that no mode explains within delta.
        infeasible: usize,
        /// Samples classified.
        samples: usize,
        /// Whether priors constrain the modes' parameters.
        constrained: bool,
        /// Whether the deadline cut the mode extraction or refinement short.
        stopped_by_deadline: bool,
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

/// Smallest admissible mode size: `max(ceil(beta N), p)`.
pub fn min_mode_size(n: usize, p: usize, beta: f64) -> usize {
    ((beta * n as f64).ceil() as usize).max(p).max(1)
}

/// Runs the procedure on `s` (the steps of the module documentation).
pub fn run(s: &Samples, set: &ProcedureSettings) -> Result<Classification, ProcedureError> {
    let limits = Limits::of(s, set)?;
    let mut rng = ChaCha8Rng::seed_from_u64(set.seed);
    let greedy = greedy_min_pfs(s, set, &limits, &mut rng)?;
    let greedy_modes = greedy.thetas.len();
    let tied = set.constraints.has_ties() && greedy_modes > 1;
    let (thetas, tie_projection_error) = if tied {
        let (thetas, error) = project_on_ties(s, set, &greedy.groups)?;
        (thetas, Some(error))
    } else {
        (greedy.thetas, None)
    };
    let refined = refine(s, set, &limits, thetas, tied);
    let mut last = final_classification(s, set.delta, refined.thetas);
    // Only to honour an exact mode count: splitting every mode whose pieces
    // another mode separates multiplies the modes of noisy records.
    let split = match set.exact_modes {
        Some(want) if last.thetas.len() < want => split::split_separated_modes(
            s,
            &mut last.thetas,
            &mut last.labels,
            limits.min_size,
            want,
        ),
        _ => 0,
    };
    if let Some(want) = set.exact_modes
        && last.thetas.len() < want
    {
        return Err(ProcedureError::TooFewModes {
            delta: set.delta,
            found: last.thetas.len(),
            wanted: want,
            infeasible: (last.classes.iter())
                .filter(|&&c| c == SampleClass::Infeasible)
                .count(),
            samples: last.labels.len(),
            constrained: !set.constraints.is_free(),
            stopped_by_deadline: greedy.stopped || refined.stopped,
        });
    }
    Ok(Classification {
        max_residual: max_residuals(s, &last.thetas, &last.labels),
        thetas: last.thetas,
        labels: last.labels,
        classes: last.classes,
        greedy_modes,
        rounds: refined.rounds,
        converged: refined.converged,
        merged: refined.merged,
        dropped: refined.dropped + last.dropped,
        split,
        stopped_by_deadline: greedy.stopped || refined.stopped,
        tie_projection_error,
    })
}

/// How many modes the procedure may keep, and how small a mode may be.
struct Limits {
    /// Most modes the greedy stage extracts (`max_modes`, `modes`).
    cap: usize,
    /// Fewest modes the refinement keeps by dropping or merging (`modes`).
    floor: usize,
    /// Smallest admissible mode ([`min_mode_size`]).
    min_size: usize,
}

impl Limits {
    fn of(s: &Samples, set: &ProcedureSettings) -> Result<Self, ProcedureError> {
        if s.len() < s.p {
            return Err(ProcedureError::TooFewSamples {
                samples: s.len(),
                params: s.p,
            });
        }
        let cap = match (set.max_modes, set.exact_modes) {
            (Some(a), Some(b)) => a.min(b),
            (a, b) => a.or(b).unwrap_or(usize::MAX),
        };
        Ok(Self {
            cap: cap.max(1),
            floor: set.exact_modes.unwrap_or(1),
            min_size: min_mode_size(s.len(), s.p, set.beta),
        })
    }
}

/// What the greedy MIN PFS extracted.
struct Greedy {
    /// Parameters of each extracted mode.
    thetas: Vec<Vec<f64>>,
    /// The samples each mode satisfied when it was extracted.
    groups: Vec<Vec<usize>>,
    /// True when the deadline ended the extraction.
    stopped: bool,
}

/// Step 1, MIN PFS by greedy MAX FS (Bemporad et al. 2005, section III):
/// the `theta` satisfying the most remaining pairs becomes a mode, its
/// satisfied samples are removed, and so on while a mode of at least the
/// minimum size is found. Ties are relaxed here.
fn greedy_min_pfs(
    s: &Samples,
    set: &ProcedureSettings,
    limits: &Limits,
    rng: &mut ChaCha8Rng,
) -> Result<Greedy, ProcedureError> {
    let n = s.len();
    let mfs = MaxFsSettings {
        delta: set.delta,
        cycles: set.cycles,
        t0: set.t0,
        chebyshev_polish: set.refit == RefitKind::Linf,
        restarts: set.restarts,
    };
    let relaxed = set.constraints.mode_space(s.p, None);
    let mut greedy = Greedy {
        thetas: Vec::new(),
        groups: Vec::new(),
        stopped: false,
    };
    let mut remaining: Vec<usize> = (0..n).collect();
    while greedy.thetas.len() < limits.cap && remaining.len() >= limits.min_size {
        if set.deadline.passed() && !greedy.thetas.is_empty() {
            greedy.stopped = true;
            break;
        }
        let fs = max_fs(s, &remaining, &mfs, &relaxed, rng);
        if fs.members.len() < limits.min_size {
            break;
        }
        let mut taken = vec![false; n];
        for &k in &fs.members {
            taken[k] = true;
        }
        remaining.retain(|&k| !taken[k]);
        greedy.thetas.push(fs.theta);
        greedy.groups.push(fs.members);
    }
    if greedy.thetas.is_empty() {
        return Err(ProcedureError::NoMode {
            delta: set.delta,
            min: limits.min_size,
        });
    }
    Ok(greedy)
}

/// Step 1b, the tie projection: all modes fitted jointly under the ties on
/// the greedy classification `groups` (the joint Chebyshev LP, or joint
/// least squares when it fails). Returns the parameters and their largest
/// residual on the groups.
fn project_on_ties(
    s: &Samples,
    set: &ProcedureSettings,
    groups: &[Vec<usize>],
) -> Result<(Vec<Vec<f64>>, f64), ProcedureError> {
    let projected = joint_fit(s, &set.constraints, groups, set.refit, f64::INFINITY)
        .or_else(|| {
            let (par, _) = set.constraints.joint(groups.len())?;
            least_squares_joint(s, &par, groups)
        })
        .ok_or_else(|| {
            ProcedureError::Setting("the joint fit under the [[tie]] priors failed".into())
        })?;
    let error = groups
        .iter()
        .zip(&projected)
        .map(|(g, t)| crate::refit::max_residual(s, g, t))
        .fold(0.0, f64::max);
    Ok((projected, error))
}

/// What the refinement left.
struct Refined {
    thetas: Vec<Vec<f64>>,
    rounds: usize,
    converged: bool,
    merged: usize,
    dropped: usize,
    /// True when the deadline ended the refinement.
    stopped: bool,
}

/// Step 2, refinement to a fixed point (at most [`MAX_ROUNDS`] rounds):
/// each round classifies the samples by `thetas`, then either drops the
/// smallest mode below the minimum size, or stops at a fixed point, or
/// re-estimates every mode on its assigned samples and merges the closest
/// pair within alpha. With `tied`, the modes share the tied values.
fn refine(
    s: &Samples,
    set: &ProcedureSettings,
    limits: &Limits,
    thetas: Vec<Vec<f64>>,
    tied: bool,
) -> Refined {
    let relaxed = set.constraints.mode_space(s.p, None);
    let mut r = Refined {
        thetas,
        rounds: 0,
        converged: false,
        merged: 0,
        dropped: 0,
        stopped: false,
    };
    let mut prev: Option<Vec<Option<usize>>> = None;
    let mut budget = Budget::new(MAX_ROUNDS, &set.deadline);
    loop {
        if let Err(end) = budget.begin() {
            r.stopped = end == Exhausted::TimeBudget;
            break;
        }
        r.rounds = budget.taken();
        let assigned = assign(s, &r.thetas, set.delta);
        if r.thetas.len() > limits.floor
            && let Some(i) = smallest_short_mode(&assigned, r.thetas.len(), limits.min_size)
        {
            r.thetas.remove(i);
            r.dropped += 1;
            prev = None;
            continue;
        }
        if prev.as_ref() == Some(&assigned) {
            // Same assignment as after the previous re-estimation: the
            // re-estimate would be the same, a fixed point.
            r.converged = true;
            break;
        }
        reestimate(s, set, &mut r.thetas, &assigned, tied, &relaxed);
        if r.thetas.len() > limits.floor
            && let Some((i, j, t)) = mergeable_pair(
                s,
                &r.thetas,
                &assigned,
                set,
                &merge_space(set, &relaxed, s.p, &r.thetas, tied),
            )
        {
            r.thetas[i] = t;
            r.thetas.remove(j);
            r.merged += 1;
            prev = None;
            continue;
        }
        prev = Some(assigned);
    }
    r
}

/// The smallest mode (lowest index among equals) with fewer than
/// `min_size` assigned samples: the one the refinement drops this round.
fn smallest_short_mode(assigned: &[Option<usize>], modes: usize, min_size: usize) -> Option<usize> {
    let mut counts = vec![0usize; modes];
    for i in assigned.iter().flatten() {
        counts[*i] += 1;
    }
    counts
        .iter()
        .enumerate()
        .filter(|&(_, &c)| c < min_size)
        .min_by_key(|&(i, &c)| (c, i))
        .map(|(i, _)| i)
}

/// The parameter set a merged mode is fitted in: with ties, one mode's
/// set with the tied parameters at the values the modes share.
fn merge_space(
    set: &ProcedureSettings,
    relaxed: &ModeSpace,
    p: usize,
    thetas: &[Vec<f64>],
    tied: bool,
) -> ModeSpace {
    if tied {
        set.constraints
            .mode_space(p, thetas.first().map(Vec::as_slice))
    } else {
        relaxed.clone()
    }
}

/// Re-estimates each mode with at least `p` assigned samples on them
/// (with ties: all modes jointly, when every mode has `p` samples); a fit
/// that does not certify delta leaves the mode as it is.
fn reestimate(
    s: &Samples,
    set: &ProcedureSettings,
    thetas: &mut Vec<Vec<f64>>,
    assigned: &[Option<usize>],
    tied: bool,
    relaxed: &ModeSpace,
) {
    let (n, p) = (s.len(), s.p);
    let members_of =
        |i: usize| -> Vec<usize> { (0..n).filter(|&k| assigned[k] == Some(i)).collect() };
    if tied {
        let members: Vec<Vec<usize>> = (0..thetas.len()).map(members_of).collect();
        if members.iter().all(|g| g.len() >= p)
            && let Some(t) = joint_fit(s, &set.constraints, &members, set.refit, set.delta)
        {
            *thetas = t;
        }
        return;
    }
    for (i, theta) in thetas.iter_mut().enumerate() {
        let members = members_of(i);
        if members.len() < p {
            continue;
        }
        if let Some(t) = refit(s, &members, set.refit, set.delta, relaxed) {
            *theta = t;
        }
    }
}

/// The final classification.
struct Final {
    thetas: Vec<Vec<f64>>,
    labels: Vec<Option<usize>>,
    classes: Vec<SampleClass>,
    /// Modes left without samples, removed.
    dropped: usize,
}

/// Step 3, the final classification with the final parameters
/// ([`final_labels`]); a mode left without samples (possible when the round
/// bound stopped the refinement) is removed, since no region can be
/// estimated for it.
fn final_classification(s: &Samples, delta: f64, mut thetas: Vec<Vec<f64>>) -> Final {
    let (mut labels, mut classes) = final_labels(s, &thetas, delta);
    let mut dropped = 0;
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
        (labels, classes) = final_labels(s, &thetas, delta);
    }
    Final {
        thetas,
        labels,
        classes,
        dropped,
    }
}

/// Of `modes`, the one of least `|residual|` at sample `k` (the first
/// among equals); `None` when `modes` is empty.
pub(crate) fn least_residual_mode(
    s: &Samples,
    k: usize,
    thetas: &[Vec<f64>],
    modes: impl IntoIterator<Item = usize>,
) -> Option<usize> {
    modes.into_iter().min_by(|&a, &b| {
        s.residual(k, &thetas[a])
            .abs()
            .total_cmp(&s.residual(k, &thetas[b]).abs())
    })
}

/// Largest `|residual|` of each mode over the samples labelled with it.
pub(crate) fn max_residuals(
    s: &Samples,
    thetas: &[Vec<f64>],
    labels: &[Option<usize>],
) -> Vec<f64> {
    let mut maxr = vec![0.0; thetas.len()];
    for (k, l) in labels.iter().enumerate() {
        if let Some(i) = *l {
            maxr[i] = f64::max(maxr[i], s.residual(k, &thetas[i]).abs());
        }
    }
    maxr
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
    c: &ModeConstraints,
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
            least_residual_mode(s, k, thetas, c.iter().copied())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Too few modes for an exact count: with samples in no mode under
    /// priors on the parameters, the priors are named beside delta.
    #[test]
    fn too_few_modes_names_the_priors_where_samples_fit_no_mode() {
        let e = |infeasible, constrained| {
            ProcedureError::TooFewModes {
                delta: 0.003,
                found: 1,
                wanted: 2,
                infeasible,
                samples: 399,
                constrained,
                stopped_by_deadline: false,
            }
            .to_string()
        };
        assert_eq!(
            e(391, true),
            "delta = 0.003 explains the data with 1 mode(s), fewer than the prior modes = 2, and \
             leaves 391 of 399 samples in no mode: lower delta, or check the priors on the \
             modes' parameters ([fixed], [bounds], [[tie]], [[equality]]): they may exclude \
             the modes of the data"
        );
        assert!(e(391, false).ends_with("samples in no mode: lower delta"));
        assert!(e(0, true).ends_with("fewer than the prior modes = 2: lower delta"));
        // Cut short by the time budget: more time, not another delta.
        let cut = ProcedureError::TooFewModes {
            delta: 0.003,
            found: 1,
            wanted: 2,
            infeasible: 0,
            samples: 399,
            constrained: false,
            stopped_by_deadline: true,
        };
        assert!(
            cut.to_string()
                .ends_with("before more were found; give it more time"),
            "{cut}"
        );
    }
}
