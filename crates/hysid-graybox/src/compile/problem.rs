//! What is wrong with a gray-box model, and where: the one error every
//! check of the compiler returns.

use super::{MAX_MODE_DEFINITIONS, MAX_OPERATIONS};
use crate::expr::{ExprError, Expression};
use crate::model::FORMAT_VERSION;

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
    /// A state, input, parameter or definition whose name another of them
    /// has (they share one namespace).
    #[error("'{name}' is already {kind}")]
    Taken {
        /// The name.
        name: String,
        /// What has it first: `a state`, `an input`, `a parameter`, `a
        /// definition`.
        kind: &'static str,
    },
    /// A parameter with non-finite numbers, low above high, or its value
    /// outside its bounds.
    #[error(
        "parameter '{name}': value {value} and bounds [{low}, {high}]: need finite numbers \
         with low <= value <= high (and high - low finite)"
    )]
    Parameter {
        /// The parameter.
        name: String,
        /// Its value.
        value: f64,
        /// Its lower bound.
        low: f64,
        /// Its upper bound.
        high: f64,
    },
    /// No input: every record and excitation drives one.
    #[error(
        "need at least one input (records and excitations drive one): give an autonomous system one it does not read, held at 0"
    )]
    NoInput,
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
    /// Definitions that read each other in a ring (the first named again
    /// at the end).
    #[error("definition '{}' depends on itself{}", .0[0], ring(.0))]
    Cycle(Vec<String>),
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
    /// A stop that bounds a position from below at or above one that
    /// bounds it from above, at the parameters' values.
    #[error(
        "stop '{below}' keeps the position at or above {at_least} and stop '{above}' at or \
         below {at_most}: no position lies between them at the parameters' values"
    )]
    CrossedStops {
        /// The stop that bounds it from below (`side = "min"`).
        below: String,
        /// Its position.
        at_least: f64,
        /// The stop that bounds it from above (`side = "max"`).
        above: String,
        /// Its position.
        at_most: f64,
    },
    /// An element's quantity that reads more than the parameters.
    #[error("'{0}' may only use parameters and numbers")]
    NotParametric(String),
    /// A guard whose surface reads neither a state nor an input: it never
    /// moves, so it is never crossed.
    #[error("'{0}' reads neither a state nor an input: the guard can never be crossed")]
    FixedGuard(String),
    /// An energy that reads more than the states and parameters.
    #[error("'{0}' may only use states, parameters and numbers")]
    NotStateFunction(String),
    /// An element label equal to a declared mode's name or label.
    #[error("the label '{0}' is a mode's name or label; an element's label must be its own")]
    LabelIsMode(String),
    /// An empty mode label.
    #[error("a mode label must not be empty")]
    EmptyLabel,
    /// A mode's label that is the name of another mode labelled otherwise.
    #[error("the label '{label}' is the name of a mode whose samples are labelled '{labelled}'")]
    LabelOfOtherMode {
        /// The label.
        label: String,
        /// The label of the mode of that name.
        labelled: String,
    },
    /// An `element_modes` entry naming no element.
    #[error("no element is named '{0}'")]
    UnknownElement(String),
    /// A definition that another mode gives, and neither the model nor
    /// this mode.
    #[error(
        "definition '{name}' has no value in this mode: mode '{given_by}' gives it, and a \
         definition a mode gives needs a value in every mode (its own, or the model's in \
         [definitions])"
    )]
    Undefined {
        /// The definition.
        name: String,
        /// The first mode that gives it.
        given_by: String,
    },
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
        /// The limit ([`MAX_DEFINITIONS`](super::MAX_DEFINITIONS),
        /// [`MAX_MODES`](super::MAX_MODES), [`MAX_ELEMENTS`](super::MAX_ELEMENTS)).
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
    #[error(
        "estimate of '{0}': need finite bounds [low, high] with low <= high (and high - low finite)"
    )]
    EstimateBounds(String),
    /// An estimated state's starting guess outside its bounds.
    #[error(
        "estimate of '{name}': the starting guess {value} lies outside the bounds [{low}, {high}]"
    )]
    EstimateStart {
        /// The state.
        name: String,
        /// Its starting guess (`values`).
        value: f64,
        /// Its lower bound.
        low: f64,
        /// Its upper bound.
        high: f64,
    },
    /// A `given` rule's `samples` without an `estimate`: no warm-up is read.
    #[error(
        "samples: a given rule reads a warm-up only to estimate states; give an estimate or leave samples out"
    )]
    WarmupWithoutEstimate,
    /// A warm-up of no sample.
    #[error("samples must be at least 1 (the warm-up's samples)")]
    NoWarmup,
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

