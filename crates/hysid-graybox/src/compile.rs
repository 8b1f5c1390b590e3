//! Checking a [`GrayBoxModel`] once and compiling every expression into a
//! tape over numbered slots ([`CompiledModel`]): what the simulator runs.
//!
//! Slot layout: the states, then the inputs and the parameters. A
//! definition may use states, inputs, parameters and other definitions, but
//! not itself through a cycle; each mode's definitions are inlined into
//! every expression evaluated in that mode, so a run stores no definition
//! (a definition an expression uses more than once is evaluated once, into
//! a register of that expression's tape: [`Expression::inline`]).

use crate::expr::{
    DefinitionError, Definitions, ExprError, Expression, Function, InlineError, Relation, Shared,
};
use crate::model::{
    DEFAULT_SAMPLES, Element, Estimates, FORMAT_VERSION, GrayBoxInitialState, GrayBoxMode,
    GrayBoxModel, GrayBoxTransition,
};
use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::rc::Rc;

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

/// What is wrong with a gray-box model: where, and the source text that a
/// reader can look for in the file ([`InvalidGrayBox::line_in`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{place}: {problem}")]
pub struct InvalidGrayBox {
    /// Where in the model (`mode 'free', flow of 'v'`).
    pub place: String,
    /// The offending text as written in the file (an expression or a name).
    pub text: Option<String>,
    /// What is wrong.
    pub problem: Problem,
}

/// The kinds of [`InvalidGrayBox`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Problem {
    /// An expression that does not compile.
    #[error(transparent)]
    Expression(#[from] ExprError),
    /// A format version this build does not read.
    #[error("format {0} is not supported (this build reads format {FORMAT_VERSION})")]
    Version(u32),
    /// A non-positive or non-finite internal step.
    #[error("internal_step must be a positive number of seconds")]
    InternalStep,
    /// A name that is not an identifier, or is a function's.
    #[error(
        "'{0}' is not a valid name (letters, digits and '_', not starting with a digit, not a function)"
    )]
    BadName(String),
    /// A name declared twice (states, inputs, parameters, definitions,
    /// modes and elements share one namespace each).
    #[error("'{0}' is declared twice")]
    Duplicate(String),
    /// A parameter with non-finite numbers, low above high, or its value
    /// outside its bounds.
    #[error("parameter '{0}': need finite value and bounds with low <= value <= high")]
    Parameter(String),
    /// Not exactly one output.
    #[error("need exactly one output (the records hysid reads have one), found {0}")]
    Outputs(usize),
    /// No mode.
    #[error("a model needs at least one mode")]
    NoMode,
    /// A mode without the flow of a state.
    #[error("no flow for state '{0}'")]
    MissingFlow(String),
    /// A name that is no state.
    #[error("'{0}' is not a state")]
    UnknownState(String),
    /// A name that is no input.
    #[error("'{0}' is not an input")]
    UnknownInput(String),
    /// A name that is no mode.
    #[error("'{0}' is not a mode")]
    UnknownMode(String),
    /// A definition that reaches itself.
    #[error("definition '{0}' depends on itself")]
    Cycle(String),
    /// A relation where a value is expected.
    #[error(
        "'{0}' is a relation (1 where it holds, 0 elsewhere) where a value is expected; \
         write if(relation, value, other value)"
    )]
    NotValue(String),
    /// A stop's restitution outside `[0, 1)` somewhere in the parameters'
    /// bounds.
    #[error(
        "restitution '{text}' ranges over [{low}, {high}] within the parameters' bounds; \
         it must lie in [0, 1)"
    )]
    Restitution {
        /// The expression.
        text: String,
        /// Its least value.
        low: f64,
        /// Its largest value.
        high: f64,
    },
    /// An element's quantity that reads more than the parameters.
    #[error("'{0}' may only use parameters and numbers")]
    NotParametric(String),
    /// An energy that reads more than the states and parameters.
    #[error("'{0}' may only use states, parameters and numbers")]
    NotStateFunction(String),
    /// An element label equal to a declared mode.
    #[error("the label '{0}' is a declared mode; an element's label must be its own")]
    LabelIsMode(String),
    /// A definition that neither the model nor the mode gives.
    #[error("definition '{0}' has no value in this mode")]
    Undefined(String),
    /// A given number that is not finite.
    #[error("the value of '{0}' is not finite")]
    NotFinite(String),
    /// Two friction elements on one velocity.
    #[error("state '{0}' has two friction elements")]
    TwoFrictions(String),
    /// More of something than a model may have.
    #[error("{count} {what}; a model may have at most {limit}")]
    TooMany {
        /// What (`definitions`, `modes`, `elements`).
        what: &'static str,
        /// How many the model has.
        count: usize,
        /// The limit ([`MAX_DEFINITIONS`], [`MAX_MODES`], [`MAX_ELEMENTS`]).
        limit: usize,
    },
    /// More modes with definitions of their own, times the definitions,
    /// than [`MAX_MODE_DEFINITIONS`].
    #[error(
        "{modes} modes give definitions of their own and the model has {definitions} \
         definitions: each such mode checks them all, at most {MAX_MODE_DEFINITIONS} in all"
    )]
    ModeDefinitions {
        /// Modes with definitions of their own.
        modes: usize,
        /// Definitions of the model.
        definitions: usize,
    },
    /// An estimated state's bounds that are not finite with low <= high.
    #[error("estimate of '{0}': need finite bounds [low, high] with low <= high")]
    EstimateBounds(String),
    /// A state both measured (the rule's position or velocity) and estimated.
    #[error("'{0}' is measured by the rule; it cannot also be estimated")]
    MeasuredAndEstimated(String),
    /// An output map not affine in the state the measured rule reads it into.
    #[error(
        "output '{output}' = '{value}' is not affine in '{state}', the state the measured rule \
         reads it into: write the output as a sensor map such as 'c*{state} + off'"
    )]
    NotAffine {
        /// The output's name.
        output: String,
        /// Its expression.
        value: String,
        /// The rule's position state.
        state: String,
    },
    /// The compiled expressions would hold more than [`MAX_OPERATIONS`].
    #[error(
        "the model's expressions, with their definitions written out, hold more than \
         {MAX_OPERATIONS} operations (the limit)"
    )]
    TooLarge,
}

