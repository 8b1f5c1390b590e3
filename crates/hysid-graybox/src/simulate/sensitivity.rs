//! Forward sensitivities of a run: the derivatives of the states and of
//! the output in the parameters and the estimated initial states, carried
//! through the simulation beside the state.
//!
//! Between events they follow the variational equations `S' = f_x S + f_θ`
//! (`S = dx/dθ`), differentiated through the same RK4 stages as the state:
//! the exact derivative of the discrete step `x+ = Φ(h, x, θ)`. At an event
//! with surface `g`, located at the length `τ` into the step, with reset
//! `x+ = R(x-)`, they jump by the saltation rule (Hiskens and Pai,
//! "Trajectory sensitivity analysis of hybrid systems", IEEE Trans.
//! Circuits and Systems I 47(2), 2000, section III), written for the
//! discrete step, whose rate in its length `Φ_h` stands for the flow:
//!
//! ```text
//! τ_θ = -(g_x S + g_θ) / (g_x Φ_h)      S at the event: Φ_x S + Φ_θ + Φ_h τ_θ
//! S+  = R_x S + R_θ                    the rest of the step: length ℓ - τ
//! ```
//!
//! The rest of the step then carries the derivative of its length,
//! `ℓ_θ - τ_θ` (the sub-step grid is fixed: `ℓ_θ = 0` at each sub-step's
//! start), which adds `Φ_h ℓ_θ` at its end: the continuous rule's
//! `(R_x f- - f+) τ_θ`, for the discrete step, exact to rounding and the
//! location's precision. The rates are taken at the last state the
//! location found before the event, in the regime the event ends.
//!
//! The events the simulator handles are of this form: a stop reached
//! (`g` the distance to the stop, `R` its position and rebound or rest), a
//! sliding velocity come to zero (`g = v`, `R` puts it at zero), a stuck
//! friction or a resting stop let go (`g` the applied force beyond the
//! static level, no reset), a transition (its guard and reset). An event
//! at a sample instant (the input's jump, a held element let go by the new
//! input, the Zeno bound's hold) has a fixed time: `τ_θ = 0`; so has one
//! whose surface does not move along the step (`g_x Φ_h = 0`).
//!
//! In a regime whose flows are affine in the states and inputs (the
//! parameters bound), the flows' derivatives are read from the tapes once
//! ([`Linear`]) and a step of the sub-step's length is one closed-form map
//! ([`LinearStep`]), as the state's is.
//!
//! The derivatives of the expressions come from their tapes
//! ([`crate::expr::Expression::gradient`]) in the model with the
//! parameters as slots; the state itself is the run's, bit for bit.
//! Delays are not differentiated: [`differentiable`] says whether a model
//! has a fitted one.
//!
//! The affine regimes' closed form is in `affine`, the jumps at events in
//! `saltation`; this module holds the sensitivities, their steps and the
//! rows of the initial states and the output.

use super::{Effect, ElementRegime, HybridState, Machine, Sliding};
use crate::compile::CompiledModel;
use crate::expr::{Adjoints, Expression};
use nalgebra::DMatrix;
use std::rc::Rc;

mod affine;
use affine::{
    Linear, LinearStep, add_affine, add_parameter_columns, compose, product_into, unit_points,
};
mod saltation;

/// The derivatives of a run in its parameters and estimated initial
/// states ([`super::run_with_sensitivities`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Sensitivities {
    /// Columns: the model's parameters, then the states the initial-state
    /// rule estimates ([`CompiledModel::estimates`]' order).
    pub columns: usize,
    /// `dy(k)/dθ`, row-major (samples x columns); zero where the run did
    /// not simulate (before its first sample).
    pub dy: Vec<f64>,
    /// `dx(k)/dθ`, row-major (samples x states x columns).
    pub dx: Vec<f64>,
    /// The sample of the first row: 0 but in a group of segments of a
    /// segmented run, which holds the rows of its own samples only.
    first: usize,
    /// The model's states.
    states: usize,
}

