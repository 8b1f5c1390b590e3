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
//! is integrated without events; [`GrayBoxRun::zeno_steps`] counts these.
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

use crate::compile::{CompiledElement, CompiledInitial, CompiledMode, CompiledModel};
use crate::expr::Crossing;
use hysid_model::data::{Dataset, RowRange};
use hysid_model::simulate::{SimError, estimate_velocity, substeps};
use hysid_numerics::budget::Deadline;
pub use hysid_numerics::event_location::LOCATE_RESOLUTION;
use hysid_numerics::least_squares::{
    CentralDifferences, Damping, Exact, LmSettings, Residuals, descend,
};
use linear::{AffineFlows, AffineRow, ClosedStep, affine_guards};
use nalgebra::DMatrix;
use sensitivity::Tangent;
pub use sensitivity::{Sensitivities, differentiable};
pub use shooting::{segmented, segmented_with_sensitivities};
use std::rc::Rc;

mod linear;
mod locate;
mod quiet;
mod sensitivity;
mod shooting;

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
    /// Sub-steps that reached [`MAX_EVENTS_PER_STEP`].
    pub zeno_steps: usize,
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
            zeno_steps: 0,
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

/// The guard surfaces of `mode`'s transitions at `slots` into `out`.
fn surfaces(mode: &CompiledMode, slots: &[f64], out: &mut Vec<f64>) {
    out.clear();
    out.extend(mode.transitions.iter().map(|t| t.guard.surface.eval(slots)));
}

/// The guard surfaces of the current mode at the start of a step and at
/// its trial end; the end of a step taken is the start of the next.
#[derive(Debug, Default)]
struct Surfaces {
    both: [Vec<f64>; 2],
    /// Which of `both` holds the start.
    start: usize,
    /// The mode and state the start was evaluated at, kept when a sample
    /// ends with it current ([`Surfaces::keep`]); forgotten when the start
    /// changes.
    kept: Option<usize>,
    kept_x: Vec<f64>,
}

impl Surfaces {
    fn start(&self) -> &[f64] {
        &self.both[self.start]
    }

    fn end(&self) -> &[f64] {
        &self.both[1 - self.start]
    }

    fn start_mut(&mut self) -> &mut Vec<f64> {
        self.kept = None;
        &mut self.both[self.start]
    }

    fn end_mut(&mut self) -> &mut Vec<f64> {
        &mut self.both[1 - self.start]
    }

    /// The start and the trial end resized to `len` surfaces, both
    /// writable: a caller that swaps their roles itself tells how many
    /// times by [`Surfaces::stepped`].
    fn start_and_end_mut(&mut self, len: usize) -> (&mut [f64], &mut [f64]) {
        let [a, b] = &mut self.both;
        let (start, end) = if self.start == 0 { (a, b) } else { (b, a) };
        end.resize(len, 0.0);
        (start, end)
    }

    /// `steps` times [`Surfaces::step`].
    fn stepped(&mut self, steps: usize) {
        if steps > 0 {
            self.kept = None;
            self.start ^= steps & 1;
        }
    }

    /// Records that the start holds the surfaces of `mode` at `x`.
    fn keep(&mut self, mode: usize, x: &[f64]) {
        self.kept = Some(mode);
        self.kept_x.clear();
        self.kept_x.extend_from_slice(x);
    }

    /// Whether the start holds the surfaces of `mode` at `x` (the same
    /// bits) by [`Surfaces::keep`].
    fn kept_at(&self, mode: usize, x: &[f64]) -> bool {
        self.kept == Some(mode)
            && self.kept_x.len() == x.len()
            && self
                .kept_x
                .iter()
                .zip(x)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }

    /// The trial end becomes the start (by index: no vector moves).
    fn step(&mut self) {
        self.kept = None;
        self.start = 1 - self.start;
    }
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
    /// elements' regimes they were listed for, and `None` where an element
    /// is held (the lane closed).
    watch: (Vec<ElementRegime>, Option<Vec<StateEnd>>),
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
    /// ([`SimError::ResetOutsideInvariant`]): a fault of the model in a run
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
    pub(crate) zeno_steps: usize,
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
            watch: (Vec::new(), None),
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
            zeno_steps: 0,
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

    /// The model the flows and friction levels are read from: the sliding
    /// regime's ([`Machine::select`]), or the model itself.
    #[inline]
    fn bound(&self) -> &CompiledModel {
        self.current.as_deref().map_or(self.m, |s| &s.bound)
    }

    /// The affine form of `mode`'s flows in the selected regime.
    fn affine_of(&self, mode: usize) -> Option<&AffineFlows> {
        match self.current.as_deref() {
            Some(s) => s.affine[mode].as_ref(),
            None => self.affine[mode].as_ref(),
        }
    }

    /// Selects the model of the sliding regime of `hs` (every friction
    /// element that slips, but on the velocity `except`), built the first
    /// time the regime is met; nothing to do where no direction decides
    /// anything.
    fn select(&mut self, hs: &HybridState, except: Option<usize>) {
        if !self.decides {
            return;
        }
        let direction = |e: &CompiledElement, r: &ElementRegime| match (e, r) {
            (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Slip(dir))
                if Some(*velocity) != except =>
            {
                Some(*dir > 0.0)
            }
            _ => None,
        };
        let pairs = self.m.elements.iter().zip(&hs.regimes);
        if self.directions.len() == hs.regimes.len()
            && pairs
                .clone()
                .zip(&self.directions)
                .all(|((e, r), d)| direction(e, r) == *d)
        {
            return;
        }
        self.directions.clear();
        self.directions.extend(pairs.map(|(e, r)| direction(e, r)));
        if let Some((_, s)) = self.sliding.iter().find(|(d, _)| *d == self.directions) {
            self.current = s.clone();
        } else {
            let sliding: Vec<(usize, bool)> = self
                .m
                .elements
                .iter()
                .zip(&self.directions)
                .filter_map(|(e, d)| match e {
                    CompiledElement::DryFriction { velocity, .. } => Some((*velocity, (*d)?)),
                    CompiledElement::Stop { .. } => None,
                })
                .collect();
            let model = self.m.sliding(&sliding).map(|bound| {
                let affine = affine_forms(&bound);
                let unbound = self
                    .unbound
                    .map(|m| m.sliding(&sliding).unwrap_or_else(|| m.clone()));
                Rc::new(Sliding {
                    bound,
                    affine,
                    unbound,
                })
            });
            self.sliding.push((self.directions.clone(), model.clone()));
            self.current = model;
        }
    }

