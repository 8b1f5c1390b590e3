//! Initial states by the model's rule: given, the rest state under the
//! first input, or read from the measured output through the sensor's
//! inverse; the states the rule leaves unknown at given values (`warmup`
//! estimates them).

use super::schedule::Schedule;
use super::{GrayBoxRun, HybridState, Machine};
use crate::compile::{CompiledInitial, CompiledModel};
use hysid_model::data::Dataset;
use hysid_model::simulate::{SimError, estimate_velocity};
use hysid_numerics::budget::Deadline;
use hysid_numerics::least_squares::{Damping, Exact, LmSettings, Residuals, descend};

/// The initial sample and state of a run on `data` from the model's rule,
/// the estimated states at `estimates` ([`CompiledModel::estimates`]'
/// order; a missing value: the starting guess).
pub(super) fn initial(
    m: &CompiledModel,
    machine: &mut Machine,
    data: &Dataset,
    schedule: &Schedule,
    estimates: &[f64],
) -> Result<(usize, HybridState), SimError> {
    let n = data.len();
    let mut u = vec![0.0; m.inputs];
    let first = match &m.initial {
        CompiledInitial::Measured { samples, .. } if m.estimates.is_empty() => samples - 1,
        _ => 0,
    };
    // The measured rule reads its warm-up; an estimate scores after it.
    let needed = match m.initial.warmup() {
        Some(w) if !m.estimates.is_empty() || first > 0 => w,
        _ => 1,
    };
    if n < needed {
        return Err(SimError::TooShort { samples: n, needed });
    }
    schedule.inputs(data, first, 0.0, &mut u);
    machine.tangent_start(None);
    match &m.initial {
        CompiledInitial::Given { x, mode, .. } => {
            let x = with_estimates(m, x.clone(), estimates);
            let hs = machine.state_at(x, &u, *mode);
            // A mode the rule names must hold the state it gives, as a
            // reset's target must hold the state it sets.
            if mode.is_some() && !machine.holds_invariant(hs.mode, &hs.x, &u) {
                return Err(SimError::InitialState(format!(
                    "the state it gives ({}) lies outside the invariant of the mode it names, '{}'",
                    m.names.states_at(&hs.x),
                    m.names.modes.get(hs.mode).map_or("", String::as_str)
                )));
            }
            Ok((0, hs))
        }
        CompiledInitial::Steady { x, mode } => {
            let (x, mode) = steady(machine, x, &u, *mode)?;
            machine.tangent_steady(&x, &u, mode);
            Ok((0, machine.state_at(x, &u, Some(mode))))
        }
        CompiledInitial::Measured {
            samples,
            velocity_tol,
            mode,
            ..
        } => {
            let ym = data.y();
            let slope = if m.estimates.is_empty() {
                estimate_velocity(ym, first, schedule.ts)
            } else {
                forward_slope(&ym[..*samples], schedule.ts)
            };
            let x = measured_state(
                m,
                machine,
                (data, schedule),
                first,
                estimates,
                slope,
                *velocity_tol,
            )?;
            Ok((first, machine.state_at(x, &u, *mode)))
        }
    }
}

/// The first sample a run scores: after the measured rule's warm-up, or
/// after the warm-up that estimates unknown states; 0 otherwise.
pub(super) fn scored_from(m: &CompiledModel) -> usize {
    m.warmup_read().map_or(0, |samples| samples - 1)
}

/// `x` with the estimated states at `estimates` (a missing value: the
/// starting guess).
fn with_estimates(m: &CompiledModel, mut x: Vec<f64>, estimates: &[f64]) -> Vec<f64> {
    for (j, e) in m.estimates.iter().enumerate() {
        x[e.state] = estimates.get(j).copied().unwrap_or(e.start);
    }
    x
}

/// The slope at the first of the samples `y` (at most 5 read) of a
/// least-squares quadratic through them: [`estimate_velocity`] on the
/// samples reversed, negated.
fn forward_slope(y: &[f64], ts: f64) -> f64 {
    let mut ahead: Vec<f64> = y.iter().take(5).copied().collect();
    ahead.reverse();
    match ahead.len() {
        0 => 0.0,
        m => -estimate_velocity(&ahead, m - 1, ts),
    }
}