impl InvalidGrayBox {
    fn new(place: impl Into<String>, text: Option<&str>, problem: impl Into<Problem>) -> Self {
        InvalidGrayBox {
            place: place.into(),
            text: text.map(str::to_string),
            problem: problem.into(),
        }
    }

    /// The 1-based line of `source` (the model file's text, TOML or JSON)
    /// where the offending text is written: the first line holding it as
    /// a whole string, or a name as a key; an expression also inside a
    /// longer string. Never a comment or part of another word: `None`
    /// when it is written nowhere else.
    pub fn line_in(&self, source: &str) -> Option<usize> {
        let text = self.text.as_deref().filter(|t| !t.is_empty())?;
        crate::source::line_of(source, text)
    }
}

/// `e`, compiled from `text` at `place`, where a value is expected: not a
/// relation (a flow, an output, a reset, a level, a stop's position).
fn value(place: &str, text: &str, e: Expression) -> Result<Expression, InvalidGrayBox> {
    if e.is_relation() {
        Err(InvalidGrayBox::new(
            place,
            Some(text),
            Problem::NotValue(text.into()),
        ))
    } else {
        Ok(e)
    }
}

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
}

fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        && Function::ALL.iter().all(|f| f.name() != name)
        && !matches!(name, "true" | "false")
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
        let elements = compile_elements(
            m,
            &c.mode_index,
            &|p, n| c.state_of(p, n),
            &|p, n| c.parametric(p, n),
            &|p, n| c.restitution(p, n),
        )?;
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
            initial,
            internal_step: m.internal_step,
        })
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
            delays: self.delays.iter().map(b).collect(),
            energy: self.energy.as_ref().map(b),
            initial: self.initial.clone(),
            estimates: self.estimates.clone(),
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

/// The format version and the internal step.
fn check_header(m: &GrayBoxModel) -> Result<(), InvalidGrayBox> {
    if m.format != FORMAT_VERSION {
        return Err(InvalidGrayBox::new(
            "format",
            None,
            Problem::Version(m.format),
        ));
    }
    if !(m.internal_step > 0.0 && m.internal_step.is_finite()) {
        return Err(InvalidGrayBox::new(
            "internal_step",
            None,
            Problem::InternalStep,
        ));
    }
    Ok(())
}

