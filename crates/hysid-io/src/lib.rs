//! # hysid-io
//!
//! Files in and out: CSV and MAT records read into a [`Dataset`] with the
//! selection rules of `docs/file-formats.md` (columns or variables by name,
//! `decimate` keeps samples `0, K, 2K, ...` without a filter, `rows` applies
//! after decimation, the sampling time comes from a `t` signal when there is
//! one), and atomic output of models and reports.

mod atomic;
mod csv_reader;
mod mat_reader;
mod table;

pub use atomic::write;
pub use mat_reader::inside_guarded_parser;
pub use table::{TimeStepError, sampling_time};

use hysid_core::model::{Model, ModelError};
use hysid_model::data::{DataError, DataSelection, Dataset, RowRange};
use std::path::{Path, PathBuf};
use table::{select, wanted_names};

/// Writes `model` atomically (temporary file then rename): TOML to a
/// `.toml` path, as [`Model::load`] reads it back, JSON to any other.
pub fn save_model(model: &Model, path: &Path) -> Result<(), ModelError> {
    let toml = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let text = if toml {
        model.to_toml().ok_or_else(|| ModelError::Format {
            path: path.display().to_string(),
            message: format!(
                "a '{}' model that TOML cannot hold; write .json",
                model.kind()
            ),
        })?
    } else {
        model.to_json()
    };
    atomic::write(path, text.as_bytes()).map_err(|source| ModelError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Reads every record, a file with its selection, and joins them in order
/// into one dataset ([`Dataset::join`]); a record that cannot be joined to
/// the first is [`DataError::NotJoined`], naming its file. One record
/// goes through the same checks (it holds a sample).
pub fn load_records(records: &[(&Path, DataSelection)]) -> Result<Dataset, DataError> {
    load_each(records).map_err(|e| e.source)
}

/// Why [`load_each`] could not read or join its records.
#[derive(Debug, thiserror::Error)]
#[error("{source}")]
pub struct RecordError {
    /// The record at fault (from 0), where one is.
    pub record: Option<usize>,
    /// What is wrong.
    pub source: DataError,
}

/// What names the file at `path` whichever way it is written: its
/// canonical path where it exists (`data.csv`, `./data.csv` and
/// `dir/../data.csv` alike), else the path as given.
pub fn file_identity(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

/// [`load_records`], its error with the record at fault, for a caller
/// that names records otherwise than by their file (several records of
/// one file).
pub fn load_each(records: &[(&Path, DataSelection)]) -> Result<Dataset, RecordError> {
    // The same file read again with the same signals over rows that overlap
    // counts those rows twice.
    let files: Vec<_> = records.iter().map(|(p, _)| file_identity(p)).collect();
    let rows_apart = |a: &DataSelection, b: &DataSelection| {
        let (a_rows, b_rows) = (a.rows, b.rows);
        let signals = |s: &DataSelection| DataSelection {
            rows: RowRange::default(),
            ..s.clone()
        };
        signals(a) != signals(b) || !a_rows.overlaps(&b_rows)
    };
    for (i, (path, sel)) in records.iter().enumerate() {
        let same = |j: &usize| files[*j] == files[i] && !rows_apart(&records[*j].1, sel);
        if let Some(first) = (0..i).find(same) {
            return Err(RecordError {
                record: Some(i),
                source: DataError::RecordTwice {
                    path: path.to_path_buf(),
                    first: first + 1,
                    second: i + 1,
                },
            });
        }
    }
    let read = (records.iter().enumerate())
        .map(|(i, (path, sel))| {
            load(path, sel).map_err(|source| RecordError {
                record: Some(i),
                source,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Dataset::join(&read).map_err(|e| match e {
        DataError::Join { record, reason } => RecordError {
            record: Some(record - 1),
            source: DataError::NotJoined {
                path: records[record - 1].0.to_path_buf(),
                reason,
            },
        },
        source => RecordError {
            record: None,
            source,
        },
    })
}

/// Reads a `.csv` or `.mat` file and applies `sel`.
pub fn load(path: &Path, sel: &DataSelection) -> Result<Dataset, DataError> {
    if sel.decimate == 0 {
        return Err(DataError::Selection("--decimate must be at least 1".into()));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let wanted = wanted_names(sel);
    let table = match ext.as_deref() {
        Some("csv") => csv_reader::read(path, &wanted)?,
        Some("mat") => mat_reader::read(path, &wanted)?,
        _ => return Err(DataError::UnsupportedFormat(path.to_path_buf())),
    };
    select(&table, sel)
}

/// The format of a record handed over as bytes (see [`load_bytes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataFormat {
    /// Comma-separated values with a header row.
    Csv,
    /// MATLAB level-5 MAT-file.
    Mat,
}

/// Reads a record already in memory and applies `sel`, exactly as [`load`]
/// does for a file; `origin` only names the source in error messages.
/// This is the entry point of the fuzz targets (`fuzz/`).
pub fn load_bytes(
    bytes: &[u8],
    format: DataFormat,
    origin: &Path,
    sel: &DataSelection,
) -> Result<Dataset, DataError> {
    if sel.decimate == 0 {
        return Err(DataError::Selection("--decimate must be at least 1".into()));
    }
    let wanted = wanted_names(sel);
    let table = match format {
        DataFormat::Csv => csv_reader::read_from(bytes, origin, &wanted)?,
        DataFormat::Mat => mat_reader::read_bytes(bytes, origin, &wanted)?,
    };
    select(&table, sel)
}

#[cfg(test)]
mod tests {
    use super::save_model;
    use hysid_core::model::Model;

    /// A model saved under any name reads back as the same model: TOML
    /// under `.toml` in any case, JSON under every other name (`.JSON`,
    /// `.txt`, none).
    #[test]
    fn a_model_saved_under_any_name_reads_back() {
        let text = r#"{"kind": "pwarx", "na": 1, "nb": 1, "inputs": 1,
            "modes": [{"theta": [0.5, 1.0, 0.0]}]}"#;
        let model = Model::from_json(text, "m.json").unwrap();
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "m.json", "m.JSON", "m.Json", "m.toml", "m.TOML", "m.txt", "m",
        ] {
            let path = dir.path().join(name);
            save_model(&model, &path).unwrap();
            let written = std::fs::read_to_string(&path).unwrap();
            let toml = name.to_lowercase().ends_with(".toml");
            assert_eq!(written.starts_with('{'), !toml, "{name}");
            let back = Model::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(back.to_json(), model.to_json(), "{name}");
        }
    }
}
