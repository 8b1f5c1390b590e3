//! The sub-steps of a sample and the events that end them: the guard
//! surfaces at a step's start and end, the first event at a trial state,
//! Karnopp's rule at a zero velocity, the events applied, the transitions
//! fired across an input's jump, and the hybrid state at a given state.

use super::{
    ElementRegime, Event, HybridState, INVARIANT_TOLERANCE, MAX_EVENTS_PER_STEP, Machine, StateEnd,
    crossed,
};
use crate::compile::{CompiledElement, CompiledMode};
use hysid_model::simulate::{SimError, ZenoSteps};

/// The guard surfaces of `mode`'s transitions at `slots` into `out`.
fn surfaces(mode: &CompiledMode, slots: &[f64], out: &mut Vec<f64>) {
    out.clear();
    out.extend(mode.transitions.iter().map(|t| t.guard.surface.eval(slots)));
}

/// The guard surfaces of the current mode at the start of a step and at
/// its trial end; the end of a step taken is the start of the next.
#[derive(Debug, Default)]
pub(super) struct Surfaces {
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
    pub(super) fn start(&self) -> &[f64] {
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
    pub(super) fn start_and_end_mut(&mut self, len: usize) -> (&mut [f64], &mut [f64]) {
        let [a, b] = &mut self.both;
        let (start, end) = if self.start == 0 { (a, b) } else { (b, a) };
        end.resize(len, 0.0);
        (start, end)
    }

    /// `steps` times [`Surfaces::step`].
    pub(super) fn stepped(&mut self, steps: usize) {
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
    pub(super) fn step(&mut self) {
        self.stepped(1);
    }
}

impl Machine<'_> {
    /// The guard surfaces at the end of a sample (state `hs`, input `u`)
    /// into `out`, for [`Machine::fire_across_jump`] to compare across the
    /// next input's jump; nothing where no guard surface of the mode reads
    /// an input (the jump cannot move them).
    #[inline]
    pub(super) fn surfaces_at_end(&mut self, hs: &HybridState, u: &[f64], out: &mut Vec<f64>) {
        if self.shortcuts && !self.input_guards[hs.mode] {
            out.clear();
        } else {
            self.load(&hs.x, u);
            surfaces(&self.m.modes[hs.mode], &self.slots, out);
        }
    }

    /// Loads `(x, u)` and evaluates the guard surfaces there into the
    /// step's trial end.
    pub(super) fn surfaces_at(&mut self, x: &[f64], u: &[f64], mode: usize) {
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
    pub(super) fn state_end(&self, i: usize, regime: ElementRegime) -> Option<StateEnd> {
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
    pub(super) fn first_event(&self, hs: &HybridState, x: &[f64]) -> Option<Event> {
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
                let from = hs.mode;
                let t = &m.modes[from].transitions[j];
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
                if self.strict_resets {
                    self.check_target(hs, u, (from, j), sample)?;
                }
            }
        }
        Ok(())
    }

    /// Fires the transitions whose guards a jump crossed (`g_before`: the
    /// surfaces before it): the input's at a sample instant (from the
    /// input `before.1`), a stop's reset (from the state `before.0`; `None`:
    /// the state as it is); whether one fired. A transition fired leads on
    /// to the next whose guard in its target mode the same jump crossed
    /// (from the point before it to the state reached), up to
    /// [`MAX_EVENTS_PER_STEP`]: an input that jumps across two thresholds
    /// passes both, whatever the order of the transitions.
    #[inline]
    pub(super) fn fire_across_jump(
        &mut self,
        hs: &mut HybridState,
        u: &[f64],
        g_before: &[f64],
        before: (Option<&[f64]>, &[f64]),
        sample: usize,
    ) -> Result<bool, SimError> {
        if g_before.is_empty() {
            return Ok(false);
        }
        let start = self.g.start_mut();
        start.clear();
        start.extend_from_slice(g_before);
        self.surfaces_at(&hs.x, u, hs.mode);
        // The modes passed through need not hold the state; the one reached
        // must.
        let strict = std::mem::replace(&mut self.strict_resets, false);
        let mut x_before = Vec::new();
        let mut last = None;
        let mut result = Ok(());
        for _ in 0..MAX_EVENTS_PER_STEP {
            let Some(Event::Transition(j)) = self.first_transition(hs) else {
                break;
            };
            if last.is_none() {
                x_before.extend_from_slice(before.0.unwrap_or(&hs.x));
            }
            last = Some((hs.mode, j));
            result = self.apply(hs, u, Event::Transition(j), sample);
            if result.is_err() {
                break;
            }
            self.load(&x_before, before.1);
            surfaces(&self.m.modes[hs.mode], &self.slots, self.g.start_mut());
            self.surfaces_at(&hs.x, u, hs.mode);
        }
        self.strict_resets = strict;
        result?;
        match last {
            Some(fired) if strict => self.check_target(hs, u, fired, sample).map(|()| true),
            fired => Ok(fired.is_some()),
        }
    }

    /// That the state `hs` under `u` meets the invariant of its mode,
    /// reached by transition `j` of mode `from`.
    fn check_target(
        &mut self,
        hs: &HybridState,
        u: &[f64],
        (from, j): (usize, usize),
        sample: usize,
    ) -> Result<(), SimError> {
        self.load(&hs.x, u);
        let outside = (self.m.modes[hs.mode].invariant.iter())
            .any(|r| r.margin(&self.slots) < -INVARIANT_TOLERANCE);
        if outside {
            let t = &self.m.modes[from].transitions[j];
            return Err(SimError::OutsideTargetInvariant {
                transition: t.label.clone(),
                reset: !t.reset.is_empty(),
                sample,
            });
        }
        Ok(())
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
    #[inline]
    pub(super) fn resettle(&mut self, hs: &mut HybridState, u: &[f64]) -> bool {
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
                    // No stop is passed, events or none.
                    self.hold_reached_stops(hs, u, None);
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
                    (g, hs.x.clone())
                });
                if let Err(e) = self.apply(hs, u, ev, sample) {
                    result = Err(e);
                    break 'steps;
                }
                if let Some((g, x)) = before_jump
                    && let Err(e) = self.fire_across_jump(hs, u, &g, (Some(&x), u), sample)
                {
                    result = Err(e);
                    break 'steps;
                }
                left -= hi;
                events += 1;
                if events >= MAX_EVENTS_PER_STEP {
                    ZenoSteps::add(&mut self.zeno, sample);
                    self.hold_reached_stops(hs, u, Some(ev));
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

    /// The Zeno bound's action: every stop reached holds
    /// ([`Machine::reached_stops`]).
    fn hold_reached_stops(&mut self, hs: &mut HybridState, u: &[f64], last: Option<Event>) {
        for (i, position, velocity, at, _) in self.reached_stops(&hs.x, last) {
            hs.x[position] = at;
            self.tangent_onto_stop(i);
            self.settle(hs, u, velocity);
        }
    }

    /// The stops that `x` has reached or passed, and that of the event
    /// `last` (its rebound starts on it): `(element, position state,
    /// velocity state, level, sign)`.
    fn reached_stops(
        &self,
        x: &[f64],
        last: Option<Event>,
    ) -> Vec<(usize, usize, usize, f64, f64)> {
        self.stops_with_velocity()
            .filter(|&(i, position, _, at, sign)| {
                sign * (x[position] - at) >= 0.0 || last == Some(Event::Element(i))
            })
            .collect()
    }

    /// Every stop: `(element, position state, velocity state, level, sign)`.
    pub(super) fn stops_with_velocity(
        &self,
    ) -> impl Iterator<Item = (usize, usize, usize, f64, f64)> + '_ {
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

    /// Whether mode `q`'s invariant holds at `x` under the inputs `u`
    /// (within [`INVARIANT_TOLERANCE`]).
    pub fn holds_invariant(&mut self, q: usize, x: &[f64], u: &[f64]) -> bool {
        self.load(x, u);
        self.m.modes[q]
            .invariant
            .iter()
            .all(|r| r.margin(&self.slots) >= -INVARIANT_TOLERANCE)
    }

    /// The hybrid state at `(x, u)`: positions clamped to their stops, the
    /// mode `mode` or the first whose invariant holds, every velocity at
    /// zero, and every stop reached by a state not moving away from it,
    /// settled.
    pub fn state_at(&mut self, mut x: Vec<f64>, u: &[f64], mode: Option<usize>) -> HybridState {
        let m = self.m;
        for (i, position, velocity, at, sign) in self.reached_stops(&x, None) {
            x[position] = at;
            self.tangent_onto_stop(i);
            if sign * x[velocity] > 0.0 {
                x[velocity] = 0.0;
                self.tangent_zero(velocity);
            }
        }
        let mode = mode.unwrap_or_else(|| {
            (0..m.modes.len())
                .find(|&q| self.holds_invariant(q, &x, u))
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
            // On a stop and not moving away from it.
            let at_stop = matches!(e, CompiledElement::Stop { position, sign, .. }
                if hs.x[*position] == self.fixed[i].0 && sign * hs.x[v] >= 0.0);
            if hs.x[v] == 0.0 || at_stop {
                self.settle(&mut hs, u, v);
            }
        }
        hs
    }
}

#[cfg(test)]
mod tests {
    use super::Surfaces;

    /// Surfaces kept for a mode and a state serve that mode at the same
    /// bits only, and are forgotten when the start changes.
    #[test]
    fn kept_surfaces_serve_the_same_mode_and_bits_only() {
        let mut g = Surfaces::default();
        assert!(!g.kept_at(0, &[1.0, 2.0]));
        g.keep(0, &[1.0, 0.0]);
        assert!(g.kept_at(0, &[1.0, 0.0]));
        assert!(!g.kept_at(1, &[1.0, 0.0]));
        assert!(!g.kept_at(0, &[1.0, -0.0]));
        assert!(!g.kept_at(0, &[1.0, 1e-300]));
        assert!(!g.kept_at(0, &[1.0]));
        g.step();
        assert!(!g.kept_at(0, &[1.0, 0.0]));
        g.keep(0, &[1.0, 0.0]);
        g.start_mut();
        assert!(!g.kept_at(0, &[1.0, 0.0]));
    }
}
