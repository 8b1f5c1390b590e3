//! The worked example back-end through the plugin contract: noise-free
//! data of a PWARX system that switches on the sign of `u(k-1)` give back
//! its parameters; priors hold; bad options and mode counts are refused.

use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{ModelInfo, PwarxMode, PwarxModel};
use hysid_sign::Sign;
use hysid_testkit::{Noise, generate};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const TRUTH: [[f64; 3]; 2] = [[0.5, 1.0, 0.2], [-0.3, -2.0, 1.0]];

/// `y(k) = theta_q . [y(k-1), u(k-1), 1]`, mode 0 for `u(k-1) < 0`.
fn record(n: usize, seed: u64) -> hysid_testkit::Benchmark {
    let mode = |theta: [f64; 3], sign: f64| PwarxMode {
        theta: theta.to_vec(),
        region: Polyhedron::from_inequalities(vec![vec![0.0, sign]], vec![0.0]),
        name: None,
    };
    let truth = PwarxModel {
        na: 1,
        nb: 1,
        inputs: 1,
        modes: vec![mode(TRUTH[0], 1.0), mode(TRUTH[1], -1.0)],
        info: ModelInfo::default(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
    generate(truth, vec![u], &[0.0], Noise::None, &mut rng)
}

fn run(priors: &Priors, set: &[&str]) -> Result<Model, IdentifyError> {
    let b = record(200, 3);
    let problem = Problem {
        data: &b.data,
        orders: b.truth.spec(),
        priors,
        priors_origin: None,
    };
    Sign.run(
        &problem,
        &Settings::parse(set).unwrap(),
        &RunContext::quiet(1),
    )
}

fn thetas(m: &Model) -> Vec<Vec<f64>> {
    match m {
        Model::Pwarx(p) => p.modes.iter().map(|q| q.theta.clone()).collect(),
        _ => panic!("not a PWARX model"),
    }
}

#[test]
fn noise_free_parameters_are_recovered() {
    let m = run(&Priors::default(), &[]).unwrap();
    for (got, want) in thetas(&m).iter().zip(TRUTH) {
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 1e-9, "{got:?} vs {want:?}");
        }
    }
    let d = &m.info().diagnostics;
    assert_eq!((d.modes, d.regions_complete), (Some(2), Some(true)));
    assert_eq!(d.method["samples_per_mode"].as_array().unwrap().len(), 2);
}

#[test]
fn a_tie_holds_in_both_modes() {
    let priors = Priors::from_toml("[[tie]]\nparams = [\"a1\"]\n", "p.toml").unwrap();
    let t = thetas(&run(&priors, &[]).unwrap());
    assert_eq!(t[0][0], t[1][0]);
}

#[test]
fn bad_options_and_mode_counts_are_refused() {
    let e = run(&Priors::default(), &["threshold=inf"]).unwrap_err();
    assert!(matches!(e, IdentifyError::Options(_)), "{e}");
    let three = Priors {
        modes: Some(3),
        ..Default::default()
    };
    let e = run(&three, &[]).unwrap_err().to_string();
    assert!(e.contains("exactly two"), "{e}");
}