/// The limits on definitions, modes and elements ([`MAX_DEFINITIONS`],
/// [`MAX_MODES`], [`MAX_ELEMENTS`], [`MAX_MODE_DEFINITIONS`]), checked
/// before any is compiled.
fn check_sizes(m: &GrayBoxModel, definitions: usize) -> Result<(), InvalidGrayBox> {
    for (what, count, limit) in [
        ("definitions", definitions, MAX_DEFINITIONS),
        ("modes", m.modes.len(), MAX_MODES),
        ("elements", m.elements.len(), MAX_ELEMENTS),
    ] {
        if count > limit {
            return Err(InvalidGrayBox::new(
                what,
                None,
                Problem::TooMany { what, count, limit },
            ));
        }
    }
    let own = m.modes.iter().filter(|q| !q.definitions.is_empty()).count();
    if own * definitions > MAX_MODE_DEFINITIONS {
        return Err(InvalidGrayBox::new(
            "modes",
            None,
            Problem::ModeDefinitions {
                modes: own,
                definitions,
            },
        ));
    }
    Ok(())
}

/// The modes by name, checked: one output, at least one mode, modes
/// named by identifiers, none twice.
fn mode_index(m: &GrayBoxModel) -> Result<BTreeMap<&str, usize>, InvalidGrayBox> {
    if m.outputs.len() != 1 {
        return Err(InvalidGrayBox::new(
            "outputs",
            None,
            Problem::Outputs(m.outputs.len()),
        ));
    }
    if m.modes.is_empty() {
        return Err(InvalidGrayBox::new("modes", None, Problem::NoMode));
    }
    let mut index = BTreeMap::new();
    for (i, q) in m.modes.iter().enumerate() {
        if !is_identifier(&q.name) {
            return Err(InvalidGrayBox::new(
                "modes",
                Some(&q.name),
                Problem::BadName(q.name.clone()),
            ));
        }
        if index.insert(q.name.as_str(), i).is_some() {
            return Err(InvalidGrayBox::new(
                "modes",
                Some(&q.name),
                Problem::Duplicate(q.name.clone()),
            ));
        }
    }
    Ok(index)
}

/// What compiling one model keeps at hand: the slots of its names, its
/// modes by name, the model's definitions (compiled when a mode first
/// reads them) and the operations compiled so far (at most
/// [`MAX_OPERATIONS`]).
struct Compiler<'m> {
    m: &'m GrayBoxModel,
    /// Every definition name ([`definition_names`]).
    names: Vec<&'m String>,
    /// The slot of every name ([`symbol_table`]).
    symbols: HashMap<&'m str, usize>,
    mode_index: BTreeMap<&'m str, usize>,
    /// Number of states: the first slots.
    nx: usize,
    /// The slot of the first definition.
    first_def: usize,
    /// Per definition name, the model's text, if it gives one.
    model_texts: Vec<Option<&'m String>>,
    /// Per definition name, the model's text compiled, once a mode read it.
    model_definitions: Vec<Option<Rc<Expression>>>,
    /// The definitions only modes give: every mode must give them.
    mode_only: Vec<usize>,
    operations: usize,
}

impl<'m> Compiler<'m> {
    fn new(m: &'m GrayBoxModel, names: Vec<&'m String>) -> Result<Self, InvalidGrayBox> {
        let symbols = symbol_table(m, &names)?;
        let mode_index = mode_index(m)?;
        // The model's definitions are the first names, in their order
        // ([`definition_names`]); the others only modes give.
        let model_texts: Vec<Option<&String>> = m
            .definitions
            .values()
            .map(Some)
            .chain(std::iter::repeat(None))
            .take(names.len())
            .collect();
        let mode_only = (0..names.len())
            .filter(|&i| model_texts[i].is_none())
            .collect();
        Ok(Compiler {
            nx: m.states.len(),
            first_def: m.states.len() + m.inputs.len() + m.parameters.len(),
            model_definitions: vec![None; names.len()],
            model_texts,
            mode_only,
            names,
            symbols,
            mode_index,
            m,
            operations: 0,
        })
    }

    fn resolve(&self, n: &str) -> Option<u32> {
        self.symbols.get(n).map(|&slot| slot as u32)
    }

