//! Named columns as a reader returns them, and the selection that turns
//! them into a [`Dataset`]: columns by name, decimation, the time base,
//! the rows.

use hysid_model::data::{
    DEFAULT_TIME, DataError, DataSelection, Dataset, RowRange, Signal, TS_TOLERANCE,
};
use std::path::PathBuf;

/// How many of a file's names an error about a missing one lists.
const AVAILABLE_LISTED: usize = 20;

/// Named columns as read from a file, before selection.
pub(crate) struct RawTable {
    pub(crate) path: PathBuf,
    pub(crate) what: &'static str,
    /// The columns read: those asked for that the file has.
    pub(crate) columns: Vec<(String, Vec<f64>)>,
    /// Every name of the file, for an error about a missing one.
    pub(crate) available: Available,
}

/// The names of a file's columns as an error lists them: the first
/// [`AVAILABLE_LISTED`] and how many there are.
pub(crate) struct Available {
    first: Vec<String>,
    count: usize,
}

impl Available {
    /// `names`, all of them, in file order.
    pub(crate) fn of<'a>(names: impl ExactSizeIterator<Item = &'a str>) -> Self {
        let count = names.len();
        Available {
            // Escaped, so that a stray byte-order mark or control character
            // in a header is visible in the message.
            first: names
                .take(AVAILABLE_LISTED)
                .map(|n| n.escape_debug().to_string())
                .collect(),
            count,
        }
    }
}

impl std::fmt::Display for Available {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.first.join(", "))?;
        match self.count - self.first.len() {
            0 => Ok(()),
            more => write!(f, ", and {more} more"),
        }
    }
}

impl RawTable {
    fn take(&self, name: &str) -> Result<&[f64], DataError> {
        self.columns
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
            .ok_or_else(|| DataError::Missing {
                path: self.path.clone(),
                what: self.what,
                name: name.to_string(),
                available: self.available.to_string(),
            })
    }

    fn has(&self, name: &str) -> bool {
        self.columns.iter().any(|(n, _)| n == name)
    }
}

/// Names the readers keep: the selected inputs, the output and the time.
pub(crate) fn wanted_names(sel: &DataSelection) -> Vec<&str> {
    sel.inputs
        .iter()
        .map(String::as_str)
        .chain([sel.output.as_str(), sel.time.as_str()])
        .collect()
}

/// Why a time column gives no sampling time; [`TimeStepError::sample`] is
/// the index of the sample whose step is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TimeStepError {
    /// Fewer than two times: no step.
    #[error("{0} sample(s); its first step is the sampling time")]
    TooShort(usize),
    /// The first step is not a positive number.
    #[error("time does not increase")]
    NotIncreasing,
    /// A later step differs from the first by more than [`TS_TOLERANCE`]
    /// of it.
    #[error(
        "the time step {step} is not the first step {first} (the samples must be equally \
         spaced, within {} % of the step)",
        TS_TOLERANCE * 100.0
    )]
    Uneven {
        /// The sample the step leads to.
        sample: usize,
        /// That step.
        step: f64,
        /// The first step.
        first: f64,
    },
}

impl TimeStepError {
    /// The index of the sample whose step is wrong.
    pub fn sample(&self) -> usize {
        match self {
            TimeStepError::TooShort(_) => 0,
            TimeStepError::NotIncreasing => 1,
            TimeStepError::Uneven { sample, .. } => *sample,
        }
    }
}

/// The sampling time of the times `t`: their first step, positive, every
/// other step within [`TS_TOLERANCE`] of it (a step that is not a number
/// is not within it). The readers' time columns and Python's take it from
/// here.
pub fn sampling_time(t: &[f64]) -> Result<f64, TimeStepError> {
    let [t0, t1, ..] = t[..] else {
        return Err(TimeStepError::TooShort(t.len()));
    };
    let dt = t1 - t0;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(TimeStepError::NotIncreasing);
    }
    let off = |k: usize| (t[k] - t[k - 1] - dt).abs();
    match (2..t.len()).find(|&k| off(k).is_nan() || off(k) > TS_TOLERANCE * dt) {
        Some(k) => Err(TimeStepError::Uneven {
            sample: k,
            step: t[k] - t[k - 1],
            first: dt,
        }),
        None => Ok(dt),
    }
}

