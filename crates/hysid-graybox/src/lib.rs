//! # hysid-graybox
//!
//! Hybrid gray-box models written by their physics (`"kind": "gray_box"`):
//! the user's own states, inputs, output map and named parameters; modes
//! whose flows are expressions; transitions whose guards are surfaces
//! crossed in a direction (lower-dimensional guard sets) with conditions
//! and reset maps; and built-in elements where an expression is the wrong
//! tool (dry friction with sticking, rigid stops). The structural models
//! the conclusion of Juloski, Heemels and Ferrari-Trecate (IFAC ADHS 2003)
//! asks for, such as its figure 3, are written in this form.
//!
//! - [`model`]: the file (TOML or JSON), format [`FORMAT_VERSION`];
//! - [`extends`]: files written as another file with changes;
//! - [`expr`]: expressions, parsed by evalexpr once and compiled into a
//!   tape evaluated without parsing or allocating;
//! - [`compile`]: the checks and the compiled model;
//! - [`mod@simulate`]: the event-located simulator, and the initial
//!   states a rule leaves unknown (estimated from a record's warm-up, or
//!   at rest), solved by hysid's one Levenberg-Marquardt
//!   ([`hysid_numerics::least_squares`]).
//!
//! The file format is documented in `docs/gray-box-models.md`.

pub mod compile;
pub mod expr;
pub mod extends;
pub mod model;
pub mod simulate;
mod source;

pub use compile::{CompiledModel, InvalidGrayBox, Problem};
pub use model::{
    DEFAULT_SAMPLES, Element, Estimates, FORMAT_VERSION, GrayBoxInitialState, GrayBoxMode,
    GrayBoxModel, GrayBoxTransition, OutputMap, StopSide,
};

use hysid_model::data::Dataset;
use hysid_model::simulate::{SimError, Simulation, SimulationOptions};

impl GrayBoxModel {
    /// Checks the model: names, expressions, modes, elements, initial state.
    pub fn validate(&self) -> Result<(), InvalidGrayBox> {
        CompiledModel::new(self).map(|_| ())
    }

    /// The rigid stops on the output's state at the parameter values:
    /// `(level, +1 for a bound from above or -1 from below)`. Empty when
    /// the output is not a bare state.
    pub fn output_stops(&self) -> Vec<(f64, f64)> {
        let Ok(c) = CompiledModel::new(self) else {
            return Vec::new();
        };
        let output = self.outputs[0].value.trim();
        let Some(state) = self.states.iter().position(|s| s == output) else {
            return Vec::new();
        };
        let machine = simulate::Machine::new(&c, &self.values());
        machine
            .stops()
            .filter(|(position, _, _)| *position == state)
            .map(|(_, at, sign)| (at, sign))
            .collect()
    }
}

fn to_simulation(r: simulate::GrayBoxRun, opts: SimulationOptions) -> Simulation {
    let n = r.y.len();
    let mut sim = Simulation {
        y: r.y.clone(),
        modes: r.modes,
        start: r.start,
        covered: r.covered,
        diverged_at: None,
        diverged_to: None,
        zeno: r.zeno,
    };
    for k in r.start..n {
        if !sim.push_checked(k, r.y[k], opts.bound) {
            break;
        }
    }
    sim
}

fn compiled(m: &GrayBoxModel) -> Result<CompiledModel, SimError> {
    CompiledModel::new(m).map_err(|e| SimError::InvalidModel(e.to_string()))
}

/// Free-run simulation of a gray-box model at its parameter values.
pub fn simulate(
    m: &GrayBoxModel,
    data: &Dataset,
    opts: SimulationOptions,
) -> Result<Simulation, SimError> {
    let c = compiled(m)?;
    simulate::run(&c, &m.values(), data).map(|r| to_simulation(r, opts))
}

/// An initial state the rule leaves unknown, as the warm-up estimated it.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatedState {
    /// The state's name.
    pub name: String,
    /// Its value.
    pub value: f64,
    /// Whether the warm-up's outputs show it ([`simulate::unseen`]); where
    /// they do not, the record does not determine `value`.
    pub seen: bool,
    /// Whether `value` lies on a bound of the rule's `estimate` range: the
    /// warm-up may ask for a value outside it.
    pub at_bound: bool,
}

/// The states the initial-state rule leaves unknown (`estimate`), in the
/// rule's order, as estimated from the warm-up outputs of `data` at the
/// model's parameter values ([`simulate::estimate`]); empty when it
/// estimates none.
pub fn initial_states(m: &GrayBoxModel, data: &Dataset) -> Result<Vec<EstimatedState>, SimError> {
    let c = compiled(m)?;
    let values = simulate::estimate(&c, &m.values(), data)?;
    let unseen = simulate::unseen(&c, &m.values(), data, &values)?;
    Ok(c.estimates
        .iter()
        .zip(values)
        .zip(unseen)
        .map(|((e, value), unseen)| EstimatedState {
            name: e.name.clone(),
            value,
            seen: !unseen,
            at_bound: value <= e.bounds[0] || value >= e.bounds[1],
        })
        .collect())
}

/// One-step prediction of a gray-box model ([`simulate::predict`]).
pub fn predict(m: &GrayBoxModel, data: &Dataset) -> Result<Simulation, SimError> {
    let c = compiled(m)?;
    simulate::predict(&c, &m.values(), data).map(|r| to_simulation(r, SimulationOptions::default()))
}
