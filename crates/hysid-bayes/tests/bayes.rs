//! The Bayesian procedure: its invariants (weights sum to one, the
//! estimate does not depend on the order of equally weighted particles,
//! the particle cloud approaches the exact Gaussian posterior, the
//! Gaussian update equals the batch posterior), the benchmarks beside
//! `cluster`, priors and determinism.

use hysid_bayes::{Bayes, GaussianPosterior, ModePrior, ParticleCloud, systematic};
use hysid_cluster::Cluster;
use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::regressors::RegressorSpec;
use hysid_testkit::{Benchmark, Noise, as_pwarx, median};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A prior `N(mean, diag(var))` without bounds.
fn prior(mean: &[f64], var: &[f64]) -> ModePrior {
    ModePrior {
        mean: DVector::from_column_slice(mean),
        cov: DMatrix::from_diagonal(&DVector::from_column_slice(var)),
        lower: vec![f64::NEG_INFINITY; mean.len()],
        upper: vec![f64::INFINITY; mean.len()],
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Bayes' rule and resampling keep the weights a probability
    /// distribution, however unlikely the sample.
    #[test]
    fn weights_sum_to_one(
        seed in 0u64..10_000,
        n in 2usize..300,
        phi in prop::collection::vec(-5.0f64..5.0, 3),
        y in -1e3f64..1e3,
        sigma in 1e-4f64..10.0,
        h in 0.0f64..0.99,
    ) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let p = prior(&[0.0, 1.0, -1.0], &[1.0, 4.0, 0.25]);
        let mut cloud = ParticleCloud::draw(&p, n, &mut rng);
        let phi = DVector::from_vec(phi);
        cloud.update(&phi, y, sigma);
        let total: f64 = cloud.weights().iter().sum();
        prop_assert!((total - 1.0).abs() < 1e-9, "after the update: {total}");
        prop_assert!(cloud.effective_sample_size() <= n as f64 * (1.0 + 1e-9));
        let fallback = p.cov.clone();
        cloud.resample(h, &p, &fallback, &mut rng);
        let total: f64 = cloud.weights().iter().sum();
        prop_assert!((total - 1.0).abs() < 1e-9, "after resampling: {total}");
        prop_assert_eq!(cloud.len(), n);
    }

    /// Permuting equally weighted particles changes neither the predictive
    /// density of a sample nor the posterior mean after it.
    #[test]
    fn the_estimate_does_not_depend_on_the_order_of_the_particles(
        seed in 0u64..10_000,
        n in 2usize..200,
        phi in prop::collection::vec(-5.0f64..5.0, 3),
        y in -20.0f64..20.0,
        sigma in 1e-2f64..10.0,
    ) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let p = prior(&[0.5, -1.0, 2.0], &[1.0, 1.0, 1.0]);
        let cloud = ParticleCloud::draw(&p, n, &mut rng);
        let mut order: Vec<usize> = (0..n).collect();
        order.reverse();
        order.rotate_left(seed as usize % n);
        let permuted = ParticleCloud::equally_weighted(
            3,
            order.iter().flat_map(|&j| cloud.particle(j).to_vec()).collect(),
        );
        let phi = DVector::from_vec(phi);
        let (a, b) = (cloud.log_predictive(&phi, y, sigma), permuted.log_predictive(&phi, y, sigma));
        prop_assert!(close(a, b, 1e-9), "predictive {a} vs {b}");
        let (mut a, mut b) = (cloud.clone(), permuted);
        a.update(&phi, y, sigma);
        b.update(&phi, y, sigma);
        for (x, z) in a.mean().iter().zip(b.mean().iter()) {
            prop_assert!(close(*x, *z, 1e-9), "posterior mean {x} vs {z}");
        }
    }

    /// The Gaussian update, one sample at a time in any order, equals the
    /// batch posterior `P = (P0^-1 + Phi' Phi / s^2)^-1`,
    /// `m = P (P0^-1 m0 + Phi' y / s^2)`.
    #[test]
    fn the_gaussian_update_is_the_batch_posterior(
        rows in prop::collection::vec(prop::collection::vec(-3.0f64..3.0, 2), 1..30),
        ys in prop::collection::vec(-10.0f64..10.0, 30),
        sigma in 0.05f64..3.0,
        reverse in any::<bool>(),
    ) {
        let p0 = prior(&[1.0, -2.0, 0.5], &[2.0, 0.5, 1.0]);
        let phis: Vec<DVector<f64>> = rows.iter().map(|r| DVector::from_vec(vec![r[0], r[1], 1.0])).collect();
        let mut g = GaussianPosterior::from_prior(&p0);
        let mut idx: Vec<usize> = (0..phis.len()).collect();
        if reverse {
            idx.reverse();
        }
        for &k in &idx {
            g.update(&phis[k], ys[k], sigma);
        }
        let p0_inv = p0.cov.clone().try_inverse().unwrap();
        let mut info = p0_inv.clone();
        let mut rhs = &p0_inv * &p0.mean;
        for (k, phi) in phis.iter().enumerate() {
            info += phi * phi.transpose() / (sigma * sigma);
            rhs += phi * ys[k] / (sigma * sigma);
        }
        let cov = info.try_inverse().unwrap();
        let mean = &cov * rhs;
        for j in 0..3 {
            prop_assert!(close(g.mean[j], mean[j], 1e-7), "mean {} vs {}", g.mean[j], mean[j]);
            for k in 0..3 {
                prop_assert!((g.cov[(j, k)] - cov[(j, k)]).abs() < 1e-7 * (1.0 + cov[(j, j)]));
            }
        }
    }
}

