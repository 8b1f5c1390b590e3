//! Region estimation for hysid: given regressors `x` (one per row) and a mode
//! label per row, find one polyhedral region per mode.
//!
//! This is step 4 of the clustering procedure of Ferrari-Trecate et al.
//! (the founding paper of hysid, Juloski, Heemels and Ferrari-Trecate,
//! ADHS 2003, uses it for the pick-and-place head) and the last step of the
//! bounded-error procedure of Bemporad et al. (2005). Four methods
//! ([`RegionMethod`]):
//!
//! * [`RegionMethod::Mrlp`] (default): the multicategory robust linear
//!   program of Bredensteiner and Bennett (1999), after Bennett and
//!   Mangasarian (1992/1994). One LP on clarabel. The regions are the
//!   argmax partition `{x : f_i(x) >= f_j(x) for all j}` of affine scores
//!   `f_i(x) = w_i.x - g_i`, so they **cover the whole space** (ties only on
//!   boundaries). That removes the holes that made the founding paper's
//!   simulation produce no output.
//! * [`RegionMethod::Msvm`]: the soft-margin multicategory SVM of Weston and
//!   Watkins (1999), a QP on clarabel, again an argmax partition.
//! * [`RegionMethod::Psvc`]: pairwise proximal SVC (Fung and Mangasarian,
//!   2001) in closed form, HIT's default. The regions are intersections of
//!   pairwise half-spaces and may leave holes (`complete = false`); use
//!   [`coverage`] to measure them.
//! * [`RegionMethod::Softmax`]: multinomial logistic regression (the
//!   multinomial-logistic separator of PARC, Bemporad 2023) by damped
//!   Newton: an argmax partition again, linear in `N` and by far the fastest
//!   complete method, but it does not minimise the MRLP objective.
//!
//! The LP and QP are solved by an exact working-set (cutting-plane) scheme:
//! only points whose hinge loss is active matter, so the solver sees a
//! subset and points outside it are checked afterwards; the scheme stops
//! only when every point outside the subset has zero loss, which certifies
//! that the subset optimum is an optimum of the full problem (see
//! `docs/regions.md`). The working set is seeded with the points near the
//! boundaries of a softmax fit (on a sample, its scores rescaled to the
//! program's units). The restricted MRLP is solved by a bounded-variable
//! simplex on its dual, which has only `(modes - 1)(d + 1)` rows and is
//! warm-started from round to round (clarabel is the fallback, and solves
//! the MSVM QP); measured times are in `docs/performance-regions.md`.
//!
//! ```
//! use hysid_estimation::regions::{estimate, RegionOptions};
//! use nalgebra::DMatrix;
//! // two modes on a line, switching at x = 0
//! let x = DMatrix::from_row_slice(6, 1, &[-3.0, -2.0, -1.0, 1.0, 2.0, 3.0]);
//! let labels = [0, 0, 0, 1, 1, 1];
//! let p = estimate(&x, &labels, 2, &RegionOptions::default()).unwrap();
//! assert!(p.complete);
//! assert_eq!(p.training_accuracy, 1.0);
//! assert!(p.regions[0].contains(&[-0.5]) && p.regions[1].contains(&[0.5]));
//! ```

use crate::conic::{self, Program, Settings, Solution, SolveError};
use hysid_core::backend::Deadline;
use hysid_model::geometry::Polyhedron;
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};

pub use adjacency::adjacency;
pub use alternation::{
    AUTO_ROUNDS, Alternation, AlternationReport, AlternationSettings, AlternationStatus,
    GATE_POINTS, alternate,
};
pub use hysid_model::geometry::argmax_regions;

mod adjacency;
mod alternation;
mod psvc;
mod simplex;
mod softmax;
mod working_set;

hysid_core::option_enum! {
    /// How regions are estimated.
    pub enum RegionMethod { /// multicategory robust LP (Bredensteiner & Bennett), complete partition (default)
        Mrlp => "mrlp", /// soft-margin multicategory SVM (Weston & Watkins QP), complete partition
        Msvm => "msvm", /// pairwise proximal SVM (Fung & Mangasarian), HIT parity, may leave holes
        Psvc => "psvc", /// multinomial logistic regression (softmax, damped Newton), complete partition, fastest
        Softmax => "softmax" }
}

