//! Checking a [`GrayBoxModel`] once and compiling every expression into a
//! tape over numbered slots ([`CompiledModel`]): what the simulator runs.
//!
//! Slot layout: the states, then the inputs and the parameters. A
//! definition may use states, inputs, parameters and other definitions, but
//! not itself through a cycle; each mode's definitions are inlined into
//! every expression evaluated in that mode, so a run stores no definition
//! (a definition an expression uses more than once is evaluated once, into
//! a register of that expression's tape: [`Expression::inline`]).
//!
//! This module holds the compiled model and its parts; the steps of
//! [`CompiledModel::new`] are its submodules: `names` (the header, the
//! sizes and the slot of every name), `elements`, `compiler` (definitions,
//! modes, transitions, delays, energy) and `initial` (the initial-state
//! rule and the sensor it reads through), each returning a `problem`
//! ([`InvalidGrayBox`]) where the model is wrong.

use crate::expr::{Expression, Relation, Shared};
use crate::model::GrayBoxModel;
use compiler::Compiler;
use elements::{LabelIndex, check_stops, compile_elements, mode_labels};
use initial::{check_sensor, initial_rule};
pub use names::is_identifier;
use names::{check_header, check_sizes, definition_names};
pub use problem::{InvalidGrayBox, Problem};

mod compiler;
mod elements;
mod initial;
mod names;
mod problem;

/// Most definitions a model may have (the model's and those only modes
/// give): each mode's are checked as a whole, so modes times definitions
/// is the work of reading a file.
pub const MAX_DEFINITIONS: usize = 10_000;

/// Most modes a model may have.
pub const MAX_MODES: usize = 1_000;

/// Most definitions checked with the values of the modes that give
/// definitions of their own: each such mode checks every definition
/// (cycles, depths) with its own values, so these modes times the
/// definitions may be at most this.
pub const MAX_MODE_DEFINITIONS: usize = 1_000_000;

/// Most elements (frictions and stops) a model may have: every mode holds
/// a friction level for each.
pub const MAX_ELEMENTS: usize = 100;

/// Most operations the compiled expressions of a model may hold, counted
/// with their definitions written out ([`Expression::inline`]).
pub const MAX_OPERATIONS: usize = 1_000_000;

/// A transition with compiled expressions.
#[derive(Debug, Clone, PartialEq)]
pub struct CompiledTransition {
    /// `from -> to`, for messages.
    pub label: String,
    /// Target mode.
    pub to: usize,
    /// The guard surface and its crossing.
    pub guard: Relation,
    /// The condition at the crossing.
    pub when: Option<Expression>,
    /// `(state, expression)`.
    pub reset: Vec<(usize, Expression)>,
}

/// A mode with compiled expressions, its definitions inlined into each
/// (a definition is a name for part of an expression, not a value stored
/// during a run).
#[derive(Debug, Clone, PartialEq)]
pub struct CompiledMode {
    /// The flow of every state, in state order.
    pub flow: Vec<Expression>,
    /// The flows evaluated together, their common operations once.
    pub joint_flow: Shared,
    /// The invariant's relations.
    pub invariant: Vec<Relation>,
    /// Transitions leaving the mode, in file order.
    pub transitions: Vec<CompiledTransition>,
    /// Per element, a friction's kinetic and static levels in this mode
    /// (constant zeros for the other elements).
    pub friction: Vec<(Expression, Expression)>,
    /// The output map.
    pub output: Expression,
}

/// A built-in element with compiled expressions.
// A model has a few elements: a stop's two expressions beside a
// friction's two indices cost no memory worth a box.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum CompiledElement {
    /// Dry friction on velocity state `velocity` (its levels are per mode:
    /// [`CompiledMode::friction`]).
    DryFriction {
        /// Velocity state.
        velocity: usize,
        /// Label index (into [`GrayBoxModel::mode_names`]).
        label: usize,
    },
    /// A stop on state `position`.
    Stop {
        /// Position state.
        position: usize,
        /// Velocity state.
        velocity: usize,
        /// Where (parameters only).
        at: Expression,
        /// +1: bounds from above; -1: from below.
        sign: f64,
        /// Restitution (parameters only).
        restitution: Expression,
        /// Rebounds slower than this rest.
        rest_speed: f64,
        /// Label index.
        label: usize,
    },
}

/// The mode labels of a run's samples, as indices into
/// [`GrayBoxModel::mode_names`].
#[derive(Debug, Clone, PartialEq)]
pub struct ModeLabels {
    /// Per mode, the label of its samples.
    pub mode: Vec<usize>,
    /// Per mode and element, the label of the samples the element holds
    /// in that mode.
    pub held: Vec<Vec<usize>>,
}

