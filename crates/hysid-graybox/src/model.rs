//! The gray-box model file (`"kind": "gray_box"`): a hybrid automaton
//! written by its physics. States, inputs, an output map and named
//! parameters; modes whose flows are expressions; transitions whose guards
//! are surfaces crossed in a direction (lower-dimensional guard sets), with
//! conditions and reset maps; and built-in elements where an expression is
//! the wrong tool (dry friction with sticking, hard stops).
//!
//! The format is documented in `docs/gray-box-models.md`; the semantics of
//! a run are [`mod@crate::simulate`]'s.

use hysid_model::model::{ModelInfo, PhysicalParameter};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The version of the gray-box model format this build reads and writes.
pub const FORMAT_VERSION: u32 = 1;

/// An output: a name and the expression of the states (and inputs) it reads.
/// Written `{ name, value }`, or as a bare name that is also its
/// expression (`"x"` for `{ name = "x", value = "x" }`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutputMap {
    /// Output name.
    pub name: String,
    /// Its expression.
    pub value: String,
}

impl<'de> Deserialize<'de> for OutputMap {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Written {
            name: String,
            value: String,
        }
        struct Entry;
        impl<'de> serde::de::Visitor<'de> for Entry {
            type Value = OutputMap;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an output { name = \"y\", value = \"expression\" } or a state's name")
            }
            fn visit_str<E: serde::de::Error>(self, name: &str) -> Result<OutputMap, E> {
                Ok(OutputMap {
                    name: name.to_string(),
                    value: name.to_string(),
                })
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<OutputMap, A::Error> {
                let w = Written::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(OutputMap {
                    name: w.name,
                    value: w.value,
                })
            }
        }
        d.deserialize_any(Entry)
    }
}

/// `state = value` entries of an initial-state rule, read with a message
/// that says so where something else is written (`values = [0.5]`).
fn values_by_name<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<BTreeMap<String, f64>, D::Error> {
    struct Values;
    impl<'de> serde::de::Visitor<'de> for Values {
        type Value = BTreeMap<String, f64>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("values by state name, such as values = { x = 0.5 }")
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(
            self,
            mut map: A,
        ) -> Result<Self::Value, A::Error> {
            let mut values = BTreeMap::new();
            while let Some((name, value)) = map.next_entry::<String, f64>()? {
                values.insert(name, value);
            }
            Ok(values)
        }
    }
    d.deserialize_map(Values)
}

/// A discrete mode: the flow of every state, an invariant, and definitions
/// that replace the model's in this mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GrayBoxMode {
    /// Name, unique.
    pub name: String,
    /// `state = "expression"`: the time derivative of every state.
    pub flow: BTreeMap<String, String>,
    /// Relations (`a >= b`, `a <= b`) that hold while in the mode.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub invariant: Vec<String>,
    /// Definitions that take the place of the model's in this mode.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub definitions: BTreeMap<String, String>,
    /// The mode label of its samples, where it is not the name: modes
    /// with one label are one mode of a run's mode sequence (one physical
    /// regime written as several modes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// `element = "label"`: the mode label of the samples an element holds
    /// while in this mode, in place of the element's own `mode` (sticking
    /// in contact labelled apart from sticking in free motion).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub element_modes: BTreeMap<String, String>,
    /// What it is.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub doc: String,
}

impl GrayBoxMode {
    /// The mode label of its samples: its `label`, else its name.
    pub fn label(&self) -> &str {
        self.label.as_deref().unwrap_or(&self.name)
    }
}

/// A transition between modes: the guard surface crossed in a direction,
/// an optional condition, and the reset map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GrayBoxTransition {
    /// Source mode.
    pub from: String,
    /// Target mode.
    pub to: String,
    /// A relation: `a >= b` fires when `a - b` crosses zero upwards,
    /// `a <= b` downwards, `a == b` either way.
    pub guard: String,
    /// A condition that must be non-zero at the crossing (e.g. `v < 0`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub when: Option<String>,
    /// `state = "expression"`, evaluated at the state before the jump;
    /// states not listed keep their values.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub reset: BTreeMap<String, String>,
    /// What it is.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub doc: String,
}