impl Sensitivities {
    /// Zeros for the samples `rows` of a model with `states` states.
    pub(super) fn zeros(rows: std::ops::Range<usize>, states: usize, columns: usize) -> Self {
        let samples = rows.len();
        Sensitivities {
            columns,
            dy: vec![0.0; samples * columns],
            dx: vec![0.0; samples * states * columns],
            first: rows.start,
            states,
        }
    }

    /// The row of `dy` at sample `k`.
    pub fn dy_row(&self, k: usize) -> &[f64] {
        let c = self.columns;
        &self.dy[(k - self.first) * c..(k - self.first + 1) * c]
    }

    /// The row of `dy` at sample `k`, to write.
    pub(super) fn dy_row_mut(&mut self, k: usize) -> &mut [f64] {
        let c = self.columns;
        &mut self.dy[(k - self.first) * c..(k - self.first + 1) * c]
    }

    /// The block of `dx` at sample `k` (states x columns, row-major).
    pub(super) fn dx_block(&self, k: usize) -> &[f64] {
        let block = self.states * self.columns;
        &self.dx[(k - self.first) * block..(k - self.first + 1) * block]
    }

    /// The block of `dx` at sample `k`, to write.
    pub(super) fn dx_block_mut(&mut self, k: usize) -> &mut [f64] {
        let block = self.states * self.columns;
        &mut self.dx[(k - self.first) * block..(k - self.first + 1) * block]
    }

    /// The row of sample `k` alone.
    pub(super) fn row(&self, k: usize) -> Sensitivities {
        let mut one = Sensitivities::zeros(k..k + 1, self.states, self.columns);
        one.copy_rows(self, k..k + 1);
        one
    }

    /// Copies the rows of the samples `rows` from `other`, which holds them.
    pub(super) fn copy_rows(&mut self, other: &Sensitivities, rows: std::ops::Range<usize>) {
        let (c, block) = (self.columns, self.states * self.columns);
        let (at, from) = (rows.start - self.first, rows.start - other.first);
        let count = rows.len();
        self.dy[at * c..(at + count) * c].copy_from_slice(&other.dy[from * c..(from + count) * c]);
        self.dx[at * block..(at + count) * block]
            .copy_from_slice(&other.dx[from * block..(from + count) * block]);
    }

    /// The rows of `dx` at sample `k` of the states `m` estimates (in
    /// [`CompiledModel::estimates`]' order), row-major.
    pub(super) fn estimated_rows(&self, m: &CompiledModel, k: usize) -> Vec<f64> {
        let c = self.columns;
        let block = self.dx_block(k);
        m.estimates
            .iter()
            .flat_map(|e| block[e.state * c..(e.state + 1) * c].iter().copied())
            .collect()
    }
}

/// Whether the sensitivities of `m`'s runs are exact in every parameter:
/// no input delay depends on a parameter (a delay moves the instants at
/// which the input is sampled, which the sensitivities do not follow).
pub fn differentiable(m: &CompiledModel) -> bool {
    m.delays.iter().all(|d| d.as_constant().is_some())
}

/// Total derivatives of expressions: the partial derivatives of an
/// expression in the states and the parameters, composed with `S`.
struct Differ {
    states: usize,
    parameters: usize,
    columns: usize,
    /// The slots differentiated: the states, then the parameters.
    wrt: Vec<u32>,
    /// The partial derivatives of the last expression, in `wrt`'s order.
    grad: Vec<f64>,
    /// The tapes' workspace ([`Expression::gradient_with`]).
    scratch: Adjoints,
}

impl Differ {
    /// The value of `e` at `slots`, and its total derivative
    /// `e_x s + e_θ` in `out` (`s`: states x columns, row-major).
    fn total(&mut self, e: &Expression, slots: &[f64], s: &[f64], out: &mut [f64]) -> f64 {
        let value = e.gradient_with(slots, &self.wrt, &mut self.grad, &mut self.scratch);
        out.fill(0.0);
        let c = self.columns;
        for (j, &g) in self.grad[..self.states].iter().enumerate() {
            if g != 0.0 {
                for (o, sj) in out.iter_mut().zip(&s[j * c..(j + 1) * c]) {
                    *o += g * sj;
                }
            }
        }
        for (o, g) in out.iter_mut().zip(&self.grad[self.states..]) {
            *o += g;
        }
        value
    }

