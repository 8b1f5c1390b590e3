//! Mass-spring-friction hybrid automata declared by their physics
//! (`"kind": "mechanical"`): one mass moving along a line, smooth forces
//! (input gains, constants, springs, dampers), dry friction (Coulomb with
//! stiction), unilateral contact surfaces (spring, damper and extra friction
//! engaged past a position: the guard `y >= y_c`) and rigid stops (guard sets
//! on the lower-dimensional sets `y = level`, with the velocity reset
//! `v := -e v`, `e = 0` for an inelastic stop).
//!
//! This is the structure of the pick-and-place mounting head of Juloski,
//! Heemels and Ferrari-Trecate, "Identification of an experimental hybrid
//! system" (IFAC ADHS 2003), figure 3: mass M, spring c1 and damper d1 to the
//! casing, dry friction f1, motor force proportional to the input, contact
//! with the board (c2, d2, f2) and the two saturations. Every force is
//! written **per unit mass** (an acceleration), since only ratios to M are
//! identifiable from `u -> y`.
//!
//! The file format is documented in `docs/mechanical-models.md`; the
//! simulator is [`crate::simulate`].

use hysid_model::model::{ModelInfo, PhysicalParameter};
use serde::{Deserialize, Serialize};
use std::collections::HashSet;

/// A number, or the name of a parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Quantity {
    /// A literal value.
    Value(f64),
    /// A parameter's name.
    Param(String),
}

impl Default for Quantity {
    fn default() -> Self {
        Quantity::Value(0.0)
    }
}

/// A smooth force acting everywhere, per unit mass.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ForceElement {
    /// `gain * u_i` (e.g. the motor force `K_u u / M`).
    Input {
        /// Input name (one of the model's `inputs`).
        input: String,
        /// Gain.
        gain: Quantity,
    },
    /// A constant force (gravity, preload).
    Constant {
        /// Value.
        value: Quantity,
    },
    /// `-stiffness * (y - rest)`.
    Spring {
        /// Stiffness per unit mass (1/s^2).
        stiffness: Quantity,
        /// Rest position.
        #[serde(default)]
        rest: Quantity,
    },
    /// `-coefficient * v`.
    Damper {
        /// Damping per unit mass (1/s).
        coefficient: Quantity,
    },
}

/// Dry friction acting everywhere: Coulomb level while sliding, static
/// (break-away) level while stuck; the simulator uses `max(static, kinetic)`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    /// Kinetic (Coulomb) level.
    #[serde(default)]
    pub kinetic: Quantity,
    /// Static level.
    #[serde(default, rename = "static")]
    pub static_level: Quantity,
}

/// Direction along the position axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// The element acts on motion towards larger `y` (it lies at larger `y`).
    Positive,
    /// The element acts on motion towards smaller `y`.
    Negative,
}

impl Direction {
    /// `+1` or `-1`.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Positive => 1.0,
            Direction::Negative => -1.0,
        }
    }
}

/// A unilateral contact surface at `position`: engaged when the
/// penetration `p = s (y - position) > 0` (`s` the direction's sign: the
/// guard `y >= y_c` for `positive`), with the contact force
/// `lambda = stiffness p + damping s v` pushing back, extra friction while
/// engaged, and (when `unilateral`) released when `lambda` would pull.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Contact {
    /// Name, referenced by modes.
    pub name: String,
    /// Surface position.
    pub position: Quantity,
    /// Side on which the surface lies.
    pub direction: Direction,
    /// Contact stiffness per unit mass.
    pub stiffness: Quantity,
    /// Contact damping per unit mass.
    #[serde(default)]
    pub damping: Quantity,
    /// Extra dry friction while engaged (added to both levels).
    #[serde(default)]
    pub friction: Quantity,
    /// The surface can only push (contact released when `lambda < 0`).
    #[serde(default = "yes")]
    pub unilateral: bool,
}

fn yes() -> bool {
    true
}