/// The side of a stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopSide {
    /// The stop bounds the position from above (`position <= at`).
    Max,
    /// From below (`position >= at`).
    Min,
}

impl StopSide {
    /// `+1` for [`StopSide::Max`], `-1` for [`StopSide::Min`].
    pub fn sign(self) -> f64 {
        match self {
            StopSide::Max => 1.0,
            StopSide::Min => -1.0,
        }
    }
}

/// A built-in element acting on a pair of states (position, velocity).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Element {
    /// Coulomb friction with stiction on a velocity state (Karnopp's
    /// switch model): while sliding in direction `s`, `-kinetic * s` is
    /// added to the velocity's flow (the applied force `F`); when the
    /// velocity reaches zero, the state sticks if `|F| <= static`, else it
    /// slides off in the direction of `F`; while stuck, the velocity is held
    /// at zero until `|F|` exceeds the static level.
    DryFriction {
        /// Name.
        name: String,
        /// The velocity state.
        velocity: String,
        /// Kinetic (Coulomb) level, an expression (may differ by mode
        /// through the mode's definitions).
        kinetic: String,
        /// Static (break-away) level; `max(static, kinetic)` is used.
        #[serde(rename = "static")]
        static_level: String,
        /// The mode label of samples where it sticks.
        mode: String,
    },
    /// A rigid stop on a position state: the guard set
    /// `{position = at, moving towards the stop}` with the reset
    /// `velocity := -restitution * velocity`. With restitution 0 (or once
    /// the rebound is slower than `rest_speed`) the state rests at the stop
    /// until the applied force pulls it away beyond any static friction on
    /// the same velocity.
    Stop {
        /// Name.
        name: String,
        /// The position state.
        position: String,
        /// Its velocity state (the position's flow must be this state).
        velocity: String,
        /// Where the stop is (an expression of parameters).
        at: String,
        /// Which side of the position it bounds.
        side: StopSide,
        /// Coefficient of restitution in `[0, 1)`, an expression of parameters.
        #[serde(default = "zero_text")]
        restitution: String,
        /// A rebound slower than this rests at the stop (position units/s).
        #[serde(default)]
        rest_speed: f64,
        /// The mode label of samples that rest at the stop.
        mode: String,
    },
}

fn zero_text() -> String {
    "0".to_string()
}

impl Element {
    /// The element's name.
    pub fn name(&self) -> &str {
        match self {
            Element::DryFriction { name, .. } | Element::Stop { name, .. } => name,
        }
    }

    /// The mode label of the samples the element holds.
    pub fn mode(&self) -> &str {
        match self {
            Element::DryFriction { mode, .. } | Element::Stop { mode, .. } => mode,
        }
    }
}

/// Bounds `[low, high]` of the states a rule leaves unknown, by name: each
/// is estimated within its bounds ([`GrayBoxInitialState`]).
pub type Estimates = BTreeMap<String, [f64; 2]>;

