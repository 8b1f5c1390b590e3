//! Measured input/output records: signals, the selection rules applied
//! when reading them (by name, decimation, row ranges) and standardisation.
//! The CSV and MAT readers live in `hysid-io`.

mod standardize;

pub use standardize::{AffineScale, Standardization};

use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;

/// One named, uniformly sampled signal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Signal {
    /// Column or variable name it was read from.
    pub name: String,
    /// Samples, one per time step.
    pub values: Vec<f64>,
}

/// A multi-input single-output (MISO) record: the inputs `u_1 .. u_m`,
/// the output `y`, and the sampling time when known.
///
/// A dataset may join several records (experiments) of one system
/// ([`Dataset::join`]): their samples follow each other and
/// [`Dataset::boundaries`] says where each record after the first begins.
/// Nothing spans a boundary: no regressor, no shooting segment, no
/// simulation (each record starts from its own initial state).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dataset {
    /// Input signals `u_1 .. u_m`, all of the output's length.
    pub inputs: Vec<Signal>,
    /// The output signal `y`.
    pub output: Signal,
    /// Sampling time in seconds (after decimation), when known.
    pub ts: Option<f64>,
    /// Samples at which a new record begins, increasing, each inside
    /// `1..len` (empty for one record).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boundaries: Vec<usize>,
}

impl Dataset {
    /// Builds a dataset from plain vectors, checking that every signal has
    /// the same length and only finite values.
    pub fn new(inputs: Vec<Signal>, output: Signal, ts: Option<f64>) -> Result<Self, DataError> {
        let n = output.values.len();
        for s in inputs.iter().chain(std::iter::once(&output)) {
            if s.values.len() != n {
                return Err(DataError::Shape(format!(
                    "signal '{}' has {} samples, the output '{}' has {}",
                    s.name,
                    s.values.len(),
                    output.name,
                    n
                )));
            }
            if let Some(k) = s.values.iter().position(|v| !v.is_finite()) {
                return Err(DataError::Shape(format!(
                    "signal '{}' has a non-finite value at sample {k}",
                    s.name
                )));
            }
        }
        if let Some(t) = ts
            && !(t.is_finite() && t > 0.0)
        {
            return Err(DataError::Shape(format!(
                "sampling time must be a finite number of seconds > 0, got {t}"
            )));
        }
        Ok(Self {
            inputs,
            output,
            ts,
            boundaries: Vec::new(),
        })
    }

    /// One dataset of several records of one system, in order: as many
    /// inputs and the same sampling time in each (to [`TS_TOLERANCE`] of
    /// it: a time column read from text gives its step with rounding),
    /// every record non-empty; the joined dataset has the first's.
    /// The signals keep the first record's names (records of one file may
    /// name theirs `u1`, `u2`, ...).
    pub fn join(records: &[Dataset]) -> Result<Self, DataError> {
        let Some(first) = records.first() else {
            return Err(DataError::Shape("no record to join".into()));
        };
        let join_error = |i: usize, reason: String| DataError::Join {
            record: i + 1,
            reason,
        };
        let mut joined = first.clone();
        for (i, r) in records.iter().enumerate() {
            if r.is_empty() {
                return Err(join_error(i, "holds no sample".into()));
            }
            if r.inputs.len() != first.inputs.len() {
                return Err(join_error(
                    i,
                    format!(
                        "{} input(s), record 1 {}",
                        r.inputs.len(),
                        first.inputs.len()
                    ),
                ));
            }
            if !same_sampling(r.ts, first.ts) {
                let none = "no sampling time (no time signal, none given)";
                let why = match (r.ts, first.ts) {
                    (None, Some(t)) => format!("{none}, record 1 {t} s"),
                    (Some(t), None) => format!("sampling time {t} s, record 1 {none}"),
                    (t, t1) => format!(
                        "sampling time {} s differs from record 1's {} s",
                        t.unwrap_or(f64::NAN),
                        t1.unwrap_or(f64::NAN)
                    ),
                };
                return Err(join_error(i, why));
            }
            if i == 0 {
                continue;
            }
            let at = joined.len();
            joined.boundaries.push(at);
            joined
                .boundaries
                .extend(r.boundaries.iter().map(|b| b + at));
            for (s, t) in joined.inputs.iter_mut().zip(&r.inputs) {
                s.values.extend_from_slice(&t.values);
            }
            joined.output.values.extend_from_slice(&r.output.values);
        }
        Ok(joined)
    }

