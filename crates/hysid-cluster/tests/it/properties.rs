//! Invariants of the `cluster` back-end, as property tests with
//! small case counts (each case is a whole identification).

use hysid_cluster::{Cluster, ClusterError};
use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::data::{Dataset, Signal};
use hysid_model::metrics::parameter_error;
use hysid_model::model::{PwarxModel, Stop, StopBound};
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::SimulationOptions;
use hysid_testkit::{Benchmark, Noise};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn try_identify(
    data: &Dataset,
    orders: RegressorSpec,
    modes: usize,
    set: &[&str],
) -> Result<Model, IdentifyError> {
    let priors = Priors {
        modes: Some(modes),
        ..Default::default()
    };
    let problem = Problem {
        data,
        orders,
        priors: &priors,
        priors_origin: None,
    };
    Pwarx(Cluster).run(
        &problem,
        &Settings::parse(set).unwrap(),
        &RunContext::quiet(7),
    )
}

fn identify(data: &Dataset, orders: RegressorSpec, modes: usize, set: &[&str]) -> PwarxModel {
    match try_identify(data, orders, modes, set).unwrap() {
        Model::Pwarx(m) => m,
        _ => unreachable!(),
    }
}

fn thetas(m: &PwarxModel) -> Vec<Vec<f64>> {
    m.modes.iter().map(|q| q.theta.clone()).collect()
}

/// H4's static three-wedge map (`hysid_testkit::h4_with_noise`, noise
/// `U[-noise, noise]`) as `n` independent pairs `(u(k-1), y(k))`.
fn wedges(n: usize, noise: f64, seed: u64) -> (Vec<[f64; 2]>, Vec<f64>) {
    let b = hysid_testkit::h4_with_noise(n + 1, Noise::Uniform(noise), seed);
    let (u1, u2, y) = (b.data.u(0), b.data.u(1), b.data.y());
    ((0..n).map(|k| [u1[k], u2[k]]).collect(), y[1..].to_vec())
}

/// B1 (`u ~ U[-4, 4]`, noise `U[-0.1, 0.1]`) with `n` regressor rows.
fn b1(n: usize, seed: u64) -> Benchmark {
    hysid_testkit::b1(n + 1, 4.0, Noise::Uniform(0.1), seed)
}

