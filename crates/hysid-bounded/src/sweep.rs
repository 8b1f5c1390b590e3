//! Choosing delta: identification over a list of bounds,
//! reporting the trade-off between delta, the number of modes and the
//! validation FIT of free-run simulation (`hysid_core::simulate::validate`).

use crate::{Bounded, BoundedError, BoundedOptions, Delta};
use hysid_core::backend::{Identifier, IdentifyError, NoProgress, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::simulate::validate;
use hysid_model::data::Dataset;
use serde::Serialize;

/// One bound of a sweep.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    /// The bound, output units.
    pub delta: f64,
    /// Modes found (0 when identification failed).
    pub modes: usize,
    /// Undecidable identification samples.
    pub undecidable: usize,
    /// Infeasible identification samples (outliers).
    pub infeasible: usize,
    /// Validation FIT of free-run simulation, percent (`None` on failure).
    pub fit_sim: Option<f64>,
    /// Validation FIT of one-step prediction, percent.
    pub fit_pred: Option<f64>,
    /// Sample where the validation simulation diverged, if it did.
    pub diverged_at: Option<usize>,
    /// Why identification or validation failed at this bound.
    pub error: Option<String>,
    /// The identified model (with provenance), when identification succeeded.
    #[serde(skip)]
    pub model: Option<Model>,
}

/// Identifies with every bound of `deltas` (the other options from
/// `options`, seed and deadline from `ctx`) and scores each model on
/// `validation` with `warmup` samples left out. Progress: one step per
/// bound through `ctx.progress`. A failure at one bound (no mode, a
/// diverging simulation, `modes` prior not met...) is recorded in that
/// point's `error` and the sweep goes on; bad options or priors, and an
/// empty or non-positive `deltas`, are errors of the whole sweep.
pub fn delta_sweep(
    problem: &Problem<'_>,
    validation: &Dataset,
    warmup: usize,
    deltas: &[f64],
    options: &BoundedOptions,
    ctx: &RunContext<'_>,
) -> Result<Vec<SweepPoint>, IdentifyError> {
    if deltas.is_empty() {
        return Err(BoundedError::NoDelta.into());
    }
    if let Some(d) = deltas.iter().find(|d| !(d.is_finite() && **d > 0.0)) {
        return Err(BoundedError::BadDelta(*d).into());
    }
    problem
        .priors
        .ensure_honoured(Bounded::NAME, Bounded::HONOURS, problem.priors_origin)?;
    ctx.progress
        .start(deltas.len() as u64, "bounded: delta sweep");
    let inner = RunContext {
        seed: ctx.seed,
        progress: &NoProgress,
        deadline: ctx.deadline.clone(),
    };
    let mut out = Vec::with_capacity(deltas.len());
    for &delta in deltas {
        let opts = BoundedOptions {
            delta: Some(Delta::Value(delta)),
            ..options.clone()
        };
        let mut point = SweepPoint {
            delta,
            modes: 0,
            undecidable: 0,
            infeasible: 0,
            fit_sim: None,
            fit_pred: None,
            diverged_at: None,
            error: None,
            model: None,
        };
        match identify_with_provenance(problem, &opts, &inner) {
            Ok(model) => {
                point.modes = model.mode_count();
                let dg = &model.info().diagnostics;
                let get = |k: &str| dg.method.get(k).and_then(|v| v.as_u64()).unwrap_or(0) as usize;
                point.undecidable = get("undecidable");
                point.infeasible = get("infeasible");
                match validate(&model, validation, warmup) {
                    Ok((r, _, _)) => {
                        point.fit_sim = Some(r.fit_sim);
                        point.fit_pred = Some(r.fit_pred);
                        point.diverged_at = r.diverged_at;
                    }
                    Err(e) => point.error = Some(format!("validation: {e}")),
                }
                point.model = Some(model);
            }
            Err(e) if e.is_setup_error() => {
                ctx.progress.finish();
                return Err(e);
            }
            Err(e) => point.error = Some(e.to_string()),
        }
        out.push(point);
        ctx.progress.advance(1);
    }
    ctx.progress.finish();
    Ok(out)
}

/// Index of the point with the best `fit_sim` (ties: fewer modes, then the
/// larger delta).
pub fn best(points: &[SweepPoint]) -> Option<usize> {
    points
        .iter()
        .enumerate()
        .filter_map(|(i, p)| p.fit_sim.filter(|f| f.is_finite()).map(|f| (i, f)))
        .max_by(|a, b| {
            a.1.total_cmp(&b.1)
                .then(points[b.0].modes.cmp(&points[a.0].modes))
                .then(points[a.0].delta.total_cmp(&points[b.0].delta))
        })
        .map(|(i, _)| i)
}

/// The sweep as a Markdown table.
pub fn table(points: &[SweepPoint]) -> String {
    let mut s = String::from(
        "| delta | modes | undecidable | infeasible | fit_sim % | fit_pred % | note |\n|---|---|---|---|---|---|---|\n",
    );
    let f = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.2}"));
    for p in points {
        let note = match (&p.error, p.diverged_at) {
            (Some(e), _) => e.clone(),
            (None, Some(k)) => format!("diverged at {k}"),
            _ => String::new(),
        };
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            p.delta,
            p.modes,
            p.undecidable,
            p.infeasible,
            f(p.fit_sim),
            f(p.fit_pred),
            note
        ));
    }
    s
}

fn identify_with_provenance(
    problem: &Problem<'_>,
    opts: &BoundedOptions,
    ctx: &RunContext<'_>,
) -> Result<Model, IdentifyError> {
    use hysid_core::options::BackendOptions;
    let checked = hysid_core::options::Checked::new(opts.clone())?;
    let mut model = Bounded
        .identify(problem, &checked, ctx)
        .map_err(|e| e.of_method(Bounded::NAME))?;
    let info = model.info_mut();
    info.method = Bounded::NAME.to_string();
    info.options = opts.to_map();
    info.seed = Some(ctx.seed);
    info.input_names = problem.data.input_names();
    info.output_name = problem.data.output.name.clone();
    info.ts = problem.data.ts;
    Ok(model)
}