// `#[default]` cannot be put on a variant through `option_enum!`.
#[allow(clippy::derivable_impls)]
impl Default for RegionMethod {
    fn default() -> Self {
        RegionMethod::Mrlp
    }
}

impl std::fmt::Display for RegionMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RegionMethod::Mrlp => "mrlp",
            RegionMethod::Msvm => "msvm",
            RegionMethod::Psvc => "psvc",
            RegionMethod::Softmax => "softmax",
        })
    }
}

/// Options of [`estimate`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RegionOptions {
    /// The method. Default [`RegionMethod::Mrlp`].
    pub method: RegionMethod,
    /// Soft-margin weight `C` of [`RegionMethod::Msvm`] (ignored otherwise).
    /// Each slack of a point of mode `i` is weighted by `C N / (s |F_i|)`,
    /// i.e. `C` per point on average with the modes balanced. Default 1.0.
    pub svm_c: f64,
    /// Regressor columns (0-based) the regions may depend on; the normals
    /// are exactly 0 in every other column. `None` (default): all columns.
    pub switching: Option<Vec<usize>>,
    /// Estimate on standardised regressors (zero mean, unit standard
    /// deviation per column) and return the regions in original units.
    /// Default true.
    pub standardize: bool,
    /// The softmax objective (method softmax, and the fallback of MRLP and
    /// MSVM when the time budget ends them). Default: balanced, ridge
    /// `1e-4`.
    #[serde(default)]
    pub softmax: SoftmaxSettings,
    /// Estimate from at most this many points: a larger set is thinned to
    /// every `ceil(N / max_points)`-th point (every point of a mode the
    /// stride would miss is kept), and the training accuracy is still
    /// measured on all points. A linear separator of a few modes in a few
    /// dimensions is fixed long before 10^5 points, and the region step is
    /// then the cost of the PWARX back-ends at N = 10^6
    /// (`docs/regions.md`). `None`: every point. Default
    /// [`DEFAULT_MAX_POINTS`].
    #[serde(default = "default_max_points")]
    pub max_points: Option<usize>,
    /// No working-set round of MRLP or MSVM starts after this instant: the
    /// scores of the last round are kept (still a complete argmax
    /// partition, optimal on the points of that round's working set) and
    /// [`SolveStats::cut_short`] is set. Default none; not serialised.
    #[serde(skip)]
    pub deadline: Deadline,
}

/// The objective of [`RegionMethod::Softmax`], `(1/N) sum_r omega_r NLL_r
/// plus (ridge/2) |w|^2` on standardised regressors (the offsets are not
/// penalised).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SoftmaxSettings {
    /// Weights `omega_r = N / (s |F_{y_r}|)` that balance the modes (the
    /// default); `false`: every point weighs 1 (PARC's separator).
    pub balanced: bool,
    /// Ridge on the normals. Default `1e-4`.
    pub ridge: f64,
    /// Scores to start Newton's method from (a warm start), one `[c; c0]`
    /// per mode in original units as [`Partition::scores`] gives them;
    /// ignored unless there is one per mode. The minimiser is unique, so
    /// only the number of steps depends on it. Default none (zeros).
    #[serde(skip)]
    pub start: Option<Vec<Vec<f64>>>,
}

impl Default for SoftmaxSettings {
    fn default() -> Self {
        Self {
            balanced: true,
            ridge: softmax::RIDGE,
            start: None,
        }
    }
}

/// The default of [`RegionOptions::max_points`].
pub const DEFAULT_MAX_POINTS: usize = 100_000;

fn default_max_points() -> Option<usize> {
    Some(DEFAULT_MAX_POINTS)
}

impl Default for RegionOptions {
    fn default() -> Self {
        Self {
            method: RegionMethod::Mrlp,
            svm_c: 1.0,
            switching: None,
            standardize: true,
            max_points: default_max_points(),
            softmax: SoftmaxSettings::default(),
            deadline: Deadline::none(),
        }
    }
}

