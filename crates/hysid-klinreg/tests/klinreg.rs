//! k-LinReg: its invariant (the cost never rises), Lauer's success rate of
//! one restart beside ours, the benchmarks beside `cluster`, priors and
//! determinism.

use hysid_cluster::Cluster;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::{Priors, Tie};
use hysid_estimation::constrained::Parametrisation;
use hysid_estimation::pwarx::Pwarx;
use hysid_klinreg::{
    DEFAULT_MIN_RESTARTS, KLinReg, KLinRegOptions, SuccessModel, restart_count, run_restart,
    success_probability,
};
use hysid_model::metrics::mode_accuracy;
use hysid_model::regressors::{RegressorSpec, Regressors};
use hysid_testkit::{Benchmark, Noise, median};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// A switched linear regression `y = theta_q . [x; 1]` with `x` uniform in
/// `[-5, 5]^d`, the mode uniform, parameters uniform in `[-10, 10]`, plus
/// Gaussian noise of standard deviation `sigma`. Returns the record and
/// the true modes.
fn switched(
    n: usize,
    d: usize,
    modes: usize,
    sigma: f64,
    seed: u64,
) -> (Regressors, Vec<usize>, Vec<Vec<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let thetas: Vec<Vec<f64>> = (0..modes)
        .map(|_| (0..=d).map(|_| rng.random_range(-10.0..10.0)).collect())
        .collect();
    let x = DMatrix::from_fn(n, d, |_, _| rng.random_range(-5.0..5.0));
    let truth: Vec<usize> = (0..n).map(|_| rng.random_range(0..modes)).collect();
    let y = DVector::from_fn(n, |k, _| {
        let t = &thetas[truth[k]];
        let noise = if sigma > 0.0 {
            sigma * rand_distr::Distribution::<f64>::sample(&rand_distr::StandardNormal, &mut rng)
        } else {
            0.0
        };
        t[d] + (0..d).map(|j| t[j] * x[(k, j)]).sum::<f64>() + noise
    });
    (
        Regressors {
            x,
            y,
            samples: (0..n).collect(),
        },
        truth,
        thetas,
    )
}

fn options() -> KLinRegOptions {
    KLinRegOptions::default()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Step 2 minimises the cost over the labels and step 3 over the
    /// parameters: the cost after each assignment never rises, with or
    /// without a tie between the modes.
    #[test]
    fn the_cost_never_rises(
        seed in 0u64..10_000,
        restart in 0usize..50,
        modes in 2usize..5,
        d in 1usize..4,
        sigma in 0.0f64..2.0,
        tie in any::<bool>(),
    ) {
        let (reg, _, _) = switched(200, d, modes, sigma, seed);
        let spec = RegressorSpec::new(0, d, 1);
        let priors = if tie {
            Priors { tie: vec![Tie { params: vec!["c".into()] }], ..Priors::default() }
        } else {
            Priors::default()
        };
        let par = Parametrisation::from_priors(&priors, &spec, modes).unwrap();
        if let Some(r) = run_restart(&reg, &par, modes, &options(), seed, restart) {
            for w in r.costs.windows(2) {
                prop_assert!(w[1] <= w[0] * (1.0 + 1e-9) + 1e-12, "{:?}", r.costs);
            }
            prop_assert_eq!(r.cost, *r.costs.last().unwrap());
            if tie {
                let c = r.thetas[0][d];
                prop_assert!(r.thetas.iter().all(|t| (t[d] - c).abs() <= 1e-9 * (1.0 + c.abs())));
            }
        }
    }
}