/// A rigid stop: the guard set `{y = position, s v > 0}` (lower-dimensional)
/// with the reset `v := -restitution v` (0: the velocity reset of the
/// saturations in the IFAC 2003 paper). The position never passes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stop {
    /// Name, referenced by modes.
    pub name: String,
    /// Position of the stop.
    pub position: Quantity,
    /// `positive`: it bounds `y` from above (`y <= position`); `negative`: from below.
    pub direction: Direction,
    /// Coefficient of restitution in `[0, 1)`; 0 keeps the mass at the stop.
    #[serde(default)]
    pub restitution: f64,
}

/// Kinds of discrete mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MechanicalModeKind {
    /// Resting at a stop (`y = position`, `v = 0`): a saturation.
    Stop,
    /// Sliding (`v != 0`) with the listed contacts engaged.
    Slip,
    /// Stuck by static friction (`v = 0`, `|F| <= f_s`) with the listed contacts engaged.
    Stick,
}

/// A declared discrete mode, the label of a physical regime.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanicalMode {
    /// Name, unique.
    pub name: String,
    /// Kind.
    pub kind: MechanicalModeKind,
    /// For `stop` modes: the stop's name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop: Option<String>,
    /// For `slip`/`stick`: the engaged contacts (exactly); absent means any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contacts: Option<Vec<String>>,
    /// What it is.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub doc: String,
}

/// How a simulation obtains its initial state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "from", rename_all = "snake_case", deny_unknown_fields)]
pub enum MechanicalInitialState {
    /// Estimated from the first `samples` measured outputs: the simulation
    /// starts at sample `samples - 1` with the measured position there and
    /// the velocity of a least-squares quadratic through the last (up to 5)
    /// of those samples; a velocity below `velocity_tol` counts as zero
    /// (stuck, when static friction holds).
    Measured {
        /// Samples used (the protocol's warm-up, 10).
        #[serde(default = "ten")]
        samples: usize,
        /// Velocities smaller than this are zero (position units per second).
        #[serde(default)]
        velocity_tol: f64,
    },
    /// A given state at sample 0.
    Given {
        /// Position.
        position: f64,
        /// Velocity.
        velocity: f64,
    },
}

fn ten() -> usize {
    10
}

/// A one-degree-of-freedom mass-spring-friction hybrid automaton.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanicalModel {
    /// Human-readable name.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// Position unit (the output's unit), as text.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub position_unit: String,
    /// Internal integration step, seconds.
    pub internal_step: f64,
    /// Input names, in the data's order.
    pub inputs: Vec<String>,
    /// Parameters.
    pub parameters: Vec<PhysicalParameter>,
    /// Smooth forces acting everywhere.
    #[serde(default)]
    pub forces: Vec<ForceElement>,
    /// Dry friction acting everywhere.
    #[serde(default)]
    pub friction: Friction,
    /// Unilateral contact surfaces.
    #[serde(default)]
    pub contacts: Vec<Contact>,
    /// Rigid stops.
    #[serde(default)]
    pub stops: Vec<Stop>,
    /// Declared modes; a sample's mode is the first that matches its regime.
    pub modes: Vec<MechanicalMode>,
    /// Initial state rule.
    pub initial_state: MechanicalInitialState,
    /// Provenance and fit diagnostics.
    #[serde(default)]
    pub info: ModelInfo,
}

/// A force element with its quantities resolved to numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ResolvedForce {
    /// `gain * u[input]`.
    Input(usize, f64),
    /// Constant.
    Constant(f64),
    /// `-k (y - rest)`.
    Spring(f64, f64),
    /// `-d v`.
    Damper(f64),
}

/// A contact with numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedContact {
    /// Surface position.
    pub position: f64,
    /// Direction sign.
    pub sign: f64,
    /// Stiffness.
    pub stiffness: f64,
    /// Damping.
    pub damping: f64,
    /// Extra friction.
    pub friction: f64,
    /// Can only push.
    pub unilateral: bool,
}

/// A stop with numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedStop {
    /// Position.
    pub position: f64,
    /// Direction sign (+1: bounds y from above).
    pub sign: f64,
    /// Restitution.
    pub restitution: f64,
}

