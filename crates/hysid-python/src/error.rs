//! The exceptions of the package: every library error as the one-line
//! message the `hysid` program prints, with the Python argument names where
//! the program names its flags (`options` for `--set`, `modes` for
//! `--modes`, ...).
//!
//! Two kinds, as the program's exit codes tell them apart:
//! `hysid.InputError` (bad data, arguments, options, priors or model file;
//! a `ValueError`, exit code 2 in the program) and `hysid.MethodError`
//! (the method ran on valid input and failed; a `RuntimeError`, exit code
//! 1). Both derive from `hysid.HysidError`.

use hysid::select::SelectError;
use hysid_core::backend::IdentifyError;
use hysid_core::model::ModelError;
use hysid_core::options::OptionError;
use hysid_core::priors::PriorError;
use hysid_estimation::pwarx::standardize::StandardizeError;
use hysid_model::data::DataError;
use hysid_model::simulate::SimError;
use pyo3::exceptions::{PyException, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

pyo3::create_exception!(
    hysid,
    HysidError,
    PyException,
    "Base class of the package's errors: InputError (bad input, a ValueError) and \
     MethodError (the method failed, a RuntimeError). The message is the `hysid` \
     program's one line."
);

/// `hysid.InputError(HysidError, ValueError)`, made at import.
static INPUT_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
/// `hysid.MethodError(HysidError, RuntimeError)`, made at import.
static METHOD_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

const INPUT_DOC: &str = "Bad input: data (shapes, lengths, non-finite values, names), \
arguments, options, priors, a record or model file. A ValueError; the program exits \
with code 2 on the same input.";

const METHOD_DOC: &str = "The method ran on valid input and failed (a solver failure, \
every candidate or start failed, the data did not allow the fit asked for). A \
RuntimeError; the program exits with code 1 on the same input.";

/// A subclass of `HysidError` and `other` named `name`, in module `hysid`.
fn subclass<'py>(
    py: Python<'py>,
    name: &str,
    other: Bound<'py, PyType>,
    doc: &str,
) -> PyResult<Py<PyType>> {
    let namespace = PyDict::new(py);
    namespace.set_item("__doc__", doc)?;
    namespace.set_item("__module__", "hysid")?;
    let bases = PyTuple::new(py, [py.get_type::<HysidError>(), other])?;
    let made = py
        .get_type::<PyType>()
        .call1((name, bases, namespace))?
        .cast_into::<PyType>()?;
    Ok(made.unbind())
}

/// Adds `HysidError`, `InputError` and `MethodError` to `module`.
pub fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = module.py();
    module.add("HysidError", py.get_type::<HysidError>())?;
    let input = INPUT_ERROR.get_or_try_init(py, || {
        subclass(py, "InputError", py.get_type::<PyValueError>(), INPUT_DOC)
    })?;
    let method = METHOD_ERROR.get_or_try_init(py, || {
        subclass(
            py,
            "MethodError",
            py.get_type::<PyRuntimeError>(),
            METHOD_DOC,
        )
    })?;
    module.add("InputError", input.bind(py))?;
    module.add("MethodError", method.bind(py))?;
    Ok(())
}

/// Whose fault a failure is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Bad input: `hysid.InputError`.
    Input,
    /// The method failed: `hysid.MethodError`.
    Method,
}

/// A failure on its way to Python: its kind and the message, on one line.
#[derive(Debug)]
pub struct Failure {
    kind: Kind,
    message: String,
}

impl Failure {
    /// Bad input, worded by this crate.
    pub fn input(message: impl Into<String>) -> Self {
        Self::of(Kind::Input, message)
    }

    /// A failure of the method or of this crate itself (not the input).
    pub fn method(message: impl Into<String>) -> Self {
        Self::of(Kind::Method, message)
    }

    /// The same failure, said of record `record` (counted from 1) of a
    /// list of records.
    pub fn in_record(self, record: usize) -> Self {
        Self {
            message: format!("record {record}: {}", self.message),
            ..self
        }
    }