/// How a simulation obtains its initial state.
///
/// `given` and `measured` may leave states unknown (`estimate`): those are
/// estimated within their bounds, at fit time with the parameters (as
/// nuisance parameters of the record), and on a record to simulate or
/// validate from its warm-up outputs alone (the first `samples`). With an
/// estimate, the run starts at sample 0 and the warm-up samples are not
/// scored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "from", rename_all = "snake_case", deny_unknown_fields)]
pub enum GrayBoxInitialState {
    /// Given values at sample 0 (states not listed start at zero).
    Given {
        /// `state = value`.
        #[serde(default, deserialize_with = "values_by_name")]
        values: BTreeMap<String, f64>,
        /// The starting mode; absent: the first mode whose invariant holds.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        mode: Option<String>,
        /// States estimated within `[low, high]` (a listed value is the
        /// starting guess; absent: the middle of the bounds).
        #[serde(
            default,
            skip_serializing_if = "BTreeMap::is_empty",
            deserialize_with = "hysid_model::model::exact_bounds_by_name"
        )]
        estimate: Estimates,
        /// The warm-up with an estimate: its outputs estimate the states
        /// (absent: [`DEFAULT_SAMPLES`]).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        samples: Option<usize>,
    },
    /// Read from the first `samples` measured outputs: the simulation starts
    /// at sample `samples - 1`, `position` takes the measured output there
    /// (through the inverse of the output map, which must be affine in it:
    /// a sensor's gain and offset) and `velocity` the slope of a
    /// least-squares quadratic through the last (up to 5) of them, divided
    /// by the output's gain; slopes at most `velocity_tol` count as zero.
    /// With an `estimate`, the simulation starts at sample 0, from the
    /// output there and the forward slope of the first (up to 5) samples.
    Measured {
        /// Samples used (the protocol's warm-up).
        #[serde(default = "ten")]
        samples: usize,
        /// The state that takes the measured output.
        position: String,
        /// The state that takes its slope, if any.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        velocity: Option<String>,
        /// Slopes smaller than this are zero.
        #[serde(default)]
        velocity_tol: f64,
        /// Values of the other states (absent: zero).
        #[serde(
            default,
            skip_serializing_if = "BTreeMap::is_empty",
            deserialize_with = "values_by_name"
        )]
        values: BTreeMap<String, f64>,
        /// The starting mode; absent: the first mode whose invariant holds.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        mode: Option<String>,
        /// States estimated within `[low, high]`, as for `given`.
        #[serde(
            default,
            skip_serializing_if = "BTreeMap::is_empty",
            deserialize_with = "hysid_model::model::exact_bounds_by_name"
        )]
        estimate: Estimates,
    },
    /// At rest under the first input sample: the states where every flow
    /// of the mode is zero, solved by Newton's method from `values`
    /// (absent: zero) in the mode `mode`, or else in the first mode where
    /// a rest state satisfies the invariant.
    Steady {
        /// The starting guess (absent: zero).
        #[serde(
            default,
            skip_serializing_if = "BTreeMap::is_empty",
            deserialize_with = "values_by_name"
        )]
        values: BTreeMap<String, f64>,
        /// The mode; absent: the first mode with a rest state in its invariant.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        mode: Option<String>,
    },
}

/// The warm-up of a `given` rule with an estimate, when it names none.
pub const DEFAULT_SAMPLES: usize = 10;

fn ten() -> usize {
    10
}

/// A hybrid gray-box model written by its physics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GrayBoxModel {
    /// Format version ([`FORMAT_VERSION`]).
    pub format: u32,
    /// Human-readable name.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// Maximum integration step, seconds.
    pub internal_step: f64,
    /// Continuous state names.
    pub states: Vec<String>,
    /// Input names, in the data's order.
    pub inputs: Vec<String>,
    /// `input = "delay"`: the model sees that input `delay` seconds late
    /// (a transport delay; an expression of parameters, at least 0).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub delays: BTreeMap<String, String>,
    /// The output map (one output: the records hysid reads have one).
    pub outputs: Vec<OutputMap>,
    /// Parameters.
    #[serde(default)]
    pub parameters: Vec<PhysicalParameter>,
    /// Named intermediate expressions, usable wherever a symbol is.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub definitions: BTreeMap<String, String>,
    /// Discrete modes.
    pub modes: Vec<GrayBoxMode>,
    /// Transitions.
    #[serde(default)]
    pub transitions: Vec<GrayBoxTransition>,
    /// Built-in elements.
    #[serde(default)]
    pub elements: Vec<Element>,
    /// The stored energy, an expression of the states and parameters,
    /// declared by the model's author: with every input at zero it never
    /// rises (the flows, elements and resets only dissipate). hysid's
    /// property tests check it on every model file that declares it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy: Option<String>,
    /// Initial state rule.
    pub initial_state: GrayBoxInitialState,
    /// Provenance and fit diagnostics.
    #[serde(default)]
    pub info: ModelInfo,
}

