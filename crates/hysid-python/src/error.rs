//! `hysid.HysidError`: every library error as the one-line message the
//! `hysid` program prints, with the Python argument names where the program
//! names its flags (`options` for `--set`, `modes` for `--modes`, ...).

use hysid::select::SelectError;
use hysid_core::backend::IdentifyError;
use hysid_core::model::ModelError;
use hysid_core::options::OptionError;
use hysid_core::priors::PriorError;
use hysid_model::data::DataError;
use hysid_model::simulate::SimError;
use pyo3::PyErr;
use pyo3::exceptions::PyValueError;

pyo3::create_exception!(
    hysid,
    HysidError,
    PyValueError,
    "Bad input or a failed identification: the message is the `hysid` program's one line."
);

/// A failure on its way to Python: the message, on one line.
#[derive(Debug)]
pub struct Failure(String);

impl Failure {
    /// A failure worded by this module.
    pub fn new(message: impl Into<String>) -> Self {
        Self(message.into())
    }
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> Self {
        let line = f.0.split_whitespace().collect::<Vec<_>>().join(" ");
        HysidError::new_err(line)
    }
}

macro_rules! displayed {
    ($($t:ty),*) => {$(
        impl From<$t> for Failure {
            fn from(e: $t) -> Self {
                Self(e.to_string())
            }
        }
    )*};
}

displayed!(DataError, ModelError, PriorError, SimError);

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
                Self(format!("{name}={value}: {what}"))
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
                Self(format!("{}: {problem}", given.join(" ")))
            }
            Error::Identify(e) => e.into(),
            Error::Select(e) => e.into(),
        }
    }
}

impl From<OptionError> for Failure {
    fn from(e: OptionError) -> Self {
        Self(e.render("option"))
    }
}

impl From<IdentifyError> for Failure {
    fn from(e: IdentifyError) -> Self {
        match e {
            IdentifyError::Options(o) => o.into(),
            IdentifyError::NeedsModeCount {
                method,
                bounded: true,
            } => Self(format!(
                "method '{method}' needs the number of modes: modes=S, max_modes=S (the count \
                 chosen by hold-out simulation FIT) or auto=True (chosen on selection rows), or \
                 modes / max_modes in the priors"
            )),
            IdentifyError::NeedsModeCount {
                method,
                bounded: false,
            } => Self(format!(
                "method '{method}' needs the number of modes: modes=S (or auto=True to choose \
                 it on selection rows), or modes in the priors"
            )),
            other => Self(other.to_string()),
        }
    }
}

impl From<SelectError> for Failure {
    fn from(e: SelectError) -> Self {
        match e {
            SelectError::Identify(e) => e.into(),
            SelectError::Folds { folds, reason } => Self(format!("folds={folds}: {reason}")),
            SelectError::Rows { rows, reason } => Self(format!("select_rows={rows}: {reason}")),
            SelectError::Candidate(c) => Self(format!("grid {}={}: not a count", c.key, c.value)),
            e @ SelectError::NoCandidate { .. } => Self(format!("auto: {e}")),
        }
    }
}
