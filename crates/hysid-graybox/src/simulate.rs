//! Event-located simulation of gray-box models.
//!
//! The hybrid state is the continuous state `x`, the mode, and the regime
//! of every element (a friction slides in a direction or sticks; a stop is
//! away or holds its position). The input is held over each sample
//! (zero-order hold); each sample is split into equal sub-steps no longer
//! than `internal_step`, each one classical RK4 step of the current
//! regime's flow (in closed form where the flows are affine in the states
//! and inputs: the module `linear`). Sub-steps that end without an event
//! are taken back to back by the module `quiet`, with the same results.
//!
//! **Events** are located inside the sub-step on the step length, to
//! [`LOCATE_RESOLUTION`] of the sub-step, by regula falsi on the event's
//! margin safeguarded by bisection
//! ([`hysid_numerics::event_location`]); the state is
//! taken just past the event and the rest of the sub-step integrated in the new regime:
//!
//! - an element's regime ends (checked on the state): a sliding velocity
//!   reaches zero, a stop is reached, a stuck friction's applied force
//!   exceeds the static level, the force pulls away from a stop;
//! - a transition's guard surface is crossed in its direction (checked
//!   against the surface's value at the start of the step) and its `when`
//!   condition holds; between samples the surface is compared across the
//!   input's jump, so a guard that the new input crosses fires at the
//!   sample instant.
//!
//! Elements take precedence over transitions, stops over frictions, and
//! earlier declarations over later ones. A velocity that comes to zero is
//! settled by Karnopp's rule: it rests at a stop it is pushed into, sticks
//! when the applied force is within the static level, and otherwise slides
//! off in the force's direction, so the friction's sign is never evaluated
//! at zero velocity and there is no chattering.
//!
//! **Zeno bound**: at most [`MAX_EVENTS_PER_STEP`] events per sub-step.
//! Beyond it, every stop that has been reached holds its position (the
//! accumulation point of a bouncing contact), and the rest of the sub-step
//! is integrated without events; [`GrayBoxRun::zeno`] counts these.
//!
//! A sample whose every state derivative is exactly zero (resting at a stop,
//! stuck, at an equilibrium) is skipped: with the input held, nothing in it
//! can change.
//!
//! **Initial states** come from the model's rule: given values; the
//! measured output read through the inverse of the output map (affine in
//! the state it sets: a sensor's gain and offset); or the rest state under
//! the first input ([`STEADY_ITERATIONS`] of Levenberg-Marquardt on the
//! flows). States a rule leaves unknown are estimated from the record's
//! warm-up outputs alone ([`estimate`]), or given ([`run_from`]).
//!
//! **Where each part lives.** This module holds the hybrid state, the
//! [`Machine`] (the simulator's workspace), [`run`] and [`predict`]; the
//! rest is in its submodules: `runs` (free runs from given estimated
//! states), `warmup` (the unknown initial states estimated from the
//! warm-up), `initial` (the initial-state rules), `schedule` (the inputs
//! held over a sample and cut by delays), `flows` (the regime's flows and
//! its RK4 step), `linear` (the closed form of affine regimes), `events` (a
//! sample's sub-steps, its events and how they are applied), `locate` (an
//! event's location inside a sub-step), `quiet` (sub-steps without events
//! taken back to back), `sensitivity` (the forward sensitivities) and
//! `shooting` (segmented runs).

use crate::compile::{CompiledElement, CompiledInitial, CompiledModel};
use crate::expr::Crossing;
use events::Surfaces;
use hysid_model::data::Dataset;
use hysid_model::simulate::{SimError, ZenoSteps, estimate_velocity};
pub use hysid_numerics::event_location::LOCATE_RESOLUTION;
pub use initial::{STEADY_ITERATIONS, STEADY_TOLERANCE};
use initial::{carried, measured_state};
use linear::{AffineFlows, AffineRow, ClosedStep, affine_guards};
use runs::{free_run, span, timing};
pub use runs::{outputs_from, run_from, run_with_sensitivities};
use schedule::Schedule;
use sensitivity::Tangent;
pub use sensitivity::{Sensitivities, differentiable};
pub use shooting::{segmented, segmented_with_sensitivities};
use std::rc::Rc;
pub use warmup::{ESTIMATE_ITERATIONS, estimate, unseen};