impl GrayBoxModel {
    /// Parameter values, in order.
    pub fn values(&self) -> Vec<f64> {
        self.parameters.iter().map(|p| p.value).collect()
    }

    /// Index of the parameter `name`.
    pub fn parameter_index(&self, name: &str) -> Option<usize> {
        self.parameters.iter().position(|p| p.name == name)
    }

    /// The mode labels of a run: the declared modes' labels, then those of
    /// the elements (a stop's rest, a friction's stick: each element's
    /// `mode`, then the modes' `element_modes`), each label once.
    pub fn mode_names(&self) -> Vec<String> {
        let mut seen = std::collections::HashSet::new();
        self.modes
            .iter()
            .map(GrayBoxMode::label)
            .chain(self.elements.iter().map(Element::mode))
            .chain(
                self.modes
                    .iter()
                    .flat_map(|q| q.element_modes.values().map(String::as_str)),
            )
            .filter(|label| seen.insert(*label))
            .map(str::to_string)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    struct Part {
        outputs: Vec<OutputMap>,
        initial_state: GrayBoxInitialState,
    }

    /// `text` read as the library reads a model file: TOML into a
    /// `serde_json::Value` (`crate::extends`), then the part.
    fn part(text: &str) -> Result<Part, serde_json::Error> {
        serde_json::from_value(toml::from_str(text).unwrap())
    }

    /// An output written as a bare name is that state; written as a
    /// table, it keeps its checks; either way it is written back as a
    /// table.
    #[test]
    fn an_output_is_a_table_or_a_state_name() {
        let rule = "initial_state = { from = \"given\", values = { x = 0.5 } }";
        let read = |outputs: &str| part(&format!("outputs = {outputs}\n{rule}"));
        let bare = read("[\"x\"]").unwrap();
        let table = read("[{ name = \"x\", value = \"x\" }]").unwrap();
        assert_eq!(bare.outputs, table.outputs);
        assert_eq!(
            serde_json::to_value(&bare.outputs).unwrap(),
            serde_json::json!([{"name": "x", "value": "x"}])
        );
        let json: Vec<OutputMap> = serde_json::from_str(r#"["x"]"#).unwrap();
        assert_eq!(json, table.outputs);
        for (outputs, says) in [
            (
                "[3]",
                "expected an output { name = \"y\", value = \"expression\" } or a state's name",
            ),
            ("[{ name = \"x\" }]", "missing field `value`"),
            (
                "[{ name = \"x\", value = \"x\", unit = \"m\" }]",
                "unknown field `unit`",
            ),
        ] {
            let e = read(outputs).unwrap_err().to_string();
            assert!(e.contains(says), "{outputs}: {e}");
        }
    }

    /// Values of an initial-state rule are by name: a list says so, in
    /// every rule that takes values.
    #[test]
    fn initial_values_are_by_name() {
        for from in ["given", "measured\", position = \"x", "steady"] {
            let text = |values: &str| {
                format!(
                    "outputs = [\"x\"]\ninitial_state = {{ from = \"{from}\", values = {values} }}"
                )
            };
            let values = match part(&text("{ x = 0.5 }")).unwrap().initial_state {
                GrayBoxInitialState::Given { values, .. }
                | GrayBoxInitialState::Measured { values, .. }
                | GrayBoxInitialState::Steady { values, .. } => values,
            };
            assert_eq!(values, BTreeMap::from([("x".to_string(), 0.5)]));
            let e = part(&text("[0.5]")).unwrap_err().to_string();
            assert!(
                e.contains("invalid type: sequence, expected values by state name, such as values = { x = 0.5 }"),
                "{from}: {e}"
            );
        }
    }
}
