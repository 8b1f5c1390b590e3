//! The experiment file: data, protocol, shared priors, runs and sweeps
//! (`docs/compare.md`).

use crate::select::SelectError;
use hysid_core::options::{first_repeated, non_empty};
use hysid_core::priors::{InconsistentPrior, Priors};
use hysid_core::search::{Axis, SearchSpace};
use hysid_model::data::{DataSelection, RowRange, SignalNameError};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::path::{Path, PathBuf};

/// Most jobs an experiment may expand into ([`Experiment::jobs`]): each
/// is an identification.
pub const MAX_JOBS: usize = 10_000;

/// Where the data come from and how they are split.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataSpec {
    /// Data file, relative to the experiment file.
    pub file: PathBuf,
    /// Input names (default `["u"]`).
    #[serde(default = "default_inputs")]
    pub input: Vec<String>,
    /// Whether the file names `input` (else the default `u` is read).
    #[serde(skip)]
    pub input_named: bool,
    /// Output name (default `"y"`).
    #[serde(default = "default_output")]
    pub output: String,
    /// Keep every K-th sample (default 1).
    #[serde(default = "one")]
    pub decimate: usize,
    /// Sampling time when the file has no `t` signal.
    #[serde(default)]
    pub ts: Option<f64>,
    /// The column/variable holding the time in seconds (default `t`).
    #[serde(default = "default_time")]
    pub time: String,
    /// Rows used for identification (after decimation). Only with
    /// `[[data.records]]` may it be left out (the file then only scored).
    #[serde(default)]
    pub identification: Option<RowRange>,
    /// Rows used for validation (after decimation). Only with
    /// `[[data.records]]` may it be left out (the file then only fitted on).
    #[serde(default)]
    pub validation: Option<RowRange>,
    /// Validation samples not scored (default 10).
    #[serde(default = "ten")]
    pub warmup: usize,
    /// Selection rows of the runs with `auto = true` (after decimation,
    /// inside the identification rows, at their start or end); default the
    /// last 20 % of the identification rows.
    #[serde(default)]
    pub selection: Option<RowRange>,
    /// Instead of one selection split: `K` contiguous blocks of the
    /// identification rows on a rolling origin (`hysid identify --folds K`).
    #[serde(default)]
    pub folds: Option<usize>,
    /// With identification rows from several records: the last `K` of
    /// them are the selection rows of the runs with `auto = true`
    /// (`hysid identify --select-records K`).
    #[serde(default)]
    pub select_records: Option<usize>,
    /// More records of the system (`[[data.records]]`), after the rows of
    /// `file`: their identification rows join the identification record,
    /// their validation rows the scored one, each record simulated from
    /// its own initial state.
    #[serde(default)]
    pub records: Vec<RecordSpec>,
    /// Starts of the refit of an auto run's choice on all the
    /// identification rows, for a back-end the seed changes
    /// (`hysid identify --refit-starts K`; default 3).
    #[serde(default = "default_refit_starts")]
    pub refit_starts: usize,
    /// Axis label of the output in figures, with its unit (default `output <name>`).
    #[serde(default)]
    pub output_label: Option<String>,
    /// Axis label of the inputs in figures, with the unit (default `input <names>`).
    #[serde(default)]
    pub input_label: Option<String>,
    /// A CSV column naming the true mode of every sample (simulated
    /// records, e.g. the `mode` column `hysid simulate` writes): each run is
    /// then scored on how its simulated modes follow it (`truth.rs`).
    #[serde(default)]
    pub truth: Option<String>,
}

/// One more record of the system in an experiment file
/// (`[[data.records]]`): rows of a file for identification, for
/// validation, or both, read with the `[data]` table's decimation, time and
/// sampling time, and its signal names unless given.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordSpec {
    /// Data file, relative to the experiment file.
    pub file: PathBuf,
    /// Input names (default: the `[data]` table's).
    #[serde(default)]
    pub input: Option<Vec<String>>,
    /// Output name (default: the `[data]` table's).
    #[serde(default)]
    pub output: Option<String>,
    /// Rows of this record used for identification (after decimation).
    #[serde(default)]
    pub identification: Option<RowRange>,
    /// Rows of this record scored (after decimation).
    #[serde(default)]
    pub validation: Option<RowRange>,
}

fn default_inputs() -> Vec<String> {
    vec!["u".into()]
}
fn default_time() -> String {
    hysid_model::data::DEFAULT_TIME.into()
}

fn default_output() -> String {
    "y".into()
}
fn one() -> usize {
    1
}
fn ten() -> usize {
    10
}
fn default_refit_starts() -> usize {
    crate::select::DEFAULT_REFIT_STARTS
}
fn yes() -> bool {
    true
}

impl DataSpec {
    /// `e`, a selection that does not split the identification rows,
    /// worded with the key of this table that set it.
    pub fn selection_error(&self, e: SelectError) -> String {
        match e {
            SelectError::Rows { rows, reason } if self.selection.is_some() => {
                format!("[data] selection = {rows}: {reason}")
            }
            SelectError::Rows { rows, reason } => format!(
                "[data] identification: the default selection rows {rows} (an auto run's): {reason}"
            ),
            SelectError::Folds { folds, reason } => format!("[data] folds = {folds}: {reason}"),
            SelectError::Records { records, reason } => {
                format!("[data] select_records = {records}: {reason}")
            }
            other => other.to_string(),
        }
    }

    /// Row of its file where `part`'s first record starts: `[data]`'s
    /// rows, else those of the first `[[data.records]]` entry that has
    /// them.
    pub fn first_row(&self, part: DataPart) -> usize {
        (part.of(self.identification, self.validation))
            .or_else(|| (self.records.iter()).find_map(|r| part.of(r.identification, r.validation)))
            .and_then(|rows| rows.start)
            .unwrap_or(0)
    }

    /// Selection of the identification or validation part.
    pub fn selection(&self, rows: RowRange) -> DataSelection {
        DataSelection {
            inputs: self.input.clone(),
            output: self.output.clone(),
            decimate: self.decimate,
            rows,
            ts: self.ts,
            time: self.time.clone(),
        }
    }