mod events;
mod flows;
mod initial;
mod linear;
mod locate;
mod quiet;
mod runs;
mod schedule;
mod sensitivity;
mod shooting;
mod warmup;

/// Bound on the events handled within one sub-step (the Zeno guard).
pub const MAX_EVENTS_PER_STEP: usize = 16;

/// Tolerance on an invariant's margin when checking a mode (states in the
/// model's own units).
pub const INVARIANT_TOLERANCE: f64 = 1e-9;

/// The regime of an element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ElementRegime {
    /// A friction sliding in direction `+1` or `-1`.
    Slip(f64),
    /// A friction stuck (its velocity held at zero).
    Stuck,
    /// A stop not touched.
    Away,
    /// A stop holding its position (and velocity at zero).
    Resting,
}

/// The hybrid state.
#[derive(Debug, Clone, PartialEq)]
pub struct HybridState {
    /// Continuous states.
    pub x: Vec<f64>,
    /// Mode index.
    pub mode: usize,
    /// One regime per element.
    pub regimes: Vec<ElementRegime>,
}

/// The result of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct GrayBoxRun {
    /// Output at every sample (before `start`: the measured output, or
    /// the simulated one over the warm-up of a rule that estimates states).
    pub y: Vec<f64>,
    /// States at every sample, row-major (`states` per sample; zeros before
    /// `start`, but over the warm-up of a rule that estimates states).
    pub x: Vec<f64>,
    /// Mode label per sample (into [`crate::GrayBoxModel::mode_names`]).
    pub modes: Vec<Option<usize>>,
    /// Per sample: the state satisfied its mode's invariant.
    pub covered: Vec<bool>,
    /// First scored sample: the first simulated one, or the last of the
    /// warm-up of a rule that estimates states (simulated from sample 0).
    pub start: usize,
    /// RK4 sub-steps integrated.
    pub steps: usize,
    /// Events handled.
    pub events: usize,
    /// The sub-steps that reached [`MAX_EVENTS_PER_STEP`], if any did.
    pub zeno: Option<ZenoSteps>,
    /// The derivatives of the outputs and states in the parameters and the
    /// estimated initial states, when asked for
    /// ([`run_with_sensitivities`]).
    pub sensitivities: Option<Sensitivities>,
}

/// What an element in its current regime does to the flows.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Effect {
    /// Friction element `i` slides velocity `v` in direction `dir`.
    Friction(usize, usize, f64),
    /// The state's derivative is zero (a stuck velocity, a resting stop).
    Hold(usize),
}

impl GrayBoxRun {
    /// A run of `data` not simulated yet: the measured outputs, no mode,
    /// every sample covered; the first simulated sample `start`. With
    /// [`Kept::Output`], no states, modes or coverage (empty).
    fn empty(data: &Dataset, states: usize, start: usize, kept: Kept) -> Self {
        let n = match kept {
            Kept::Output => 0,
            Kept::Everything => data.len(),
        };
        GrayBoxRun {
            y: data.y().to_vec(),
            x: vec![0.0; n * states],
            modes: vec![None; n],
            covered: vec![true; n],
            start,
            steps: 0,
            events: 0,
            zeno: None,
            sensitivities: None,
        }
    }
}

/// What a run keeps of each sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kept {
    /// The output alone (what a fit's residuals read).
    Output,
    /// The output, the state, the mode label and the coverage.
    Everything,
}

/// What ended a sub-step early.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Event {
    Element(usize),
    Transition(usize),
}

/// The model as it reads in a sliding regime
/// ([`CompiledModel::sliding`]): bound, with its flows' affine forms, and
/// unbound for the sensitivities (when they are carried).
struct Sliding {
    bound: CompiledModel,
    affine: Vec<Option<AffineFlows>>,
    unbound: Option<CompiledModel>,
}

impl Sliding {
    /// What the sensitivities differentiate in the regime of `sliding`:
    /// its unbound model, or `model` outside a sliding regime.
    fn unbound_or<'m>(sliding: Option<&'m Sliding>, model: &'m CompiledModel) -> &'m CompiledModel {
        sliding.and_then(|s| s.unbound.as_ref()).unwrap_or(model)
    }
}