/// Systematic resampling picks each particle its weight times `n` times,
/// rounded up or down: with `u = 0.3` the points 0.075, 0.325, 0.575 and
/// 0.825 fall in the cumulative intervals of particles 0, 0, 1 and 2.
#[test]
fn systematic_resampling_follows_the_weights() {
    let w = [0.5, 0.25, 0.125, 0.125];
    let picks = systematic(&w, 0.3);
    let count = |j| picks.iter().filter(|&&p| p == j).count();
    assert_eq!(picks.len(), 4);
    assert_eq!((count(0), count(1), count(2), count(3)), (2, 1, 1, 0));
    assert_eq!(systematic(&[0.0, 1.0, 0.0], 0.99), vec![1, 1, 1]);
}

/// With many particles and no resampling, the particle posterior after
/// five samples lies close to the exact Gaussian one: the mean within a
/// twentieth of the posterior standard deviation, the variances within
/// 10 %. A wrong likelihood or weight update moves the mean by whole
/// standard deviations.
#[test]
fn particles_approach_the_exact_posterior() {
    let p0 = prior(&[0.0, 0.0, 0.0], &[1.0, 1.0, 1.0]);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut cloud = ParticleCloud::draw(&p0, 200_000, &mut rng);
    let mut exact = GaussianPosterior::from_prior(&p0);
    let samples = [
        ([0.3, -1.0], 0.7),
        ([1.2, 0.4], 1.5),
        ([-0.8, 0.9], -0.2),
        ([0.1, 0.1], 0.4),
        ([-1.5, -0.3], -1.1),
    ];
    for (x, y) in samples {
        let phi = DVector::from_vec(vec![x[0], x[1], 1.0]);
        assert!(close(
            cloud.log_predictive(&phi, y, 0.5),
            exact.log_predictive(&phi, y, 0.5),
            0.02
        ));
        cloud.update(&phi, y, 0.5);
        exact.update(&phi, y, 0.5);
    }
    let (m, c) = (cloud.mean(), cloud.covariance());
    for j in 0..3 {
        let sd = exact.cov[(j, j)].sqrt();
        assert!(
            (m[j] - exact.mean[j]).abs() < 0.05 * sd,
            "mean {j}: {} vs {} (sd {sd})",
            m[j],
            exact.mean[j]
        );
        assert!(
            (c[(j, j)] / exact.cov[(j, j)] - 1.0).abs() < 0.1,
            "variance {j}: {} vs {}",
            c[(j, j)],
            exact.cov[(j, j)]
        );
    }
}

fn priors(modes: usize) -> Priors {
    Priors {
        modes: Some(modes),
        ..Priors::default()
    }
}

fn run_with(
    b: &Benchmark,
    priors: &Priors,
    set: &[&str],
    seed: u64,
) -> Result<Model, IdentifyError> {
    b.run(&Pwarx(Bayes), priors, &Settings::parse(set).unwrap(), seed)
}

/// B1 (the classic one-dimensional 3-mode PWARX) on five draws, beside
/// `cluster` as its paper publishes it (`preset=paper`; its default
/// alternation gains about one point of accuracy here) on the same draws,
/// for both
/// representations of the pdfs: mode accuracy on a fresh draw and the
/// largest relative parameter error.
#[test]
fn b1_beside_cluster() {
    for posterior in ["gaussian", "particles"] {
        let set = format!("posterior={posterior}");
        let (mut acc, mut err, mut c_acc, mut c_err) = (vec![], vec![], vec![], vec![]);
        for seed in 1..=5 {
            let b = hysid_testkit::b1(301, 4.0, Noise::Uniform(0.1), seed);
            let fresh = hysid_testkit::b1(301, 4.0, Noise::Uniform(0.1), seed + 100);
            let m = run_with(&b, &priors(3), &[set.as_str()], seed).unwrap();
            acc.push(fresh.recovery(as_pwarx(&m)).0);
            err.push(b.recovery(as_pwarx(&m)).1);
            let c = b
                .run(
                    &Pwarx(Cluster),
                    &priors(3),
                    &Settings::parse(&["preset=paper"]).unwrap(),
                    seed,
                )
                .unwrap();
            c_acc.push(fresh.recovery(as_pwarx(&c)).0);
            c_err.push(b.recovery(as_pwarx(&c)).1);
        }
        let (acc, err, c_acc, c_err) = (median(acc), median(err), median(c_acc), median(c_err));
        eprintln!(
            "B1 {posterior}: accuracy {acc:.3} (cluster {c_acc:.3}), error {err:.3} (cluster {c_err:.3})"
        );
        assert!(acc >= 0.95, "{posterior}: median accuracy {acc}");
        assert!(
            acc >= c_acc - 0.02,
            "{posterior}: {acc} against cluster {c_acc}"
        );
        assert!(err <= 0.06, "{posterior}: median parameter error {err}");
    }
}

