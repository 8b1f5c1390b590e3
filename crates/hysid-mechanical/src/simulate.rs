//! Event-aware simulation of [`MechanicalModel`]s (mass-spring-friction
//! hybrid automata; `docs/mechanical-models.md`).
//!
//! The state is `(y, v)` and a *regime*: sliding with a direction of
//! friction `s = sign(v)` and a set of engaged contacts, stuck (`v = 0`),
//! or resting at a stop. Within a regime the force law is smooth (affine),
//! and it is integrated with classical RK4 at the model's fixed internal
//! step (the sample time divided into equal sub-steps no longer than
//! `internal_step`), the input held over each sample (zero-order hold). A
//! full sub-step takes RK4's closed form for affine flows
//! ([`hysid_numerics::affine_rk4`]), formed once per sliding regime
//! ([`Integrator`]); shorter steps around events take the four stages.
//!
//! Events are located inside the internal step on the step length, to
//! [`LOCATE_RESOLUTION`] of the step, by regula falsi on the regime's
//! margin safeguarded by bisection
//! ([`hysid_numerics::event_location`]), the state taken just past the
//! event, and the rest of the step integrated in the
//! new regime (at most [`MAX_EVENTS_PER_STEP`] events per step):
//!
//! - **velocity zero** (`s v <= 0`): `v := 0`; the mass sticks when the net
//!   smooth force `|F| <= f_s` (static level), else it slides off in the
//!   direction of `F` (Karnopp's switch model: the sign of the friction is
//!   never evaluated at `v = 0`, so there is no chattering);
//! - **stop reached** (`s_i (y - y_i) >= 0`, a lower-dimensional guard set):
//!   `y := y_i`, `v := -e v`; with `e = 0` the mass rests at the stop until
//!   the net force pulls it away beyond static friction;
//! - **contact engaged/released** (`p = s_c (y - y_c)` crosses 0, or the
//!   contact force `lambda = k_c p + d_c s_c v` of a unilateral contact
//!   becomes negative): the engaged set changes, `(y, v)` are continuous.
//!
//! While stuck or at a stop nothing moves, the net force is constant over a
//! sample (held input, fixed position), and the break-away test is made at
//! each sample. The output is the position at the sampling instants; the
//! mode of a sample is the declared mode of its regime at that instant.

use crate::{MechanicalInitialState, MechanicalModel, ResolvedForce, ResolvedMechanics};
use hysid_model::data::Dataset;
use hysid_model::simulate::{SimError, Simulation, SimulationOptions};
pub use hysid_model::simulate::{estimate_velocity, substeps};
use hysid_numerics::affine_rk4::ClosedStep;
pub use hysid_numerics::event_location::LOCATE_RESOLUTION;
use hysid_numerics::event_location::{Bracket, LOCATE_TRIALS};

/// Bound on the events processed within one internal step (a Zeno guard).
pub const MAX_EVENTS_PER_STEP: usize = 16;

/// Discrete part of the state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Regime {
    /// Sliding; `dir` is the sign of the velocity (+1 or -1), `engaged` the
    /// bit mask of engaged contacts.
    Slip {
        /// Direction of motion.
        dir: i8,
        /// Engaged contacts.
        engaged: u32,
    },
    /// Stuck by static friction, with these contacts engaged.
    Stuck {
        /// Engaged contacts.
        engaged: u32,
    },
    /// Resting at stop `i`.
    AtStop(usize),
}

/// Full state of the mechanical simulator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MechanicalState {
    /// Position.
    pub y: f64,
    /// Velocity.
    pub v: f64,
    /// Regime.
    pub regime: Regime,
}

/// Result of a mechanical simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct MechanicalRun {
    /// Positions at the samples (before `start`: the measured outputs).
    pub y: Vec<f64>,
    /// Velocities at the samples (0 before `start`).
    pub v: Vec<f64>,
    /// Declared mode per sample (`None` before `start`).
    pub modes: Vec<Option<usize>>,
    /// First simulated sample (the initial state's).
    pub start: usize,
    /// Internal steps integrated (stuck and stop intervals are skipped).
    pub steps: usize,
    /// Events handled.
    pub events: usize,
}

impl ResolvedMechanics {
    /// Net smooth force per unit mass (everything but dry friction and the
    /// stops) with the contacts of `engaged`.
    #[inline]
    pub fn smooth_force(&self, y: f64, v: f64, u: &[f64], engaged: u32) -> f64 {
        let mut f = 0.0;
        for fe in &self.forces {
            f += match *fe {
                ResolvedForce::Input(i, g) => g * u[i],
                ResolvedForce::Constant(c) => c,
                ResolvedForce::Spring(k, rest) => -k * (y - rest),
                ResolvedForce::Damper(d) => -d * v,
            };
        }
        if engaged != 0 {
            for (i, c) in self.contacts.iter().enumerate() {
                if engaged & (1 << i) != 0 {
                    let p = c.sign * (y - c.position);
                    f -= c.sign * (c.stiffness * p + c.damping * c.sign * v);
                }
            }
        }
        f
    }