    /// `u2 -> z2`: the signals of `record` where they are not `[data]`'s
    /// (a record of other signals of the same file, often).
    pub fn other_signals(&self, record: &RecordSpec) -> Option<String> {
        let own = self.record_selection(record, RowRange::default());
        (own.inputs != self.input || own.output != self.output)
            .then(|| format!("{} -> {}", own.inputs.join(", "), own.output))
    }

    /// `u1 -> z1`: `[data]`'s signals, where a record reads others (so
    /// that every entry says which it reads).
    pub fn own_signals(&self) -> Option<String> {
        (self.records.iter())
            .any(|r| self.other_signals(r).is_some())
            .then(|| format!("{} -> {}", self.input.join(", "), self.output))
    }

    /// Selection of rows `rows` of the extra record `record`.
    pub fn record_selection(&self, record: &RecordSpec, rows: RowRange) -> DataSelection {
        DataSelection {
            inputs: record.input.clone().unwrap_or_else(|| self.input.clone()),
            output: record.output.clone().unwrap_or_else(|| self.output.clone()),
            ..self.selection(rows)
        }
    }
}

/// One identification run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Label in the report (unique).
    pub name: String,
    /// Back-end name.
    pub method: String,
    /// Output lags (default: the experiment's).
    #[serde(default)]
    pub na: Option<usize>,
    /// Input lags (default: the experiment's).
    #[serde(default)]
    pub nb: Option<usize>,
    /// Number of modes (sets the prior `modes`).
    #[serde(default)]
    pub modes: Option<usize>,
    /// Whether the experiment's shared priors apply (default true).
    #[serde(default = "yes")]
    pub use_priors: bool,
    /// Extra priors of this run, merged over the shared ones.
    #[serde(default)]
    pub priors: Option<Priors>,
    /// Back-end options (`--set`).
    #[serde(default)]
    pub set: BTreeMap<String, toml::Value>,
    /// Seed (default: the experiment's).
    #[serde(default)]
    pub seed: Option<u64>,
    /// Run once per seed (instead of `seed`); the report gives the median
    /// and the range of the scores over them.
    #[serde(default, deserialize_with = "listed")]
    pub seeds: Vec<u64>,
    /// Choose the options on the selection rows (`hysid identify --auto`,
    /// docs/selection.md); `set` and `modes` fix what is not searched.
    #[serde(default)]
    pub auto: bool,
    /// Where the fixed options of a run without `auto` come from; the
    /// report labels the run by it (an `auto` run and the points of a
    /// sweep are labelled by the program).
    #[serde(default)]
    pub provenance: Option<Provenance>,
}

impl RunSpec {
    /// The model file its `set` names ([`MODEL_FILE_OPTION`]), if any.
    pub fn model_file(&self) -> Option<&Path> {
        self.set.get(MODEL_FILE_OPTION)?.as_str().map(Path::new)
    }

    /// Its `set` table as options, values as `--set` writes them.
    pub fn settings(&self) -> hysid_core::options::Settings {
        hysid_core::options::Settings::from_pairs(
            (self.set.iter())
                .map(|(k, v)| (k.clone(), value_text(v)))
                .collect(),
        )
    }
}

/// Where a run's fixed options come from, as its experiment file declares
/// them (`provenance = "paper"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Provenance {
    /// A setting of a published study (the founding paper's section 4).
    Paper,
    /// Chosen on the rows the run is scored on: what the method reaches
    /// with hindsight, not what a user gets.
    Oracle,
    /// The user's own choice or knowledge, made without the scored rows.
    User,
}

/// A sweep: one run repeated over values of one parameter (`vary`,
/// `values`) or over the cartesian product of several (`grid`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// The run being varied (its `name` labels the sweep).
    #[serde(flatten)]
    pub run: RunSpec,
    /// What varies: a back-end option key, or `modes`, `na`, `nb`.
    #[serde(default)]
    pub vary: Option<String>,
    /// The values of `vary`.
    #[serde(default)]
    pub values: Vec<toml::Value>,
    /// Several keys at once: `{ c = [20, 40], modes = [2, 3] }` (all
    /// combinations, keys in alphabetical order, the last varying fastest).
    #[serde(default)]
    pub grid: BTreeMap<String, Vec<toml::Value>>,
}

impl SweepSpec {
    /// The values the sweep gives [`MODEL_FILE_OPTION`] (`vary = "model"`,
    /// a `grid` key `model`): the model files it fits, one a point.
    fn swept_model_files(&self) -> impl Iterator<Item = &toml::Value> {
        let varied = (self.vary.as_deref() == Some(MODEL_FILE_OPTION)).then_some(&self.values);
        (varied.into_iter())
            .chain(self.grid.get(MODEL_FILE_OPTION))
            .flatten()
    }

    /// The model files the sweep's points fit: its run's `set` one, and
    /// those it sweeps.
    pub fn model_files(&self) -> impl Iterator<Item = &Path> {
        (self.run.model_file().into_iter()).chain(
            self.swept_model_files()
                .filter_map(|file| file.as_str().map(Path::new)),
        )
    }

    /// How a point shows `value` of `key`: a swept model file by its file
    /// name where the sweep's files have distinct names (they are resolved
    /// against the experiment's folder), anything else as it is.
    pub fn shown<'v>(&self, key: &str, value: &'v str) -> &'v str {
        fn file_name(path: &str) -> Option<&str> {
            Path::new(path).file_name()?.to_str()
        }
        if key != MODEL_FILE_OPTION {
            return value;
        }
        let names: Vec<Option<&str>> = (self.swept_model_files())
            .map(|v| v.as_str().and_then(file_name))
            .collect();
        let distinct =
            (names.iter().enumerate()).all(|(i, n)| n.is_some() && !names[..i].contains(n));
        match file_name(value) {
            Some(name) if distinct => name,
            _ => value,
        }
    }

    /// [`Self::swept_model_files`], to resolve.
    fn swept_model_files_mut(&mut self) -> impl Iterator<Item = &mut toml::Value> {
        let varied = (self.vary.as_deref() == Some(MODEL_FILE_OPTION)).then_some(&mut self.values);
        (varied.into_iter())
            .chain(self.grid.get_mut(MODEL_FILE_OPTION))
            .flatten()
    }

    /// The grid: `vary` first, then the `grid` keys in alphabetical order
    /// (the last varying fastest), values as `--set` writes them.
    pub fn space(&self) -> SearchSpace {
        let mut space = SearchSpace::default();
        if let Some(v) = &self.vary {
            space.axes.push(Axis {
                key: v.clone(),
                values: self.values.iter().map(value_text).collect(),
            });
        }
        space.axes.extend(self.grid.iter().map(|(k, v)| Axis {
            key: k.clone(),
            values: v.iter().map(value_text).collect(),
        }));
        space
    }
}

