//! Hybrid-automaton simulation: mode selection by invariant, affine flow,
//! guard crossings located within the step, resets.
//!
//! Guard sets come in two kinds. A guard with equality rows (a
//! lower-dimensional set such as the stop `y = 25`) is a **crossing guard**:
//! it fires at the first point of a step's trajectory that lies in it, when
//! the step did not start inside it, and at the start of a step that starts
//! on it and heads past it (a state released exactly onto a stop level, as
//! quantised data give, and pushed back). A full-dimensional guard is a
//! **condition guard**: in discrete time it fires at the start of a step
//! when `[x; u]` lies in it (the release of a saturation: "the motor pulls
//! away from the stop"); in continuous time it fires when the trajectory
//! enters it.
//!
//! Discrete time, one step `k -> k+1` in mode `q`:
//! 1. if `[x; u]` left `q`'s invariant, `q` becomes the first mode whose
//!    invariant holds it, else the one of least violation (uncovered);
//! 2. condition guards of `q` holding at `[x; u]` fire (first in file order,
//!    chained at most [`MAX_EVENTS_PER_STEP`] times);
//! 3. `x+ = A_q x + B_q u + f_q`;
//! 4. the crossing guard of `q` that the segment `[x; u] -> [x+; u]` meets
//!    first fires: `x+` is reset and `q` becomes its target.
//!
//! Continuous time: classical RK4 with the model's fixed internal step and
//! the input held over each sample; a crossing is located by bisection on
//! the step length (to 1e-12 of the step), the reset applied there and the
//! rest of the step integrated in the new mode. At most
//! [`MAX_EVENTS_PER_STEP`] events per internal step (a Zeno guard).

use super::{SimError, Simulation, SimulationOptions, ZenoSteps};
use crate::data::Dataset;
use crate::geometry::{MEMBERSHIP_TOL, Polyhedron};
use crate::model::{HybridAutomaton, InitialState, TimeDomain};

/// Bound on the events processed within one internal step.
pub const MAX_EVENTS_PER_STEP: usize = 16;

struct Runner<'a> {
    m: &'a HybridAutomaton,
    n: usize,
    z: Vec<f64>,
}

impl<'a> Runner<'a> {
    fn new(m: &'a HybridAutomaton) -> Self {
        let n = m.states.len();
        Self {
            m,
            n,
            z: vec![0.0; n + m.inputs.len()],
        }
    }

    fn ext(&mut self, x: &[f64], u: &[f64]) -> &[f64] {
        self.z[..self.n].copy_from_slice(x);
        self.z[self.n..].copy_from_slice(u);
        &self.z
    }

    /// Mode for `[x; u]`, keeping `q` while its invariant holds. Otherwise
    /// the first mode whose invariant holds it, lower-dimensional invariants
    /// first (a state on a stop starts in the stop's mode), else the mode of
    /// least violation (ties to a lower-dimensional invariant: a state just
    /// beyond a stop, e.g. a noisy measured initial output, is held at it).
    /// The flag tells whether the state is covered: inside an invariant, or
    /// off a stop whose set holds its projection.
    fn select(&mut self, q: Option<usize>, x: &[f64], u: &[f64]) -> (usize, bool) {
        let m = self.m;
        let z = self.ext(x, u).to_vec();
        if let Some(q) = q
            && m.modes[q].invariant.contains(&z)
        {
            return (q, true);
        }
        for lower_dimensional in [true, false] {
            if let Some(i) = m.modes.iter().position(|mode| {
                mode.invariant.is_lower_dimensional() == lower_dimensional
                    && mode.invariant.contains(&z)
            }) {
                return (i, true);
            }
        }
        let scale = 1.0 + z.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let mut best = (f64::INFINITY, false, 0usize);
        for (i, mode) in m.modes.iter().enumerate() {
            let v = mode.invariant.violation(&z);
            let lower = mode.invariant.is_lower_dimensional();
            let tie = (v - best.0).abs() <= 1e-12 * scale;
            if (v < best.0 && !tie) || (tie && lower && !best.1) {
                best = (v, lower, i);
            }
        }
        // Off a stop (e.g. a measured output just past it) is not a hole of
        // the model: covered when the point moved onto the stop's set lies
        // in some invariant.
        let covered = best.1 && {
            let on = onto_equalities(&m.modes[best.2].invariant, &z);
            m.modes.iter().any(|mode| mode.invariant.contains(&on))
        };
        (best.2, covered)
    }