    /// The samples of each record, in order (one range for one record).
    /// A boundary out of order or outside `1..len` (set by hand) is
    /// ignored.
    pub fn record_ranges(&self) -> Vec<std::ops::Range<usize>> {
        let mut ranges = Vec::with_capacity(self.boundaries.len() + 1);
        let mut start = 0;
        for &b in &self.boundaries {
            if b > start && b < self.len() {
                ranges.push(start..b);
                start = b;
            }
        }
        ranges.push(start..self.len());
        ranges
    }

    /// Number of records joined in the dataset (1 for a single record).
    pub fn record_count(&self) -> usize {
        self.record_ranges().len()
    }

    /// Each record as a dataset of its own.
    pub fn records(&self) -> Vec<Dataset> {
        self.record_ranges()
            .into_iter()
            .map(|r| self.cut(r.start, r.end))
            .collect()
    }

    /// Each record played backwards: its samples in reverse order, the
    /// records in their order, the same boundaries.
    pub fn backwards(&self) -> Self {
        let ranges = self.record_ranges();
        let turn = |s: &Signal| Signal {
            name: s.name.clone(),
            values: (ranges.iter())
                .flat_map(|r| s.values[r.clone()].iter().rev().copied())
                .collect(),
        };
        Self {
            inputs: self.inputs.iter().map(turn).collect(),
            output: turn(&self.output),
            ts: self.ts,
            boundaries: self.boundaries.clone(),
        }
    }

    /// Samples `a..b`, with the boundaries inside them.
    fn cut(&self, a: usize, b: usize) -> Self {
        let cut = |s: &Signal| Signal {
            name: s.name.clone(),
            values: s.values[a..b].to_vec(),
        };
        Self {
            inputs: self.inputs.iter().map(cut).collect(),
            output: cut(&self.output),
            ts: self.ts,
            boundaries: self
                .boundaries
                .iter()
                .filter(|&&k| k > a && k < b)
                .map(|k| k - a)
                .collect(),
        }
    }

    /// A single-input dataset named `u`, `y`.
    pub fn siso(u: Vec<f64>, y: Vec<f64>, ts: Option<f64>) -> Result<Self, DataError> {
        Self::new(
            vec![Signal {
                name: "u".into(),
                values: u,
            }],
            Signal {
                name: "y".into(),
                values: y,
            },
            ts,
        )
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.output.values.len()
    }

    /// True when the record holds no sample.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Output samples.
    pub fn y(&self) -> &[f64] {
        &self.output.values
    }

    /// Samples of input `i`.
    pub fn u(&self, i: usize) -> &[f64] {
        &self.inputs[i].values
    }

    /// Input names, in order.
    pub fn input_names(&self) -> Vec<String> {
        self.inputs.iter().map(|s| s.name.clone()).collect()
    }

    /// Keeps rows `range` (clamped to the dataset), with the record
    /// boundaries inside them.
    pub fn slice(&self, range: RowRange) -> Result<Self, DataError> {
        let (a, b) = range.resolve(self.len())?;
        Ok(self.cut(a, b))
    }
}

/// Relative difference up to which two sampling times are the same: a
/// time column's later steps against its first (clock jitter and rounding
/// pass; a missing or repeated sample does not), and two records' sampling
/// times ([`Dataset::join`]; pieces of one jittering record join as the
/// record itself reads).
pub const TS_TOLERANCE: f64 = 0.01;

/// Whether two sampling times are the same: both unknown, or both known
/// and equal to [`TS_TOLERANCE`] of the larger.
pub fn same_sampling(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => (a - b).abs() <= TS_TOLERANCE * a.abs().max(b.abs()),
        _ => false,
    }
}

/// Which signals to read and which samples to keep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DataSelection {
    /// Input column/variable names (default `["u"]`).
    pub inputs: Vec<String>,
    /// Output column/variable name (default `"y"`).
    pub output: String,
    /// Keep every K-th sample, no filter (default 1).
    pub decimate: usize,
    /// Rows to keep, counted after decimation (default: all).
    pub rows: RowRange,
    /// Sampling time in seconds when the file has no time signal.
    pub ts: Option<f64>,
    /// The column/variable holding the time in seconds (default `"t"`):
    /// the sampling time is its first step.
    pub time: String,
}