/// A TOML value as `--set` writes it: text without quotes, other scalars
/// as TOML writes them.
pub fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// `folder/file` with each `name/..` pair dropped (`models/a/../head.toml`
/// is `models/head.toml`), without reading the file system.
fn lexically_joined(folder: &Path, file: &str) -> std::path::PathBuf {
    use std::path::Component;
    let mut out = std::path::PathBuf::new();
    for c in folder.join(file).components() {
        match c {
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// The back-end option that names a model file (`physical`'s `model`): in
/// an experiment file it is relative to the file's folder, as `data.file` is.
pub const MODEL_FILE_OPTION: &str = "model";

/// An experiment file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    /// Title of the report.
    pub title: String,
    /// Free text under the title.
    #[serde(default)]
    pub description: String,
    /// Data and split.
    pub data: DataSpec,
    /// Default output lags (default 2).
    #[serde(default = "two")]
    pub na: usize,
    /// Default input lags (default 2).
    #[serde(default = "two")]
    pub nb: usize,
    /// Default seed (default 0).
    #[serde(default)]
    pub seed: u64,
    /// Priors shared by every run.
    #[serde(default)]
    pub priors: Priors,
    /// Runs.
    #[serde(default, rename = "run")]
    pub runs: Vec<RunSpec>,
    /// Sweeps.
    #[serde(default, rename = "sweep")]
    pub sweeps: Vec<SweepSpec>,
    /// What the scored rows (`[data] validation`) are to the reader:
    /// test rows of an experiment, or the selection rows of `hysid sweep`.
    #[serde(skip)]
    pub scored_rows: ScoredRows,
}

/// The role of the rows every run is scored on, as the report names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ScoredRows {
    /// Validation (test) rows, scored once.
    #[default]
    Validation,
    /// Selection rows: the sweep's best point is chosen on them.
    Selection,
}

impl ScoredRows {
    /// The word for the rows, lower case.
    pub fn word(self) -> &'static str {
        match self {
            ScoredRows::Validation => "validation",
            ScoredRows::Selection => "selection",
        }
    }
}

/// The identification or the scored rows of an experiment's records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataPart {
    /// The rows identified on (`identification`).
    Identification,
    /// The rows scored (`validation`).
    Scored,
}

impl DataPart {
    /// Of an entry's `identification` and `validation` rows, this part's.
    pub fn of(
        self,
        identification: Option<RowRange>,
        validation: Option<RowRange>,
    ) -> Option<RowRange> {
        match self {
            DataPart::Identification => identification,
            DataPart::Scored => validation,
        }
    }

    /// The key that gives these rows in an experiment file.
    pub fn key(self) -> &'static str {
        match self {
            DataPart::Identification => "identification",
            DataPart::Scored => "validation",
        }
    }
}

/// The entry of an experiment file that gives a record: the `[data]`
/// table's own file, or a `[[data.records]]` entry (counted from 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataEntry {
    /// `[data] file`.
    Main,
    /// `[[data.records]]` entry `k`, counted from 1.
    Record(usize),
}

impl fmt::Display for DataEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DataEntry::Main => write!(f, "[data]"),
            DataEntry::Record(k) => write!(f, "[[data.records]] #{k}"),
        }
    }
}

fn two() -> usize {
    2
}

/// Errors in an experiment file.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// Unreadable file.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// A record of the data (`[data] file` or a `[[data.records]]` file)
    /// could not be read as selected, or joined to the first (the cause
    /// names the file, as resolved, where it concerns one).
    #[error("{entry} file: {source}")]
    Data {
        /// The entry that gives the record.
        entry: DataEntry,
        /// Cause.
        source: hysid_model::data::DataError,
    },
    /// Rows of a record that it does not hold, worded with their entry and
    /// key (`identification` or `validation`).
    #[error("{entry}: {}", source.rows_named(part.key()).unwrap_or_default())]
    Rows {
        /// The entry that gives the rows.
        entry: DataEntry,
        /// Which rows.
        part: DataPart,
        /// Cause ([`hysid_model::data::DataError::Rows`]).
        source: hysid_model::data::DataError,
    },
    /// The true modes could not be read (the message names the file again).
    #[error("{path}: {source}")]
    Truth {
        /// Data file.
        path: String,
        /// Cause.
        source: Box<crate::compare::truth::TruthError>,
    },
    /// Inconsistent entries.
    #[error("{path}: {problem}")]
    Inconsistent {
        /// File.
        path: String,
        /// What is wrong.
        problem: InconsistentExperiment,
    },
    /// The `[data]` table's selection rows, folds or held-out records do
    /// not split the identification rows (the message names the key).
    #[error("{0}")]
    Selection(String),
    /// A scored record no longer than the warm-up: nothing of it is scored.
    #[error(
        "[data] warmup = {warmup}: a record of the {word} rows holds {samples} samples, none scored after the warm-up"
    )]
    Warmup {
        /// The warm-up.
        warmup: usize,
        /// The shortest scored record's samples.
        samples: usize,
        /// What the scored rows are called ([`ScoredRows::word`]).
        word: &'static str,
    },
    /// Malformed, or a sweep value that does not fit its option.
    #[error("{path}: {message}")]
    Invalid {
        /// File.
        path: String,
        /// What is wrong, naming the entry.
        message: String,
    },
}

