//! RK4 in closed form for regimes whose flows are affine in the states and
//! the inputs, as most mechanical and electrical models are once their
//! parameters are bound: the regime's `A`, `B` and `c` are read from the
//! compiled flows ([`AffineFlows`]) and stepped by
//! [`hysid_numerics::affine_rk4`], formed once per regime and step length
//! and reused for every full sub-step spent in it.
//!
//! In a regime, a sliding friction adds its constant kinetic level against
//! the motion (`w_v -= level * direction`), and a held state (a stuck
//! velocity, a position resting at a stop) has a zero row in `A` and `w`.
//! A regime whose friction level is not constant (it depends on the state
//! or the input) has no closed form: the caller integrates it stage by
//! stage.
//!
//! Guard surfaces affine in the states and inputs are read the same way,
//! from the state and the input directly ([`AffineRow`]).

use crate::compile::CompiledMode;
use crate::expr::{Crossing, Expression};
pub(super) use hysid_numerics::affine_rk4::ClosedStep;

/// An expression affine in the states and the inputs,
/// `constant + sum(coefficient * z)` over `z = [x; u]`: a guard surface
/// read without loading the slots.
#[derive(Debug, Clone)]
pub(super) struct AffineRow {
    constant: f64,
    terms: Vec<(usize, f64)>,
}

impl AffineRow {
    /// The affine form of `e` over `states` states, then the inputs, or
    /// `None` when it reads anything else or is not affine.
    fn of(e: &Expression, states: usize, inputs: usize) -> Option<Self> {
        let (constant, terms) = e.affine()?;
        let terms = terms
            .into_iter()
            .map(|(slot, c)| ((slot as usize) < states + inputs).then_some((slot as usize, c)))
            .collect::<Option<_>>()?;
        Some(AffineRow { constant, terms })
    }

    /// The value at `(x, u)`, summed in the expression's own order.
    #[inline]
    pub(super) fn eval(&self, x: &[f64], u: &[f64]) -> f64 {
        self.eval_by(x.len(), |s| x[s], u)
    }

    /// [`AffineRow::eval`] with the `n` states read by `x`.
    #[inline(always)]
    pub(super) fn eval_by(&self, n: usize, x: impl Fn(usize) -> f64, u: &[f64]) -> f64 {
        let mut acc = self.constant;
        for &(s, c) in &self.terms {
            acc += c * if s < n { x(s) } else { u[s - n] };
        }
        acc
    }
}

/// A mode's guard surfaces with their crossings, when every one is affine
/// in the states and the inputs.
pub(super) fn affine_guards(
    mode: &CompiledMode,
    states: usize,
    inputs: usize,
) -> Option<Vec<(Crossing, AffineRow)>> {
    mode.transitions
        .iter()
        .map(|t| {
            Some((
                t.guard.crossing,
                AffineRow::of(&t.guard.surface, states, inputs)?,
            ))
        })
        .collect()
}

/// A mode's flows `dx/dt = A x + B u + c`, read from its expressions.
#[derive(Debug, Clone)]
pub(super) struct AffineFlows {
    /// `A`, row-major `n x n`.
    a: Vec<f64>,
    /// `B`, row-major `n x m`.
    b: Vec<f64>,
    /// `c`.
    c: Vec<f64>,
    /// Per element, its kinetic friction level when it is a constant
    /// (negative levels count as zero, as in the stage-by-stage flows).
    kinetic: Vec<Option<f64>>,
}

impl AffineFlows {
    /// The affine form of `mode`'s flows over `states` states and `inputs`
    /// inputs (slots `0..states`, then the inputs), or `None` when a flow
    /// is not affine in them alone.
    pub(super) fn of(mode: &CompiledMode, states: usize, inputs: usize) -> Option<Self> {
        let (n, m) = (states, inputs);
        let mut flows = AffineFlows {
            a: vec![0.0; n * n],
            b: vec![0.0; n * m],
            c: vec![0.0; n],
            kinetic: mode
                .friction
                .iter()
                .map(|(k, _)| k.as_constant().map(|v| v.max(0.0)))
                .collect(),
        };
        for (i, f) in mode.flow.iter().enumerate().take(n) {
            let row = AffineRow::of(f, n, m)?;
            flows.c[i] = row.constant;
            for (s, coefficient) in row.terms {
                if s < n {
                    flows.a[i * n + s] += coefficient;
                } else {
                    flows.b[i * m + s - n] += coefficient;
                }
            }
        }
        Some(flows)
    }