    /// The slot of the state `n` (the states take the first slots).
    fn state_of(&self, place: &str, n: &str) -> Result<usize, InvalidGrayBox> {
        match self.symbols.get(n) {
            Some(&slot) if slot < self.nx => Ok(slot),
            _ => Err(InvalidGrayBox::new(
                place,
                Some(n),
                Problem::UnknownState(n.into()),
            )),
        }
    }

    fn mode_of(&self, place: &str, n: &str) -> Result<usize, InvalidGrayBox> {
        self.mode_index
            .get(n)
            .copied()
            .ok_or_else(|| InvalidGrayBox::new(place, Some(n), Problem::UnknownMode(n.into())))
    }

    /// The parameters' slots.
    fn parameter_slots(&self) -> std::ops::Range<u32> {
        (self.nx + self.m.inputs.len()) as u32..self.first_def as u32
    }

    fn expr(&self, place: &str, text: &str) -> Result<Expression, InvalidGrayBox> {
        self.expr_at(|| place.to_string(), text)
    }

    /// [`Compiler::expr`], with the place worded only for an error.
    fn expr_at(
        &self,
        place: impl FnOnce() -> String,
        text: &str,
    ) -> Result<Expression, InvalidGrayBox> {
        Expression::compile(text, &|n| self.resolve(n))
            .map_err(|e| InvalidGrayBox::new(place(), Some(text), e))
    }

    /// An expression of the parameters only.
    fn parametric(&self, place: &str, text: &str) -> Result<Expression, InvalidGrayBox> {
        let e = value(place, text, self.expr(place, text)?)?;
        let params = self.parameter_slots();
        if e.slots().all(|s| params.contains(&s)) {
            Ok(e)
        } else {
            Err(InvalidGrayBox::new(
                place,
                Some(text),
                Problem::NotParametric(text.into()),
            ))
        }
    }

    /// A stop's restitution: parameters only, within `[0, 1)` over the
    /// parameters' bounds where it is affine in them (a number, a
    /// parameter, a scaled sum), at their values otherwise.
    fn restitution(&self, place: &str, text: &str) -> Result<Expression, InvalidGrayBox> {
        let e = self.parametric(place, text)?;
        let first = self.parameter_slots().start;
        let parameter = |slot: u32| &self.m.parameters[(slot - first) as usize];
        let (low, high) = match e.affine() {
            Some((constant, terms)) => {
                terms
                    .iter()
                    .fold((constant, constant), |(low, high), &(slot, k)| {
                        let [a, b] = parameter(slot).bounds.map(|x| k * x);
                        (low + a.min(b), high + a.max(b))
                    })
            }
            None => {
                let v = e.bind(first, &self.m.values()).eval(&[]);
                (v, v)
            }
        };
        if low >= 0.0 && high < 1.0 {
            Ok(e)
        } else {
            Err(InvalidGrayBox::new(
                place,
                Some(text),
                Problem::Restitution {
                    text: text.into(),
                    low,
                    high,
                },
            ))
        }
    }

    /// A mode's definitions, checked: every name has a value, no cycle,
    /// none too deep once written out.
    fn definitions_of(&mut self, q: &GrayBoxMode) -> Result<Definitions, InvalidGrayBox> {
        let place = format!("mode '{}'", q.name);
        // The mode's own values, by index (every name is in the table).
        let mut own: Vec<(usize, &String)> = q
            .definitions
            .iter()
            .filter_map(|(d, text)| {
                Some((
                    self.symbols.get(d.as_str())?.checked_sub(self.first_def)?,
                    text,
                ))
            })
            .collect();
        own.sort_unstable_by_key(|&(i, _)| i);
        let model_texts = &self.model_texts;
        let text_of = |i: usize| match own.binary_search_by_key(&i, |&(j, _)| j) {
            Ok(k) => Some(own[k].1),
            Err(_) => model_texts[i],
        };
        if let Some(&i) = self.mode_only.iter().find(|&&i| text_of(i).is_none()) {
            let d = self.names[i];
            return Err(InvalidGrayBox::new(
                &place,
                Some(d),
                Problem::Undefined(d.to_string()),
            ));
        }
        let mut written = Vec::with_capacity(self.names.len());
        let mut mine = own.iter().peekable();
        for (i, d) in self.names.iter().enumerate() {
            let at = || format!("{place}, definition '{d}'");
            let e = match (mine.next_if(|&&(j, _)| j == i), self.model_texts[i]) {
                (Some((_, text)), _) => Rc::new(self.expr_at(at, text)?),
                (None, Some(text)) => match &self.model_definitions[i] {
                    Some(e) => Rc::clone(e),
                    None => {
                        let e = Rc::new(self.expr_at(at, text)?);
                        self.model_definitions[i] = Some(Rc::clone(&e));
                        e
                    }
                },
                (None, None) => unreachable!("every name only modes give is given above"),
            };
            written.push(e);
        }
        Definitions::new(self.first_def as u32, written).map_err(|e| match e {
            DefinitionError::Cycle(i) => InvalidGrayBox::new(
                &place,
                Some(self.names[i]),
                Problem::Cycle(self.names[i].to_string()),
            ),
            DefinitionError::TooDeep(i) => {
                let text = text_of(i).map_or("", String::as_str);
                InvalidGrayBox::new(
                    format!("{place}, definition '{}'", self.names[i]),
                    Some(text),
                    ExprError::TooDeep(text.to_string()),
                )
            }
        })
    }