    /// `e`'s rate along the flow `f`: its partial derivatives in the states
    /// (of the last [`Differ::total`]) times `f`.
    fn rate(&self, f: &[f64]) -> f64 {
        self.grad[..self.states]
            .iter()
            .zip(f)
            .map(|(g, f)| g * f)
            .sum()
    }
}

/// The sensitivities a [`Machine`] carries (see the module doc).
pub(crate) struct Tangent<'a> {
    /// The model with its parameters as slots: what is differentiated.
    model: &'a CompiledModel,
    d: Differ,
    /// `dx/dθ`, row-major (states x columns).
    s: Vec<f64>,
    /// The RK4 stage's `S`, and the four stages' derivatives of the flows.
    stage: Vec<f64>,
    t: [Vec<f64>; 4],
    /// The same in the step's length: the stage state's derivative, the
    /// stages' flows' derivatives, and `Φ_h` of the last step.
    stage_h: Vec<f64>,
    t_h: [Vec<f64>; 4],
    phi_h: Vec<f64>,
    /// `ℓ_θ`: the derivative of the length left in the sub-step.
    left: Vec<f64>,
    /// The flows' partial derivatives at a point: in the states
    /// (states x states) and in the parameters (states x parameters).
    fx: Vec<f64>,
    ftheta: Vec<f64>,
    /// Spare rows (columns long).
    row: Vec<f64>,
    spare: Vec<f64>,
    /// The regimes met, with their flows' derivatives where these are
    /// affine in the state and the input ([`Linear`]).
    regimes: Vec<(usize, Vec<ElementRegime>, Option<Linear>)>,
    /// The sliding regime's model ([`Machine::select`]) of the step being
    /// carried; `None`: `model`.
    sliding: Option<Rc<Sliding>>,
}

/// The columns of `m`'s sensitivities: its parameters, then the states its
/// initial-state rule estimates ([`Sensitivities::columns`]).
pub(super) fn columns(m: &CompiledModel) -> usize {
    m.parameters + m.estimates.len()
}

/// Relative agreement asked of a regime's derivatives at a check point
/// before they are taken as affine.
const AFFINE_CHECK: f64 = 1e-9;