/// An inconsistency of an experiment ([`Experiment::check`]); `what` is
/// `run` or `sweep`, `name` the entry's name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InconsistentExperiment {
    /// Neither runs nor sweeps.
    #[error("no [[run]] and no [[sweep]]")]
    NothingToRun,
    /// Signal names of `[data]` or of a record that cannot be read as a
    /// record: an input named twice, or also the output.
    #[error("{entry}: {problem}")]
    Signals {
        /// The entry that names them.
        entry: DataEntry,
        /// What is wrong.
        problem: SignalNameError,
    },
    /// More jobs than [`MAX_JOBS`]: runs, their seeds, and every point of
    /// every sweep.
    #[error("the runs, their seeds and the points of the sweeps make more than {MAX_JOBS} jobs")]
    TooManyJobs,
    /// The shared priors are inconsistent.
    #[error("[priors]: {0}")]
    Priors(InconsistentPrior),
    /// Two entries of one name.
    #[error("[[{what}]] name '{name}' appears twice")]
    DuplicateName {
        /// `run` or `sweep`.
        what: &'static str,
        /// The name.
        name: String,
    },
    /// An entry whose name gives no file name.
    #[error("[[{what}]] name '{name}': needs a letter or a digit (it names the entry's files)")]
    NoFileName {
        /// `run` or `sweep`.
        what: &'static str,
        /// The name.
        name: String,
    },
    /// Two entries whose names give one file name.
    #[error(
        "[[{what}]] '{name}' and '{other}' would write their results to one file name, '{file}': rename one"
    )]
    SameFileName {
        /// `run` or `sweep`.
        what: &'static str,
        /// The later entry.
        name: String,
        /// The earlier one.
        other: String,
        /// The file name both give.
        file: String,
    },
    /// A seed or a sweep value listed twice.
    #[error("[[{what}]] '{name}': {key} lists {value} twice")]
    Repeated {
        /// `run` or `sweep`.
        what: &'static str,
        /// Entry name.
        name: String,
        /// `seeds`, or the swept key.
        key: String,
        /// The value.
        value: String,
    },
    /// An entry naming an unknown method.
    #[error("[[{what}]] '{name}': unknown method '{method}' (methods: {known})")]
    UnknownMethod {
        /// `run` or `sweep`.
        what: &'static str,
        /// Entry name.
        name: String,
        /// The unknown method.
        method: String,
        /// Registered methods.
        known: String,
    },
    /// An entry's own priors are inconsistent.
    #[error("[[{what}]] '{name}' priors: {problem}")]
    RunPriors {
        /// `run` or `sweep`.
        what: &'static str,
        /// Entry name.
        name: String,
        /// The inconsistency.
        problem: InconsistentPrior,
    },
    /// An entry with both `seed` and `seeds`.
    #[error("[[{what}]] '{name}': give seed or seeds, not both")]
    SeedAndSeeds {
        /// `run` or `sweep`.
        what: &'static str,
        /// Entry name.
        name: String,
    },
    /// A sweep with `auto` or `seeds`.
    #[error("[[sweep]] '{0}': auto and seeds belong to a [[run]] (a sweep is its own grid)")]
    SweepOfRuns(String),
    /// A `provenance` the program gives itself: an `auto` run's options
    /// are chosen on the selection rows, a sweep's points are labelled by
    /// where its best point was chosen.
    #[error(
        "[[{what}]] '{name}': provenance is for a [[run]] without auto (the program labels {what}s of this kind)"
    )]
    ProvenanceGiven {
        /// `run` or `sweep`.
        what: &'static str,
        /// Entry name.
        name: String,
    },
    /// A sweep with nothing to vary.
    #[error("[[sweep]] '{0}': give vary and values, or grid")]
    NoAxis(String),
    /// A key both `vary` and in `grid`.
    #[error("[[sweep]] '{name}': {key} is both vary and a grid key")]
    SweptTwice {
        /// Entry name.
        name: String,
        /// The key.
        key: String,
    },
    /// An entry's mode count given as its `modes` and in its `priors`.
    #[error(
        "[[{what}]] '{name}': modes given twice (modes = {given} and priors = {{ modes = {prior} }}): give it in one place"
    )]
    ModesTwice {
        /// `run` or `sweep`.
        what: &'static str,
        /// Entry name.
        name: String,
        /// Its `modes`.
        given: usize,
        /// Its priors' `modes`.
        prior: usize,
    },
    /// A swept key also given a fixed value by the sweep's run.
    #[error("[[sweep]] '{name}': {key} is swept and also fixed ({given}): give it in one place")]
    SweptAndFixed {
        /// Entry name.
        name: String,
        /// The key.
        key: String,
        /// Where it is fixed.
        given: String,
    },
    /// A sweep with values but no `vary`.
    #[error("[[sweep]] '{0}': values without vary")]
    ValuesWithoutVary(String),
    /// A sweep axis without values.
    #[error("[[sweep]] '{name}': no values for '{key}'")]
    NoValues {
        /// Sweep name.
        name: String,
        /// The axis.
        key: String,
    },
    /// `decimate = 0`.
    #[error("[data] decimate must be at least 1")]
    Decimate,
    /// `refit_starts` outside `1..=MAX_COUNT`.
    #[error(
        "[data] refit_starts must be in 1..={}",
        hysid_core::options::MAX_COUNT
    )]
    RefitStarts,
    /// Both selection rows and folds.
    #[error("[data] selection and folds are two ways of choosing: give one")]
    SelectionAndFolds,
    /// Held-out records beside selection rows or folds.
    #[error(
        "[data] select_records is one more way of choosing: give one of selection, folds and select_records"
    )]
    SelectRecordsAndRows,
    /// Selection rows or true modes with more records.
    #[error("[data] {0} counts rows of the file: not with [[data.records]]")]
    RowsWithRecords(&'static str),
    /// A record with neither identification nor validation rows.
    #[error("[[data.records]] #{0}: give identification or validation rows")]
    EmptyRecord(usize),
    /// `[data]` without identification or validation rows, and no
    /// `[[data.records]]` to give them.
    #[error("[data]: give {0} rows (or list [[data.records]] that have them)")]
    MissingRows(&'static str),
    /// `[data]` with neither identification nor validation rows.
    #[error(
        "[data]: give identification or validation rows (its file is read for nothing otherwise)"
    )]
    EmptyData,
    /// Neither `[data]` nor any record gives rows of this part.
    #[error("no {0} rows: give them in [data] or in a [[data.records]] entry")]
    NoRows(&'static str),
    /// A record with another number of inputs.
    #[error("[[data.records]] #{record}: {found} input(s), [data] has {expected}")]
    RecordInputs {
        /// The record, counted from 1.
        record: usize,
        /// Its inputs.
        found: usize,
        /// The `[data]` table's.
        expected: usize,
    },
}