    /// The closed-form step of length `h` in the regime where the states
    /// `held` do not move and the frictions `sliding` (element, velocity
    /// state, direction) act; `None` when one of them has no constant level.
    pub(super) fn step(
        &self,
        h: f64,
        held: &[bool],
        sliding: &[(usize, usize, f64)],
    ) -> Option<ClosedStep> {
        let n = self.c.len();
        let m = self.b.len() / n.max(1);
        // The regime's forcing: w = B' u + c', zero on the held rows.
        let mut c = self.c.clone();
        for &(element, velocity, direction) in sliding {
            c[velocity] -= self.kinetic.get(element).copied().flatten()? * direction;
        }
        // The regime's A' and B': the held rows zeroed.
        let (mut a, mut b) = (self.a.clone(), self.b.clone());
        for i in (0..n).filter(|&i| held[i]) {
            c[i] = 0.0;
            a[i * n..(i + 1) * n].fill(0.0);
            b[i * m..(i + 1) * m].fill(0.0);
        }
        Some(ClosedStep::new(a, b, c, h))
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::simulate::initial::initial;
    use crate::simulate::{GrayBoxRun, Kept, Machine, Schedule, span};
    use crate::{CompiledModel, GrayBoxModel, extends};
    use hysid_model::data::Dataset;
    use hysid_model::excitation::Excitation;
    use proptest::prelude::*;
    use std::path::{Path, PathBuf};

    fn vector(len: usize, scale: f64) -> impl Strategy<Value = Vec<f64>> {
        prop::collection::vec(-scale..scale, len)
    }

    proptest! {
        /// A regime's step is the closed form of the regime written out:
        /// the held rows of `A`, `B` and `c` zero, a sliding friction's
        /// level against the direction on its velocity (RK4 itself is
        /// tested in `hysid_numerics::affine_rk4`).
        #[test]
        fn a_regime_steps_its_own_flows(
            (n, m) in (1usize..5, 1usize..3),
            seed in vector(64, 1.0),
            h in 1e-4f64..0.05,
            held_mask in 0u32..16,
            direction in prop_oneof![Just(1.0), Just(-1.0)],
            fraction in 0.0f64..1.0,
        ) {
            let take = |from: usize, len: usize, scale: f64| -> Vec<f64> {
                seed[from..from + len].iter().map(|v| v * scale).collect()
            };
            let flows = AffineFlows {
                a: take(0, n * n, 40.0),
                b: take(16, n * m, 10.0),
                c: take(24, n, 5.0),
                kinetic: vec![Some(3.0)],
            };
            let (x, u) = (take(32, n, 2.0), take(40, m, 1.0));
            let held: Vec<bool> = (0..n).map(|i| held_mask >> i & 1 == 1).collect();
            let velocity = n - 1;
            let step = flows.step(h, &held, &[(0, velocity, direction)]).unwrap();
            let (mut a, mut b, mut c) = (flows.a.clone(), flows.b.clone(), flows.c.clone());
            c[velocity] -= 3.0 * direction;
            for i in (0..n).filter(|&i| held[i]) {
                a[i * n..(i + 1) * n].fill(0.0);
                b[i * m..(i + 1) * m].fill(0.0);
                c[i] = 0.0;
            }
            let want = ClosedStep::new(a, b, c, h);
            let (mut got, mut expected) = (vec![0.0; n], vec![0.0; n]);
            step.apply(&x, &u, &mut got);
            want.apply(&x, &u, &mut expected);
            prop_assert_eq!(&got, &expected);
            let (mut k, mut t) = (vec![0.0; n], vec![0.0; n]);
            step.apply_length(h * fraction, &x, &u, (&mut k, &mut t), &mut got);
            want.apply_length(h * fraction, &x, &u, (&mut k, &mut t), &mut expected);
            prop_assert_eq!(&got, &expected);
            for i in (0..n).filter(|&i| held[i]) {
                prop_assert_eq!(got[i], x[i]);
            }
        }
    }

    /// A friction whose level is not constant has no closed form.
    #[test]
    fn a_varying_friction_level_has_no_closed_form() {
        let flows = AffineFlows {
            a: vec![0.0, 1.0, -1.0, 0.0],
            b: vec![0.0, 1.0],
            c: vec![0.0, 0.0],
            kinetic: vec![None],
        };
        assert!(flows.step(0.01, &[false, false], &[(0, 1, 1.0)]).is_none());
        assert!(flows.step(0.01, &[false, true], &[]).is_some());
    }

    /// The gray-box head with its free parameters at `z` (0..1) of their
    /// bounds, read as [`model_files`] reads every file.
    pub(in crate::simulate) fn head(z: &[f64]) -> GrayBoxModel {
        let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../models"));
        let mut value = extends::read(&root.join("pick-and-place/head-graybox.toml"))
            .unwrap()
            .value;
        value.as_object_mut().unwrap().remove("kind");
        let mut g: GrayBoxModel = serde_json::from_value(value).unwrap();
        for (p, zi) in g.parameters.iter_mut().zip(z) {
            if !p.fixed {
                p.value = p.bounds[0] + (p.bounds[1] - p.bounds[0]) * zi;
            }
        }
        g
    }

    /// Every gray-box file under `models/examples` and
    /// `models/pick-and-place` (the structure study's included), with the
    /// input of its "Try:" line, which drives it through its guards, stops
    /// and sticking (guards that an input's jump crosses among them: the
    /// ball's table, the tanks' overflows).
    pub(in crate::simulate) fn model_files() -> Vec<(PathBuf, GrayBoxModel, Excitation)> {
        let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../models"));
        let mut files = Vec::new();
        for dir in ["examples", "pick-and-place", "pick-and-place/structures"] {
            for entry in std::fs::read_dir(root.join(dir)).unwrap() {
                let path = entry.unwrap().path();
                if path.extension().is_none_or(|e| e != "toml") {
                    continue;
                }
                let resolved = extends::read(&path).unwrap();
                let mut value = resolved.value;
                let kind = value.as_object_mut().and_then(|o| o.remove("kind"));
                if kind.as_ref().and_then(|k| k.as_str()) != Some("gray_box") {
                    continue;
                }
                let g: GrayBoxModel = serde_json::from_value(value).unwrap();
                let ex: Excitation = resolved.sources[0]
                    .text
                    .lines()
                    .find_map(|l| l.split("--excite ").nth(1)?.split_whitespace().next())
                    .unwrap_or_else(|| panic!("{}: no Try: line", path.display()))
                    .parse()
                    .unwrap();
                files.push((path, g, ex));
            }
        }
        files
    }

    /// The head's test record of 1500 samples: a random input held over 40
    /// samples between -0.3 and 0.05 (from `seed`), the output at 3 mm.
    pub(in crate::simulate) fn head_record(seed: u64) -> Dataset {
        let ex = Excitation {
            n: 1500,
            hold: 40,
            low: -0.3,
            high: 0.05,
            ts: Some(0.0025),
            inputs: 1,
        };
        Dataset::siso(ex.generate(seed).remove(0), vec![3.0; 1500], Some(0.0025)).unwrap()
    }

    /// A run of `m` on `data` from its initial rule, the machine set by
    /// `set` first: the run with its steps, events and Zeno steps, the
    /// steps the quiet lane took and the trials of the events' location.
    pub(in crate::simulate) fn run_with(
        m: &CompiledModel,
        values: &[f64],
        data: &Dataset,
        set: impl FnOnce(&mut Machine),
    ) -> (GrayBoxRun, usize, usize) {
        let bound = m.bind(values);
        let schedule = Schedule::new(&bound, data.ts.unwrap());
        let mut machine = Machine::new(&bound, values);
        set(&mut machine);
        let (first, hs) = initial(&bound, &mut machine, data, &schedule, &[]).unwrap();
        let mut out = GrayBoxRun::empty(data, m.states, first, Kept::Everything);
        span(
            &mut machine,
            hs,
            data,
            first..data.len(),
            &schedule,
            &mut out,
        )
        .unwrap();
        out.steps = machine.steps;
        out.events = machine.events;
        out.zeno = machine.zeno;
        (out, machine.quiet_steps, machine.locate_trials)
    }

    /// The outputs of a run of `m`, every full sub-step in closed form or
    /// every step by stages.
    fn outputs(m: &CompiledModel, values: &[f64], data: &Dataset, closed_form: bool) -> Vec<f64> {
        run_with(m, values, data, |machine| machine.closed_form = closed_form)
            .0
            .y
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]

        /// The mounting head (affine flows in both modes, a constant
        /// friction level in each) simulates the same in closed form as by
        /// stages, through its impacts, sticking and stops.
        #[test]
        fn the_head_runs_the_same_in_closed_form(z in prop::collection::vec(0.0f64..1.0, 12), seed in 0u64..1000) {
            let g = head(&z);
            let m = CompiledModel::new(&g).unwrap();
            prop_assert!(m.bind(&g.values()).modes.iter().all(|q| AffineFlows::of(q, 2, 1).is_some()));
            let data = head_record(seed);
            let closed = outputs(&m, &g.values(), &data, true);
            let staged = outputs(&m, &g.values(), &data, false);
            let range = staged.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(1.0);
            for (k, (a, b)) in closed.iter().zip(&staged).enumerate() {
                prop_assert!((a - b).abs() <= 1e-8 * range, "sample {k}: {a} vs {b}");
            }
        }
    }
}