    /// An expression of a mode with its definitions written in, counted
    /// into the operations compiled so far.
    fn inlined(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
        e: Expression,
    ) -> Result<Expression, InvalidGrayBox> {
        let at = |problem: Problem| InvalidGrayBox::new(place, Some(text), problem);
        let e = e.inline(defs, MAX_OPERATIONS).map_err(|e| {
            at(match e {
                InlineError::TooDeep => ExprError::TooDeep(text.into()).into(),
                InlineError::TooLarge => ExprError::TooLarge(MAX_OPERATIONS).into(),
            })
        })?;
        self.operations += e.operations();
        if self.operations > MAX_OPERATIONS {
            return Err(at(Problem::TooLarge));
        }
        Ok(e)
    }

    /// The value `text` compiled in a mode whose definitions are `defs`.
    fn direct(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
    ) -> Result<Expression, InvalidGrayBox> {
        let e = self.condition(defs, place, text)?;
        value(place, text, e)
    }

    /// [`Compiler::direct`] for a condition, which may be a relation.
    fn condition(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
    ) -> Result<Expression, InvalidGrayBox> {
        let e = self.expr(place, text)?;
        self.inlined(defs, place, text, e)
    }

    fn direct_relation(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
    ) -> Result<Relation, InvalidGrayBox> {
        let r = Relation::compile(text, &|n| self.resolve(n))
            .map_err(|e| InvalidGrayBox::new(place, Some(text), e))?;
        Ok(Relation {
            surface: self.inlined(defs, place, text, r.surface)?,
            crossing: r.crossing,
        })
    }

    /// Every mode with the transitions leaving it, each compiled with the
    /// definitions of the mode it leaves; the transitions' errors are
    /// reported in file order, after the modes'.
    fn compile_modes(&mut self) -> Result<Vec<CompiledMode>, InvalidGrayBox> {
        let m = self.m;
        let mut leaving = vec![Vec::new(); m.modes.len()];
        for (i, t) in m.transitions.iter().enumerate() {
            if let Some(&from) = self.mode_index.get(t.from.as_str()) {
                leaving[from].push(i);
            }
        }
        let mut transitions: Vec<Option<Result<CompiledTransition, InvalidGrayBox>>> =
            vec![None; m.transitions.len()];
        // The definitions of the modes that give none of their own.
        let mut common: Option<Definitions> = None;
        let mut modes = Vec::with_capacity(m.modes.len());
        for (qi, q) in m.modes.iter().enumerate() {
            let mut own = None;
            if !q.definitions.is_empty() {
                own = Some(self.definitions_of(q)?);
            } else if common.is_none() {
                common = Some(self.definitions_of(q)?);
            }
            let Some(defs) = own.as_mut().or(common.as_mut()) else {
                unreachable!("a mode's definitions are made above");
            };
            modes.push(self.compile_mode(q, defs)?);
            for &i in &leaving[qi] {
                transitions[i] = Some(self.compile_transition(&m.transitions[i], defs));
            }
        }
        for (t, compiled) in m.transitions.iter().zip(transitions) {
            let place = format!("transition {} -> {}", t.from, t.to);
            let from = self.mode_of(&place, &t.from)?;
            let to = self.mode_of(&place, &t.to)?;
            let Some(compiled) = compiled else {
                unreachable!("every transition from a mode is compiled with it");
            };
            modes[from]
                .transitions
                .push(CompiledTransition { to, ..compiled? });
        }
        Ok(modes)
    }