    /// The state `x` moved onto the equality rows of mode `q`'s invariant
    /// (a measured output past a stop, put on the stop); unchanged for a
    /// full-dimensional invariant or a state already in it.
    fn onto_invariant(&mut self, q: usize, x: &[f64], u: &[f64]) -> Vec<f64> {
        let inv = &self.m.modes[q].invariant;
        let z = self.ext(x, u).to_vec();
        if !inv.is_lower_dimensional() || inv.contains(&z) {
            return x.to_vec();
        }
        onto_equalities(inv, &z)[..self.n].to_vec()
    }

    /// First transition from `q` met on the segment `x0 -> x1` under `u`;
    /// with `crossing_only`, only guards with equality rows count.
    fn first_crossing(
        &mut self,
        q: usize,
        x0: &[f64],
        x1: &[f64],
        u: &[f64],
        crossing_only: bool,
    ) -> Option<(f64, usize)> {
        let z0 = self.ext(x0, u).to_vec();
        let z1 = self.ext(x1, u).to_vec();
        let from = &self.m.modes[q].name;
        let mut best: Option<(f64, usize)> = None;
        let invariant = &self.m.modes[q].invariant;
        for (ti, t) in self.m.transitions.iter().enumerate() {
            if &t.from != from
                || (crossing_only && !t.guard.0.is_lower_dimensional())
                || (t.guard.0.contains(&z0) && !passes_through(invariant, &t.guard.0, &z0, &z1))
            {
                continue;
            }
            if let Some(s) = t.guard.0.first_hit_on_segment(&z0, &z1)
                && best.is_none_or(|(b, _)| s < b)
            {
                best = Some((s, ti));
            }
        }
        best
    }

    fn fire(&self, ti: usize, x: &mut [f64]) -> usize {
        let t = &self.m.transitions[ti];
        t.reset.apply(x);
        self.m.mode_index(&t.to).expect("validated")
    }

    /// First full-dimensional guard of `q` that holds at `[x; u]`.
    fn condition_guard(&mut self, q: usize, x: &[f64], u: &[f64]) -> Option<usize> {
        let z = self.ext(x, u).to_vec();
        let from = &self.m.modes[q].name;
        self.m.transitions.iter().position(|t| {
            &t.from == from && !t.guard.0.is_lower_dimensional() && t.guard.0.contains(&z)
        })
    }

    /// Steps 2-4 of a discrete-time step (see the module docs).
    fn discrete_step(&mut self, q: usize, x: &[f64], u: &[f64]) -> (usize, Vec<f64>) {
        let (q, x1, _) = self.traced_step(q, x, u);
        (q, x1)
    }

    /// [`Runner::discrete_step`] with what happened in it.
    fn traced_step(
        &mut self,
        mut q: usize,
        x: &[f64],
        u: &[f64],
    ) -> (usize, Vec<f64>, DiscreteStep) {
        let mut x = x.to_vec();
        let mut guards = Vec::new();
        for _ in 0..MAX_EVENTS_PER_STEP {
            match self.condition_guard(q, &x, u) {
                Some(ti) => {
                    guards.push(ti);
                    q = self.fire(ti, &mut x);
                }
                None => break,
            }
        }
        let flow_mode = q;
        let mut x1 = vec![0.0; self.n];
        self.m.modes[q].flow.eval(&x, u, &mut x1);
        let crossing = self.first_crossing(q, &x, &x1, u, true).map(|(_, ti)| ti);
        if let Some(ti) = crossing {
            q = self.fire(ti, &mut x1);
        }
        let step = DiscreteStep {
            guards,
            flow_mode,
            state: x,
            crossing,
        };
        (q, x1, step)
    }
}

/// `z` moved onto the equality rows of `p`, one row after the other, each by
/// the orthogonal projection onto its hyperplane (exact for the single row
/// of a stop).
fn onto_equalities(p: &Polyhedron, z: &[f64]) -> Vec<f64> {
    let mut on = z.to_vec();
    for (row, b) in p.a_eq.iter().zip(&p.b_eq) {
        let nn: f64 = row.iter().map(|v| v * v).sum();
        let r = (row.iter().zip(&on).map(|(a, v)| a * v).sum::<f64>() - b) / nn;
        for (v, a) in on.iter_mut().zip(row) {
            *v -= r * a;
        }
    }
    on
}

