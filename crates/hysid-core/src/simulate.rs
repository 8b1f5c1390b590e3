//! Free-run simulation and one-step prediction of any [`Model`], and its
//! validation against a record.
//!
//! PWARX models and hybrid automata have their simulators
//! (`hysid_model::simulate::pwarx`, `hysid_model::simulate::automaton`);
//! physical models one, `hysid_graybox::simulate`, which runs a
//! mechanical model as its gray-box form ([`crate::model::to_gray_box`]).
//! The policies they share (least violation outside every region,
//! divergence, initial conditions) are documented in
//! `hysid_model::simulate` and `docs/simulation.md`.

use crate::model::{Model, mechanical_labels, written};
use crate::options::short;
use hysid_graybox::GrayBoxModel;
use hysid_mechanical::{MechanicalInitialState, MechanicalModel};
use hysid_model::data::Dataset;
use hysid_model::data::same_sampling;
use hysid_model::metrics::{fit, fit_undefined, pooled_fit, rmse, spread};
use hysid_model::model::InitialState;
use hysid_model::simulate::{
    DivergedTo, MAX_SUBSTEPS_PER_SAMPLE, SimError, Simulation, SimulationOptions,
    SimulationWarning, ZenoSteps, automaton, per_record, pwarx,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

fn check_inputs(model: &Model, data: &Dataset) -> Result<(), SimError> {
    if model.inputs() != data.inputs.len() {
        return Err(SimError::Inputs {
            expected: model.inputs(),
            found: data.inputs.len(),
        });
    }
    Ok(())
}

/// Free-run simulation driven by the inputs of `data`; measured outputs are
/// used only for the initial condition. Each record of a joined dataset
/// is simulated from its own initial state ([`per_record`]).
pub fn simulate(
    model: &Model,
    data: &Dataset,
    opts: SimulationOptions,
) -> Result<Simulation, SimError> {
    check_inputs(model, data)?;
    per_record(data, |data| match model {
        Model::Pwarx(m) => pwarx::simulate(m, data, opts),
        Model::HybridAutomaton(m) => automaton::simulate(m, data, opts),
        Model::Mechanical(m) => as_gray_box(m, |g| hysid_graybox::simulate(g, data, opts)),
        Model::GrayBox(m) => hysid_graybox::simulate(m, data, opts),
    })
}

/// The run of a mechanical model: `run` of its gray-box form (which
/// compiles, so checks, the form), each sample labelled by the mechanical
/// mode of its label.
fn as_gray_box(
    m: &MechanicalModel,
    run: impl FnOnce(&GrayBoxModel) -> Result<Simulation, SimError>,
) -> Result<Simulation, SimError> {
    let gray = written(m).map_err(|e| SimError::InvalidModel(e.to_string()))?;
    let labels = mechanical_labels(m, &gray);
    let mut sim = run(&gray)?;
    for q in sim.modes.iter_mut().flatten() {
        *q = labels[*q];
    }
    Ok(sim)
}

/// `m` as its one-step prediction reads it: every step from the state the
/// measured outputs give (the position and its slope), a given initial
/// state included.
fn measured_each_step(m: &MechanicalModel) -> std::borrow::Cow<'_, MechanicalModel> {
    match m.initial_state {
        MechanicalInitialState::Measured { .. } => std::borrow::Cow::Borrowed(m),
        MechanicalInitialState::Given { .. } => {
            let mut m = m.clone();
            m.initial_state = MechanicalInitialState::Measured {
                samples: 1,
                velocity_tol: 0.0,
            };
            std::borrow::Cow::Owned(m)
        }
    }
}

/// One-step-ahead prediction: every step starts from the measured state.
/// For automata whose state cannot be read from data (a fixed initial
/// state), this is the free-run simulation.
pub fn predict(
    model: &Model,
    data: &Dataset,
    opts: SimulationOptions,
) -> Result<Simulation, SimError> {
    check_inputs(model, data)?;
    per_record(data, |data| match model {
        Model::Pwarx(m) => pwarx::predict(m, data),
        Model::HybridAutomaton(m) => match m.initial_state {
            InitialState::ArxHistory { .. } => automaton::predict(m, data),
            InitialState::Given { .. } => automaton::simulate(m, data, opts),
        },
        Model::Mechanical(m) => {
            as_gray_box(&measured_each_step(m), |g| hysid_graybox::predict(g, data))
        }
        Model::GrayBox(m) => hysid_graybox::predict(m, data),
    })
}