fn static_dataset(x: &[[f64; 2]], y: &[f64], order: &[usize]) -> Dataset {
    let mut u1: Vec<f64> = order.iter().map(|&k| x[k][0]).collect();
    let mut u2: Vec<f64> = order.iter().map(|&k| x[k][1]).collect();
    let mut yy = vec![0.0];
    yy.extend(order.iter().map(|&k| y[k]));
    u1.push(0.0);
    u2.push(0.0);
    Dataset::new(
        vec![
            Signal {
                name: "u1".into(),
                values: u1,
            },
            Signal {
                name: "u2".into(),
                values: u2,
            },
        ],
        Signal {
            name: "y".into(),
            values: yy,
        },
        None,
    )
    .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// Permuting the samples of a static map (the regressor/target pairs)
    /// does not change the identified model beyond tolerance.
    #[test]
    fn sample_order_does_not_matter(seed in any::<u64>(), perm_seed in any::<u64>()) {
        let (x, y) = wedges(300, 0.1, seed);
        let id: Vec<usize> = (0..x.len()).collect();
        let mut perm = id.clone();
        use rand::seq::SliceRandom;
        perm.shuffle(&mut ChaCha8Rng::seed_from_u64(perm_seed));
        let orders = RegressorSpec::new(0, 1, 2);
        let a = identify(&static_dataset(&x, &y, &id), orders, 3, &["c=12"]);
        let b = identify(&static_dataset(&x, &y, &perm), orders, 3, &["c=12"]);
        prop_assert_eq!(a.modes.len(), b.modes.len());
        let e = parameter_error(&thetas(&a), &thetas(&b)).unwrap().max_relative_error;
        prop_assert!(e < 1e-3, "models differ by {e}: {:?} vs {:?}", thetas(&a), thetas(&b));
    }

    /// Scaling the output by `k` scales the input and constant parameters
    /// by `k` and leaves the autoregressive ones unchanged. Under the
    /// default standardisation the working data are the same for every
    /// `k`, so this checks the way back to original units. Without it
    /// (`scale = false`, HIT's raw distances) the neighbour search and the
    /// K-means see the scaled numbers and the property does not hold: the
    /// first draw of this test differed by 1.8 % (`docs/cluster.md`).
    #[test]
    fn output_scaling_scales_the_affine_part(seed in any::<u64>(), k in prop_oneof![0.2f64..5.0, -5.0f64..-0.2]) {
        let ex = b1(400, seed);
        let scaled = Dataset::siso(ex.data.u(0).to_vec(), ex.data.y().iter().map(|v| k * v).collect(), None).unwrap();
        let a = identify(&ex.data, ex.truth.spec(), 3, &[]);
        let b = identify(&scaled, ex.truth.spec(), 3, &[]);
        let expect: Vec<Vec<f64>> = thetas(&a).into_iter().map(|t| vec![t[0], k * t[1], k * t[2]]).collect();
        prop_assert_eq!(a.modes.len(), b.modes.len());
        let e = parameter_error(&expect, &thetas(&b)).unwrap().max_relative_error;
        prop_assert!(e < 1e-6, "scaled model differs by {e}: {:?} vs {:?}", expect, thetas(&b));
    }

    /// Every complete partition (MRLP, MSVM, softmax) covers random points
    /// of (and beyond) the regressor domain: the polyhedra written to the
    /// model, not the classifier, are what is checked. `discard=0` keeps
    /// every non-empty cluster, so that asking B1 (3 true modes) for 4
    /// modes gives a model of 4 modes instead of the exact-modes refusal.
    #[test]
    fn complete_partitions_cover_the_domain(seed in any::<u64>(), modes in 2usize..5, regions in prop_oneof![Just("mrlp"), Just("msvm"), Just("softmax")]) {
        let ex = b1(300, seed);
        let method = format!("regions={regions}");
        let m = identify(&ex.data, ex.truth.spec(), modes, &["discard=0", &method]);
        let polyhedra: Vec<_> = m.modes.iter().map(|q| q.region.clone()).collect();
        let rep = hysid_estimation::regions::coverage(&polyhedra, &[-20.0, -10.0], &[20.0, 10.0], 2000, seed);
        prop_assert_eq!(rep.uncovered_fraction, 0.0);
    }

    /// With a known stop, the model (regions and the stop's mode) covers
    /// every state a free run reaches under inputs beyond the identification
    /// range: B1 clipped at its 85th output percentile, `[[saturation]]`
    /// at that level.
    #[test]
    fn a_model_with_a_stop_covers_its_free_run(seed in any::<u64>(), regions in prop_oneof![Just("mrlp"), Just("msvm"), Just("softmax")]) {
        let ex = b1(400, seed);
        let mut sorted = ex.data.y().to_vec();
        sorted.sort_by(f64::total_cmp);
        let level = sorted[sorted.len() * 85 / 100];
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let u = ex.data.u(0).to_vec();
        let mut y = vec![ex.data.y()[0].min(level)];
        for k in 1..u.len() {
            let t = &ex.truth.modes[ex.truth.mode_of(&[y[k - 1], u[k - 1]]).mode].theta;
            let noise = rng.random_range(-0.1..0.1);
            y.push((t[0] * y[k - 1] + t[1] * u[k - 1] + t[2] + noise).min(level));
        }
        let clipped = Dataset::siso(u, y, None).unwrap();
        let priors = Priors {
            modes: Some(4),
            saturation: vec![Stop { level, bound: StopBound::Max, tol: None }],
            ..Default::default()
        };
        let problem = Problem { data: &clipped, orders: ex.truth.spec(), priors: &priors, priors_origin: None };
        let method = format!("regions={regions}");
        let model = Pwarx(Cluster).run(&problem, &Settings::parse(&["discard=0", &method]).unwrap(), &RunContext::quiet(7)).unwrap();
        let u: Vec<f64> = (0..300).map(|_| rng.random_range(-8.0..8.0)).collect();
        let run = Dataset::siso(u, vec![0.0; 300], None).unwrap();
        let sim = hysid_core::simulate::simulate(&model, &run, SimulationOptions::for_data(&run)).unwrap();
        let holes = sim.covered.iter().skip(sim.start + 1).filter(|&&c| !c).count();
        prop_assert_eq!(holes, 0);
    }

    /// Noise-free PWARX data with well-separated modes is recovered
    /// exactly (parameters to 1e-6).
    #[test]
    fn noise_free_pwarx_is_recovered_exactly(
        a1 in -0.8f64..0.8, b1 in 0.5f64..2.0, c1 in -1.0f64..1.0, dc in 1.5f64..3.0, seed in any::<u64>()
    ) {
        // Mode 1 for u(k-1) < 0, mode 2 for u(k-1) >= 0; very different slopes.
        let th = [[a1, b1, c1], [-a1 * 0.5, -b1, c1 + dc]];
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = 300;
        let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut y = vec![0.0; n];
        for k in 1..n {
            let t = if u[k - 1] < 0.0 { th[0] } else { th[1] };
            y[k] = t[0] * y[k - 1] + t[1] * u[k - 1] + t[2];
        }
        let data = Dataset::siso(u, y, None).unwrap();
        let m = identify(&data, RegressorSpec::new(1, 1, 1), 2, &[]);
        prop_assert_eq!(m.modes.len(), 2);
        let e = parameter_error(&th.iter().map(|t| t.to_vec()).collect::<Vec<_>>(), &thetas(&m)).unwrap().max_relative_error;
        prop_assert!(e < 1e-6, "error {e}: {:?} vs {:?} ({:?})", th, thetas(&m), m.info.diagnostics);
    }
}