    /// A failure of kind `kind`.
    pub fn of(kind: Kind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> Self {
        let line = f.message.split_whitespace().collect::<Vec<_>>().join(" ");
        let lock = match f.kind {
            Kind::Input => &INPUT_ERROR,
            Kind::Method => &METHOD_ERROR,
        };
        Python::attach(|py| match lock.get(py) {
            Some(ty) => PyErr::from_type(ty.bind(py).clone(), line),
            // Only before the module's import finished: the base class.
            None => HysidError::new_err(line),
        })
    }
}

macro_rules! bad_input {
    ($($t:ty),*) => {$(
        impl From<$t> for Failure {
            fn from(e: $t) -> Self {
                Self::input(e.to_string())
            }
        }
    )*};
}

// A record or model file that cannot be read, a malformed model or prior
// file, a model that cannot simulate the record given: the user's input.
bad_input!(DataError, ModelError, PriorError, SimError);

impl From<hysid::identify::Error> for Failure {
    fn from(e: hysid::identify::Error) -> Self {
        use hysid::identify::{Error, Field};
        match e {
            Error::Field { field, value, what } => {
                let name = match field {
                    Field::Modes => "modes",
                    Field::MaxModes => "max_modes",
                    Field::TimeBudget => "time_budget",
                    Field::RefitStarts => "refit_starts",
                };
                Self::input(format!("{name}={value}: {what}"))
            }
            Error::Modes {
                modes,
                max_modes,
                problem,
            } => {
                let given: Vec<String> = [("modes", modes), ("max_modes", max_modes)]
                    .iter()
                    .filter_map(|(name, v)| v.map(|s| format!("{name}={s}")))
                    .collect();
                Self::input(format!("{}: {problem}", given.join(" ")))
            }
            Error::Identify(e) => e.into(),
            Error::Select(e) => e.into(),
            e @ Error::ShortRecord(_) => Self::input(format!("{e} (warmup=)")),
        }
    }
}

impl From<OptionError> for Failure {
    fn from(e: OptionError) -> Self {
        Self::input(e.render("option"))
    }
}

impl From<IdentifyError> for Failure {
    /// Every variant but `Failed` is the input's fault (an unknown method,
    /// a bad option or prior, data too short or non-finite, a mode count
    /// missing or too large for the data, a back-end's own refusal):
    /// `IdentifyError::is_bad_input`, which the program's exit code follows.
    fn from(e: IdentifyError) -> Self {
        let kind = if e.is_bad_input() {
            Kind::Input
        } else {
            Kind::Method
        };
        let standardize = e
            .downcast_ref::<StandardizeError>()
            .map(|s| s.render("standardize=True"));
        let message = match e {
            IdentifyError::Options(o) => o.render("option"),
            _ if let Some(m) = standardize => m,
            IdentifyError::NeedsModeCount {
                method,
                bounded: true,
            } => format!(
                "method '{method}' needs the number of modes: modes=S, max_modes=S (the count \
                 chosen by hold-out simulation FIT) or auto=True (chosen on selection rows), or \
                 modes / max_modes in the priors"
            ),
            IdentifyError::NeedsModeCount {
                method,
                bounded: false,
            } => format!(
                "method '{method}' needs the number of modes: modes=S (or auto=True to choose \
                 it on selection rows), or modes in the priors (a max_modes bound alone does \
                 not give it)"
            ),
            other => other.to_string(),
        };
        Self::of(kind, message)
    }
}

impl From<SelectError> for Failure {
    /// Selection rows, folds or a grid that do not fit are the input's
    /// fault; no candidate fitted is a failure of the method.
    fn from(e: SelectError) -> Self {
        match e {
            SelectError::Identify(e) => e.into(),
            SelectError::EveryCandidateRefused(e) => {
                let Failure { message, kind } = (*e).into();
                Failure {
                    message: format!("grid: every candidate was refused: {message}"),
                    kind,
                }
            }
            SelectError::Folds { folds, reason } => Self::input(format!("folds={folds}: {reason}")),
            SelectError::Rows { rows, reason } => {
                Self::input(format!("select_rows={rows}: {reason}"))
            }
            SelectError::Records { records, reason } => {
                Self::input(format!("select_records={records}: {reason}"))
            }
            SelectError::Candidate(c) => {
                Self::input(format!("grid {}={}: {}", c.key, c.value, c.reason))
            }
            e @ SelectError::Option { .. } => Self::input(e.to_string()),
            SelectError::GridFixed { key, given } => {
                use hysid::select::FixedBy;
                let by = match given {
                    FixedBy::Option(v) => format!("options={{'{key}': {v}}}"),
                    FixedBy::Modes(s) => format!("modes={s}"),
                    other => other.to_string(),
                };
                Self::input(format!(
                    "grid {key}: also fixed by {by}; give it in one place"
                ))
            }
            e @ SelectError::NoCandidate { .. } => Self::method(format!("auto: {e}")),
        }
    }
}
