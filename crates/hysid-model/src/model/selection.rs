//! How automatic selection chose a model's options: the candidates tried,
//! their scores on the selection rows and the choice, recorded in the model
//! file so that the choice can be checked and repeated.

use serde::{Deserialize, Serialize};

/// The record of an automatic selection (`hysid identify --auto`).
///
/// Every candidate was fitted on the fit rows of each split and scored by
/// the FIT of its free-run simulation on the split's selection rows; the
/// chosen one was then fitted again on all the identification rows, which
/// gave the model of the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Selection {
    /// The splits of the identification rows: one, or the folds of a
    /// rolling origin (a candidate's score is then the mean over them).
    pub splits: Vec<SplitRows>,
    /// Samples at the start of the selection rows left out of the score.
    pub warmup: usize,
    /// Every candidate, in the order tried.
    pub candidates: Vec<ScoredCandidate>,
    /// Index of the chosen candidate in `candidates`: the one with the
    /// fewest modes among those within one standard error of the best
    /// (the one-standard-error rule), or the next when its refit failed.
    pub chosen: usize,
    /// Index of the candidate of highest selection FIT.
    pub best: usize,
    /// Whether the simulation-error refinement was tried on the chosen
    /// candidate, and whether it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refinement: Option<RefinementChoice>,
}

/// The rows of one split, `A..B`, rows of the data file after decimation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SplitRows {
    /// Rows the candidates were fitted on.
    pub fit_rows: String,
    /// Rows the candidates were scored on.
    pub select_rows: String,
}

/// One candidate of a selection and its score.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScoredCandidate {
    /// Back-end that fitted it.
    pub method: String,
    /// `key = value` of the candidate (options, `modes`, `na`, `nb`).
    pub values: Vec<(String, String)>,
    /// Free-run simulation FIT on the selection rows, percent; `None`
    /// when the fit or the simulation failed.
    pub fit_sim: Option<f64>,
    /// Modes of the model fitted on the fit rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub modes: Option<usize>,
    /// Why the candidate has no score.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The simulation-error refinement of the chosen candidate, scored on the
/// selection rows like the candidates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefinementChoice {
    /// Selection-row FIT with the refinement, percent (`None`: it failed).
    pub fit_sim: Option<f64>,
    /// Whether the refinement was kept (it raised the selection-row FIT).
    pub kept: bool,
}