impl<'a> Tangent<'a> {
    /// Sensitivities in the parameters and estimated states of `model`
    /// (not bound: its parameters are slots), at zero.
    pub(super) fn new(model: &'a CompiledModel) -> Self {
        let (n, p) = (model.states, model.parameters);
        let columns = columns(model);
        let p0 = model.parameter_slot() as u32;
        let wrt = (0..n as u32).chain(p0..p0 + p as u32).collect();
        let matrix = || vec![0.0; n * columns];
        Tangent {
            model,
            d: Differ {
                states: n,
                parameters: p,
                columns,
                wrt,
                grad: vec![0.0; n + p],
                scratch: Adjoints::default(),
            },
            s: matrix(),
            stage: matrix(),
            t: [matrix(), matrix(), matrix(), matrix()],
            stage_h: vec![0.0; n],
            t_h: [vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            phi_h: vec![0.0; n],
            left: vec![0.0; columns],
            fx: vec![0.0; n * n],
            ftheta: vec![0.0; n * p],
            row: vec![0.0; columns],
            spare: vec![0.0; columns],
            regimes: Vec::new(),
            sliding: None,
        }
    }

    /// Row `i` of `S`.
    fn s_row(&mut self, i: usize) -> &mut [f64] {
        let c = self.d.columns;
        &mut self.s[i * c..(i + 1) * c]
    }

    /// Stage `i`'s derivatives of the flows (into `t[i]` and `t_h[i]`) at
    /// the stage state loaded in `slots`, from the stage's `S` in `stage`
    /// and `stage_h`: the partials read from the tapes ([`Tangent::partials_at`])
    /// or, in an affine regime, from `linear`.
    fn stage_tangent(
        &mut self,
        (mode, effects): (usize, &[Effect]),
        linear: Option<&Linear>,
        slots: &[f64],
        i: usize,
    ) {
        let (n, p, c) = (self.d.states, self.d.parameters, self.d.columns);
        let fx = match linear {
            // f_θ = G0 + Σ x_j Gx_j + Σ u_i Gu_i: the slots hold (x, u) in order.
            Some(l) => {
                l.f_theta_into(&slots[..n], &slots[n..n + l.b.len() - 1], &mut self.ftheta);
                &l.a
            }
            None => {
                self.partials_at(mode, effects, slots);
                &self.fx
            }
        };
        compose(
            (fx, &self.ftheta),
            (&self.stage, &self.stage_h),
            (&mut self.t[i], &mut self.t_h[i]),
            (p, c),
        );
    }

    /// `S` and `Φ_h` over the closed-form step `step` of `linear` from `(x,
    /// u)`.
    fn closed_step(&mut self, linear: &Linear, step: &LinearStep, x: &[f64], u: &[f64]) {
        let (n, p, c) = (self.d.states, self.d.parameters, self.d.columns);
        // T(hA) S + P(x, u), into `stage`, then swapped into `s`.
        product_into(&step.t, &self.s, n, c, &mut self.stage);
        self.ftheta.fill(0.0);
        add_affine(&step.p, x.iter().chain(u).copied(), &mut self.ftheta);
        add_parameter_columns(&self.ftheta, &mut self.stage, p, c);
        std::mem::swap(&mut self.s, &mut self.stage);
        // Φ_h = T'(hA) f(x, u), f into a spare row.
        let f = &mut self.t_h[0];
        linear.flow_into(x, u, f);
        product_into(&step.dt, f, n, 1, &mut self.phi_h);
    }

    /// The partial derivatives of the flows of `mode` under `effects` at
    /// the point loaded in `slots`, into `fx` (in the states) and `ftheta`
    /// (in the parameters): a held state's row is zero, a sliding
    /// friction's level (where positive) is subtracted in its direction.
    fn partials_at(&mut self, mode: usize, effects: &[Effect], slots: &[f64]) {
        let (n, p) = (self.d.states, self.d.parameters);
        let sliding = self.sliding.clone();
        let q = &Sliding::unbound_or(sliding.as_deref(), self.model).modes[mode];
        let d = &mut self.d;
        for (r, f) in q.flow.iter().enumerate() {
            f.gradient_with(slots, &d.wrt, &mut d.grad, &mut d.scratch);
            self.fx[r * n..(r + 1) * n].copy_from_slice(&d.grad[..n]);
            self.ftheta[r * p..(r + 1) * p].copy_from_slice(&d.grad[n..]);
        }
        for effect in effects {
            match *effect {
                Effect::Friction(v, e, dir) => {
                    let kinetic = &q.friction[e].0;
                    if kinetic.gradient_with(slots, &d.wrt, &mut d.grad, &mut d.scratch) > 0.0 {
                        let rows = self.fx[v * n..(v + 1) * n]
                            .iter_mut()
                            .chain(&mut self.ftheta[v * p..(v + 1) * p]);
                        for (o, g) in rows.zip(&d.grad) {
                            *o -= dir * g;
                        }
                    }
                }
                Effect::Hold(s) => {
                    self.fx[s * n..(s + 1) * n].fill(0.0);
                    self.ftheta[s * p..(s + 1) * p].fill(0.0);
                }
            }
        }
    }

    /// `S += Φ_h ⊗ l`.
    fn add_rate(&mut self, l: &[f64]) {
        let c = self.d.columns;
        for (i, fi) in self.phi_h.iter().enumerate() {
            for (s, t) in self.s[i * c..(i + 1) * c].iter_mut().zip(l) {
                *s += fi * t;
            }
        }
    }
}

impl<'a> Machine<'a> {
    /// Carries sensitivities in the parameters and estimated states of
    /// `unbound` (the machine's model before its parameters were bound).
    pub(super) fn differentiate(&mut self, unbound: &'a CompiledModel) {
        self.tangent = Some(Box::new(Tangent::new(unbound)));
        self.unbound = Some(unbound);
        self.sliding.clear();
        self.directions.clear();
        self.current = None;
    }

