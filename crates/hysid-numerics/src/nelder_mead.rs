//! Nelder-Mead's simplex search (Nelder and Mead 1965) in argmin's
//! variant: its coefficients (reflection 1, expansion 2, contraction and
//! shrink 1/2), its choice of step, its order of operations and its
//! stopping test (the standard deviation of the vertices' costs), so the
//! iterates are argmin's bit for bit (a test runs both).
//!
//! What it adds: the points of an iteration are known before any is
//! evaluated (the reflection, the expansion and both contractions are
//! made from the centroid, the reflection and the worst vertex), so the
//! reflection's cost and a guess at the second cost the step will need
//! are evaluated side by side, and the simplex's first vertices and a
//! shrink's in parallel. The guess is the kind of the last second
//! evaluation (an expansion, an outside or an inside contraction); a wrong
//! guess costs one evaluation on another core. The iterates, and the
//! evaluations counted, are those of the search without it.

use crate::budget::{Budget, Deadline, Exhausted};
use rayon::prelude::*;
use std::cmp::Ordering;

/// Reflection coefficient.
const ALPHA: f64 = 1.0;
/// Expansion coefficient.
const GAMMA: f64 = 2.0;
/// Contraction coefficient.
const RHO: f64 = 0.5;
/// Shrink coefficient.
const SIGMA: f64 = 0.5;

/// The settings of a search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// At most this many iterations.
    pub max_iterations: usize,
    /// The search has converged when the standard deviation of the
    /// vertices' costs is below this.
    pub sd_tolerance: f64,
    /// Whether an iteration evaluates a guessed second point beside the
    /// reflection: for a cost whose evaluation leaves cores idle.
    pub speculate: bool,
}

/// Why a search ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// The costs of the vertices agree within the tolerance.
    Converged,
    /// The iteration bound was reached.
    IterationLimit,
    /// The deadline passed, or a stop was requested.
    TimeBudget,
}

/// The outcome of a search.
#[derive(Debug, Clone, PartialEq)]
pub struct Minimum {
    /// The best vertex.
    pub x: Vec<f64>,
    /// Its cost.
    pub cost: f64,
    /// Why the search ended.
    pub stop: Stop,
    /// Iterations taken.
    pub iterations: usize,
    /// Costs the search used (those of the search without guesses).
    pub evaluations: usize,
    /// Guessed costs evaluated and not used.
    pub unused_guesses: usize,
}

/// The second point an iteration may evaluate after the reflection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Second {
    Expansion,
    OutsideContraction,
    InsideContraction,
}

/// A simplex: its vertices and their costs, best first.
struct Simplex {
    vertices: Vec<(Vec<f64>, f64)>,
}

impl Simplex {
    /// Sorts the vertices by cost, keeping the order of equal costs.
    fn sort(&mut self) {
        self.vertices
            .sort_by(|a, b| a.1.partial_cmp(&b.1).unwrap_or(Ordering::Equal));
    }

    /// The centroid of every vertex but the worst.
    fn centroid(&self) -> Vec<f64> {
        let n = self.vertices.len() - 1;
        let sum = self.vertices[1..n]
            .iter()
            .fold(self.vertices[0].0.clone(), |acc, (p, _)| add(&acc, p));
        scale(&sum, 1.0 / n as f64)
    }

    /// The standard deviation of the vertices' costs.
    fn cost_spread(&self) -> f64 {
        let n = self.vertices.len() as f64;
        let mean = self.vertices.iter().map(|(_, c)| *c).sum::<f64>() / n;
        let squares = self
            .vertices
            .iter()
            .map(|(_, c)| (*c - mean).powi(2))
            .sum::<f64>();
        (1.0 / (n - 1.0) * squares).sqrt()
    }
}

fn add(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + y).collect()
}

fn sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

fn scale(a: &[f64], s: f64) -> Vec<f64> {
    a.iter().map(|x| x * s).collect()
}

