//! Known saturations of the output (mechanical stops).

use serde::{Deserialize, Serialize};

/// Which side of the level the output stays on at a stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopBound {
    /// The output never exceeds the level.
    Max,
    /// The output never goes below the level.
    Min,
}

impl StopBound {
    /// Its name in files: `"max"` or `"min"`.
    pub fn name(self) -> &'static str {
        match self {
            StopBound::Max => "max",
            StopBound::Min => "min",
        }
    }
}

/// A known saturation: the output's value at a mechanical stop. In a prior
/// file it is a `[[saturation]]` entry; in a hybrid automaton it becomes a
/// mode on the guard set `y = level`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stop {
    /// Output value at the stop.
    pub level: f64,
    /// Side.
    pub bound: StopBound,
    /// How close to the level (or beyond it, on the stop's side) an output
    /// sample must be to count as saturated. Default
    /// [`Stop::DEFAULT_TOL`] `* (1 + |level|)`: exact for
    /// simulated data; give the measurement noise for real records.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tol: Option<f64>,
}

impl Stop {
    /// Relative default of [`Stop::tol`].
    pub const DEFAULT_TOL: f64 = 1e-6;

    /// The tolerance in use (the given `tol` or the default).
    pub fn tolerance(&self) -> f64 {
        self.tol
            .unwrap_or(Self::DEFAULT_TOL * (1.0 + self.level.abs()))
    }

    /// How far the output value `y` lies past the level on the side the
    /// stop forbids (negative on the allowed side).
    pub fn beyond(&self, y: f64) -> f64 {
        match self.bound {
            StopBound::Max => y - self.level,
            StopBound::Min => self.level - y,
        }
    }

    /// Whether the output value `y` sits at the stop: within the tolerance
    /// of the level or beyond it on the stop's side (a `max` stop at `L`
    /// holds `y >= L - tol`).
    pub fn holds(&self, y: f64) -> bool {
        let tol = self.tolerance();
        match self.bound {
            StopBound::Max => y >= self.level - tol,
            StopBound::Min => y <= self.level + tol,
        }
    }
}
