//! What a back-end reports about its run, recorded in the model file under
//! `info.diagnostics`: the fields every back-end shares, under fixed names,
//! and the back-end's own fields.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunStatus {
    /// Every stage ran to its own end (convergence test or planned count).
    #[default]
    Completed,
    /// An iterative stage stopped at its iteration bound before its
    /// convergence test held; the result may not be converged.
    IterationLimit,
    /// The time budget (`--time-budget`) stopped the run; the model is the
    /// best found by then.
    TimeBudget,
}

impl RunStatus {
    /// Whether the run was cut short (by a bound or the time budget).
    pub fn cut_short(self) -> bool {
        self != RunStatus::Completed
    }
}

/// How the simulation-error refinement of a PWARX fit ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RefinementStatus {
    /// A convergence test of the Levenberg-Marquardt descent held (the
    /// relative decrease of the cost, the gradient or the step; see
    /// `docs/refinement.md`), or the cost reached zero.
    Converged,
    /// No step of any damping decreased the cost: a local minimum to the
    /// precision of the linearisation.
    NoDescent,
    /// The iteration bound stopped the refinement before its convergence
    /// test held.
    IterationLimit,
    /// The run's time budget stopped the refinement first.
    TimeBudget,
    /// The simulation of the starting parameters diverges: nothing was
    /// refined.
    Diverged,
}

/// The outcome of the multiple-shooting simulation-error refinement of the
/// mode parameters (recorded under `refinement`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Refinement {
    /// Samples per shooting segment.
    pub segment: usize,
    /// Shooting segments of the record.
    pub segments: usize,
    /// Levenberg-Marquardt iterations taken (solved steps, accepted or not).
    pub iterations: usize,
    /// The iteration bound.
    pub max_iterations: usize,
    /// Sum of squared simulation errors of the starting parameters (`None`:
    /// the simulation diverges).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cost_before: Option<f64>,
    /// Sum of squared simulation errors of the refined parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cost_after: Option<f64>,
    /// How the refinement ended.
    pub status: RefinementStatus,
    /// The second stage, moving the region boundaries (`refine =
    /// sim_regions`), when it was asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regions: Option<RegionRefinement>,
}

/// What became of the region-moving stage of the refinement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionRefinementStatus {
    /// The moved regions lowered the simulation error: they are the
    /// model's.
    Moved,
    /// No hardened relaxation lowered the simulation error: the regions
    /// are the back-end's.
    NoGain,
    /// One ordinary mode: there is no boundary to move.
    OneMode,
    /// Known stops: the relaxation covers PWARX models without stops only.
    WithStops,
    /// The regions are not the argmax partition of affine scores (the
    /// `psvc` regions, or a partition with holes).
    NotArgmax,
    /// The simulation of the back-end's model diverges.
    Diverged,
}

/// The outcome of moving the region boundaries by a softmax relaxation of
/// the simulation error (recorded under `refinement.regions`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionRefinement {
    /// What became of it.
    pub status: RegionRefinementStatus,
    /// Levenberg-Marquardt iterations of the relaxed gate, over all
    /// sharpness levels.
    pub gate_iterations: usize,
    /// Descents of the relaxed gate (one per sharpness level and round).
    #[serde(default)]
    pub gate_descents: usize,
    /// Of [`Self::gate_descents`], those that ended at their iteration
    /// bound (`refine_iterations`) before a convergence test held.
    #[serde(default)]
    pub gate_descents_at_bound: usize,
    /// Levenberg-Marquardt iterations of the mode parameters under the
    /// hardened regions.
    pub parameter_iterations: usize,
    /// The sharpness whose hardened gate was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sharpness: Option<f64>,
    /// Sum of squared simulation errors with the back-end's regions (after
    /// the first stage).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cost_before: Option<f64>,
    /// Sum of squared simulation errors with the moved regions and their
    /// refined parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cost_after: Option<f64>,
    /// Identification samples whose region changed.
    pub moved_samples: usize,
}

impl RegionRefinement {
    /// A stage that did not run, for `status`.
    pub fn skipped(status: RegionRefinementStatus) -> Self {
        Self {
            status,
            gate_iterations: 0,
            gate_descents: 0,
            gate_descents_at_bound: 0,
            parameter_iterations: 0,
            sharpness: None,
            cost_before: None,
            cost_after: None,
            moved_samples: 0,
        }
    }
}

