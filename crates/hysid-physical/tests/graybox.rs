//! The `physical` back-end on gray-box models: parameters recovered from a
//! record simulated with known values, priors by name, the fitted model's
//! kind and diagnostics.

use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_graybox::{CompiledModel, GrayBoxModel, simulate};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use hysid_model::regressors::RegressorSpec;
use hysid_physical::Physical;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::path::PathBuf;

const TS: f64 = 0.01;

fn example(name: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/examples"
    ))
    .join(name)
}

fn ball() -> GrayBoxModel {
    match Model::load(&example("ball-on-table.toml")).unwrap() {
        Model::GrayBox(m) => m,
        other => panic!("kind {}", other.kind()),
    }
}

fn set(m: &mut GrayBoxModel, name: &str, value: f64) {
    let i = m.parameter_index(name).unwrap();
    m.parameters[i].value = value;
}

/// The ball with `truth`'s parameters, driven by random table drives,
/// its height measured with Gaussian noise.
fn record(truth: &GrayBoxModel, n: usize, seed: u64, noise: f64) -> Dataset {
    let ex = Excitation {
        n,
        hold: 60,
        low: -30.0,
        high: 30.0,
        ts: Some(TS),
        inputs: 1,
    };
    let u = ex.generate(seed).remove(0);
    let clean = Dataset::siso(u.clone(), vec![0.0; n], Some(TS)).unwrap();
    let c = CompiledModel::new(truth).unwrap();
    let run = simulate::run(&c, &truth.values(), &clean).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xba11);
    let normal = Normal::new(0.0, noise).unwrap();
    let y = run.y.iter().map(|v| v + normal.sample(&mut rng)).collect();
    Dataset::siso(u, y, Some(TS)).unwrap()
}

fn fit(data: &Dataset, priors: &Priors, file: &str, seed: u64) -> GrayBoxModel {
    let problem = Problem {
        data,
        orders: RegressorSpec::new(2, 2, 1),
        priors,
        priors_origin: None,
    };
    let model = format!("model={file}");
    let settings = Settings::parse(&[model.as_str(), "particles=12", "swarm_iters=15"]).unwrap();
    match Physical
        .run(&problem, &settings, &RunContext::quiet(seed))
        .unwrap()
    {
        Model::GrayBox(m) => m,
        other => panic!("kind {}", other.kind()),
    }
}

/// Restitution, suspension frequency and damping recovered within 5 % from
/// 20 s of noisy heights, starting from the file's nominal values.
#[test]
fn ball_parameters_are_recovered() {
    let mut truth = ball();
    for (n, v) in [("e", 0.62), ("wn", 15.5), ("zeta", 0.21)] {
        set(&mut truth, n, v);
    }
    let data = record(&truth, 2000, 3, 1e-3);
    let fitted = fit(
        &data,
        &Priors::default(),
        example("ball-on-table.toml").to_str().unwrap(),
        1,
    );
    for name in ["e", "wn", "zeta"] {
        let i = truth.parameter_index(name).unwrap();
        let (t, f) = (truth.parameters[i].value, fitted.parameters[i].value);
        let rel = ((f - t) / t).abs();
        eprintln!("{name}: true {t}, fitted {f}, relative error {rel:.4}");
        assert!(rel <= 0.05, "{name}: true {t}, fitted {f}");
    }
    assert_eq!(fitted.info.method, "physical");
    let diagnostics = &fitted.info.diagnostics.method;
    assert_eq!(diagnostics["free_parameters"], 3);
    // Fixed parameters stay, and the fitted file reads back.
    let g = fitted.parameters[fitted.parameter_index("g").unwrap()].value;
    assert_eq!(g, 9.81);
    let text = Model::GrayBox(fitted).to_json();
    assert!(matches!(
        Model::from_json(&text, "fitted.json").unwrap(),
        Model::GrayBox(_)
    ));
}

/// Priors by parameter name: a fixed value is kept exactly, a bound is
/// honoured, and an unknown name is refused with the names the model has.
#[test]
fn priors_name_gray_box_parameters() {
    let truth = ball();
    let data = record(&truth, 600, 5, 1e-3);
    let file = example("ball-on-table.toml");
    let priors =
        Priors::from_toml("[fixed]\nzeta = 0.3\n[bounds]\ne = [0.5, 0.7]\n", "p.toml").unwrap();
    let fitted = fit(&data, &priors, file.to_str().unwrap(), 2);
    let value = |n: &str| fitted.parameters[fitted.parameter_index(n).unwrap()].value;
    assert_eq!(value("zeta"), 0.3);
    assert!((0.5..=0.7).contains(&value("e")), "e = {}", value("e"));

    let bad = Priors::from_toml("[fixed]\nrestitution = 0.3\n", "p.toml").unwrap();
    let problem = Problem {
        data: &data,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &bad,
        priors_origin: None,
    };
    let model = format!("model={}", file.display());
    let e = Physical
        .run(
            &problem,
            &Settings::parse(&[model.as_str()]).unwrap(),
            &RunContext::quiet(1),
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("restitution") && e.contains("wn"), "{e}");
}
