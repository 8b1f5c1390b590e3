//! Refinement of a PWARX partition by **alternation**: the modes'
//! parameters, a softmax gate and the mode of every sample are improved in
//! turn until no sample changes mode.
//!
//! The model is a mixture of affine experts with a softmax gate (Jordan and
//! Jacobs, *Neural Computation* 6(2), 1994): sample `j` belongs to mode `i`
//! with probability `p_i(x_j) = exp f_i(x_j) / sum_k exp f_k(x_j)`, with
//! affine scores `f_i`, and then `y_j = theta_i' [x_j; 1] + e_j`,
//! `e_j ~ N(0, sigma^2)`. With one mode per sample (hard assignment, the
//! classification EM of Celeux and Govaert, *Computational Statistics &
//! Data Analysis* 14(3), 1992) the negative log-likelihood is
//!
//! ```text
//! J = sum_j [ r_{j,l_j}^2 / (2 sigma^2) + (1/2) log sigma^2 + lse_j - f_{l_j}(x_j) ]
//! ```
//!
//! (`r_{j,i} = y_j - theta_i' [x_j; 1]`, `lse_j = log sum_k exp f_k(x_j)`),
//! the cost PARC (Bemporad, IEEE TAC 2023) minimises by the same
//! block-coordinate descent with the residual weight as a tuning constant
//! instead of `1/(2 sigma^2)`. One round is four exact block minimisations
//! of `J`:
//!
//! 1. `fit_parameters`: the parameters of every mode by least squares on
//!    its samples (the back-end's own least squares, under its priors);
//! 2. `noise_variance`: `sigma^2`, the mean squared residual;
//! 3. `fit_gate`: the scores, by multinomial logistic regression of the
//!    labels on the regressors ([`crate::regions::options::RegionMethod::Softmax`],
//!    unbalanced, warm-started from the previous round);
//! 4. `reassign`: every sample to the mode of least
//!    `r_{j,i}^2 / (2 sigma^2) - f_i(x_j)`.
//!
//! So `J` never rises from round to round when the gate is fitted on every
//! sample (up to the gate's small ridge and the tolerance of its Newton
//! method; by default it is fitted on a thinned set,
//! [`AlternationSettings::gate_points`]), and the alternation ends when a
//! round moves no sample, when a mode would keep fewer samples than its
//! least squares needs, at the round bound, or at the deadline. The
//! clustering procedure's weakness that this repairs: local datasets that
//! straddle a boundary give feature vectors between the modes, which
//! K-means may gather into a cluster of their own in place of a small true
//! mode (`docs/cluster.md`).

use crate::regions::estimate;
use crate::regions::options::{RegionFailure, RegionMethod, RegionOptions, SoftmaxSettings};
use hysid_core::backend::{Budget, Deadline, Exhausted, IdentifyError};
use nalgebra::DMatrix;

/// The default of [`AlternationSettings::gate_points`].
pub const GATE_POINTS: usize = 2000;

/// Smallest `sigma^2`, relative to the mean squared target: a noise-free
/// record keeps a finite residual weight.
const VARIANCE_FLOOR: f64 = 1e-24;

/// Settings of [`alternate`].
#[derive(Debug, Clone, PartialEq)]
pub struct AlternationSettings {
    /// Bound on the rounds.
    pub max_rounds: usize,
    /// A mode keeps at least this many samples (its least squares needs
    /// them): a reassignment that would leave fewer is not made, and the
    /// alternation ends.
    pub min_mode_size: usize,
    /// Regressor columns the gate may depend on (the `switching` prior);
    /// `None`: all.
    pub switching: Option<Vec<usize>>,
    /// Ridge of the gate's logistic regression (standardised units).
    pub ridge: f64,
    /// The gate is fitted on at most this many samples (every
    /// `ceil(N / gate_points)`-th, as [`RegionOptions::max_points`] thins):
    /// it is a smooth prior on the modes, and its fit on all samples was
    /// most of the alternation's cost. `None`: every sample, and then `J`
    /// never rises (the gate step is then an exact minimisation).
    pub gate_points: Option<usize>,
    /// No round starts after this instant.
    pub deadline: Deadline,
}