    /// Loads `(x, u)` into the slots.
    #[inline]
    fn load(&mut self, x: &[f64], u: &[f64]) {
        load(&mut self.slots, x, u);
    }

    /// The applied force on velocity `v` (its flow without the friction).
    #[inline]
    fn force(&self, mode: usize, v: usize) -> f64 {
        self.bound().modes[mode].flow[v].eval(&self.slots)
    }

    /// Kinetic and static levels of friction element `e` in `mode`.
    #[inline]
    fn levels(&self, mode: usize, e: usize) -> (f64, f64) {
        let (kinetic, static_level) = &self.bound().modes[mode].friction[e];
        let k = kinetic.eval(&self.slots).max(0.0);
        (k, static_level.eval(&self.slots).max(k))
    }

    /// The static level on velocity `v` in `mode` (0 without friction).
    fn static_on(&self, mode: usize, v: usize) -> f64 {
        self.friction_of[v].map_or(0.0, |e| self.levels(mode, e).1)
    }

    /// Lists what the elements do to the flows in the regimes of `hs`, and
    /// selects the model of its sliding regime.
    fn prepare(&mut self, hs: &HybridState) {
        self.select(hs, None);
        if self.effects_of == hs.regimes {
            return;
        }
        self.effects_of.clone_from(&hs.regimes);
        self.effects.clear();
        for (i, e) in self.m.elements.iter().enumerate() {
            match (e, hs.regimes[i]) {
                (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Slip(dir)) => {
                    self.effects.push(Effect::Friction(*velocity, i, dir));
                }
                (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Stuck) => {
                    self.effects.push(Effect::Hold(*velocity));
                }
                (
                    CompiledElement::Stop {
                        position, velocity, ..
                    },
                    ElementRegime::Resting,
                ) => {
                    self.effects.push(Effect::Hold(*position));
                    self.effects.push(Effect::Hold(*velocity));
                }
                _ => {}
            }
        }
    }

    /// The state derivative in `mode` at the loaded slots, with the
    /// [`Machine::prepare`]d effects of the elements.
    #[inline]
    fn flows(&self, mode: usize, out: &mut [f64]) {
        let q = &self.bound().modes[mode];
        let out = &mut out[..q.flow.len()];
        q.joint_flow.eval(&q.flow, &self.slots, out);
        if !self.effects.is_empty() {
            for (s, o) in out.iter_mut().enumerate() {
                *o = self.with_effects(q, s, *o);
            }
        }
    }

    /// The derivative of state `s` in mode `q` at the loaded slots
    /// ([`Machine::with_effects`] on its flow).
    #[inline]
    fn derivative_of(&self, q: &CompiledMode, s: usize) -> f64 {
        self.with_effects(q, s, q.flow[s].eval(&self.slots))
    }

    /// The derivative of state `s` in mode `q` whose flow is `d` at the
    /// loaded slots: less the level of a friction sliding on it in its
    /// direction, zero where the [`Machine::prepare`]d effects hold it.
    #[inline]
    fn with_effects(&self, q: &CompiledMode, s: usize, mut d: f64) -> f64 {
        for effect in &self.effects {
            match *effect {
                Effect::Friction(v, i, dir) if v == s => {
                    d -= q.friction[i].0.eval(&self.slots).max(0.0) * dir;
                }
                Effect::Hold(h) if h == s => d = 0.0,
                _ => {}
            }
        }
        d
    }

    /// One RK4 step of length `h` from `hs.x` into `out`: in closed form
    /// where the regime has one ([`linear`]), else stage by stage, the
    /// stages written into the slots directly.
    fn rk4(&mut self, hs: &HybridState, u: &[f64], h: f64, out: &mut [f64]) {
        if self.closed_form {
            self.form_closed_step(hs);
            if let Some((.., Some(step))) = &self.closed {
                if h == self.full_step {
                    step.apply(&hs.x, u, out);
                } else {
                    let [k, t, ..] = &mut self.k;
                    step.apply_length(h, &hs.x, u, (k, t), out);
                }
                self.steps += 1;
                return;
            }
        }
        let [mut k1, mut k2, mut k3, mut k4] = std::mem::take(&mut self.k);
        self.load(&hs.x, u);
        self.prepare(hs);
        let q = hs.mode;
        self.flows(q, &mut k1);
        self.stage(hs, &k1, 0.5 * h);
        self.flows(q, &mut k2);
        self.stage(hs, &k2, 0.5 * h);
        self.flows(q, &mut k3);
        self.stage(hs, &k3, h);
        self.flows(q, &mut k4);
        let sixth = h / 6.0;
        for (((((o, x), a), b), c), d) in out
            .iter_mut()
            .zip(&hs.x)
            .zip(&k1)
            .zip(&k2)
            .zip(&k3)
            .zip(&k4)
        {
            *o = x + sixth * (a + 2.0 * b + 2.0 * c + d);
        }
        self.k = [k1, k2, k3, k4];
        self.steps += 1;
    }