    /// Zero sensitivities for a run over the samples `rows` (`None` when
    /// the machine carries none).
    pub(super) fn sensitivities_for(&self, rows: std::ops::Range<usize>) -> Option<Sensitivities> {
        let t = self.tangent.as_ref()?;
        Some(Sensitivities::zeros(rows, t.d.states, t.d.columns))
    }

    /// Whether this machine carries sensitivities.
    pub(super) fn differentiates(&self) -> bool {
        self.tangent.is_some()
    }

    /// `S` at the start of a run: zero, but for the estimated states'
    /// rows, which are `rows` (estimates x columns, row-major), or the unit
    /// rows of their own columns when `None`.
    pub(super) fn tangent_start(&mut self, rows: Option<&[f64]>) {
        let Some(t) = self.tangent.as_mut() else {
            return;
        };
        t.s.fill(0.0);
        let (p, c) = (t.d.parameters, t.d.columns);
        for (j, e) in t.model.estimates.iter().enumerate() {
            let row = &mut t.s[e.state * c..(e.state + 1) * c];
            match rows {
                Some(rows) => row.copy_from_slice(&rows[j * c..(j + 1) * c]),
                None => row[p + j] = 1.0,
            }
        }
    }

    /// A new sub-step: its length is fixed (`ℓ_θ = 0`).
    pub(super) fn tangent_substep(&mut self) {
        if let Some(t) = self.tangent.as_mut() {
            t.left.fill(0.0);
        }
    }

    /// Carries `S` over the RK4 step of length `h` from `hs.x` (the step
    /// the state takes), stage by stage, into `Φ_x S + Φ_θ`, with `Φ_h`
    /// kept; a step to the end of the sub-step (`to_end`) adds `Φ_h ℓ_θ`.
    pub(super) fn tangent_step(&mut self, hs: &HybridState, u: &[f64], h: f64, to_end: bool) {
        let Some(mut t) = self.tangent.take() else {
            return;
        };
        self.prepare(hs);
        t.sliding = self.current.clone();
        let at = self.linear_regime(&mut t, hs, u);
        let mut regimes = std::mem::take(&mut t.regimes);
        let linear = regimes[at].2.as_mut();
        match linear {
            // The sub-step's length: the closed form.
            Some(l) if h == self.full_step => {
                l.form_step(h, t.d.states, u.len());
                if let Some((_, step)) = &l.step {
                    t.closed_step(l, step, &hs.x, u);
                }
            }
            l => {
                self.load(&hs.x, u);
                self.stages_tangent(&mut t, hs, h, l.map(|l| &*l));
            }
        }
        t.regimes = regimes;
        if to_end {
            let left = std::mem::take(&mut t.left);
            t.add_rate(&left);
            t.left = left;
        }
        self.tangent = Some(t);
    }

    /// [`Machine::tangent_step`] stage by stage (the stage states from the
    /// flows, as [`Machine::rk4`] takes them), from the state loaded.
    fn stages_tangent(
        &mut self,
        t: &mut Tangent,
        hs: &HybridState,
        h: f64,
        linear: Option<&Linear>,
    ) {
        let mut k = std::mem::take(&mut self.k);
        t.stage.copy_from_slice(&t.s);
        t.stage_h.fill(0.0);
        let lengths = [0.5 * h, 0.5 * h, h];
        for i in 0..4 {
            self.flows(hs.mode, &mut k[i]);
            t.stage_tangent((hs.mode, &self.effects), linear, &self.slots, i);
            if let Some(&c) = lengths.get(i) {
                self.stage(hs, &k[i], c);
                let Tangent {
                    stage,
                    s,
                    t: d,
                    stage_h,
                    t_h,
                    ..
                } = t;
                for ((st, s), d) in stage.iter_mut().zip(s.iter()).zip(&d[i]) {
                    *st = s + c * d;
                }
                // d(x + c k_i)/dh, with c = h/2 or h.
                let dc = c / h;
                for ((st, k), d) in stage_h.iter_mut().zip(&k[i]).zip(&t_h[i]) {
                    *st = dc * k + c * d;
                }
            }
        }
        let sixth = h / 6.0;
        let Tangent {
            s,
            t: d,
            phi_h,
            t_h,
            ..
        } = t;
        for (j, s) in s.iter_mut().enumerate() {
            *s += sixth * (d[0][j] + 2.0 * d[1][j] + 2.0 * d[2][j] + d[3][j]);
        }
        for (j, p) in phi_h.iter_mut().enumerate() {
            let mean = (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]) / 6.0;
            *p = mean + sixth * (2.0 * t_h[1][j] + 2.0 * t_h[2][j] + t_h[3][j]);
        }
        self.k = k;
    }

