//! Ground-truth modes of simulated records (`[data] truth = "mode"`): a
//! text column of a CSV data file naming the true mode of every sample
//! (what `hysid simulate` writes), scored against the mode sequence of each
//! run's validation simulation. Identified modes are matched to true modes
//! by the Hungarian method (`hysid_model::metrics::mode_accuracy`); the
//! report gives the overall accuracy and, per true mode, the fraction of its
//! samples simulated in the matched mode (its recall).

use hysid_model::data::{DataError, RowRange};
use hysid_model::metrics::{MatchError, mode_accuracy};
use hysid_model::simulate::Simulation;
use serde::Serialize;
use std::path::Path;

/// The true mode of every validation sample (`None` where the cell is empty).
#[derive(Debug, Clone, PartialEq)]
pub struct TrueModes {
    /// Mode names, in order of first appearance in the whole file.
    pub names: Vec<String>,
    /// Per validation sample, an index into `names`.
    pub labels: Vec<Option<usize>>,
}

/// How well a run's simulated modes follow the true ones.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModeRecovery {
    /// Samples scored (labelled, simulated, after the warm-up).
    pub samples: usize,
    /// Fraction of them in the matched mode.
    pub accuracy: f64,
    /// Per true mode: its name, its number of samples and the fraction
    /// simulated in the identified mode matched to it (0 when unmatched).
    pub recall: Vec<(String, usize, f64)>,
}

/// Reads the column `column` of the CSV file `path`, decimated by
/// `decimate` and restricted to `rows` exactly as the data selection is.
pub fn load(
    path: &Path,
    column: &str,
    decimate: usize,
    rows: RowRange,
) -> Result<TrueModes, TruthError> {
    let file = || path.display().to_string();
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|source| TruthError::Csv {
            file: file(),
            source,
        })?;
    let headers = reader
        .headers()
        .map_err(|source| TruthError::Csv {
            file: file(),
            source,
        })?
        .clone();
    let col = headers
        .iter()
        .position(|h| h == column)
        .ok_or_else(|| TruthError::NoColumn {
            file: file(),
            column: column.to_string(),
            columns: headers.iter().map(str::to_string).collect(),
        })?;
    let mut names: Vec<String> = Vec::new();
    let mut all: Vec<Option<usize>> = Vec::new();
    for (i, rec) in reader.records().enumerate() {
        let rec = rec.map_err(|source| TruthError::Row {
            file: file(),
            row: i + 2,
            source,
        })?;
        let cell = rec.get(col).unwrap_or("");
        all.push(if cell.is_empty() {
            None
        } else {
            Some(match names.iter().position(|n| n == cell) {
                Some(q) => q,
                None => {
                    names.push(cell.to_string());
                    names.len() - 1
                }
            })
        });
    }
    let picked: Vec<Option<usize>> = all.into_iter().step_by(decimate.max(1)).collect();
    let (a, b) = rows
        .resolve(picked.len())
        .map_err(|source| TruthError::Rows {
            file: file(),
            source,
        })?;
    Ok(TrueModes {
        names,
        labels: picked[a..b].to_vec(),
    })
}

/// Why the true modes could not be read; every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    /// The file or its header could not be read.
    #[error("{file}: {source}")]
    Csv {
        /// The data file.
        file: String,
        /// Cause.
        source: csv::Error,
    },
    /// No column of that name.
    #[error("{file}: [data] truth = '{column}': no such column (columns: {})", .columns.join(", "))]
    NoColumn {
        /// The data file.
        file: String,
        /// The column asked for.
        column: String,
        /// The columns of the file.
        columns: Vec<String>,
    },
    /// A malformed row (numbered as in the file, the header being row 1).
    #[error("{file}: row {row}: {source}")]
    Row {
        /// The data file.
        file: String,
        /// Row number.
        row: usize,
        /// Cause.
        source: csv::Error,
    },
    /// The validation rows do not fit the column.
    #[error("{file}: [data] truth: {source}")]
    Rows {
        /// The data file.
        file: String,
        /// Cause.
        source: DataError,
    },
}

impl TrueModes {
    /// Scores the simulated modes of `sim` (same samples as `labels`) from
    /// sample `warmup` on.
    /// An error when the simulated modes cannot be matched to the true ones.
    pub fn score(
        &self,
        sim: &Simulation,
        warmup: usize,
    ) -> Result<Option<ModeRecovery>, MatchError> {
        let (truth, found): (Vec<usize>, Vec<usize>) = self
            .labels
            .iter()
            .zip(&sim.modes)
            .skip(warmup.max(sim.start))
            .filter_map(|(t, q)| Some(((*t)?, (*q)?)))
            .unzip();
        if truth.is_empty() {
            return Ok(None);
        }
        let matched = mode_accuracy(&truth, &found)?;
        let recall = self
            .names
            .iter()
            .enumerate()
            .filter_map(|(t, name)| {
                let n_t = truth.iter().filter(|&&x| x == t).count();
                if n_t == 0 {
                    return None;
                }
                let hit = matched
                    .pairs
                    .iter()
                    .find(|&&(pt, _)| pt == t)
                    .map_or(0, |&(_, q)| {
                        truth
                            .iter()
                            .zip(&found)
                            .filter(|&(&x, &y)| x == t && y == q)
                            .count()
                    });
                Some((name.clone(), n_t, hit as f64 / n_t as f64))
            })
            .collect();
        Ok(Some(ModeRecovery {
            samples: truth.len(),
            accuracy: matched.accuracy,
            recall,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_follow_the_selection_and_score_by_matching() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("d.csv");
        std::fs::write(
            &f,
            "u,y,mode\n0,0,\n0,0,free\n0,0,free\n0,0,stop\n0,0,stop\n0,0,free\n",
        )
        .unwrap();
        let t = load(
            &f,
            "mode",
            1,
            RowRange {
                start: Some(1),
                end: None,
            },
        )
        .unwrap();
        assert_eq!(t.names, ["free", "stop"]);
        assert_eq!(t.labels, [Some(0), Some(0), Some(1), Some(1), Some(0)]);
        let sim = Simulation {
            y: vec![0.0; 5],
            modes: vec![None, Some(4), Some(7), Some(7), Some(7)],
            start: 1,
            covered: vec![true; 5],
            diverged_at: None,
            diverged_to: None,
            zeno: None,
        };
        let r = t.score(&sim, 0).unwrap().unwrap();
        assert_eq!(r.samples, 4);
        assert!((r.accuracy - 0.75).abs() < 1e-12, "{r:?}");
        assert_eq!(r.recall[0], ("free".into(), 2, 0.5));
        assert_eq!(r.recall[1], ("stop".into(), 2, 1.0));
        let e = load(&f, "truth", 1, RowRange::default()).unwrap_err();
        assert!(matches!(e, TruthError::NoColumn { .. }), "{e}");
        let e = e.to_string();
        assert!(e.contains("truth") && e.contains("mode"), "{e}");
        // Decimation keeps every second row, as the data selection does.
        let t2 = load(&f, "mode", 2, RowRange::default()).unwrap();
        assert_eq!(t2.labels, [None, Some(0), Some(1)]);
    }
}
