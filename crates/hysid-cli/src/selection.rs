//! Data selection flags shared by the commands (`docs/cli.md`, "Data
//! selection").

use crate::error::CliError;
use hysid_core::model::{Model, SignalNames};
use hysid_model::data::{DataError, DataSelection, Dataset, RowRange, SignalNameError};
use std::path::PathBuf;

/// Which signals and samples of a data file to use.
#[derive(clap::Args, Debug, Clone)]
pub struct DataArgs {
    #[command(flatten)]
    pub signals: SignalArgs,
    /// Rows A..B after decimation (A inclusive, B exclusive).
    ///
    /// Either bound may be left out. With several data files: once for
    /// every file, or once per file in their order.
    // Hyphen values are taken, so `-5..10` is refused as rows, not read as a flag.
    #[arg(long, allow_hyphen_values = true)]
    pub rows: Vec<RowRange>,
}

/// Which signals of a data file to use, and how they are sampled.
#[derive(clap::Args, Debug, Clone)]
pub struct SignalArgs {
    /// Input column/variable name(s), comma separated.
    ///
    /// Default: u; where the record has no u, the model's inputs (those it
    /// was identified on, or those its file declares).
    #[arg(long, value_delimiter = ',')]
    pub input: Option<Vec<String>>,
    /// Output column/variable name.
    ///
    /// Default: y; where the record has no y, the output the model was
    /// identified on.
    #[arg(long)]
    pub output: Option<String>,
    /// Keep every K-th sample (0, K, 2K, ...; no filter).
    #[arg(long, default_value_t = 1, value_parser = parse_at_least_one)]
    pub decimate: usize,
    /// Sampling time in seconds when the file has no time signal.
    #[arg(long, value_parser = parse_ts)]
    pub ts: Option<f64>,
    /// Column/variable of the time in seconds.
    ///
    /// Its first step (after decimation) is the sampling time.
    #[arg(long, default_value = hysid_model::data::DEFAULT_TIME)]
    pub time: String,
    /// The names read where `--input`/`--output` are not given and the
    /// record lacks `u` or `y`.
    #[arg(skip)]
    pub defaults: SignalDefaults,
}

/// The signal names a command reads where the user names none and the
/// record lacks `u` or `y`: a model's ([`Model::signal_names`]), or the
/// inputs a model file declares.
#[derive(Debug, Clone, Default)]
pub struct SignalDefaults {
    inputs: Option<Vec<String>>,
    output: Option<String>,
    /// Whose names they are, as a message says it.
    whose: &'static str,
}

impl SignalDefaults {
    /// The names `model` reads its record under ([`Model::signal_names`]).
    pub fn of_model(model: &Model) -> Self {
        let SignalNames { inputs, output } = model.signal_names();
        let whose = if !model.info().input_names.is_empty() {
            "the model was identified on"
        } else {
            "the model file declares"
        };
        SignalDefaults {
            inputs,
            output,
            whose,
        }
    }

    /// The signals a model file declares (or was identified on), for a
    /// fit of it.
    pub fn declared(names: SignalNames) -> Self {
        SignalDefaults {
            inputs: names.inputs.filter(|names| !names.is_empty()),
            output: names.output,
            whose: "the model file declares",
        }
    }

    /// `--input A,B --output Y` for the names these defaults give.
    fn flags(&self) -> Option<String> {
        let inputs = self.inputs.as_ref()?;
        let output = (self.output.as_ref())
            .map(|o| format!(" --output {o}"))
            .unwrap_or_default();
        Some(format!("--input {}{output}", inputs.join(",")))
    }
}

/// A whole number of at least 1 (`--decimate`, `--refit-starts`).
pub fn parse_at_least_one(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(k) if k >= 1 => Ok(k),
        _ => Err(format!("'{s}' is not a whole number of at least 1")),
    }
}

/// A count of samples (`--warmup`): a whole number, 0 or more.
pub fn parse_count(s: &str) -> Result<usize, String> {
    s.parse::<usize>()
        .map_err(|_| format!("'{s}' is not a whole number of samples (0 or more)"))
}

fn parse_ts(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a positive number of seconds")),
    }
}

impl DataArgs {
    /// The selection of one data file for `hysid_io::load`
    /// ([`SignalArgs::selection`]).
    pub fn selection(&self) -> Result<DataSelection, CliError> {
        match self.rows[..] {
            [] => self.signals.selection(RowRange::default()),
            [rows] => self.signals.selection(rows),
            _ => Err(CliError::input(format!(
                "--rows: given {} times for one data file",
                self.rows.len()
            ))),
        }
    }