/// True when a step `z0 -> z1` that starts on the crossing guard `guard`
/// ends beyond it: the guard's hyperplane is a boundary of the mode's
/// `invariant` at `z0` (a row of it, active at `z0`, with a normal parallel
/// to one of the guard's equality rows) and `z1` violates that row. A step
/// that starts on a stop and moves away from it (a release) does not pass
/// through; one that starts on it and heads past it does, and the guard
/// fires at the start of the step.
fn passes_through(invariant: &Polyhedron, guard: &Polyhedron, z0: &[f64], z1: &[f64]) -> bool {
    let scale = 1.0 + z0.iter().chain(z1).fold(0.0f64, |m, v| m.max(v.abs()));
    let tol = MEMBERSHIP_TOL * scale;
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    guard.a_eq.iter().any(|e| {
        invariant.a.iter().zip(&invariant.b).any(|(a, b)| {
            let (na, ne) = (dot(a, a).sqrt(), dot(e, e).sqrt());
            let parallel = dot(a, e).abs() >= (1.0 - 1e-9) * na * ne;
            let active = ((dot(a, z0) - b) / na).abs() <= tol;
            parallel && active && (dot(a, z1) - b) / na > tol
        })
    })
}

fn rk4(m: &HybridAutomaton, q: usize, x: &[f64], u: &[f64], h: f64) -> Vec<f64> {
    let n = x.len();
    let f = |xs: &[f64], out: &mut [f64]| m.modes[q].flow.eval(xs, u, out);
    let (mut k1, mut k2, mut k3, mut k4) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut tmp = vec![0.0; n];
    f(x, &mut k1);
    for i in 0..n {
        tmp[i] = x[i] + 0.5 * h * k1[i];
    }
    f(&tmp, &mut k2);
    for i in 0..n {
        tmp[i] = x[i] + 0.5 * h * k2[i];
    }
    f(&tmp, &mut k3);
    for i in 0..n {
        tmp[i] = x[i] + h * k3[i];
    }
    f(&tmp, &mut k4);
    (0..n)
        .map(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
        .collect()
}

/// The ARX history state at sample `k` read from `y` and the inputs.
fn arx_state(na: usize, nb: usize, y: &[f64], data: &Dataset, k: usize) -> Vec<f64> {
    let mut x: Vec<f64> = (0..na.max(1)).map(|i| y[k - i]).collect();
    for i in 0..data.inputs.len() {
        for j in 1..nb {
            x.push(data.u(i)[k - j]);
        }
    }
    x
}

fn inputs_at(data: &Dataset, k: usize) -> Vec<f64> {
    (0..data.inputs.len()).map(|i| data.u(i)[k]).collect()
}

/// Initial sample index and state.
fn initial(m: &HybridAutomaton, data: &Dataset) -> Result<(usize, Vec<f64>), SimError> {
    match &m.initial_state {
        InitialState::ArxHistory { na, nb } => {
            let lag = (*na).max(*nb).max(1);
            if data.len() <= lag {
                return Err(SimError::TooShort {
                    samples: data.len(),
                    needed: lag,
                });
            }
            Ok((lag - 1, arx_state(*na, *nb, data.y(), data, lag - 1)))
        }
        InitialState::Given { state } => {
            if data.is_empty() {
                return Err(SimError::TooShort {
                    samples: 0,
                    needed: 0,
                });
            }
            Ok((0, state.clone()))
        }
    }
}

/// What one discrete-time step `k -> k+1` of [`simulate_traced`] did
/// (steps 2-4 of the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct DiscreteStep {
    /// The condition transitions that fired before the flow, in order
    /// (indices into `transitions`).
    pub guards: Vec<usize>,
    /// The mode whose flow made the step.
    pub flow_mode: usize,
    /// The state the flow started from (after the condition guards'
    /// resets).
    pub state: Vec<f64>,
    /// The crossing transition that fired after the flow, if any.
    pub crossing: Option<usize>,
}

/// Free-run simulation of a hybrid automaton driven by the inputs of `data`.
pub fn simulate(
    m: &HybridAutomaton,
    data: &Dataset,
    opts: SimulationOptions,
) -> Result<Simulation, SimError> {
    simulate_with(m, data, opts, None)
}

