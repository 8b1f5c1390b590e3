//! What a region estimate is asked to do ([`RegionMethod`],
//! [`RegionOptions`]) and what it gives ([`Partition`], [`RegionError`]).

use hysid_core::backend::Deadline;
use hysid_model::geometry::Polyhedron;

/// Ridge on the normals of the softmax fit (standardised units).
pub const RIDGE: f64 = 1e-4;

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

/// Options of [`estimate`](crate::regions::estimate).
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
            ridge: RIDGE,
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

/// A region estimation that ran inside a method and failed, carried by
/// [`hysid_core::backend::IdentifyError::Failed`].
#[derive(Debug, thiserror::Error)]
pub enum RegionFailure {
    /// The regions of the modes' samples.
    #[error("regions: {0}")]
    Estimate(RegionError),
    /// The gate of the alternation.
    #[error("alternation gate: {0}")]
    Gate(RegionError),
}

/// Errors of region estimation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RegionError {
    /// `modes` was 0.
    #[error("region estimation needs at least one mode")]
    NoModes,
    /// A mode in `0..modes` has no points.
    #[error(
        "mode {} has no points: cannot estimate its region (drop the mode or relabel)",
        .mode + 1
    )]
    EmptyMode {
        /// The empty mode (from 0; shown from 1).
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