/// How the solution was obtained (for reports and benchmarks).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SolveStats {
    /// Number of LP/QP solves (working-set rounds); 0 for closed forms.
    pub solves: usize,
    /// Points in the final working set (all points for closed forms).
    pub working_points: usize,
    /// Total clarabel interior-point iterations.
    pub solver_iterations: u64,
    /// Newton steps of the softmax fit (also used to seed the working set
    /// of mrlp and msvm).
    pub newton_steps: usize,
    /// True when [`RegionOptions::deadline`] ended the working-set rounds
    /// before every point had zero loss (the scores are then not the
    /// program's optimum).
    pub cut_short: bool,
}

/// One region per mode.
#[derive(Debug, Clone, PartialEq)]
pub struct Partition {
    /// One per mode, in ORIGINAL regressor coordinates, `{x : a x <= b}`.
    pub regions: Vec<Polyhedron>,
    /// Fraction of training points inside their own mode's region, with the
    /// first-match rule (the lowest-index region containing a point wins, as
    /// in HIT's `hit_pwa`; points in no region count as wrong).
    pub training_accuracy: f64,
    /// True when the regions cover the whole space by construction (argmax
    /// form; also pairwise PSVC with at most two modes).
    pub complete: bool,
    /// For argmax partitions (mrlp, msvm): per mode the affine score
    /// `f_i(x) = c_i . x + c_i0` in original units, stored as
    /// `[c_i1, ..., c_id, c_i0]`; region `i` is where `f_i` is largest.
    /// Empty for psvc.
    pub scores: Vec<Vec<f64>>,
    /// Solver statistics.
    pub stats: SolveStats,
}

/// Errors of region estimation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RegionError {
    /// `modes` was 0.
    #[error("region estimation needs at least one mode")]
    NoModes,
    /// A mode in `0..modes` has no points.
    #[error("mode {mode} has no points: cannot estimate its region (drop the mode or relabel)")]
    EmptyMode {
        /// The empty mode.
        mode: usize,
    },
    /// A label is not below `modes`.
    #[error("label {label} at row {row} is not below the mode count {modes}")]
    LabelOutOfRange {
        /// Row of the offending label.
        row: usize,
        /// The label.
        label: usize,
        /// The mode count.
        modes: usize,
    },
    /// Inconsistent sizes.
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// [`RegionOptions::deadline`] passed during a solve.
    #[error("{method}: the time budget ended a solve")]
    TimeLimit {
        /// The method.
        method: &'static str,
    },
    /// A regressor entry is NaN or infinite.
    #[error("regressor at row {row}, column {col} is not finite")]
    NonFinite {
        /// Row.
        row: usize,
        /// Column.
        col: usize,
    },
    /// A switching column is out of range or repeated.
    #[error(
        "switching column {col} is invalid for regressors of dimension {dim} (out of range or repeated)"
    )]
    SwitchingColumn {
        /// The column.
        col: usize,
        /// The regressor dimension.
        dim: usize,
    },
    /// An option has an invalid value.
    #[error("invalid region option {key}: {reason}")]
    InvalidOption {
        /// Option name.
        key: &'static str,
        /// Why.
        reason: String,
    },
    /// clarabel refused the problem data or settings.
    #[error("{method}: clarabel refused the problem ({detail})")]
    SolverSetup {
        /// Method name.
        method: &'static str,
        /// clarabel's message.
        detail: String,
    },
    /// clarabel stopped without a solution.
    #[error(
        "{method}: clarabel stopped with status {status} after {iterations} iterations \
         (working set of {points} points, {variables} variables, {rows} rows, round {round})"
    )]
    Solver {
        /// Method name.
        method: &'static str,
        /// clarabel's status, e.g. `MaxIterations`, `NumericalError`.
        status: String,
        /// Iterations done.
        iterations: u32,
        /// Points in the working set.
        points: usize,
        /// Number of variables.
        variables: usize,
        /// Number of constraint rows.
        rows: usize,
        /// Working-set round (1-based).
        round: usize,
    },
    /// A closed-form system could not be solved.
    #[error("{method}: singular linear system for modes {i} and {j}")]
    Singular {
        /// Method name.
        method: &'static str,
        /// First mode.
        i: usize,
        /// Second mode.
        j: usize,
    },
}