/// Degenerate data (a stop: constant output over long stretches, and
/// noise-free local fits) do not abort; the count is reported.
#[test]
fn degenerate_local_datasets_are_regularised_and_counted() {
    let n = 400;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let u: Vec<f64> = (0..n)
        .map(|k| {
            if (k / 50) % 2 == 0 {
                1.0
            } else {
                rng.random_range(-1.0..0.0)
            }
        })
        .collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        // Saturates at 1 while the input is held at 1.
        y[k] = if u[k - 1] >= 1.0 {
            1.0
        } else {
            0.5 * y[k - 1] + u[k - 1]
        };
    }
    let data = Dataset::siso(u, y, None).unwrap();
    let m = identify(&data, RegressorSpec::new(1, 1, 1), 2, &[]);
    let d = &m.info.diagnostics.method;
    assert!(
        d["degenerate_local_datasets"].as_u64().unwrap() > 0,
        "{d:?}"
    );
    assert!(
        m.modes
            .iter()
            .all(|q| q.theta.iter().all(|v| v.is_finite()))
    );
}

#[test]
fn errors_are_clear() {
    let ex = b1(200, 1);
    let run = |p: &Priors, set: &[&str]| {
        let problem = Problem {
            data: &ex.data,
            orders: ex.truth.spec(),
            priors: p,
            priors_origin: None,
        };
        Pwarx(Cluster)
            .run(
                &problem,
                &Settings::parse(set).unwrap(),
                &RunContext::quiet(1),
            )
            .map(|_| ())
    };
    let none = Priors::default();
    let e = run(&none, &[]).unwrap_err().to_string();
    assert!(e.contains("modes"), "{e}");
    let three = Priors {
        modes: Some(3),
        ..Default::default()
    };
    let e = run(&three, &["c=2"]).unwrap_err().to_string();
    assert!(e.contains("c=2") && e.contains("n+2"), "{e}");
    assert!(run(&three, &["restarts=0"]).is_err());
    assert!(run(&three, &["features=xyz"]).is_err());
    assert!(run(&three, &["regions=svc"]).is_err());
    let mut sw = Priors {
        modes: Some(2),
        ..Default::default()
    };
    // Every prior kind is honoured; names are checked.
    sw.switching = vec!["y9".into()];
    let e = run(&sw, &[]).unwrap_err().to_string();
    assert!(e.contains("y9") && e.contains("switching"), "{e}");
}