/// `: a -> b -> a` for a ring of several definitions, nothing for one.
fn ring(names: &[String]) -> String {
    if names.len() < 2 {
        return String::new();
    }
    let path: Vec<&str> = names
        .iter()
        .chain(&names[..1])
        .map(String::as_str)
        .collect();
    format!(": {}", path.join(" -> "))
}

impl InvalidGrayBox {
    pub(super) fn new(
        place: impl Into<String>,
        text: Option<&str>,
        problem: impl Into<Problem>,
    ) -> Self {
        InvalidGrayBox {
            place: place.into(),
            text: text.map(str::to_string),
            problem: problem.into(),
        }
    }

    /// The 1-based line of `source` (the model file's text, TOML or JSON)
    /// where the offending text is written: the first line where the
    /// place's own key writes it as a whole string, else the first line
    /// holding it as a whole string, or a name as a key; an expression also
    /// inside a longer string. Never a comment or part of another word:
    /// `None` when it is written nowhere else.
    pub fn line_in(&self, source: &str) -> Option<usize> {
        let text = self.text.as_deref().filter(|t| !t.is_empty())?;
        if let Some(line) = self.entry_line(source, text) {
            return Some(line);
        }
        match self.field() {
            Some(key) => crate::source::line_of_field(source, key, text),
            None => crate::source::line_of(source, text),
        }
    }

    /// Where the offending text is an entry's name (the place is the
    /// entry, `mode 'free'` or `element 'f1'`, or a list that declares a
    /// name twice): the line of that entry's `name`, for a missing flow
    /// the line of its `flow`, for a name declared twice its second
    /// declaration ([`crate::source::entry_line`]); for a ring of
    /// definitions, where its first is written as a key.
    fn entry_line(&self, source: &str, text: &str) -> Option<usize> {
        match &self.problem {
            Problem::Duplicate(name) => return crate::source::entry_line(source, name, None, 1),
            // A ring of definitions: where its first is written.
            Problem::Cycle(ring) if ring.first().is_some_and(|d| d == text) => {
                return crate::source::key_line(source, text);
            }
            _ => {}
        }
        let entry = (self.place.strip_prefix("mode '"))
            .or_else(|| self.place.strip_prefix("element '"))
            .and_then(|rest| rest.strip_suffix('\''))
            .filter(|name| *name == text)?;
        let key = matches!(self.problem, Problem::MissingFlow(_)).then_some("flow");
        crate::source::entry_line(source, entry, key, 0)
    }

    /// The key that writes the text, where the place ends in one: `guard`
    /// of `transition a -> b, guard`, `v` of `mode 'm', flow of 'v'`.
    fn field(&self) -> Option<&str> {
        let last = self.place.rsplit(", ").next()?;
        match last.split_once(" of '") {
            Some((_, name)) => name.strip_suffix('\''),
            None => (!last.contains(' ')).then_some(last),
        }
    }
}

/// `e`, compiled from `text` at `place`, where a value is expected: not a
/// relation (a flow, an output, a reset, a level, a stop's position).
pub(super) fn value(place: &str, text: &str, e: Expression) -> Result<Expression, InvalidGrayBox> {
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