    /// The closed-form step of the regime of `hs` and the sub-step length
    /// ([`linear`]; `None` where the regime has none) into
    /// [`Machine::closed`], formed when the regime or the length differs
    /// from the last one's.
    fn form_closed_step(&mut self, hs: &HybridState) {
        let h = self.full_step;
        let key = |(mode, regimes, length, _): &ClosedEntry| {
            *mode == hs.mode && *length == h && *regimes == hs.regimes
        };
        if !self.closed.as_ref().is_some_and(key) {
            self.prepare(hs);
            if let Some(at) = self.formed.iter().position(key) {
                let entry = self.formed.remove(at);
                self.keep_formed(entry);
                return;
            }
            let step = match self.affine_of(hs.mode) {
                Some(flows) => {
                    let mut held = vec![false; self.m.states];
                    let mut sliding = Vec::new();
                    for effect in &self.effects {
                        match *effect {
                            Effect::Friction(v, i, dir) => sliding.push((i, v, dir)),
                            Effect::Hold(s) => held[s] = true,
                        }
                    }
                    flows.step(h, &held, &sliding)
                }
                None => None,
            };
            self.keep_formed((hs.mode, hs.regimes.clone(), h, step));
        }
    }

    /// Makes `entry` the current closed-form step, the one it replaces
    /// kept among the [`FORMED_STEPS`] last formed.
    fn keep_formed(&mut self, entry: ClosedEntry) {
        if let Some(previous) = self.closed.replace(entry) {
            if self.formed.len() == FORMED_STEPS {
                self.formed.remove(0);
            }
            self.formed.push(previous);
        }
    }

    /// Loads the RK4 stage state `x + step * k` into the slots.
    #[inline]
    fn stage(&mut self, hs: &HybridState, k: &[f64], step: f64) {
        for ((slot, x), k) in self.slots.iter_mut().zip(&hs.x).zip(k) {
            *slot = x + step * k;
        }
    }

    /// The guard surfaces at the end of a sample (state `hs`, input `u`)
    /// into `out`, for [`Machine::fire_across_jump`] to compare across the
    /// next input's jump; nothing where no guard surface of the mode reads
    /// an input (the jump cannot move them).
    fn surfaces_at_end(&mut self, hs: &HybridState, u: &[f64], out: &mut Vec<f64>) {
        if self.shortcuts && !self.input_guards[hs.mode] {
            out.clear();
        } else {
            self.load(&hs.x, u);
            surfaces(&self.m.modes[hs.mode], &self.slots, out);
        }
    }

    /// Loads `(x, u)` and evaluates the guard surfaces there into the
    /// step's trial end.
    fn surfaces_at(&mut self, x: &[f64], u: &[f64], mode: usize) {
        self.load(x, u);
        surfaces(&self.m.modes[mode], &self.slots, self.g.end_mut());
    }

    /// Whether the step to `x` under `u` certainly ends without an event,
    /// decided from the state alone where it can be: no stop reached, no
    /// sliding velocity at zero, no element held (a held element's
    /// release depends on the forces), and no guard crossed, the surfaces
    /// read from their affine forms into the trial end. `false` when it
    /// cannot tell: then [`Machine::first_event`] decides.
    fn quiet_step(&mut self, hs: &HybridState, x: &[f64], u: &[f64]) -> bool {
        let Some(guards) = &self.guards[hs.mode] else {
            return false;
        };
        for (i, &regime) in hs.regimes.iter().enumerate() {
            let held = matches!(regime, ElementRegime::Stuck | ElementRegime::Resting);
            if held || self.ended_by_state(i, regime, x) {
                return false;
            }
        }
        let end = self.g.end_mut();
        end.clear();
        end.extend(guards.iter().map(|(_, row)| row.eval(x, u)));
        !guards
            .iter()
            .zip(self.g.start().iter().zip(self.g.end()))
            .any(|((c, _), (g0, g1))| crossed(*c, *g0, *g1))
    }

    /// Whether element `i` has left `regime` at the state `x`, for the
    /// regimes whose end the state alone decides: a stop reached or passed
    /// while away, a sliding velocity come to zero or reversed. A held
    /// element's release depends on the forces ([`Machine::first_event`]).
    fn ended_by_state(&self, i: usize, regime: ElementRegime, x: &[f64]) -> bool {
        self.state_end(i, regime)
            .is_some_and(|end| end.margin(x) >= 0.0)
    }

    /// The state test that ends element `i`'s `regime` (a stop reached or
    /// passed while away, a sliding velocity come to zero or reversed);
    /// `None` for a held element, whose release the forces decide.
    fn state_end(&self, i: usize, regime: ElementRegime) -> Option<StateEnd> {
        match (&self.m.elements[i], regime) {
            (CompiledElement::Stop { position, sign, .. }, ElementRegime::Away) => Some(StateEnd {
                state: *position,
                sign: *sign,
                level: self.fixed[i].0,
            }),
            (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Slip(dir)) => {
                Some(StateEnd {
                    state: *velocity,
                    sign: -dir,
                    level: 0.0,
                })
            }
            _ => None,
        }
    }

    /// The first event at state `x` (loaded, with the guard surfaces there
    /// as the step's trial end), given the surfaces at the start of the step.
    fn first_event(&self, hs: &HybridState, x: &[f64]) -> Option<Event> {
        let m = self.m;
        let mut friction = None;
        for (i, e) in m.elements.iter().enumerate() {
            match (e, hs.regimes[i]) {
                (CompiledElement::Stop { .. }, regime @ ElementRegime::Away)
                    if self.ended_by_state(i, regime, x) =>
                {
                    return Some(Event::Element(i));
                }
                (CompiledElement::Stop { velocity, sign, .. }, ElementRegime::Resting)
                    if -sign * self.force(hs.mode, *velocity)
                        - self.static_on(hs.mode, *velocity)
                        > 0.0 =>
                {
                    return Some(Event::Element(i));
                }
                (CompiledElement::DryFriction { .. }, regime @ ElementRegime::Slip(_))
                    if self.ended_by_state(i, regime, x) =>
                {
                    friction = friction.or(Some(i));
                }
                (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Stuck)
                    if !self.held_by_stop(hs, *velocity)
                        && self.force(hs.mode, *velocity).abs() - self.levels(hs.mode, i).1
                            > 0.0 =>
                {
                    friction = friction.or(Some(i));
                }
                _ => {}
            }
        }
        if let Some(i) = friction {
            return Some(Event::Element(i));
        }
        self.first_transition(hs)
    }

