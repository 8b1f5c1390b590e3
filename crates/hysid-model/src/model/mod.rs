//! The model kinds every back-end can produce and every simulator can run,
//! with their provenance.
//!
//! - [`PwarxModel`] (`"pwarx"`): modes with a parameter vector and a
//!   polyhedral region in regressor space;
//! - [`HybridAutomaton`] (`"hybrid_automaton"`): discrete modes with affine
//!   dynamics and invariants, and transitions whose guard sets may be
//!   lower-dimensional, each with a reset map;
//! - [`Stop`]: a known saturation of the output, the guard set of a
//!   lower-dimensional mode (Juloski, Heemels, Ferrari-Trecate 2003,
//!   section 5).
//!
//! The tagged `Model` enum that also holds the mechanical kind, and the
//! model files, live in `hysid-core`.

mod automaton;
mod diagnostics;
mod parameter;
mod pwarx;
mod selection;
mod stop;

pub use automaton::{
    AffineDynamics, AutomatonMode, GuardSet, HybridAutomaton, InitialState, InvalidModel,
    OutputMap, ResetMap, TimeDomain, Transition, arx_state_positions,
};
pub use diagnostics::{
    Diagnostics, Refinement, RefinementStatus, RegionRefinement, RegionRefinementStatus, RunStatus,
    Trimming, TrimmingStatus,
};
pub use parameter::{PhysicalParameter, exact_bounds, exact_bounds_by_name};
pub use pwarx::{PwarxMode, PwarxModel, RegionChoice, mode_name, region_of};
pub use selection::{RefinementChoice, RefitStart, ScoredCandidate, Selection, SplitRows};
pub use stop::{Stop, StopBound};

use crate::data::Standardization;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Where a model came from: written into every model file so that a result
/// can be reproduced. Deterministic (no clock time), so the same inputs and
/// seed give byte-identical files.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct ModelInfo {
    /// Back-end that identified it (empty for hand-written models).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub method: String,
    /// The back-end's options as used, after defaults.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub options: BTreeMap<String, serde_json::Value>,
    /// Seed of the run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Input names of the data it was identified on.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub input_names: Vec<String>,
    /// Output name of the data it was identified on.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub output_name: String,
    /// Sampling time of the data, seconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ts: Option<f64>,
    /// Standardisation used during identification. The parameters and
    /// regions in the file are already in original units; this records how
    /// the back-end saw the data.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scaling: Option<Standardization>,
    /// Back-end diagnostics (counts, costs, statuses).
    #[serde(skip_serializing_if = "Diagnostics::is_empty")]
    pub diagnostics: Diagnostics,
    /// How automatic selection chose the options, when it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection: Option<Selection>,
}
