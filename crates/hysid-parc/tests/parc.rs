//! PARC: the package's own example, its invariants (the cost of the
//! descent never rises, the partition is complete), B1 beside `cluster`.

use hysid_cluster::Cluster;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::data::{Dataset, Signal};
use hysid_model::regressors::RegressorSpec;
use hysid_parc::{Parc, ParcOptions};
use hysid_testkit::{Benchmark, Noise, median};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn problem<'a>(data: &'a Dataset, orders: RegressorSpec, priors: &'a Priors) -> Problem<'a> {
    Problem {
        data,
        orders,
        priors,
        priors_origin: None,
    }
}

/// PyPARC's unit test (`tests/test_parc.py`): `y = x1 + x2` where
/// `x2 >= 0`, else `x1 - x2`, `x` uniform in `[-1, 1]^2`, N = 1000, no
/// noise; PARC with K = 2 and 15 iterations must reach R^2 > 0.99999. Here
/// `x(k) = [u1(k-1), u2(k-1)]` (na = 0, nb = 1), and R^2 is scored on 1000
/// fresh samples by one-step prediction.
#[test]
fn pyparc_unit_test() {
    let record = |seed: u64| {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = 1001;
        let u1: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let u2: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let y: Vec<f64> = (0..n)
            .map(|k| {
                if k == 0 {
                    0.0
                } else if u2[k - 1] >= 0.0 {
                    u1[k - 1] + u2[k - 1]
                } else {
                    u1[k - 1] - u2[k - 1]
                }
            })
            .collect();
        let signal = |name: &str, values: Vec<f64>| Signal {
            name: name.into(),
            values,
        };
        Dataset::new(
            vec![signal("u1", u1), signal("u2", u2)],
            signal("y", y),
            None,
        )
        .unwrap()
    };
    let train = record(1);
    let priors = Priors {
        modes: Some(2),
        ..Priors::default()
    };
    let settings = Settings::from_pairs(vec![("max_iter".into(), "15".into())]);
    let model = Pwarx(Parc)
        .run(
            &problem(&train, RegressorSpec::new(0, 1, 2), &priors),
            &settings,
            &RunContext::quiet(0),
        )
        .unwrap();
    let test = record(2);
    let (report, _, _) = hysid_core::simulate::validate(&model, &test, 1).unwrap();
    let r2 = 1.0 - (1.0 - report.fit_pred / 100.0).powi(2);
    eprintln!("PyPARC unit test: R^2 = {r2:.8} (threshold 0.99999)");
    assert!(r2 > 0.99999, "R^2 {r2}");
}

/// A random 2- or 3-mode PWARX record (na = nb = 1) with Gaussian noise.
fn random_pwarx(seed: u64) -> Benchmark {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = rng.random_range(0.0..0.2);
    hysid_testkit::b1(
        300,
        rng.random_range(1.0..5.0),
        Noise::Gaussian(noise),
        seed,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Steps 1-3 each lower `J` for the others fixed (least squares, the
    /// separator's own objective, the argmin), so the recorded cost never
    /// rises by more than the separator's ridge can move it; and the cells
    /// cover the regressor space: every point lies in some region.
    #[test]
    fn the_cost_never_rises_and_the_partition_is_complete(
        seed in 0u64..5000,
        clusters in 2usize..6,
        sigma in 0.0f64..50.0,
        random_init in any::<bool>(),
    ) {
        let b = random_pwarx(seed);
        let priors = Priors { max_modes: Some(clusters), ..Priors::default() };
        let p = problem(&b.data, RegressorSpec::new(1, 1, 1), &priors);
        let data = pwarx::prepare(&p, "parc").unwrap();
        let options = ParcOptions {
            sigma,
            cost_tol: 0.0,
            init: if random_init { hysid_parc::Init::Random } else { hysid_parc::Init::Kmeans },
            ..ParcOptions::default()
        };
        let fit = hysid_parc::fit(&options, &data, &RunContext::quiet(seed)).unwrap();
        let cost = &fit.diagnostics.cost;
        for w in cost.windows(2) {
            prop_assert!(w[1] <= w[0] * (1.0 + 1e-6) + 1e-9, "{cost:?}");
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..200 {
            let x = [rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0)];
            prop_assert!(fit.modes.iter().any(|m| m.region.contains(&x)), "{x:?} in no region");
        }
    }
}

/// `modes` exactly, or with `bound` at most (PARC's own reading of K).
fn run(backend: &dyn Backend, b: &Benchmark, modes: usize, bound: bool, seed: u64) -> Model {
    let priors = Priors {
        modes: (!bound).then_some(modes),
        max_modes: bound.then_some(modes),
        ..Priors::default()
    };
    b.run(backend, &priors, &Settings::default(), seed).unwrap()
}

/// B1 (N = 500, u uniform in [-4, 4], uniform noise 0.1) on five draws,
/// PARC with K = 3 as its bound beside `cluster` with 3 modes, both with
/// their defaults, on the same draws (figures in docs/parc.md).
#[test]
fn b1_beside_cluster() {
    let mut rows = Vec::new();
    for seed in 1..=5 {
        let b = hysid_testkit::b1(500, 4.0, Noise::Uniform(0.1), seed);
        let parc = run(&Pwarx(Parc), &b, 3, true, seed);
        let p = b.score(&parc);
        let c = b.score(&run(&Pwarx(Cluster), &b, 3, false, seed));
        eprintln!(
            "B1 draw {seed}: parc {} modes, acc {:.3} err {:.4}; cluster acc {:.3} err {:.4}",
            parc.mode_count(),
            p.0,
            p.1,
            c.0,
            c.1
        );
        rows.push((p, c));
    }
    let p_acc = median(rows.iter().map(|r| r.0.0).collect());
    let c_acc = median(rows.iter().map(|r| r.1.0).collect());
    assert!(p_acc >= 0.95, "parc median accuracy {p_acc}");
    assert!(
        p_acc >= c_acc - 0.01,
        "parc {p_acc} against cluster {c_acc}"
    );
}

/// A `max_modes` bound larger than the record can fill is cut to the
/// clusters of `min_number` samples each it can hold: a fit, not a
/// failure where every cluster ends too small.
#[test]
fn a_bound_beyond_the_record_is_cut_to_what_it_can_hold() {
    let b = hysid_testkit::b1(41, 4.0, Noise::Uniform(0.1), 1);
    let m = run(&Pwarx(Parc), &b, 1000, true, 1);
    // 40 regressors of 2 (min_number 3): at most 13 clusters.
    assert!((1..=13).contains(&m.mode_count()), "{}", m.mode_count());
}
