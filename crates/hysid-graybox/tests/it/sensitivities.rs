//! Forward sensitivities against central differences of the runs
//! themselves, on every gray-box model file with random parameters and
//! inputs: equal to the differences' own precision, across events
//! included; the outputs of a run with sensitivities are the run's, bit
//! for bit; and the multiple-shooting run's sensitivities likewise.

use crate::examples::{FILES, randomised};
use crate::initial::{cascade, model, record};
use hysid_graybox::simulate::{
    Sensitivities, differentiable, estimate, run, run_from, run_with_sensitivities, segmented,
    segmented_with_sensitivities,
};
use hysid_graybox::{CompiledModel, GrayBoxModel};
use hysid_model::data::Dataset;
use proptest::prelude::*;

/// The Euclidean norm.
fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Column `j` of row-major `dy` with `columns` columns.
fn column(s: &Sensitivities, j: usize) -> Vec<f64> {
    s.dy.chunks(s.columns).map(|row| row[j]).collect()
}

/// Central differences of `f` in coordinate `j` of `theta`, the step
/// `relative` of the coordinate's size (at least 1e-3).
fn central(f: &dyn Fn(&[f64]) -> Vec<f64>, theta: &[f64], j: usize, relative: f64) -> Vec<f64> {
    let step = relative * theta[j].abs().max(1e-3);
    let (mut up, mut down) = (theta.to_vec(), theta.to_vec());
    up[j] += step;
    down[j] -= step;
    f(&up)
        .iter()
        .zip(f(&down))
        .map(|(a, b)| (a - b) / (2.0 * step))
        .collect()
}

/// The columns of `exact` a fit moves (`free`) against central
/// differences of `f` at steps 1e-6 and 1e-7: within 1e-6 of the column's
/// size, or within 4 times the two differences' own disagreement (their
/// error, where an event moves with the parameter).
fn agrees(
    name: &str,
    exact: &Sensitivities,
    f: &dyn Fn(&[f64]) -> Vec<f64>,
    theta: &[f64],
    free: &[bool],
) -> Result<(), TestCaseError> {
    for j in (0..exact.columns).filter(|j| free[*j]) {
        let (fine, finer) = (central(f, theta, j, 1e-6), central(f, theta, j, 1e-7));
        let own = norm(
            &fine
                .iter()
                .zip(&finer)
                .map(|(a, b)| a - b)
                .collect::<Vec<_>>(),
        );
        let e = column(exact, j);
        let error = norm(&e.iter().zip(&fine).map(|(a, b)| a - b).collect::<Vec<_>>());
        prop_assert!(
            error <= (1e-6 * norm(&fine)).max(4.0 * own) + 1e-12,
            "{}: column {}: |exact - differences| = {:.3e}, |differences| = {:.3e}, their own error {:.3e}",
            name,
            j,
            error,
            norm(&fine),
            own
        );
    }
    Ok(())
}

/// A model, a record, and the point `theta` the sensitivities are taken
/// at: the parameters (`p` of them), then the estimated initial states.
struct Case {
    m: GrayBoxModel,
    c: CompiledModel,
    data: Dataset,
    p: usize,
    theta: Vec<f64>,
}

impl Case {
    /// The parameters and the estimated states of `theta`.
    fn split<'t>(&self, theta: &'t [f64]) -> (&'t [f64], &'t [f64]) {
        theta.split_at(self.p)
    }

    /// The columns a fit moves: a parameter not fixed, or an estimated
    /// state.
    fn free(&self) -> Vec<bool> {
        let estimates = self.theta.len() - self.p;
        self.m
            .parameters
            .iter()
            .map(|p| !p.fixed)
            .chain(std::iter::repeat_n(true, estimates))
            .collect()
    }
}