    /// The entry of `t`'s cache of regimes for the regime of `hs` (the
    /// effects [`Machine::prepare`]d), added when first met, with its affine
    /// derivatives where the bound flows are affine in the state and the
    /// input, every sliding friction's level is a constant, and the tapes'
    /// derivatives at `x = 1, u = 1` agree with the affine form read at `0`
    /// and the unit vectors; `None` elsewhere: the stages read the tapes.
    fn linear_regime(&mut self, t: &mut Tangent, hs: &HybridState, u: &[f64]) -> usize {
        let at = t
            .regimes
            .iter()
            .position(|(q, r, _)| *q == hs.mode && *r == hs.regimes);
        if let Some(i) = at {
            return i;
        }
        let linear = self.form_linear(t, hs.mode, u.len());
        t.regimes.push((hs.mode, hs.regimes.clone(), linear));
        t.regimes.len() - 1
    }

    /// [`Machine::linear_regime`]'s affine derivatives of `mode` under the
    /// prepared effects, `None` where they are not affine.
    fn form_linear(&mut self, t: &mut Tangent, mode: usize, inputs: usize) -> Option<Linear> {
        self.affine_of(mode)?;
        let q = &self.bound().modes[mode];
        let constant_levels = self.effects.iter().all(|e| match *e {
            Effect::Friction(_, i, _) => q.friction[i].0.as_constant().is_some(),
            Effect::Hold(_) => true,
        });
        if !constant_levels {
            return None;
        }
        let (n, p) = (t.d.states, t.d.parameters);
        // f_x, f_θ and f at a point.
        let mut at = |x: &[f64], u: &[f64]| -> (Vec<f64>, Vec<f64>, Vec<f64>) {
            self.load(x, u);
            t.partials_at(mode, &self.effects, &self.slots);
            let mut f = vec![0.0; n];
            self.flows(mode, &mut f);
            (t.fx.clone(), t.ftheta.clone(), f)
        };
        let (a, g0, b0) = at(&vec![0.0; n], &vec![0.0; inputs]);
        let (mut g, mut b) = (vec![g0], vec![b0]);
        for (j, (x, u)) in unit_points(n, inputs).enumerate() {
            let (_, gj, bj) = at(&x, &u);
            g.push(gj.iter().zip(&g[0]).map(|(a, b)| a - b).collect());
            if j >= n {
                b.push(bj.iter().zip(&b[0]).map(|(a, b)| a - b).collect());
            }
        }
        let ones = (vec![1.0; n], vec![1.0; inputs]);
        let (a_check, g_check, f_check) = at(&ones.0, &ones.1);
        debug_assert_eq!(g[0].len(), n * p);
        let linear = Linear {
            a,
            g,
            b,
            step: None,
        };
        let near = |x: &f64, y: &f64| (x - y).abs() <= AFFINE_CHECK * x.abs().max(y.abs()).max(1.0);
        let affine = linear.a.iter().zip(&a_check).all(|(x, y)| near(x, y))
            && linear
                .f_theta(&ones.0, &ones.1)
                .iter()
                .zip(&g_check)
                .all(|(x, y)| near(x, y))
            && linear
                .flow(&ones.0, &ones.1)
                .iter()
                .zip(&f_check)
                .all(|(x, y)| near(x, y));
        affine.then_some(linear)
    }

