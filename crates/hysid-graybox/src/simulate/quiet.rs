//! The quiet lane: full sub-steps of one regime taken back to back while
//! nothing happens, the common case of a free run.
//!
//! In a regime whose flows have a closed form and whose guard surfaces are
//! affine, and where no element is held, a sub-step is one affine map of
//! the state, and whether it ends without an event is decided from the
//! state alone ([`Machine::quiet_step`]): no stop reached, no sliding
//! velocity at zero, no guard crossed. The lane lists those tests once for
//! the regime (`watch`: a state, a sign and a level, the event when
//! `sign * (x - level) >= 0`) and steps until one fails; the sub-step where
//! it fails is left to the general loop, which takes it again from the
//! same state and locates its event. The states, the steps counted and
//! the surfaces carried are the general loop's, bit for bit: the lane
//! only skips its bookkeeping. Runs carrying sensitivities do not take it.

use super::linear::{AffineRow, ClosedStep};
use super::{ElementRegime, HybridState, Machine, StateEnd, crossed, load};
use crate::expr::Crossing;

impl Machine<'_> {
    /// Takes the full sub-steps `0..n_sub` of length `self.full_step` from
    /// `hs` under the input `u` while each ends without an event, and
    /// returns how many it took (`n_sub`: the whole sample). `fresh` says
    /// whether the surfaces at `hs.x` are the step's start, as in
    /// [`Machine::advance`]; `x1` is its trial state (swapped with the
    /// state at each step taken, so it holds a scratch state).
    pub(super) fn quiet_substeps(
        &mut self,
        hs: &mut HybridState,
        u: &[f64],
        n_sub: usize,
        fresh: &mut bool,
        x1: &mut Vec<f64>,
    ) -> usize {
        if !self.quiet_lane_open(hs) {
            return 0;
        }
        if !*fresh {
            self.surfaces_at(&hs.x, u, hs.mode);
            self.g.step();
            *fresh = true;
        }
        let (Some(watch), Some((.., Some(step))), Some(guards)) =
            (&self.watch.1, &self.closed, &self.guards[hs.mode])
        else {
            return 0;
        };
        let lane = Lane {
            step,
            watch,
            guards,
            u,
        };
        let surfaces = self.g.start_and_end_mut(guards.len());
        // The common small models' states and inputs as arrays: their
        // steps unroll and the state stays out of memory between them.
        let fixed = match (hs.x.len(), u.len()) {
            (1, 1) => lane.on_arrays::<1, 1>(&mut hs.x, n_sub, surfaces),
            (2, 1) => lane.on_arrays::<2, 1>(&mut hs.x, n_sub, surfaces),
            (2, 2) => lane.on_arrays::<2, 2>(&mut hs.x, n_sub, surfaces),
            (3, 1) => lane.on_arrays::<3, 1>(&mut hs.x, n_sub, surfaces),
            (4, 1) => lane.on_arrays::<4, 1>(&mut hs.x, n_sub, surfaces),
            (4, 2) => lane.on_arrays::<4, 2>(&mut hs.x, n_sub, surfaces),
            _ => Err(surfaces),
        };
        let taken = match fixed {
            Ok(taken) => taken,
            Err(surfaces) => {
                let apply = |x: &Vec<f64>, out: &mut Vec<f64>| step.apply(x, u, out);
                let ended = |x: &Vec<f64>| watched_event(watch, |s| x[s]);
                lane.run(apply, ended, &mut hs.x, x1, n_sub, surfaces)
            }
        };
        self.g.stepped(taken);
        self.steps += taken;
        self.quiet_steps += taken;
        taken
    }

    /// Whether the regime of `hs` takes the quiet lane: no sensitivities,
    /// a closed-form step (formed here), affine guards and no element
    /// held; lists the regime's tests into `watch` when the elements'
    /// regimes differ from those they were listed for.
    pub(super) fn quiet_lane_open(&mut self, hs: &HybridState) -> bool {
        if !self.shortcuts
            || self.differentiates()
            || !self.closed_form
            || self.guards[hs.mode].is_none()
        {
            return false;
        }
        if self.watch.0.as_deref() != Some(&hs.regimes[..]) {
            let held = (hs.regimes.iter())
                .any(|r| matches!(r, ElementRegime::Stuck | ElementRegime::Resting));
            let tests = (!held).then(|| {
                (hs.regimes.iter().enumerate())
                    .filter_map(|(i, &regime)| self.state_end(i, regime))
                    .collect()
            });
            self.watch = (Some(hs.regimes.clone()), tests);
        }
        if self.watch.1.is_none() {
            return false;
        }
        self.form_closed_step(hs);
        matches!(&self.closed, Some((.., Some(_))))
    }

    /// Whether the state `x` under `u` ends the lane's regime in `mode`
    /// (opened by [`Machine::quiet_lane_open`]): what
    /// [`Machine::first_event`] finds there, decided from the watched
    /// states and the guards' affine forms against the step's start, the
    /// slots loaded only for a crossed guard's `when` condition. The
    /// event's location asks it at every trial.
    pub(super) fn ends_lane(&mut self, x: &[f64], u: &[f64], mode: usize) -> bool {
        if self
            .watch
            .1
            .as_deref()
            .is_some_and(|w| watched_event(w, |s| x[s]))
        {
            return true;
        }
        let m = self.m;
        let Some(guards) = &self.guards[mode] else {
            return true;
        };
        for (j, ((c, row), t)) in guards.iter().zip(&m.modes[mode].transitions).enumerate() {
            if crossed(*c, self.g.start()[j], row.eval(x, u)) {
                let Some(when) = &t.when else {
                    return true;
                };
                load(&mut self.slots, x, u);
                if when.eval(&self.slots) != 0.0 {
                    return true;
                }
            }
        }
        false
    }
}