/// The model with every quantity a number: what the simulator runs.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedMechanics {
    /// Forces.
    pub forces: Vec<ResolvedForce>,
    /// Kinetic friction level.
    pub kinetic: f64,
    /// Static friction level (>= kinetic).
    pub static_level: f64,
    /// Contacts.
    pub contacts: Vec<ResolvedContact>,
    /// Stops.
    pub stops: Vec<ResolvedStop>,
}

/// Maximum number of contact surfaces (modes are matched on subsets of them).
pub const MAX_CONTACTS: usize = 8;

/// A structurally inconsistent mechanical model
/// ([`MechanicalModel::validate`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InvalidMechanical {
    /// A non-positive or non-finite internal step.
    #[error("internal_step must be > 0 (seconds)")]
    InternalStep,
    /// No input.
    #[error("a mechanical model needs at least one input")]
    NoInput,
    /// Two parameters of one name.
    #[error("parameter '{0}' appears twice")]
    DuplicateParameter(String),
    /// A parameter with a non-finite value or bounds, or low above high.
    #[error("parameter '{0}': need finite value and bounds low <= high (and high - low finite)")]
    ParameterBounds(String),
    /// A parameter value outside its bounds.
    #[error("parameter '{name}': value {value} outside its bounds [{low}, {high}]")]
    ParameterOutsideBounds {
        /// Parameter name.
        name: String,
        /// Its value.
        value: f64,
        /// Lower bound.
        low: f64,
        /// Upper bound.
        high: f64,
    },
    /// A quantity given as a non-finite number.
    #[error("{what}: value must be finite")]
    NonFiniteQuantity {
        /// Which quantity (`spring stiffness`, `contact 'c' position`, ...).
        what: String,
    },
    /// A quantity naming an unknown parameter.
    #[error("{what}: no parameter named '{name}' (a quantity is a parameter's name or a number)")]
    UnknownParameter {
        /// Which quantity.
        what: String,
        /// The unknown name.
        name: String,
    },
    /// An input force naming an unknown input.
    #[error("input force: no input named '{0}'")]
    UnknownInput(String),
    /// A friction level that can be negative: its value, or its
    /// parameter's value or lower bound (the simulator would read it as 0).
    #[error("{what}: a friction level is a magnitude, at least 0; {given} is {low}")]
    NegativeFriction {
        /// Which level (`friction.kinetic`, `contact 'c' friction`).
        what: String,
        /// `its value`, or `the value of 'f1'` or `the lower bound of 'f1'`.
        given: String,
        /// The negative number.
        low: f64,
    },
    /// More contacts than the simulator handles.
    #[error("at most {MAX_CONTACTS} contacts")]
    TooManyContacts,
    /// Two contacts of one name.
    #[error("contact '{0}' appears twice")]
    DuplicateContact(String),
    /// Two stops of one name.
    #[error("stop '{0}' appears twice")]
    DuplicateStop(String),
    /// A restitution outside `[0, 1)`.
    #[error("stop '{0}': restitution must be in [0, 1)")]
    Restitution(String),
    /// An upper and a lower stop with no position between them.
    #[error(
        "stops '{upper}' (y <= {at_most}) and '{lower}' (y >= {at_least}) leave no position between them"
    )]
    CrossedStops {
        /// The stop that bounds the position from above.
        upper: String,
        /// Its position.
        at_most: f64,
        /// The stop that bounds it from below.
        lower: String,
        /// Its position.
        at_least: f64,
    },
    /// Two modes of one name.
    #[error("mode '{0}' appears twice")]
    DuplicateMode(String),
    /// A stop mode naming an unknown stop.
    #[error("mode '{mode}': no stop named '{stop}'")]
    UnknownStop {
        /// Mode name.
        mode: String,
        /// The unknown stop.
        stop: String,
    },
    /// A stop mode without `stop`.
    #[error("mode '{0}': a stop mode needs `stop`")]
    StopModeWithoutStop(String),
    /// A mode other than a stop mode naming a stop.
    #[error("mode '{0}': only stop modes name a stop")]
    StopOnOrdinaryMode(String),
    /// A mode naming an unknown contact.
    #[error("mode '{mode}': no contact named '{contact}'")]
    UnknownContact {
        /// Mode name.
        mode: String,
        /// The unknown contact.
        contact: String,
    },
    /// No mode for resting at a stop.
    #[error("no mode for resting at stop '{0}'")]
    NoRestMode(String),
    /// No stick or slip mode for a set of engaged contacts.
    #[error(
        "no {} mode with contacts [{}] engaged",
        if *.stuck { "stick" } else { "slip" },
        .contacts.join(", ")
    )]
    NoContactMode {
        /// Stick (true) or slip.
        stuck: bool,
        /// The engaged contacts.
        contacts: Vec<String>,
    },
    /// A given initial state that is not finite.
    #[error("initial_state: position and velocity must be finite")]
    InitialState,
}