impl Experiment {
    /// Parses experiment text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ExperimentError> {
        Self::parse(text, origin)?.checked(origin)
    }

    /// The experiment of `text`, read as it is written.
    fn parse(text: &str, origin: &str) -> Result<Self, ExperimentError> {
        let mut e: Self = toml::from_str(text).map_err(|e| ExperimentError::Invalid {
            path: origin.into(),
            message: e.to_string().trim().replace('\n', " "),
        })?;
        // The file read, so it is a table.
        let table = text.parse::<toml::Table>().unwrap_or_default();
        e.data.input_named = table.get("data").and_then(|d| d.get("input")).is_some();
        Ok(e)
    }

    /// The experiment, checked ([`Experiment::check`]) and its jobs
    /// expanded as they will run (each checked as its back-end checks it,
    /// with the model files it names).
    fn checked(self, origin: &str) -> Result<Self, ExperimentError> {
        self.check()
            .map_err(|problem| ExperimentError::Inconsistent {
                path: origin.into(),
                problem,
            })?;
        // Sweep values that are not counts are found while expanding the
        // jobs; report them against this file, not at run time.
        self.jobs().map_err(|err| match err {
            ExperimentError::Invalid { message, .. } => ExperimentError::Invalid {
                path: origin.into(),
                message,
            },
            other => other,
        })?;
        Ok(self)
    }

    /// Reads an experiment file; the data path and the runs' model files
    /// ([`MODEL_FILE_OPTION`]) are resolved against its folder.
    pub fn load(path: &Path) -> Result<Self, ExperimentError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ExperimentError::Io {
            path: origin.clone(),
            source,
        })?;
        let mut e = Self::parse(&text, &origin)?;
        let folder = path.parent().unwrap_or(Path::new("."));
        if e.data.file.is_relative() {
            e.data.file = folder.join(&e.data.file);
        }
        for r in &mut e.data.records {
            if r.file.is_relative() {
                r.file = folder.join(&r.file);
            }
        }
        // A model file as given, resolved; refused before any run starts,
        // as every other entry is, where there is none.
        let resolve = |name: &str, key: &str, file: &mut toml::Value| {
            let toml::Value::String(file) = file else {
                return Ok(());
            };
            if Path::new(file.as_str()).is_relative() {
                *file = lexically_joined(folder, file).display().to_string();
            }
            if Path::new(file.as_str()).is_file() {
                return Ok(());
            }
            Err(ExperimentError::Invalid {
                path: origin.clone(),
                message: format!("'{name}': {key} = {file}: no such file"),
            })
        };
        let set_key = format!("set.{MODEL_FILE_OPTION}");
        for run in (e.runs.iter_mut()).chain(e.sweeps.iter_mut().map(|s| &mut s.run)) {
            if let Some(file) = run.set.get_mut(MODEL_FILE_OPTION) {
                resolve(&run.name, &set_key, file)?;
            }
        }
        let swept_key = format!("swept {MODEL_FILE_OPTION}");
        for sweep in &mut e.sweeps {
            let name = sweep.run.name.clone();
            for file in sweep.swept_model_files_mut() {
                resolve(&name, &swept_key, file)?;
            }
        }
        e.checked(&origin)
    }

    /// The files the experiment reads: its data files and its runs' model
    /// files.
    pub fn input_files(&self) -> Vec<&Path> {
        let records = self.data.records.iter().map(|r| r.file.as_path());
        let runs = self.runs.iter().filter_map(RunSpec::model_file);
        let sweeps = self.sweeps.iter().flat_map(SweepSpec::model_files);
        std::iter::once(self.data.file.as_path())
            .chain(records)
            .chain(runs)
            .chain(sweeps)
            .collect()
    }

    /// The first `[[run]]` or `[[sweep]]` whose model file declares input
    /// names ([`hysid_core::backend::Backend::declared_signals`]), with
    /// them: what a record that lacks the `[data]` inputs may name
    /// otherwise.
    pub fn declared_inputs(&self) -> Option<(&RunSpec, Vec<String>)> {
        let registry = crate::registry();
        self.entries().find_map(|(run, _)| {
            let inputs = registry
                .get(&run.method)?
                .declared_signals(&run.settings())
                .ok()?
                .inputs?;
            Some((run, inputs)).filter(|(_, i)| !i.is_empty())
        })
    }

    /// Where `[data]` names no inputs, so that its default `u` is read,
    /// while its file also has the inputs a run's model file declares
    /// ([`Experiment::declared_inputs`]): the warning that says which it
    /// reads. A record with an unrelated `u` would otherwise fit and score
    /// the model on it without a word (as `hysid identify` says).
    pub fn unread_declared_inputs(&self) -> Option<ExperimentWarning> {
        if self.data.input_named {
            return None;
        }
        let (run, declared) = self.declared_inputs()?;
        if declared == self.data.input {
            return None;
        }
        let selection = DataSelection {
            inputs: declared.clone(),
            ..self.data.selection(RowRange::default())
        };
        hysid_io::load(&self.data.file, &selection).ok()?;
        Some(ExperimentWarning::DeclaredInputsUnread {
            run: run.name.clone(),
            read: self.data.input.clone(),
            declared,
        })
    }

    /// Every `[[run]]` and `[[sweep]]`'s run, with `run` or `sweep`.
    fn entries(&self) -> impl Iterator<Item = (&RunSpec, &'static str)> {
        (self.runs.iter().map(|r| (r, "run"))).chain(self.sweeps.iter().map(|s| (&s.run, "sweep")))
    }

    /// Every entry's name once, with a letter or a digit, and every
    /// sweep's figure a file name of its own (case aside); the runs' files
    /// are checked with their seeds and sweep points ([`Experiment::jobs`]).
    fn check_names(&self) -> Result<(), InconsistentExperiment> {
        use InconsistentExperiment as E;
        let mut names = HashSet::new();
        let mut figures: HashMap<String, &str> = HashMap::new();
        for (r, what) in self.entries() {
            let name = || r.name.clone();
            if !names.insert(r.name.as_str()) {
                return Err(E::DuplicateName { what, name: name() });
            }
            if !r.name.chars().any(|c| c.is_ascii_alphanumeric()) {
                return Err(E::NoFileName { what, name: name() });
            }
            let file = file_name(&r.name);
            if what == "sweep"
                && let Some(other) = figures.insert(file.clone(), &r.name)
            {
                return Err(E::SameFileName {
                    what,
                    name: name(),
                    other: other.to_string(),
                    file,
                });
            }
        }
        Ok(())
    }

    /// Consistency checks (also for experiments built in code).
    pub fn check(&self) -> Result<(), InconsistentExperiment> {
        use InconsistentExperiment as E;
        if self.runs.is_empty() && self.sweeps.is_empty() {
            return Err(E::NothingToRun);
        }
        self.priors.check().map_err(E::Priors)?;
        self.check_names()?;
        let registry = crate::registry();
        for (r, what) in self.entries() {
            if let Some(seed) = first_repeated(&r.seeds) {
                return Err(E::Repeated {
                    what,
                    name: r.name.clone(),
                    key: "seeds".into(),
                    value: seed.to_string(),
                });
            }
            if registry.get(&r.method).is_none() {
                return Err(E::UnknownMethod {
                    what,
                    name: r.name.clone(),
                    method: r.method.clone(),
                    known: registry.names().join(", "),
                });
            }
            if r.seed.is_some() && !r.seeds.is_empty() {
                return Err(E::SeedAndSeeds {
                    what,
                    name: r.name.clone(),
                });
            }
            if let (Some(given), Some(prior)) = (r.modes, r.priors.as_ref().and_then(|p| p.modes)) {
                return Err(E::ModesTwice {
                    what,
                    name: r.name.clone(),
                    given,
                    prior,
                });
            }
            if let Some(p) = &r.priors {
                p.check().map_err(|problem| E::RunPriors {
                    what,
                    name: r.name.clone(),
                    problem,
                })?;
            }
            if r.provenance.is_some() && (r.auto || what == "sweep") {
                return Err(E::ProvenanceGiven {
                    what,
                    name: r.name.clone(),
                });
            }
        }
        for s in &self.sweeps {
            let shared = self.priors.modes.filter(|_| s.run.use_priors);
            check_sweep(s, shared)?;
        }
        // Counted before any is made: a sweep's points are the product of
        // its axes' lengths.
        let runs = self.runs.iter().map(|r| r.seeds.len().max(1));
        let sweeps = self.sweeps.iter().map(|s| s.space().count());
        if runs
            .chain(sweeps)
            .try_fold(0usize, |n, k| n.checked_add(k))
            .is_none_or(|n| n > MAX_JOBS)
        {
            return Err(E::TooManyJobs);
        }
        if self.data.decimate == 0 {
            return Err(E::Decimate);
        }
        if !(1..=hysid_core::options::MAX_COUNT).contains(&self.data.refit_starts) {
            return Err(E::RefitStarts);
        }
        if self.data.selection.is_some() && self.data.folds.is_some() {
            return Err(E::SelectionAndFolds);
        }
        if self.data.select_records.is_some()
            && (self.data.selection.is_some() || self.data.folds.is_some())
        {
            return Err(E::SelectRecordsAndRows);
        }
        if !self.data.records.is_empty() {
            if self.data.selection.is_some() {
                return Err(E::RowsWithRecords("selection"));
            }
            if self.data.truth.is_some() {
                return Err(E::RowsWithRecords("truth"));
            }
        }
        let d = &self.data;
        for part in [DataPart::Identification, DataPart::Scored] {
            let in_records =
                (d.records.iter()).any(|r| part.of(r.identification, r.validation).is_some());
            match (
                part.of(d.identification, d.validation),
                d.records.is_empty(),
                in_records,
            ) {
                (None, true, _) => return Err(E::MissingRows(part.key())),
                (None, false, false) => return Err(E::NoRows(part.key())),
                _ => {}
            }
        }
        if d.identification.is_none() && d.validation.is_none() {
            return Err(E::EmptyData);
        }
        (d.selection(RowRange::default()).check_names()).map_err(|problem| E::Signals {
            entry: DataEntry::Main,
            problem,
        })?;
        for (i, r) in self.data.records.iter().enumerate() {
            (d.record_selection(r, RowRange::default()).check_names()).map_err(|problem| {
                E::Signals {
                    entry: DataEntry::Record(i + 1),
                    problem,
                }
            })?;
            if r.identification.is_none() && r.validation.is_none() {
                return Err(E::EmptyRecord(i + 1));
            }
            if let Some(input) = &r.input
                && input.len() != self.data.input.len()
            {
                return Err(E::RecordInputs {
                    record: i + 1,
                    found: input.len(),
                    expected: self.data.input.len(),
                });
            }
        }
        Ok(())
    }
}