/// `[fixed]` values come back exactly in every mode, with either
/// representation; `[bounds]` hold with particles (`auto` picks them) and
/// are refused by the Gaussian posterior.
#[test]
fn fixed_values_and_bounds_hold() {
    let b = hysid_testkit::b1(301, 4.0, Noise::Uniform(0.1), 3);
    let mut fixed = priors(3);
    fixed.fixed.insert("a1".into(), 0.25);
    for posterior in ["gaussian", "particles"] {
        let set = format!("posterior={posterior}");
        let m = run_with(&b, &fixed, &[set.as_str()], 1).unwrap();
        let spec = as_pwarx(&m).spec();
        let a1 = spec.param_names().iter().position(|n| n == "a1").unwrap();
        for mode in &as_pwarx(&m).modes {
            assert_eq!(mode.theta[a1], 0.25, "{posterior}");
        }
    }
    let mut bounded = priors(3);
    bounded.bounds.insert("c".into(), [-1.0, 1.0]);
    let m = run_with(&b, &bounded, &[], 1).unwrap();
    let spec = as_pwarx(&m).spec();
    let c = spec.param_names().iter().position(|n| n == "c").unwrap();
    for mode in &as_pwarx(&m).modes {
        assert!(
            (-1.0..=1.0).contains(&mode.theta[c]),
            "c = {}",
            mode.theta[c]
        );
    }
    assert_eq!(
        m.info().diagnostics.method["posterior"].as_str(),
        Some("particles")
    );
    let e = run_with(&b, &bounded, &["posterior=gaussian"], 1).unwrap_err();
    assert!(e.to_string().contains("posterior=gaussian"), "{e}");
}

/// The same seed gives the same model, with particles and a random order.
#[test]
fn same_seed_same_model() {
    let b = hysid_testkit::b1(200, 4.0, Noise::Uniform(0.1), 5);
    let set = ["posterior=particles", "order=random"];
    let one = run_with(&b, &priors(3), &set, 9).unwrap().to_json();
    assert_eq!(one, run_with(&b, &priors(3), &set, 9).unwrap().to_json());
    assert_ne!(one, run_with(&b, &priors(3), &set, 10).unwrap().to_json());
}

/// The back-end declares the seed where it draws from it: with the exact
/// Gaussian posterior in time or nearest-neighbour order two seeds give
/// the same modes and regions (automatic selection then refits once, and
/// an experiment runs one seed for all); with particles, a random order,
/// or [bounds] that make `posterior = auto` draw particles, the seed is
/// declared and changes the model.
#[test]
fn the_seed_counts_where_it_is_drawn() {
    let b = hysid_testkit::b1(200, 4.0, Noise::Uniform(0.1), 5);
    let mut bounded = priors(3);
    bounded.bounds.insert("c".into(), [-1.0, 1.0]);
    let fitted = |priors: &Priors, set: &[&str], seed: u64| {
        let m = run_with(&b, priors, set, seed).unwrap();
        let p = as_pwarx(&m);
        p.modes.clone()
    };
    let cases: [(&Priors, &[&str], bool); 5] = [
        (&priors(3), &[], false),
        (&priors(3), &["order=time"], false),
        (&priors(3), &["order=random"], true),
        (&priors(3), &["posterior=particles"], true),
        (&bounded, &[], true),
    ];
    for (priors, set, seeded) in cases {
        let settings = Settings::parse(set).unwrap();
        let declared = Pwarx(Bayes)
            .seeded_with(&b.problem(priors), &settings)
            .unwrap();
        assert_eq!(declared, seeded, "{set:?}, bounds {:?}", priors.bounds);
        let same = fitted(priors, set, 1) == fitted(priors, set, 2);
        assert_eq!(same, !seeded, "{set:?}, bounds {:?}", priors.bounds);
    }
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
    let e = Pwarx(Bayes)
        .run(&problem, &Settings::default(), &RunContext::quiet(0))
        .unwrap_err();
    assert!(
        matches!(
            e,
            IdentifyError::NeedsModeCount {
                method: "bayes",
                bounded: true
            }
        ),
        "{e}"
    );
}
