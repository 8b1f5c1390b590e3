//! The failures of the PWARX pipeline's shared steps, carried by
//! [`hysid_core::backend::IdentifyError::Failed`].

use crate::constrained::EstimationError;

/// A step of the PWARX pipeline that ran and failed.
#[derive(Debug, thiserror::Error)]
pub enum PwarxFailure {
    /// The least squares of the trimmed re-estimation.
    #[error("trimmed re-estimation: {0}")]
    Trim(EstimationError),
    /// The refinement could not start from the fit's parameters.
    #[error("refinement: {0}")]
    RefinementStart(EstimationError),
    /// A hybrid automaton given to the refinement that was not built from
    /// a PWARX model.
    #[error("refinement: the automaton was not built from a PWARX model")]
    AutomatonNotPwarx,
    /// A model given to the refinement that is no PWARX fit.
    #[error("refinement: a {kind} model is not a PWARX fit")]
    NotPwarx {
        /// The model's kind.
        kind: &'static str,
    },
    /// A model given to the refinement that was refined when fitted.
    #[error("refinement: the model was refined when it was fitted")]
    AlreadyRefined,
    /// No mode count of the hold-out choice could be identified and
    /// simulated.
    #[error("no mode count in 1..={max} could be identified and simulated on the hold-out part")]
    NoModeCount {
        /// The largest count tried (the stops included).
        max: usize,
    },
}