/// [`simulate`], with the record of every discrete-time step: with an
/// ARX-history initial state, entry `i` is the step that produced sample
/// `start + i` (the trace is empty for continuous time). The simulation is the same as [`simulate`]'s, bit for bit.
pub fn simulate_traced(
    m: &HybridAutomaton,
    data: &Dataset,
    opts: SimulationOptions,
) -> Result<(Simulation, Vec<DiscreteStep>), SimError> {
    let mut trace = Vec::new();
    let sim = simulate_with(m, data, opts, Some(&mut trace))?;
    Ok((sim, trace))
}

fn simulate_with(
    m: &HybridAutomaton,
    data: &Dataset,
    opts: SimulationOptions,
    mut trace: Option<&mut Vec<DiscreteStep>>,
) -> Result<Simulation, SimError> {
    let (k0, mut x) = initial(m, data)?;
    let h = match m.time {
        TimeDomain::Discrete => None,
        TimeDomain::Continuous => {
            let ts = data.ts.ok_or(SimError::NoSamplingTime)?;
            let step = m.internal_step.expect("validated");
            Some((ts, super::check_substeps((ts / step).ceil(), ts, step)?))
        }
    };
    let mut run = Runner::new(m);
    let mut sim = Simulation {
        y: data.y().to_vec(),
        modes: vec![None; data.len()],
        start: k0 + 1,
        covered: vec![true; data.len()],
        diverged_at: None,
        diverged_to: None,
        zeno: None,
    };
    let mut q = m.initial_mode.as_deref().and_then(|n| m.mode_index(n));
    let u0 = inputs_at(data, k0);
    if matches!(m.initial_state, InitialState::Given { .. }) {
        // A given initial state: its output is the first simulated sample.
        sim.start = 0;
        let (q0, covered) = run.select(q, &x, &u0);
        q = Some(q0);
        sim.covered[0] = covered;
        sim.modes[0] = Some(q0);
        if !sim.push_checked(0, m.output.eval(&x, &u0), opts.bound) {
            return Ok(sim);
        }
    }
    for k in k0..data.len() - 1 {
        let u = inputs_at(data, k);
        let (mut qk, covered) = run.select(q, &x, &u);
        sim.covered[k + 1] = covered;
        match h {
            None => {
                let (q1, x1, step) = run.traced_step(qk, &x, &u);
                if let Some(t) = trace.as_deref_mut() {
                    t.push(step);
                }
                qk = q1;
                x = x1;
            }
            Some((ts, substeps)) => {
                let hh = ts / substeps as f64;
                for _ in 0..substeps {
                    let mut left = hh;
                    let mut events = 0;
                    while left > 0.0 {
                        let x1 = rk4(m, qk, &x, &u, left);
                        match run.first_crossing(qk, &x, &x1, &u, false) {
                            Some(_) if events < MAX_EVENTS_PER_STEP => {
                                // Bisection on the step length for the first crossing.
                                let (mut lo, mut hi) = (0.0, left);
                                for _ in 0..60 {
                                    let mid = 0.5 * (lo + hi);
                                    let xm = rk4(m, qk, &x, &u, mid);
                                    if run.first_crossing(qk, &x, &xm, &u, false).is_some() {
                                        hi = mid;
                                    } else {
                                        lo = mid;
                                    }
                                    if hi - lo <= 1e-12 * hh {
                                        break;
                                    }
                                }
                                let mut xe = rk4(m, qk, &x, &u, hi);
                                let ti = run
                                    .first_crossing(qk, &x, &xe, &u, false)
                                    .map(|(_, ti)| ti)
                                    .expect("crossing found by bisection");
                                qk = run.fire(ti, &mut xe);
                                x = xe;
                                left -= hi;
                                events += 1;
                            }
                            crossing => {
                                if crossing.is_some() {
                                    ZenoSteps::add(&mut sim.zeno, k);
                                }
                                x = x1;
                                left = 0.0;
                            }
                        }
                    }
                    let (qn, _) = run.select(Some(qk), &x, &u);
                    qk = qn;
                }
            }
        }
        q = Some(qk);
        sim.modes[k + 1] = Some(qk);
        let u1 = inputs_at(data, k + 1);
        if !sim.push_checked(k + 1, m.output.eval(&x, &u1), opts.bound) {
            break;
        }
    }
    Ok(sim)
}