/// What `hysid validate --json` prints (`docs/cli.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationReport {
    /// Samples scored.
    pub n: usize,
    /// Samples left out at the start, as asked; a model whose initial
    /// state reads a warm-up leaves it out too (a gray-box `given` rule
    /// all but its last sample; `n` counts the samples scored).
    pub warmup: usize,
    /// FIT of free-run simulation, percent.
    pub fit_sim: f64,
    /// RMSE of free-run simulation.
    pub rmse_sim: f64,
    /// FIT of one-step prediction, percent.
    pub fit_pred: f64,
    /// RMSE of one-step prediction.
    pub rmse_pred: f64,
    /// Fraction of scored (measured) regressors inside some region.
    pub coverage: f64,
    /// Fraction of scored simulation steps inside some region.
    pub coverage_sim: f64,
    /// Sample where the simulation diverged, if it did.
    pub diverged_at: Option<usize>,
    /// How it diverged (`bound` or `undefined`), where it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diverged_to: Option<DivergedTo>,
    /// The simulation's sub-steps that reached the Zeno bound, if any did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zeno: Option<ZenoSteps>,
    /// Scored samples per mode in the simulation (by mode index).
    pub mode_counts: Vec<usize>,
    /// The initial states the model leaves unknown, as estimated from the
    /// record's warm-up outputs ([`initial_states`]): the fields
    /// `initial_states`, `unseen_initial_states` and
    /// `initial_states_at_bound`, each absent when empty; empty when the
    /// data join several records (each record's are in its own report).
    #[serde(flatten)]
    pub initial: InitialStates,
    /// For data that join several records: each record scored on its own,
    /// with its own warm-up; the figures above pool their scored samples.
    /// Absent for one record.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub records: Vec<ValidationReport>,
    /// The scored output is constant (every record's, for several), so
    /// FIT is undefined: it says 100 for an exact match and 0 otherwise
    /// ([`hysid_model::metrics::fit`]). Absent when false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub constant_output: bool,
}

impl ValidationReport {
    /// What the user of this validation should be told: about its
    /// simulation ([`SimulationWarning`]), and that FIT means nothing on
    /// a constant output.
    pub fn warnings(&self) -> Vec<ValidationWarning> {
        let simulation = SimulationWarning::of(self.diverged_at, self.diverged_to, self.zeno);
        (simulation.into_iter().map(ValidationWarning::Simulation))
            .chain(
                self.constant_output
                    .then_some(ValidationWarning::ConstantOutput),
            )
            .collect()
    }
}

/// What the user of a validation should be told about it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValidationWarning {
    /// About the simulation.
    Simulation(SimulationWarning),
    /// The scored output is constant: FIT is undefined.
    ConstantOutput,
}

impl std::fmt::Display for ValidationWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ValidationWarning::Simulation(w) => w.fmt(f),
            ValidationWarning::ConstantOutput => f.write_str(
                "the scored output is constant: FIT is undefined there (100 % for an exact \
                 match, 0 % otherwise); judge the model by its RMSE",
            ),
        }
    }
}

/// The initial states a model leaves unknown, as its simulation of a
/// record estimates them from the warm-up outputs.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct InitialStates {
    /// Every such state by name, with its value.
    #[serde(
        rename = "initial_states",
        default,
        skip_serializing_if = "BTreeMap::is_empty"
    )]
    pub values: BTreeMap<String, f64>,
    /// Those the warm-up's outputs do not show (moving one changes none of
    /// them): the record does not determine them
    /// (`hysid_graybox::simulate::unseen`).
    #[serde(
        rename = "unseen_initial_states",
        default,
        skip_serializing_if = "Vec::is_empty"
    )]
    pub unseen: Vec<String>,
    /// Those the warm-up shows whose value lies on a bound of their
    /// `estimate` range: the record may ask for a value outside it.
    #[serde(
        rename = "initial_states_at_bound",
        default,
        skip_serializing_if = "Vec::is_empty"
    )]
    pub at_bound: Vec<String>,
}

