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
    /// The splits of the identification rows: one, the two ends of a short
    /// record, or the folds of a rolling origin (a candidate's score is
    /// then the mean over them).
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
    /// The simulation-error refinements tried on the chosen candidate, in
    /// order, and which one was kept (at most one). A file may hold one
    /// object in place of the list.
    #[serde(
        default,
        deserialize_with = "one_or_many",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub refinement: Vec<RefinementChoice>,
}

impl Selection {
    /// The refinement that was kept, if any.
    pub fn kept_refinement(&self) -> Option<&RefinementChoice> {
        self.refinement.iter().find(|r| r.kept)
    }
}

/// A list, or a single object read as a list of one.
fn one_or_many<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<RefinementChoice>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum OneOrMany {
        One(RefinementChoice),
        Many(Vec<RefinementChoice>),
    }
    Ok(match OneOrMany::deserialize(d)? {
        OneOrMany::One(r) => vec![r],
        OneOrMany::Many(v) => v,
    })
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
    /// The value of the back-end's `refine` option tried (`sim` when a
    /// file does not say).
    #[serde(default = "sim")]
    pub refine: String,
    /// Selection-row FIT with the refinement, percent (`None`: it failed).
    pub fit_sim: Option<f64>,
    /// Whether the refinement was kept: of those tried, it had the highest
    /// selection-row FIT, above the unrefined candidate's.
    pub kept: bool,
}

fn sim() -> String {
    "sim".into()
}
