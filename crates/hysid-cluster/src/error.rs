//! The errors of the `cluster` back-end.

use crate::procedure::ProcedureError;
use hysid_core::backend::IdentifyError;

/// What the `cluster` back-end refuses (an [`IdentifyError::Input`]) or
/// fails at (an [`IdentifyError::Failed`]).
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    /// A mode count of zero.
    #[error("the number of modes must be at least 1")]
    NoMode,
    /// A mode count that leaves no ordinary mode beside the stops.
    #[error(
        "{modes} mode(s) requested, but the mode count includes the {stops} saturation mode(s) of the priors: \
         need at least {} for one ordinary mode",
        .stops + 1
    )]
    NoOrdinaryMode {
        /// Modes requested, stops included.
        modes: usize,
        /// Known stops.
        stops: usize,
    },
    /// Orders giving no regressor.
    #[error("method 'cluster' needs at least one regressor (na + nb > 0)")]
    NoRegressor,
    /// Too many regressors for the local datasets.
    #[error("method 'cluster' supports regressors of dimension up to {max}, got {dim}")]
    Dimension {
        /// Regressor dimension.
        dim: usize,
        /// Largest supported.
        max: usize,
    },
    /// Fewer samples than the automatic local dataset size.
    #[error(
        "{samples} samples (regressors) are too few: method 'cluster' needs local datasets of at \
         least n+2 = {} samples (n = {n} parameters besides the constant; automatic c = {c})",
        .n + 2
    )]
    TooFewForLocalDatasets {
        /// Ordinary samples.
        samples: usize,
        /// Regressor dimension.
        n: usize,
        /// The automatic local dataset size.
        c: usize,
    },
    /// More samples than the local datasets can index.
    #[error(
        "{samples} samples: the local datasets index at most 2^32 - 1 (use a subset of the rows)"
    )]
    TooManySamples {
        /// Regression rows.
        samples: usize,
    },
    /// A step of the procedure failed (its least squares, its clustering).
    #[error(transparent)]
    Procedure(ProcedureError),
    /// An exact mode count not reached: too few clusters kept their
    /// discard size.
    #[error(
        "exactly {asked} modes were asked for, but only {found} of the {clusters} clusters kept at least \
         {discard_size} points (the discard size max(c, discard (n+1)), c = {c}): lower c, set \
         discard=0, or give max_modes = {asked} to allow fewer modes"
    )]
    FewerModesFound {
        /// Modes asked for, stops included.
        asked: usize,
        /// Modes found.
        found: usize,
        /// Clusters formed (the ordinary modes asked for).
        clusters: usize,
        /// The discard size.
        discard_size: usize,
        /// The local dataset size.
        c: usize,
    },
    /// An exact mode count exceeded: single linkage with a distance
    /// threshold left more clusters.
    #[error(
        "exactly {asked} modes were asked for, but {found} clusters of at least {discard_size} points \
         are left (single linkage with sl_distance = {}): raise sl_distance, or leave it unset to \
         cut the tree into {clusters} clusters",
        .sl_distance.map_or("none".into(), |t| t.to_string())
    )]
    MoreModesFound {
        /// Modes asked for, stops included.
        asked: usize,
        /// Clusters left.
        found: usize,
        /// Clusters asked of the tree (the ordinary modes asked for).
        clusters: usize,
        /// The discard size.
        discard_size: usize,
        /// The option `sl_distance`.
        sl_distance: Option<f64>,
    },
}

impl From<ClusterError> for IdentifyError {
    /// The orders, the mode count and the record's size are the input's;
    /// the procedure's failures and an exact mode count it does not reach,
    /// the method's.
    fn from(e: ClusterError) -> Self {
        match e {
            ClusterError::Procedure(_)
            | ClusterError::FewerModesFound { .. }
            | ClusterError::MoreModesFound { .. } => IdentifyError::failed(e),
            ClusterError::TooFewForLocalDatasets { .. } => IdentifyError::too_few_samples(e),
            e => IdentifyError::input(e),
        }
    }
}