    /// A stop on velocity `v` holds it.
    fn held_by_stop(&self, hs: &HybridState, v: usize) -> bool {
        self.m.elements.iter().enumerate().any(|(i, e)| {
            matches!(e, CompiledElement::Stop { velocity, .. } if *velocity == v)
                && hs.regimes[i] == ElementRegime::Resting
        })
    }

    /// Karnopp's rule for velocity `v` at zero: rest at a stop it is pushed
    /// into, stick within the static level, else slide off along the force.
    fn settle(&mut self, hs: &mut HybridState, u: &[f64], v: usize) {
        hs.x[v] = 0.0;
        self.tangent_zero(v);
        self.load(&hs.x, u);
        // At zero the velocity slides neither way.
        self.select(hs, Some(v));
        let f = self.force(hs.mode, v);
        let fs = self.static_on(hs.mode, v);
        let m = self.m;
        let mut resting = false;
        for (i, e) in m.elements.iter().enumerate() {
            if let CompiledElement::Stop {
                position,
                velocity,
                sign,
                ..
            } = e
                && *velocity == v
            {
                let at = self.fixed[i].0;
                hs.regimes[i] = if !resting && hs.x[*position] == at && sign * f >= -fs {
                    resting = true;
                    ElementRegime::Resting
                } else {
                    ElementRegime::Away
                };
            }
        }
        if let Some(e) = self.friction_of[v] {
            hs.regimes[e] = if resting || f.abs() <= fs {
                ElementRegime::Stuck
            } else {
                ElementRegime::Slip(f.signum())
            };
        }
    }

    /// Whether `ev` is a stop's (its reset moves the state by a jump).
    fn stop_event(&self, ev: Event) -> bool {
        matches!(ev, Event::Element(i) if matches!(self.m.elements[i], CompiledElement::Stop { .. }))
    }

    /// Applies an event at the located state `hs.x`.
    fn apply(
        &mut self,
        hs: &mut HybridState,
        u: &[f64],
        ev: Event,
        sample: usize,
    ) -> Result<(), SimError> {
        self.events += 1;
        let m = self.m;
        match ev {
            Event::Element(i) => match (&m.elements[i], hs.regimes[i]) {
                (CompiledElement::Stop { velocity, .. }, ElementRegime::Resting) => {
                    hs.regimes[i] = ElementRegime::Away;
                    let v = *velocity;
                    self.load(&hs.x, u);
                    let f = self.force(hs.mode, v);
                    if let Some(fe) = self.friction_of[v] {
                        hs.regimes[fe] = ElementRegime::Slip(f.signum());
                    }
                }
                (
                    CompiledElement::Stop {
                        position,
                        velocity,
                        rest_speed,
                        sign,
                        ..
                    },
                    _,
                ) => {
                    let (at, e) = self.fixed[i];
                    hs.x[*position] = at;
                    self.tangent_onto_stop(i);
                    let rebound = -e * hs.x[*velocity];
                    if sign * rebound < 0.0 && rebound.abs() > *rest_speed {
                        self.tangent_rebound(i, hs.x[*velocity]);
                        hs.x[*velocity] = rebound;
                        if let Some(f) = self.friction_of[*velocity] {
                            hs.regimes[f] = ElementRegime::Slip(rebound.signum());
                        }
                    } else {
                        self.settle(hs, u, *velocity);
                    }
                }
                (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Slip(_)) => {
                    self.settle(hs, u, *velocity);
                }
                (CompiledElement::DryFriction { velocity, .. }, _) => {
                    self.load(&hs.x, u);
                    let f = self.force(hs.mode, *velocity);
                    hs.regimes[i] = ElementRegime::Slip(f.signum());
                }
            },
            Event::Transition(j) => {
                let t = &m.modes[hs.mode].transitions[j];
                self.load(&hs.x, u);
                let values: Vec<(usize, f64)> = t
                    .reset
                    .iter()
                    .map(|(s, e)| (*s, e.eval(&self.slots)))
                    .collect();
                self.tangent_reset(hs.mode, j);
                for (s, v) in values {
                    hs.x[s] = v;
                }
                hs.mode = t.to;
                self.load(&hs.x, u);
                if self.strict_resets
                    && m.modes[hs.mode]
                        .invariant
                        .iter()
                        .any(|r| r.margin(&self.slots) < -INVARIANT_TOLERANCE)
                {
                    return Err(SimError::ResetOutsideInvariant {
                        transition: t.label.clone(),
                        sample,
                    });
                }
            }
        }
        Ok(())
    }

    /// Fires the transitions whose guards a jump crossed (`g_before`: the
    /// surfaces before it): the input's at a sample instant, a stop's
    /// reset; whether one fired.
    fn fire_across_jump(
        &mut self,
        hs: &mut HybridState,
        u: &[f64],
        g_before: &[f64],
        sample: usize,
    ) -> Result<bool, SimError> {
        if g_before.is_empty() {
            return Ok(false);
        }
        let start = self.g.start_mut();
        start.clear();
        start.extend_from_slice(g_before);
        self.surfaces_at(&hs.x, u, hs.mode);
        if let Some(Event::Transition(j)) = self.first_transition(hs) {
            self.apply(hs, u, Event::Transition(j), sample)?;
            return Ok(true);
        }
        Ok(false)
    }