    /// The flows of `(y, v)` while sliding in direction `dir` with the
    /// contacts of `engaged`, `d(y, v)/dt = A (y, v) + B u + c`, for `inputs`
    /// inputs: the terms of [`Self::smooth_force`] and the kinetic friction
    /// against the motion, as `A` (2 x 2), `B` (2 x `inputs`) and `c`,
    /// row-major.
    pub fn affine_flows(&self, dir: f64, engaged: u32, inputs: usize) -> [Vec<f64>; 3] {
        let (mut a, mut b, mut c) = (
            vec![0.0, 1.0, 0.0, 0.0],
            vec![0.0; 2 * inputs],
            vec![0.0; 2],
        );
        for fe in &self.forces {
            match *fe {
                ResolvedForce::Input(i, g) => b[inputs + i] += g,
                ResolvedForce::Constant(k) => c[1] += k,
                ResolvedForce::Spring(k, rest) => {
                    a[2] -= k;
                    c[1] += k * rest;
                }
                ResolvedForce::Damper(d) => a[3] -= d,
            }
        }
        for (i, contact) in self.contacts.iter().enumerate() {
            if engaged & (1 << i) != 0 {
                let s2 = contact.sign * contact.sign;
                a[2] -= s2 * contact.stiffness;
                a[3] -= s2 * contact.damping;
                c[1] += s2 * contact.stiffness * contact.position;
            }
        }
        c[1] -= dir * self.friction(engaged).0;
        [a, b, c]
    }

    /// Kinetic and static friction levels with the contacts of `engaged`.
    #[inline]
    pub fn friction(&self, engaged: u32) -> (f64, f64) {
        let mut extra = 0.0;
        if engaged != 0 {
            for (i, c) in self.contacts.iter().enumerate() {
                if engaged & (1 << i) != 0 {
                    extra += c.friction;
                }
            }
        }
        let k = (self.kinetic + extra).max(0.0);
        (k, (self.static_level + extra).max(k))
    }

    /// Contacts engaged at `(y, v)`: penetration > 0 and, for unilateral
    /// ones, a contact force that pushes (`lambda >= 0`).
    #[inline]
    pub fn engaged_at(&self, y: f64, v: f64) -> u32 {
        let mut m = 0;
        for (i, c) in self.contacts.iter().enumerate() {
            let p = c.sign * (y - c.position);
            if p > 0.0 && (!c.unilateral || c.stiffness * p + c.damping * c.sign * v >= 0.0) {
                m |= 1 << i;
            }
        }
        m
    }

    /// Acceleration while sliding in direction `dir` with `engaged` contacts.
    #[inline]
    fn slip_accel(&self, y: f64, v: f64, u: &[f64], dir: f64, engaged: u32) -> f64 {
        self.smooth_force(y, v, u, engaged) - dir * self.friction(engaged).0
    }

    /// The regime of a mass at rest (`v = 0`) at `y`: at a stop when on it
    /// and pushed into it (or held by friction), stuck when static friction
    /// holds, else sliding off in the direction of the net force.
    pub fn rest_regime(&self, y: f64, u: &[f64]) -> Regime {
        let engaged = self.engaged_at(y, 0.0);
        let f = self.smooth_force(y, 0.0, u, engaged);
        let (_, fs) = self.friction(engaged);
        for (i, s) in self.stops.iter().enumerate() {
            if (y - s.position).abs() <= 1e-12 * (1.0 + s.position.abs()) && s.sign * f >= -fs {
                return Regime::AtStop(i);
            }
        }
        if f.abs() <= fs {
            Regime::Stuck { engaged }
        } else {
            Regime::Slip {
                dir: if f > 0.0 { 1 } else { -1 },
                engaged,
            }
        }
    }

    /// Clamps a position into the admissible interval between the stops.
    pub fn clamp_position(&self, mut y: f64) -> f64 {
        for s in &self.stops {
            if s.sign * (y - s.position) > 0.0 {
                y = s.position;
            }
        }
        y
    }

    /// The state of a mass at `(y, v)`: position clamped, regime chosen.
    pub fn state_at(&self, y: f64, v: f64, u: &[f64]) -> MechanicalState {
        let y = self.clamp_position(y);
        let on_stop = self
            .stops
            .iter()
            .any(|s| y == s.position && s.sign * v >= 0.0);
        if v == 0.0 || on_stop {
            MechanicalState {
                y,
                v: 0.0,
                regime: self.rest_regime(y, u),
            }
        } else {
            MechanicalState {
                y,
                v,
                regime: Regime::Slip {
                    dir: if v > 0.0 { 1 } else { -1 },
                    engaged: self.engaged_at(y, v),
                },
            }
        }
    }

    /// One RK4 step of length `h` in a sliding regime.
    #[inline]
    fn rk4(&self, y: f64, v: f64, u: &[f64], dir: f64, engaged: u32, h: f64) -> (f64, f64) {
        let a1 = self.slip_accel(y, v, u, dir, engaged);
        let (y2, v2) = (y + 0.5 * h * v, v + 0.5 * h * a1);
        let a2 = self.slip_accel(y2, v2, u, dir, engaged);
        let (y3, v3) = (y + 0.5 * h * v2, v + 0.5 * h * a2);
        let a3 = self.slip_accel(y3, v3, u, dir, engaged);
        let (y4, v4) = (y + h * v3, v + h * a3);
        let a4 = self.slip_accel(y4, v4, u, dir, engaged);
        (
            y + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
        )
    }