/// What an experiment file asks for that runs, but that its user should be
/// told (`hysid compare` says it on standard error).
#[derive(Debug, Clone, PartialEq)]
pub enum ExperimentWarning {
    /// Scored rows that are also identification rows of the same file:
    /// their scores are not on rows the fits did not see.
    ValidationOverlaps {
        /// The entry that gives the validation rows.
        entry: DataEntry,
        /// The entry that gives the identification rows (`entry`, or
        /// another of the same file and signals).
        identified_in: DataEntry,
        /// The identification rows.
        identification: RowRange,
        /// The validation rows.
        validation: RowRange,
    },
    /// `[data]` names no inputs and its file has `u`, which is read, and
    /// also the inputs a run's model file declares
    /// ([`Experiment::unread_declared_inputs`]).
    DeclaredInputsUnread {
        /// The run whose model file declares them.
        run: String,
        /// The inputs read (the default).
        read: Vec<String>,
        /// The inputs the model file declares.
        declared: Vec<String>,
    },
}

impl fmt::Display for ExperimentWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExperimentWarning::ValidationOverlaps {
                entry,
                identified_in,
                identification,
                validation,
            } => {
                let of = if identified_in == entry {
                    String::new()
                } else {
                    format!(" of {identified_in} (the same file and signals)")
                };
                write!(
                    f,
                    "{entry}: the validation rows {validation} overlap the identification rows \
                     {identification}{of}: their scores are not on rows the fits did not see"
                )
            }
            ExperimentWarning::DeclaredInputsUnread {
                run,
                read,
                declared,
            } => {
                let (read, declared) = (read.join(", "), declared.join(", "));
                write!(
                    f,
                    "the record has {read} and also {declared} (the model file of '{run}' \
                     declares {declared}): {read} is read, as the default; name {declared} in \
                     [data] input to read it"
                )
            }
        }
    }
}

