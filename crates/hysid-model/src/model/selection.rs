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
    /// (the one-standard-error rule), or the next when its refit on all the
    /// identification rows failed or simulated them below the affine model.
    pub chosen: usize,
    /// Index of the candidate of highest selection FIT.
    pub best: usize,
    /// The refined forms of the chosen candidate's options (candidates
    /// whose values add `refine`), and which one is the choice. Older
    /// files list the refinements tried on the choice alone, at most one
    /// kept; a file may hold one object in place of the list.
    #[serde(
        default,
        deserialize_with = "one_or_many",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub refinement: Vec<RefinementChoice>,
    /// The starts of the written refit on all the identification rows:
    /// a seeded back-end's choice is fitted from several seeds and the fit
    /// that simulates those rows best is kept. Empty in files written
    /// before starts were recorded, and for a back-end the seed does not
    /// change (one refit).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub refit: Vec<RefitStart>,
    /// The time budget had run out when the selection ended: the fits
    /// after it stopped at their first check of it and refit starts after
    /// the first were left out, so the choice is among what the budget
    /// reached.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub cut_short: bool,
}

impl Selection {
    /// The refinement that was kept, if any.
    pub fn kept_refinement(&self) -> Option<&RefinementChoice> {
        self.refinement.iter().find(|r| r.kept)
    }

    /// The `key = value` pairs of the chosen candidate, with the kept
    /// refinement as `refine = ...` where the candidate does not name it
    /// (files in which refinements were tried on the choice only).
    pub fn chosen_values(&self) -> Vec<(String, String)> {
        let Some(chosen) = self.candidates.get(self.chosen) else {
            return Vec::new();
        };
        let mut values = chosen.values.clone();
        if let Some(r) = self.kept_refinement()
            && !values.iter().any(|(k, _)| k == "refine")
        {
            values.push(("refine".into(), r.refine.clone()));
        }
        values
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
    /// Why the candidate has no score, or why its refit on all the
    /// identification rows was not written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// A simulation-error refinement of the chosen candidate's options, scored
/// on the selection rows like the candidates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefinementChoice {
    /// The value of the back-end's `refine` option tried (`sim` when a
    /// file does not say).
    #[serde(default = "sim")]
    pub refine: String,
    /// Selection-row FIT with the refinement, percent (`None`: it failed).
    pub fit_sim: Option<f64>,
    /// Whether this refined form is the choice.
    pub kept: bool,
}

/// One start of the refit of the choice on all the identification rows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefitStart {
    /// Seed of the start: the run's seed for the first.
    pub seed: u64,
    /// Whether the start is the chosen candidate's own fit on the fit rows
    /// instead of a fresh fit: refined on all the identification rows when
    /// the choice is refined, as it was scored otherwise.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub from_candidate: bool,
    /// Free-run simulation FIT of the start's model on all the
    /// identification rows, percent; `None` when the fit failed or its
    /// simulation is not finite.
    pub fit_sim: Option<f64>,
    /// Whether the start's model diverges in a free run of the
    /// identification inputs played backwards: such a start is kept only
    /// when every start does.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub diverges_backwards: bool,
    /// Whether this start's model is the one written.
    pub kept: bool,
    /// Why the start has no model, when it failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

fn sim() -> String {
    "sim".into()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn selection(values: &[(&str, &str)], refinement: &[(&str, bool)]) -> Selection {
        Selection {
            splits: Vec::new(),
            warmup: 10,
            candidates: vec![ScoredCandidate {
                method: "cluster".into(),
                values: values.iter().map(|&(k, v)| (k.into(), v.into())).collect(),
                fit_sim: Some(80.0),
                modes: Some(3),
                error: None,
            }],
            chosen: 0,
            best: 0,
            refinement: refinement
                .iter()
                .map(|&(r, kept)| RefinementChoice {
                    refine: r.into(),
                    fit_sim: Some(81.0),
                    kept,
                })
                .collect(),
            refit: Vec::new(),
            cut_short: false,
        }
    }

    #[test]
    fn the_chosen_values_name_the_kept_refinement_once() {
        let pairs = |s: &Selection| -> Vec<String> {
            s.chosen_values()
                .into_iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect()
        };
        // A file whose refinement was tried on the choice alone.
        let old = selection(&[("c", "20")], &[("sim", false), ("sim_regions", true)]);
        assert_eq!(pairs(&old), ["c=20", "refine=sim_regions"]);
        // A refined candidate names its refinement itself.
        let new = selection(
            &[("c", "20"), ("refine", "sim_regions")],
            &[("sim", false), ("sim_regions", true)],
        );
        assert_eq!(pairs(&new), ["c=20", "refine=sim_regions"]);
        // Nothing kept: the candidate's own values.
        let none = selection(&[("c", "20")], &[("sim", false)]);
        assert_eq!(pairs(&none), ["c=20"]);
    }
}