/// The initial states `model` leaves unknown, as its simulation of `data`
/// estimates them from the warm-up outputs (a gray-box model's
/// `estimate`, `hysid_graybox::initial_states`); empty for every other
/// model.
pub fn initial_states(model: &Model, data: &Dataset) -> Result<InitialStates, SimError> {
    check_inputs(model, data)?;
    let Model::GrayBox(m) = model else {
        return Ok(InitialStates::default());
    };
    let estimated = hysid_graybox::initial_states(m, data)?;
    Ok(InitialStates {
        unseen: (estimated.iter())
            .filter(|e| !e.seen)
            .map(|e| e.name.clone())
            .collect(),
        at_bound: (estimated.iter())
            .filter(|e| e.seen && e.at_bound)
            .map(|e| e.name.clone())
            .collect(),
        values: estimated.into_iter().map(|e| (e.name, e.value)).collect(),
    })
}

/// Simulated samples whose regressor (or state) lay outside the model's
/// regions or invariants ([`Simulation::covered`]): the sign of a PWARX
/// model or an automaton with holes (each such sample took the mode of
/// least violation), or of a physical model whose guards let the state
/// leave its mode's invariant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutsideRegions {
    /// Samples outside.
    pub outside: usize,
    /// Samples simulated.
    pub simulated: usize,
    /// Whether the model's modes are chosen by regions or invariants
    /// (PWARX, hybrid automaton), rather than followed by its transitions.
    pub chosen: bool,
}

impl OutsideRegions {
    /// The samples of `sim`, a run of `model`, outside; `None` when there
    /// are none.
    pub fn of(model: &Model, sim: &Simulation) -> Option<Self> {
        let simulated = sim.covered.len().saturating_sub(sim.start);
        let outside = sim.covered.iter().skip(sim.start).filter(|c| !**c).count();
        let chosen = matches!(model, Model::Pwarx(_) | Model::HybridAutomaton(_));
        (outside > 0).then_some(Self {
            outside,
            simulated,
            chosen,
        })
    }
}

impl std::fmt::Display for OutsideRegions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (outside, simulated) = (self.outside, self.simulated);
        if self.chosen {
            write!(
                f,
                "{outside} of {simulated} simulated samples lie outside every region (or \
                 invariant); each took the mode of least violation"
            )
        } else {
            write!(
                f,
                "{outside} of {simulated} simulated samples lie outside their mode's invariant: \
                 a guard that should have led out of the mode was not crossed"
            )
        }
    }
}

/// The record's and the model's sampling times, where `model` is a
/// discrete-time model (PWARX, hybrid automaton: its lags are samples)
/// identified at another sampling time than `data`'s
/// ([`hysid_model::data::same_sampling`]): its lags then mean other times,
/// the usual sign of a decimation or sampling time left out. `None`
/// otherwise, and for models of continuous time, which simulate at any
/// sampling time.
pub fn sampling_time_mismatch(model: &Model, data: &Dataset) -> Option<(f64, f64)> {
    if !matches!(model, Model::Pwarx(_) | Model::HybridAutomaton(_)) {
        return None;
    }
    let (record, own) = (data.ts?, model.info().ts?);
    (!same_sampling(Some(record), Some(own))).then_some((record, own))
}

/// A physical model's `internal_step` far from the record's sampling time,
/// the usual sign of a step or a time column in other units than seconds:
/// longer than it (each sample is then one integration step of the
/// sampling time, coarser than the file asks for), or so much shorter
/// that a sample takes at least [`StepScale::FINE`] steps (a time column
/// in milliseconds read as seconds: every run that many times slower; a
/// model stepping once per sample, as one written for a 1 kHz record with
/// a 1 ms step, then takes exactly that many), and not more than the
/// sub-steps a run is refused beyond.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepScale {
    /// The model's internal step, seconds.
    pub internal_step: f64,
    /// The record's sampling time, seconds.
    pub ts: f64,
}