    /// A mode's flows, invariant, friction levels and output (its
    /// transitions are added by [`Compiler::compile_modes`]).
    fn compile_mode(
        &mut self,
        q: &GrayBoxMode,
        defs: &mut Definitions,
    ) -> Result<CompiledMode, InvalidGrayBox> {
        let m = self.m;
        let place = format!("mode '{}'", q.name);
        let mut flow = Vec::with_capacity(self.nx);
        for s in &m.states {
            let text = q.flow.get(s).ok_or_else(|| {
                InvalidGrayBox::new(&place, Some(&q.name), Problem::MissingFlow(s.clone()))
            })?;
            flow.push(self.direct(defs, &format!("{place}, flow of '{s}'"), text)?);
        }
        for s in q.flow.keys() {
            self.state_of(&format!("{place}, flow"), s)?;
        }
        let invariant = q
            .invariant
            .iter()
            .map(|t| self.direct_relation(defs, &format!("{place}, invariant"), t))
            .collect::<Result<_, _>>()?;
        let mut friction = Vec::with_capacity(m.elements.len());
        for e in &m.elements {
            friction.push(match e {
                Element::DryFriction {
                    kinetic,
                    static_level,
                    ..
                } => {
                    let at = format!("{place}, element '{}'", e.name());
                    (
                        self.direct(defs, &format!("{at}, kinetic"), kinetic)?,
                        self.direct(defs, &format!("{at}, static"), static_level)?,
                    )
                }
                Element::Stop { .. } => (Expression::constant(0.0), Expression::constant(0.0)),
            });
        }
        let output = &m.outputs[0];
        let output = self.direct(defs, &format!("output '{}'", output.name), &output.value)?;
        Ok(CompiledMode {
            joint_flow: Shared::of(&flow),
            flow,
            invariant,
            transitions: Vec::new(),
            friction,
            output,
        })
    }

    /// A transition's guard, condition and reset, in the definitions of
    /// the mode it leaves; `to` is set by [`Compiler::compile_modes`].
    fn compile_transition(
        &mut self,
        t: &GrayBoxTransition,
        defs: &mut Definitions,
    ) -> Result<CompiledTransition, InvalidGrayBox> {
        let place = format!("transition {} -> {}", t.from, t.to);
        let guard = self.direct_relation(defs, &format!("{place}, guard"), &t.guard)?;
        let when = t
            .when
            .as_deref()
            .map(|w| self.condition(defs, &format!("{place}, when"), w))
            .transpose()?;
        let mut reset = Vec::with_capacity(t.reset.len());
        for (s, text) in &t.reset {
            reset.push((
                self.state_of(&format!("{place}, reset"), s)?,
                self.direct(defs, &format!("{place}, reset of '{s}'"), text)?,
            ));
        }
        Ok(CompiledTransition {
            label: format!("{} -> {}", t.from, t.to),
            to: 0,
            guard,
            when,
            reset,
        })
    }

    /// Per input, its delay (parameters only; a constant 0 without one).
    fn compile_delays(&self) -> Result<Vec<Expression>, InvalidGrayBox> {
        let m = self.m;
        let mut delays = vec![Expression::constant(0.0); m.inputs.len()];
        for (input, text) in &m.delays {
            let i = m.inputs.iter().position(|n| n == input).ok_or_else(|| {
                InvalidGrayBox::new("delays", Some(input), Problem::UnknownInput(input.clone()))
            })?;
            delays[i] = self.parametric(&format!("delays, input '{input}'"), text)?;
        }
        Ok(delays)
    }

    /// The stored energy: states and parameters only.
    fn compile_energy(&self) -> Result<Option<Expression>, InvalidGrayBox> {
        let params = self.parameter_slots();
        self.m
            .energy
            .as_deref()
            .map(|text| {
                let e = value("energy", text, self.expr("energy", text)?)?;
                if e.slots()
                    .all(|s| (s as usize) < self.nx || params.contains(&s))
                {
                    Ok(e)
                } else {
                    Err(InvalidGrayBox::new(
                        "energy",
                        Some(text),
                        Problem::NotStateFunction(text.into()),
                    ))
                }
            })
            .transpose()
    }
}