impl Experiment {
    /// What the file asks for that its user should be told
    /// ([`ExperimentWarning`]), in the order of the file.
    pub fn warnings(&self) -> Vec<ExperimentWarning> {
        let d = &self.data;
        // Each entry: its file, its signals and its rows.
        let own = (
            DataEntry::Main,
            hysid_io::file_identity(&d.file),
            d.selection(RowRange::default()),
        );
        let entries: Vec<_> = std::iter::once((own, d.identification, d.validation))
            .chain(d.records.iter().enumerate().map(|(i, r)| {
                let at = (
                    DataEntry::Record(i + 1),
                    hysid_io::file_identity(&r.file),
                    d.record_selection(r, RowRange::default()),
                );
                (at, r.identification, r.validation)
            }))
            .collect();
        let mut warnings = Vec::new();
        for ((entry, file, signals), _, validation) in &entries {
            let Some(validation) = validation else {
                continue;
            };
            for ((identified_in, other, theirs), identification, _) in &entries {
                let same = file == other
                    && (&signals.inputs, &signals.output) == (&theirs.inputs, &theirs.output);
                if let (true, Some(identification)) = (same, identification)
                    && identification.overlaps(validation)
                {
                    warnings.push(ExperimentWarning::ValidationOverlaps {
                        entry: *entry,
                        identified_in: *identified_in,
                        identification: *identification,
                        validation: *validation,
                    });
                }
            }
        }
        warnings
    }
}

/// A file name made from a run label.
pub fn slug(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect();
    s.trim_matches('_').to_string()
}

/// A sweep's own consistency: what it varies, each key once and not also
/// fixed by its run or (`modes`) by the experiment's priors it reads
/// (`shared_modes`), each value once; no `auto` or `seeds`.
fn check_sweep(s: &SweepSpec, shared_modes: Option<usize>) -> Result<(), InconsistentExperiment> {
    use InconsistentExperiment as E;
    let name = || s.run.name.clone();
    if s.run.auto || !s.run.seeds.is_empty() {
        return Err(E::SweepOfRuns(name()));
    }
    let space = s.space();
    if space.axes.is_empty() {
        return Err(E::NoAxis(name()));
    }
    if s.vary.is_none() && !s.values.is_empty() {
        return Err(E::ValuesWithoutVary(name()));
    }
    if let Some(axis) = space.axes.iter().find(|a| a.values.is_empty()) {
        return Err(E::NoValues {
            name: name(),
            key: axis.key.clone(),
        });
    }
    let keys: Vec<&str> = space.axes.iter().map(|a| a.key.as_str()).collect();
    if let Some(key) = first_repeated(&keys) {
        return Err(E::SweptTwice {
            name: name(),
            key: key.to_string(),
        });
    }
    let r = &s.run;
    let fixed = |key: &str| match key {
        "na" => r.na.is_some(),
        "nb" => r.nb.is_some(),
        "modes" => r
            .modes
            .or(r.priors.as_ref().and_then(|p| p.modes))
            .is_some(),
        key => r.set.contains_key(key),
    };
    let shared = |key: &str| key == "modes" && shared_modes.is_some();
    if let Some(key) = keys.iter().find(|k| fixed(k) || shared(k)) {
        let given = if r.set.contains_key(*key) {
            format!("set = {{ {key} = ... }}")
        } else if fixed(key) {
            format!("{key} = ...")
        } else {
            format!("[priors] {key} = ...")
        };
        return Err(E::SweptAndFixed {
            name: name(),
            key: key.to_string(),
            given,
        });
    }
    for axis in &space.axes {
        if let Some(value) = first_repeated(&axis.values) {
            return Err(E::Repeated {
                what: "sweep",
                name: name(),
                key: axis.key.clone(),
                value: value.clone(),
            });
        }
    }
    Ok(())
}

/// The file name of `name`'s results as two names compare on any file
/// system: [`slug`], case aside.
pub fn file_name(name: &str) -> String {
    slug(name).to_lowercase()
}

