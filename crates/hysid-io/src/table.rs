//! Named columns as a reader returns them, and the selection that turns
//! them into a [`Dataset`]: columns by name, decimation, the time base,
//! the rows.

use hysid_model::data::{DEFAULT_TIME, DataError, DataSelection, Dataset, RowRange, Signal};
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

/// How far a time step may differ from the first, relative to it (clock
/// jitter and rounding pass; a missing or repeated sample does not).
const STEP_TOLERANCE: f64 = 0.01;

/// The first sample `k` whose step `t[k] - t[k - 1]` differs from `dt` by
/// more than [`STEP_TOLERANCE`] of it (the readers refuse non-finite
/// values, so every step compares).
fn uneven_step(t: &[f64], dt: f64) -> Option<usize> {
    (2..t.len()).find(|&k| (t[k] - t[k - 1] - dt).abs() > STEP_TOLERANCE * dt)
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
            let dt = t[1] - t[0];
            if !(dt.is_finite() && dt > 0.0) {
                return Err(DataError::Parse {
                    path: table.path.clone(),
                    location: format!("{} '{time}', row {}: ", table.what, sel.decimate + 1),
                    message: "time does not increase".into(),
                });
            }
            if let Some(k) = uneven_step(&t, dt) {
                return Err(DataError::Parse {
                    path: table.path.clone(),
                    location: format!("{} '{time}', row {}: ", table.what, k * sel.decimate + 1),
                    message: format!(
                        "the time step {} is not the first step {dt} (the samples must be \
                         equally spaced, within {} % of the step)",
                        t[k] - t[k - 1],
                        STEP_TOLERANCE * 100.0
                    ),
                });
            }
            let off = sel.ts.map(|given| (given - dt).abs());
            if let Some(given) = sel.ts
                && off.is_some_and(|off| off.is_nan() || off > STEP_TOLERANCE * dt)
            {
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
    let ds = Dataset::new(inputs, output, ts)?;
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
