//! Known stops on a record of the mechanical simulator, as a sensor gives
//! it: Gaussian noise of 0.005 mm on every sample (at the stops too) and
//! positions rounded to 0.01 mm. The prior names each stop with
//! `tol = 0.02` mm (four noise standard deviations, two quanta); the
//! published procedures of `cluster` and `bounded` (`preset=paper`) then
//! find the samples at the stops, never simulate past them, and simulate
//! the test rows better than without the prior; every back-end that
//! declares the prior finds and holds the stops too.

use hysid_core::backend::{Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::simulate::{simulate, validate};
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::SimulationOptions;
use hysid_testkit::SimulatedHead;

const STOPS: &str = "[[saturation]]\nlevel = 0.0\nbound = \"min\"\ntol = 0.02\n\
                     [[saturation]]\nlevel = 25.0\nbound = \"max\"\ntol = 0.02\n";

fn identify(
    method: &str,
    data: &hysid_model::data::Dataset,
    priors: &Priors,
    set: &[&str],
) -> Model {
    let problem = Problem {
        data,
        orders: RegressorSpec::new(2, 2, 1),
        priors,
        priors_origin: Some("p.toml"),
    };
    hysid::registry()
        .get(method)
        .unwrap()
        .run(
            &problem,
            &Settings::parse(set).unwrap(),
            &RunContext::quiet(1),
        )
        .unwrap_or_else(|e| panic!("{method}: {e}"))
}

/// The samples truly held at the upper and the lower stop among the
/// regression targets of a record whose true modes are `truth` (samples
/// 2.., na = nb = 2).
fn held_at_stops(truth: &[Option<String>]) -> [usize; 2] {
    let count = |name: &str| {
        (truth[2..].iter())
            .filter(|m| m.as_deref() == Some(name))
            .count()
    };
    [count("upper_saturation"), count("lower_saturation")]
}

/// Asserts that `model` found the samples at the stops to within 3 % of
/// `held`, and never simulates `test` past a stop.
fn assert_stops_found_and_held(
    method: &str,
    model: &Model,
    held: [usize; 2],
    test: &hysid_model::data::Dataset,
) {
    let found = model.info().diagnostics.saturated_per_stop.clone().unwrap();
    for (stop, (&f, &t)) in found.iter().zip(&held).enumerate() {
        let off = (f as f64 - t as f64).abs() / t as f64;
        assert!(
            off <= 0.03,
            "{method}: stop {stop}: {f} samples found, {t} true"
        );
    }
    let sim = simulate(model, test, SimulationOptions::for_data(test)).unwrap();
    for &y in &sim.y[sim.start..] {
        assert!(
            (0.0..=25.0).contains(&y),
            "{method}: simulated {y} past a stop"
        );
    }
}

#[test]
fn stops_are_found_held_and_help_on_a_noisy_quantised_record() {
    let record = SimulatedHead::read("both-saturations.csv", 0.01);
    let (ident, truth) = record.rows(0..4000);
    let (test, _) = record.rows(4000..6000);
    let true_at_stops = held_at_stops(&truth);
    // The published procedures, as the simulated-head experiments run
    // them (models/pick-and-place/simulated/both.toml). With cluster's
    // default alternation the model without the stops scores 93.3 % here,
    // above the 91.9 % with them: the alternation already separates the
    // saturated samples.
    for (method, modes, set) in [
        ("cluster", 4, &["c=40", "preset=paper"][..]),
        ("bounded", 0, &["delta=0.02", "preset=paper"][..]),
    ] {
        let count = if modes > 0 {
            format!("modes = {modes}\n")
        } else {
            String::new()
        };
        let with = Priors::from_toml(&format!("{count}{STOPS}"), "p.toml").unwrap();
        let without = Priors::from_toml(&count, "p.toml").unwrap();
        let model = identify(method, &ident, &with, set);
        assert_stops_found_and_held(method, &model, true_at_stops, &test);
        let found = model.info().diagnostics.saturated_per_stop.clone().unwrap();
        let score = |m: &Model| validate(m, &test, 10).unwrap().0.fit_sim;
        let (fit_with, fit_without) = (
            score(&model),
            score(&identify(method, &ident, &without, set)),
        );
        eprintln!(
            "{method}: stop samples {found:?} of {true_at_stops:?}; fit_sim {fit_with:.2} % with the stops, {fit_without:.2} % without"
        );
        assert!(
            fit_with > fit_without,
            "{method}: {fit_with} with, {fit_without} without"
        );
    }
}

/// Every back-end that declares the `[[saturation]]` prior, with its
/// defaults and the same prior (the stops, and four modes in all with the
/// stops counted; arx: its one ordinary mode): the samples at the stops
/// are found to within 3 %, and the model never simulates past them.
/// `milp`'s exact program takes at most 40 ordinary samples: it runs on
/// rows 100..160 (23 ordinary samples, 35 at the stops).
#[test]
fn every_back_end_declaring_stops_finds_and_holds_them() {
    let record = SimulatedHead::read("both-saturations.csv", 0.01);
    let (test, _) = record.rows(4000..6000);
    let registry = hysid::registry();
    let declaring: Vec<&str> = (registry.names().into_iter())
        .filter(|m| {
            let honours = registry.get(m).unwrap().honours();
            honours.contains(&hysid_core::priors::PriorKind::Saturation)
        })
        .collect();
    assert_eq!(
        declaring,
        [
            "arx", "cluster", "bounded", "klinreg", "parc", "bayes", "milp"
        ]
    );
    for method in declaring {
        let (ident, truth) = record.rows(if method == "milp" { 100..160 } else { 0..4000 });
        let modes = if method == "arx" { 3 } else { 4 };
        let with = Priors::from_toml(&format!("modes = {modes}\n{STOPS}"), "p.toml").unwrap();
        let model = identify(method, &ident, &with, &[]);
        assert_stops_found_and_held(method, &model, held_at_stops(&truth), &test);
    }
}