/// The default name of the time column/variable.
pub const DEFAULT_TIME: &str = "t";

/// The default name of the input column/variable.
pub const DEFAULT_INPUT: &str = "u";

/// The default name of the output column/variable.
pub const DEFAULT_OUTPUT: &str = "y";

impl Default for DataSelection {
    fn default() -> Self {
        Self {
            inputs: vec![DEFAULT_INPUT.into()],
            output: DEFAULT_OUTPUT.into(),
            decimate: 1,
            rows: RowRange::default(),
            ts: None,
            time: DEFAULT_TIME.into(),
        }
    }
}

impl DataSelection {
    /// Checks the signal names: none empty, no input named twice, no input
    /// that is also the output (the regressors would hold collinear copies
    /// of one signal). Each front end words the error with its own argument
    /// names.
    pub fn check_names(&self) -> Result<(), SignalNameError> {
        for (i, name) in self.inputs.iter().enumerate() {
            if name.is_empty() {
                return Err(SignalNameError::Empty);
            }
            if self.inputs[..i].contains(name) {
                return Err(SignalNameError::InputTwice(name.clone()));
            }
            if *name == self.output {
                return Err(SignalNameError::InputIsOutput(name.clone()));
            }
        }
        if self.output.is_empty() {
            return Err(SignalNameError::Empty);
        }
        Ok(())
    }
}

/// What is wrong with the signal names of a [`DataSelection`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SignalNameError {
    /// An empty name.
    #[error("an empty signal name")]
    Empty,
    /// An input named twice.
    #[error("input '{0}' is named twice")]
    InputTwice(String),
    /// An input that is also the output.
    #[error("input '{0}' is also the output; an input must be another signal")]
    InputIsOutput(String),
}

/// A half-open row range `A..B`; either bound may be left out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct RowRange {
    /// First row kept (inclusive).
    pub start: Option<usize>,
    /// First row not kept (exclusive).
    pub end: Option<usize>,
}

impl RowRange {
    /// Whether the two ranges share a row (an open end reaches every row).
    pub fn overlaps(&self, other: &RowRange) -> bool {
        let start = self.start.unwrap_or(0).max(other.start.unwrap_or(0));
        let end = (self.end.unwrap_or(usize::MAX)).min(other.end.unwrap_or(usize::MAX));
        start < end
    }

    /// Resolves the bounds against a record of `n` rows.
    pub fn resolve(&self, n: usize) -> Result<(usize, usize), DataError> {
        let a = self.start.unwrap_or(0);
        let b = self.end.unwrap_or(n).min(n);
        if a >= b {
            return Err(DataError::NoRows {
                rows: *self,
                available: n,
            });
        }
        Ok((a, b))
    }
}

impl fmt::Display for RowRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(a) = self.start {
            write!(f, "{a}")?;
        }
        write!(f, "..")?;
        if let Some(b) = self.end {
            write!(f, "{b}")?;
        }
        Ok(())
    }
}

impl std::str::FromStr for RowRange {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (a, b) = s
            .split_once("..")
            .ok_or_else(|| format!("row range '{s}' is not of the form A..B"))?;
        let parse = |x: &str| -> Result<Option<usize>, String> {
            let x = x.trim();
            if x.is_empty() {
                Ok(None)
            } else {
                x.parse::<usize>()
                    .map(Some)
                    .map_err(|_| format!("row range '{s}': '{x}' is not a row number"))
            }
        };
        let r = RowRange {
            start: parse(a)?,
            end: parse(b)?,
        };
        if let (Some(a), Some(b)) = (r.start, r.end)
            && a >= b
        {
            return Err(format!("row range '{s}' is empty"));
        }
        Ok(r)
    }
}

impl TryFrom<String> for RowRange {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        s.parse()
    }
}

impl From<RowRange> for String {
    fn from(r: RowRange) -> String {
        r.to_string()
    }
}