/// The measured rule's state at sample `k` of the record (with its
/// schedule): the rule's values, the estimated states at `estimates`, the
/// position from the output through the inverse of the output map, the
/// velocity from the output's slope `slope` divided by the map's gain (0
/// when the slope is at most `tol`).
pub(super) fn measured_state(
    m: &CompiledModel,
    machine: &mut Machine,
    (data, schedule): (&Dataset, &Schedule),
    k: usize,
    estimates: &[f64],
    slope: f64,
    tol: f64,
) -> Result<Vec<f64>, SimError> {
    let CompiledInitial::Measured {
        position,
        velocity,
        x,
        mode,
        ..
    } = &m.initial
    else {
        return Err(SimError::InvalidModel(
            "the state is read from the output only by the measured rule".into(),
        ));
    };
    let mut x = with_estimates(m, x.clone(), estimates);
    let mut u = vec![0.0; m.inputs];
    schedule.inputs(data, k, 0.0, &mut u);
    let mode = mode.unwrap_or(0);
    let gain = machine.sensor(&mut x, &u, mode, *position, data.y()[k])?;
    if let Some(v) = velocity {
        x[*v] = if slope.abs() <= tol {
            0.0
        } else {
            slope / gain
        };
    }
    machine.tangent_measured(&x, &u, (mode, *position, *velocity), gain);
    Ok(x)
}

/// The estimated states at every sample of a run (`run.x`), in
/// [`CompiledModel::estimates`]' order, at sample `k`.
pub(super) fn carried(m: &CompiledModel, run: &GrayBoxRun, k: usize) -> Vec<f64> {
    let row = &run.x[k * m.states..(k + 1) * m.states];
    m.estimates.iter().map(|e| row[e.state]).collect()
}

/// Iterations of the rest state's Newton (Levenberg-Marquardt) solve.
pub const STEADY_ITERATIONS: usize = 100;

/// Largest flow (relative to the flows at the guess, at least 1) that
/// counts as at rest.
pub const STEADY_TOLERANCE: f64 = 1e-9;

/// The cost test of the initial-state solves (the warm-up estimate, the
/// rest state): a relative decrease this small, predicted and reached.
const STATE_TOLERANCE: f64 = 1e-15;

/// The settings of the initial-state solves: at most `iterations` steps,
/// the cost test at [`STATE_TOLERANCE`], states of different units damped
/// alike ([`Damping::Marquardt`]).
pub(super) fn state_solve(iterations: usize) -> LmSettings {
    LmSettings::new(iterations)
        .with_cost_tolerance(STATE_TOLERANCE)
        .with_damping(Damping::Marquardt)
}

/// The rest state under the input `u`: the states where every flow of the
/// mode is zero (the elements aside: at rest a friction holds a velocity
/// at zero whatever its level), solved by
/// [`descend`] (Levenberg-Marquardt: Newton's method, damped, on the flows'
/// exact Jacobian) from
/// the guess `guess` ([`STEADY_ITERATIONS`] iterations at most), in
/// `mode`, or else in the first mode whose rest state satisfies its
/// invariant. Returns the state and its mode; an error when no mode has
/// one (the solve does not reach [`STEADY_TOLERANCE`], or its rest state
/// leaves the invariant).
fn steady(
    machine: &mut Machine,
    guess: &[f64],
    u: &[f64],
    mode: Option<usize>,
) -> Result<(Vec<f64>, usize), SimError> {
    let modes: Vec<usize> = match mode {
        Some(q) => vec![q],
        None => (0..machine.modes()).collect(),
    };
    let n = guess.len();
    let cell = std::cell::RefCell::new(machine);
    for &q in &modes {
        let flows = |x: &[f64]| -> Option<Vec<f64>> {
            let mut out = vec![0.0; n];
            cell.borrow_mut().bare_flows(x, u, q, &mut out);
            out.iter().all(|v| v.is_finite()).then_some(out)
        };
        let jacobian = |x: &[f64]| cell.borrow_mut().bare_flow_jacobian(x, u, q);
        let Some(f0) = flows(guess) else { continue };
        let scale = f0.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let problem = Residuals::new(&flows, n, None, Exact(&jacobian));
        let settings = state_solve(STEADY_ITERATIONS);
        let descent = descend(&problem, guess.to_vec(), &settings, &Deadline::none());
        let x = descent.v.unwrap_or_else(|| guess.to_vec());
        let at_rest =
            flows(&x).is_some_and(|f| f.iter().all(|v| v.abs() <= STEADY_TOLERANCE * scale));
        if at_rest && cell.borrow_mut().in_invariant(&x, u, q) {
            return Ok((x, q));
        }
    }
    let place = match mode {
        Some(_) => "in the rule's mode the flows do not vanish",
        None => "in no mode do the flows vanish",
    };
    Err(SimError::InitialState(format!(
        "no rest state under the first input: {place} at a state within its invariant \
         (damped Newton from the guess, at most {STEADY_ITERATIONS} iterations)"
    )))
}
