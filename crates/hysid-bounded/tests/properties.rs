//! Invariants of the bounded-error procedure, on random PWARX
//! systems with fixed seeds.

use hysid_bounded::procedure::SampleClass;
mod common;

use hysid_bounded::{Bounded, BoundedOptions, Delta};
use hysid_core::backend::{Problem, RunContext};
use hysid_core::priors::Priors;
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
        delta: Some(Delta::Value(delta)),
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

    /// Every sample labelled with a mode has |residual| <= delta (+1e-9)
    /// for that mode, whatever the bound (assigned and undecidable alike).
    #[test]
    fn labelled_samples_are_within_delta(s in 1usize..4, noise in 0.0f64..0.2, delta in 0.02f64..0.5, seed in 0u64..1000) {
        let g = common::sliced(&random_thetas(s, seed), 200, noise, seed);
        let c = classify(&g.data, delta, seed);
        let reg = RegressorSpec::new(1, 1, 1).build(&g.data).unwrap();
        for (k, l) in c.labels.iter().enumerate() {
            let Some(i) = *l else {
                prop_assert_eq!(c.classes[k], SampleClass::Infeasible);
                continue;
            };
            let t = &c.thetas[i];
            let r = reg.y[k] - (t[0] * reg.x[(k, 0)] + t[1] * reg.x[(k, 1)] + t[2]);
            prop_assert!(r.abs() <= delta + 1e-9, "sample {} mode {} residual {} delta {}", k, i, r, delta);
        }
        for (i, m) in c.max_residual.iter().enumerate() {
            prop_assert!(*m <= delta + 1e-9, "mode {} max residual {}", i, m);
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// A constant-output segment (saturation) comes out as a mode of its
    /// own with theta = [0 .. 0 y_sat].
    #[test]
    fn saturation_is_its_own_mode(y_sat in 0.8f64..1.5, seed in 0u64..1000) {
        let (d, sat) = saturated(300, y_sat, seed);
        let n_sat = sat.iter().filter(|&&s| s).count();
        prop_assume!(n_sat >= 30);
        let c = classify(&d, 0.05, seed);
        let i = c.thetas.iter().position(|t| t[0].abs() < 1e-6 && t[1].abs() < 1e-6 && (t[2] - y_sat).abs() < 1e-6);
        prop_assert!(i.is_some(), "no saturation mode among {:?} (y_sat {})", c.thetas, y_sat);
        let i = i.unwrap();
        let hit = sat.iter().zip(&c.labels).filter(|&(&s, &l)| s && l == Some(i)).count();
        prop_assert!(hit as f64 >= 0.9 * n_sat as f64, "{} of {} saturated samples in the saturation mode", hit, n_sat);
    }
}