    /// The first transition whose guard was crossed from the step's start
    /// to its trial end and whose condition holds (loaded slots).
    fn first_transition(&self, hs: &HybridState) -> Option<Event> {
        self.m.modes[hs.mode]
            .transitions
            .iter()
            .enumerate()
            .find(|(j, t)| {
                crossed(t.guard.crossing, self.g.start()[*j], self.g.end()[*j])
                    && t.when.as_ref().is_none_or(|w| w.eval(&self.slots) != 0.0)
            })
            .map(|(j, _)| Event::Transition(j))
    }

    /// Re-settles the held velocities under a new input: a stuck friction
    /// or a resting stop whose force now exceeds its level lets go.
    /// Whether any element was held.
    fn resettle(&mut self, hs: &mut HybridState, u: &[f64]) -> bool {
        let m = self.m;
        let mut held = false;
        for i in 0..m.elements.len() {
            let v = match (&m.elements[i], hs.regimes[i]) {
                (CompiledElement::Stop { velocity, .. }, ElementRegime::Resting)
                | (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Stuck) => {
                    *velocity
                }
                _ => continue,
            };
            self.settle(hs, u, v);
            held = true;
        }
        held
    }

    /// Advances `hs` over one sample of length `ts` in `n_sub` sub-steps
    /// with the input `u` held. `moving`: the caller's rest test already
    /// found the state moving under `u`, so it is not repeated.
    pub(crate) fn advance(
        &mut self,
        hs: &mut HybridState,
        u: &[f64],
        (ts, n_sub): (f64, usize),
        sample: usize,
        moving: bool,
    ) -> Result<(), SimError> {
        let h = ts / n_sub as f64;
        if !moving && self.at_rest(hs, u) {
            self.tangent_rest(hs, u, std::iter::repeat_n(h, n_sub));
            return Ok(());
        }
        self.full_step = h;
        let mut x1 = std::mem::take(&mut self.x1);
        let mut xm = std::mem::take(&mut self.xm);
        let mut result = Ok(());
        // Whether the start surfaces are those at hs.x: kept from the
        // sample before where no guard reads an input, evaluated again
        // after an event.
        let mut fresh =
            self.shortcuts && !self.input_guards[hs.mode] && self.g.kept_at(hs.mode, &hs.x);
        let mut step = 0;
        'steps: while step < n_sub {
            step += self.quiet_substeps(hs, u, n_sub - step, &mut fresh, &mut x1);
            if step == n_sub {
                break;
            }
            let mut left = h;
            self.tangent_substep();
            let mut events = 0;
            // At most MAX_EVENTS_PER_STEP events, then one event-free step.
            while left > 0.0 {
                if !fresh {
                    self.surfaces_at(&hs.x, u, hs.mode);
                    self.g.step();
                    fresh = true;
                }
                self.rk4(hs, u, left, &mut x1);
                if events >= MAX_EVENTS_PER_STEP {
                    self.tangent_step(hs, u, left, true);
                    hs.x.copy_from_slice(&x1);
                    fresh = false;
                    break;
                }
                if self.quiet_step(hs, &x1, u) {
                    self.tangent_step(hs, u, left, true);
                    hs.x.copy_from_slice(&x1);
                    self.g.step();
                    break;
                }
                self.surfaces_at(&x1, u, hs.mode);
                let Some(mut ev) = self.first_event(hs, &x1) else {
                    self.tangent_step(hs, u, left, true);
                    hs.x.copy_from_slice(&x1);
                    self.g.step();
                    break;
                };
                // The last state before the event, for the sensitivities.
                let mut before = self.differentiates().then(|| hs.clone());
                let (lo, hi) = self.locate(hs, u, left, &mut ev, (&mut x1, &mut xm), &mut before);
                if let Some(before) = before {
                    self.tangent_step(hs, u, lo, false);
                    self.tangent_event(&before, u, ev);
                }
                hs.x.copy_from_slice(&x1);
                fresh = false;
                // A stop's reset jumps the state: the guards it jumps
                // across fire as across an input's jump.
                let before_jump = self.stop_event(ev).then(|| {
                    let mut g = Vec::new();
                    self.load(&hs.x, u);
                    surfaces(&self.m.modes[hs.mode], &self.slots, &mut g);
                    g
                });
                if let Err(e) = self.apply(hs, u, ev, sample) {
                    result = Err(e);
                    break 'steps;
                }
                if let Some(g) = before_jump
                    && let Err(e) = self.fire_across_jump(hs, u, &g, sample)
                {
                    result = Err(e);
                    break 'steps;
                }
                left -= hi;
                events += 1;
                if events >= MAX_EVENTS_PER_STEP {
                    self.zeno_steps += 1;
                    self.hold_reached_stops(hs, u);
                }
                if self.at_rest(hs, u) {
                    // Come to rest: the rest of the sample changes nothing
                    // but the sensitivities.
                    let rest = std::iter::repeat_n(h, n_sub - step - 1);
                    self.tangent_rest(hs, u, std::iter::once(left).chain(rest));
                    break 'steps;
                }
            }
            step += 1;
        }
        if fresh && result.is_ok() {
            self.g.keep(hs.mode, &hs.x);
        }
        self.x1 = x1;
        self.xm = xm;
        result
    }

    /// Every derivative of the state is exactly zero under the input `u`
    /// (read state by state up to the first that is not).
    fn at_rest(&mut self, hs: &HybridState, u: &[f64]) -> bool {
        self.load(&hs.x, u);
        self.prepare(hs);
        let q = &self.bound().modes[hs.mode];
        (0..q.flow.len()).all(|s| self.derivative_of(q, s) == 0.0)
    }

    /// The Zeno bound's action: every stop that has been reached holds.
    fn hold_reached_stops(&mut self, hs: &mut HybridState, u: &[f64]) {
        for (i, position, velocity, at, _) in self.reached_stops(&hs.x) {
            hs.x[position] = at;
            self.tangent_onto_stop(i);
            self.settle(hs, u, velocity);
        }
    }

    /// The stops that `x` has reached or passed: `(element, position
    /// state, velocity state, level, sign)`.
    fn reached_stops(&self, x: &[f64]) -> Vec<(usize, usize, usize, f64, f64)> {
        self.stops_with_velocity()
            .filter(|(_, position, _, at, sign)| sign * (x[*position] - at) >= 0.0)
            .collect()
    }

    /// Every stop: `(element, position state, velocity state, level, sign)`.
    fn stops_with_velocity(&self) -> impl Iterator<Item = (usize, usize, usize, f64, f64)> + '_ {
        self.m
            .elements
            .iter()
            .zip(&self.fixed)
            .enumerate()
            .filter_map(|(i, (e, (at, _)))| match e {
                CompiledElement::Stop {
                    position,
                    velocity,
                    sign,
                    ..
                } => Some((i, *position, *velocity, *at, *sign)),
                CompiledElement::DryFriction { .. } => None,
            })
    }

    /// The output of the state under the sample's input `u`.
    fn output(&mut self, hs: &HybridState, u: &[f64]) -> f64 {
        self.load(&hs.x, u);
        self.m.modes[hs.mode].output.eval(&self.slots)
    }

    /// The output of the state under the sample's input `u`, its mode label,
    /// and whether it satisfies its mode's invariant under `held`, the input
    /// that brought it there (the regime reached, before the new input acts).
    pub fn observe(&mut self, hs: &HybridState, u: &[f64], held: &[f64]) -> (f64, usize, bool) {
        let m = self.m;
        let invariant = &m.modes[hs.mode].invariant;
        let covered = invariant.is_empty() || {
            self.load(&hs.x, held);
            invariant
                .iter()
                .all(|r| r.margin(&self.slots) >= -INVARIANT_TOLERANCE)
        };
        let y = self.output(hs, u);
        // A stop's label where one holds the state, else a stuck
        // friction's, else the mode's.
        let mut stuck = None;
        for (e, r) in m.elements.iter().zip(&hs.regimes) {
            match (e, r) {
                (CompiledElement::Stop { label, .. }, ElementRegime::Resting) => {
                    return (y, *label, covered);
                }
                (CompiledElement::DryFriction { label, .. }, ElementRegime::Stuck) => {
                    stuck = stuck.or(Some(*label));
                }
                _ => {}
            }
        }
        (y, stuck.unwrap_or(hs.mode), covered)
    }

    /// Sets the state `position` of `x` to the inverse of `mode`'s output
    /// map at the measured output `y` (the map is affine in it, checked when
    /// the model is compiled: `y = a + b x`, with `a` and `b` read at
    /// `x = 0` and `x = 1`, the other states and the inputs `u` held);
    /// returns the gain `b`. A gain of zero (or not finite) is an error:
    /// the output then says nothing of the state.
    pub(crate) fn sensor(
        &mut self,
        x: &mut [f64],
        u: &[f64],
        mode: usize,
        position: usize,
        y: f64,
    ) -> Result<f64, SimError> {
        let output = &self.m.modes[mode].output;
        x[position] = 0.0;
        self.load(x, u);
        let a = output.eval(&self.slots);
        x[position] = 1.0;
        self.load(x, u);
        let gain = output.eval(&self.slots) - a;
        if !(gain.is_finite() && gain != 0.0 && a.is_finite()) {
            return Err(SimError::InitialState(format!(
                "the output map's gain in the measured state is {gain}: the output does not give the state"
            )));
        }
        x[position] = (y - a) / gain;
        Ok(gain)
    }

    /// The flows of `mode` at `(x, u)` into `out`, without the elements
    /// (what a rest state zeroes: a friction holds a velocity at zero
    /// whatever its level, a stop a position at its level).
    pub(crate) fn bare_flows(&mut self, x: &[f64], u: &[f64], mode: usize, out: &mut [f64]) {
        self.load(x, u);
        for (o, f) in out.iter_mut().zip(&self.m.modes[mode].flow) {
            *o = f.eval(&self.slots);
        }
    }

    /// The Jacobian of [`Machine::bare_flows`] in the states at `(x, u)`
    /// (row `i`: the flow of state `i`), exact through the expressions'
    /// tapes ([`crate::expr::Expression::gradient`]).
    pub(crate) fn bare_flow_jacobian(&mut self, x: &[f64], u: &[f64], mode: usize) -> DMatrix<f64> {
        self.load(x, u);
        let n = x.len();
        let states: Vec<u32> = (0..n as u32).collect();
        let mut jac = DMatrix::zeros(n, n);
        let mut row = vec![0.0; n];
        for (i, f) in self.m.modes[mode].flow.iter().enumerate().take(n) {
            f.gradient(&self.slots, &states, &mut row);
            jac.row_mut(i).copy_from_slice(&row);
        }
        jac
    }

    /// Whether `(x, u)` satisfies `mode`'s invariant.
    pub(crate) fn in_invariant(&mut self, x: &[f64], u: &[f64], mode: usize) -> bool {
        self.load(x, u);
        self.m.modes[mode]
            .invariant
            .iter()
            .all(|r| r.margin(&self.slots) >= -INVARIANT_TOLERANCE)
    }

    /// The hybrid state at `(x, u)`: positions clamped to their stops, the
    /// mode `mode` or the first whose invariant holds, every velocity at
    /// zero settled.
    pub fn state_at(&mut self, mut x: Vec<f64>, u: &[f64], mode: Option<usize>) -> HybridState {
        let m = self.m;
        for (i, position, velocity, at, sign) in self.reached_stops(&x) {
            x[position] = at;
            self.tangent_onto_stop(i);
            if sign * x[velocity] > 0.0 {
                x[velocity] = 0.0;
                self.tangent_zero(velocity);
            }
        }
        let mode = mode.unwrap_or_else(|| {
            (0..m.modes.len())
                .find(|&q| {
                    self.load(&x, u);
                    m.modes[q]
                        .invariant
                        .iter()
                        .all(|r| r.margin(&self.slots) >= -INVARIANT_TOLERANCE)
                })
                .unwrap_or(0)
        });
        let regimes = m
            .elements
            .iter()
            .map(|e| match e {
                CompiledElement::DryFriction { velocity, .. } => {
                    ElementRegime::Slip(x[*velocity].signum())
                }
                CompiledElement::Stop { .. } => ElementRegime::Away,
            })
            .collect();
        let mut hs = HybridState { x, mode, regimes };
        for (i, e) in m.elements.iter().enumerate() {
            let v = match e {
                CompiledElement::DryFriction { velocity, .. }
                | CompiledElement::Stop { velocity, .. } => *velocity,
            };
            let at_stop = matches!(e, CompiledElement::Stop { position, .. } if hs.x[*position] == self.fixed[i].0);
            if hs.x[v] == 0.0 || at_stop {
                self.settle(&mut hs, u, v);
            }
        }
        hs
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

/// The inputs as the model sees them: each held over its sample and, when
/// the model gives it a delay `d = q ts + r`, seen `q` samples and `r`
/// seconds late. Within sample `k` such an input is the recorded one of
/// sample `k - q - 1` until `r`, then that of `k - q` (the first sample's
/// before the record starts), so a sample is cut into pieces of constant
/// input at the remainders.
struct Schedule {
    /// Per input: whole samples of delay and the remainder, seconds.
    lags: Vec<(usize, f64)>,
    /// The ends of the pieces within a sample: the remainders, then `ts`.
    cuts: Vec<f64>,
    /// The sampling time.
    ts: f64,
    /// The model's longest integration step.
    internal_step: f64,
    /// Sub-steps of a whole sample, where its step is valid.
    whole: Option<usize>,
}

/// A piece of a sample: duration, the inputs held over it, sub-steps.
type Piece = (f64, Vec<f64>, usize);

impl Schedule {
    /// The delays of the bound model `m` at the sampling time `ts`
    /// (negative delays count as 0).
    fn new(m: &CompiledModel, ts: f64) -> Self {
        let lags: Vec<(usize, f64)> = m
            .delays
            .iter()
            .map(|d| {
                let d = d.as_constant().unwrap_or(0.0).max(0.0);
                let q = (d / ts + 1e-9).floor();
                let r = d - q * ts;
                (q as usize, if r <= 1e-9 * ts { 0.0 } else { r })
            })
            .collect();
        let mut cuts: Vec<f64> = lags.iter().map(|(_, r)| *r).filter(|r| *r > 0.0).collect();
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        cuts.push(ts);
        Schedule {
            lags,
            cuts,
            ts,
            internal_step: m.internal_step,
            whole: substeps(ts, m.internal_step).ok(),
        }
    }

    /// The input of sample `k` in effect from `t` seconds into it.
    fn inputs(&self, data: &Dataset, k: usize, t: f64, u: &mut [f64]) {
        for (i, (x, (q, r))) in u.iter_mut().zip(&self.lags).enumerate() {
            let back = q + usize::from(t < *r);
            *x = data.inputs[i].values[k.saturating_sub(back)];
        }
    }

    /// Writes the pieces of sample `k` into `pieces` (reusing its buffers)
    /// in time order, consecutive pieces of equal inputs merged, and
    /// returns how many there are (one without delays).
    fn fill(&self, data: &Dataset, k: usize, pieces: &mut Vec<Piece>) -> Result<usize, SimError> {
        if let (&[ts], Some(n)) = (&self.cuts[..], self.whole) {
            // No delay cuts the sample: one piece of the whole sample.
            if pieces.is_empty() {
                pieces.push((0.0, vec![0.0; self.lags.len()], 0));
            }
            self.inputs(data, k, 0.0, &mut pieces[0].1);
            pieces[0].0 = ts;
            pieces[0].2 = n;
            return Ok(1);
        }
        let mut count = 0;
        let mut from = 0.0;
        for &to in &self.cuts {
            if count == pieces.len() {
                pieces.push((0.0, vec![0.0; self.lags.len()], 0));
            }
            self.inputs(data, k, from, &mut pieces[count].1);
            if count > 0 && pieces[count].1 == pieces[count - 1].1 {
                pieces[count - 1].0 += to - from;
            } else {
                pieces[count].0 = to - from;
                count += 1;
            }
            from = to;
        }
        for piece in &mut pieces[..count] {
            piece.2 = match self.whole {
                Some(n) if piece.0 == self.ts => n,
                _ => substeps(piece.0, self.internal_step)?,
            };
        }
        Ok(count)
    }
}

/// The initial sample and state of a run on `data` from the model's rule,
/// the estimated states at `estimates` ([`CompiledModel::estimates`]'
/// order; a missing value: the starting guess).
fn initial(
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
            Ok((0, machine.state_at(x, &u, *mode)))
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
fn scored_from(m: &CompiledModel) -> usize {
    match m.initial {
        CompiledInitial::Measured { samples, .. } => samples - 1,
        CompiledInitial::Given { samples, .. } if !m.estimates.is_empty() => samples - 1,
        _ => 0,
    }
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
fn measured_state(
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
fn carried(m: &CompiledModel, run: &GrayBoxRun, k: usize) -> Vec<f64> {
    let row = &run.x[k * m.states..(k + 1) * m.states];
    m.estimates.iter().map(|e| row[e.state]).collect()
}

/// Runs the compiled model with parameter values `values` on the inputs of
/// `data` (sampling time `data.ts`), from the model's initial-state rule;
/// the states the rule leaves unknown are estimated from the record's
/// warm-up outputs ([`estimate`]).
pub fn run(m: &CompiledModel, values: &[f64], data: &Dataset) -> Result<GrayBoxRun, SimError> {
    let estimates = estimate(m, values, data)?;
    run_from(m, values, &estimates, data)
}

/// [`run`] with the states the rule leaves unknown at `estimates`
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
/// [`differentiable`]). The outputs and states are [`run_from`]'s, bit
/// for bit.
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
fn free_run(
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
    out.zeno_steps = machine.zeno_steps;
    Ok(out)
}

/// The sampling time, with the record's inputs and the model's step checked.
fn timing(m: &CompiledModel, data: &Dataset) -> Result<f64, SimError> {
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
fn span(
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
                    moving &= !machine.fire_across_jump(&mut hs, u, &g_before, k)?;
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

/// One-step prediction: at each sample the state is read again from the
/// measured outputs up to it (the model's `measured` rule; the states it
/// leaves unknown are taken from the free run) and advanced by one
/// sample. A model with a given or a rest initial state has no such
/// reading: its prediction is its free run.
pub fn predict(m: &CompiledModel, values: &[f64], data: &Dataset) -> Result<GrayBoxRun, SimError> {
    let CompiledInitial::Measured {
        samples,
        velocity_tol,
        mode,
        ..
    } = m.initial
    else {
        return run(m, values, data);
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
                machine.fire_across_jump(&mut hs, u, &g_before, k)?;
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
    out.zeno_steps = machine.zeno_steps;
    Ok(out)
}

/// Iterations of the warm-up estimate's solver.
pub const ESTIMATE_ITERATIONS: usize = 100;

/// Iterations of the rest state's Newton (Levenberg-Marquardt) solve.
pub const STEADY_ITERATIONS: usize = 100;

/// Largest flow (relative to the flows at the guess, at least 1) that
/// counts as at rest.
pub const STEADY_TOLERANCE: f64 = 1e-9;

/// The cost test of the initial-state solves (the warm-up estimate, the
/// rest state): a relative decrease this small, predicted and reached.
const STATE_TOLERANCE: f64 = 1e-15;

/// The finite-difference step of the warm-up estimate, in box-normalised
/// coordinates.
const STATE_DIFFERENCE: f64 = 1e-7;

/// The settings of the initial-state solves: at most `iterations` steps,
/// the cost test at [`STATE_TOLERANCE`], states of different units damped
/// alike ([`Damping::Marquardt`]).
fn state_solve(iterations: usize) -> LmSettings {
    LmSettings::new(iterations)
        .with_cost_tolerance(STATE_TOLERANCE)
        .with_damping(Damping::Marquardt)
}

/// The states [`CompiledModel::estimates`] lists, estimated from the
/// outputs of `data`'s warm-up alone (its first
/// [`crate::compile::CompiledInitial::warmup`] samples; the rows after it
/// are not read): the values within their bounds that minimise the sum of
/// squared differences between the measured and the simulated outputs
/// over the warm-up, from the rule's starting guesses, by
/// [`descend`] (Levenberg-Marquardt) on central differences in box-normalised
/// coordinates (steps projected onto the bounds). Empty when the rule estimates
/// nothing.
pub fn estimate(m: &CompiledModel, values: &[f64], data: &Dataset) -> Result<Vec<f64>, SimError> {
    if m.estimates.is_empty() {
        return Ok(Vec::new());
    }
    let w = m.initial.warmup().unwrap_or(1);
    if data.len() < w {
        return Err(SimError::TooShort {
            samples: data.len(),
            needed: w,
        });
    }
    let window = data
        .slice(RowRange {
            start: Some(0),
            end: Some(w),
        })
        .map_err(|e| SimError::InitialState(e.to_string()))?;
    let to_values = |z: &[f64]| -> Vec<f64> {
        m.estimates
            .iter()
            .zip(z)
            .map(|(e, z)| e.bounds[0] + (e.bounds[1] - e.bounds[0]) * z.clamp(0.0, 1.0))
            .collect()
    };
    let residuals = |z: &[f64]| -> Option<Vec<f64>> {
        let r = run_from(m, values, &to_values(z), &window).ok()?;
        let e: Vec<f64> = window.y().iter().zip(&r.y).map(|(a, b)| a - b).collect();
        e.iter().all(|v| v.is_finite()).then_some(e)
    };
    let z0: Vec<f64> = m
        .estimates
        .iter()
        .map(|e| {
            let [lo, hi] = e.bounds;
            if hi > lo {
                (e.start - lo) / (hi - lo)
            } else {
                0.5
            }
        })
        .collect();
    let unit = vec![[0.0, 1.0]; z0.len()];
    let problem = Residuals::new(
        residuals,
        z0.len(),
        Some(&unit),
        CentralDifferences {
            step: STATE_DIFFERENCE,
        },
    );
    let settings = state_solve(ESTIMATE_ITERATIONS);
    let descent = descend(&problem, z0.clone(), &settings, &Deadline::none());
    let z = match descent.v {
        Some(z) => z,
        // No step from the guess: a flat spot of the warm-up's cost (a
        // state a held friction or a dead zone hides). The descents from a
        // quarter and three quarters of the bounds are tried; the lowest
        // cost is kept, the guess among equals.
        None => {
            FLAT_SPOT_STARTS
                .iter()
                .map(|&q| {
                    let start = vec![q; unit.len()];
                    let d = descend(&problem, start.clone(), &settings, &Deadline::none());
                    (d.cost_after, d.v.unwrap_or(start))
                })
                .fold((descent.cost_after, z0), |best, (cost, z)| {
                    if cost < best.0 { (cost, z) } else { best }
                })
                .1
        }
    };
    Ok(to_values(&z))
}

/// Where [`estimate`] starts again, in box-normalised coordinates, when
/// the guess is a flat spot of the warm-up's cost.
const FLAT_SPOT_STARTS: [f64; 2] = [0.25, 0.75];

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
pub(crate) fn steady(
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