/// One regime's quiet lane: its closed-form step, the ends it watches and
/// its guards' affine forms, under the input `u`.
struct Lane<'l> {
    step: &'l ClosedStep,
    watch: &'l [StateEnd],
    guards: &'l [(Crossing, AffineRow)],
    u: &'l [f64],
}

/// The two guard-surface buffers of a step, its start's and its trial
/// end's ([`super::Surfaces`]).
type SurfacePair<'s> = (&'s mut [f64], &'s mut [f64]);

impl Lane<'_> {
    /// [`Lane::run`] on `N` states and `M` inputs held in arrays
    /// ([`hysid_numerics::affine_rk4::FixedStep`]), the watched ends as
    /// [`Levels`]; the surfaces back when the step or the ends do not fit.
    fn on_arrays<'s, const N: usize, const M: usize>(
        &self,
        x: &mut [f64],
        n_sub: usize,
        surfaces: SurfacePair<'s>,
    ) -> Result<usize, SurfacePair<'s>> {
        let (Some(step), Ok(u), Some(levels)) = (
            self.step.fixed::<N, M>(),
            <[f64; M]>::try_from(self.u),
            Levels::<N>::of(self.watch),
        ) else {
            return Err(surfaces);
        };
        let mut at = [0.0; N];
        at.copy_from_slice(x);
        let apply = |x: &[f64; N], out: &mut [f64; N]| *out = step.apply(x, &u);
        let ended = |x: &[f64; N]| levels.reached(x);
        let taken = self.run(apply, ended, &mut at, &mut [0.0; N], n_sub, surfaces);
        x.copy_from_slice(&at);
        Ok(taken)
    }

    /// Takes up to `n_sub` full sub-steps (`apply`) from `x` while each
    /// ends without an event, and returns how many it took; `x1` is the
    /// trial state. The guard surfaces at `x` are the first of `surfaces`,
    /// the second the trial end's; after the steps taken they have swapped
    /// roles as many times ([`super::Surfaces::stepped`]).
    fn run<X: LaneState>(
        &self,
        apply: impl Fn(&X, &mut X),
        ended: impl Fn(&X) -> bool,
        x: &mut X,
        x1: &mut X,
        n_sub: usize,
        (mut start, mut end): SurfacePair<'_>,
    ) -> usize {
        let n = x.as_ref().len();
        for taken in 0..n_sub {
            apply(x, x1);
            if ended(x1) {
                return taken;
            }
            let at = |s| x1.at(s);
            for (((c, row), g0), g1) in self.guards.iter().zip(&*start).zip(end.iter_mut()) {
                *g1 = row.eval_by(n, at, self.u);
                if crossed(*c, *g0, *g1) {
                    return taken;
                }
            }
            std::mem::swap(x, x1);
            std::mem::swap(&mut start, &mut end);
        }
        n_sub
    }
}