/// One-step prediction of an automaton whose state is its ARX history.
pub fn predict(m: &HybridAutomaton, data: &Dataset) -> Result<Simulation, SimError> {
    let InitialState::ArxHistory { na, nb } = m.initial_state else {
        unreachable!("prediction needs a state readable from data")
    };
    let (k0, _) = initial(m, data)?;
    let mut run = Runner::new(m);
    let mut sim = Simulation {
        y: data.y().to_vec(),
        modes: vec![None; data.len()],
        start: k0 + 1,
        covered: vec![true; data.len()],
        diverged_at: None,
        diverged_to: None,
        zeno: None,
    };
    for k in k0..data.len() - 1 {
        let x = arx_state(na, nb, data.y(), data, k);
        let u = inputs_at(data, k);
        let (q0, covered) = run.select(None, &x, &u);
        sim.covered[k + 1] = covered;
        // A measurement past a stop is the mass at the stop: from there the
        // release guard decides, as it does in simulation.
        let x = run.onto_invariant(q0, &x, &u);
        let (qk, x1) = run.discrete_step(q0, &x, &u);
        sim.modes[k + 1] = Some(qk);
        sim.y[k + 1] = m.output.eval(&x1, &inputs_at(data, k + 1));
    }
    Ok(sim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Dataset;
    use crate::geometry::Polyhedron;
    use crate::model::{
        AffineDynamics, AutomatonMode, GuardSet, ModelInfo, OutputMap, PwarxMode, PwarxModel,
        ResetMap, Transition,
    };
    use crate::simulate::SimulationOptions;
    use crate::simulate::pwarx;
    use proptest::prelude::*;

    /// The bouncing ball of the CORA toolbox's examples: y'' = -9.81, guard
    /// y = 0 with v <= 0, reset v := -0.75 v.
    fn ball() -> HybridAutomaton {
        HybridAutomaton {
            time: TimeDomain::Continuous,
            internal_step: Some(1e-3),
            states: vec!["y".into(), "v".into()],
            inputs: vec!["u".into()],
            output: OutputMap {
                c: vec![1.0, 0.0],
                d: vec![],
                e: 0.0,
            },
            modes: vec![AutomatonMode {
                name: "fly".into(),
                flow: AffineDynamics {
                    a: vec![vec![0.0, 1.0], vec![0.0, 0.0]],
                    b: vec![],
                    f: vec![0.0, -9.81],
                },
                invariant: Polyhedron::from_inequalities(vec![vec![-1.0, 0.0, 0.0]], vec![0.0]),
            }],
            transitions: vec![Transition {
                from: "fly".into(),
                to: "fly".into(),
                guard: GuardSet(Polyhedron {
                    a: vec![vec![0.0, 1.0, 0.0]],
                    b: vec![0.0],
                    a_eq: vec![vec![1.0, 0.0, 0.0]],
                    b_eq: vec![0.0],
                }),
                reset: ResetMap {
                    r: vec![vec![1.0, 0.0], vec![0.0, -0.75]],
                    c: vec![],
                },
            }],
            initial_mode: None,
            initial_state: InitialState::Given {
                state: vec![2.0, 0.0],
            },
            info: ModelInfo::default(),
        }
    }

    #[test]
    fn bouncing_ball_never_goes_below_ground_and_loses_energy() {
        let m = ball();
        m.validate().unwrap();
        let n = 301;
        let data = Dataset::siso(vec![0.0; n], vec![0.0; n], Some(0.01)).unwrap();
        let s = simulate(&(m), &data, SimulationOptions::default()).unwrap();
        assert!(
            s.y.iter().all(|&y| y >= -1e-9),
            "min {}",
            s.y.iter().cloned().fold(f64::INFINITY, f64::min)
        );
        // First impact at t = sqrt(2*2/9.81) = 0.6386 s; apex after it is 2 * 0.75^2 = 1.125.
        let apex = s.y[70..140].iter().cloned().fold(0.0, f64::max);
        assert!((apex - 1.125).abs() < 0.01, "apex {apex}");
        assert_eq!(s.diverged_at, None);
    }

    /// Random PWARX models whose regions are slabs `t_i <= w x <= t_(i+1)`
    /// along one direction: a partition, so the mode is unambiguous.
    fn arb_pwarx() -> impl Strategy<Value = PwarxModel> {
        (
            1usize..3,
            1usize..3,
            1usize..4,
            proptest::collection::vec(-0.4f64..0.4, 40),
            proptest::collection::vec(-1.0f64..1.0, 8),
        )
            .prop_map(|(na, nb, s, th, w)| {
                let d = na + nb;
                let w: Vec<f64> = w[..d].to_vec();
                let neg: Vec<f64> = w.iter().map(|v| -v).collect();
                let modes = (0..s)
                    .map(|i| {
                        let (mut a, mut b) = (vec![], vec![]);
                        if i > 0 {
                            a.push(neg.clone());
                            b.push(-0.2 * i as f64);
                        }
                        if i + 1 < s {
                            a.push(w.clone());
                            b.push(0.2 * (i + 1) as f64);
                        }
                        PwarxMode {
                            theta: (0..=d).map(|j| th[(i * 7 + j) % 40]).collect(),
                            region: Polyhedron::from_inequalities(a, b),
                            name: None,
                        }
                    })
                    .collect();
                PwarxModel {
                    na,
                    nb,
                    inputs: 1,
                    modes,
                    info: ModelInfo::default(),
                }
            })
    }

    proptest! {
        /// A PWARX model and its automaton form simulate to the same output.
        #[test]
        fn automaton_form_of_pwarx_simulates_identically(p in arb_pwarx(), u in proptest::collection::vec(-1.0f64..1.0, 30)) {
            let n = u.len();
            let y: Vec<f64> = (0..n).map(|k| (k as f64 * 0.3).sin()).collect();
            let data = Dataset::siso(u, y, None).unwrap();
            let a = HybridAutomaton::from_pwarx(&p);
            a.validate().unwrap();
            let sp = pwarx::simulate(&(p), &data, SimulationOptions::default()).unwrap();
            let sa = simulate(&(a), &data, SimulationOptions::default()).unwrap();
            prop_assert_eq!(sp.start, sa.start);
            for k in sp.start..n {
                prop_assert!((sp.y[k] - sa.y[k]).abs() < 1e-9 * (1.0 + sp.y[k].abs()), "k={} {} {}", k, sp.y[k], sa.y[k]);
            }
        }
    }
}

#[cfg(test)]
mod stop_tests {
    use super::simulate;
    use crate::data::Dataset;
    use crate::geometry::Polyhedron;
    use crate::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel};
    use crate::model::{Stop, StopBound};
    use crate::simulate::SimulationOptions;
    use proptest::prelude::*;

    /// A damped second-order system y(k) = a1 y(k-1) + a2 y(k-2) + b u(k-1) + c,
    /// two modes split at y(k-1) = 0.
    fn head(a1: f64, a2: f64, b: f64) -> PwarxModel {
        let mode = |theta: Vec<f64>, a: Vec<f64>| PwarxMode {
            theta,
            region: Polyhedron::from_inequalities(vec![a], vec![0.0]),
            name: None,
        };
        PwarxModel {
            na: 2,
            nb: 1,
            inputs: 1,
            modes: vec![
                mode(vec![a1, a2, b, 0.1], vec![1.0, 0.0, 0.0]),
                mode(vec![a1 * 0.9, a2, b * 1.2, -0.1], vec![-1.0, 0.0, 0.0]),
            ],
            info: ModelInfo::default(),
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Simulation never passes a known stop, and every sample in a
        /// saturation mode sits exactly on its level.
        #[test]
        fn simulation_never_passes_a_stop(
            a1 in 1.2f64..1.9, b in 0.5f64..3.0, hi in 0.5f64..3.0, lo in -3.0f64..-0.5,
            u in proptest::collection::vec(-2.0f64..2.0, 20..120),
            y0 in -4.0f64..4.0, on_stop in 0usize..3,
        ) {
            let a2 = -0.95 * a1 * a1 / 4.0; // real, stable poles
            let stops = [
                Stop { level: hi, bound: StopBound::Max, tol: None },
                Stop { level: lo, bound: StopBound::Min, tol: None },
            ];
            let a = HybridAutomaton::from_pwarx_with_stops(&head(a1, a2, b), &stops);
            a.validate().unwrap();
            let n = u.len();
            // Measured initial outputs anywhere: inside, exactly on a stop,
            // or beyond one (noise).
            let start = [y0, hi, lo][on_stop];
            let data = Dataset::siso(u, vec![start; n], None).unwrap();
            let names: Vec<String> = a.modes.iter().map(|m| m.name.clone()).collect();
            let s = simulate(&(a), &data, SimulationOptions::default()).unwrap();
            // Starting off a stop is not a hole: every step is covered.
            prop_assert!(s.covered.iter().all(|&c| c));
            for k in s.start..n {
                prop_assert!(s.y[k] <= hi + 1e-12 && s.y[k] >= lo - 1e-12, "k={} y={}", k, s.y[k]);
                let q = &names[s.modes[k].unwrap()];
                if q.starts_with("sat_max") { prop_assert_eq!(s.y[k], hi); }
                if q.starts_with("sat_min") { prop_assert_eq!(s.y[k], lo); }
            }
        }
    }

    /// y(k+1) = 0.5 y(k) + u(k) against a stop at y = 1: every number
    /// below is exact in binary, as on quantised data.
    fn first_order_with_stop() -> HybridAutomaton {
        let p = PwarxModel {
            na: 1,
            nb: 1,
            inputs: 1,
            modes: vec![PwarxMode {
                theta: vec![0.5, 1.0, 0.0],
                region: Polyhedron::everything(),
                name: None,
            }],
            info: ModelInfo::default(),
        };
        let stop = Stop {
            level: 1.0,
            bound: StopBound::Max,
            tol: None,
        };
        HybridAutomaton::from_pwarx_with_stops(&p, &[stop])
    }

    #[test]
    fn a_step_that_starts_exactly_on_the_stop_does_not_pass_it() {
        let a = first_order_with_stop();
        // Reach the stop (0 + 2 > 1), release onto it exactly (0.5 + 0.5 = 1),
        // then push past it from y = 1 (0.5 + 2 > 1).
        let u = vec![2.0, 0.5, 2.0, 2.0];
        let data = Dataset::siso(u, vec![0.0; 4], None).unwrap();
        let s = simulate(&(a.clone()), &data, SimulationOptions::default()).unwrap();
        assert_eq!(&s.y[1..], &[1.0, 1.0, 1.0]);
        let free = a.mode_index("mode 1").unwrap();
        let sat = a.mode_index("sat_max_1").unwrap();
        assert_eq!(s.modes[2], Some(free), "released onto the level");
        assert_eq!(s.modes[3], Some(sat), "held again when pushed");
    }

    /// One-step prediction from a measured output just past the stop (noise)
    /// while the input releases it: the mass is taken at the stop and the
    /// release guard decides, so the prediction leaves the stop.
    #[test]
    fn prediction_from_a_measurement_past_the_stop_can_release() {
        let a = first_order_with_stop();
        let data = Dataset::siso(vec![0.0, 2.0, 0.0], vec![1.003, 0.5, 1.0], None).unwrap();
        let p = super::predict(&a, &data).unwrap();
        assert_eq!(p.y[1], 0.5, "released: 0.5 * 1 + 0");
        assert_eq!(p.modes[1], a.mode_index("mode 1"));
        // Pushed from inside: the prediction stops at the level.
        assert_eq!(p.y[2], 1.0);
    }

    #[test]
    fn the_stop_is_reached_held_and_released() {
        let a = HybridAutomaton::from_pwarx_with_stops(
            &head(1.5, -0.56, 1.0),
            &[Stop {
                level: 1.0,
                bound: StopBound::Max,
                tol: None,
            }],
        );
        // Push hard for 40 samples, then pull back.
        let u: Vec<f64> = (0..80).map(|k| if k < 40 { 2.0 } else { -2.0 }).collect();
        let data = Dataset::siso(u, vec![0.0; 80], None).unwrap();
        let s = simulate(&(a.clone()), &data, SimulationOptions::default()).unwrap();
        let sat = a.mode_index("sat_max_1").unwrap();
        let first = s
            .modes
            .iter()
            .position(|q| *q == Some(sat))
            .expect("the stop is reached");
        assert!(first < 40);
        assert!(
            s.modes[first..40].iter().all(|q| *q == Some(sat)),
            "held while pushed"
        );
        assert!(s.y[60..].iter().all(|&y| y < 1.0), "released when pulled");
    }
}