/// `seeds`, not empty: `seeds = []` runs nothing it names.
fn listed<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<u64>, D::Error> {
    non_empty(d, "give the seeds, or leave seeds out")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_file_is_joined_to_the_folder_without_dot_dot() {
        let j = |folder: &str, file: &str| lexically_joined(Path::new(folder), file);
        assert_eq!(
            j("models/a/sim", "../head.toml"),
            Path::new("models/a/head.toml")
        );
        assert_eq!(
            j("models/a", "./head.toml"),
            Path::new("models/a/head.toml")
        );
        assert_eq!(j("", "../x.toml"), Path::new("../x.toml"));
        assert_eq!(j("a", "../../x.toml"), Path::new("../x.toml"));
        assert_eq!(j("/m", "/abs/x.toml"), Path::new("/abs/x.toml"));
    }

    #[test]
    fn the_jobs_are_counted_before_they_are_made() {
        let text = |grid: &str| {
            format!(
                "title = \"t\"\n[data]\nfile = \"d.csv\"\nidentification = \"0..100\"\n\
                 validation = \"100..\"\n[[run]]\nname = \"a\"\nmethod = \"arx\"\n\
                 seeds = [1, 2, 3]\n[[sweep]]\nname = \"s\"\nmethod = \"arx\"\ngrid = {{ {grid} }}\n"
            )
        };
        // `k` axes of `n` values each.
        let axes = |k: usize, n: usize| {
            let values: Vec<String> = (0..n).map(|v| v.to_string()).collect();
            (0..k)
                .map(|i| format!("o{i} = [{}]", values.join(", ")))
                .collect::<Vec<_>>()
                .join(", ")
        };
        // 3 seeds and 99 * 101 points: 10 002 jobs, two more than the limit.
        let over = format!("{}, {}", axes(1, 99), axes(1, 101).replace("o0", "p0"));
        let e = Experiment::from_toml(&text(&over), "x.toml").unwrap_err();
        assert!(e.to_string().contains("more than 10000 jobs"), "{e}");
        // One value fewer: 3 + 99 * 100 = 9 903 jobs (of keys arx takes, as
        // every point is checked as a run).
        let at = format!("{}, {}", axes(1, 99), axes(1, 101).replace("o0", "p0"))
            .replace("p0 = [0, ", "p0 = [")
            .replace("o0", "na")
            .replace("p0", "nb");
        let e = Experiment::from_toml(&text(&at), "x.toml").unwrap();
        assert_eq!(e.sweeps[0].space().count(), 9_900);
        // 64 axes of two values: 2^64 points, counted without overflow.
        let e = Experiment::from_toml(&text(&axes(64, 2)), "x.toml").unwrap_err();
        assert!(e.to_string().contains("more than 10000 jobs"), "{e}");
    }

    /// Validation rows that share a row with the identification rows of
    /// the same file are warned of, open ends included; disjoint ones and
    /// rows of different files are not.
    #[test]
    fn overlapping_validation_rows_are_warned_of() {
        let warned = |id: &str, val: &str, records: &str| {
            let text = format!(
                "title = \"t\"\n[data]\nfile = \"d.csv\"\nidentification = \"{id}\"\n\
                 validation = \"{val}\"\n{records}[[run]]\nname = \"a\"\nmethod = \"arx\"\n"
            );
            let e = Experiment::from_toml(&text, "x.toml").unwrap();
            e.warnings()
                .iter()
                .map(|w| w.to_string())
                .collect::<Vec<_>>()
        };
        assert!(warned("0..100", "100..", "").is_empty());
        assert!(warned("100..", "0..100", "").is_empty());
        let w = warned("0..100", "99..", "");
        assert_eq!(w.len(), 1);
        assert!(
            w[0].starts_with(
                "[data]: the validation rows 99.. overlap the identification rows 0..100"
            ),
            "{}",
            w[0]
        );
        assert_eq!(warned("..", "5..6", "").len(), 1);
        assert_eq!(warned("50..", "0..51", "").len(), 1);
        let record = |id: &str, val: &str| {
            format!(
                "[[data.records]]\nfile = \"e.csv\"\nidentification = \"{id}\"\n\
                 validation = \"{val}\"\n"
            )
        };
        // A record's rows against its own identification rows only.
        assert!(warned("0..100", "100..", &record("100..", "0..100")).is_empty());
        let w = warned("0..100", "100..", &record("0..10", "5.."));
        assert_eq!(w.len(), 1);
        assert!(w[0].starts_with("[[data.records]] #1: "), "{}", w[0]);
    }

    /// A record that names the main file by another path (`./d.csv`,
    /// `sub/../d.csv`) is the same file: its identification rows overlap
    /// the main entry's validation rows; another file's do not.
    #[test]
    fn one_file_written_two_ways_is_one_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        for name in ["d.csv", "e.csv"] {
            std::fs::write(dir.path().join(name), "t,u,y\n0,0,0\n").unwrap();
        }
        let warnings = |file: &str| {
            let text = format!(
                "title = \"t\"\n[data]\nfile = \"d.csv\"\nidentification = \"0..100\"\n\
                 validation = \"100..\"\n[[data.records]]\nfile = \"{file}\"\n\
                 identification = \"100..200\"\n[[run]]\nname = \"a\"\nmethod = \"arx\"\n"
            );
            let path = dir.path().join("x.toml");
            std::fs::write(&path, text).unwrap();
            Experiment::load(&path).unwrap().warnings().len()
        };
        assert_eq!(warnings("./d.csv"), 1);
        assert_eq!(warnings("sub/../d.csv"), 1);
        assert_eq!(warnings("e.csv"), 0);
    }

    #[test]
    fn parses_and_rejects_typos() {
        let text = r#"
title = "t"
[data]
file = "d.csv"
identification = "0..100"
validation = "100.."
[[run]]
name = "a"
method = "arx"
set = { ridge = 0.1 }
[[sweep]]
name = "s"
method = "arx"
vary = "na"
values = [1, 2]
"#;
        let e = Experiment::from_toml(text, "x.toml").unwrap();
        assert_eq!(e.runs[0].set["ridge"], toml::Value::Float(0.1));
        assert_eq!(e.sweeps[0].vary.as_deref(), Some("na"));
        assert_eq!(e.sweeps[0].space().count(), 2);
        let grid = text.replace(
            "method = \"arx\"\nvary = \"na\"\nvalues = [1, 2]",
            "method = \"cluster\"\ngrid = { na = [1, 2], modes = [1, 2, 3] }",
        );
        let g = Experiment::from_toml(&grid, "x.toml").unwrap();
        let pts = g.sweeps[0].space().candidates();
        assert_eq!(pts.len(), 6);
        assert_eq!(pts[1].values[0].0, "modes");
        assert_eq!(pts[1].values[1], ("na".to_string(), "2".to_string()));
        let bad = text.replace("method = \"arx\"\nset", "method = \"nope\"\nset");
        assert!(
            Experiment::from_toml(&bad, "x")
                .unwrap_err()
                .to_string()
                .contains("unknown method 'nope'")
        );
        let bad = text.replace("validation", "valdation");
        assert!(
            Experiment::from_toml(&bad, "x")
                .unwrap_err()
                .to_string()
                .contains("valdation")
        );
    }

    #[test]
    fn seeds_expand_into_one_job_each_and_auto_stays_out_of_sweeps() {
        let text = r#"
title = "t"
[data]
file = "d.csv"
identification = "0..100"
validation = "100.."
[[run]]
name = "c"
method = "cluster"
auto = true
seeds = [3, 4]
"#;
        let e = Experiment::from_toml(text, "x.toml").unwrap();
        let jobs = e.jobs().unwrap();
        assert_eq!(jobs.len(), 2);
        assert_eq!(jobs[1].name, "c [seed=4]");
        assert_eq!(jobs[1].seed, 4);
        assert_eq!(jobs[1].seed_group.as_deref(), Some("c"));
        assert!(jobs.iter().all(|j| j.auto));
        let both = text.replace("seeds = [3, 4]", "seeds = [3, 4]\nseed = 1");
        let err = Experiment::from_toml(&both, "x").unwrap_err().to_string();
        assert!(err.contains("give seed or seeds, not both"), "{err}");
        let sweep = text.replace("[[run]]", "[[sweep]]\nvary = \"c\"\nvalues = [20]");
        let err = Experiment::from_toml(&sweep, "x").unwrap_err().to_string();
        assert!(err.contains("auto and seeds belong to a [[run]]"), "{err}");
    }
}