impl AlternationSettings {
    /// `max_rounds` rounds, modes of at least `min_mode_size` samples, the
    /// softmax ridge of the region estimate, a gate fitted on at most
    /// [`GATE_POINTS`] samples, no switching restriction and no deadline.
    pub fn new(max_rounds: usize, min_mode_size: usize) -> Self {
        Self {
            max_rounds,
            min_mode_size,
            switching: None,
            ridge: crate::regions::options::RIDGE,
            gate_points: Some(GATE_POINTS),
            deadline: Deadline::none(),
        }
    }
}

/// Why the alternation ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AlternationStatus {
    /// A round moved no sample: a fixed point of the four steps.
    Converged,
    /// [`AlternationSettings::max_rounds`] rounds were run.
    RoundLimit,
    /// The next assignment would have left a mode with fewer than
    /// [`AlternationSettings::min_mode_size`] samples; the last valid one
    /// is kept.
    ModeTooSmall,
    /// The deadline passed before the alternation ended.
    TimeBudget,
}

/// The round bound of the alternation in every candidate of automatic
/// selection (`hysid identify --auto`) of the back-ends that offer it
/// (`cluster`, `bounded`): on the benchmark systems, where the modes are
/// known, it raised the mode accuracy of `cluster` or left it (B1, H1-H4,
/// the PyPARC-type record), and a one-split search over {0, 50} chose
/// between selection FITs closer than their noise.
pub const AUTO_ROUNDS: usize = 50;

/// What the alternation did, as a back-end's diagnostics record it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AlternationReport {
    /// Rounds run.
    pub rounds: usize,
    /// Samples whose mode it changed.
    pub moved: usize,
    /// Why it ended.
    pub status: AlternationStatus,
}

impl From<&Alternation> for AlternationReport {
    fn from(a: &Alternation) -> Self {
        Self {
            rounds: a.rounds,
            moved: a.moved,
            status: a.status,
        }
    }
}

/// What [`alternate`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Alternation {
    /// Mode of every sample.
    pub labels: Vec<usize>,
    /// The parameters `[theta_i; constant]` fitted to `labels`.
    pub theta: Vec<Vec<f64>>,
    /// Rounds run.
    pub rounds: usize,
    /// Samples whose mode differs from the one they started with.
    pub moved: usize,
    /// `J` after each round's reassignment.
    pub cost: Vec<f64>,
    /// Why it ended.
    pub status: AlternationStatus,
}

/// Alternates from `labels` (modes `0..modes`, each with at least
/// `settings.min_mode_size` samples) on the regressors `x` (one per row)
/// and targets `y`. `fit_parameters` returns the parameters
/// `[theta_i; constant]` of every mode for a labelling; the back-end passes
/// its least squares, so that its priors hold in every round.
pub fn alternate<F>(
    x: &DMatrix<f64>,
    y: &[f64],
    labels: Vec<usize>,
    modes: usize,
    settings: &AlternationSettings,
    mut fit_parameters: F,
) -> Result<Alternation, IdentifyError>
where
    F: FnMut(&[usize]) -> Result<Vec<Vec<f64>>, IdentifyError>,
{
    let initial = labels.clone();
    let mut labels = labels;
    let mut theta = fit_parameters(&labels)?;
    let mut gate_scores: Option<Vec<Vec<f64>>> = None;
    let mut cost = Vec::new();
    let floor = VARIANCE_FLOOR * y.iter().map(|v| v * v).sum::<f64>() / y.len().max(1) as f64;
    let mut budget = Budget::new(settings.max_rounds, &settings.deadline);
    let status = loop {
        if modes < 2 {
            break AlternationStatus::Converged;
        }
        match budget.begin() {
            Err(Exhausted::IterationLimit) => break AlternationStatus::RoundLimit,
            Err(Exhausted::TimeBudget) => break AlternationStatus::TimeBudget,
            Ok(()) => {}
        }
        let residuals = squared_residuals(x, y, &theta);
        let sigma2 = noise_variance(&residuals, &labels, modes).max(floor);
        let scores = fit_gate(x, &labels, modes, settings, gate_scores.take())?;
        let (next, j) = reassign(x, &residuals, sigma2, &scores, modes);
        cost.push(j);
        gate_scores = Some(scores);
        if next == labels {
            break AlternationStatus::Converged;
        }
        if mode_sizes(&next, modes)
            .iter()
            .any(|&k| k < settings.min_mode_size)
        {
            break AlternationStatus::ModeTooSmall;
        }
        labels = next;
        theta = fit_parameters(&labels)?;
    };
    let moved = labels.iter().zip(&initial).filter(|(a, b)| a != b).count();
    Ok(Alternation {
        labels,
        theta,
        rounds: cost.len(),
        moved,
        cost,
        status,
    })
}