    /// True when `(y, v)` has left the sliding regime `(dir, engaged)`.
    #[inline]
    fn left_slip(&self, y: f64, v: f64, dir: f64, engaged: u32) -> bool {
        if dir * v <= 0.0 {
            return true;
        }
        for s in &self.stops {
            if s.sign * (y - s.position) >= 0.0 && s.sign * dir > 0.0 {
                return true;
            }
        }
        self.engaged_at(y, v) != engaged
    }

    /// The margin of the sliding regime `(dir, engaged)` at `(y, v)`: not
    /// negative where [`ResolvedMechanics::left_slip`] finds it left (the
    /// largest of the velocity against `dir`, the distances past the stops
    /// ahead, and each contact's distance from changing its engagement).
    fn slip_margin(&self, y: f64, v: f64, dir: f64, engaged: u32) -> f64 {
        let mut m = -dir * v;
        for s in &self.stops {
            if s.sign * dir > 0.0 {
                m = m.max(s.sign * (y - s.position));
            }
        }
        for (i, c) in self.contacts.iter().enumerate() {
            let p = c.sign * (y - c.position);
            let engage = if c.unilateral {
                p.min(c.stiffness * p + c.damping * c.sign * v)
            } else {
                p
            };
            m = m.max(if engaged & (1 << i) != 0 {
                -engage
            } else {
                engage
            });
        }
        m
    }

    /// The state just after leaving a sliding regime at `(y, v)`.
    fn handle_event(&self, y: f64, v: f64, u: &[f64], dir: f64) -> MechanicalState {
        // A stop crossed in the direction of motion takes precedence.
        for (i, s) in self.stops.iter().enumerate() {
            if s.sign * (y - s.position) >= 0.0 && s.sign * dir > 0.0 {
                let vr = -s.restitution * v;
                if vr * dir < 0.0 && vr.abs() > 0.0 {
                    let nd = if vr > 0.0 { 1 } else { -1 };
                    return MechanicalState {
                        y: s.position,
                        v: vr,
                        regime: Regime::Slip {
                            dir: nd,
                            engaged: self.engaged_at(s.position, vr),
                        },
                    };
                }
                let regime = match self.rest_regime(s.position, u) {
                    Regime::Slip { dir: nd, engaged } if nd as f64 * s.sign > 0.0 => {
                        // Pushed further into the stop: stays there.
                        let _ = engaged;
                        Regime::AtStop(i)
                    }
                    r => r,
                };
                return MechanicalState {
                    y: s.position,
                    v: 0.0,
                    regime,
                };
            }
        }
        if dir * v <= 0.0 {
            // Velocity reached zero: stick or slide off (Karnopp).
            return MechanicalState {
                y,
                v: 0.0,
                regime: self.rest_regime(y, u),
            };
        }
        MechanicalState {
            y,
            v,
            regime: Regime::Slip {
                dir: dir as i8,
                engaged: self.engaged_at(y, v),
            },
        }
    }
}

/// The sub-steps of a run: RK4 over the model's internal step, a full
/// sub-step of a sliding regime in closed form
/// ([`ResolvedMechanics::affine_flows`], [`ClosedStep`], formed when the
/// regime is first met), events located on the step length
/// ([`Bracket`]).
#[derive(Debug, Clone)]
pub struct Integrator<'a> {
    mech: &'a ResolvedMechanics,
    n_sub: usize,
    /// The sub-step length.
    h: f64,
    /// The closed forms of the sliding regimes met, by direction and
    /// engaged contacts.
    closed: Vec<(i8, u32, ClosedStep)>,
    /// Full sub-steps in closed form (else by RK4's four stages).
    closed_form: bool,
    /// Full sub-steps of a sliding regime taken back to back
    /// ([`Integrator::quiet_substeps`]); off only to test that they
    /// change no bit.
    quiet: bool,
}

impl<'a> Integrator<'a> {
    /// Sub-steps of `mech` for samples of `dt` split into `n_sub`.
    pub fn new(mech: &'a ResolvedMechanics, dt: f64, n_sub: usize) -> Self {
        Integrator {
            mech,
            n_sub,
            h: dt / n_sub as f64,
            closed: Vec::new(),
            closed_form: true,
            quiet: true,
        }
    }

    /// The closed-form sub-step of the sliding regime `(dir, engaged)`.
    fn closed(&mut self, dir: i8, engaged: u32, inputs: usize) -> &ClosedStep {
        let at = match self
            .closed
            .iter()
            .position(|(d, e, _)| (*d, *e) == (dir, engaged))
        {
            Some(at) => at,
            None => {
                let [a, b, c] = self.mech.affine_flows(dir as f64, engaged, inputs);
                let step = ClosedStep::new(a, b, c, self.h);
                self.closed.push((dir, engaged, step));
                self.closed.len() - 1
            }
        };
        &self.closed[at].2
    }

