//! Any model hysid identifies, simulates or validates, and its JSON (and
//! TOML) files.
//!
//! A model file is a JSON object tagged by `"kind"` (`docs/file-formats.md`).
//! Three kinds:
//!
//! - [`PwarxModel`] (`"pwarx"`): modes with a parameter vector and a
//!   polyhedral region in regressor space;
//! - [`HybridAutomaton`] (`"hybrid_automaton"`): discrete modes with affine
//!   dynamics and invariants, and transitions whose guard sets may be
//!   lower-dimensional, each with a reset map;
//! - [`MechanicalModel`] (`"mechanical"`): a mass-spring-friction hybrid
//!   automaton declared by its physical parameters, contacts and stops;
//! - [`GrayBoxModel`] (`"gray_box"`): a hybrid automaton written by its
//!   physics, with expressions, guards, resets and built-in elements.

use hysid_graybox::extends::Syntax;
use hysid_graybox::{GrayBoxInitialState, GrayBoxModel, InvalidGrayBox, extends};
use hysid_mechanical::{InvalidMechanical, MechanicalModel};
use hysid_model::model::{
    HybridAutomaton, InitialState, InvalidModel, ModelInfo, PwarxModel, Stop, StopBound,
};
use hysid_model::regressors::RegressorSpec;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

mod located;
mod translate;

pub(crate) use translate::written;
pub use translate::{Untranslatable, mechanical_labels, signed_sum, to_gray_box};

/// The names under which a model reads a record's signals
/// ([`Model::signal_names`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SignalNames {
    /// One name per input; `None` where the model names none, or not one
    /// per input.
    pub inputs: Option<Vec<String>>,
    /// The output's name; `None` where the model names none.
    pub output: Option<String>,
}

/// Why a model cannot start from a given state ([`Model::starting_from`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GivenStateError {
    /// A PWARX model has no state.
    #[error("a pwarx model has no state to give: its initial condition is its first outputs")]
    NoState,
    /// A name that is not one of the model's states.
    #[error("'{name}' is not a state of the model (its states: {})", .states.join(", "))]
    Unknown {
        /// The name given.
        name: String,
        /// The model's states.
        states: Vec<String>,
    },
    /// A value that is not a finite number.
    #[error("{name} = {value} is not finite")]
    NotFinite {
        /// The state.
        name: String,
        /// Its value.
        value: f64,
    },
    /// A state without a value.
    #[error("no value for the state '{name}' (give every state: {})", .states.join(", "))]
    Missing {
        /// The state.
        name: String,
        /// The model's states.
        states: Vec<String>,
    },
    /// A mechanical model without a gray-box form.
    #[error(transparent)]
    Untranslatable(Untranslatable),
}

/// The values of `state` in the order of `states`: every name a state,
/// every value finite, every state named.
fn every_state(
    states: &[String],
    state: &BTreeMap<String, f64>,
) -> Result<Vec<f64>, GivenStateError> {
    if let Some(name) = state.keys().find(|n| !states.contains(n)) {
        return Err(GivenStateError::Unknown {
            name: name.clone(),
            states: states.to_vec(),
        });
    }
    if let Some((name, &value)) = state.iter().find(|(_, v)| !v.is_finite()) {
        return Err(GivenStateError::NotFinite {
            name: name.clone(),
            value,
        });
    }
    states
        .iter()
        .map(|name| {
            state
                .get(name)
                .copied()
                .ok_or_else(|| GivenStateError::Missing {
                    name: name.clone(),
                    states: states.to_vec(),
                })
        })
        .collect()
}

/// What a file without a model's `kind` is, where its tables say: an
/// experiment file (`[data]` and `[[run]]` or `[[sweep]]`), or a prior
/// file (only the keys of priors).
fn other_file_kind(value: &serde_json::Value) -> Option<&'static str> {
    let table = value.as_object().filter(|t| !t.contains_key("kind"))?;
    let has = |key: &str| table.contains_key(key);
    if has("data") && (has("run") || has("sweep")) {
        return Some("an experiment file (its [data] and [[run]] tables)");
    }
    let priors = [
        "modes",
        "max_modes",
        "saturation",
        "fixed",
        "bounds",
        "tie",
        "equality",
        "switching",
    ];
    (!table.is_empty() && table.keys().all(|k| priors.contains(&k.as_str())))
        .then_some("a prior file")
}

