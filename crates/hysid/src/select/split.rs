//! The fit and selection rows of a selection: one split of the
//! identification rows (at their end, or at both ends of a short record),
//! whole records held out, or contiguous folds on a rolling origin.

use super::{DEFAULT_SELECTION_PERCENT, Plan, SelectError};
use hysid_estimation::parsimony;
use hysid_model::data::{DataError, Dataset, RowRange};
use hysid_model::metrics;

/// Fit rows and selection rows, as half-open ranges of the identification
/// record.
pub type Split = ((usize, usize), (usize, usize));

/// The splits of an identification record of `n` rows that `plan` asks
/// for: one ([`split`]), the two ends of a short record ([`both_ends`]),
/// or the rolling-origin folds ([`folds`]).
///
/// Splits whose scored selection rows hold a constant output are refused:
/// every candidate's FIT there is 0 (100 for an exact match), so it cannot
/// rank them.
pub fn splits(data: &Dataset, plan: &Plan) -> Result<Vec<Split>, SelectError> {
    let n = data.len();
    let out = if let Some(k) = plan.select_records {
        vec![record_split(data, k, plan)?]
    } else {
        match plan.folds {
            Some(k) => folds(n, k, plan.warmup)?,
            None if plan.select.is_none() => both_ends(n, split(n, plan)?),
            None => vec![split(n, plan)?],
        }
    };
    match (out.iter()).position(|&(_, rows)| constant_output(data, rows, plan.warmup)) {
        None => Ok(out),
        Some(i) => {
            let (_, (a, b)) = out[i];
            // Of a short record's two ends, the first is the start block.
            let start_block =
                plan.select_records.is_none() && plan.folds.is_none() && i + 1 < out.len();
            let reason = format!(
                "the output is constant on rows {}..{}{} after the warm-up, so FIT cannot rank the candidates there",
                a + plan.first_row,
                b + plan.first_row,
                if start_block {
                    " (the block at the start, scored as well on a record this short)"
                } else {
                    ""
                }
            );
            Err(match (plan.select_records, plan.folds) {
                (Some(records), _) => SelectError::Records { records, reason },
                (None, Some(folds)) => SelectError::Folds { folds, reason },
                (None, None) => SelectError::Rows {
                    rows: selection_rows(n, plan).to_string(),
                    reason,
                },
            })
        }
    }
}

/// Whether the output of `data` is constant on the selection rows `a..b`
/// as they are scored: each record's share without its first `warmup`
/// samples ([`metrics::fit_undefined`]). Rows that leave nothing to score
/// are not constant: their shortness is said where they are simulated.
fn constant_output(data: &Dataset, (a, b): (usize, usize), warmup: usize) -> bool {
    let y = data.y();
    let scored: Vec<&[f64]> = (data.record_ranges().iter())
        .map(|r| (a.max(r.start) + warmup).min(b.min(r.end))..b.min(r.end))
        .filter(|r| !r.is_empty())
        .map(|r| &y[r])
        .collect();
    !scored.is_empty() && metrics::fit_undefined(&scored)
}

/// The fit rows and selection rows when the last `k` records of `data`
/// are held out for selection.
pub fn record_split(data: &Dataset, k: usize, plan: &Plan) -> Result<Split, SelectError> {
    let bad = |reason: String| SelectError::Records { records: k, reason };
    if plan.select.is_some() || plan.folds.is_some() {
        return Err(bad(
            "selection rows and folds are not taken beside it".into()
        ));
    }
    let ranges = data.record_ranges();
    let count = ranges.len();
    if count < 2 {
        return Err(bad("holding out records needs two or more records".into()));
    }
    if k == 0 || k >= count {
        return Err(bad(format!(
            "must be between 1 and the number of records less one ({})",
            count - 1
        )));
    }
    let a = ranges[count - k].start;
    Ok(((0, a), (a, data.len())))
}

/// Default selection blocks shorter than this are joined by the block of
/// the same length at the record's start: two blocks of the
/// one-standard-error rule ([`parsimony::BLOCK`]), below which that rule
/// cannot act and a score rests on a few samples.
pub const SHORT_SELECTION: usize = 2 * parsimony::BLOCK;

/// The default split `last` (the selection block at the end), and, when
/// that block is shorter than [`SHORT_SELECTION`], first the split with a
/// block of the same length at the start of the record (fitted on the rows
/// after it): on a record of tens of rows the candidates are then scored
/// on twice the rows, and both fit-row sets are contiguous records.
pub fn both_ends(n: usize, last: Split) -> Vec<Split> {
    let (_, (a, b)) = last;
    let len = b - a;
    if len >= SHORT_SELECTION {
        return vec![last];
    }
    vec![((len, n), (0, len)), last]
}

/// `k` contiguous blocks of an `n`-row record: fold `j` (1 to `k - 1`)
/// fits on the blocks before block `j` and is scored on block `j` (a
/// rolling origin, as time series are cross-validated: the fit rows always
/// precede the rows they are scored on).
pub fn folds(n: usize, k: usize, warmup: usize) -> Result<Vec<Split>, SelectError> {
    let bad = |reason: String| SelectError::Folds { folds: k, reason };
    if k < 2 {
        return Err(bad("at least 2 folds are needed".into()));
    }
    let edge = |j: usize| j * n / k;
    if edge(1) <= warmup {
        return Err(bad(format!(
            "blocks of {} rows leave nothing to score after a warm-up of {warmup}",
            edge(1)
        )));
    }
    Ok((1..k)
        .map(|j| ((0, edge(j)), (edge(j), edge(j + 1))))
        .collect())
}

/// The selection rows `plan` gives, in rows of the file: its own, else
/// the last [`DEFAULT_SELECTION_PERCENT`] % of the `n` identification rows.
fn selection_rows(n: usize, plan: &Plan) -> RowRange {
    plan.select.unwrap_or(RowRange {
        start: Some(plan.first_row + n - n * DEFAULT_SELECTION_PERCENT / 100),
        end: None,
    })
}

/// The fit rows and the selection rows of an identification record of `n`
/// rows, as half-open ranges of the record. `plan.select` counts rows of
/// the file (the record starts at `plan.first_row`); the selection rows
/// must start or end the record, so that the fit rows are one contiguous
/// record.
pub fn split(n: usize, plan: &Plan) -> Result<Split, SelectError> {
    let first = plan.first_row;
    let given = selection_rows(n, plan);
    let bad = |reason: String| SelectError::Rows {
        rows: given.to_string(),
        reason,
    };
    let in_record = |v: Option<usize>| {
        v.map(|v| {
            v.checked_sub(first)
                .ok_or_else(|| bad(format!("before the first identification row {first}")))
        })
        .transpose()
    };
    let rows = RowRange {
        start: in_record(given.start)?,
        end: in_record(given.end)?,
    };
    if rows.end.is_some_and(|e| e > n) {
        return Err(bad(format!(
            "end beyond the last identification row {}",
            first + n - 1
        )));
    }
    let (a, b) = rows.resolve(n).map_err(|e: DataError| bad(e.to_string()))?;
    let fit = match (a, b) {
        (0, b) if b < n => (b, n),
        (a, b) if b == n && a > 0 => (0, a),
        _ => {
            return Err(bad(format!(
                "must start or end the {n} identification rows and leave some of them to fit on"
            )));
        }
    };
    if b - a <= plan.warmup {
        return Err(bad(format!(
            "{} rows leave nothing to score after a warm-up of {}",
            b - a,
            plan.warmup
        )));
    }
    Ok((fit, (a, b)))
}