impl DataError {
    /// A [`DataError::Rows`] worded with `name`, the flag or key that gave
    /// the rows (`--rows`, `--identify-rows`, `[data] identification`).
    pub fn rows_named(&self, name: &str) -> Option<String> {
        let DataError::Rows {
            path,
            rows,
            available,
            decimate,
            beyond,
        } = self
        else {
            return None;
        };
        let what = if *beyond {
            "ends beyond"
        } else {
            "selects no sample of"
        };
        Some(format!(
            "{}: {name} {rows} {what} the {available} rows left after decimation by {decimate}",
            path.display()
        ))
    }
}

/// Errors from reading or selecting data. Every message names the file and,
/// where it applies, the row and column.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A malformed cell, row or variable.
    #[error("{path}: {location}{message}")]
    Parse {
        /// File concerned.
        path: PathBuf,
        /// "row R, column 'C': " or "variable 'v': " (may be empty).
        location: String,
        /// What is wrong.
        message: String,
    },
    /// A requested column or variable does not exist.
    #[error("{path}: no {what} '{name}' (available: {available})")]
    Missing {
        /// File concerned.
        path: PathBuf,
        /// "column" or "variable".
        what: &'static str,
        /// Name asked for.
        name: String,
        /// Names present.
        available: String,
    },
    /// A file type that is not supported.
    #[error("{0}: unsupported data file type (expected .csv or .mat)")]
    UnsupportedFormat(PathBuf),
    /// Signals of different lengths or other shape problems.
    #[error("{0}")]
    Shape(String),
    /// Bad decimation or row selection.
    #[error("{0}")]
    Selection(String),
    /// Rows that the record, after decimation, does not hold: they end
    /// beyond it (`beyond`) or select none of it. Front ends word it with
    /// the flag or key that gave the rows ([`DataError::rows_named`]).
    #[error("{}", self.rows_named("rows").unwrap_or_default())]
    Rows {
        /// File concerned.
        path: PathBuf,
        /// The rows asked for.
        rows: RowRange,
        /// Rows the record holds after decimation.
        available: usize,
        /// The decimation.
        decimate: usize,
        /// The rows end beyond the record (else they select none of it).
        beyond: bool,
    },
    /// Rows that select no sample of a record ([`RowRange::resolve`]).
    #[error("rows {rows} select no sample of a record with {available} rows")]
    NoRows {
        /// The rows asked for.
        rows: RowRange,
        /// Rows the record holds.
        available: usize,
    },
    /// A record that cannot be joined to the first ([`Dataset::join`]).
    #[error("record {record}: {reason}")]
    Join {
        /// The record, counted from 1.
        record: usize,
        /// What is wrong.
        reason: String,
    },
    /// The record read from a file that cannot be joined to the first.
    #[error("{path}: {reason}")]
    NotJoined {
        /// File of the record.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// One file given as two records with the same signals over rows that
    /// overlap: those rows counted twice.
    #[error("{path}: given twice with the same signals over rows that overlap (records {first} and {second}): those rows would count twice", path = path.display())]
    RecordTwice {
        /// The file.
        path: PathBuf,
        /// The first record (from 1).
        first: usize,
        /// The record that repeats it (from 1).
        second: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_record_is_played_backwards_in_its_place() {
        let record =
            |u: &[f64], y: &[f64]| Dataset::siso(u.to_vec(), y.to_vec(), Some(0.5)).unwrap();
        let joined = Dataset::join(&[
            record(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0]),
            record(&[4.0, 5.0], &[40.0, 50.0]),
        ])
        .unwrap();
        let back = joined.backwards();
        assert_eq!(back.u(0), [3.0, 2.0, 1.0, 5.0, 4.0]);
        assert_eq!(back.y(), [30.0, 20.0, 10.0, 50.0, 40.0]);
        assert_eq!(back.boundaries, [3]);
        assert_eq!(
            (back.ts, &back.output.name),
            (Some(0.5), &joined.output.name)
        );
        assert_eq!(back.backwards(), joined);
    }

    #[test]
    fn rows_that_select_nothing_are_named_with_the_record_s_length() {
        let rows: RowRange = "120..".parse().unwrap();
        assert_eq!(rows.resolve(200).unwrap(), (120, 200));
        let e = rows.resolve(100).unwrap_err();
        assert!(matches!(e, DataError::NoRows { rows: r, available: 100 } if r == rows));
        assert_eq!(
            e.to_string(),
            "rows 120.. select no sample of a record with 100 rows"
        );
    }

    #[test]
    fn row_range_parses_open_bounds() {
        assert_eq!(
            "..5".parse::<RowRange>().unwrap(),
            RowRange {
                start: None,
                end: Some(5)
            }
        );
        assert_eq!(
            "5..".parse::<RowRange>().unwrap(),
            RowRange {
                start: Some(5),
                end: None
            }
        );
        assert_eq!("2..5".parse::<RowRange>().unwrap().to_string(), "2..5");
        assert!("5..2".parse::<RowRange>().is_err());
        assert!("x..2".parse::<RowRange>().is_err());
        assert!("7".parse::<RowRange>().is_err());
    }

    #[test]
    fn dataset_rejects_ragged_and_non_finite() {
        assert!(Dataset::siso(vec![1.0], vec![1.0, 2.0], None).is_err());
        assert!(Dataset::siso(vec![1.0, f64::NAN], vec![1.0, 2.0], None).is_err());
        assert!(Dataset::siso(vec![1.0, 2.0], vec![1.0, 2.0], Some(0.0)).is_err());
    }

    fn ramp(a: usize, b: usize, ts: Option<f64>) -> Dataset {
        let v: Vec<f64> = (a..b).map(|k| k as f64).collect();
        Dataset::siso(v.clone(), v, ts).unwrap()
    }

    #[test]
    fn joined_records_keep_their_boundaries_through_slices() {
        let d = Dataset::join(&[ramp(0, 4, None), ramp(4, 6, None), ramp(6, 9, None)]).unwrap();
        assert_eq!(d.y(), ramp(0, 9, None).y());
        assert_eq!(d.boundaries, [4, 6]);
        assert_eq!(d.record_ranges(), [0..4, 4..6, 6..9]);
        let parts = d.records();
        assert_eq!(parts[1], ramp(4, 6, None));
        assert_eq!(Dataset::join(&parts).unwrap(), d);
        let s = d.slice("5..8".parse().unwrap()).unwrap();
        assert_eq!((s.y(), &s.boundaries[..]), (&[5.0, 6.0, 7.0][..], &[1][..]));
        assert_eq!(d.slice("6..".parse().unwrap()).unwrap().record_count(), 1);
        let mut by_hand = d.clone();
        by_hand.boundaries = vec![6, 4, 9, 12];
        assert_eq!(by_hand.record_ranges(), [0..6, 6..9]);
    }

    #[test]
    fn records_of_other_signals_or_sampling_do_not_join() {
        let e = Dataset::join(&[ramp(0, 3, Some(0.1)), ramp(0, 3, Some(0.2))]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "record 2: sampling time 0.2 s differs from record 1's 0.1 s"
        );
        let e = Dataset::join(&[ramp(0, 3, Some(0.1)), ramp(0, 3, None)]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "record 2: no sampling time (no time signal, none given), record 1 0.1 s"
        );
        // A step read from a text time column (50.01 - 50.0) is the same.
        let rounded = Dataset::join(&[ramp(0, 3, Some(0.01)), ramp(0, 3, Some(50.01 - 50.0))]);
        assert_eq!(rounded.unwrap().ts, Some(0.01));
        // So is a piece of a record whose clock jitters, as the record's
        // own steps are (within 1 %); 2 % is another sampling time.
        let jitter = Dataset::join(&[ramp(0, 3, Some(0.01)), ramp(0, 3, Some(0.009_999_96))]);
        assert_eq!(jitter.unwrap().ts, Some(0.01));
        assert!(Dataset::join(&[ramp(0, 3, Some(0.01)), ramp(0, 3, Some(0.0102))]).is_err());
        let mut other = ramp(0, 3, None);
        other.output.name = "z".into();
        assert_eq!(
            Dataset::join(&[ramp(0, 3, None), other])
                .unwrap()
                .output
                .name,
            "y"
        );
        let two = Dataset::siso(vec![0.0; 3], vec![0.0; 3], None).unwrap();
        let two = Dataset::new(vec![two.inputs[0].clone(); 2], two.output, None);
        let e = Dataset::join(&[ramp(0, 3, None), two.unwrap()]).unwrap_err();
        assert_eq!(e.to_string(), "record 2: 2 input(s), record 1 1");
        assert!(Dataset::join(&[]).is_err());
    }
}