impl MechanicalModel {
    /// Parameter names, in order.
    pub fn parameter_names(&self) -> Vec<String> {
        self.parameters.iter().map(|p| p.name.clone()).collect()
    }

    /// Current parameter values, in order.
    pub fn values(&self) -> Vec<f64> {
        self.parameters.iter().map(|p| p.value).collect()
    }

    /// Index of the parameter `name`.
    pub fn parameter_index(&self, name: &str) -> Option<usize> {
        self.parameters.iter().position(|p| p.name == name)
    }

    fn quantity(&self, q: &Quantity, values: &[f64]) -> f64 {
        match q {
            Quantity::Value(v) => *v,
            Quantity::Param(n) => self
                .parameter_index(n)
                .map(|i| values[i])
                .unwrap_or(f64::NAN),
        }
    }

    /// Resolves every quantity with `values` (one per parameter, in order).
    pub fn resolve_with(&self, values: &[f64]) -> ResolvedMechanics {
        let q = |x: &Quantity| self.quantity(x, values);
        let forces = self
            .forces
            .iter()
            .map(|f| match f {
                ForceElement::Input { input, gain } => ResolvedForce::Input(
                    self.inputs.iter().position(|n| n == input).unwrap_or(0),
                    q(gain),
                ),
                ForceElement::Constant { value } => ResolvedForce::Constant(q(value)),
                ForceElement::Spring { stiffness, rest } => {
                    ResolvedForce::Spring(q(stiffness), q(rest))
                }
                ForceElement::Damper { coefficient } => ResolvedForce::Damper(q(coefficient)),
            })
            .collect();
        let kinetic = q(&self.friction.kinetic);
        let static_level = q(&self.friction.static_level).max(kinetic);
        ResolvedMechanics {
            forces,
            kinetic,
            static_level,
            contacts: self
                .contacts
                .iter()
                .map(|c| ResolvedContact {
                    position: q(&c.position),
                    sign: c.direction.sign(),
                    stiffness: q(&c.stiffness),
                    damping: q(&c.damping),
                    friction: q(&c.friction),
                    unilateral: c.unilateral,
                })
                .collect(),
            stops: self
                .stops
                .iter()
                .map(|s| ResolvedStop {
                    position: q(&s.position),
                    sign: s.direction.sign(),
                    restitution: s.restitution,
                })
                .collect(),
        }
    }

    /// Resolves with the model's own values.
    pub fn resolve(&self) -> ResolvedMechanics {
        self.resolve_with(&self.values())
    }

    /// The declared mode of a regime: `stop` (index of the stop), else slip
    /// or stick with the engaged contacts as a bit mask.
    pub fn mode_of(&self, stop: Option<usize>, stuck: bool, engaged: u32) -> Option<usize> {
        self.modes.iter().position(|m| match (m.kind, stop) {
            (MechanicalModeKind::Stop, Some(s)) => {
                m.stop.as_deref() == Some(self.stops[s].name.as_str())
            }
            (MechanicalModeKind::Stop, None) | (_, Some(_)) => false,
            (MechanicalModeKind::Slip, None) if stuck => false,
            (MechanicalModeKind::Stick, None) if !stuck => false,
            _ => match &m.contacts {
                None => true,
                Some(list) => {
                    let mask = list
                        .iter()
                        .filter_map(|n| self.contacts.iter().position(|c| &c.name == n))
                        .fold(0u32, |a, i| a | (1 << i));
                    mask == engaged
                }
            },
        })
    }