impl StepScale {
    /// Integration steps per sample from which a run is warned of.
    pub const FINE: f64 = 1000.0;

    /// The step of `model` on `data` where it is far from the sampling
    /// time; `None` where it is not, or the model has none.
    pub fn of(model: &Model, data: &Dataset) -> Option<Self> {
        let internal_step = match model {
            Model::GrayBox(m) => m.internal_step,
            Model::Mechanical(m) => m.internal_step,
            _ => return None,
        };
        let ts = data.ts?;
        // Beyond the sub-step bound the run is refused, not warned of.
        let steps = ts / internal_step;
        // At least FINE to rounding: 1/0.001 need not divide exactly.
        let fine = steps >= Self::FINE * (1.0 - 1e-9) && steps <= MAX_SUBSTEPS_PER_SAMPLE as f64;
        let far = internal_step > ts || fine;
        far.then_some(Self { internal_step, ts })
    }
}

impl std::fmt::Display for StepScale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (step, ts) = (short(self.internal_step), short(self.ts));
        if self.internal_step > self.ts {
            write!(
                f,
                "internal_step = {step} s is longer than the sampling time {ts} s: each sample is \
                 one integration step of {ts} s (internal_step is in seconds)"
            )
        } else {
            write!(
                f,
                "the sampling time {ts} s is {:.0} integration steps of internal_step = {step} s: \
                 every run takes that many per sample (the time column is in seconds: one in \
                 milliseconds?)",
                self.ts / self.internal_step
            )
        }
    }
}

/// The definitions of a gray-box model that no expression reads
/// (`hysid_graybox::Names::unread_definitions`): harmless to a run, and
/// the usual sign of a misspelt name, such as an `extends` file's new
/// definition where it meant to change the base's.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnreadDefinitions(pub Vec<String>);

impl UnreadDefinitions {
    /// Those of `model`; `None` where it has none, or is no gray-box
    /// model that compiles.
    pub fn of(model: &Model) -> Option<Self> {
        let Model::GrayBox(m) = model else {
            return None;
        };
        let compiled = hysid_graybox::CompiledModel::new(m).ok()?;
        let unread = compiled.names.unread_definitions.clone();
        (!unread.is_empty()).then_some(Self(unread))
    }
}

impl std::fmt::Display for UnreadDefinitions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "no expression reads the definition(s) {}: a misspelt name? (in an `extends` file a \
             new name adds a definition, it does not change the base's)",
            self.0.join(", ")
        )
    }
}

/// A model whose initial state its file gives, run on rows that start
/// after a record's first: the state is applied at that row, where the
/// system may be elsewhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GivenStateLater {
    /// The first row after a record's first at which the model starts.
    pub row: usize,
}

impl GivenStateLater {
    /// For `model` started at the first row of each of `starts`: the first
    /// start after row 0, where the model's initial state is given by its
    /// file; `None` otherwise.
    pub fn of(model: &Model, starts: impl IntoIterator<Item = usize>) -> Option<Self> {
        let row = starts.into_iter().find(|&start| start > 0)?;
        model.initial_state_given().then_some(Self { row })
    }
}

impl std::fmt::Display for GivenStateLater {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "its initial state is given by the file, not read from the record: it is applied at \
             row {}, where the record's state may differ (an `estimate` or a measured rule reads \
             it from the record)",
            self.row
        )
    }
}