/// How the trimmed re-estimation of the mode parameters ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrimmingStatus {
    /// The samples left out no longer changed from one round to the next.
    Converged,
    /// The round bound stopped the re-estimation before that.
    RoundLimit,
    /// A mode kept fewer samples than it has parameters: the parameters
    /// are those of the last round that had enough (the back-end's, when
    /// the first round had not).
    TooFewSamples,
}

/// The outcome of the trimmed re-estimation of the mode parameters on the
/// samples of their regions (recorded under `trimming`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trimming {
    /// Residuals beyond this many robust standard deviations of their
    /// mode were left out (option `trim`).
    pub cutoff: f64,
    /// Least-squares rounds run.
    pub rounds: usize,
    /// Samples of each ordinary mode's region left out of its last
    /// estimate.
    pub left_out: Vec<usize>,
    /// How it ended.
    pub status: TrimmingStatus,
}

/// The diagnostics of a run. The common fields have fixed names in every
/// back-end; `method` holds the back-end's own fields (its typed
/// diagnostics struct, serialised). In the file all keys form one object,
/// in alphabetical order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Diagnostics {
    /// How the run ended (`run_status`).
    pub run_status: RunStatus,
    /// Messages for the user: why the run was cut short, warnings
    /// (`status`, joined by "; ").
    pub status: Vec<String>,
    /// Regression rows (samples) the back-end was given (`samples`).
    pub samples: Option<usize>,
    /// Modes of the model, saturation modes included (`modes`).
    pub modes: Option<usize>,
    /// Whether the regions cover the whole regressor space
    /// (`regions_complete`); `false` means the partition leaves holes.
    pub regions_complete: Option<bool>,
    /// Fraction of the identification regressors' bounding box in no region,
    /// when the partition is incomplete (`uncovered_fraction_of_data_box`).
    pub uncovered_fraction_of_data_box: Option<f64>,
    /// Rows whose target sits at each known stop, in prior order
    /// (`saturated_per_stop`).
    pub saturated_per_stop: Option<Vec<usize>>,
    /// The simulation-error refinement of the mode parameters, when the
    /// back-end ran it (`refinement`).
    pub refinement: Option<Refinement>,
    /// The trimmed re-estimation of the mode parameters on their regions,
    /// when the options asked for it or the back-end ran it (`trimming`).
    pub trimming: Option<Trimming>,
    /// The back-end's own fields.
    pub method: BTreeMap<String, serde_json::Value>,
}

impl Diagnostics {
    /// Whether there is nothing to record.
    pub fn is_empty(&self) -> bool {
        *self == Diagnostics::default()
    }

    /// What every front end says of the run: its status messages joined
    /// by "; ", when it was cut short or has any; `None` otherwise.
    pub fn note(&self) -> Option<String> {
        (self.run_status.cut_short() || !self.status.is_empty()).then(|| self.status.join("; "))
    }

    /// Adds the fields of a back-end's typed diagnostics (a struct that
    /// serialises to a JSON object); a field named like a common one is an
    /// error of the back-end, caught by its tests.
    pub fn with_method(mut self, fields: &impl Serialize) -> Self {
        if let Ok(serde_json::Value::Object(m)) = serde_json::to_value(fields) {
            for (k, v) in m {
                debug_assert!(
                    !COMMON.contains(&k.as_str()),
                    "method diagnostics field '{k}' shadows a common field"
                );
                self.method.insert(k, v);
            }
        }
        self
    }

    /// All fields as one map, as written in the file.
    pub fn to_map(&self) -> BTreeMap<String, serde_json::Value> {
        let mut m = self.method.clone();
        let mut put = |k: &str, v: serde_json::Value| {
            m.insert(k.to_string(), v);
        };
        if self.run_status.cut_short() {
            put("run_status", serde_json::json!(self.run_status));
        }
        if !self.status.is_empty() {
            put("status", self.status.join("; ").into());
        }
        if let Some(v) = self.samples {
            put("samples", v.into());
        }
        if let Some(v) = self.modes {
            put("modes", v.into());
        }
        if let Some(v) = self.regions_complete {
            put("regions_complete", v.into());
        }
        if let Some(v) = self.uncovered_fraction_of_data_box {
            put("uncovered_fraction_of_data_box", v.into());
        }
        if let Some(v) = &self.saturated_per_stop {
            put("saturated_per_stop", serde_json::json!(v));
        }
        if let Some(v) = &self.refinement {
            put("refinement", serde_json::json!(v));
        }
        if let Some(v) = &self.trimming {
            put("trimming", serde_json::json!(v));
        }
        m
    }