    /// These flags reading, where they name no signal and the record lacks
    /// `u` or `y`, `defaults`.
    pub fn reading(self, defaults: SignalDefaults) -> Self {
        DataArgs {
            signals: SignalArgs {
                defaults,
                ..self.signals
            },
            ..self
        }
    }

    /// The records of `files`, each with its `--rows`, joined into one
    /// dataset ([`hysid_io::load_records`]), read as [`Self::read`] says.
    pub fn load(&self, files: &[PathBuf]) -> Result<Dataset, CliError> {
        once_or_per_file("--rows", self.rows.len(), files.len())?;
        self.read(|signals| {
            let records = (files.iter().enumerate())
                .map(|(i, file)| {
                    let rows = self.rows_of(i).unwrap_or_default();
                    Ok((file.as_path(), signals.selection(rows)?))
                })
                .collect::<Result<Vec<_>, CliError>>()?;
            Ok(hysid_io::load_records(&records))
        })
    }

    /// One data file with its `--rows`, read as [`Self::read`] says.
    pub fn load_one(&self, file: &std::path::Path) -> Result<Dataset, CliError> {
        let rows = self.selection()?.rows;
        self.read(|signals| Ok(hysid_io::load(file, &signals.selection(rows)?)))
    }

    /// What `load` reads: the signals as the flags name them (`u` and `y`
    /// where they name none), and, where the record lacks `u` or `y`, as
    /// the model names that signal ([`SignalArgs::naming_as_the_model`]);
    /// the last reading's error, worded by [`SignalArgs::data_error`], when
    /// none reads.
    fn read(
        &self,
        load: impl Fn(&SignalArgs) -> Result<Result<Dataset, DataError>, CliError>,
    ) -> Result<Dataset, CliError> {
        let mut signals = self.signals.clone();
        let mut failed = match load(&signals)? {
            Ok(data) => {
                self.warn_of_the_model_s(&load);
                return Ok(data);
            }
            Err(e) => e,
        };
        // Each swap names one more signal (the inputs, the output): at most
        // two.
        for _ in 0..2 {
            let DataError::Missing { name, .. } = &failed else {
                break;
            };
            let Some(next) = signals.naming_as_the_model(name) else {
                break;
            };
            signals = next;
            failed = match load(&signals)? {
                Ok(data) => return Ok(data),
                Err(e) => e,
            };
        }
        Err(self.error(failed))
    }

    /// Says on standard error where the record read by the defaults (`u`,
    /// `y`) also has the model's own signal, which is not read: a record
    /// with an unrelated `u` would otherwise score the model on it without
    /// a word. Each signal is swapped as a missing one would be
    /// ([`SignalArgs::naming_as_the_model`]).
    fn warn_of_the_model_s(
        &self,
        load: &impl Fn(&SignalArgs) -> Result<Result<Dataset, DataError>, CliError>,
    ) {
        let signals = &self.signals;
        let inputs = signals.inputs();
        let (read_inputs, read_output) = (inputs.join(","), signals.output());
        let first = inputs.first().cloned().unwrap_or_default();
        let swaps = [
            ("--input", &read_inputs, &first),
            ("--output", &read_output, &read_output),
        ];
        for (flag, read, name) in swaps {
            let Some(named) = signals.naming_as_the_model(name) else {
                continue;
            };
            let model = match flag {
                "--input" => named.inputs().join(","),
                _ => named.output(),
            };
            if let Ok(Ok(_)) = load(&named) {
                eprintln!(
                    "hysid: warning: the record has {read} and also {model} ({} {flag} {model}): \
                     {read} is read, as the default; give {flag} {model} to read {model}",
                    signals.defaults.whose
                );
            }
        }
    }

    /// `e`, met reading the records, as the program words it.
    fn error(&self, e: DataError) -> CliError {
        match e {
            // The records of one file under other signal names need an
            // experiment file.
            DataError::RecordTwice { .. } => CliError::input(format!(
                "{e}: give each record its --rows, or, for records of one file under other signal \
                 names, an experiment file's [[data.records]] (docs/compare.md)"
            )),
            e => self.signals.data_error(e),
        }
    }

    /// The `--rows` of the `i`-th data file (from 0): given once for all
    /// files, or once per file.
    pub fn rows_of(&self, i: usize) -> Option<RowRange> {
        self.rows.get(i).or(self.rows.first()).copied()
    }

    /// Row of the file where the (first) record starts.
    pub fn first_row(&self) -> usize {
        self.rows.first().and_then(|r| r.start).unwrap_or(0)
    }
}