pub(crate) fn select(table: &RawTable, sel: &DataSelection) -> Result<Dataset, DataError> {
    let pick = |v: &[f64]| -> Vec<f64> { v.iter().step_by(sel.decimate).copied().collect() };
    let output = Signal {
        name: sel.output.clone(),
        values: pick(table.take(&sel.output)?),
    };
    let mut inputs = Vec::with_capacity(sel.inputs.len());
    for name in &sel.inputs {
        inputs.push(Signal {
            name: name.clone(),
            values: pick(table.take(name)?),
        });
    }
    let time = sel.time.as_str();
    if time != DEFAULT_TIME {
        // A time column named by the user must exist (the error lists the
        // file's names) and be neither an input nor the output.
        table.take(time)?;
        if sel.inputs.iter().any(|n| n == time) || sel.output == time {
            return Err(DataError::Parse {
                path: table.path.clone(),
                location: format!("{} '{time}': ", table.what),
                message: "named as the time and as a signal; the time must be another column"
                    .into(),
            });
        }
    }
    let ts = if table.has(time) && !sel.inputs.iter().any(|n| n == time) && sel.output != time {
        let t = pick(table.take(time)?);
        if t.len() >= 2 {
            let dt = sampling_time(&t).map_err(|e| DataError::Parse {
                path: table.path.clone(),
                location: format!(
                    "{} '{time}', row {}: ",
                    table.what,
                    e.sample() * sel.decimate + 1
                ),
                message: e.to_string(),
            })?;
            let differs = |given: &f64| {
                let off = (given - dt).abs();
                off.is_nan() || off > TS_TOLERANCE * dt
            };
            if let Some(given) = sel.ts.filter(differs) {
                return Err(DataError::Parse {
                    path: table.path.clone(),
                    location: format!("{} '{time}': ", table.what),
                    message: format!(
                        "its step {dt} (after decimation by {}) is the sampling time, and the \
                         ts given ({given}) differs; ts is given for files without a time column",
                        sel.decimate
                    ),
                });
            }
            Some(dt)
        } else {
            sel.ts
        }
    } else {
        sel.ts
    };
    // Signals of other lengths (a MAT variable of another size) name the
    // file.
    let ds = Dataset::new(inputs, output, ts).map_err(|e| match e {
        DataError::Shape(message) => DataError::Parse {
            path: table.path.clone(),
            location: String::new(),
            message,
        },
        other => other,
    })?;
    let n = ds.len();
    let rows_error = |beyond| DataError::Rows {
        path: table.path.clone(),
        rows: sel.rows,
        available: n,
        decimate: sel.decimate,
        beyond,
    };
    if sel.rows.end.is_some_and(|end| end > n) {
        return Err(rows_error(true));
    }
    let (a, b) = sel.rows.resolve(n).map_err(|_| rows_error(false))?;
    ds.slice(RowRange {
        start: Some(a),
        end: Some(b),
    })
}

#[cfg(test)]
mod tests {
    use super::{TimeStepError, sampling_time};

    #[test]
    fn the_sampling_time_is_the_first_step_of_equally_spaced_times() {
        assert_eq!(sampling_time(&[0.0, 0.5, 1.004, 1.5]), Ok(0.5));
        assert_eq!(sampling_time(&[1.0]), Err(TimeStepError::TooShort(1)));
        assert_eq!(
            sampling_time(&[1.0, 1.0]),
            Err(TimeStepError::NotIncreasing)
        );
        let uneven = sampling_time(&[0.0, 0.5, 1.0, 2.0]).unwrap_err();
        assert_eq!(uneven.sample(), 3);
        assert_eq!(
            uneven.to_string(),
            "the time step 1 is not the first step 0.5 (the samples must be equally spaced, within 1 % of the step)"
        );
        // A time that is not a number is not within the tolerance.
        assert_eq!(
            sampling_time(&[0.0, 0.5, f64::NAN]).unwrap_err().sample(),
            2
        );
    }
}