/// Per mode of `m`, its flows' affine form, when they have one.
fn affine_forms(m: &CompiledModel) -> Vec<Option<AffineFlows>> {
    m.modes
        .iter()
        .map(|q| AffineFlows::of(q, m.states, m.inputs))
        .collect()
}

/// Per element, the direction it slides in (`true`: positive), `None`
/// where it does not slide.
type Directions = Vec<Option<bool>>;

/// A closed-form step with the mode, element regimes and step length it
/// was formed for.
type ClosedEntry = (usize, Vec<ElementRegime>, f64, Option<ClosedStep>);

/// Closed-form steps kept besides the current one: a run returns to a few
/// regimes (sliding either way, in or out of contact) again and again.
const FORMED_STEPS: usize = 8;

/// The simulator's workspace for one model and one parameter vector.
pub struct Machine<'a> {
    m: &'a CompiledModel,
    slots: Vec<f64>,
    /// Per element: (stop position or NaN, restitution or NaN), from the parameters.
    fixed: Vec<(f64, f64)>,
    /// Friction element of each state, if any.
    friction_of: Vec<Option<usize>>,
    k: [Vec<f64>; 4],
    /// The end of a trial step, and the event location's trial state.
    x1: Vec<f64>,
    xm: Vec<f64>,
    /// Guard surfaces at the start of the step and at its trial end.
    g: Surfaces,
    /// The quiet lane's tests of the regime it steps in ([`quiet`]): the
    /// elements' regimes they were listed for (`None`: not listed yet),
    /// and `None` where an element is held (the lane closed).
    watch: (Option<Vec<ElementRegime>>, Option<Vec<StateEnd>>),
    /// Per mode, whether a guard surface reads an input.
    input_guards: Vec<bool>,
    /// The elements' effects in the regime of the step being integrated,
    /// and the regimes they were listed for.
    effects: Vec<Effect>,
    effects_of: Vec<ElementRegime>,
    /// Per mode, its flows' affine form, when they have one.
    affine: Vec<Option<AffineFlows>>,
    /// The models of the sliding regimes met, by the direction of each
    /// element (`None`: not sliding; a `None` model: the same as `m`).
    sliding: Vec<(Directions, Option<Rc<Sliding>>)>,
    /// The one of the regime selected last (`None`: `m` itself), and that
    /// regime's directions.
    current: Option<Rc<Sliding>>,
    directions: Directions,
    /// Whether a sliding direction decides anything in the model
    /// ([`CompiledModel::decides_sliding`]); if not, `current` stays `None`.
    decides: bool,
    /// The model with its parameters as slots, when the sensitivities are
    /// carried.
    unbound: Option<&'a CompiledModel>,
    /// Per mode, its guard surfaces read from the state and the input,
    /// when every one is affine in them.
    guards: Vec<Option<Vec<(Crossing, AffineRow)>>>,
    /// The closed-form step of the last regime and step length integrated
    /// (`None` inside: that regime has none), with its mode and regimes.
    closed: Option<ClosedEntry>,
    /// The closed-form steps formed before it, the oldest first.
    formed: Vec<ClosedEntry>,
    /// The sub-step length of the sample being advanced, the length the
    /// closed form is formed for; shorter steps around events take the
    /// regime's Horner form.
    full_step: f64,
    /// Whether the steps of affine regimes take the closed form
    /// ([`linear`]); off, every step runs stage by stage.
    pub(crate) closed_form: bool,
    /// Whether the exact shortcuts are taken: the [`quiet`] lane, the
    /// start surfaces kept from one sample to the next, and no surfaces
    /// compared across an input's jump that no guard reads (off: every
    /// step and surface by the general loop, with the same results).
    pub(crate) shortcuts: bool,
    /// Whether a reset that leaves its target mode's invariant is an error
    /// ([`SimError::OutsideTargetInvariant`]): a fault of the model in a run
    /// from its own initial state. Off where every segment or sample
    /// restarts from measured states ([`segmented`], [`predict`]), which
    /// may lie outside every invariant: the transition is followed (and
    /// where coverage is kept, such samples count as not covered).
    strict_resets: bool,
    pub(crate) steps: usize,
    /// Of `steps`, those the [`quiet`] lane took.
    pub(crate) quiet_steps: usize,
    pub(crate) events: usize,
    /// The trial steps of the events' location.
    pub(crate) locate_trials: usize,
    pub(crate) zeno: Option<ZenoSteps>,
    /// The sensitivities carried beside the state, when asked for (boxed:
    /// each step takes them out of the machine and puts them back).
    tangent: Option<Box<Tangent<'a>>>,
}