/// The initial-state rule with indices.
#[derive(Debug, Clone, PartialEq)]
pub enum CompiledInitial {
    /// Given state at sample 0.
    Given {
        /// Values of every state (estimated ones at their starting guess).
        x: Vec<f64>,
        /// Starting mode, if given.
        mode: Option<usize>,
        /// Warm-up samples whose outputs estimate the unknown states.
        samples: usize,
    },
    /// From the measured output.
    Measured {
        /// Samples of warm-up.
        samples: usize,
        /// State taking the output (through the inverse of the output map).
        position: usize,
        /// State taking the slope.
        velocity: Option<usize>,
        /// Slope tolerance.
        velocity_tol: f64,
        /// Values of every state (position and velocity overwritten).
        x: Vec<f64>,
        /// Starting mode, if given.
        mode: Option<usize>,
    },
    /// At rest under the first input sample.
    Steady {
        /// The starting guess of every state.
        x: Vec<f64>,
        /// The mode, if given.
        mode: Option<usize>,
    },
}

impl CompiledInitial {
    /// The warm-up samples whose outputs estimate the unknown states
    /// (`None` for a rest state, which estimates none).
    pub fn warmup(&self) -> Option<usize> {
        match self {
            CompiledInitial::Given { samples, .. } | CompiledInitial::Measured { samples, .. } => {
                Some(*samples)
            }
            CompiledInitial::Steady { .. } => None,
        }
    }
}

/// A state of the initial state that the rule leaves unknown: estimated
/// within its bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatedState {
    /// The state's index.
    pub state: usize,
    /// Its name.
    pub name: String,
    /// `[low, high]`.
    pub bounds: [f64; 2],
    /// The starting guess: the rule's value, clamped into the bounds, or
    /// the middle of the bounds.
    pub start: f64,
}

/// A checked gray-box model with every expression compiled.
#[derive(Debug, Clone, PartialEq)]
pub struct CompiledModel {
    /// Number of states.
    pub states: usize,
    /// Number of inputs.
    pub inputs: usize,
    /// Number of parameters.
    pub parameters: usize,
    /// Modes.
    pub modes: Vec<CompiledMode>,
    /// Elements.
    pub elements: Vec<CompiledElement>,
    /// The mode labels of the samples.
    pub labels: ModeLabels,
    /// Per input, its delay in seconds (parameters only; a constant 0
    /// without one).
    pub delays: Vec<Expression>,
    /// The initial-state rule.
    pub initial: CompiledInitial,
    /// The states the rule leaves unknown, in the order of their names.
    pub estimates: Vec<EstimatedState>,
    /// Maximum integration step.
    pub internal_step: f64,
    /// The declared stored energy ([`GrayBoxModel::energy`]): states and
    /// parameters only.
    pub energy: Option<Expression>,
    /// The names of the states and of the modes, in order, for messages
    /// (shared by the bound copies of a fit's runs).
    pub names: std::sync::Arc<Names>,
}

/// The names of a compiled model's states and modes, in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Names {
    /// State names.
    pub states: Vec<String>,
    /// Mode names.
    pub modes: Vec<String>,
    /// The definitions no expression reads, directly or through other
    /// definitions, in name order.
    pub unread_definitions: Vec<String>,
}