/// Where a region program is solved, for error messages.
pub(crate) struct Context {
    pub(crate) method: &'static str,
    pub(crate) points: usize,
    pub(crate) round: usize,
    /// The solve stops here ([`RegionError::TimeLimit`]).
    pub(crate) deadline: Deadline,
}

/// The clarabel settings of every region program: an explicit bound of 300
/// iterations and 3 iterative-refinement steps per linear solve, and the time
/// left before `deadline` (the other fields are clarabel's defaults).
pub(crate) fn solver_settings(deadline: &Deadline) -> Settings {
    let time_limit = deadline
        .remaining()
        .map_or(f64::INFINITY, |d| d.as_secs_f64());
    Settings {
        max_iter: 300,
        iterative_refinement_max_iter: 3,
        time_limit,
        ..Settings::default()
    }
}

/// Solves a region program with [`solver_settings`]. A solution (`Solved`
/// or `AlmostSolved`, the policy of `crate::conic`) is returned;
/// a failure is the [`SolveError`].
pub(crate) fn solve_program(program: Program) -> Result<Solution, SolveError> {
    conic::solve(program, &solver_settings(&Deadline::none()))
}

impl RegionError {
    /// The error of a failed solve of a program with `variables` variables
    /// and `rows` rows, in the context `ctx`.
    pub(crate) fn from_solve(e: SolveError, ctx: &Context, variables: usize, rows: usize) -> Self {
        match e {
            SolveError::Setup(detail) => RegionError::SolverSetup {
                method: ctx.method,
                detail,
            },
            SolveError::TimeLimit { .. } => RegionError::TimeLimit { method: ctx.method },
            e => RegionError::Solver {
                method: ctx.method,
                status: e.status().to_string(),
                iterations: e.iterations(),
                points: ctx.points,
                variables,
                rows,
                round: ctx.round,
            },
        }
    }
}

/// [`solve_program`] with a failure as a [`RegionError`] naming `ctx`.
pub(crate) fn solve_in_context(program: Program, ctx: &Context) -> Result<Solution, RegionError> {
    let (variables, rows) = (program.variables(), program.rows());
    conic::solve(program, &solver_settings(&ctx.deadline))
        .map_err(|e| RegionError::from_solve(e, ctx, variables, rows))
}

/// Standardised, column-selected data: row-major `n x p`.
pub(crate) struct Prepared {
    pub(crate) z: Vec<f64>,
    pub(crate) n: usize,
    pub(crate) p: usize,
    /// Selected original columns.
    pub(crate) cols: Vec<usize>,
    /// Mean and scale of each selected column (`z = (x - mean) / scale`).
    pub(crate) mean: Vec<f64>,
    pub(crate) scale: Vec<f64>,
    /// Points per mode.
    pub(crate) counts: Vec<usize>,
}

impl Prepared {
    pub(crate) fn row(&self, r: usize) -> &[f64] {
        &self.z[r * self.p..(r + 1) * self.p]
    }
}

