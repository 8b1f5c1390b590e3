//! Choosing `c` and the number of modes `s`:
//! every pair of a grid is identified on one record and scored on another
//! by free-run **simulation** FIT (`hysid_core::simulate::validate`), the
//! headline metric; HIT's `hit_estimate_cs` scores one-step MSE instead,
//! which cannot rank models of a 400 Hz record.

use crate::{ClusterOptions, identify_with};
use hysid_core::backend::{Problem, RunContext};
use hysid_core::simulate::{ValidationReport, validate};
use hysid_model::data::Dataset;
use serde::{Deserialize, Serialize};

/// One grid point of [`sweep`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepPoint {
    /// Local dataset size used (`None` when identification failed before
    /// it was resolved).
    pub c: Option<usize>,
    /// Number of modes asked for.
    pub modes: usize,
    /// Number of modes of the identified model (the saturation modes
    /// included; a grid point whose clusters fall below the discard size
    /// fails instead of returning fewer modes).
    pub modes_found: Option<usize>,
    /// Validation FIT of free-run simulation, percent.
    pub fit_sim: Option<f64>,
    /// Validation FIT of one-step prediction, percent.
    pub fit_pred: Option<f64>,
    /// The whole validation report.
    pub report: Option<ValidationReport>,
    /// Why the point has no score.
    pub error: Option<String>,
    /// Free-run simulation errors `y - y_sim` on the scored validation
    /// samples (empty without a score).
    #[serde(skip)]
    pub sim_errors: Vec<f64>,
}

/// Identifies `problem` (its prior mode count is ignored) for every pair of
/// `cs x modes` and scores each model on `validation`, leaving out the
/// first `warmup` samples. An empty `cs` means the `c` of `base` (automatic
/// when unset). Progress: one step per grid point through `ctx.progress`.
/// Every point uses `ctx.seed`. Points come back in grid order (`cs` outer);
/// a failure is reported in the point, never as a panic.
pub fn sweep(
    problem: &Problem<'_>,
    validation: &Dataset,
    warmup: usize,
    cs: &[usize],
    modes: &[usize],
    base: &ClusterOptions,
    ctx: &RunContext<'_>,
) -> Vec<SweepPoint> {
    let grid: Vec<Option<usize>> = if cs.is_empty() {
        vec![base.c]
    } else {
        cs.iter().map(|&c| Some(c)).collect()
    };
    ctx.progress.start(
        (grid.len() * modes.len()) as u64,
        "cluster: sweeping c and the mode count",
    );
    let mut out = Vec::with_capacity(grid.len() * modes.len());
    for &c in &grid {
        for &s in modes {
            let opts = ClusterOptions { c, ..base.clone() };
            let mut point = SweepPoint {
                c,
                modes: s,
                modes_found: None,
                fit_sim: None,
                fit_pred: None,
                report: None,
                error: None,
                sim_errors: Vec::new(),
            };
            match identify_with(problem, &opts, s, ctx.seed, ctx.deadline.clone()) {
                Ok(model) => {
                    point.modes_found = Some(model.mode_count());
                    point.c = model
                        .info()
                        .diagnostics
                        .method
                        .get("c")
                        .and_then(|v| v.as_u64())
                        .map(|v| v as usize)
                        .or(c);
                    match validate(&model, validation, warmup) {
                        Ok((r, sim, _)) => {
                            let y = validation.y();
                            let first = y.len() - r.n;
                            point.sim_errors = y[first..]
                                .iter()
                                .zip(&sim.y[first..])
                                .map(|(a, b)| a - b)
                                .collect();
                            point.fit_sim = Some(r.fit_sim);
                            point.fit_pred = Some(r.fit_pred);
                            point.report = Some(r);
                        }
                        Err(e) => point.error = Some(format!("validation: {e}")),
                    }
                }
                Err(e) => point.error = Some(e.to_string()),
            }
            out.push(point);
            ctx.progress.advance(1);
            if ctx.deadline.passed() {
                ctx.progress.finish();
                return out;
            }
        }
    }
    ctx.progress.finish();
    out
}
