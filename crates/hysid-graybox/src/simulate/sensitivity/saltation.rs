//! The jump of the sensitivities at an event (the saltation rule, see
//! the parent module's doc): the event's time moved by the parameters, and
//! the resets of stops, rebounds, settled velocities and transitions.

use super::Tangent;
use crate::compile::{CompiledElement, CompiledModel};
use crate::expr::Expression;
use crate::simulate::{ElementRegime, Event, HybridState, Machine, Sliding};

impl Machine<'_> {
    /// Before event `ev` is applied: at `hs`, the last state the
    /// location found before the event (under `u`; the end of the step
    /// [`Machine::tangent_step`] just carried, so that the rates are the
    /// regime's before the event), `τ_θ`; `S` moved to the event (`S +=
    /// Φ_h τ_θ`) and the length left in the sub-step shortened by it (`ℓ_θ
    /// -= τ_θ`).
    pub(in crate::simulate) fn tangent_event(&mut self, hs: &HybridState, u: &[f64], ev: Event) {
        let Some(mut t) = self.tangent.take() else {
            return;
        };
        self.load(&hs.x, u);
        self.prepare(hs);
        let sliding = self.current.clone();
        t.sliding = sliding.clone();
        let model = Sliding::unbound_or(sliding.as_deref(), t.model);
        let q = &model.modes[hs.mode];
        let c = t.d.columns;
        // The surface's total derivative (into `row`) and its rate in the
        // step's length.
        let mut rate = 0.0;
        t.row.fill(0.0);
        let mut add = |t: &mut Tangent, e: &Expression, weight: f64, slots: &[f64]| {
            let mut spare = std::mem::take(&mut t.spare);
            t.d.total(e, slots, &t.s, &mut spare);
            rate += weight * t.d.rate(&t.phi_h);
            for (r, s) in t.row.iter_mut().zip(&spare) {
                *r += weight * s;
            }
            t.spare = spare;
        };
        match ev {
            Event::Element(i) => match (&model.elements[i], hs.regimes[i]) {
                (
                    CompiledElement::Stop {
                        position, sign, at, ..
                    },
                    ElementRegime::Away,
                ) => {
                    add(&mut t, at, -sign, &self.slots);
                    let (s, row) = (&t.s[position * c..(position + 1) * c], &mut t.row);
                    for (r, s) in row.iter_mut().zip(s) {
                        *r += sign * s;
                    }
                    rate = sign * t.phi_h[*position];
                }
                (CompiledElement::Stop { velocity, sign, .. }, _) => {
                    add(&mut t, &q.flow[*velocity], -sign, &self.slots);
                    if let Some(level) = self.static_level(hs.mode, *velocity, model) {
                        add(&mut t, level, -1.0, &self.slots);
                    }
                }
                (CompiledElement::DryFriction { velocity, .. }, ElementRegime::Slip(_)) => {
                    let v = *velocity;
                    t.row.copy_from_slice(&t.s[v * c..(v + 1) * c]);
                    rate = t.phi_h[v];
                }
                (CompiledElement::DryFriction { velocity, .. }, _) => {
                    let force = self.force(hs.mode, *velocity);
                    add(&mut t, &q.flow[*velocity], force.signum(), &self.slots);
                    if let Some(level) = self.static_level(hs.mode, *velocity, model) {
                        add(&mut t, level, -1.0, &self.slots);
                    }
                }
            },
            Event::Transition(j) => add(&mut t, &q.transitions[j].guard.surface, 1.0, &self.slots),
        }
        if rate != 0.0 && rate.is_finite() {
            let tau: Vec<f64> = t.row.iter().map(|r| -r / rate).collect();
            t.add_rate(&tau);
            for (l, tau) in t.left.iter_mut().zip(&tau) {
                *l -= tau;
            }
        }
        self.tangent = Some(t);
    }

    /// The expression of the static level on velocity `v` in `mode` at the
    /// loaded slots, as [`Machine::static_on`] takes it (the larger of the
    /// static and kinetic levels, at least 0): `None` at 0 or without
    /// friction. Read from `model`'s (unbound) expressions.
    fn static_level<'m>(
        &self,
        mode: usize,
        v: usize,
        model: &'m CompiledModel,
    ) -> Option<&'m Expression> {
        let e = self.friction_of[v]?;
        let (kinetic, static_level) = &self.bound().modes[mode].friction[e];
        let (k, s) = (kinetic.eval(&self.slots), static_level.eval(&self.slots));
        let (kinetic, static_level) = &model.modes[mode].friction[e];
        if s >= k.max(0.0) && s > 0.0 {
            Some(static_level)
        } else {
            (k > 0.0).then_some(kinetic)
        }
    }

    /// The reset of a velocity to zero (Karnopp's rule, a stop's rest).
    pub(in crate::simulate) fn tangent_zero(&mut self, v: usize) {
        if let Some(t) = self.tangent.as_mut() {
            t.s_row(v).fill(0.0);
        }
    }

    /// The reset of a position onto stop element `i`'s level.
    pub(in crate::simulate) fn tangent_onto_stop(&mut self, i: usize) {
        let Some(t) = self.tangent.as_mut() else {
            return;
        };
        let CompiledElement::Stop { position, at, .. } = &t.model.elements[i] else {
            return;
        };
        let mut row = std::mem::take(&mut t.row);
        t.d.total(at, &self.slots, &t.s, &mut row);
        t.s_row(*position).copy_from_slice(&row);
        t.row = row;
    }

    /// The rebound `v+ = -e v-` of stop element `i` (`v-`: `before`).
    pub(in crate::simulate) fn tangent_rebound(&mut self, i: usize, before: f64) {
        let Some(t) = self.tangent.as_mut() else {
            return;
        };
        let CompiledElement::Stop {
            velocity,
            restitution,
            ..
        } = &t.model.elements[i]
        else {
            return;
        };
        let v = *velocity;
        let mut row = std::mem::take(&mut t.row);
        let e = t.d.total(restitution, &self.slots, &t.s, &mut row);
        let inside = e > 0.0 && e < 1.0;
        let e = e.clamp(0.0, 1.0);
        for (s, de) in t.s_row(v).iter_mut().zip(&row) {
            *s = -e * *s - if inside { before * de } else { 0.0 };
        }
        t.row = row;
    }

    /// The reset of transition `j` of `mode` at the loaded slots (every new
    /// value from the state before it).
    pub(in crate::simulate) fn tangent_reset(&mut self, mode: usize, j: usize) {
        let Some(t) = self.tangent.as_mut() else {
            return;
        };
        let model = t.model;
        let c = t.d.columns;
        let reset = &model.modes[mode].transitions[j].reset;
        let mut rows = vec![0.0; reset.len() * c];
        for ((_, e), row) in reset.iter().zip(rows.chunks_mut(c)) {
            t.d.total(e, &self.slots, &t.s, row);
        }
        for ((s, _), row) in reset.iter().zip(rows.chunks(c)) {
            t.s_row(*s).copy_from_slice(row);
        }
    }
}