/// `x0 + (x - x0) * coefficient`: the point at `coefficient` of the way
/// from `x0` to `x`.
fn toward(x0: &[f64], x: &[f64], coefficient: f64) -> Vec<f64> {
    add(x0, &scale(&sub(x, x0), coefficient))
}

/// Minimises `cost` from the vertices `simplex` (of one length), at most
/// `settings.max_iterations` iterations, none begun after `deadline`. A
/// cost that is NaN counts as `+inf`. Fewer than two vertices move
/// nothing: the one given (or an empty point of cost `+inf`) is returned.
pub fn minimise(
    cost: &(dyn Fn(&[f64]) -> f64 + Sync),
    simplex: Vec<Vec<f64>>,
    settings: &Settings,
    deadline: &Deadline,
) -> Minimum {
    let cost = |x: &[f64]| {
        let c = cost(x);
        if c.is_nan() { f64::INFINITY } else { c }
    };
    let mut s = Simplex {
        vertices: simplex
            .into_par_iter()
            .map(|x| {
                let c = cost(&x);
                (x, c)
            })
            .collect(),
    };
    let mut evaluations = s.vertices.len();
    let mut unused_guesses = 0;
    s.sort();
    if s.vertices.len() < 2 {
        // No simplex to move: its one vertex (or none) is the answer.
        let (x, cost) = s.vertices.pop().unwrap_or((Vec::new(), f64::INFINITY));
        return Minimum {
            x,
            cost,
            stop: Stop::Converged,
            iterations: 0,
            evaluations,
            unused_guesses,
        };
    }
    let mut budget = Budget::new(settings.max_iterations, deadline);
    let mut guess = Second::InsideContraction;
    let stop = loop {
        if s.cost_spread() < settings.sd_tolerance {
            break Stop::Converged;
        }
        match budget.begin() {
            Ok(()) => {}
            Err(Exhausted::IterationLimit) => break Stop::IterationLimit,
            Err(Exhausted::TimeBudget) => break Stop::TimeBudget,
        }
        let step = iterate(&mut s, &cost, settings.speculate.then_some(guess));
        evaluations += step.evaluations;
        unused_guesses += step.unused_guess as usize;
        guess = step.second.unwrap_or(guess);
        s.sort();
    };
    let (x, c) = s.vertices.swap_remove(0);
    Minimum {
        x,
        cost: c,
        stop,
        iterations: budget.taken(),
        evaluations,
        unused_guesses,
    }
}

/// What one iteration evaluated.
struct Step {
    /// Costs used.
    evaluations: usize,
    /// The kind of the second point it needed, if any.
    second: Option<Second>,
    /// Whether a guessed cost went unused.
    unused_guess: bool,
}

/// One iteration on the sorted simplex `s`: the reflection of the worst
/// vertex through the centroid of the others, then the expansion, a
/// contraction or the shrink its cost calls for; `guess`: the second
/// point evaluated beside the reflection.
fn iterate(s: &mut Simplex, cost: &(dyn Fn(&[f64]) -> f64 + Sync), guess: Option<Second>) -> Step {
    let n = s.vertices.len();
    let x0 = s.centroid();
    let (best, second_worst) = (s.vertices[0].1, s.vertices[n - 2].1);
    let (worst_x, worst) = (s.vertices[n - 1].0.clone(), s.vertices[n - 1].1);
    let xr = add(&x0, &scale(&sub(&x0, &worst_x), ALPHA));
    let point = |second: Second| match second {
        Second::Expansion => toward(&x0, &xr, GAMMA),
        Second::OutsideContraction => toward(&x0, &xr, RHO),
        Second::InsideContraction => toward(&x0, &worst_x, RHO),
    };
    let (xr_cost, guessed) = match guess {
        Some(g) => {
            let xg = point(g);
            let (r, c) = rayon::join(|| cost(&xr), || cost(&xg));
            (r, Some((g, xg, c)))
        }
        None => (cost(&xr), None),
    };
    let second = if xr_cost < second_worst && xr_cost >= best {
        None
    } else if xr_cost < best {
        Some(Second::Expansion)
    } else if xr_cost < worst {
        Some(Second::OutsideContraction)
    } else {
        Some(Second::InsideContraction)
    };
    let mut step = Step {
        evaluations: 1,
        second,
        unused_guess: guessed.is_some(),
    };
    let Some(kind) = second else {
        s.vertices[n - 1] = (xr, xr_cost);
        return step;
    };
    step.evaluations += 1;
    let (x2, c2) = match guessed {
        Some((g, x, c)) if g == kind => {
            step.unused_guess = false;
            (x, c)
        }
        _ => {
            let x = point(kind);
            let c = cost(&x);
            (x, c)
        }
    };
    let replaced = match kind {
        Second::Expansion if c2 < xr_cost => Some((x2, c2)),
        Second::Expansion => Some((xr, xr_cost)),
        Second::OutsideContraction => (c2 <= xr_cost).then_some((x2, c2)),
        Second::InsideContraction => (c2 < worst).then_some((x2, c2)),
    };
    match replaced {
        Some(vertex) => s.vertices[n - 1] = vertex,
        None => step.evaluations += shrink(s, cost),
    }
    step
}

