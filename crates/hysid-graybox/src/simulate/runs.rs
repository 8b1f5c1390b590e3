//! Free runs from given estimated states: the outputs alone, everything,
//! or with the forward sensitivities, sample by sample over a span of the
//! record.

use super::initial::{initial, scored_from};
use super::schedule::Schedule;
use super::{GrayBoxRun, HybridState, Kept, Machine};
use crate::compile::CompiledModel;
use hysid_model::data::Dataset;
use hysid_model::simulate::{SimError, substeps};

/// [`run`](super::run) with the states the rule leaves unknown at `estimates`
/// ([`CompiledModel::estimates`]' order).
pub fn run_from(
    m: &CompiledModel,
    values: &[f64],
    estimates: &[f64],
    data: &Dataset,
) -> Result<GrayBoxRun, SimError> {
    free_run(m, values, estimates, data, false, Kept::Everything)
}

/// [`run_from`]'s outputs alone: the run's `x`, `modes` and `covered` are
/// empty (what a fit's residuals need, without writing the rest).
pub fn outputs_from(
    m: &CompiledModel,
    values: &[f64],
    estimates: &[f64],
    data: &Dataset,
) -> Result<GrayBoxRun, SimError> {
    free_run(m, values, estimates, data, false, Kept::Output)
}

/// [`run_from`] with the derivatives of its outputs and states in the
/// parameters and the estimated states ([`GrayBoxRun::sensitivities`]:
/// forward sensitivities, exact but for fitted delays, see
/// [`differentiable`](super::differentiable)). The outputs and states
/// are [`run_from`]'s, bit for bit.
pub fn run_with_sensitivities(
    m: &CompiledModel,
    values: &[f64],
    estimates: &[f64],
    data: &Dataset,
) -> Result<GrayBoxRun, SimError> {
    free_run(m, values, estimates, data, true, Kept::Everything)
}

/// [`run_from`], with the sensitivities when `differentiate`, keeping
/// `kept` of each sample.
pub(super) fn free_run(
    m: &CompiledModel,
    values: &[f64],
    estimates: &[f64],
    data: &Dataset,
    differentiate: bool,
    kept: Kept,
) -> Result<GrayBoxRun, SimError> {
    let ts = timing(m, data)?;
    let n = data.len();
    let bound = m.bind(values);
    let schedule = Schedule::new(&bound, ts);
    let mut machine = Machine::new(&bound, values);
    let mut out = GrayBoxRun::empty(data, m.states, 0, kept);
    if differentiate {
        machine.differentiate(m);
        out.sensitivities = machine.sensitivities_for(0..n);
    }
    let (first, hs) = initial(&bound, &mut machine, data, &schedule, estimates)?;
    span(&mut machine, hs, data, first..n, &schedule, &mut out)?;
    out.start = scored_from(m);
    out.steps = machine.steps;
    out.events = machine.events;
    out.zeno = machine.zeno;
    Ok(out)
}

/// The sampling time, with the record's inputs and the model's step checked.
pub(super) fn timing(m: &CompiledModel, data: &Dataset) -> Result<f64, SimError> {
    let ts = data.ts.ok_or(SimError::NoSamplingTime)?;
    if data.inputs.len() != m.inputs {
        return Err(SimError::Inputs {
            expected: m.inputs,
            found: data.inputs.len(),
        });
    }
    substeps(ts, m.internal_step)?;
    Ok(ts)
}

/// Runs from `hs` at sample `samples.start` over `samples`, writing each
/// sample's output and, where `out` keeps them ([`Kept`]), its label,
/// coverage and state into `out`.
pub(super) fn span(
    machine: &mut Machine,
    mut hs: HybridState,
    data: &Dataset,
    samples: std::ops::Range<usize>,
    schedule: &Schedule,
    out: &mut GrayBoxRun,
) -> Result<(), SimError> {
    let (start, end) = (samples.start, samples.end);
    let states = hs.x.len();
    let everything = !out.modes.is_empty();
    let mut held = vec![0.0; data.inputs.len()];
    schedule.inputs(data, start, 0.0, &mut held);
    let mut g_end = Vec::new();
    let mut repeat = false;
    let mut buffer = Vec::new();
    for k in samples {
        let count = schedule.fill(data, k, &mut buffer)?;
        let pieces = &buffer[..count];
        let u = &pieces[0].1;
        let changed = k == start || pieces.len() > 1 || *u != held;
        if changed || !repeat {
            if everything {
                let (y, label, covered) = machine.observe(&hs, u, &held);
                out.y[k] = y;
                out.modes[k] = Some(label);
                out.covered[k] = covered;
                out.x[k * states..(k + 1) * states].copy_from_slice(&hs.x);
            } else {
                out.y[k] = machine.output(&hs, u);
            }
            if let Some(sens) = out.sensitivities.as_mut() {
                machine.tangent_output(&hs, u, k, sens);
            }
        } else {
            out.y[k] = out.y[k - 1];
            if everything {
                out.modes[k] = out.modes[k - 1];
                out.covered[k] = out.covered[k - 1];
                out.x.copy_within((k - 1) * states..k * states, k * states);
            }
        }
        // At rest (every derivative exactly zero) under an unchanged input,
        // a sample repeats the one before. With sensitivities a sample at
        // rest is integrated all the same: the state stays, its
        // sensitivities may move. A sample that repeated leaves the state
        // and the input as they were: the test's answer stands.
        let tested = k + 1 < end && !changed && !machine.differentiates();
        repeat = tested && (repeat || machine.at_rest(&hs, u));
        if k + 1 < end && !repeat {
            for (j, (duration, u, n_sub)) in pieces.iter().enumerate() {
                // Found moving by the rest test, unless a held element is
                // re-settled or a transition fires first.
                let mut moving = tested;
                if k > start || j > 0 {
                    moving &= !machine.resettle(&mut hs, u);
                    let g_before = std::mem::take(&mut g_end);
                    let u_before = if j > 0 { &pieces[j - 1].1 } else { &held };
                    let before = (None, &u_before[..]);
                    moving &= !machine.fire_across_jump(&mut hs, u, &g_before, before, k)?;
                }
                machine.advance(&mut hs, u, (*duration, *n_sub), k, moving)?;
                machine.surfaces_at_end(&hs, u, &mut g_end);
            }
        }
        // The last piece's input is held into the next sample; its buffer
        // is written whole by the next sample's schedule.
        std::mem::swap(&mut held, &mut buffer[count - 1].1);
    }
    Ok(())
}
