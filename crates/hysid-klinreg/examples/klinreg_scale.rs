//! Cost of k-LinReg against N on B1 (3 modes, na = nb = 1, u uniform in
//! [-4, 4], uniform noise 0.1): the restarts alone (steps 1-4, in parallel)
//! and the whole back-end with the softmax and the MRLP region steps, with
//! the mode accuracy of its regions on a fresh draw of 10^4 samples.
//! Figures in docs/klinreg.md ("Cost").
//!
//! Run: cargo run --release -p hysid-klinreg --example klinreg_scale [N ...]

use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::constrained::Parametrisation;
use hysid_estimation::pwarx;
use hysid_estimation::pwarx::Pwarx;
use hysid_klinreg::{KLinReg, KLinRegOptions, best_restart, restart_count};
use hysid_model::regressors::RegressorSpec;
use hysid_testkit::Noise;
use std::time::Instant;

fn main() {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() {
        vec![10_000, 100_000, 1_000_000]
    } else {
        sizes
    };
    println!(
        "| N | restarts | restarts (s) | back-end, softmax regions (s) (mode accuracy) | back-end, MRLP regions (s) (mode accuracy) |"
    );
    println!("|---|---|---|---|---|");
    for n in sizes {
        let b = hysid_testkit::b1(n, 4.0, Noise::Uniform(0.1), 1);
        let fresh = hysid_testkit::b1(10_000, 4.0, Noise::Uniform(0.1), 2);
        let priors = Priors {
            modes: Some(3),
            ..Priors::default()
        };
        let problem = Problem {
            data: &b.data,
            orders: RegressorSpec::new(1, 1, 1),
            priors: &priors,
            priors_origin: None,
        };
        let data = pwarx::prepare(&problem, "klinreg").expect("prepared");
        let reg = data.ordinary_regressors();
        let par = Parametrisation::from_priors(&priors, &data.spec, 3).expect("priors");
        let planned = restart_count(reg.x.nrows(), 3, 3).max(hysid_klinreg::DEFAULT_MIN_RESTARTS);
        let t = Instant::now();
        let r = best_restart(
            &reg,
            &par,
            3,
            planned,
            &KLinRegOptions::default(),
            &RunContext::quiet(1),
        );
        let restarts = t.elapsed().as_secs_f64();
        assert!(r.best.is_some());
        let whole = |regions: &str| {
            let settings = Settings::from_pairs(vec![("regions".into(), regions.into())]);
            let t = Instant::now();
            let model = Pwarx(KLinReg)
                .run(&problem, &settings, &RunContext::quiet(1))
                .expect("identified");
            let wall = t.elapsed().as_secs_f64();
            let Model::Pwarx(p) = model else {
                panic!("a PWARX model")
            };
            (wall, fresh.recovery(&p).0)
        };
        let (softmax, softmax_accuracy) = whole("softmax");
        let (mrlp, mrlp_accuracy) = whole("mrlp");
        println!(
            "| {n} | {planned} | {restarts:.2} | {softmax:.2} ({softmax_accuracy:.4}) | {mrlp:.2} ({mrlp_accuracy:.4}) |"
        );
    }
}