/// Every definition name: the model's, then those only modes give, in the
/// order the modes first give them.
fn definition_names(m: &GrayBoxModel) -> Vec<&String> {
    let mut names: Vec<&String> = m.definitions.keys().collect();
    let mut seen: HashSet<&String> = names.iter().copied().collect();
    for q in &m.modes {
        for d in q.definitions.keys() {
            if seen.insert(d) {
                names.push(d);
            }
        }
    }
    names
}

/// The slot of every state, input, parameter and definition
/// (`definitions`, as [`definition_names`] lists them), in that order;
/// checks names and parameters.
fn symbol_table<'m>(
    m: &'m GrayBoxModel,
    definitions: &[&'m String],
) -> Result<HashMap<&'m str, usize>, InvalidGrayBox> {
    let mut table = HashMap::with_capacity(
        m.states.len() + m.inputs.len() + m.parameters.len() + definitions.len(),
    );
    let mut slot = 0;
    let mut add = |what: &str, name: &'m str| -> Result<(), InvalidGrayBox> {
        if !is_identifier(name) {
            return Err(InvalidGrayBox::new(
                what,
                Some(name),
                Problem::BadName(name.into()),
            ));
        }
        if table.insert(name, slot).is_some() {
            return Err(InvalidGrayBox::new(
                what,
                Some(name),
                Problem::Duplicate(name.into()),
            ));
        }
        slot += 1;
        Ok(())
    };
    for s in &m.states {
        add("states", s)?;
    }
    for s in &m.inputs {
        add("inputs", s)?;
    }
    for p in &m.parameters {
        add("parameters", &p.name)?;
        let [lo, hi] = p.bounds;
        if !(p.value.is_finite()
            && lo.is_finite()
            && hi.is_finite()
            && lo <= p.value
            && p.value <= hi)
        {
            return Err(InvalidGrayBox::new(
                "parameters",
                Some(&p.name),
                Problem::Parameter(p.name.clone()),
            ));
        }
    }
    for d in definitions {
        add("definitions", d)?;
    }
    Ok(table)
}

/// The elements, checked: names, states, labels, one friction per velocity,
/// stop quantities of parameters only.
fn compile_elements(
    m: &GrayBoxModel,
    mode_index: &BTreeMap<&str, usize>,
    state_of: &dyn Fn(&str, &str) -> Result<usize, InvalidGrayBox>,
    parametric: &dyn Fn(&str, &str) -> Result<Expression, InvalidGrayBox>,
    restitution_of: &dyn Fn(&str, &str) -> Result<Expression, InvalidGrayBox>,
) -> Result<Vec<CompiledElement>, InvalidGrayBox> {
    let labels = m.mode_names();
    let label_index: HashMap<&str, usize> = labels
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let label_of = |l: &str| label_index[l];
    let mut elements = Vec::with_capacity(m.elements.len());
    let mut names = BTreeSet::new();
    let mut friction_on = BTreeSet::new();
    for e in &m.elements {
        let place = format!("element '{}'", e.name());
        if !names.insert(e.name()) {
            return Err(InvalidGrayBox::new(
                "elements",
                Some(e.name()),
                Problem::Duplicate(e.name().into()),
            ));
        }
        if mode_index.contains_key(e.mode()) {
            return Err(InvalidGrayBox::new(
                &place,
                Some(e.mode()),
                Problem::LabelIsMode(e.mode().into()),
            ));
        }
        elements.push(match e {
            Element::DryFriction { velocity, mode, .. } => {
                let v = state_of(&place, velocity)?;
                if !friction_on.insert(v) {
                    return Err(InvalidGrayBox::new(
                        &place,
                        Some(velocity),
                        Problem::TwoFrictions(velocity.clone()),
                    ));
                }
                CompiledElement::DryFriction {
                    velocity: v,
                    label: label_of(mode),
                }
            }
            Element::Stop {
                position,
                velocity,
                at,
                side,
                restitution,
                rest_speed,
                mode,
                ..
            } => CompiledElement::Stop {
                position: state_of(&place, position)?,
                velocity: state_of(&place, velocity)?,
                at: parametric(&format!("{place}, at"), at)?,
                sign: side.sign(),
                restitution: restitution_of(&format!("{place}, restitution"), restitution)?,
                rest_speed: rest_speed.max(0.0),
                label: label_of(mode),
            },
        });
    }
    Ok(elements)
}