    /// Every friction level (kinetic, static, each contact's) is a
    /// magnitude: its value, or its parameter's value and lower bound, at
    /// least 0 ([`InvalidMechanical::NegativeFriction`]); part of
    /// [`Self::validate`].
    pub fn check_friction_levels(&self) -> Result<(), InvalidMechanical> {
        self.magnitude(&self.friction.kinetic, "friction.kinetic")?;
        self.magnitude(&self.friction.static_level, "friction.static")?;
        for c in &self.contacts {
            self.magnitude(&c.friction, &format!("contact '{}' friction", c.name))?;
        }
        Ok(())
    }

    /// A friction level `q` (`what`) that cannot be negative: its value, or
    /// its parameter's value and lower bound, at least 0. Where it could be
    /// negative the simulator would read it as 0, and a fit would search a
    /// range that does nothing.
    fn magnitude(&self, q: &Quantity, what: &str) -> Result<(), InvalidMechanical> {
        let (given, low) = match q {
            Quantity::Value(v) => ("its value".to_string(), *v),
            Quantity::Param(n) => match self.parameters.iter().find(|p| &p.name == n) {
                Some(p) if p.value < 0.0 => (format!("the value of '{n}'"), p.value),
                Some(p) => (format!("the lower bound of '{n}'"), p.bounds[0]),
                None => return Ok(()),
            },
        };
        if low < 0.0 {
            return Err(InvalidMechanical::NegativeFriction {
                what: what.to_string(),
                given,
                low,
            });
        }
        Ok(())
    }

