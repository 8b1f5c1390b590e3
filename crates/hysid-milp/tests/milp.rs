//! The exact programs: the true parameters of a noise-free record, the l1
//! optimum never above the l1 cost of the truth or of k-LinReg's model, no
//! error-bounded partition of the greedy `bounded` back-end with fewer
//! modes than the exact minimum, priors, limits and refusals.

use hysid_bounded::Bounded;
use hysid_core::backend::{Backend, IdentifyError};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::{Priors, Tie};
use hysid_estimation::pwarx::Pwarx;
use hysid_klinreg::KLinReg;
use hysid_milp::Milp;
use hysid_model::regressors::Regressors;
use hysid_testkit::{Benchmark, Noise, as_pwarx};
use proptest::prelude::*;

fn priors(modes: Option<usize>) -> Priors {
    Priors {
        modes,
        ..Priors::default()
    }
}

fn run(
    backend: &dyn Backend,
    b: &Benchmark,
    priors: &Priors,
    set: &[&str],
) -> Result<Model, IdentifyError> {
    b.run(backend, priors, &Settings::parse(set).unwrap(), 1)
}

/// The regression rows of `b`.
fn rows(b: &Benchmark) -> Regressors {
    b.truth.spec().build(&b.data).unwrap()
}

/// `sum_k min_i |y_k - theta_i . [x_k; 1]|`.
fn l1_cost(reg: &Regressors, thetas: &[Vec<f64>]) -> f64 {
    let d = reg.x.ncols();
    (0..reg.len())
        .map(|k| {
            thetas
                .iter()
                .map(|t| {
                    (reg.y[k] - t[d] - (0..d).map(|j| t[j] * reg.x[(k, j)]).sum::<f64>()).abs()
                })
                .fold(f64::INFINITY, f64::min)
        })
        .sum()
}

fn thetas(m: &Model) -> Vec<Vec<f64>> {
    as_pwarx(m).modes.iter().map(|q| q.theta.clone()).collect()
}

fn diagnostic(m: &Model, key: &str) -> serde_json::Value {
    m.info().diagnostics.method[key].clone()
}

