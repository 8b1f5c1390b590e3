//! Locating an event inside a sub-step ([`Bracket`]) on the margin of
//! the event that ended it.

use super::{Event, HybridState, Machine};
use crate::expr::Crossing;
use hysid_numerics::event_location::{Bracket, LOCATE_TRIALS};

impl Machine<'_> {
    /// Locates the event `ev` that the step of length `left` from `hs`
    /// under `u` ends in (`x1`: its end state; `xm`: scratch): the bracket
    /// `(lo, hi)` closed around it, `x1` the state at `hi` and `ev` the
    /// event named there; `before`, when carried, the state at `lo`.
    pub(super) fn locate(
        &mut self,
        hs: &HybridState,
        u: &[f64],
        left: f64,
        ev: &mut Event,
        (x1, xm): (&mut Vec<f64>, &mut Vec<f64>),
        before: &mut Option<HybridState>,
    ) -> (f64, f64) {
        // In the quiet lane's regimes, the trials test the state alone and
        // the event is named once at the end.
        let lane = self.quiet_lane_open(hs);
        let aim = *ev;
        let margin = |m: &Self, x: &[f64]| m.margin(hs, aim, x, u, m.g.start());
        let mut b = Bracket::new(left, margin(self, &hs.x), margin(self, x1));
        let mut moved = false;
        for _ in 0..LOCATE_TRIALS {
            let Some(t) = b.trial() else {
                break;
            };
            self.locate_trials += 1;
            self.rk4(hs, u, t, xm);
            let found = if lane {
                self.ends_lane(xm, u, hs.mode).then_some(*ev)
            } else {
                self.surfaces_at(xm, u, hs.mode);
                self.first_event(hs, xm)
            };
            b.update(t, found.is_some(), margin(self, xm));
            if let Some(e) = found {
                *ev = e;
                moved = true;
                x1.copy_from_slice(xm);
            } else if let Some(b) = before.as_mut() {
                b.x.copy_from_slice(xm);
            }
        }
        if lane && moved {
            self.surfaces_at(x1, u, hs.mode);
            if let Some(e) = self.first_event(hs, x1) {
                *ev = e;
            }
        }
        (b.lo, b.hi)
    }

    /// The margin of `event` at the state `x` under `u`: not negative
    /// where the event test holds it (a stop's signed distance, a sliding
    /// velocity against its direction, an affine guard's surface in its
    /// crossing's direction from `g0`). `None` for the events decided by
    /// forces (a held element's release) and for guards without an affine
    /// form.
    pub(super) fn margin(
        &self,
        hs: &HybridState,
        event: Event,
        x: &[f64],
        u: &[f64],
        g0: &[f64],
    ) -> Option<f64> {
        match event {
            Event::Element(i) => self.state_end(i, hs.regimes[i]).map(|end| end.margin(x)),
            Event::Transition(j) => {
                let (crossing, row) = self.guards[hs.mode].as_ref()?.get(j)?;
                let g = row.eval(x, u);
                match (crossing, g0.get(j)?) {
                    (Crossing::Rising, _) => Some(g),
                    (Crossing::Falling, _) => Some(-g),
                    (Crossing::Either, g0) if *g0 < 0.0 => Some(g),
                    (Crossing::Either, g0) if *g0 > 0.0 => Some(-g),
                    _ => None,
                }
            }
        }
    }
}
