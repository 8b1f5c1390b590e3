//! Parameters recovered from data simulated from
//! `head.toml` with known parameters, both saturations excited and
//! measurement noise added; `fit_sim` on a fresh validation record.

use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_mechanical::simulate as mechanical;
use hysid_mechanical::{MechanicalInitialState, MechanicalModel};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use hysid_model::regressors::RegressorSpec;
use hysid_physical::{Physical, head_model};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const TS: f64 = 0.0025; // 400 Hz, as the decimated record

/// The head with "true" parameters away from the nominal ones (close to a
/// fit on the real record), the lower stop inside its bounds.
fn truth() -> MechanicalModel {
    let mut m = head_model();
    let set = [
        ("ku", -1.46e5),
        ("f0", -1870.0),
        ("c1", 663.0),
        ("d1", 8.7),
        ("f1", 404.0),
        ("fs", 682.0),
        ("c2", 516.0),
        ("d2", 10.7),
        ("f2", 830.0),
        ("yc", 12.14),
        ("y_low", 24.8),
    ];
    for (n, v) in set {
        let i = m.parameter_index(n).unwrap();
        m.parameters[i].value = v;
    }
    m.validate().unwrap();
    m
}

/// Noise-free simulation from rest at the upper stop (y = 0, v = 0).
fn from_rest(m: &MechanicalModel, u: &[f64]) -> mechanical::MechanicalRun {
    let mut m = m.clone();
    m.initial_state = MechanicalInitialState::Given {
        position: 0.0,
        velocity: 0.0,
    };
    let d = Dataset::siso(u.to_vec(), vec![0.0; u.len()], Some(TS)).unwrap();
    mechanical::run(&m, &m.values(), &d).unwrap()
}

/// A record driven by the paper's input (random levels held 0.3 s), from
/// rest at the upper stop, with Gaussian measurement noise.
fn record(m: &MechanicalModel, n: usize, seed: u64, noise: f64) -> Dataset {
    let ex = Excitation {
        n,
        hold: 120,
        low: -0.2,
        high: 0.0,
        ts: Some(TS),
        inputs: 1,
    };
    let u = ex.generate(seed).remove(0);
    let run = from_rest(m, &u);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let normal = Normal::new(0.0, noise).unwrap();
    let y = run.y.iter().map(|v| v + normal.sample(&mut rng)).collect();
    Dataset::siso(u, y, Some(TS)).unwrap()
}

#[test]
fn recovers_parameters_and_validates() {
    let truth = truth();
    // 20 s at 400 Hz: 66 random levels, enough for free sliding in both
    // directions (with 10 s, f0 and f1 are only weakly separable and the fit
    // lands in a neighbouring optimum).
    let ident = record(&truth, 8000, 11, 0.02);
    // Both saturations are excited in the identification record.
    let clean = from_rest(&truth, ident.u(0));
    let names = Model::Mechanical(truth.clone()).mode_names();
    let count = |name: &str| {
        clean
            .modes
            .iter()
            .filter(|q| q.map(|q| names[q] == name).unwrap_or(false))
            .count()
    };
    let (us, ls) = (count("upper_saturation"), count("lower_saturation"));
    assert!(
        us > 50 && ls > 50,
        "saturations excited: upper {us}, lower {ls} samples"
    );

    let priors = Priors::default();
    let problem = Problem {
        data: &ident,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &priors,
        priors_origin: None,
    };
    let model = Physical
        .run(
            &problem,
            &Settings::parse(&[crate::HEAD_MODEL_SET]).unwrap(),
            &RunContext::quiet(7),
        )
        .unwrap();
    eprintln!(
        "cost at truth {:.6}, fitted {:.6}, evals {}",
        hysid_physical::objective::simulation_mse(
            &hysid_physical::GrayBoxTarget::new(hysid_core::model::to_gray_box(&truth).unwrap())
                .unwrap(),
            &truth.values(),
            std::slice::from_ref(&ident)
        ),
        model.info().diagnostics.method["cost"],
        model.info().diagnostics.method["evaluations"]
    );
    let Model::Mechanical(fitted) = &model else {
        panic!("kind {}", model.kind())
    };
    let counts: Vec<(String, usize)> = names.iter().map(|n| (n.clone(), count(n))).collect();
    eprintln!("modes in the clean identification record: {counts:?}");
    let mut worst = (0.0f64, String::new());
    for (p, t) in fitted.parameters.iter().zip(&truth.parameters) {
        if t.fixed {
            assert_eq!(p.value, t.value);
            continue;
        }
        let rel = ((p.value - t.value) / t.value).abs();
        eprintln!(
            "{:6} true {:>12.4} fitted {:>12.4} rel {:.4}",
            p.name, t.value, p.value, rel
        );
        if rel > worst.0 {
            worst = (rel, p.name.clone());
        }
    }
    assert!(
        worst.0 <= 0.05,
        "worst relative error {:.4} on {}",
        worst.0,
        worst.1
    );
    let fresh = record(&truth, 2000, 99, 0.02);
    let (rep, _, _) = hysid_core::simulate::validate(&model, &fresh, 10).unwrap();
    eprintln!("fit_sim on a fresh record: {:.2} %", rep.fit_sim);
    assert!(rep.fit_sim >= 97.0, "fit_sim {:.2}", rep.fit_sim);
}