/// A flag given `given` times for `files` data files: at most once, or
/// once per file.
pub fn once_or_per_file(flag: &str, given: usize, files: usize) -> Result<(), CliError> {
    if given > 1 && given != files {
        return Err(CliError::input(format!(
            "{flag}: given {given} times for {files} data files; give it once for every file or once per file"
        )));
    }
    Ok(())
}

impl SignalArgs {
    /// The input names read: `--input`, else `u`.
    pub fn inputs(&self) -> Vec<String> {
        (self.input.clone()).unwrap_or_else(|| vec![hysid_model::data::DEFAULT_INPUT.to_string()])
    }

    /// The output name read: `--output`, else `y`.
    pub fn output(&self) -> String {
        (self.output.clone()).unwrap_or_else(|| hysid_model::data::DEFAULT_OUTPUT.to_string())
    }

    /// These flags with the signal `missing` names (one the record lacks)
    /// named as the model names it ([`SignalDefaults`]), where the flags
    /// leave it unnamed and the model names it otherwise: the inputs as a
    /// whole, or the output; `None` where that reads nothing else.
    pub fn naming_as_the_model(&self, missing: &str) -> Option<SignalArgs> {
        let inputs = self.inputs();
        if self.input.is_none()
            && inputs.iter().any(|i| i == missing)
            && let Some(model) = self.defaults.inputs.as_ref().filter(|m| **m != inputs)
        {
            return Some(SignalArgs {
                input: Some(model.clone()),
                ..self.clone()
            });
        }
        if self.output.is_none()
            && self.output() == missing
            && let Some(model) = self.defaults.output.as_ref().filter(|m| **m != missing)
        {
            return Some(SignalArgs {
                output: Some(model.clone()),
                ..self.clone()
            });
        }
        None
    }

    /// `e` as the program words it; a signal the record lacks also names
    /// the model's signals ([`SignalDefaults`]): those the user named
    /// instead, or those read because the user named none. A model file
    /// given as data is named as such.
    pub fn data_error(&self, e: DataError) -> CliError {
        let model_file = |p: &std::path::Path| {
            (p.extension().and_then(|x| x.to_str()))
                .is_some_and(|x| x.eq_ignore_ascii_case("json") || x.eq_ignore_ascii_case("toml"))
        };
        match &e {
            DataError::UnsupportedFormat(path) if model_file(path) => CliError::input(format!(
                "{}: a model file where a data file (.csv or .mat) is expected",
                path.display()
            )),
            DataError::Missing { name, .. } => {
                // A signal read, as the flags or the model name it (not
                // the time, say).
                let d = &self.defaults;
                let signal = self.inputs().contains(name)
                    || self.output() == *name
                    || d.inputs.as_ref().is_some_and(|i| i.contains(name))
                    || d.output.as_ref() == Some(name);
                let Some(flags) = self.defaults.flags().filter(|_| signal) else {
                    return e.into();
                };
                let whose = self.defaults.whose;
                let taken = (self.input.is_none() && self.defaults.inputs.is_some())
                    || (self.output.is_none() && self.defaults.output.is_some());
                let differ = (self.defaults.inputs.as_ref()).is_some_and(|d| *d != self.inputs())
                    || (self.defaults.output.as_ref()).is_some_and(|d| *d != self.output());
                if taken {
                    CliError::input(format!(
                        "{e}; {whose} {flags}: name this record's signals with --input and --output"
                    ))
                } else if differ {
                    CliError::input(format!("{e}; {whose} {flags}"))
                } else {
                    e.into()
                }
            }
            _ => e.into(),
        }
    }

    /// The selection of `rows` for `hysid_io::load`. A signal named twice
    /// (twice among the inputs, or as an input and the output) is refused:
    /// the regressors would be collinear copies of each other.
    pub fn selection(&self, rows: RowRange) -> Result<DataSelection, CliError> {
        let selection = DataSelection {
            inputs: self.inputs(),
            output: self.output(),
            decimate: self.decimate,
            rows,
            ts: self.ts,
            time: self.time.clone(),
        };
        selection.check_names().map_err(|e| {
            CliError::input(match e {
                SignalNameError::Empty => "--input/--output: an empty signal name".to_string(),
                SignalNameError::InputTwice(name) => format!("--input: '{name}' is named twice"),
                SignalNameError::InputIsOutput(name) => format!(
                    "--input '{name}' is also the --output; an input must be another signal"
                ),
            })
        })?;
        Ok(selection)
    }
}