/// A noise-free B1 record of 16 samples: the optimum has zero error and
/// the true parameters, to 1e-6, proven optimal.
#[test]
fn noise_free_b1_gives_the_true_parameters() {
    let b = hysid_testkit::b1(17, 4.0, Noise::None, 2);
    let m = run(&Pwarx(Milp), &b, &priors(Some(3)), &[]).unwrap();
    assert!(diagnostic(&m, "l1_error").as_f64().unwrap() < 1e-7);
    assert_eq!(diagnostic(&m, "proven_optimal"), true);
    let (_, error) = b.recovery(as_pwarx(&m));
    assert!(error < 1e-6, "largest relative parameter error {error}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// The exact l1 optimum with B1's three modes is never above the l1
    /// cost of the true parameters nor of k-LinReg's (least-squares) modes
    /// on the same rows (at least the 9 rows of the modes' parameters:
    /// fewer are refused before any fit).
    #[test]
    fn the_optimum_is_below_the_truth_and_the_heuristic(
        seed in 0u64..1000,
        n in 9usize..13,
        noise in 0.0f64..0.3,
    ) {
        let b = hysid_testkit::b1(n + 1, 4.0, Noise::Uniform(noise), seed);
        let reg = rows(&b);
        let m = run(&Pwarx(Milp), &b, &priors(Some(3)), &[]).unwrap();
        let optimum = diagnostic(&m, "l1_error").as_f64().unwrap();
        prop_assert!((l1_cost(&reg, &thetas(&m)) - optimum).abs() < 1e-6 * (1.0 + optimum));
        let truth: Vec<Vec<f64>> = b.truth.modes.iter().map(|q| q.theta.clone()).collect();
        prop_assert!(optimum <= l1_cost(&reg, &truth) + 1e-7, "optimum {optimum} above the truth");
        if let Ok(k) = run(&Pwarx(KLinReg), &b, &priors(Some(3)), &[]) {
            let heuristic = l1_cost(&reg, &thetas(&k));
            prop_assert!(optimum <= heuristic + 1e-7, "optimum {optimum} above k-LinReg's {heuristic}");
        }
    }

    /// With an error bound, the exact solution keeps every sample within it,
    /// and the greedy MIN PFS of the `bounded` back-end, whenever it explains
    /// every sample, uses at least the exact minimum of modes (about a third
    /// of the draws; on the others it leaves samples unexplained).
    #[test]
    fn the_greedy_partition_never_beats_the_exact_minimum(
        seed in 0u64..1000,
        n in 8usize..15,
        delta in 0.05f64..1.0,
    ) {
        let b = hysid_testkit::b1(n + 1, 4.0, Noise::Uniform(0.05), seed);
        let reg = rows(&b);
        let set = format!("delta={delta}");
        let exact = run(&Pwarx(Milp), &b, &priors(None), &[set.as_str()]).unwrap();
        let minimum = diagnostic(&exact, "fewest_modes").as_u64().unwrap() as usize;
        prop_assert_eq!(as_pwarx(&exact).modes.len(), minimum);
        let within = |thetas: &[Vec<f64>]| {
            let d = reg.x.ncols();
            (0..reg.len()).all(|k| thetas.iter().any(|t| {
                (reg.y[k] - t[d] - (0..d).map(|j| t[j] * reg.x[(k, j)]).sum::<f64>()).abs()
                    <= delta * (1.0 + 1e-6)
            }))
        };
        prop_assert!(within(&thetas(&exact)));
        if let Ok(g) = run(&Pwarx(Bounded), &b, &priors(None), &[set.as_str(), "refine=none"]) {
            let greedy = diagnostic(&g, "greedy_modes").as_u64().unwrap() as usize;
            if diagnostic(&g, "infeasible") == 0 {
                prop_assert!(greedy >= minimum, "bounded's greedy {greedy} modes, exact minimum {minimum}");
            }
        }
    }
}

/// Ties share one value across the modes and fixed values come back
/// exactly.
#[test]
fn ties_and_fixed_values_hold() {
    let b = hysid_testkit::b1(13, 4.0, Noise::Uniform(0.05), 4);
    let mut p = priors(Some(2));
    p.tie.push(Tie {
        params: vec!["b1".into()],
    });
    p.fixed.insert("a1".into(), 0.1);
    let m = run(&Pwarx(Milp), &b, &p, &[]).unwrap();
    let t = thetas(&m);
    assert_eq!(t[0][1].to_bits(), t[1][1].to_bits());
    assert!(t.iter().all(|q| q[0] == 0.1));
}

/// Records above `max_samples`, and runs with neither a mode count nor a
/// bound, are refused with a typed error.
#[test]
fn refusals() {
    let b = hysid_testkit::b1(60, 4.0, Noise::Uniform(0.05), 1);
    let e = run(&Pwarx(Milp), &b, &priors(Some(2)), &[]).unwrap_err();
    assert!(e.to_string().contains("max_samples = 40"), "{e}");
    let small = hysid_testkit::b1(10, 4.0, Noise::Uniform(0.05), 1);
    let e = run(&Pwarx(Milp), &small, &priors(None), &[]).unwrap_err();
    assert!(
        matches!(e, IdentifyError::NeedsModeCount { method: "milp", .. }),
        "{e}"
    );
    // A bound outside the parameters' box names its entry; a fixed value
    // is not a variable of the program, whatever its bounds.
    let boxed = |fixed: bool| {
        let mut p = priors(Some(2));
        p.bounds.insert("c".into(), [200.0, 300.0]);
        if fixed {
            p.fixed.insert("c".into(), 250.0);
        }
        run(&Pwarx(Milp), &small, &p, &["theta_max=100"])
    };
    let e = boxed(false).unwrap_err();
    assert!(
        e.to_string()
            .contains("[bounds] c = [200, 300] lies outside [-theta_max, theta_max] = [-100, 100]"),
        "{e}"
    );
    if let Err(e) = boxed(true) {
        assert!(!e.to_string().contains("theta_max"), "{e}");
    }
}

/// A node limit of one ends branch and bound early: the model is the best
/// found, marked as not proven optimal.
#[test]
fn the_node_limit_bounds_the_search() {
    let b = hysid_testkit::b1(21, 4.0, Noise::Uniform(0.1), 3);
    let m = run(&Pwarx(Milp), &b, &priors(Some(3)), &["node_limit=1"]);
    match m {
        Ok(m) => assert_eq!(diagnostic(&m, "proven_optimal"), false),
        Err(e) => assert!(e.to_string().contains("before a first solution"), "{e}"),
    }
}