impl<'a> Machine<'a> {
    /// A workspace for `m` with parameter values `values`.
    pub fn new(m: &'a CompiledModel, values: &[f64]) -> Self {
        let mut slots = vec![0.0; m.slots()];
        let p0 = m.parameter_slot();
        slots[p0..p0 + m.parameters].copy_from_slice(&values[..m.parameters]);
        let fixed = m
            .elements
            .iter()
            .map(|e| match e {
                CompiledElement::Stop {
                    at, restitution, ..
                } => (at.eval(&slots), restitution.eval(&slots).clamp(0.0, 1.0)),
                CompiledElement::DryFriction { .. } => (f64::NAN, f64::NAN),
            })
            .collect();
        let mut friction_of = vec![None; m.states];
        for (i, e) in m.elements.iter().enumerate() {
            if let CompiledElement::DryFriction { velocity, .. } = e {
                friction_of[*velocity] = Some(i);
            }
        }
        let n = m.states;
        let affine = affine_forms(m);
        let guards = m
            .modes
            .iter()
            .map(|q| affine_guards(q, m.states, m.inputs))
            .collect();
        Machine {
            m,
            slots,
            fixed,
            friction_of,
            affine,
            sliding: Vec::new(),
            current: None,
            directions: Vec::new(),
            decides: m.decides_sliding(),
            unbound: None,
            guards,
            closed: None,
            formed: Vec::with_capacity(FORMED_STEPS),
            full_step: f64::NAN,
            closed_form: true,
            shortcuts: true,
            strict_resets: true,
            k: [vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            x1: vec![0.0; n],
            xm: vec![0.0; n],
            g: Surfaces::default(),
            watch: (None, None),
            input_guards: m
                .modes
                .iter()
                .map(|q| {
                    let inputs = m.states as u32..(m.states + m.inputs) as u32;
                    q.transitions
                        .iter()
                        .any(|t| t.guard.surface.slots().any(|s| inputs.contains(&s)))
                })
                .collect(),
            effects: Vec::with_capacity(2 * m.elements.len()),
            effects_of: Vec::new(),
            steps: 0,
            quiet_steps: 0,
            locate_trials: 0,
            events: 0,
            zeno: None,
            tangent: None,
        }
    }

    /// The stops at these parameter values: `(position state, level, sign)`.
    pub fn stops(&self) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.stops_with_velocity()
            .map(|(_, position, _, at, sign)| (position, at, sign))
    }

    /// Number of modes.
    pub(crate) fn modes(&self) -> usize {
        self.m.modes.len()
    }
}

/// A regime's end read from one state: it ends where `sign * (x[state] -
/// level) >= 0`.
#[derive(Debug, Clone, Copy)]
struct StateEnd {
    state: usize,
    sign: f64,
    level: f64,
}

impl StateEnd {
    /// How far past its end the state `x` is (negative before it).
    #[inline]
    fn margin(&self, x: &[f64]) -> f64 {
        self.margin_by(|s| x[s])
    }

    /// [`StateEnd::margin`] with the state read by `x`.
    #[inline(always)]
    fn margin_by(&self, x: impl Fn(usize) -> f64) -> f64 {
        self.sign * (x(self.state) - self.level)
    }
}

/// Loads `(x, u)` into the first slots.
#[inline]
fn load(slots: &mut [f64], x: &[f64], u: &[f64]) {
    let (states, rest) = slots.split_at_mut(x.len());
    for (slot, v) in states.iter_mut().zip(x) {
        *slot = *v;
    }
    for (slot, v) in rest.iter_mut().zip(u) {
        *slot = *v;
    }
}