/// The model of `path` at `z`, its input from `seed`, and a record of its
/// own output at `z`; the parameters `shift` of the way further through
/// their bounds (so that a measured start does not sit exactly on a stop of
/// the record's own parameters: a fixed stop level can, and a fit never
/// moves it); the states the rule leaves unknown estimated from the
/// record.
fn case(path: &str, z: &[f64], seed: u64, shift: f64) -> Case {
    let (m, ex) = randomised(path, z);
    let c = CompiledModel::new(&m).unwrap();
    let u = ex.generate(seed).remove(0);
    let silent = Dataset::siso(u.clone(), vec![0.0; ex.n], ex.ts).unwrap();
    let y = run(&c, &m.values(), &silent).unwrap().y;
    let moved: Vec<f64> = z.iter().map(|z| (z + shift).min(1.0)).collect();
    let (m, _) = randomised(path, &moved);
    let c = CompiledModel::new(&m).unwrap();
    let data = Dataset::siso(u, y, ex.ts).unwrap();
    let values = m.values();
    let estimates = estimate(&c, &values, &data).unwrap();
    let p = values.len();
    let theta = values.into_iter().chain(estimates).collect();
    Case {
        m,
        c,
        data,
        p,
        theta,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn the_sensitivities_of_every_model_file_are_its_runs_derivatives(
        which in 0usize..FILES.len(),
        z in proptest::collection::vec(0.05f64..=0.9, 16),
        seed in any::<u64>(),
        shift in 0.001f64..0.05,
    ) {
        let path = &FILES[which];
        let k = case(path, &z, seed, shift);
        // A fitted delay is not differentiated (see below).
        prop_assume!(differentiable(&k.c));
        let (values, estimates) = k.split(&k.theta);
        let with = run_with_sensitivities(&k.c, values, estimates, &k.data).unwrap();
        let plain = run_from(&k.c, values, estimates, &k.data).unwrap();
        prop_assert_eq!(&with.y, &plain.y, "{}", path);
        prop_assert_eq!(&with.x, &plain.x, "{}", path);
        let exact = with.sensitivities.unwrap();
        prop_assert_eq!(exact.columns, k.theta.len());
        let outputs = |t: &[f64]| {
            let (values, estimates) = k.split(t);
            run_from(&k.c, values, estimates, &k.data).unwrap().y
        };
        agrees(path, &exact, &outputs, &k.theta, &k.free())?;
    }

    #[test]
    fn the_multiple_shooting_sensitivities_are_its_derivatives(
        which in 0usize..FILES.len(),
        z in proptest::collection::vec(0.05f64..=0.9, 16),
        seed in any::<u64>(),
        shift in 0.001f64..0.05,
        segment in 5usize..60,
    ) {
        let path = &FILES[which];
        let k = case(path, &z, seed, shift);
        // A fitted delay is not differentiated (see below).
        prop_assume!(differentiable(&k.c));
        let (values, estimates) = k.split(&k.theta);
        let ts = k.data.ts.unwrap();
        let y = k.data.y().to_vec();
        // The segments' start velocities from the record (a central slope).
        let slope = move |k: usize| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(y.len() - 1));
            (y[b] - y[a]) / ((b - a).max(1) as f64 * ts)
        };
        let (yhat, exact) =
            segmented_with_sensitivities(&k.c, values, estimates, &k.data, segment, &slope)
                .unwrap();
        let plain = segmented(&k.c, values, estimates, &k.data, segment, &slope).unwrap();
        prop_assert_eq!(&yhat, &plain, "{}", path);
        let outputs = |t: &[f64]| {
            let (values, estimates) = k.split(t);
            segmented(&k.c, values, estimates, &k.data, segment, &slope).unwrap()
        };
        agrees(path, &exact, &outputs, &k.theta, &k.free())?;
    }
}

/// Away from events the sensitivities are the derivative at every sample,
/// relative 1e-6: the coupled drives (no event) at their file's values.
#[test]
fn without_events_every_sample_matches_central_differences() {
    let path = "models/examples/coupled-drives.toml";
    let k = case(path, &[0.5; 16], 3, 0.01);
    let with = run_with_sensitivities(&k.c, &k.theta, &[], &k.data).unwrap();
    assert_eq!(with.events, 0);
    let exact = with.sensitivities.unwrap();
    let outputs = |t: &[f64]| run_from(&k.c, t, &[], &k.data).unwrap().y;
    for j in 0..exact.columns {
        let fd = central(&outputs, &k.theta, j, 1e-6);
        let e = column(&exact, j);
        let scale = norm(&fd) / (fd.len() as f64).sqrt();
        for (k, (a, b)) in e.iter().zip(&fd).enumerate() {
            assert!(
                (a - b).abs() <= 1e-6 * scale.max(b.abs()),
                "column {j}, sample {k}: {a} against {b}"
            );
        }
    }
}

/// A model whose delay is a parameter says its sensitivities are not
/// exact; one with delays given as numbers, or none, says they are.
#[test]
fn a_fitted_delay_is_declared_not_differentiable() {
    for (path, expected) in [
        ("models/pick-and-place/structures/delay.toml", false),
        ("models/pick-and-place/head-graybox.toml", true),
    ] {
        let (m, _) = randomised(path, &[0.5; 16]);
        assert_eq!(
            differentiable(&CompiledModel::new(&m).unwrap()),
            expected,
            "{path}"
        );
    }
}

/// The initial-state rules' rows: a position read through a sensor map
/// with a fitted gain and offset beside an estimated state, and a rest
/// state, against central differences.
#[test]
fn the_initial_rules_are_differentiated() {
    let data = record("c*x2 + off", 2.3, 0.7, 120, 4);
    for initial in [
        r#"{ from = "measured", samples = 10, position = "x2", estimate = { x1 = [-5.0, 5.0] } }"#,
        r#"{ from = "steady", values = { x1 = 5.0 } }"#,
    ] {
        let m = model(&cascade("c*x2 + off", initial));
        let c = CompiledModel::new(&m).unwrap();
        let values = m.values();
        let p = values.len();
        let estimates = estimate(&c, &values, &data).unwrap();
        let exact = run_with_sensitivities(&c, &values, &estimates, &data)
            .unwrap()
            .sensitivities
            .unwrap();
        let theta: Vec<f64> = values.iter().chain(&estimates).copied().collect();
        let outputs = |t: &[f64]| run_from(&c, &t[..p], &t[p..], &data).unwrap().y;
        let all = vec![true; theta.len()];
        agrees(initial, &exact, &outputs, &theta, &all).unwrap();
        // Every column moves the output: the start reads each parameter.
        for j in 0..exact.columns {
            assert!(
                column(&exact, j).iter().any(|d| *d != 0.0),
                "{initial}: column {j}"
            );
        }
    }
}
