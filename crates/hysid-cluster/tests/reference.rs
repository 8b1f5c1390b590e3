//! The reference examples of `hysid_cluster::systems` with their exact
//! parameters and fixed seeds, through the whole back-end (regions
//! included).

use hysid_cluster::Cluster;
use hysid_cluster::systems::{self, Example};
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_model::metrics::{mode_accuracy, parameter_error};
use hysid_model::model::PwarxModel;

fn identify(ex: &Example, modes: usize, set: &[&str], seed: u64) -> PwarxModel {
    let priors = Priors {
        modes: Some(modes),
        ..Default::default()
    };
    let problem = Problem {
        data: &ex.data,
        orders: ex.orders,
        priors: &priors,
        priors_origin: None,
    };
    match Cluster
        .run(
            &problem,
            &Settings::parse(set).unwrap(),
            &RunContext::quiet(seed),
        )
        .unwrap()
    {
        Model::Pwarx(m) => m,
        _ => unreachable!(),
    }
}

/// Mode accuracy of the model's regions on the example's regressors, and
/// the largest relative parameter error after matching.
fn score(ex: &Example, m: &PwarxModel) -> (f64, f64) {
    let reg = ex.orders.build(&ex.data).unwrap();
    let ident: Vec<usize> = (0..reg.len())
        .map(|r| {
            m.mode_of(&reg.x.row(r).iter().copied().collect::<Vec<_>>())
                .mode
        })
        .collect();
    let acc = mode_accuracy(&ex.modes, &ident).accuracy;
    let theta: Vec<Vec<f64>> = m.modes.iter().map(|q| q.theta.clone()).collect();
    (acc, parameter_error(&ex.theta, &theta).max_relative_error)
}

/// Parameter error of the oracle: least squares on the true mode datasets
/// of the identification record (the best any method can do from these
/// samples without knowing the parameters).
fn oracle_error(ex: &Example) -> f64 {
    let reg = ex.orders.build(&ex.data).unwrap();
    let phi = reg.phi();
    let theta: Vec<Vec<f64>> = (0..ex.mode_count())
        .map(|i| {
            let rows: Vec<usize> = (0..reg.len()).filter(|&r| ex.modes[r] == i).collect();
            let sol =
                hysid_estimation::linalg::lstsq(&phi.select_rows(&rows), &reg.y.select_rows(&rows))
                    .unwrap();
            sol.theta.iter().copied().collect()
        })
        .collect();
    parameter_error(&ex.theta, &theta).max_relative_error
}

/// Validation mode accuracy, parameter error and the oracle's parameter error.
fn report(name: &str, ex: &Example, valid: &Example, m: &PwarxModel) -> (f64, f64, f64) {
    let oracle = oracle_error(ex);
    eprintln!("{name}: oracle parameter error {oracle:.3}");
    let (acc, perr) = score(valid, m);
    let (acc_id, _) = score(ex, m);
    eprintln!(
        "{name}: validation mode accuracy {acc:.3}, identification {acc_id:.3}, parameter error {perr:.3}, diagnostics {:?}",
        m.info.diagnostics
    );
    (acc, perr, oracle)
}

#[test]
fn b1_classic_three_mode_pwarx() {
    let ex = systems::b1(1000, 11);
    let valid = systems::b1(1000, 12);
    let m = identify(&ex, 3, &[], 1);
    let (acc, perr, _) = report("B1", &ex, &valid, &m);
    assert!(acc >= 0.95, "mode accuracy {acc}");
    assert!(perr <= 0.05, "parameter error {perr}");
    assert_eq!(m.info.diagnostics["regions_complete"], true);
}

#[test]
fn h1_equal_parameters_on_two_regions() {
    let ex = systems::h1(70, 21);
    let valid = systems::h1(1000, 22);
    let c = ex.c.to_string();
    let m = identify(&ex, 3, &[&format!("c={c}")], 1);
    let (acc, perr, oracle) = report("H1", &ex, &valid, &m);
    assert_eq!(m.modes.len(), 3);
    assert!(acc >= 0.95, "mode accuracy {acc}");
    assert!(
        perr <= oracle + 0.1,
        "parameter error {perr} (oracle {oracle})"
    );
}

#[test]
fn h2_five_modes() {
    let ex = systems::h2(100, 31);
    let valid = systems::h2(1000, 32);
    let m = identify(&ex, 5, &[&format!("c={}", ex.c)], 1);
    let (acc, perr, oracle) = report("H2", &ex, &valid, &m);
    assert!(acc >= 0.95, "mode accuracy {acc}");
    assert!(
        perr <= oracle + 0.1,
        "parameter error {perr} (oracle {oracle})"
    );
}

#[test]
fn h3_two_dimensional_repeated_parameters() {
    let ex = systems::h3(60, 41);
    let valid = systems::h3(1000, 42);
    let m = identify(&ex, 3, &[&format!("c={}", ex.c)], 1);
    let (acc, perr, oracle) = report("H3", &ex, &valid, &m);
    assert!(acc >= 0.9, "mode accuracy {acc}");
    assert!(
        perr <= oracle + 0.45,
        "parameter error {perr} (oracle {oracle})"
    );
}

#[test]
fn h4_static_three_wedges() {
    let ex = systems::h4(60, 51);
    let valid = systems::h4(1000, 52);
    let m = identify(&ex, 3, &[&format!("c={}", ex.c)], 1);
    let (acc, perr, oracle) = report("H4", &ex, &valid, &m);
    assert!(acc >= 0.95, "mode accuracy {acc}");
    assert!(
        perr <= oracle + 0.15,
        "parameter error {perr} (oracle {oracle})"
    );
}