    /// Takes up to `n` full sub-steps of the current sliding regime in
    /// closed form, back to back while none leaves it, and returns how
    /// many it took; the sub-step that leaves it is left to
    /// [`Integrator::advance`], which takes it again from the same state.
    fn quiet_substeps(&mut self, st: &mut MechanicalState, u: &[f64], n: usize) -> usize {
        let Regime::Slip { dir, engaged } = st.regime else {
            return 0;
        };
        if !(self.closed_form && self.quiet) {
            return 0;
        }
        let mech = self.mech;
        let step = self.closed(dir, engaged, u.len());
        let mut x1 = [0.0; 2];
        for taken in 0..n {
            step.apply(&[st.y, st.v], u, &mut x1);
            if mech.left_slip(x1[0], x1[1], dir as f64, engaged) {
                return taken;
            }
            st.y = x1[0];
            st.v = x1[1];
        }
        n
    }

    /// Advances the state by one sample with input `u` held. Returns
    /// (internal steps, events).
    pub fn advance(&mut self, st: &mut MechanicalState, u: &[f64]) -> (usize, usize) {
        let (mech, n_sub, h) = (self.mech, self.n_sub, self.h);
        let (mut steps, mut events) = (0, 0);
        // At rest: a constant net force over the interval.
        if !matches!(st.regime, Regime::Slip { .. }) {
            st.v = 0.0;
            st.regime = mech.rest_regime(st.y, u);
            if !matches!(st.regime, Regime::Slip { .. }) {
                return (0, 0);
            }
        }
        let mut sub = 0;
        while sub < n_sub {
            let quiet = self.quiet_substeps(st, u, n_sub - sub);
            steps += quiet;
            sub += quiet;
            if sub == n_sub {
                break;
            }
            sub += 1;
            let mut left = h;
            let mut n_ev = 0;
            while left > 0.0 {
                let Regime::Slip { dir, engaged } = st.regime else {
                    // Stuck or at a stop for the rest of the step; the force
                    // stays constant, so for the rest of the sample too.
                    return (steps, events);
                };
                let d = dir as f64;
                steps += 1;
                let (y1, v1) = if left == h && self.closed_form {
                    let mut x1 = [0.0; 2];
                    self.closed(dir, engaged, u.len())
                        .apply(&[st.y, st.v], u, &mut x1);
                    (x1[0], x1[1])
                } else {
                    mech.rk4(st.y, st.v, u, d, engaged, left)
                };
                if !mech.left_slip(y1, v1, d, engaged) {
                    st.y = y1;
                    st.v = v1;
                    break;
                }
                // Locate the first exit in (0, left].
                let margin = |y, v| Some(mech.slip_margin(y, v, d, engaged));
                let mut b = Bracket::new(left, margin(st.y, st.v), margin(y1, v1));
                let (mut yh, mut vh) = (y1, v1);
                for _ in 0..LOCATE_TRIALS {
                    let Some(t) = b.trial() else {
                        break;
                    };
                    let (ym, vm) = mech.rk4(st.y, st.v, u, d, engaged, t);
                    let left_it = mech.left_slip(ym, vm, d, engaged);
                    b.update(t, left_it, margin(ym, vm));
                    if left_it {
                        yh = ym;
                        vh = vm;
                    }
                }
                let hi = b.hi;
                events += 1;
                n_ev += 1;
                left -= hi;
                *st = mech.handle_event(yh, vh, u, d);
                if n_ev >= MAX_EVENTS_PER_STEP {
                    // Zeno guard: come to rest here.
                    st.v = 0.0;
                    st.regime = mech.rest_regime(st.y, u);
                    break;
                }
            }
        }
        (steps, events)
    }
}

/// Runs a mechanical model with parameter values `values` on the inputs of
/// `data` (sampling time `data.ts`), from the model's initial-state rule.
pub fn run(
    model: &MechanicalModel,
    values: &[f64],
    data: &Dataset,
) -> Result<MechanicalRun, SimError> {
    run_with(model, values, data, |_| ())
}

/// [`run`] with its integrator set by `set` first (full sub-steps by
/// RK4's four stages, or not back to back).
fn run_with(
    model: &MechanicalModel,
    values: &[f64],
    data: &Dataset,
    set: impl FnOnce(&mut Integrator),
) -> Result<MechanicalRun, SimError> {
    let r = model.resolve_with(values);
    let ts = data.ts.ok_or(SimError::NoSamplingTime)?;
    if data.inputs.len() != model.inputs.len() {
        return Err(SimError::Inputs {
            expected: model.inputs.len(),
            found: data.inputs.len(),
        });
    }
    let n = data.len();
    let ym = data.y();
    let mut u = vec![0.0; model.inputs.len()];
    let input_at = |k: usize, u: &mut [f64]| {
        for (i, x) in u.iter_mut().enumerate() {
            *x = data.inputs[i].values[k];
        }
    };
    let (start, mut st) = match model.initial_state {
        MechanicalInitialState::Measured {
            samples,
            velocity_tol,
        } => {
            let s = samples.max(1) - 1;
            if n <= s {
                return Err(SimError::TooShort {
                    samples: n,
                    needed: s + 1,
                });
            }
            let mut v = estimate_velocity(ym, s, ts);
            if v.abs() <= velocity_tol {
                v = 0.0;
            }
            input_at(s, &mut u);
            (s, r.state_at(ym[s], v, &u))
        }
        MechanicalInitialState::Given { position, velocity } => {
            if n == 0 {
                return Err(SimError::TooShort {
                    samples: 0,
                    needed: 1,
                });
            }
            input_at(0, &mut u);
            (0, r.state_at(position, velocity, &u))
        }
    };
    let n_sub = substeps(ts, model.internal_step)?;
    let mut out = MechanicalRun {
        y: ym.to_vec(),
        v: vec![0.0; n],
        modes: vec![None; n],
        start,
        steps: 0,
        events: 0,
    };
    let label = |st: &MechanicalState| match st.regime {
        Regime::AtStop(i) => model.mode_of(Some(i), true, 0),
        Regime::Stuck { engaged } => model.mode_of(None, true, engaged),
        Regime::Slip { engaged, .. } => model.mode_of(None, false, engaged),
    };
    out.y[start] = st.y;
    out.v[start] = st.v;
    out.modes[start] = label(&st);
    let mut integrator = Integrator::new(&r, ts, n_sub);
    set(&mut integrator);
    for k in start..n.saturating_sub(1) {
        input_at(k, &mut u);
        let (s, e) = integrator.advance(&mut st, &u);
        out.steps += s;
        out.events += e;
        out.y[k + 1] = st.y;
        out.v[k + 1] = st.v;
        out.modes[k + 1] = label(&st);
    }
    Ok(out)
}