/// Moves every vertex but the best halfway toward it and evaluates them
/// (in parallel); returns the evaluations.
fn shrink(s: &mut Simplex, cost: &(dyn Fn(&[f64]) -> f64 + Sync)) -> usize {
    let x0 = s.vertices[0].0.clone();
    s.vertices[1..].par_iter_mut().for_each(|(p, c)| {
        *p = toward(&x0, p, SIGMA);
        *c = cost(p);
    });
    s.vertices.len() - 1
}

#[cfg(test)]
mod tests {
    use super::*;
    use argmin::core::{CostFunction, Error, Executor, State, TerminationReason};
    use argmin::solver::neldermead::NelderMead;
    use proptest::prelude::*;

    /// Test costs: a shifted quadratic, Rosenbrock's valley, and a kinked
    /// sum of absolute values (the kind of cost a hybrid system's
    /// simulation error has).
    #[derive(Clone, Copy)]
    struct Test {
        kind: u8,
        shift: f64,
    }

    impl Test {
        fn at(&self, x: &[f64]) -> f64 {
            match self.kind {
                0 => x.iter().map(|v| (v - self.shift).powi(2)).sum(),
                1 => x
                    .windows(2)
                    .map(|w| 100.0 * (w[1] - w[0] * w[0]).powi(2) + (1.0 - w[0]).powi(2))
                    .sum(),
                _ => x
                    .iter()
                    .enumerate()
                    .map(|(i, v)| (i + 1) as f64 * (v - self.shift).abs())
                    .sum(),
            }
        }
    }

    impl CostFunction for Test {
        type Param = Vec<f64>;
        type Output = f64;
        fn cost(&self, x: &Vec<f64>) -> Result<f64, Error> {
            Ok(self.at(x))
        }
    }

    /// argmin's Nelder-Mead on the same problem: best point, cost, why it
    /// stopped and iterations.
    fn argmin_run(
        f: Test,
        simplex: Vec<Vec<f64>>,
        settings: &Settings,
    ) -> (Vec<f64>, f64, Stop, u64) {
        let nm: NelderMead<Vec<f64>, f64> = NelderMead::new(simplex)
            .with_sd_tolerance(settings.sd_tolerance)
            .unwrap();
        let res = Executor::new(f, nm)
            .configure(|s| s.max_iters(settings.max_iterations as u64))
            .run()
            .unwrap();
        let st = res.state();
        let stop = match st.get_termination_reason() {
            Some(TerminationReason::SolverConverged) => Stop::Converged,
            Some(TerminationReason::MaxItersReached) => Stop::IterationLimit,
            other => panic!("{other:?}"),
        };
        (
            st.get_best_param().unwrap().clone(),
            st.get_best_cost(),
            stop,
            st.get_iter(),
        )
    }

