//! One error type for the program: a one-line message and an exit code
//! (2 for bad input or usage, 1 for a failure of the method itself).

use hysid_core::backend::IdentifyError;
use hysid_core::model::ModelError;
use hysid_core::options::OptionError;
use hysid_core::priors::PriorError;
use hysid_estimation::pwarx::standardize::StandardizeError;
use hysid_model::data::DataError;
use hysid_model::simulate::SimError;

/// What a command returns.
pub type Result<T> = std::result::Result<T, CliError>;

/// A failed command.
#[derive(Debug)]
pub struct CliError {
    message: String,
    bad_input: bool,
}

impl CliError {
    /// Bad input or usage (exit code 2).
    pub fn input(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            bad_input: true,
        }
    }

    /// A failure of the computation itself (exit code 1).
    pub fn failure(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            bad_input: false,
        }
    }

    /// The message on one line.
    pub fn one_line(&self) -> String {
        self.message
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// Process exit code.
    pub fn exit_code(&self) -> i32 {
        if self.bad_input { 2 } else { 1 }
    }
}

impl From<DataError> for CliError {
    /// Rows are named by the flag that gives them (`--rows`).
    fn from(e: DataError) -> Self {
        Self::input(e.rows_named("--rows").unwrap_or_else(|| e.to_string()))
    }
}

impl From<ModelError> for CliError {
    /// A model file that cannot be read or written, or that is malformed,
    /// is the user's input.
    fn from(e: ModelError) -> Self {
        Self::input(e.to_string())
    }
}

impl From<PriorError> for CliError {
    fn from(e: PriorError) -> Self {
        Self::input(e.to_string())
    }
}

impl From<SimError> for CliError {
    fn from(e: SimError) -> Self {
        Self::input(e.to_string())
    }
}

impl CliError {
    /// A simulation set-up error of the model in `model_file` on a record:
    /// a problem of the model itself or of the record for this model (its
    /// `internal_step`, a reset that leaves its target's invariant, a
    /// record shorter than its initial-state rule reads, inputs it does
    /// not have), naming the file.
    pub fn simulation(model_file: &std::path::Path, e: SimError) -> Self {
        Self::input(format!("{}: {e}", model_file.display()))
    }
}

/// The clause of a mode-count message for a method that needs the count
/// itself, where a `max_modes` bound does not give it.
pub(crate) const NO_COUNT_FROM_A_BOUND: &str = " (a max_modes bound alone does not give it)";

impl From<IdentifyError> for CliError {
    fn from(e: IdentifyError) -> Self {
        let bad = e.is_bad_input();
        let message = match &e {
            IdentifyError::Options(o) => o.render("--set"),
            e if let Some(s) = e.downcast_ref::<StandardizeError>() => s.render("--standardize"),
            IdentifyError::NeedsModeCount {
                method,
                bounded: true,
            } => format!(
                "method '{method}' needs the number of modes: --modes S, --max-modes S (the \
                 count chosen by hold-out simulation FIT) or --auto (chosen on selection rows), \
                 or modes = S / max_modes = S in the prior file"
            ),
            IdentifyError::NeedsModeCount {
                method,
                bounded: false,
            } => format!(
                "method '{method}' needs the number of modes: --modes S (or --auto to choose \
                 it on selection rows), or modes = S in the prior file{NO_COUNT_FROM_A_BOUND}"
            ),
            other => other.to_string(),
        };
        Self {
            message,
            bad_input: bad,
        }
    }
}

impl From<hysid::select::SelectError> for CliError {
    fn from(e: hysid::select::SelectError) -> Self {
        use hysid::select::SelectError;
        match e {
            SelectError::Identify(e) => e.into(),
            SelectError::EveryCandidateRefused(e) => match *e {
                IdentifyError::NeedsModeCount { method, .. } => Self::input(format!(
                    "--grid: every candidate of '{method}' needs the number of modes: add \
                     modes=S1,S2,... to the grid, or give --modes S"
                )),
                e => e.into(),
            },
            SelectError::Folds { folds, reason } => {
                Self::input(format!("--folds {folds}: {reason}"))
            }
            SelectError::Rows { rows, reason } => {
                Self::input(format!("--select-rows {rows}: {reason}"))
            }
            SelectError::Records { records, reason } => {
                Self::input(format!("--select-records {records}: {reason}"))
            }
            SelectError::Candidate(c) => {
                Self::input(format!("--grid {}={}: {}", c.key, c.value, c.reason))
            }
            SelectError::Option { error, from_grid } => {
                Self::input(error.render(if from_grid { "--grid" } else { "--set" }))
            }
            SelectError::GridFixed { key, given } => {
                use hysid::select::FixedBy;
                let by = match given {
                    FixedBy::Option(v) => format!("--set {key}={v}"),
                    FixedBy::Modes(s) => format!("--modes {s}"),
                    FixedBy::Order(n) => format!("--{key} {n}"),
                    other => other.to_string(),
                };
                Self::input(format!(
                    "--grid {key}: also fixed by {by}; give it in one place"
                ))
            }
            e @ SelectError::NoCandidate { .. } => Self::failure(format!("--auto: {e}")),
        }
    }
}

impl From<hysid::identify::Error> for CliError {
    fn from(e: hysid::identify::Error) -> Self {
        use hysid::identify::{Error, Field};
        match e {
            Error::Field { field, value, what } => {
                let flag = match field {
                    Field::Modes => "--modes",
                    Field::MaxModes => "--max-modes",
                    Field::TimeBudget => "--time-budget",
                    Field::RefitStarts => "--refit-starts",
                };
                Self::input(format!("{flag} {value}: {what}"))
            }
            Error::Modes {
                modes,
                max_modes,
                problem,
            } => {
                let given: Vec<String> = [("--modes", modes), ("--max-modes", max_modes)]
                    .iter()
                    .filter_map(|(flag, v)| v.map(|s| format!("{flag} {s}")))
                    .collect();
                Self::input(format!("{}: {problem}", given.join(" ")))
            }
            Error::Identify(e) => e.into(),
            Error::Select(e) => e.into(),
            e @ Error::ShortRecord(_) => Self::input(format!("{e} (--warmup)")),
        }
    }
}

impl From<OptionError> for CliError {
    fn from(e: OptionError) -> Self {
        Self::input(e.render("--set"))
    }
}