/// A surface crossed in direction `c` between the values `g0` and `g1`:
/// from one side onto or past zero, or from exactly zero (a reset onto the
/// guard) strictly past it, so that a return to the surface within the same
/// step is not missed.
fn crossed(c: Crossing, g0: f64, g1: f64) -> bool {
    let rising = (g0 < 0.0 && g1 >= 0.0) || (g0 == 0.0 && g1 > 0.0);
    let falling = (g0 > 0.0 && g1 <= 0.0) || (g0 == 0.0 && g1 < 0.0);
    match c {
        Crossing::Rising => rising,
        Crossing::Falling => falling,
        Crossing::Either => rising || falling,
    }
}

/// Runs the compiled model with parameter values `values` on the inputs of
/// `data` (sampling time `data.ts`), from the model's initial-state rule;
/// the states the rule leaves unknown are estimated from the record's
/// warm-up outputs ([`estimate`]).
pub fn run(m: &CompiledModel, values: &[f64], data: &Dataset) -> Result<GrayBoxRun, SimError> {
    let estimates = estimate(m, values, data)?;
    run_from(m, values, &estimates, data)
}

/// One-step prediction: at each sample the state is read again from the
/// measured outputs up to it (the model's `measured` rule; the states it
/// leaves unknown are taken from the free run) and advanced by one
/// sample. A model with a given or a rest initial state has no such
/// reading: its prediction is its free run, which starts, as a measured
/// rule's prediction does, after every sample its initial state reads (a
/// given rule's warm-up that estimates states).
pub fn predict(m: &CompiledModel, values: &[f64], data: &Dataset) -> Result<GrayBoxRun, SimError> {
    let CompiledInitial::Measured {
        samples,
        velocity_tol,
        mode,
        ..
    } = m.initial
    else {
        let mut free = run(m, values, data)?;
        free.start = free.start.max(m.warmup_read().unwrap_or(0));
        return Ok(free);
    };
    let free = if m.estimates.is_empty() {
        None
    } else {
        Some(run(m, values, data)?)
    };
    let ts = timing(m, data)?;
    let n = data.len();
    let first = samples - 1;
    if n <= first {
        return Err(SimError::TooShort {
            samples: n,
            needed: first + 1,
        });
    }
    let bound = m.bind(values);
    let schedule = Schedule::new(&bound, ts);
    let mut machine = Machine::new(&bound, values);
    machine.strict_resets = false;
    let mut out = GrayBoxRun::empty(data, m.states, (first + 1).min(n - 1), Kept::Everything);
    let mut u = vec![0.0; m.inputs];
    let mut buffer = Vec::new();
    for k in first..n.saturating_sub(1) {
        let at_k = free.as_ref().map(|r| carried(m, r, k)).unwrap_or_default();
        let slope = estimate_velocity(data.y(), k, ts);
        let x = measured_state(
            &bound,
            &mut machine,
            (data, &schedule),
            k,
            &at_k,
            slope,
            velocity_tol,
        )?;
        schedule.inputs(data, k, 0.0, &mut u);
        let mut hs = machine.state_at(x, &u, mode);
        let count = schedule.fill(data, k, &mut buffer)?;
        let pieces = &buffer[..count];
        let mut g_end = Vec::new();
        for (j, (duration, u, n_sub)) in pieces.iter().enumerate() {
            if j > 0 {
                machine.resettle(&mut hs, u);
                let g_before = std::mem::take(&mut g_end);
                let before = (None, &pieces[j - 1].1[..]);
                machine.fire_across_jump(&mut hs, u, &g_before, before, k)?;
            }
            machine.advance(&mut hs, u, (*duration, *n_sub), k, false)?;
            machine.surfaces_at_end(&hs, u, &mut g_end);
        }
        let held = &pieces[pieces.len() - 1].1;
        schedule.inputs(data, k + 1, 0.0, &mut u);
        let (y, label, covered) = machine.observe(&hs, &u, held);
        out.y[k + 1] = y;
        out.modes[k + 1] = Some(label);
        out.covered[k + 1] = covered;
        out.x[(k + 1) * m.states..(k + 2) * m.states].copy_from_slice(&hs.x);
    }
    out.steps = machine.steps;
    out.events = machine.events;
    out.zeno = machine.zeno;
    Ok(out)
}
