//! Named physical parameters of the models declared by their physics.

use serde::{Deserialize, Serialize};

/// A named physical parameter of a model declared by its physics (a
/// mechanical or gray-box model), with unit, value and bounds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicalParameter {
    /// Name used by the model's elements or expressions and by priors
    /// (`[fixed]`, `[bounds]`, `[[tie]]`).
    pub name: String,
    /// Unit, as text (e.g. `1/s^2`, `mm/s^2`).
    #[serde(default)]
    pub unit: String,
    /// Value: nominal in a declared model, fitted in an identified one.
    pub value: f64,
    /// Admissible range `[low, high]` (search box of the fit).
    pub bounds: [f64; 2],
    /// Known exactly: never fitted.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fixed: bool,
    /// What it is.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub doc: String,
}