/// `r_{j,i}^2` for every sample `j` (row) and mode `i` (column).
fn squared_residuals(x: &DMatrix<f64>, y: &[f64], theta: &[Vec<f64>]) -> DMatrix<f64> {
    let (n, d) = x.shape();
    DMatrix::from_fn(n, theta.len(), |j, i| {
        let t = &theta[i];
        let pred = (0..d).map(|k| x[(j, k)] * t[k]).sum::<f64>() + t[d];
        (y[j] - pred).powi(2)
    })
}

/// Step 2: `sigma^2`, the mean squared residual of the samples in their
/// own modes.
fn noise_variance(residuals: &DMatrix<f64>, labels: &[usize], modes: usize) -> f64 {
    let total: f64 = labels
        .iter()
        .enumerate()
        .filter(|&(_, &l)| l < modes)
        .map(|(j, &l)| residuals[(j, l)])
        .sum();
    total / labels.len().max(1) as f64
}

/// Step 3: the gate's scores `[c_i; c_i0]` (original units), by unbalanced
/// multinomial logistic regression, warm-started from `start`.
fn fit_gate(
    x: &DMatrix<f64>,
    labels: &[usize],
    modes: usize,
    settings: &AlternationSettings,
    start: Option<Vec<Vec<f64>>>,
) -> Result<Vec<Vec<f64>>, IdentifyError> {
    let options = RegionOptions {
        method: RegionMethod::Softmax,
        switching: settings.switching.clone(),
        softmax: SoftmaxSettings {
            balanced: false,
            ridge: settings.ridge,
            start,
        },
        max_points: settings.gate_points,
        ..RegionOptions::default()
    };
    let partition = estimate(x, labels, modes, &options)
        .map_err(|e| IdentifyError::failed(RegionFailure::Gate(e)))?;
    Ok(partition.scores)
}

/// Step 4 (exp and log of the `libm` crate, as in the softmax fit): every
/// sample to the mode of least
/// `r_{j,i}^2 / (2 sigma^2) - f_i(x_j)` (the first on ties), and `J` of
/// that assignment.
fn reassign(
    x: &DMatrix<f64>,
    residuals: &DMatrix<f64>,
    sigma2: f64,
    scores: &[Vec<f64>],
    modes: usize,
) -> (Vec<usize>, f64) {
    let d = x.ncols();
    let half_log = 0.5 * sigma2.ln();
    let mut f = vec![0.0; modes];
    let mut cost = 0.0;
    let labels = (0..x.nrows())
        .map(|j| {
            for (fi, c) in f.iter_mut().zip(scores) {
                *fi = (0..d).map(|k| x[(j, k)] * c[k]).sum::<f64>() + c[d];
            }
            let top = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let lse = top + libm::log(f.iter().map(|v| libm::exp(v - top)).sum::<f64>());
            let (best, value) = (0..modes)
                .map(|i| (i, residuals[(j, i)] / (2.0 * sigma2) - f[i]))
                .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
            cost += value + lse + half_log;
            best
        })
        .collect();
    (labels, cost)
}

fn mode_sizes(labels: &[usize], modes: usize) -> Vec<usize> {
    let mut size = vec![0; modes];
    for &l in labels {
        if let Some(s) = size.get_mut(l) {
            *s += 1;
        }
    }
    size
}