/// `max_modes` alone: the mode count is chosen by hold-out simulation FIT
/// (the fewest modes within one standard error of the best). On a stable
/// three-mode PWARX switched by the input (noise `U[-0.05, 0.05]`, 600
/// samples), where free-run FIT tells the counts apart, `max_modes = 4`
/// gives 3 modes for every seed. (On B1 the free run is erratic: seed 5
/// scored 67 % with 3 modes and 98 % with 4, so B1 is not used here.)
#[test]
fn max_modes_chooses_the_true_count() {
    let th = [[0.5, 1.0, 0.0], [-0.3, -1.0, 1.0], [0.2, 2.0, -1.0]];
    for seed in 1..=3u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = 600;
        let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut y = vec![0.0; n];
        for k in 1..n {
            let t = th[((u[k - 1] + 1.0) * 1.5).floor().min(2.0) as usize];
            y[k] = t[0] * y[k - 1] + t[1] * u[k - 1] + t[2] + rng.random_range(-0.05..0.05);
        }
        let data = Dataset::siso(u, y, None).unwrap();
        let priors = Priors {
            max_modes: Some(4),
            ..Default::default()
        };
        let problem = Problem {
            data: &data,
            orders: RegressorSpec::new(1, 1, 1),
            priors: &priors,
            priors_origin: None,
        };
        let m = Pwarx(Cluster)
            .run(&problem, &Settings::default(), &RunContext::quiet(1))
            .unwrap();
        let choice = &m.info().diagnostics.method["mode_choice"];
        assert_eq!(m.mode_count(), 3, "seed {seed}: {choice}");
        assert_eq!(choice.as_array().map(Vec::len), Some(4), "{choice}");
    }
}

/// Every option variant runs on B1 and returns a valid model; the
/// pairwise PSVC partition comes with a holes report.
#[test]
fn option_variants_run() {
    let ex = b1(300, 9);
    for set in [
        &["features=lpv"][..],
        &["clustering=single_linkage"],
        &["clustering=single_linkage", "sl_distance=0.5"],
        &["init=plusplus"],
        &["regions=msvm"],
        &["regions=psvc"],
        &[
            "scale=false",
            "weights=confidence",
            "region_refit=false",
            "regions=psvc",
        ],
        &["weights=capped"],
        &["weights=uniform", "reattribute=false", "discard=0"],
    ] {
        // `modes = 3` is exact: three modes, or a model-level failure that
        // says why (single linkage chains B1 into one large cluster and
        // singletons below the discard size; a distance threshold can leave
        // more than three clusters above it), never another mode count.
        let m = match try_identify(&ex.data, ex.truth.spec(), 3, set) {
            Ok(Model::Pwarx(m)) => m,
            Ok(other) => panic!("{set:?}: a {} model", other.kind()),
            Err(e) if set[0] == "clustering=single_linkage" => {
                assert!(
                    matches!(
                        e.downcast_ref::<ClusterError>(),
                        Some(ClusterError::FewerModesFound { asked: 3, .. })
                    ) || (set.contains(&"sl_distance=0.5")
                        && matches!(
                            e.downcast_ref::<ClusterError>(),
                            Some(ClusterError::MoreModesFound { asked: 3, .. })
                        )),
                    "{set:?}: {e}"
                );
                assert!(!e.is_bad_input(), "{set:?}: {e}");
                continue;
            }
            Err(e) => panic!("{set:?}: {e}"),
        };
        assert_eq!(m.modes.len(), 3, "{set:?}");
        Model::Pwarx(m.clone())
            .validate()
            .unwrap_or_else(|e| panic!("{set:?}: {e}"));
        if set.contains(&"regions=psvc") {
            assert!(
                m.info.diagnostics.uncovered_fraction_of_data_box.is_some(),
                "{set:?}"
            );
        }
    }
}