fn prepare(
    x: &DMatrix<f64>,
    labels: &[usize],
    modes: usize,
    opts: &RegionOptions,
) -> Result<Prepared, RegionError> {
    let (n, d) = x.shape();
    if modes == 0 {
        return Err(RegionError::NoModes);
    }
    if labels.len() != n {
        return Err(RegionError::Shape(format!(
            "{} labels for {n} regressor rows",
            labels.len()
        )));
    }
    for (row, &label) in labels.iter().enumerate() {
        if label >= modes {
            return Err(RegionError::LabelOutOfRange { row, label, modes });
        }
    }
    for col in 0..d {
        for row in 0..n {
            if !x[(row, col)].is_finite() {
                return Err(RegionError::NonFinite { row, col });
            }
        }
    }
    let mut counts = vec![0usize; modes];
    for &l in labels {
        counts[l] += 1;
    }
    if let Some(mode) = counts.iter().position(|&c| c == 0) {
        return Err(RegionError::EmptyMode { mode });
    }
    if !(opts.svm_c.is_finite() && opts.svm_c > 0.0) {
        return Err(RegionError::InvalidOption {
            key: "svm_c",
            reason: format!("must be finite and positive, got {}", opts.svm_c),
        });
    }
    let cols: Vec<usize> = match &opts.switching {
        None => (0..d).collect(),
        Some(s) => {
            let mut seen = vec![false; d];
            for &c in s {
                if c >= d || seen[c] {
                    return Err(RegionError::SwitchingColumn { col: c, dim: d });
                }
                seen[c] = true;
            }
            s.clone()
        }
    };
    let p = cols.len();
    let mut mean = vec![0.0; p];
    let mut scale = vec![1.0; p];
    if opts.standardize {
        for (k, &c) in cols.iter().enumerate() {
            let column = x.column(c);
            let m = column.iter().sum::<f64>() / n as f64;
            let var = column.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n as f64;
            let sd = var.sqrt();
            mean[k] = m;
            // Constant columns are only centred.
            scale[k] = if sd.is_finite() && sd > f64::MIN_POSITIVE * 1e10 {
                sd
            } else {
                1.0
            };
        }
    }
    let mut z = Vec::with_capacity(n * p);
    for r in 0..n {
        for (k, &c) in cols.iter().enumerate() {
            z.push((x[(r, c)] - mean[k]) / scale[k]);
        }
    }
    Ok(Prepared {
        z,
        n,
        p,
        cols,
        mean,
        scale,
        counts,
    })
}

/// Estimates one region per mode from labelled regressors.
///
/// `x` is `N x d` with one regressor per row; `labels[r]` in `0..modes` is
/// the mode of row `r`. Every mode must have at least one point. With
/// `modes == 1` the single region is the whole space.
pub fn estimate(
    x: &DMatrix<f64>,
    labels: &[usize],
    modes: usize,
    opts: &RegionOptions,
) -> Result<Partition, RegionError> {
    if let Some(rows) = opts.max_points.and_then(|m| thinned_rows(labels, modes, m)) {
        let sub_x = x.select_rows(&rows);
        let sub_labels: Vec<usize> = rows.iter().map(|&r| labels[r]).collect();
        let all = RegionOptions {
            max_points: None,
            ..opts.clone()
        };
        let mut partition = estimate(&sub_x, &sub_labels, modes, &all)?;
        partition.training_accuracy = training_accuracy(&partition.regions, x, labels);
        return Ok(partition);
    }
    let prep = prepare(x, labels, modes, opts)?;
    let d = x.ncols();
    if modes == 1 {
        return Ok(Partition {
            regions: vec![Polyhedron::everything()],
            training_accuracy: 1.0,
            complete: true,
            scores: vec![vec![0.0; d + 1]],
            stats: SolveStats {
                working_points: prep.n,
                ..SolveStats::default()
            },
        });
    }
    let (regions, complete, scores, stats) = match opts.method {
        RegionMethod::Mrlp | RegionMethod::Msvm => {
            let (wg, stats) = working_set::solve(&prep, labels, modes, opts)?;
            let scores = scores_in_original_units(&prep, &wg, d);
            (argmax_regions(&scores), true, scores, stats)
        }
        RegionMethod::Softmax => {
            let (wg, steps) = softmax::fit(&prep, labels, modes, &opts.softmax)?;
            let scores = scores_in_original_units(&prep, &wg, d);
            let stats = SolveStats {
                working_points: prep.n,
                newton_steps: steps,
                ..SolveStats::default()
            };
            (argmax_regions(&scores), true, scores, stats)
        }
        RegionMethod::Psvc => {
            let regions = psvc::regions(&prep, labels, modes, d)?;
            let stats = SolveStats {
                working_points: prep.n,
                ..SolveStats::default()
            };
            (regions, modes <= 2, Vec::new(), stats)
        }
    };
    let training_accuracy = training_accuracy(&regions, x, labels);
    Ok(Partition {
        regions,
        training_accuracy,
        complete,
        scores,
        stats,
    })
}