impl Names {
    /// `x = 5, v = 0`: the states' names with the values of `x`.
    pub fn states_at(&self, x: &[f64]) -> String {
        (self.states.iter().zip(x))
            .map(|(name, value)| format!("{name} = {value}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl CompiledModel {
    /// Checks `m` and compiles it: the header and the sizes, the names,
    /// the elements, each mode with the transitions that leave it, then
    /// the delays, the energy and the initial state.
    pub fn new(m: &GrayBoxModel) -> Result<Self, InvalidGrayBox> {
        check_header(m)?;
        let names = definition_names(m);
        check_sizes(m, names.len())?;
        let mut c = Compiler::new(m, names)?;
        let label_index = LabelIndex::of_model(m);
        let labels = mode_labels(m, &c.mode_index, &label_index)?;
        let elements = compile_elements(
            m,
            &label_index,
            &|p, n| c.state_of(p, n),
            &|p, n| c.parametric(p, n),
            &|p, n| c.restitution(p, n),
        )?;
        check_stops(m, &elements, &|e| c.at_values(e))?;
        let modes = c.compile_modes()?;
        let delays = c.compile_delays()?;
        let energy = c.compile_energy()?;
        let (initial, estimates) =
            initial_rule(m, &|p, n| c.state_of(p, n), &|p, n| c.mode_of(p, n))?;
        check_sensor(m, &initial, &modes)?;
        Ok(CompiledModel {
            estimates,
            energy,
            delays,
            states: c.nx,
            inputs: m.inputs.len(),
            parameters: m.parameters.len(),
            modes,
            elements,
            labels,
            initial,
            internal_step: m.internal_step,
            names: std::sync::Arc::new(Names {
                states: m.states.clone(),
                modes: m.modes.iter().map(|mode| mode.name.clone()).collect(),
                unread_definitions: c.unread_definitions(),
            }),
        })
    }

    /// The warm-up samples the initial state reads from the record: a
    /// measured rule's, or those of a given rule that estimates states;
    /// `None` for a state given whole, or at rest.
    pub fn warmup_read(&self) -> Option<usize> {
        match self.initial {
            CompiledInitial::Measured { samples, .. } => Some(samples),
            CompiledInitial::Given { samples, .. } if !self.estimates.is_empty() => Some(samples),
            CompiledInitial::Given { .. } | CompiledInitial::Steady { .. } => None,
        }
    }

    /// Whether the direction of a sliding friction decides any comparison
    /// in the model's flows and friction levels ([`CompiledModel::sliding`]
    /// changes something).
    pub fn decides_sliding(&self) -> bool {
        let velocities: Vec<u32> = self
            .elements
            .iter()
            .filter_map(|e| match e {
                CompiledElement::DryFriction { velocity, .. } => Some(*velocity as u32),
                CompiledElement::Stop { .. } => None,
            })
            .collect();
        self.modes.iter().any(|q| {
            let levels = q.friction.iter().flat_map(|(k, s)| [k, s]);
            q.flow
                .iter()
                .chain(levels)
                .any(|e| velocities.iter().any(|&v| e.with_sign(v, true).is_some()))
        })
    }

    /// The model as it reads while the velocity states `sliding` slide,
    /// each in the direction given (`true`: positive): in every mode's
    /// flows and friction levels, the comparisons of those velocities with
    /// zero are decided by the directions ([`Expression::with_sign`]), also
    /// at the instant of break-away, when the velocity is still zero.
    /// `None` when no expression changes.
    pub fn sliding(&self, sliding: &[(usize, bool)]) -> Option<CompiledModel> {
        let decide = |e: &Expression| {
            sliding
                .iter()
                .fold(None, |decided: Option<Expression>, &(v, positive)| {
                    decided
                        .as_ref()
                        .unwrap_or(e)
                        .with_sign(v as u32, positive)
                        .or(decided)
                })
        };
        let mut model = self.clone();
        let mut changed = false;
        for q in &mut model.modes {
            let levels = q.friction.iter_mut().flat_map(|(k, s)| [k, s]);
            for e in q.flow.iter_mut().chain(levels) {
                if let Some(d) = decide(e) {
                    *e = d;
                    changed = true;
                }
            }
        }
        changed.then_some(model)
    }

    /// The model specialised to the parameter values `values`: every
    /// expression with the parameters folded in ([`Expression::bind`]), the
    /// slot layout unchanged. What a run evaluates.
    pub fn bind(&self, values: &[f64]) -> CompiledModel {
        let first = self.parameter_slot() as u32;
        let b = |e: &Expression| e.bind(first, values);
        let relation = |r: &Relation| Relation {
            surface: b(&r.surface),
            crossing: r.crossing,
        };
        CompiledModel {
            modes: self
                .modes
                .iter()
                .map(|q| {
                    let flow: Vec<Expression> = q.flow.iter().map(b).collect();
                    CompiledMode {
                        joint_flow: Shared::of(&flow),
                        flow,
                        invariant: q.invariant.iter().map(relation).collect(),
                        transitions: q
                            .transitions
                            .iter()
                            .map(|t| CompiledTransition {
                                label: t.label.clone(),
                                to: t.to,
                                guard: relation(&t.guard),
                                when: t.when.as_ref().map(b),
                                reset: t.reset.iter().map(|(s, e)| (*s, b(e))).collect(),
                            })
                            .collect(),
                        friction: q.friction.iter().map(|(k, s)| (b(k), b(s))).collect(),
                        output: b(&q.output),
                    }
                })
                .collect(),
            elements: self
                .elements
                .iter()
                .map(|e| match e {
                    CompiledElement::Stop {
                        position,
                        velocity,
                        at,
                        sign,
                        restitution,
                        rest_speed,
                        label,
                    } => CompiledElement::Stop {
                        position: *position,
                        velocity: *velocity,
                        at: b(at),
                        sign: *sign,
                        restitution: b(restitution),
                        rest_speed: *rest_speed,
                        label: *label,
                    },
                    friction => friction.clone(),
                })
                .collect(),
            labels: self.labels.clone(),
            delays: self.delays.iter().map(b).collect(),
            energy: self.energy.as_ref().map(b),
            initial: self.initial.clone(),
            estimates: self.estimates.clone(),
            names: self.names.clone(),
            ..*self
        }
    }

    /// The declared energy at the state `x`, on a model whose parameters
    /// are bound ([`CompiledModel::bind`]); `None` without a declared
    /// energy, or when it still reads a parameter (an unbound model) or
    /// `x` is shorter than the states it reads.
    pub fn energy_at(&self, x: &[f64]) -> Option<f64> {
        let e = self.energy.as_ref()?;
        e.slots().all(|s| (s as usize) < x.len()).then(|| e.eval(x))
    }

    /// Slots an evaluation reads: the states, the inputs and the parameters.
    pub fn slots(&self) -> usize {
        self.states + self.inputs + self.parameters
    }

    /// The first slot of the parameters.
    pub fn parameter_slot(&self) -> usize {
        self.states + self.inputs
    }
}
