//! What the identification rows say about each parameter. A parameter with
//! no local effect on the simulated output (zero sensitivity) has no
//! standard error, for one of two reasons:
//!
//! - it is **not identifiable** from these rows: a different value changes
//!   nothing on them (a stop the rows never reach). It is kept at its
//!   nominal value, not at wherever the search left it, which the rows did
//!   not choose;
//! - it is a **threshold**: no small change flips an event, but a large one
//!   does (the static friction level decides when the mass breaks away).
//!   Its fitted value stays; it has no local standard error.
//!
//! The two are told apart by moving the parameter back to its nominal
//! value: when the identification cost does not change (relative
//! [`UNCHANGED`]), the rows do not identify it.

use crate::objective::simulation_mse;
use crate::parameters::ParameterMap;
use crate::sensitivity::Sensitivity;
use crate::target::Simulator;
use hysid_model::data::Dataset;
use serde::{Deserialize, Serialize};

/// Largest relative change of the identification cost that counts as none.
pub const UNCHANGED: f64 = 1e-12;

/// What the identification rows determine about a parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Identifiability {
    /// Fitted, with a local standard error.
    Estimated,
    /// Fitted; a threshold without local sensitivity, so no standard error.
    Threshold,
    /// No effect on the identification rows: kept at its nominal value.
    NotIdentifiable,
    /// Fitted, but the standard error could not be computed (a failed
    /// perturbed simulation or a singular Jacobian).
    NoStandardError,
}

/// Per free coordinate of `map`, its [`Identifiability`] at the fitted
/// `values` (cost `cost` on `records`); the coordinates not identifiable are
/// moved to their nominal values in `values`.
pub fn classify(
    model: &dyn Simulator,
    map: &ParameterMap,
    values: &mut [f64],
    cost: f64,
    records: &[Dataset],
    sens: &Sensitivity,
) -> Vec<Identifiability> {
    (0..map.groups.len())
        .map(|gi| {
            if sens.std_errors[gi].is_finite() {
                return Identifiability::Estimated;
            }
            if sens.effect[gi] {
                return Identifiability::NoStandardError;
            }
            let g = &map.groups[gi];
            let [lo, hi] = map.bounds[gi];
            let nominal = map.base[g[0]].clamp(lo, hi);
            let mut moved = values.to_vec();
            for &i in g {
                moved[i] = nominal;
            }
            let changed = simulation_mse(model, &moved, records) - cost;
            if changed.abs() <= UNCHANGED * cost.max(f64::MIN_POSITIVE) {
                values.copy_from_slice(&moved);
                Identifiability::NotIdentifiable
            } else {
                Identifiability::Threshold
            }
        })
        .collect()
}