/// The rows [`RegionOptions::max_points`] keeps of `labels.len()` points:
/// every `stride`-th, plus every point of a mode the stride misses; `None`
/// when there are at most `max_points` points (or `max_points` is 0).
fn thinned_rows(labels: &[usize], modes: usize, max_points: usize) -> Option<Vec<usize>> {
    let n = labels.len();
    if max_points == 0 || n <= max_points {
        return None;
    }
    let stride = n.div_ceil(max_points);
    let mut rows: Vec<usize> = (0..n).step_by(stride).collect();
    let mut seen = vec![false; modes];
    for &r in &rows {
        if let Some(s) = seen.get_mut(labels[r]) {
            *s = true;
        }
    }
    if seen.iter().any(|s| !s) {
        rows.extend((0..n).filter(|&r| labels[r] < modes && !seen[labels[r]]));
        rows.sort_unstable();
    }
    Some(rows)
}

/// The regions of a PWARX back-end's final assignment: [`estimate`] with
/// `method`, the normals restricted to the `switching` regressors of the
/// priors, and the error worded for the run.
pub fn for_pwarx(
    method: RegionMethod,
    data: &crate::pwarx::PwarxData<'_>,
    reg: &hysid_model::regressors::Regressors,
    labels: &[usize],
    modes: usize,
) -> Result<Partition, hysid_core::backend::IdentifyError> {
    let options = RegionOptions {
        method,
        switching: data.switching.clone(),
        ..Default::default()
    };
    estimate(&reg.x, labels, modes, &options)
        .map_err(|e| hysid_core::backend::IdentifyError::failed(format!("regions: {e}")))
}

/// `wg` holds per mode `[w (p); g]` on standardised selected columns, with
/// `f(z) = w.z - g`. Returns `[c (d); c0]` with `f = c.x + c0` in original
/// units and exact zeros outside the selected columns.
fn scores_in_original_units(prep: &Prepared, wg: &[Vec<f64>], d: usize) -> Vec<Vec<f64>> {
    wg.iter()
        .map(|v| {
            let mut c = vec![0.0; d + 1];
            let mut c0 = -v[prep.p];
            for k in 0..prep.p {
                let ck = v[k] / prep.scale[k];
                c[prep.cols[k]] = ck;
                c0 -= ck * prep.mean[k];
            }
            c[d] = c0;
            c
        })
        .collect()
}

/// The first region (lowest index) that contains `z`, as HIT's `hit_pwa`.
pub fn classify(regions: &[Polyhedron], z: &[f64]) -> Option<usize> {
    regions.iter().position(|r| r.contains(z))
}

/// The first region containing `z`, or else the region it violates least
/// ([`Polyhedron::violation`], Euclidean distance to the violated rows; ties
/// to the lowest index): a "nearest region" policy for points in holes.
/// `None` only when `regions` is empty.
/// The rule of `hysid_model::model::region_of`, which simulation uses.
pub fn classify_nearest(regions: &[Polyhedron], z: &[f64]) -> Option<usize> {
    (!regions.is_empty()).then(|| hysid_model::model::region_of(regions, z).mode)
}

/// Fraction of rows of `x` whose first-match region is their label.
pub fn training_accuracy(regions: &[Polyhedron], x: &DMatrix<f64>, labels: &[usize]) -> f64 {
    let n = x.nrows().min(labels.len());
    if n == 0 {
        return 1.0;
    }
    let mut row = vec![0.0; x.ncols()];
    let mut ok = 0usize;
    for (r, &label) in labels.iter().enumerate().take(n) {
        for (k, v) in row.iter_mut().enumerate() {
            *v = x[(r, k)];
        }
        if classify(regions, &row) == Some(label) {
            ok += 1;
        }
    }
    ok as f64 / n as f64
}

/// Result of [`coverage`].
#[derive(Debug, Clone, PartialEq)]
pub struct CoverageReport {
    /// Number of sampled points.
    pub samples: usize,
    /// Fraction of samples in no region (holes).
    pub uncovered_fraction: f64,
    /// Fraction of samples in two or more regions (overlaps; for exact
    /// partitions only boundary points, which have probability zero).
    pub multiply_covered_fraction: f64,
}