    fn bits(x: &[f64]) -> Vec<u64> {
        x.iter().map(|v| v.to_bits()).collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// The search ends where argmin's ends, bit for bit, after as
        /// many iterations and for the same reason, with and without
        /// guesses; a search without guesses evaluates none.
        #[test]
        fn the_iterates_are_argmins(
            kind in 0u8..3,
            shift in -1.0f64..1.0,
            start in prop::collection::vec(-2.0f64..2.0, 2..6),
            size in 0.01f64..0.5,
            max_iterations in 1usize..300,
            tolerance in prop_oneof![Just(1e-12), Just(1e-6), Just(0.0)],
        ) {
            let f = Test { kind, shift };
            let mut simplex = vec![start.clone()];
            for i in 0..start.len() {
                let mut v = start.clone();
                v[i] += size;
                simplex.push(v);
            }
            let (x, c, stop, iterations) = argmin_run(f, simplex.clone(), &Settings {
                max_iterations,
                sd_tolerance: tolerance,
                speculate: false,
            });
            for speculate in [false, true] {
                let settings = Settings { max_iterations, sd_tolerance: tolerance, speculate };
                let m = minimise(&|x| f.at(x), simplex.clone(), &settings, &Deadline::none());
                prop_assert_eq!(bits(&m.x), bits(&x));
                prop_assert_eq!(m.cost.to_bits(), c.to_bits());
                prop_assert_eq!(m.stop, stop);
                prop_assert_eq!(m.iterations as u64, iterations);
                if !speculate {
                    prop_assert_eq!(m.unused_guesses, 0);
                }
            }
        }
    }

    /// The evaluations counted are the search's own: with guesses, as
    /// many as without, and the calls of the cost exceed them by the
    /// unused guesses.
    #[test]
    fn guesses_leave_the_count_of_evaluations() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let f = Test {
            kind: 1,
            shift: 0.0,
        };
        let simplex = vec![vec![-1.0, 1.0], vec![-0.9, 1.0], vec![-1.0, 1.1]];
        let mut counted = Vec::new();
        for speculate in [false, true] {
            let calls = AtomicUsize::new(0);
            let cost = |x: &[f64]| {
                calls.fetch_add(1, Ordering::Relaxed);
                f.at(x)
            };
            let settings = Settings {
                max_iterations: 200,
                sd_tolerance: 1e-12,
                speculate,
            };
            let m = minimise(&cost, simplex.clone(), &settings, &Deadline::none());
            assert_eq!(
                calls.load(Ordering::Relaxed),
                m.evaluations + m.unused_guesses
            );
            counted.push(m.evaluations);
        }
        assert_eq!(counted[0], counted[1]);
    }

    /// A single vertex is returned as it is; no vertex, as an empty point.
    #[test]
    fn fewer_than_two_vertices_move_nothing() {
        let settings = Settings {
            max_iterations: 10,
            sd_tolerance: 0.0,
            speculate: true,
        };
        let f = |x: &[f64]| x.iter().sum::<f64>();
        let one = minimise(&f, vec![vec![2.0]], &settings, &Deadline::none());
        assert_eq!((one.x, one.cost, one.evaluations), (vec![2.0], 2.0, 1));
        let none = minimise(&f, vec![], &settings, &Deadline::none());
        assert_eq!(
            (none.x.len(), none.cost, none.stop),
            (0, f64::INFINITY, Stop::Converged)
        );
    }

    /// A passed deadline ends the search before its first iteration, with
    /// the best of the first vertices.
    #[test]
    fn a_passed_deadline_ends_the_search() {
        let f = Test {
            kind: 0,
            shift: 0.5,
        };
        let simplex = vec![vec![1.0, 1.0], vec![0.6, 1.0], vec![1.0, 0.5]];
        let settings = Settings {
            max_iterations: 100,
            sd_tolerance: 0.0,
            speculate: true,
        };
        let passed = Deadline::at(std::time::Instant::now());
        let m = minimise(&|x| f.at(x), simplex, &settings, &passed);
        assert_eq!(
            (m.stop, m.iterations, m.evaluations),
            (Stop::TimeBudget, 0, 3)
        );
        assert_eq!(m.x, vec![1.0, 0.5]);
    }
}