/// Scores `model` on `data`, leaving out the first `warmup` samples (and
/// any before the simulation can start). Data that join several records
/// are scored record by record, each with its own warm-up and initial
/// state, and as a whole over the samples scored in each.
pub fn validate(
    model: &Model,
    data: &Dataset,
    warmup: usize,
) -> Result<(ValidationReport, Simulation, Simulation), SimError> {
    let mut scored = scores(model, data, warmup);
    if scored.len() == 1 {
        return scored.remove(0).1;
    }
    let mut ranges = Vec::new();
    let mut parts = Vec::new();
    let (mut sims, mut preds) = (Vec::new(), Vec::new());
    for (i, (range, result)) in scored.into_iter().enumerate() {
        let (report, sim, pred) = result.map_err(|e| SimError::InRecord {
            record: i + 1,
            source: Box::new(e),
        })?;
        ranges.push(range);
        parts.push(report);
        sims.push(sim);
        preds.push(pred);
    }
    let sim = Simulation::join(sims, &ranges);
    let pred = Simulation::join(preds, &ranges);
    let y = scored_parts(data.y(), &ranges, &parts);
    let (ys, yp) = (
        scored_parts(&sim.y, &ranges, &parts),
        scored_parts(&pred.y, &ranges, &parts),
    );
    let paired = |yhat: &[&'_ [f64]]| {
        let pairs: Vec<(&[f64], &[f64])> = y.iter().copied().zip(yhat.iter().copied()).collect();
        (pooled_fit(&pairs), rmse(&y.concat(), &yhat.concat()))
    };
    let ((fit_sim, rmse_sim), (fit_pred, rmse_pred)) = (paired(&ys), paired(&yp));
    let n = parts.iter().map(|p| p.n).sum();
    let weighted = |f: fn(&ValidationReport) -> f64| {
        parts.iter().map(|p| f(p) * p.n as f64).sum::<f64>() / n as f64
    };
    let mut mode_counts = vec![0; model.mode_count()];
    for p in &parts {
        for (c, q) in mode_counts.iter_mut().zip(&p.mode_counts) {
            *c += q;
        }
    }
    let report = ValidationReport {
        n,
        warmup,
        fit_sim,
        rmse_sim,
        fit_pred,
        rmse_pred,
        coverage: weighted(|p| p.coverage),
        coverage_sim: weighted(|p| p.coverage_sim),
        diverged_at: sim.diverged_at,
        diverged_to: sim.diverged_to,
        zeno: sim.zeno,
        mode_counts,
        initial: InitialStates::default(),
        constant_output: fit_undefined(&y),
        records: parts,
    };
    Ok((report, sim, pred))
}

/// Each record's scored samples of `v` (a signal of the joined records):
/// the last `n` of its range, `n` from its report.
fn scored_parts<'v>(
    v: &'v [f64],
    ranges: &[std::ops::Range<usize>],
    parts: &[ValidationReport],
) -> Vec<&'v [f64]> {
    (ranges.iter().zip(parts))
        .map(|(r, p)| &v[r.end - p.n..r.end])
        .collect()
}

/// A record's report, free-run simulation and prediction.
type Scored = (ValidationReport, Simulation, Simulation);

/// Each record of `data` (the dataset itself when it is one record) with
/// its samples in `data`, scored on its own ([`validate_record`]).
fn scores(
    model: &Model,
    data: &Dataset,
    warmup: usize,
) -> Vec<(std::ops::Range<usize>, Result<Scored, SimError>)> {
    let opts = SimulationOptions::for_data(data);
    if data.record_count() == 1 {
        return vec![(0..data.len(), validate_record(model, data, warmup, opts))];
    }
    data.records()
        .iter()
        .zip(data.record_ranges())
        .map(|(record, range)| (range, validate_record(model, record, warmup, opts)))
        .collect()
}

/// [`validate`] on one record.
fn validate_record(
    model: &Model,
    data: &Dataset,
    warmup: usize,
    opts: SimulationOptions,
) -> Result<Scored, SimError> {
    let sim = simulate(model, data, opts)?;
    let pred = predict(model, data, opts)?;
    let states = initial_states(model, data)?;
    let first = warmup.max(sim.start).max(pred.start);
    let n_all = data.len();
    if first >= n_all {
        return Err(SimError::TooShort {
            samples: n_all,
            needed: first,
        });
    }
    let y = &data.y()[first..];
    let frac = |s: &Simulation| {
        s.covered[first..].iter().filter(|&&c| c).count() as f64 / (n_all - first) as f64
    };
    let mut mode_counts = vec![0; model.mode_count()];
    for q in sim.modes[first..].iter().flatten() {
        if let Some(c) = mode_counts.get_mut(*q) {
            *c += 1;
        }
    }
    let report = ValidationReport {
        n: n_all - first,
        warmup,
        fit_sim: fit(y, &sim.y[first..]),
        rmse_sim: rmse(y, &sim.y[first..]),
        fit_pred: fit(y, &pred.y[first..]),
        rmse_pred: rmse(y, &pred.y[first..]),
        coverage: frac(&pred),
        coverage_sim: frac(&sim),
        diverged_at: sim.diverged_at,
        diverged_to: sim.diverged_to,
        zeno: sim.zeno,
        mode_counts,
        initial: states,
        records: Vec::new(),
        constant_output: fit_undefined(&[y]),
    };
    Ok((report, sim, pred))
}