/// Holes report: `samples` uniform points in the box `[lo, hi]` (seeded
/// with `ChaCha8Rng::seed_from_u64(seed)`), counted as uncovered (in no
/// region) or multiply covered (in two or more), with the membership
/// tolerance of [`Polyhedron::contains`]. The box dimension is
/// `min(lo.len(), hi.len())`; a side with `lo > hi` is sampled in
/// `[hi, lo]`.
pub fn coverage(
    regions: &[Polyhedron],
    lo: &[f64],
    hi: &[f64],
    samples: usize,
    seed: u64,
) -> CoverageReport {
    let d = lo.len().min(hi.len());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut z = vec![0.0; d];
    let (mut none, mut many) = (0usize, 0usize);
    for _ in 0..samples {
        for k in 0..d {
            let u: f64 = rng.random();
            let (a, b) = if lo[k] <= hi[k] {
                (lo[k], hi[k])
            } else {
                (hi[k], lo[k])
            };
            z[k] = a + u * (b - a);
        }
        let hits = regions.iter().filter(|r| r.contains(&z)).take(2).count();
        match hits {
            0 => none += 1,
            1 => {}
            _ => many += 1,
        }
    }
    let frac = |c: usize| {
        if samples == 0 {
            0.0
        } else {
            c as f64 / samples as f64
        }
    };
    CoverageReport {
        samples,
        uncovered_fraction: frac(none),
        multiply_covered_fraction: frac(many),
    }
}

#[cfg(test)]
mod tests {
    //! The region programs are feasible by construction (soft margins) and
    //! no option reaches the iteration bound, so the failure statuses are
    //! reached here, on a small program, through the `solve_in_context`
    //! the working-set scheme calls. The status mapping itself is tested in
    //! `crate::conic`.
    use super::*;
    use crate::conic::{Cone, Triplets};

    const CTX: Context = Context {
        method: "test",
        points: 7,
        round: 2,
        deadline: hysid_core::backend::Deadline::none(),
    };

    /// `min x1 + x2` subject to `lo <= x <= hi` (as `A x + s = b`, `s >= 0`).
    fn boxed(lo: f64, hi: f64) -> Program {
        let mut a = Triplets::default();
        for j in 0..2 {
            a.push(2 * j, j, -1.0); // -x + s = -lo
            a.push(2 * j + 1, j, 1.0); // x + s = hi
        }
        Program {
            p: Triplets::default(),
            q: vec![1.0, 1.0],
            a,
            b: vec![-lo, hi, -lo, hi],
            cones: vec![Cone::Nonnegative(4)],
        }
    }

    #[test]
    fn a_feasible_program_is_solved() {
        let s = solve_in_context(boxed(0.5, 2.0), &CTX).unwrap();
        assert!(s.x.iter().all(|x| (x - 0.5).abs() < 1e-6), "{:?}", s.x);
    }

    #[test]
    fn an_infeasible_program_is_an_error_naming_the_status() {
        let Err(e) = solve_in_context(boxed(2.0, 0.5), &CTX) else {
            panic!("an infeasible program was solved");
        };
        let m = e.to_string();
        assert!(
            matches!(&e, RegionError::Solver { status, .. } if status == "PrimalInfeasible"),
            "{m}"
        );
        assert!(
            m.starts_with("test: clarabel stopped with status PrimalInfeasible after "),
            "{m}"
        );
        assert!(
            m.contains("working set of 7 points, 2 variables, 4 rows, round 2"),
            "{m}"
        );
    }

    #[test]
    fn the_iteration_bound_is_an_error_naming_the_status() {
        let settings = Settings {
            max_iter: 1,
            ..solver_settings(&hysid_core::backend::Deadline::none())
        };
        let e = conic::solve(boxed(0.5, 2.0), &settings).unwrap_err();
        let e = RegionError::from_solve(e, &CTX, 2, 4);
        assert!(
            e.to_string()
                .starts_with("test: clarabel stopped with status MaxIterations after 1 iterations"),
            "{e}"
        );
    }

    #[test]
    fn a_refused_program_is_a_setup_error() {
        let mut prog = boxed(0.5, 2.0);
        prog.cones = vec![Cone::Nonnegative(3)];
        let Err(e) = solve_in_context(prog, &CTX) else {
            panic!("a program with inconsistent dimensions was solved");
        };
        assert!(matches!(e, RegionError::SolverSetup { .. }), "{e}");
        assert!(
            e.to_string()
                .starts_with("test: clarabel refused the problem ("),
            "{e}"
        );
    }
}