    /// Carries `S` over steps of the given lengths at a state at rest (its
    /// derivative is zero, so is `Φ_h`; its sensitivities may still move).
    pub(super) fn tangent_rest(
        &mut self,
        hs: &HybridState,
        u: &[f64],
        lengths: impl Iterator<Item = f64>,
    ) {
        if self.tangent.is_some() {
            for h in lengths.filter(|h| *h > 0.0) {
                self.tangent_step(hs, u, h, false);
            }
        }
    }

    /// The rows of the measured rule's states in `x` (loaded with `u`):
    /// the position read through the output map of `mode`, affine in it
    /// (`y = a + b x_p`, so `dx_p = -(da + x_p db) / b`), the velocity
    /// `slope / b` (`dx_v = -x_v db / b`). The other states' rows are set
    /// before ([`Machine::tangent_start`]); the output is taken not to read
    /// the velocity.
    pub(super) fn tangent_measured(
        &mut self,
        x: &[f64],
        u: &[f64],
        (mode, position, velocity): (usize, usize, Option<usize>),
        gain: f64,
    ) {
        let Some(mut t) = self.tangent.take() else {
            return;
        };
        let output = &t.model.modes[mode].output;
        let mut at = x.to_vec();
        t.s_row(position).fill(0.0);
        let mut da = std::mem::take(&mut t.row);
        let mut db = std::mem::take(&mut t.spare);
        at[position] = 0.0;
        self.load(&at, u);
        t.d.total(output, &self.slots, &t.s, &mut da);
        at[position] = 1.0;
        self.load(&at, u);
        t.d.total(output, &self.slots, &t.s, &mut db);
        for (b, a) in db.iter_mut().zip(&da) {
            *b -= a;
        }
        let xp = x[position];
        for ((s, a), b) in t.s_row(position).iter_mut().zip(&da).zip(&db) {
            *s = -(a + xp * b) / gain;
        }
        if let Some(v) = velocity {
            let xv = x[v];
            for (s, b) in t.s_row(v).iter_mut().zip(&db) {
                *s = -xv * b / gain;
            }
        }
        self.load(x, u);
        t.row = da;
        t.spare = db;
        self.tangent = Some(t);
    }

    /// The rows of a rest state `x` of `mode` under `u` (implicit
    /// function: `f(x, θ) = 0`, so `S = -f_x^+ f_θ`, the pseudo-inverse
    /// as the rest state is a least-squares solve).
    pub(super) fn tangent_steady(&mut self, x: &[f64], u: &[f64], mode: usize) {
        let Some(mut t) = self.tangent.take() else {
            return;
        };
        let (n, p, c) = (t.d.states, t.d.parameters, t.d.columns);
        self.load(x, u);
        t.sliding = None;
        t.partials_at(mode, &[], &self.slots);
        let fx = DMatrix::from_row_slice(n, n, &t.fx);
        let ftheta = DMatrix::from_row_slice(n, p, &t.ftheta);
        if let Ok(pinv) = fx.pseudo_inverse(1e-12) {
            let s = -pinv * ftheta;
            t.s.fill(0.0);
            for (i, row) in t.s.chunks_mut(c).enumerate() {
                for (j, v) in row[..p].iter_mut().enumerate() {
                    *v = s[(i, j)];
                }
            }
        }
        self.tangent = Some(t);
    }

    /// The output's derivative at sample `k` (state `hs`, input `u`) and
    /// `S` into `out`.
    pub(super) fn tangent_output(
        &mut self,
        hs: &HybridState,
        u: &[f64],
        k: usize,
        out: &mut Sensitivities,
    ) {
        if self.tangent.is_none() {
            return;
        }
        self.load(&hs.x, u);
        let Some(t) = self.tangent.as_mut() else {
            return;
        };
        t.d.total(
            &t.model.modes[hs.mode].output,
            &self.slots,
            &t.s,
            out.dy_row_mut(k),
        );
        out.dx_block_mut(k).copy_from_slice(&t.s);
    }
}