/// A model scored on rows it was not fitted on: what automatic selection
/// and the mode-count choice under `max_modes` compare candidates by.
#[derive(Debug, Clone, PartialEq)]
pub struct Holdout {
    /// FIT of the free-run simulation, percent (finite).
    pub fit_sim: f64,
    /// The simulation errors `y - y_sim` of the scored samples, in order:
    /// what the one-standard-error rule compares. An error within
    /// [`ERROR_RESOLUTION`] of the output's deviation is zero.
    pub errors: Vec<f64>,
}

/// The least simulation error a [`Holdout`] tells from zero, as a fraction
/// of the root-mean-square deviation of the scored output about its mean:
/// below any measurement's resolution (a 16-bit converter resolves 1.5e-5
/// of its range), and above the rounding of a simulation in double
/// precision. Two models exact on noise-free rows then compare as equal in
/// the one-standard-error rule, which takes the one of fewer modes, instead
/// of by their rounding errors, whose differences have a standard error
/// as small.
pub const ERROR_RESOLUTION: f64 = 1e-6;

/// A FIT as held-out scores are compared: 100 where the error is within
/// [`ERROR_RESOLUTION`] of the output's deviation (a FIT of at least
/// `100 (1 - ERROR_RESOLUTION)`), so that models exact on the rows tie
/// instead of being ranked by their rounding.
pub fn resolved_fit(fit: f64) -> f64 {
    if fit >= 100.0 * (1.0 - ERROR_RESOLUTION) {
        100.0
    } else {
        fit
    }
}

/// Why a model could not be scored on held-out rows.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HoldoutError {
    /// The simulation failed.
    #[error("simulation on the held-out rows: {0}")]
    Simulation(#[from] SimError),
    /// The simulation FIT is not a number.
    #[error("the simulation FIT is not finite")]
    NotFinite,
}