/// A regime's watched ends on `N` states held in an array, as levels per
/// state: it ends where `x[s] >= above[s]` or `x[s] <= below[s]` (NaN: no
/// such end). The same test as [`watched_event`] on the list: with a sign
/// of one, `sign * (x - level) >= 0` is `x >= level` (a difference of
/// finite numbers is zero only where they are equal), and two ends on one
/// side of one state are the nearer level's.
struct Levels<const N: usize> {
    above: [f64; N],
    below: [f64; N],
}

impl<const N: usize> Levels<N> {
    /// The levels of `watch`, or `None` where an end's sign is not one,
    /// its level not finite or its state not among the `N`.
    fn of(watch: &[StateEnd]) -> Option<Self> {
        let mut levels = Levels {
            above: [f64::NAN; N],
            below: [f64::NAN; N],
        };
        for end in watch {
            if !end.level.is_finite() || end.state >= N {
                return None;
            }
            // `min` and `max` take the level over a NaN.
            if end.sign == 1.0 {
                levels.above[end.state] = levels.above[end.state].min(end.level);
            } else if end.sign == -1.0 {
                levels.below[end.state] = levels.below[end.state].max(end.level);
            } else {
                return None;
            }
        }
        Some(levels)
    }

    /// Whether `x` meets one of the ends.
    #[inline(always)]
    fn reached(&self, x: &[f64; N]) -> bool {
        let mut hit = false;
        for ((v, above), below) in x.iter().zip(&self.above).zip(&self.below) {
            hit |= (*v >= *above) | (*v <= *below);
        }
        hit
    }
}

/// A state the lane steps: a vector, or an array of a small model's
/// states, read by [`LaneState::at`] without indexing memory so that it
/// can stay in registers from one step to the next.
trait LaneState: AsRef<[f64]> + AsMut<[f64]> {
    /// State `s`.
    fn at(&self, s: usize) -> f64;
}

impl LaneState for Vec<f64> {
    #[inline(always)]
    fn at(&self, s: usize) -> f64 {
        self[s]
    }
}

impl<const N: usize> LaneState for [f64; N] {
    /// A selection among the `N` constant positions (`s < N`).
    #[inline(always)]
    fn at(&self, s: usize) -> f64 {
        let mut value = self[0];
        for (j, v) in self.iter().enumerate().skip(1) {
            if j == s {
                value = *v;
            }
        }
        value
    }
}

/// Whether the state read by `x` meets one of the `watch` list's ends (a
/// stop reached, a sliding velocity at zero or reversed).
#[inline(always)]
fn watched_event(watch: &[StateEnd], x: impl Fn(usize) -> f64 + Copy) -> bool {
    watch.iter().any(|end| end.margin_by(x) >= 0.0)
}

#[cfg(test)]
mod tests {
    use crate::CompiledModel;
    use crate::simulate::linear::tests::{head, head_record, model_files, run_with};
    use crate::simulate::quiet::{Levels, watched_event};
    use crate::simulate::{GrayBoxRun, Kept, Machine, Schedule, StateEnd, span};
    use hysid_model::data::Dataset;
    use proptest::prelude::*;

    /// Whether two runs are the same to the bit.
    fn same_bits(a: &GrayBoxRun, b: &GrayBoxRun) -> bool {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        bits(&a.y) == bits(&b.y)
            && bits(&a.x) == bits(&b.x)
            && a.modes == b.modes
            && a.covered == b.covered
            && (a.steps, a.events, a.zeno) == (b.steps, b.events, b.zeno)
    }