/// Lauer (2013) fits a model of the probability that one restart reaches
/// the global minimum; for switched regression with N = 300 samples, 3
/// modes and 3 parameters per mode it gives P_s = 0.985. Ours, on 300
/// random noiseless problems of that size (one restart each, a success
/// when every sample gets its true mode up to a permutation), is lower:
/// 196 of 300 (0.653) with these seed-fixed draws. The test guards that
/// figure (at least 0.55, four standard errors below it) and checks what
/// the back-end relies on instead: the best of its default number of
/// restarts ([`DEFAULT_MIN_RESTARTS`] at least) finds the true modes of
/// every one of 100 such problems.
#[test]
fn one_restart_beside_lauers_model_and_the_default_restarts_succeed() {
    let (n, modes, d) = (300, 3, 2);
    let model = success_probability(SuccessModel::Static, n, modes, d + 1);
    assert!((model - 0.985).abs() < 5e-4, "{model}");
    let spec = RegressorSpec::new(0, d, 1);
    let par = Parametrisation::from_priors(&Priors::default(), &spec, modes).unwrap();
    let succeeds = |t: usize, restart: usize, reg: &Regressors, truth: &[usize]| {
        run_restart(reg, &par, modes, &options(), t as u64, restart).map(|r| {
            (
                r.cost,
                mode_accuracy(truth, &r.labels).unwrap().accuracy == 1.0,
            )
        })
    };
    // The problems are independent: solved in parallel, counted in any order.
    let trials = 300;
    let successes = (0..trials)
        .into_par_iter()
        .filter(|&t| {
            let (reg, truth, _) = switched(n, d, modes, 0.0, 1000 + t as u64);
            succeeds(t, 0, &reg, &truth).is_some_and(|(_, ok)| ok)
        })
        .count();
    let rate = successes as f64 / trials as f64;
    eprintln!("one restart: {successes}/{trials} = {rate:.3}; Lauer's model {model:.3}");
    assert!(rate >= 0.55, "one restart succeeds {rate}");
    let restarts = restart_count(n, modes, d + 1).max(DEFAULT_MIN_RESTARTS);
    (0..100).into_par_iter().for_each(|t| {
        let (reg, truth, _) = switched(n, d, modes, 0.0, 5000 + t as u64);
        let best = (0..restarts)
            .filter_map(|i| succeeds(t, i, &reg, &truth))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap();
        assert!(
            best.1,
            "problem {t}: the best of {restarts} restarts misses the true modes"
        );
    });
}

fn run(backend: &dyn Backend, b: &Benchmark, modes: usize, seed: u64) -> Model {
    let priors = Priors {
        modes: Some(modes),
        ..Priors::default()
    };
    let paper = Settings::parse(&["preset=paper"]).unwrap();
    b.run(backend, &priors, &paper, seed).unwrap()
}

/// B1 (the classic 3-mode PWARX) on five draws: k-LinReg beside `cluster`,
/// each as its paper publishes it (`preset=paper`; cluster's default
/// alternation gains about one point of accuracy here), on the same draws. k-LinReg's modes come from the
/// residuals alone, so its parameter error is at most cluster's on most
/// draws; both region steps are the same MRLP.
#[test]
fn b1_beside_cluster() {
    let mut rows = Vec::new();
    for seed in 1..=5 {
        let b = hysid_testkit::b1(500, 4.0, Noise::Uniform(0.1), seed);
        let k = b.score(&run(&Pwarx(KLinReg), &b, 3, seed));
        let c = b.score(&run(&Pwarx(Cluster), &b, 3, seed));
        eprintln!(
            "B1 draw {seed}: klinreg acc {:.3} err {:.4}; cluster acc {:.3} err {:.4}",
            k.0, k.1, c.0, c.1
        );
        rows.push((k, c));
    }
    let k_acc = median(rows.iter().map(|r| r.0.0).collect());
    let c_acc = median(rows.iter().map(|r| r.1.0).collect());
    let k_err = median(rows.iter().map(|r| r.0.1).collect());
    let c_err = median(rows.iter().map(|r| r.1.1).collect());
    assert!(k_acc >= 0.95, "klinreg median accuracy {k_acc}");
    assert!(
        k_acc >= c_acc - 0.01,
        "klinreg {k_acc} against cluster {c_acc}"
    );
    assert!(
        k_err <= c_err * 1.1,
        "klinreg {k_err} against cluster {c_err}"
    );
}

/// The same model for one thread or two (restarts on their own random
/// streams, the least cost and then the lowest index kept).
#[test]
fn the_model_does_not_depend_on_the_thread_count() {
    let b = hysid_testkit::b1(400, 4.0, Noise::Uniform(0.1), 9);
    let fit = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&Pwarx(KLinReg), &b, 3, 4).to_json())
    };
    assert_eq!(fit(1), fit(2));
}

/// Without a mode count the run is refused with the typed error that
/// names the method.
#[test]
fn a_mode_count_is_needed() {
    let b = hysid_testkit::b1(200, 4.0, Noise::Uniform(0.1), 1);
    let problem = Problem {
        data: &b.data,
        orders: RegressorSpec::new(1, 1, 1),
        priors: &Priors::default(),
        priors_origin: None,
    };
    let e = Pwarx(KLinReg)
        .run(&problem, &Settings::default(), &RunContext::quiet(0))
        .unwrap_err();
    assert!(
        matches!(
            e,
            hysid_core::backend::IdentifyError::NeedsModeCount {
                method: "klinreg",
                bounded: true
            }
        ),
        "{e}"
    );
}