/// `model` scored on `data` by free-run simulation, the first `warmup`
/// samples of each record left out ([`validate`]). A record of a joined
/// dataset too short to be scored (held-out rows that begin or end a few
/// samples from a record's boundary) is left out, unless every one is.
pub fn holdout(model: &Model, data: &Dataset, warmup: usize) -> Result<Holdout, HoldoutError> {
    let several = data.record_count() > 1;
    // Each scored record's measured and simulated outputs.
    let mut parts: Vec<(&[f64], Vec<f64>)> = Vec::new();
    let mut short = None;
    for (range, scored) in scores(model, data, warmup) {
        let (report, sim, _) = match scored {
            Err(e @ SimError::TooShort { .. }) if several => {
                short.get_or_insert(e);
                continue;
            }
            scored => scored?,
        };
        let simulated = sim.y[sim.y.len() - report.n..].to_vec();
        parts.push((&data.y()[range.end - report.n..range.end], simulated));
    }
    if parts.is_empty()
        && let Some(e) = short
    {
        return Err(e.into());
    }
    let pairs: Vec<(&[f64], &[f64])> = parts.iter().map(|(y, s)| (*y, s.as_slice())).collect();
    let fit_sim = pooled_fit(&pairs);
    if !fit_sim.is_finite() {
        return Err(HoldoutError::NotFinite);
    }
    let scored: usize = pairs.iter().map(|(y, _)| y.len()).sum();
    let resolution =
        ERROR_RESOLUTION * spread(pairs.iter().map(|(y, _)| *y)) / (scored.max(1) as f64).sqrt();
    let resolved = |e: f64| if e.abs() <= resolution { 0.0 } else { e };
    Ok(Holdout {
        fit_sim,
        errors: (pairs.iter())
            .flat_map(|(y, s)| y.iter().zip(*s).map(|(a, b)| resolved(a - b)))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `y(k) = 0.5 y(k-1) + u(k-1)`, one mode.
    fn first_order() -> Model {
        Model::from_json(
            r#"{"kind":"pwarx","na":1,"nb":1,"inputs":1,"modes":[
                {"theta":[0.5,1.0,0.0],"region":{"a":[],"b":[]}}]}"#,
            "m.json",
        )
        .unwrap()
    }

    /// A record of the model, with a disturbance `bias` on the output.
    fn record(n: usize, bias: f64) -> Dataset {
        let u: Vec<f64> = (0..n).map(|k| ((k * 7 % 5) as f64) - 2.0).collect();
        let mut y = vec![0.0; n];
        for k in 1..n {
            y[k] = 0.5 * y[k - 1] + u[k - 1];
        }
        Dataset::siso(
            u,
            y.iter().map(|v| v + bias * (1.0 + v.abs())).collect(),
            None,
        )
        .unwrap()
    }

    /// Errors at the level of rounding are zero, so that two exact models
    /// compare as equal; an error a millionth of the output's deviation
    /// (times a few) is kept. FITs within that resolution of 100 tie.
    #[test]
    fn held_out_errors_below_the_resolution_are_zero() {
        let model = first_order();
        let exact = record(200, 0.0);
        // The output computed in another order: rounding apart.
        let y: Vec<f64> = (exact.y().iter())
            .map(|v| (v * 3.0 + 0.1) / 3.0 - 0.1 / 3.0)
            .collect();
        let rounded = Dataset::siso(exact.u(0).to_vec(), y, None).unwrap();
        let h = holdout(&model, &rounded, 5).unwrap();
        assert!(h.fit_sim < 100.0, "{}", h.fit_sim);
        assert!(h.errors.iter().all(|e| *e == 0.0));
        assert_eq!(resolved_fit(h.fit_sim), 100.0);
        let off = holdout(&model, &record(200, 1e-5), 5).unwrap();
        assert!(off.errors.iter().all(|e| *e != 0.0));
        assert!(resolved_fit(off.fit_sim) < 100.0, "{}", off.fit_sim);
    }

    /// Each record of a joined dataset is scored as on its own; the pooled
    /// figures are over the scored samples of both; a record too short to
    /// score is an error of `validate` and left out by `holdout`.
    #[test]
    fn joined_records_are_scored_each_and_together() {
        let model = first_order();
        let (a, b) = (record(40, 0.02), record(30, -0.05));
        let joined = Dataset::join(&[a.clone(), b.clone()]).unwrap();
        let (whole, sim, _) = validate(&model, &joined, 5).unwrap();
        let (ra, _, _) = validate(&model, &a, 5).unwrap();
        let (rb, _, _) = validate(&model, &b, 5).unwrap();
        assert_eq!(whole.records, [ra.clone(), rb.clone()]);
        assert_eq!(whole.n, ra.n + rb.n);
        assert_eq!(sim.y.len(), 70);
        let h = holdout(&model, &joined, 5).unwrap();
        assert_eq!(h.errors.len(), whole.n);
        assert_eq!(h.fit_sim, whole.fit_sim);
        assert!(whole.fit_sim < ra.fit_sim.max(rb.fit_sim));
        assert!(whole.fit_sim > ra.fit_sim.min(rb.fit_sim));
        let with_short = Dataset::join(&[a.clone(), record(3, 0.0)]).unwrap();
        let e = validate(&model, &with_short, 5).unwrap_err();
        assert_eq!(
            e.to_string(),
            "record 2: the record has 3 samples; the model needs more than 5"
        );
        assert_eq!(
            holdout(&model, &with_short, 5).unwrap(),
            holdout(&model, &a, 5).unwrap()
        );
    }
}
