//! The flows of the regime being integrated: the sliding regime's model
//! selected, the elements' effects listed, the RK4 step (in closed form
//! where the regime's flows are affine), and what is read from the flows
//! and the output at a state: the rest test, the output and the mode
//! label, the sensor's inverse, the invariant.

use super::linear::AffineFlows;
use super::{
    ClosedEntry, Effect, ElementRegime, FORMED_STEPS, HybridState, INVARIANT_TOLERANCE, Machine,
    Sliding, affine_forms, load,
};
use crate::compile::{CompiledElement, CompiledMode, CompiledModel};
use hysid_model::simulate::SimError;
use nalgebra::DMatrix;
use std::rc::Rc;

impl Machine<'_> {
    /// The model the flows and friction levels are read from: the sliding
    /// regime's ([`Machine::select`]), or the model itself.
    #[inline]
    pub(super) fn bound(&self) -> &CompiledModel {
        self.current.as_deref().map_or(self.m, |s| &s.bound)
    }

    /// The affine form of `mode`'s flows in the selected regime.
    pub(super) fn affine_of(&self, mode: usize) -> Option<&AffineFlows> {
        match self.current.as_deref() {
            Some(s) => s.affine[mode].as_ref(),
            None => self.affine[mode].as_ref(),
        }
    }

    /// Selects the model of the sliding regime of `hs` (every friction
    /// element that slips, but on the velocity `except`), built the first
    /// time the regime is met; nothing to do where no direction decides
    /// anything.
    pub(super) fn select(&mut self, hs: &HybridState, except: Option<usize>) {
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
    pub(super) fn load(&mut self, x: &[f64], u: &[f64]) {
        load(&mut self.slots, x, u);
    }

    /// The applied force on velocity `v` (its flow without the friction).
    #[inline]
    pub(super) fn force(&self, mode: usize, v: usize) -> f64 {
        self.bound().modes[mode].flow[v].eval(&self.slots)
    }

    /// Kinetic and static levels of friction element `e` in `mode`.
    #[inline]
    pub(super) fn levels(&self, mode: usize, e: usize) -> (f64, f64) {
        let (kinetic, static_level) = &self.bound().modes[mode].friction[e];
        let k = kinetic.eval(&self.slots).max(0.0);
        (k, static_level.eval(&self.slots).max(k))
    }

    /// The static level on velocity `v` in `mode` (0 without friction).
    pub(super) fn static_on(&self, mode: usize, v: usize) -> f64 {
        self.friction_of[v].map_or(0.0, |e| self.levels(mode, e).1)
    }

    /// Lists what the elements do to the flows in the regimes of `hs`, and
    /// selects the model of its sliding regime.
    #[inline]
    pub(super) fn prepare(&mut self, hs: &HybridState) {
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
    pub(super) fn flows(&self, mode: usize, out: &mut [f64]) {
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
    /// where the regime has one ([`super::linear`]), else stage by stage, the
    /// stages written into the slots directly.
    pub(super) fn rk4(&mut self, hs: &HybridState, u: &[f64], h: f64, out: &mut [f64]) {
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
    /// ([`super::linear`]; `None` where the regime has none) into
    /// [`Machine::closed`], formed when the regime or the length differs
    /// from the last one's.
    pub(super) fn form_closed_step(&mut self, hs: &HybridState) {
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
    pub(super) fn stage(&mut self, hs: &HybridState, k: &[f64], step: f64) {
        for ((slot, x), k) in self.slots.iter_mut().zip(&hs.x).zip(k) {
            *slot = x + step * k;
        }
    }

    /// Every derivative of the state is exactly zero under the input `u`
    /// (read state by state up to the first that is not).
    #[inline]
    pub(super) fn at_rest(&mut self, hs: &HybridState, u: &[f64]) -> bool {
        self.load(&hs.x, u);
        self.prepare(hs);
        let q = &self.bound().modes[hs.mode];
        (0..q.flow.len()).all(|s| self.derivative_of(q, s) == 0.0)
    }

    /// The output of the state under the sample's input `u`.
    #[inline]
    pub(super) fn output(&mut self, hs: &HybridState, u: &[f64]) -> f64 {
        self.load(&hs.x, u);
        self.m.modes[hs.mode].output.eval(&self.slots)
    }

    /// The output of the state under the sample's input `u`, its mode label,
    /// and whether it satisfies its mode's invariant under `held`, the input
    /// that brought it there (the regime reached, before the new input acts).
    #[inline]
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
        // friction's, else the mode's; each as labelled in this mode.
        let held = &m.labels.held[hs.mode];
        let mut stuck = None;
        for ((e, r), &label) in m.elements.iter().zip(&hs.regimes).zip(held) {
            match (e, r) {
                (CompiledElement::Stop { .. }, ElementRegime::Resting) => {
                    return (y, label, covered);
                }
                (CompiledElement::DryFriction { .. }, ElementRegime::Stuck) => {
                    stuck = stuck.or(Some(label));
                }
                _ => {}
            }
        }
        (y, stuck.unwrap_or(m.labels.mode[hs.mode]), covered)
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
}