/// The initial-state rule and the states it estimates, checked: known
/// states and modes, finite values, bounds with low <= high, no state both
/// measured and estimated.
fn initial_rule(
    m: &GrayBoxModel,
    state_of: &dyn Fn(&str, &str) -> Result<usize, InvalidGrayBox>,
    mode_of: &dyn Fn(&str, &str) -> Result<usize, InvalidGrayBox>,
) -> Result<(CompiledInitial, Vec<EstimatedState>), InvalidGrayBox> {
    let place = "initial_state";
    let values = |given: &BTreeMap<String, f64>| -> Result<Vec<f64>, InvalidGrayBox> {
        let mut x = vec![0.0; m.states.len()];
        for (s, v) in given {
            if !v.is_finite() {
                return Err(InvalidGrayBox::new(
                    place,
                    Some(s),
                    Problem::NotFinite(s.clone()),
                ));
            }
            x[state_of(place, s)?] = *v;
        }
        Ok(x)
    };
    let mode = |q: &Option<String>| q.as_deref().map(|q| mode_of(place, q)).transpose();
    let no_estimate = Estimates::new();
    let (rule, estimate, given, measured) = match &m.initial_state {
        GrayBoxInitialState::Given {
            values: v,
            mode: q,
            estimate,
            samples,
        } => (
            CompiledInitial::Given {
                x: values(v)?,
                mode: mode(q)?,
                samples: samples.unwrap_or(DEFAULT_SAMPLES).max(1),
            },
            estimate,
            v,
            vec![],
        ),
        GrayBoxInitialState::Measured {
            samples,
            position,
            velocity,
            velocity_tol,
            values: v,
            mode: q,
            estimate,
        } => (
            CompiledInitial::Measured {
                samples: (*samples).max(1),
                position: state_of(place, position)?,
                velocity: velocity
                    .as_deref()
                    .map(|s| state_of(place, s))
                    .transpose()?,
                velocity_tol: velocity_tol.max(0.0),
                x: values(v)?,
                mode: mode(q)?,
            },
            estimate,
            v,
            std::iter::once(position).chain(velocity).collect(),
        ),
        GrayBoxInitialState::Steady { values: v, mode: q } => (
            CompiledInitial::Steady {
                x: values(v)?,
                mode: mode(q)?,
            },
            &no_estimate,
            v,
            vec![],
        ),
    };
    let mut estimates = Vec::with_capacity(estimate.len());
    for (name, &[lo, hi]) in estimate {
        let place = "initial_state, estimate";
        let state = state_of(place, name)?;
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(InvalidGrayBox::new(
                place,
                None,
                Problem::EstimateBounds(name.clone()),
            ));
        }
        if measured.contains(&name) {
            return Err(InvalidGrayBox::new(
                place,
                None,
                Problem::MeasuredAndEstimated(name.clone()),
            ));
        }
        let start = given.get(name).map_or(0.5 * (lo + hi), |v| v.clamp(lo, hi));
        estimates.push(EstimatedState {
            state,
            name: name.clone(),
            bounds: [lo, hi],
            start,
        });
    }
    Ok((rule, estimates))
}

/// With the measured rule, the output map of every mode must be affine in
/// the position state ([`Expression::affine_in`]): the state is read from
/// the output through its inverse.
fn check_sensor(
    m: &GrayBoxModel,
    initial: &CompiledInitial,
    modes: &[CompiledMode],
) -> Result<(), InvalidGrayBox> {
    let CompiledInitial::Measured { position, .. } = initial else {
        return Ok(());
    };
    if modes.iter().all(|q| q.output.affine_in(*position as u32)) {
        return Ok(());
    }
    let output = &m.outputs[0];
    Err(InvalidGrayBox::new(
        "initial_state",
        Some(&output.value),
        Problem::NotAffine {
            output: output.name.clone(),
            value: output.value.clone(),
            state: m.states[*position].clone(),
        },
    ))
}