/// The case the property test found (seed kept): a noise-free two-mode
/// PWARX on which every restart of HIT's block initialisation ends in the
/// same wrong optimum, while the default k-means++ recovers the modes.
#[test]
fn kmeans_plusplus_escapes_the_block_initialisation_trap() {
    let th = [[0.0, 0.5, 0.0], [0.0, -0.5, 2.8637975064419523]];
    let mut rng = ChaCha8Rng::seed_from_u64(11232757085378686);
    let n = 300;
    let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        let t = if u[k - 1] < 0.0 { th[0] } else { th[1] };
        y[k] = t[0] * y[k - 1] + t[1] * u[k - 1] + t[2];
    }
    let data = Dataset::siso(u, y, None).unwrap();
    let truth: Vec<Vec<f64>> = th.iter().map(|t| t.to_vec()).collect();
    let good = identify(&data, RegressorSpec::new(1, 1, 1), 2, &[]);
    assert!(
        parameter_error(&truth, &thetas(&good))
            .unwrap()
            .max_relative_error
            < 1e-6
    );
    let hit = identify(&data, RegressorSpec::new(1, 1, 1), 2, &["init=blocks"]);
    assert!(
        parameter_error(&truth, &thetas(&hit))
            .unwrap()
            .max_relative_error
            > 0.5
    );
}

/// A time budget that has run out: one K-means restart, the softmax
/// partition instead of the region program, a complete partition all the
/// same, and the run says where the budget cut it short.
#[test]
fn a_spent_time_budget_still_gives_a_complete_model() {
    let ex = b1(600, 4);
    let priors = Priors {
        modes: Some(3),
        ..Default::default()
    };
    let problem = Problem {
        data: &ex.data,
        orders: ex.truth.spec(),
        priors: &priors,
        priors_origin: None,
    };
    let ctx = RunContext {
        deadline: hysid_core::backend::Deadline::at(std::time::Instant::now()),
        ..RunContext::quiet(1)
    };
    let m = Pwarx(Cluster)
        .run(&problem, &Settings::default(), &ctx)
        .unwrap();
    let d = &m.info().diagnostics;
    assert_eq!(d.run_status, hysid_model::model::RunStatus::TimeBudget);
    assert_eq!(d.regions_complete, Some(true));
    let status = d.status.join("; ");
    assert!(status.contains("K-means restarts"), "{status}");
    assert!(status.contains("mrlp region estimation"), "{status}");
}

/// A progress sink that counts what it is told.
#[derive(Default)]
struct Counted {
    started: std::sync::Mutex<Vec<(u64, String)>>,
    advanced: std::sync::atomic::AtomicU64,
    finished: std::sync::atomic::AtomicU64,
}

impl hysid_core::backend::Progress for Counted {
    fn start(&self, total: u64, what: &str) {
        self.started.lock().unwrap().push((total, what.to_string()));
    }
    fn advance(&self, n: u64) {
        self.advanced
            .fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }
    fn finish(&self) {
        self.finished
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
}

/// A run shows its three steps (clustering, regions, refit) as progress.
#[test]
fn a_run_reports_its_steps_as_progress() {
    use std::sync::atomic::Ordering::Relaxed;
    let ex = b1(300, 2);
    let priors = Priors {
        modes: Some(3),
        ..Default::default()
    };
    let problem = Problem {
        data: &ex.data,
        orders: ex.truth.spec(),
        priors: &priors,
        priors_origin: None,
    };
    let counted = Counted::default();
    let ctx = RunContext {
        progress: &counted,
        ..RunContext::quiet(1)
    };
    Pwarx(Cluster)
        .run(&problem, &Settings::default(), &ctx)
        .unwrap();
    let started = counted.started.lock().unwrap().clone();
    assert_eq!(started.len(), 1, "{started:?}");
    assert_eq!(started[0].0, 3);
    assert_eq!(counted.advanced.load(Relaxed), 3);
    assert_eq!(counted.finished.load(Relaxed), 1);
}