/// Free-run, event-located simulation of a mechanical model.
pub fn simulate(
    m: &MechanicalModel,
    data: &Dataset,
    opts: SimulationOptions,
) -> Result<Simulation, SimError> {
    let r = run(m, &m.values(), data)?;
    let n = data.len();
    let mut sim = Simulation {
        y: r.y.clone(),
        modes: r.modes,
        start: r.start,
        covered: vec![true; n],
        diverged_at: None,
        diverged_to: None,
        zeno: None,
    };
    for k in r.start..n {
        if !sim.push_checked(k, r.y[k], opts.bound) {
            break;
        }
    }
    Ok(sim)
}

/// One-step prediction: at each sample the state is re-estimated from the
/// measured outputs up to the previous sample (as the initial state is) and
/// advanced by one sample.
pub fn predict(m: &MechanicalModel, data: &Dataset) -> Result<Simulation, SimError> {
    let ts = data.ts.ok_or(SimError::NoSamplingTime)?;
    let r = m.resolve();
    let n = data.len();
    let ym = data.y();
    let (first, tol) = match m.initial_state {
        MechanicalInitialState::Measured {
            samples,
            velocity_tol,
        } => (samples.max(1) - 1, velocity_tol),
        MechanicalInitialState::Given { .. } => (0, 0.0),
    };
    if n <= first {
        return Err(SimError::TooShort {
            samples: n,
            needed: first + 1,
        });
    }
    let n_sub = substeps(ts, m.internal_step)?;
    let mut sim = Simulation {
        y: ym.to_vec(),
        modes: vec![None; n],
        start: first + 1,
        covered: vec![true; n],
        diverged_at: None,
        diverged_to: None,
        zeno: None,
    };
    let mut u = vec![0.0; m.inputs.len()];
    let mut integrator = Integrator::new(&r, ts, n_sub);
    for k in first..n.saturating_sub(1) {
        for (i, x) in u.iter_mut().enumerate() {
            *x = data.inputs[i].values[k];
        }
        let mut v = estimate_velocity(ym, k, ts);
        if v.abs() <= tol {
            v = 0.0;
        }
        let mut st = r.state_at(ym[k], v, &u);
        integrator.advance(&mut st, &u);
        sim.y[k + 1] = st.y;
        sim.modes[k + 1] = match st.regime {
            Regime::AtStop(i) => m.mode_of(Some(i), true, 0),
            Regime::Stuck { engaged } => m.mode_of(None, true, engaged),
            Regime::Slip { engaged, .. } => m.mode_of(None, false, engaged),
        };
    }
    if n == first + 1 {
        sim.start = first;
    }
    Ok(sim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MechanicalModeKind;
    use hysid_model::excitation::Excitation;
    use proptest::prelude::*;

    /// A file of the repository, read at test time.
    fn repository_file(path: &str) -> String {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
        std::fs::read_to_string(format!("{root}/{path}")).unwrap()
    }

    /// A mechanical model file (TOML, tagged `kind = "mechanical"`), read
    /// into a `serde_json::Value` first, as model files are read, so that
    /// these tests deserialize a model through one deserializer.
    fn parse(text: &str) -> MechanicalModel {
        let mut value: serde_json::Value = toml::from_str(text).unwrap();
        let kind = value.as_object_mut().unwrap().remove("kind");
        assert_eq!(kind.as_ref().and_then(|k| k.as_str()), Some("mechanical"));
        let m: MechanicalModel = serde_json::from_value(value).unwrap();
        m.validate().unwrap();
        m
    }
    const TS: f64 = 0.0025;

    fn head() -> MechanicalModel {
        parse(&repository_file("models/pick-and-place/head.toml"))
    }

    /// The head with every parameter at fraction `z` of its bounds.
    fn head_at(z: &[f64]) -> MechanicalModel {
        let mut m = head();
        for (p, zi) in m.parameters.iter_mut().zip(z) {
            if !p.fixed {
                p.value = p.bounds[0] + (p.bounds[1] - p.bounds[0]) * zi;
            }
        }
        m
    }

    fn given(m: &mut MechanicalModel, y: f64, v: f64) {
        m.initial_state = MechanicalInitialState::Given {
            position: y,
            velocity: v,
        };
    }

    fn value(m: &MechanicalModel, name: &str) -> f64 {
        m.parameters[m.parameter_index(name).unwrap()].value
    }

    /// Potential energy per unit mass with u = 0: springs, constant force and
    /// the engaged-or-not contact spring (counted whenever penetrating).
    fn energy(m: &MechanicalModel, y: f64, v: f64) -> f64 {
        let (c1, f0, c2, yc) = (
            value(m, "c1"),
            value(m, "f0"),
            value(m, "c2"),
            value(m, "yc"),
        );
        0.5 * v * v + 0.5 * c1 * y * y - f0 * y
            + if y > yc {
                0.5 * c2 * (y - yc).powi(2)
            } else {
                0.0
            }
    }

    #[test]
    fn head_model_parses_with_its_five_modes() {
        let m = head();
        let names: Vec<&str> = m.modes.iter().map(|q| q.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "upper_saturation",
                "free",
                "impact",
                "lower_saturation",
                "stick"
            ]
        );
        assert_eq!(m.mode_of(None, false, 1), Some(2));
        assert_eq!(m.mode_of(None, true, 1), Some(4));
        assert_eq!(m.mode_of(Some(1), true, 0), Some(3));
        let mut bad = m.clone();
        bad.modes.retain(|q| q.kind != MechanicalModeKind::Stick);
        assert!(bad.validate().unwrap_err().to_string().contains("stick"));
        // Long lists are checked by name sets: a name repeated at the end
        // of 50 000 parameters or modes is found, and a stop without a
        // rest mode is named.
        let mut long = m.clone();
        let p = long.parameters[0].clone();
        long.parameters
            .extend((0..50_000).map(|i| hysid_model::model::PhysicalParameter {
                name: format!("extra{i}"),
                ..p.clone()
            }));
        long.parameters.push(hysid_model::model::PhysicalParameter {
            name: "extra7".into(),
            ..p
        });
        assert_eq!(
            long.validate().unwrap_err().to_string(),
            crate::InvalidMechanical::DuplicateParameter("extra7".into()).to_string()
        );
        let mut long = m.clone();
        let q = long.modes[1].clone();
        long.modes
            .extend((0..50_000).map(|i| crate::MechanicalMode {
                name: format!("extra{i}"),
                ..q.clone()
            }));
        assert!(long.validate().is_ok());
        long.modes
            .retain(|q| q.stop.as_deref() != Some(m.stops[1].name.as_str()));
        assert_eq!(
            long.validate().unwrap_err().to_string(),
            crate::InvalidMechanical::NoRestMode(m.stops[1].name.clone()).to_string()
        );
        let json = serde_json::to_value(&m).unwrap();
        assert_eq!(serde_json::from_value::<MechanicalModel>(json).unwrap(), m);
    }

    /// Without friction, contacts or stops reached, the simulator matches
    /// the closed-form step response of a damped oscillator.
    #[test]
    fn linear_regime_matches_closed_form() {
        let mut m = head();
        for (n, v) in [("f1", 0.0), ("fs", 0.0), ("yc", 17.0)] {
            let i = m.parameter_index(n).unwrap();
            m.parameters[i].bounds[0] = 0.0;
            m.parameters[i].value = v;
        }
        given(&mut m, 5.0, 0.0);
        let (k, d, ku, f0) = (
            value(&m, "c1"),
            value(&m, "d1"),
            value(&m, "ku"),
            value(&m, "f0"),
        );
        let u = -0.05;
        let n = 400;
        let data = Dataset::siso(vec![u; n], vec![0.0; n], Some(TS)).unwrap();
        let r = run(&m, &m.values(), &data).unwrap();
        let yss = (ku * u + f0) / k;
        let wn = k.sqrt();
        let zeta = d / (2.0 * wn);
        let wd = wn * (1.0 - zeta * zeta).sqrt();
        let (a, b) = (5.0 - yss, zeta * wn * (5.0 - yss) / wd);
        let mut worst = 0.0f64;
        for (i, y) in r.y.iter().enumerate() {
            let t = i as f64 * TS;
            let exact = yss + (-zeta * wn * t).exp() * (a * (wd * t).cos() + b * (wd * t).sin());
            assert!(exact > 0.0 && exact < 17.0);
            worst = worst.max((y - exact).abs());
        }
        assert!(worst < 1e-7, "max error {worst}");
        assert!(r.modes.iter().all(|q| *q == Some(1)));
    }

    /// A frictionless free fall onto the lower stop: the impact is located
    /// within the step (the sample after it reads the stop exactly, with
    /// the closed-form impact time) and the velocity is reset to zero.
    #[test]
    fn stop_is_hit_at_the_right_time_and_resets_velocity() {
        let mut m = head();
        m.forces
            .retain(|f| matches!(f, crate::ForceElement::Constant { .. }));
        m.contacts.clear();
        m.modes
            .retain(|q| q.contacts.as_ref().is_none_or(|c| c.is_empty()));
        for (n, v) in [("f1", 0.0), ("fs", 0.0), ("f0", 1000.0)] {
            let i = m.parameter_index(n).unwrap();
            m.parameters[i].bounds[0] = 0.0;
            m.parameters[i].value = v;
        }
        m.validate().unwrap();
        given(&mut m, 0.0, 0.0);
        let n = 200;
        let data = Dataset::siso(vec![0.0; n], vec![0.0; n], Some(TS)).unwrap();
        let r = run(&m, &m.values(), &data).unwrap();
        // y = 500 t^2 reaches 25 at t = sqrt(0.05).
        let t_hit = 0.05f64.sqrt();
        for (k, y) in r.y.iter().enumerate() {
            let t = k as f64 * TS;
            if t < t_hit {
                assert!((y - 500.0 * t * t).abs() < 1e-9, "k {k}: {y}");
            } else {
                assert_eq!(*y, 25.0);
                assert_eq!(r.v[k], 0.0);
                assert_eq!(r.modes[k], Some(2), "lower_saturation after the reset");
            }
        }
    }

    /// The example of `docs/mechanical-models.md` ("Writing another system")
    /// is a valid model, and its bouncing stop never lets the mass through.
    #[test]
    fn documented_example_parses_and_bounces() {
        let doc = repository_file("docs/mechanical-models.md");
        let start = doc.rfind("```toml\n").unwrap() + "```toml\n".len();
        let end = start + doc[start..].find("```").unwrap();
        let mut m = parse(&doc[start..end]);
        given(&mut m, 0.0, -3.0);
        let n = 400;
        let data = Dataset::siso(vec![0.0; n], vec![0.0; n], Some(0.001)).unwrap();
        let r = run(&m, &m.values(), &data).unwrap();
        let lowest = r.y.iter().copied().fold(f64::INFINITY, f64::min);
        assert!((-0.1..-0.09).contains(&lowest), "lowest {lowest}");
        // Bounced (v := -0.5 v at the wall): moving away right after.
        let k = r.y.iter().position(|y| *y == lowest).unwrap();
        assert!(
            r.v[k + 1] > 0.0 || r.v[k] > 0.0,
            "{} {}",
            r.v[k],
            r.v[k + 1]
        );
        assert!(r.events > 0);
    }

    /// The head's test record of 1500 samples: a random input held over 40
    /// samples between -0.3 and 0.05 (from `seed`).
    fn head_record(seed: u64) -> Dataset {
        let ex = Excitation {
            n: 1500,
            hold: 40,
            low: -0.3,
            high: 0.05,
            ts: Some(TS),
            inputs: 1,
        };
        Dataset::siso(ex.generate(seed).remove(0), vec![0.0; 1500], Some(TS)).unwrap()
    }

    fn unit() -> impl Strategy<Value = Vec<f64>> {
        proptest::collection::vec(0.0f64..=1.0, 12)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// The position never leaves [y_up, y_low], and resting at a stop
        /// means exactly the stop's position with zero velocity.
        #[test]
        fn position_stays_between_the_stops(z in unit(), seed in any::<u64>(), low in -0.3f64..-0.1) {
            let mut m = head_at(&z);
            given(&mut m, 0.0, 0.0);
            let ex = Excitation { n: 600, hold: 40, low, high: 0.05, ts: Some(TS), inputs: 1 };
            let data = Dataset::siso(ex.generate(seed).remove(0), vec![0.0; 600], Some(TS)).unwrap();
            let r = run(&m, &m.values(), &data).unwrap();
            let (up, lowstop) = (value(&m, "y_up"), value(&m, "y_low"));
            for k in 0..600 {
                prop_assert!(r.y[k] >= up && r.y[k] <= lowstop, "k {}: y {}", k, r.y[k]);
                match r.modes[k].map(|q| m.modes[q].name.as_str()) {
                    Some("upper_saturation") => prop_assert!(r.y[k] == up && r.v[k] == 0.0),
                    Some("lower_saturation") => prop_assert!(r.y[k] == lowstop && r.v[k] == 0.0),
                    Some("stick") => prop_assert!(r.v[k] == 0.0),
                    Some(_) => {}
                    None => prop_assert!(false, "no mode at {}", k),
                }
                // Entering a stop (a reset) leaves zero velocity.
                if k > 0 && (r.y[k] == up || r.y[k] == lowstop) && r.y[k - 1] != r.y[k] {
                    prop_assert_eq!(r.v[k], 0.0);
                }
            }
        }

        /// The affine flows of a sliding regime are its acceleration: at
        /// random states, inputs, directions and engaged contacts,
        /// `A (y, v) + B u + c` equals `(v, slip_accel)`.
        #[test]
        fn the_affine_flows_are_the_sliding_acceleration(
            z in unit(), y in 0.0f64..30.0, v in -500.0f64..500.0, u in -0.3f64..0.1,
            dir in prop_oneof![Just(1.0), Just(-1.0)], engaged in 0u32..4,
        ) {
            let m = head_at(&z);
            let r = m.resolve();
            let engaged = engaged & ((1 << r.contacts.len()) - 1);
            let [a, b, c] = r.affine_flows(dir, engaged, 1);
            let (dy, dv) = (a[0] * y + a[1] * v + b[0] * u + c[0], a[2] * y + a[3] * v + b[1] * u + c[1]);
            let want = r.slip_accel(y, v, &[u], dir, engaged);
            prop_assert_eq!(dy, v);
            prop_assert!((dv - want).abs() <= 1e-9 * (1.0 + want.abs() + a[2].abs() * y), "{dv} vs {want}");
        }

        /// The sliding regime's margin marks what `left_slip` tests: not
        /// negative exactly where the state has left the regime (away from
        /// the margin's zero, where the two may round apart), so the event
        /// location's regula falsi is never turned to bisection by it.
        #[test]
        fn the_margin_agrees_with_the_regime_test(
            z in unit(), y in -2.0f64..30.0, v in -500.0f64..500.0,
            dir in prop_oneof![Just(1.0), Just(-1.0)], engaged in 0u32..4,
        ) {
            let r = head_at(&z).resolve();
            let engaged = engaged & ((1 << r.contacts.len()) - 1);
            let margin = r.slip_margin(y, v, dir, engaged);
            prop_assume!(margin.abs() > 1e-9);
            prop_assert_eq!(margin >= 0.0, r.left_slip(y, v, dir, engaged), "margin {}", margin);
        }

        /// Full sub-steps taken back to back change no bit of a run of the
        /// head through its impacts, sticking and stops.
        #[test]
        fn the_quiet_substeps_change_no_bit(z in unit(), seed in any::<u64>()) {
            let mut m = head_at(&z);
            given(&mut m, 0.0, 0.0);
            let data = head_record(seed);
            let quiet = run(&m, &m.values(), &data).unwrap();
            let each = run_with(&m, &m.values(), &data, |i| i.quiet = false).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            prop_assert_eq!(bits(&quiet.y), bits(&each.y));
            prop_assert_eq!(bits(&quiet.v), bits(&each.v));
            prop_assert_eq!(&quiet.modes, &each.modes);
            prop_assert_eq!((quiet.steps, quiet.events), (each.steps, each.events));
            prop_assert!(quiet.events > 0);
        }

        /// Full sub-steps in closed form simulate the head as RK4's four
        /// stages do, through its impacts, sticking and stops, with the
        /// same modes.
        #[test]
        fn the_closed_form_runs_as_the_stages(z in unit(), seed in any::<u64>()) {
            let mut m = head_at(&z);
            given(&mut m, 0.0, 0.0);
            let data = head_record(seed);
            let closed = run(&m, &m.values(), &data).unwrap();
            let staged = run_with(&m, &m.values(), &data, |i| i.closed_form = false).unwrap();
            let range = staged.y.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(1.0);
            for k in 0..data.len() {
                prop_assert!((closed.y[k] - staged.y[k]).abs() <= 1e-8 * range, "sample {k}: {} vs {}", closed.y[k], staged.y[k]);
            }
            prop_assert_eq!(&closed.modes, &staged.modes);
            prop_assert_eq!(closed.events, staged.events);
        }

        /// Without input the energy never grows (dampers, friction and the
        /// inelastic stops only dissipate).
        #[test]
        fn energy_does_not_grow_without_input(z in unit(), y0 in 0.0f64..1.0, v0 in -400.0f64..400.0) {
            let mut m = head_at(&z);
            let y0 = y0 * value(&m, "y_low");
            given(&mut m, y0, v0);
            let n = 400;
            let data = Dataset::siso(vec![0.0; n], vec![0.0; n], Some(TS)).unwrap();
            let r = run(&m, &m.values(), &data).unwrap();
            let scale = energy(&m, y0, v0).abs() + 1.0;
            let mut e_prev = energy(&m, r.y[0], r.v[0]);
            prop_assert!(e_prev <= energy(&m, y0, v0) + 1e-9 * scale);
            for k in 1..n {
                let e = energy(&m, r.y[k], r.v[k]);
                prop_assert!(e <= e_prev + 1e-9 * scale, "k {}: {} > {}", k, e, e_prev);
                e_prev = e;
            }
        }

        /// A stuck head stays stuck while the net force is below the static
        /// level, and breaks away when it exceeds it.
        #[test]
        fn stuck_stays_stuck_below_static_friction(z in unit(), y0 in 0.05f64..0.95, frac in -0.98f64..0.98) {
            let mut m = head_at(&z);
            let y0 = y0 * value(&m, "y_low");
            let r = m.resolve();
            let engaged = r.engaged_at(y0, 0.0);
            let (_, fs) = r.friction(engaged);
            let ku = value(&m, "ku");
            // u such that the net smooth force is frac * fs.
            let f_at_zero_u = r.smooth_force(y0, 0.0, &[0.0], engaged);
            let u = (frac * fs - f_at_zero_u) / ku;
            given(&mut m, y0, 0.0);
            let n = 200;
            let data = Dataset::siso(vec![u; n], vec![0.0; n], Some(TS)).unwrap();
            let run1 = run(&m, &m.values(), &data).unwrap();
            prop_assert!(run1.y.iter().all(|y| *y == y0));
            prop_assert!(run1.modes.iter().all(|q| *q == Some(4)));
            // Beyond the static level it moves.
            let u2 = ((1.05 * fs).copysign(frac) - f_at_zero_u) / ku;
            let data2 = Dataset::siso(vec![u2; n], vec![0.0; n], Some(TS)).unwrap();
            let run2 = run(&m, &m.values(), &data2).unwrap();
            prop_assert!(run2.y[1] != y0);
        }
    }
}