/// Any model hysid can simulate and validate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Model {
    /// Piecewise ARX model.
    Pwarx(PwarxModel),
    /// Hybrid automaton with guards and resets.
    HybridAutomaton(HybridAutomaton),
    /// Mass-spring-friction hybrid automaton declared by its physics.
    Mechanical(MechanicalModel),
    /// Hybrid gray-box model written by its physics.
    GrayBox(GrayBoxModel),
}

/// Errors reading, writing or checking a model.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// File concerned.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The file is not a valid model.
    #[error("{path}: {message}")]
    Format {
        /// File concerned.
        path: String,
        /// What is wrong (with line and column when the parser knows them).
        message: String,
    },
    /// The model is structurally inconsistent.
    #[error("invalid model: {0}")]
    Invalid(#[from] StructureError),
}

/// What is structurally wrong with a model ([`Model::validate`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StructureError {
    /// A PWARX model or hybrid automaton.
    #[error(transparent)]
    Hybrid(#[from] InvalidModel),
    /// A mechanical model.
    #[error(transparent)]
    Mechanical(#[from] InvalidMechanical),
    /// A mechanical model whose gray-box form, the form it runs as, does
    /// not check (a parameter's name that is no gray-box name).
    #[error("as a gray-box model: {0}")]
    MechanicalForm(Box<InvalidGrayBox>),
    /// A gray-box model.
    #[error(transparent)]
    GrayBox(#[from] InvalidGrayBox),
    /// A sampling time in `info` that is not a positive number.
    #[error("info.ts must be a finite number of seconds > 0, got {0}")]
    SamplingTime(f64),
}

/// A [`located::ReadError`] of the file `origin`: `origin, line N:` and
/// the entry, as the checks of a gray-box model name theirs.
fn located_error(origin: &str, e: &located::ReadError) -> ModelError {
    ModelError::Format {
        path: match e.line {
            Some(line) => format!("{origin}, line {line}"),
            None => origin.to_string(),
        },
        message: e.describe(),
    }
}

impl Model {
    /// Short name of the kind, as in the file.
    pub fn kind(&self) -> &'static str {
        match self {
            Model::Pwarx(_) => "pwarx",
            Model::HybridAutomaton(_) => "hybrid_automaton",
            Model::Mechanical(_) => "mechanical",
            Model::GrayBox(_) => "gray_box",
        }
    }

    /// The gray-box form of a mechanical model ([`to_gray_box`]); a model
    /// of another kind has none.
    pub fn to_gray_box(&self) -> Result<GrayBoxModel, Untranslatable> {
        match self {
            Model::Mechanical(m) => to_gray_box(m),
            other => Err(Untranslatable::NotMechanical(other.kind())),
        }
    }

    /// Provenance of the model.
    pub fn info(&self) -> &ModelInfo {
        match self {
            Model::Pwarx(m) => &m.info,
            Model::HybridAutomaton(m) => &m.info,
            Model::Mechanical(m) => &m.info,
            Model::GrayBox(m) => &m.info,
        }
    }

    /// Mutable provenance.
    pub fn info_mut(&mut self) -> &mut ModelInfo {
        match self {
            Model::Pwarx(m) => &mut m.info,
            Model::HybridAutomaton(m) => &mut m.info,
            Model::Mechanical(m) => &mut m.info,
            Model::GrayBox(m) => &mut m.info,
        }
    }

    /// Number of inputs the model takes.
    pub fn inputs(&self) -> usize {
        match self {
            Model::Pwarx(m) => m.inputs,
            Model::HybridAutomaton(m) => m.inputs.len(),
            Model::Mechanical(m) => m.inputs.len(),
            Model::GrayBox(m) => m.inputs.len(),
        }
    }

    /// The model started from `state` (a value for every state, by name)
    /// at sample 0, in place of its file's initial-state rule; a gray-box
    /// rule's starting mode is kept. A mechanical model becomes its
    /// gray-box form ([`to_gray_box`]), whose states (`y`, `v`) take the
    /// values. A PWARX model has no state: its initial condition is its
    /// first outputs.
    pub fn starting_from(&self, state: &BTreeMap<String, f64>) -> Result<Model, GivenStateError> {
        match self {
            Model::Pwarx(_) => Err(GivenStateError::NoState),
            Model::HybridAutomaton(m) => {
                let values = every_state(&m.states, state)?;
                Ok(Model::HybridAutomaton(HybridAutomaton {
                    initial_state: InitialState::Given { state: values },
                    ..m.clone()
                }))
            }
            Model::Mechanical(m) => {
                let g = to_gray_box(m).map_err(GivenStateError::Untranslatable)?;
                Model::GrayBox(g).starting_from(state)
            }
            Model::GrayBox(m) => {
                let values = every_state(&m.states, state)?;
                let mode = match &m.initial_state {
                    GrayBoxInitialState::Given { mode, .. }
                    | GrayBoxInitialState::Measured { mode, .. }
                    | GrayBoxInitialState::Steady { mode, .. } => mode.clone(),
                };
                Ok(Model::GrayBox(GrayBoxModel {
                    initial_state: GrayBoxInitialState::Given {
                        values: m.states.iter().cloned().zip(values).collect(),
                        mode,
                        estimate: Default::default(),
                        samples: None,
                    },
                    ..m.clone()
                }))
            }
        }
    }

    /// Whether the model's initial state is given whole by its file (not
    /// read from the record's warm-up, estimated, or at rest): a run that
    /// starts at a later row of a record starts there from that state.
    pub fn initial_state_given(&self) -> bool {
        match self {
            Model::Pwarx(_) => false,
            Model::HybridAutomaton(m) => {
                matches!(
                    m.initial_state,
                    hysid_model::model::InitialState::Given { .. }
                )
            }
            Model::Mechanical(m) => {
                matches!(
                    m.initial_state,
                    hysid_mechanical::MechanicalInitialState::Given { .. }
                )
            }
            Model::GrayBox(m) => matches!(
                &m.initial_state,
                hysid_graybox::GrayBoxInitialState::Given { estimate, .. } if estimate.is_empty()
            ),
        }
    }

    /// The names under which the model reads its inputs and output from a
    /// record: those it was identified on, else the names its file
    /// declares (a mechanical, gray-box or automaton file's `inputs`, a
    /// gray-box file's output `name`).
    pub fn signal_names(&self) -> SignalNames {
        let info = self.info();
        let declared = match self {
            Model::Pwarx(_) => &[][..],
            Model::HybridAutomaton(m) => &m.inputs[..],
            Model::Mechanical(m) => &m.inputs[..],
            Model::GrayBox(m) => &m.inputs[..],
        };
        let inputs = [&info.input_names[..], declared]
            .into_iter()
            .find(|names| !names.is_empty() && names.len() == self.inputs())
            .map(<[String]>::to_vec);
        let declared_output = match self {
            Model::GrayBox(m) => m.outputs.first().map(|o| o.name.as_str()),
            _ => None,
        };
        let output = [Some(info.output_name.as_str()), declared_output]
            .into_iter()
            .flatten()
            .find(|name| !name.is_empty())
            .map(str::to_string);
        SignalNames { inputs, output }
    }

    /// The ARX orders of a model whose state is a window of past outputs
    /// and inputs (PWARX models, automata with an ARX history); `None` for
    /// the others.
    pub fn orders(&self) -> Option<RegressorSpec> {
        match self {
            Model::Pwarx(m) => Some(m.spec()),
            Model::HybridAutomaton(m) => match m.initial_state {
                InitialState::ArxHistory { na, nb } => {
                    Some(RegressorSpec::new(na, nb, m.inputs.len()))
                }
                InitialState::Given { .. } => None,
            },
            Model::Mechanical(_) | Model::GrayBox(_) => None,
        }
    }

    /// Number of discrete modes.
    pub fn mode_count(&self) -> usize {
        match self {
            Model::Pwarx(m) => m.modes.len(),
            Model::HybridAutomaton(m) => m.modes.len(),
            Model::Mechanical(m) => m.modes.len(),
            Model::GrayBox(m) => m.mode_names().len(),
        }
    }

    /// Mode names (index strings for unnamed PWARX modes).
    pub fn mode_names(&self) -> Vec<String> {
        match self {
            Model::Pwarx(m) => (0..m.modes.len())
                .map(|i| hysid_model::model::mode_name(m.modes[i].name.as_deref(), i))
                .collect(),
            Model::HybridAutomaton(m) => m.modes.iter().map(|q| q.name.clone()).collect(),
            Model::Mechanical(m) => m.modes.iter().map(|q| q.name.clone()).collect(),
            Model::GrayBox(m) => m.mode_names(),
        }
    }

    /// The known output stops: none for a PWARX model; the stop modes of a
    /// hybrid automaton ([`HybridAutomaton::stops`]); the declared stops of
    /// a mechanical model at its parameter values.
    pub fn stops(&self) -> Vec<Stop> {
        let stop = |(level, sign): (f64, f64)| Stop {
            level,
            bound: if sign > 0.0 {
                StopBound::Max
            } else {
                StopBound::Min
            },
            tol: None,
        };
        match self {
            Model::Pwarx(_) => Vec::new(),
            Model::HybridAutomaton(m) => m.stops(),
            Model::Mechanical(m) => m
                .resolve()
                .stops
                .iter()
                .map(|s| stop((s.position, s.sign)))
                .collect(),
            Model::GrayBox(m) => m.output_stops().into_iter().map(stop).collect(),
        }
    }

    /// Structural checks: dimensions agree, numbers are finite, names
    /// resolve; a mechanical model has a gray-box form.
    pub fn validate(&self) -> Result<(), ModelError> {
        if let Some(ts) = self.info().ts
            && !(ts.is_finite() && ts > 0.0)
        {
            return Err(ModelError::Invalid(StructureError::SamplingTime(ts)));
        }
        match self {
            Model::Pwarx(m) => m.validate().map_err(StructureError::from),
            Model::HybridAutomaton(m) => m.validate().map_err(StructureError::from),
            Model::Mechanical(m) => match to_gray_box(m) {
                Ok(_) | Err(Untranslatable::NotMechanical(_)) => Ok(()),
                Err(Untranslatable::Mechanical(e)) => Err(StructureError::from(e)),
                Err(Untranslatable::GrayBox(e)) => Err(StructureError::MechanicalForm(Box::new(e))),
            },
            Model::GrayBox(m) => m.validate().map_err(StructureError::from),
        }
        .map_err(ModelError::Invalid)
    }

    /// Parses a model from JSON text; `origin` names the source in errors.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, ModelError> {
        match serde_json::from_str::<Model>(text) {
            Ok(m) => m.checked(text, origin),
            // A NaN or an infinity, which JSON has no words for, is said
            // so beside the parser's position.
            Err(e) if extends::json_message(&e, text) != e.to_string() => Err(ModelError::Format {
                path: origin.to_string(),
                message: extends::json_message(&e, text),
            }),
            Err(e) => Err(Self::unreadable(text, origin, Syntax::Json, e.to_string())),
        }
    }

    /// The error of a file's `text` that does not deserialize as a model:
    /// the parser's error at its line ([`located`]), with the entry for
    /// TOML, read straight into the struct of the kind the file declares;
    /// `message`, the tagged reader's, when that finds no error or the
    /// kind is unknown.
    fn unreadable(text: &str, origin: &str, syntax: Syntax, message: String) -> ModelError {
        let found = located::kind_of(text, syntax)
            .and_then(|kind| located::read_error(&kind, text, syntax));
        match found {
            Some(e) => located_error(origin, &e),
            None => ModelError::Format {
                path: origin.to_string(),
                message,
            },
        }
    }

    /// [`Model::validate`], with the line of `text` (the file) that a
    /// gray-box model's error points at.
    fn checked(self, text: &str, origin: &str) -> Result<Self, ModelError> {
        self.checked_in(&[(origin, text)])
    }

    /// [`Model::validate`] of a model read from `files` (`(origin, text)`,
    /// a file first, then the bases it extends): a gray-box model's error
    /// names the first file, and its line, that writes the offending text.
    fn checked_in(self, files: &[(&str, &str)]) -> Result<Self, ModelError> {
        let e = match self.validate() {
            Ok(()) => return Ok(self),
            Err(e) => e,
        };
        let located = match &e {
            ModelError::Invalid(StructureError::GrayBox(g)) => files
                .iter()
                .find_map(|(origin, text)| Some(format!("{origin}, line {}", g.line_in(text)?))),
            _ => None,
        };
        // Found in no file: a model merged from several is named with the
        // files it extends, where the merge may have made the fault.
        let merged = || match files {
            [(origin, _)] => origin.to_string(),
            [(origin, _), bases @ ..] => {
                let bases: Vec<&str> = bases.iter().map(|(b, _)| *b).collect();
                format!("{origin} (merged with {})", bases.join(", "))
            }
            [] => String::new(),
        };
        Err(ModelError::Format {
            path: located.unwrap_or_else(merged),
            message: e.to_string(),
        })
    }

    /// Parses a hand-written TOML model.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ModelError> {
        match toml::from_str::<Model>(text) {
            Ok(m) => m.checked(text, origin),
            Err(e) => Err(Self::unreadable(
                text,
                origin,
                Syntax::Toml,
                e.to_string().trim().replace('\n', " "),
            )),
        }
    }

    /// Reads a `.json` or `.toml` model file, with the bases it
    /// `extends` ([`hysid_graybox::extends`]) laid under it.
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        let origin = path.display().to_string();
        let resolved = extends::read(path).map_err(|e| match e {
            extends::ExtendsError::Read { path, source } => ModelError::Io {
                path: path.display().to_string(),
                source,
            },
            extends::ExtendsError::Syntax { path, message }
            | extends::ExtendsError::Chain { path, message } => ModelError::Format {
                path: path.display().to_string(),
                message,
            },
        })?;
        if let Some(other) = other_file_kind(&resolved.value) {
            return Err(ModelError::Format {
                path: origin,
                message: format!(
                    "{other}, not a model file (which names its kind: kind = \"pwarx\", \"hybrid_automaton\", \"mechanical\" or \"gray_box\")"
                ),
            });
        }
        let m = match Model::deserialize(&resolved.value) {
            Ok(m) => m,
            // A file on its own is parsed again from its text, so that a
            // wrong field gets the parser's line (and, in TOML, its entry).
            Err(_) if resolved.sources.len() == 1 => {
                let text = &resolved.sources[0].text;
                return match Syntax::of(path, text) {
                    Syntax::Toml => Self::from_toml(text, &origin),
                    Syntax::Json => Self::from_json(text, &origin),
                };
            }
            // The first file of the chain whose own text raises the same
            // error names it, with its line.
            Err(e) => {
                let message = e.to_string();
                let kind = resolved.value.get("kind").and_then(|k| k.as_str());
                let found = kind.and_then(|kind| {
                    resolved.sources.iter().find_map(|s| {
                        let name = s.path.display().to_string();
                        let syntax = Syntax::of(&s.path, &s.text);
                        let e = located::chain_error(kind, &s.text, syntax, &message)?;
                        Some(located_error(&name, &e))
                    })
                });
                return Err(found.unwrap_or_else(|| ModelError::Format {
                    path: origin,
                    message: format!("{message} (in the file or the files it extends)"),
                }));
            }
        };
        let names: Vec<String> = resolved
            .sources
            .iter()
            .map(|s| s.path.display().to_string())
            .collect();
        let files: Vec<(&str, &str)> = names
            .iter()
            .zip(&resolved.sources)
            .map(|(name, s)| (name.as_str(), s.text.as_str()))
            .collect();
        m.checked_in(&files)
    }

    /// Pretty JSON with a trailing newline (deterministic).
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("models serialise");
        s.push('\n');
        s
    }

    /// TOML (deterministic), the format of hand-written model files;
    /// `None` for a model TOML cannot hold (a missing value in a list).
    /// TOML has no null: an entry whose value is missing (an unset option,
    /// a diagnostic not computed) is left out, as its reader takes it.
    pub fn to_toml(&self) -> Option<String> {
        fn drop_nulls(value: &mut serde_json::Value) {
            match value {
                serde_json::Value::Object(map) => {
                    map.retain(|_, v| !v.is_null());
                    map.values_mut().for_each(drop_nulls);
                }
                serde_json::Value::Array(items) => items.iter_mut().for_each(drop_nulls),
                _ => {}
            }
        }
        let mut value = serde_json::to_value(self).ok()?;
        drop_nulls(&mut value);
        let model = Model::deserialize(&value).ok()?;
        toml::to_string(&model).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_model::geometry::Polyhedron;
    use hysid_model::model::PwarxMode;
    use proptest::prelude::*;

    #[test]
    fn spec_example_parses() {
        let text = r#"{
          "kind": "pwarx", "na": 2, "nb": 2, "inputs": 1,
          "modes": [ { "theta": [0.9, -0.2, 0.1, 0.05, 1.3],
                       "region": { "a": [[1.0, 0.0, 0.0, 0.0]], "b": [25.0] } } ] }"#;
        let m = Model::from_json(text, "x.json").unwrap();
        assert_eq!(m.kind(), "pwarx");
        assert_eq!(m.mode_count(), 1);
        let bad = text.replace("[0.9, -0.2, 0.1, 0.05, 1.3]", "[0.9]");
        let e = Model::from_json(&bad, "x.json").unwrap_err().to_string();
        assert!(e.contains("x.json") && e.contains("theta"), "{e}");
        // Text given as such (Python's Model.from_json) gets the reason too.
        let nan = text.replace("0.05", "NaN");
        let e = Model::from_json(&nan, "x.json").unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("JSON has no NaN"), "{e}");
    }

    #[test]
    fn a_model_file_may_extend_another() {
        let dir = std::env::temp_dir().join(format!("hysid-core-extends-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let head = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/pick-and-place/head-graybox.toml"
        );
        let write = |name: &str, body: &str| {
            let p = dir.join(name);
            std::fs::write(&p, format!("extends = {head:?}\n{body}")).unwrap();
            p
        };
        let cubic = write(
            "cubic.toml",
            "[[parameters]]\nname = \"c3\"\nvalue = 0.1\nbounds = [-1.0, 1.0]\n\
             [definitions]\nF = \"ku*u + f0 - c1*y - c3*y^3 - d1*v\"\n",
        );
        let Model::GrayBox(g) = Model::load(&cubic).unwrap() else {
            panic!("not a gray-box model")
        };
        let Model::GrayBox(base) = Model::load(Path::new(head)).unwrap() else {
            panic!("not a gray-box model")
        };
        assert_eq!(g.parameters.len(), base.parameters.len() + 1);
        assert_eq!(g.parameters.last().unwrap().name, "c3");
        assert_eq!(g.modes, base.modes);
        assert_ne!(g.definitions["F"], base.definitions["F"]);

        let unknown = write("unknown.toml", "\n[definitions]\nF = \"ku*u + nosuch\"\n");
        let e = Model::load(&unknown).unwrap_err().to_string();
        assert!(
            e.contains("unknown.toml, line 4") && e.contains("nosuch"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");

        // A fault the merge made, written in no file as such: the file is
        // named with the files it extends.
        let second = write(
            "second.toml",
            "outputs = [{ name = \"z\", value = \"y\" }]\n",
        );
        let e = Model::load(&second).unwrap_err().to_string();
        let merged = format!("second.toml (merged with {head}): ");
        assert!(e.contains(&merged) && e.contains("found 2"), "{e}");

        let gone = write("gone.toml", "remove = [\"parameters.nosuch\"]\n");
        let e = Model::load(&gone).unwrap_err().to_string();
        assert!(
            e.contains("gone.toml: remove: the base has no entry `parameters.nosuch`"),
            "{e}"
        );
        std::fs::remove_dir_all(dir).unwrap();
    }

    /// A misspelt field of a PWARX model or hybrid automaton is refused,
    /// in one line naming the file and the field, wherever it is written;
    /// `info` keeps fields this version does not know.
    #[test]
    fn unknown_fields_of_pwarx_models_and_automata_are_refused() {
        let ball = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/examples/bouncing-ball.toml"
        ))
        .unwrap();
        Model::from_toml(&ball, "hb.toml").unwrap();
        for (from, to) in [
            ("reset = {", "rest = {"),
            ("invariant = {", "invarient = {"),
            ("internal_step = ", "internal_stp = "),
            (
                "[output]\nc = [1.0, 0.0]",
                "[output]\nc = [1.0, 0.0]\nf = 1.0",
            ),
            ("flow = { a", "flow = { z = [], a"),
            ("guard = { a", "guard = { a_qe = [], a"),
            ("state = [2.0, 0.0]", "state = [2.0, 0.0], na = 2"),
            ("from = \"fly\"", "from = \"fly\"\nwhen = \"v < 0\""),
        ] {
            assert_eq!(ball.matches(from).count(), 1, "{from}");
            let typo = ball.replace(from, to);
            let e = Model::from_toml(&typo, "hb.toml").unwrap_err().to_string();
            let field = to
                .split(['\n', ',', '{'])
                .rev()
                .find_map(|part| Some(part.split_once('=')?.0.trim()))
                .unwrap();
            assert!(
                e.starts_with("hb.toml") && e.contains(&format!("unknown field `{field}`")),
                "{to}: {e}"
            );
            assert!(!e.contains('\n'), "{e}");
        }

        let pwarx = r#"{"kind": "pwarx", "na": 1, "nb": 1, "inputs": 1,
            "modes": [{"theta": [0.5, 1.0, 0.0], "region": {"a": [[1.0, 0.0]], "b": [0.0]}}],
            "info": {"method": "arx", "written_by": "a later version",
                     "diagnostics": {"own_count": 3}}}"#;
        Model::from_json(pwarx, "m.json").unwrap();
        for (from, to) in [
            ("\"region\"", "\"regoin\""),
            ("\"b\": [0.0]", "\"b\": [0.0], \"c\": [1.0]"),
            ("\"inputs\": 1", "\"inputs\": 1, \"ny\": 1"),
        ] {
            let typo = pwarx.replace(from, to);
            let e = Model::from_json(&typo, "m.json").unwrap_err().to_string();
            let field = to.rsplit(", ").next().unwrap().split('"').nth(1).unwrap();
            assert!(
                e.starts_with("m.json") && e.contains(&format!("unknown field `{field}`")),
                "{to}: {e}"
            );
        }
    }

    /// A field of the wrong name, type or variant in a gray-box file names
    /// the file, the line and the entry, in TOML (also in a file that
    /// extends another, and in its base) and in JSON.
    #[test]
    fn field_errors_name_the_line_and_the_entry() {
        let head_path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/pick-and-place/head-graybox.toml"
        );
        let head = std::fs::read_to_string(head_path).unwrap();
        // The 1-based line of the `nth` line of `text` that holds `part`.
        let line = |text: &str, part: &str, nth: usize| {
            text.lines()
                .enumerate()
                .filter(|(_, l)| l.contains(part))
                .nth(nth)
                .map(|(i, _)| i + 1)
                .unwrap()
        };
        let cases = [
            ("flow = ", "flwo = ", "modes", "unknown field `flwo`"),
            (
                "value = 640.0",
                "value = \"640\"",
                "parameters.value",
                "invalid type: string \"640\", expected a number",
            ),
            (
                "type = \"dry_friction\"",
                "type = \"dry_fricton\"",
                "elements.type",
                "unknown variant `dry_fricton`",
            ),
            (
                "from = \"measured\"",
                "from = \"measurd\"",
                "initial_state.from",
                "unknown variant `measurd`",
            ),
            (
                "bounds = [8.0, 17.0]",
                "bounds = [8.0, 17.0, 3.0]",
                "parameters.bounds",
                "invalid length 3, expected bounds [low, high]: 2 numbers",
            ),
            (
                "internal_step =",
                "internal_stp =",
                "",
                "unknown field `internal_stp`",
            ),
        ];
        for (from, to, entry, message) in cases {
            let g = head.replacen(from, to, 1);
            let at = line(&g, to, 0);
            let e = Model::from_toml(&g, "g.toml").unwrap_err().to_string();
            let entry = if entry.is_empty() {
                String::new()
            } else {
                format!("{entry}: ")
            };
            assert!(
                e.starts_with(&format!("g.toml, line {at}: {entry}{message}")),
                "{to}: {e}"
            );
        }
        // A field of a stop element: the line of its entry, not of the
        // first element's.
        let g = head.replace("side = \"min\"", "side = \"minimum\"");
        let e = Model::from_toml(&g, "g.toml").unwrap_err().to_string();
        let at = line(&g, "[[elements]]", 1);
        assert!(
            e.starts_with(&format!(
                "g.toml, line {at}: elements: unknown variant `minimum`"
            )),
            "{e}"
        );
        // A field of an automaton, and a missing field of the whole file
        // (no line).
        let ball = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/examples/bouncing-ball.toml"
        ))
        .unwrap();
        let hb = ball.replace("reset = {", "rest = {");
        let e = Model::from_toml(&hb, "hb.toml").unwrap_err().to_string();
        let at = line(&hb, "rest = {", 0);
        assert!(
            e.starts_with(&format!(
                "hb.toml, line {at}: transitions: unknown field `rest`"
            )),
            "{e}"
        );
        let hb = ball.replace("states = [\"y\", \"v\"]", "");
        let e = Model::from_toml(&hb, "hb.toml").unwrap_err().to_string();
        assert_eq!(e, "hb.toml: missing field `states`");

        // JSON: the line of the value.
        let value: serde_json::Value = toml::from_str(&head).unwrap();
        let json = serde_json::to_string_pretty(&value)
            .unwrap()
            .replace("\"value\": 640.0", "\"value\": \"640\"");
        let e = Model::from_json(&json, "g.json").unwrap_err().to_string();
        let at = line(&json, "      \"value\": \"640\"", 0);
        assert!(
            e.starts_with(&format!(
                "g.json, line {at}: invalid type: string \"640\", expected a number"
            )),
            "{e}"
        );

        // A chain of files: the file that writes the field, and its line.
        let dir = std::env::temp_dir().join(format!("hysid-core-located-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let lag = "extends = \"base.toml\"\nremove = [\"energy\"]\nstates = [\"y\", \"v\", \"ul\"]\n\n\
                   [initial_state]\nvalues = { ul = -0.05 }\n\n\
                   [[parameters]]\nname = \"tau\"\nvalue = 0.005\nbounds = [0.0005, 0.05]\n\n\
                   [definitions]\nF = \"ku*ul + f0 - c1*y - d1*v\"\n\n\
                   [[modes]]\nname = \"free\"\nflow = { ul = \"(u - ul)/tau\" }\n\n\
                   [[modes]]\nname = \"impact\"\nflow = { ul = \"(u - ul)/tau\" }\n";
        let load = |base: &str, own: &str| {
            std::fs::write(dir.join("base.toml"), base).unwrap();
            std::fs::write(dir.join("lag.toml"), own).unwrap();
            Model::load(&dir.join("lag.toml"))
        };
        load(&head, lag).unwrap();
        for (from, to, entry, message) in [
            (
                "value = 0.005",
                "value = \"0.005\"",
                "parameters.value",
                "invalid type: string \"0.005\", expected a number",
            ),
            (
                "flow = { ul",
                "flwo = { ul",
                "modes",
                "unknown field `flwo`",
            ),
        ] {
            let own = lag.replacen(from, to, 1);
            let e = load(&head, &own).unwrap_err().to_string();
            let at = line(&own, to, 0);
            let want = format!("lag.toml, line {at}: {entry}: {message}");
            assert!(e.contains(&want) && !e.contains("base.toml"), "{e}");
        }
        let base = head.replace("value = 640.0", "value = \"640\"");
        let e = load(&base, lag).unwrap_err().to_string();
        let at = line(&base, "value = \"640\"", 0);
        assert!(
            e.contains(&format!(
                "base.toml, line {at}: parameters.value: invalid type"
            )),
            "{e}"
        );
        std::fs::remove_dir_all(dir).unwrap();
    }

    /// Every model file of the repository reads: the `.json` and `.toml`
    /// files under `models/`, `docs/` and `crates/` whose document (with
    /// its bases) has a `kind`. Model structures refuse unknown fields, so
    /// a field a file carries outside `info` fails here.
    #[test]
    fn every_model_file_of_the_repository_reads() {
        fn walk(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
            for entry in std::fs::read_dir(dir).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    if path.file_name().is_some_and(|n| n != "target") {
                        walk(&path, out);
                    }
                } else if path.extension().is_some_and(|e| e == "json" || e == "toml") {
                    out.push(path);
                }
            }
        }
        let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
        let mut paths = Vec::new();
        for dir in ["models", "docs", "crates"] {
            walk(&root.join(dir), &mut paths);
        }
        let mut kinds = std::collections::BTreeMap::<String, usize>::new();
        let mut failures = Vec::new();
        for path in &paths {
            let Ok(file) = extends::read(path) else {
                continue;
            };
            if file.value.get("kind").is_none() {
                continue;
            }
            match Model::load(path) {
                Ok(m) => *kinds.entry(m.kind().to_string()).or_default() += 1,
                Err(e) => failures.push(e.to_string()),
            }
        }
        assert!(failures.is_empty(), "{}", failures.join("\n"));
        // The scan reaches every kind, and the identified models of docs/.
        for kind in ["pwarx", "hybrid_automaton", "mechanical", "gray_box"] {
            assert!(kinds.contains_key(kind), "no {kind} file: {kinds:?}");
        }
        assert!(kinds.values().sum::<usize>() >= 150, "{kinds:?}");
    }

    fn arb_pwarx() -> impl Strategy<Value = PwarxModel> {
        (1usize..3, 0usize..3, 1usize..4).prop_flat_map(|(na, nb, s)| {
            let d = na + nb;
            proptest::collection::vec(
                (
                    proptest::collection::vec(-10.0f64..10.0, d + 1),
                    proptest::collection::vec(proptest::collection::vec(-5.0f64..5.0, d), 0..3),
                    any::<u64>(),
                ),
                s,
            )
            .prop_map(move |modes| PwarxModel {
                na,
                nb,
                inputs: 1,
                modes: modes
                    .into_iter()
                    .map(|(theta, a, seed)| PwarxMode {
                        theta,
                        region: Polyhedron::from_inequalities(
                            a.clone(),
                            a.iter()
                                .enumerate()
                                .map(|(i, _)| (seed % 7) as f64 + i as f64 * 0.1)
                                .collect(),
                        ),
                        name: None,
                    })
                    .collect(),
                info: ModelInfo {
                    method: "arx".into(),
                    seed: Some(3),
                    ..Default::default()
                },
            })
        })
    }

    proptest! {
        /// Serde round trip is the identity (JSON, bit-exact floats).
        #[test]
        fn json_round_trip_is_identity(m in arb_pwarx()) {
            let model = Model::Pwarx(m);
            let back = Model::from_json(&model.to_json(), "mem").unwrap();
            prop_assert_eq!(&back, &model);
            prop_assert_eq!(back.to_json(), model.to_json());
        }
    }
}