    /// `data` cut into segments of 40 samples, each started from the state
    /// of `reference` at its first sample with its first state moved by
    /// 1e-3, all on one machine set by `set` (as the multiple-shooting
    /// cost runs them: a segment never starts where the last one ended).
    fn segments(
        m: &CompiledModel,
        values: &[f64],
        data: &Dataset,
        reference: &GrayBoxRun,
        set: impl FnOnce(&mut Machine),
    ) -> GrayBoxRun {
        let bound = m.bind(values);
        let schedule = Schedule::new(&bound, data.ts.unwrap());
        let mut machine = Machine::new(&bound, values);
        machine.strict_resets = false;
        set(&mut machine);
        let mut out = GrayBoxRun::empty(data, m.states, 0, Kept::Everything);
        let (n, states) = (data.len(), m.states);
        let mut u = vec![0.0; m.inputs];
        let mut s = reference.start;
        while s + 1 < n {
            schedule.inputs(data, s, 0.0, &mut u);
            let mut x = reference.x[s * states..(s + 1) * states].to_vec();
            x[0] += 1e-3;
            let hs = machine.state_at(x, &u, None);
            let end = (s + 41).min(n);
            span(&mut machine, hs, data, s..end, &schedule, &mut out).unwrap();
            s = end - 1;
        }
        out.steps = machine.steps;
        out.events = machine.events;
        out.zeno = machine.zeno;
        out
    }

    /// Every model file ([`model_files`]) under the seeds 1 to 3 of its
    /// input: the same bits with the shortcuts on and off, in a free run
    /// and in segments.
    #[test]
    fn every_model_file_runs_the_same_without_the_shortcuts() {
        let files = model_files();
        for (path, g, ex) in &files {
            let m = CompiledModel::new(g).unwrap();
            for seed in 1..=3 {
                let u = ex.generate(seed).remove(0);
                let data = Dataset::siso(u, vec![0.0; ex.n], ex.ts).unwrap();
                let (with, ..) = run_with(&m, &g.values(), &data, |_| ());
                let (without, ..) =
                    run_with(&m, &g.values(), &data, |machine| machine.shortcuts = false);
                assert!(
                    same_bits(&with, &without),
                    "{}, seed {seed}",
                    path.display()
                );
                let cut = segments(&m, &g.values(), &data, &with, |_| ());
                let plain = segments(&m, &g.values(), &data, &with, |machine| {
                    machine.shortcuts = false;
                });
                let file = path.display();
                assert!(same_bits(&cut, &plain), "{file}, seed {seed}, segments");
            }
        }
        assert!(files.len() >= 30, "{} files", files.len());
    }

    /// A value drawn near the levels of [`ends`], often exactly on one.
    fn near_levels() -> impl Strategy<Value = f64> {
        prop_oneof![
            prop::sample::select(vec![-1.0, 0.0, -0.0, 0.5, 1.0]),
            -2.0f64..2.0,
        ]
    }

    /// Up to four ends on two states, either sign, at levels [`near_levels`].
    fn ends() -> impl Strategy<Value = Vec<StateEnd>> {
        let end =
            (0usize..2, prop::bool::ANY, near_levels()).prop_map(|(state, up, level)| StateEnd {
                state,
                sign: if up { 1.0 } else { -1.0 },
                level,
            });
        prop::collection::vec(end, 0..5)
    }

    proptest! {
        /// The levels per state meet an end exactly where the list does,
        /// on a level and between two levels of one side alike.
        #[test]
        fn the_levels_are_the_watch_list(watch in ends(), x0 in near_levels(), x1 in near_levels()) {
            let levels = Levels::<2>::of(&watch).unwrap();
            let x = [x0, x1];
            prop_assert_eq!(levels.reached(&x), watched_event(&watch, |s| x[s]));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]

        /// The mounting head, anywhere in its parameters' bounds, through
        /// impacts, sticking and stops: the lane takes most sub-steps, and
        /// the shortcuts change no bit of the run (outputs, states, modes,
        /// coverage, steps and events); the events are located in regula
        /// falsi's few trials.
        #[test]
        fn the_quiet_lane_changes_no_bit(z in prop::collection::vec(0.0f64..1.0, 12), seed in 0u64..1000) {
            let g = head(&z);
            let m = CompiledModel::new(&g).unwrap();
            let data = head_record(seed);
            let (with, quiet, trials) = run_with(&m, &g.values(), &data, |_| ());
            let (without, none, _) = run_with(&m, &g.values(), &data, |machine| machine.shortcuts = false);
            prop_assert_eq!(none, 0);
            prop_assert!(2 * quiet > with.steps, "{quiet} of {} steps in the lane", with.steps);
            prop_assert!(with.events > 0);
            // The events' margins agree with their tests: the location
            // takes regula falsi's few trials, not a bisection's 40.
            prop_assert!(trials <= 12 * with.events, "{trials} trials for {} events", with.events);
            prop_assert!(same_bits(&with, &without));
        }
    }
}