    /// Structural checks: names resolve, bounds hold the values, every
    /// regime has a declared mode.
    pub fn validate(&self) -> Result<(), InvalidMechanical> {
        use InvalidMechanical as E;
        if !(self.internal_step.is_finite() && self.internal_step > 0.0) {
            return Err(E::InternalStep);
        }
        if self.inputs.is_empty() {
            return Err(E::NoInput);
        }
        // Names looked up by set: a file's lists may be long.
        let mut parameters = HashSet::with_capacity(self.parameters.len());
        for p in &self.parameters {
            if !parameters.insert(p.name.as_str()) {
                return Err(E::DuplicateParameter(p.name.clone()));
            }
            let [lo, hi] = p.bounds;
            if !(p.value.is_finite() && lo <= hi && (hi - lo).is_finite()) {
                return Err(E::ParameterBounds(p.name.clone()));
            }
            if p.value < lo || p.value > hi {
                return Err(E::ParameterOutsideBounds {
                    name: p.name.clone(),
                    value: p.value,
                    low: lo,
                    high: hi,
                });
            }
        }
        let check = |q: &Quantity, what: &str| -> Result<(), InvalidMechanical> {
            match q {
                Quantity::Value(v) if v.is_finite() => Ok(()),
                Quantity::Value(_) => Err(E::NonFiniteQuantity {
                    what: what.to_string(),
                }),
                Quantity::Param(n) if parameters.contains(n.as_str()) => Ok(()),
                Quantity::Param(n) => Err(E::UnknownParameter {
                    what: what.to_string(),
                    name: n.clone(),
                }),
            }
        };
        for f in &self.forces {
            match f {
                ForceElement::Input { input, gain } => {
                    if !self.inputs.contains(input) {
                        return Err(E::UnknownInput(input.clone()));
                    }
                    check(gain, "input force gain")?;
                }
                ForceElement::Constant { value } => check(value, "constant force")?,
                ForceElement::Spring { stiffness, rest } => {
                    check(stiffness, "spring stiffness")?;
                    check(rest, "spring rest")?;
                }
                ForceElement::Damper { coefficient } => check(coefficient, "damper coefficient")?,
            }
        }
        check(&self.friction.kinetic, "friction.kinetic")?;
        check(&self.friction.static_level, "friction.static")?;
        if self.contacts.len() > MAX_CONTACTS {
            return Err(E::TooManyContacts);
        }
        let mut contacts = HashSet::with_capacity(self.contacts.len());
        for c in &self.contacts {
            if !contacts.insert(c.name.as_str()) {
                return Err(E::DuplicateContact(c.name.clone()));
            }
            let w = |s: &str| format!("contact '{}' {s}", c.name);
            check(&c.position, &w("position"))?;
            check(&c.stiffness, &w("stiffness"))?;
            check(&c.damping, &w("damping"))?;
            check(&c.friction, &w("friction"))?;
        }
        let mut stops = HashSet::with_capacity(self.stops.len());
        for s in &self.stops {
            if !stops.insert(s.name.as_str()) {
                return Err(E::DuplicateStop(s.name.clone()));
            }
            check(&s.position, &format!("stop '{}' position", s.name))?;
            if !(0.0..1.0).contains(&s.restitution) {
                return Err(E::Restitution(s.name.clone()));
            }
        }
        let mut modes = HashSet::with_capacity(self.modes.len());
        // The stops with a rest mode.
        let mut resting = HashSet::new();
        for m in &self.modes {
            if !modes.insert(m.name.as_str()) {
                return Err(E::DuplicateMode(m.name.clone()));
            }
            match m.kind {
                MechanicalModeKind::Stop => match &m.stop {
                    Some(s) if stops.contains(s.as_str()) => {
                        resting.insert(s.as_str());
                    }
                    Some(s) => {
                        return Err(E::UnknownStop {
                            mode: m.name.clone(),
                            stop: s.clone(),
                        });
                    }
                    None => return Err(E::StopModeWithoutStop(m.name.clone())),
                },
                _ => {
                    if m.stop.is_some() {
                        return Err(E::StopOnOrdinaryMode(m.name.clone()));
                    }
                }
            }
            for c in m.contacts.iter().flatten() {
                if !contacts.contains(c.as_str()) {
                    return Err(E::UnknownContact {
                        mode: m.name.clone(),
                        contact: c.clone(),
                    });
                }
            }
        }
        // Every regime needs a mode (a stop's: a stop mode naming it, as
        // `mode_of` finds it).
        for s in &self.stops {
            if !resting.contains(s.name.as_str()) {
                return Err(E::NoRestMode(s.name.clone()));
            }
        }
        for mask in 0..(1u32 << self.contacts.len()) {
            for stuck in [false, true] {
                if self.mode_of(None, stuck, mask).is_none() {
                    return Err(E::NoContactMode {
                        stuck,
                        contacts: self
                            .contacts
                            .iter()
                            .enumerate()
                            .filter(|(i, _)| mask & (1 << i) != 0)
                            .map(|(_, c)| c.name.clone())
                            .collect(),
                    });
                }
            }
        }
        self.check_friction_levels()?;
        self.check_stop_positions()?;
        if let MechanicalInitialState::Given { position, velocity } = self.initial_state
            && !(position.is_finite() && velocity.is_finite())
        {
            return Err(E::InitialState);
        }
        Ok(())
    }

    /// At the file's values, every upper stop lies above every lower one:
    /// the stops leave positions between them.
    fn check_stop_positions(&self) -> Result<(), InvalidMechanical> {
        let resolved = self.resolve();
        let stops = || self.stops.iter().zip(&resolved.stops);
        for (upper, at_most) in stops().filter(|(_, r)| r.sign > 0.0) {
            for (lower, at_least) in stops().filter(|(_, r)| r.sign < 0.0) {
                if at_least.position >= at_most.position {
                    return Err(InvalidMechanical::CrossedStops {
                        upper: upper.name.clone(),
                        at_most: at_most.position,
                        lower: lower.name.clone(),
                        at_least: at_least.position,
                    });
                }
            }
        }
        Ok(())
    }
}
