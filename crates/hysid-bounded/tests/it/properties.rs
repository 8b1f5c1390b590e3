//! Invariants of the bounded-error procedure, on random PWARX
//! systems.

use crate::common;

use hysid_bounded::{Bounded, BoundedOptions, Delta};
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::data::Dataset;
use hysid_model::regressors::RegressorSpec;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn classify(data: &Dataset, delta: f64, seed: u64) -> hysid_bounded::procedure::Classification {
    let pri = Priors::default();
    let problem = Problem {
        data,
        orders: RegressorSpec::new(1, 1, 1),
        priors: &pri,
        priors_origin: None,
    };
    let opts = BoundedOptions {
        delta: Delta::Value(delta),
        ..Default::default()
    };
    Bounded::classify(&problem, &opts, &RunContext::quiet(seed))
        .unwrap()
        .0
}

/// Random stable parameters `[a1, b1, c]`.
fn random_thetas(s: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..s)
        .map(|_| {
            [
                rng.random_range(-0.8..0.8),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ]
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// On the returned model of the published procedure (`preset=paper`;
    /// the alternation of the defaults trades the bound for the fit): a
    /// sample is within delta of no mode exactly when the run reports it
    /// infeasible, and each mode's reported largest residual is at most
    /// delta (+1e-9).
    #[test]
    fn the_model_explains_every_feasible_sample_within_delta(s in 1usize..4, noise in 0.0f64..0.2, delta in 0.02f64..0.5, seed in 0u64..1000) {
        let g = common::sliced(&random_thetas(s, seed), 200, noise, seed);
        let pri = Priors::default();
        let problem = Problem {
            data: &g.data,
            orders: RegressorSpec::new(1, 1, 1),
            priors: &pri,
            priors_origin: None,
        };
        let set = Settings::parse(&[format!("delta={delta}"), "preset=paper".into()]).unwrap();
        let Model::Pwarx(m) = Pwarx(Bounded).run(&problem, &set, &RunContext::quiet(seed)).unwrap() else {
            panic!("a PWARX model")
        };
        let reg = RegressorSpec::new(1, 1, 1).build(&g.data).unwrap();
        let tol = delta + 1e-9;
        let unexplained = (0..reg.len())
            .filter(|&k| {
                m.modes.iter().all(|q| {
                    let t = &q.theta;
                    (reg.y[k] - (t[0] * reg.x[(k, 0)] + t[1] * reg.x[(k, 1)] + t[2])).abs() > tol
                })
            })
            .count();
        let d = &m.info.diagnostics.method;
        prop_assert_eq!(unexplained as u64, d["infeasible"].as_u64().unwrap());
        for r in d["max_residual"].as_array().unwrap() {
            prop_assert!(r.as_f64().unwrap() <= tol, "max residual {} delta {}", r, delta);
        }
    }

    /// With delta at or above the noise bound, the number of modes never
    /// exceeds the truth by more than one.
    #[test]
    fn mode_count_at_most_truth_plus_one(s in 1usize..4, noise in 0.01f64..0.1, factor in 1.0f64..2.0, seed in 0u64..1000) {
        let g = common::sliced(&random_thetas(s, seed), 300, noise, seed);
        let c = classify(&g.data, noise * factor, seed);
        prop_assert!(c.thetas.len() <= s + 1, "{} modes for {} true: {:?}", c.thetas.len(), s, c.thetas);
    }
}

/// A linear ARX that saturates at `y_sat` (exactly constant output, a
/// mechanical stop): returns the record and which regressor rows are saturated.
fn saturated(n: usize, y_sat: f64, seed: u64) -> (Dataset, Vec<bool>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.5)).collect();
    let mut y = vec![0.0; n];
    let mut sat = Vec::with_capacity(n - 1);
    for k in 1..n {
        let lin = 0.6 * y[k - 1] + u[k - 1] + 0.2 + rng.random_range(-0.02..0.02);
        y[k] = lin.min(y_sat);
        sat.push(lin >= y_sat);
    }
    (Dataset::siso(u, y, None).unwrap(), sat)
}

/// A constant-output segment (saturation) comes out, without any prior,
/// as a mode of its own with theta = [0 0 y_sat] exactly, in at least 95 %
/// of 200 fixed draws of the level and the record (measured: 198 of 200).
/// It is not an invariant: when a few saturated
/// samples near the corner fall within delta of the linear mode, its
/// minimax fit bends towards them and leaves two linear samples outside
/// its band, which then join the saturation mode. A known level is
/// honoured exactly by the `[[saturation]]` prior instead.
#[test]
fn saturation_is_its_own_mode_almost_always() {
    let mut draws = ChaCha8Rng::seed_from_u64(2003);
    let (mut cases, mut exact) = (0, 0);
    while cases < 200 {
        let (y_sat, seed) = (draws.random_range(0.8..1.5), draws.random_range(0..1000u64));
        let (d, sat) = saturated(300, y_sat, seed);
        let n_sat = sat.iter().filter(|&&s| s).count();
        if n_sat < 30 {
            continue;
        }
        cases += 1;
        let c = classify(&d, 0.05, seed);
        let flat =
            |t: &Vec<f64>| t[0].abs() < 1e-6 && t[1].abs() < 1e-6 && (t[2] - y_sat).abs() < 1e-6;
        let Some(i) = c.thetas.iter().position(flat) else {
            continue;
        };
        let hit = sat
            .iter()
            .zip(&c.labels)
            .filter(|&(&s, &l)| s && l == Some(i))
            .count();
        if hit as f64 >= 0.9 * n_sat as f64 {
            exact += 1;
        }
    }
    eprintln!("{exact} of {cases} draws with an exact saturation mode");
    assert!(exact >= 190, "{exact} of {cases}");
}