    /// The fields of a map as written in a file.
    pub fn from_map(mut m: BTreeMap<String, serde_json::Value>) -> Self {
        let mut take = |k: &str| m.remove(k);
        let run_status = take("run_status")
            .and_then(|v| serde_json::from_value(v).ok())
            .unwrap_or_default();
        let status = take("status")
            .and_then(|v| v.as_str().map(|s| vec![s.to_string()]))
            .unwrap_or_default();
        let samples = take("samples").and_then(|v| v.as_u64()).map(|v| v as usize);
        let modes = take("modes").and_then(|v| v.as_u64()).map(|v| v as usize);
        let regions_complete = take("regions_complete").and_then(|v| v.as_bool());
        let uncovered_fraction_of_data_box =
            take("uncovered_fraction_of_data_box").and_then(|v| v.as_f64());
        let saturated_per_stop =
            take("saturated_per_stop").and_then(|v| serde_json::from_value(v).ok());
        let refinement = take("refinement").and_then(|v| serde_json::from_value(v).ok());
        let trimming = take("trimming").and_then(|v| serde_json::from_value(v).ok());
        Diagnostics {
            run_status,
            status,
            samples,
            modes,
            regions_complete,
            uncovered_fraction_of_data_box,
            saturated_per_stop,
            refinement,
            trimming,
            method: m,
        }
    }
}

/// The file names of the common fields.
const COMMON: &[&str] = &[
    "run_status",
    "status",
    "samples",
    "modes",
    "regions_complete",
    "uncovered_fraction_of_data_box",
    "saturated_per_stop",
    "refinement",
    "trimming",
];

impl Serialize for Diagnostics {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.to_map().serialize(s)
    }
}

impl<'de> Deserialize<'de> for Diagnostics {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        BTreeMap::<String, serde_json::Value>::deserialize(d).map(Diagnostics::from_map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file's diagnostics read back give the same typed fields and the
    /// same bytes, and unknown fields stay with the method.
    #[test]
    fn round_trip_keeps_fields_and_order() {
        let d = Diagnostics {
            run_status: RunStatus::TimeBudget,
            status: vec!["time budget reached".into()],
            samples: Some(10),
            modes: Some(3),
            regions_complete: Some(false),
            uncovered_fraction_of_data_box: Some(0.25),
            saturated_per_stop: Some(vec![2, 0]),
            refinement: Some(Refinement {
                segment: 200,
                segments: 3,
                iterations: 7,
                max_iterations: 50,
                cost_before: Some(2.5),
                cost_after: None,
                status: RefinementStatus::Diverged,
                regions: None,
            }),
            trimming: Some(Trimming {
                cutoff: 3.0,
                rounds: 2,
                left_out: vec![4, 0],
                status: TrimmingStatus::Converged,
            }),
            method: BTreeMap::new(),
        }
        .with_method(&serde_json::json!({"c": 40, "kmeans_cost": 1.5}));
        let text = serde_json::to_string(&d).unwrap();
        let back: Diagnostics = serde_json::from_str(&text).unwrap();
        assert_eq!(back, d);
        assert_eq!(serde_json::to_string(&back).unwrap(), text);
        let keys: Vec<String> = d.to_map().into_keys().collect();
        let mut sorted = keys.clone();
        sorted.sort();
        assert_eq!(keys, sorted);
        assert!(text.contains("\"run_status\":\"time_budget\""), "{text}");
    }

    /// A completed run writes no `run_status`: the files of runs that were
    /// not cut short keep their keys.
    #[test]
    fn completed_runs_write_no_status() {
        let d = Diagnostics {
            samples: Some(4),
            ..Default::default()
        };
        assert_eq!(serde_json::to_string(&d).unwrap(), r#"{"samples":4}"#);
        assert!(Diagnostics::default().is_empty());
    }
}
