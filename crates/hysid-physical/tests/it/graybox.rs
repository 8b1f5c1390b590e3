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

fn load(name: &str) -> GrayBoxModel {
    match Model::load(&example(name)).unwrap() {
        Model::GrayBox(m) => m,
        other => panic!("kind {}", other.kind()),
    }
}

fn ball() -> GrayBoxModel {
    load("ball-on-table.toml")
}

fn set(m: &mut GrayBoxModel, name: &str, value: f64) {
    let i = m.parameter_index(name).unwrap();
    m.parameters[i].value = value;
}

/// A random-level input held `hold` samples in `[low, high]`.
fn drive(n: usize, hold: usize, low: f64, high: f64) -> Excitation {
    Excitation {
        n,
        hold,
        low,
        high,
        ts: Some(TS),
        inputs: 1,
    }
}

/// The ball with `truth`'s parameters, driven by random table drives,
/// its height measured with Gaussian noise.
fn record(truth: &GrayBoxModel, n: usize, seed: u64, noise: f64) -> Dataset {
    simulated(truth, &drive(n, 60, -30.0, 30.0), seed, noise)
}

/// `truth` driven by `ex`, its output measured with Gaussian noise.
fn simulated(truth: &GrayBoxModel, ex: &Excitation, seed: u64, noise: f64) -> Dataset {
    let n = ex.n;
    let u = ex.generate(seed).remove(0);
    let clean = Dataset::siso(u.clone(), vec![0.0; n], Some(TS)).unwrap();
    let c = CompiledModel::new(truth).unwrap();
    let run = simulate::run(&c, &truth.values(), &clean).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xba11);
    let normal = Normal::new(0.0, noise).unwrap();
    let y = run.y.iter().map(|v| v + normal.sample(&mut rng)).collect();
    Dataset::siso(u, y, Some(TS)).unwrap()
}

/// The search of the recovery tests: a small swarm.
const SMALL_SEARCH: [&str; 2] = ["particles=12", "swarm_iters=15"];

/// `file` fitted on `data` under `priors` with the options `settings`.
fn fit(data: &Dataset, priors: &Priors, file: &str, settings: &[&str], seed: u64) -> GrayBoxModel {
    let problem = Problem {
        data,
        orders: RegressorSpec::new(2, 2, 1),
        priors,
        priors_origin: None,
    };
    let model = format!("model={file}");
    let mut all = vec![model.as_str()];
    all.extend(settings);
    match Physical
        .run(
            &problem,
            &Settings::parse(&all).unwrap(),
            &RunContext::quiet(seed),
        )
        .unwrap()
    {
        Model::GrayBox(m) => m,
        other => panic!("kind {}", other.kind()),
    }
}

/// Every free parameter of `truth` recovered within 5 % from `data` by the
/// small search, starting from the nominal values of the example file
/// `file`.
fn recovers(truth: &GrayBoxModel, data: &Dataset, file: &str) -> GrayBoxModel {
    recovers_within(truth, data, file, &SMALL_SEARCH, 0.05)
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
    let fitted = recovers(&truth, &data, "ball-on-table.toml");
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

/// Two masses: input gain, both springs, the damper of mass 1 and the gap
/// recovered from 30 s of the first mass's position. Long (half a minute to
/// a minute in the test profile): `cargo test -p hysid-physical --test it
/// -- --ignored` runs it.
#[test]
#[ignore = "long recovery fit: cargo test -p hysid-physical --test it -- --ignored"]
fn two_mass_parameters_are_recovered() {
    let mut truth = load("two-masses.toml");
    for (n, v) in [
        ("b", 1.4),
        ("k1", 55.0),
        ("d1", 1.6),
        ("k2", 120.0),
        ("gap", 0.07),
    ] {
        set(&mut truth, n, v);
    }
    let data = simulated(&truth, &drive(3000, 100, -2.0, 6.0), 4, 1e-4);
    recovers(&truth, &data, "two-masses.toml");
}

/// The drive: torque gain, both viscous frictions, the shaft stiffness and
/// the backlash recovered from 30 s of the load angle. Long (one to two
/// minutes in the test profile): `cargo test -p hysid-physical --test it --
/// --ignored` runs it. It fails: the fit ends at a local minimum of the cost
/// near the truth, `dl` 8 % low (docs/physical.md, "Recovery").
#[test]
#[ignore = "long recovery fit, failing: the fit ends at a local minimum near the truth (docs/physical.md, Recovery)"]
fn backlash_parameters_are_recovered() {
    let mut truth = load("backlash-drive.toml");
    for (n, v) in [
        ("b", 13.0),
        ("dm", 2.6),
        ("dl", 0.7),
        ("k", 420.0),
        ("bl", 0.035),
    ] {
        set(&mut truth, n, v);
    }
    let data = simulated(&truth, &drive(3000, 80, -1.0, 1.0), 5, 1e-4);
    recovers(&truth, &data, "backlash-drive.toml");
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
    let fitted = fit(&data, &priors, file.to_str().unwrap(), &SMALL_SEARCH, 2);
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

/// The bridge of the gray-box head gives the mechanical bridge's modes: the
/// same ARX(2,2) parameters for each sliding direction, free and in
/// contact, and the same stick and stop modes.
#[test]
fn gray_box_head_bridges_as_the_mechanical_head() {
    use hysid_physical::bridge::{graybox_to_pwarx, to_pwarx};
    let path = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/pick-and-place/head-graybox.toml"
    ));
    let Model::GrayBox(g) = Model::load(&path).unwrap() else {
        panic!("a gray-box file")
    };
    let ts = 0.0025;
    let gray = graybox_to_pwarx(&g, ts).unwrap();
    let mech = to_pwarx(&hysid_physical::head_model(), ts);
    let pairs = [
        ("free+", "slip+[]"),
        ("free-", "slip-[]"),
        ("impact+", "slip+[board]"),
        ("impact-", "slip-[board]"),
        ("stick", "stick"),
        ("upper_saturation", "stop[upper]"),
        ("lower_saturation", "stop[lower]"),
    ];
    assert_eq!(gray.modes.len(), pairs.len());
    for (a, b) in pairs {
        let find = |p: &hysid_model::model::PwarxModel, n: &str| {
            p.modes
                .iter()
                .find(|q| q.name.as_deref() == Some(n))
                .unwrap()
                .theta
                .clone()
        };
        let (ta, tb) = (find(&gray, a), find(&mech, b));
        for (x, y) in ta.iter().zip(&tb) {
            assert!(
                (x - y).abs() <= 1e-9 * y.abs().max(1.0),
                "{a}: {ta:?} vs {b}: {tb:?}"
            );
        }
    }
}

/// With four states, the ARX(4,4) mode of a regime reproduces the
/// simulator while the regime lasts: the two masses kept apart.
#[test]
fn four_state_bridge_predicts_the_simulator_in_its_mode() {
    let m = load("two-masses.toml");
    let p = hysid_physical::bridge::graybox_to_pwarx(&m, TS).unwrap();
    Model::Pwarx(p.clone()).validate().unwrap();
    assert_eq!((p.na, p.nb), (4, 4));
    let data = simulated(&m, &drive(400, 40, -0.5, 0.5), 9, 0.0);
    let c = CompiledModel::new(&m).unwrap();
    let r = simulate::run(&c, &m.values(), &data).unwrap();
    assert!(
        r.modes.iter().all(|q| *q == Some(0)),
        "the masses stay apart"
    );
    let theta = &p.modes[0].theta;
    let (y, u) = (data.y(), data.u(0));
    for k in 4..400 {
        let mut x: Vec<f64> = (1..=4).map(|i| y[k - i]).collect();
        x.extend((1..=4).map(|i| u[k - i]));
        x.push(1.0);
        let pred: f64 = theta.iter().zip(&x).map(|(a, b)| a * b).sum();
        assert!((pred - y[k]).abs() < 1e-9, "k {k}: {pred} vs {}", y[k]);
    }
}

/// `truth` driven by the input `u` at sample time `ts`, from the initial
/// state `x0` (by state name; the others zero) at sample 0, measured
/// without noise.
fn noise_free(truth: &GrayBoxModel, x0: &[(&str, f64)], u: Vec<f64>, ts: f64) -> Dataset {
    let n = u.len();
    let mut m = truth.clone();
    m.initial_state = given(x0);
    let clean = Dataset::siso(u.clone(), vec![0.0; n], Some(ts)).unwrap();
    let c = CompiledModel::new(&m).unwrap();
    let run = simulate::run(&c, &m.values(), &clean).unwrap();
    Dataset::siso(u, run.y, Some(ts)).unwrap()
}

/// The initial state `x0` (by state name; the others zero) at sample 0.
fn given(x0: &[(&str, f64)]) -> hysid_graybox::GrayBoxInitialState {
    hysid_graybox::GrayBoxInitialState::Given {
        values: x0.iter().map(|(n, v)| (n.to_string(), *v)).collect(),
        mode: None,
        estimate: Default::default(),
        samples: None,
    }
}

/// Every free parameter of `truth` recovered within `tolerance` (relative)
/// from `data` by a small search (`settings` added), seed 1, starting from
/// the nominal values of the example file `file`.
fn recovers_within(
    truth: &GrayBoxModel,
    data: &Dataset,
    file: &str,
    settings: &[&str],
    tolerance: f64,
) -> GrayBoxModel {
    let path = example(file);
    let fitted = fit(
        data,
        &Priors::default(),
        path.to_str().unwrap(),
        settings,
        1,
    );
    for (t, f) in truth.parameters.iter().zip(&fitted.parameters) {
        let rel = ((f.value - t.value) / t.value).abs();
        eprintln!(
            "{}: true {}, fitted {}, relative error {rel:.2e}",
            t.name, t.value, f.value
        );
        assert!(
            rel <= tolerance,
            "{}: true {}, fitted {}",
            t.name,
            t.value,
            f.value
        );
    }
    fitted
}

/// The positioning axis (the EMPS benchmark's physics): mass, viscous and
/// Coulomb friction and the constant force recovered within 0.1 % from 5 s
/// of noise-free position at 100 Hz, the axis at rest for the first
/// 0.3 s, then driven by random drive voltages in [-2, 2] V held 0.3 s,
/// which make it stick and break away again.
#[test]
fn positioning_axis_parameters_are_recovered() {
    let mut truth = load("positioning-axis.toml");
    for (n, v) in [("M", 110.0), ("Fv", 170.0), ("Fc", 25.0), ("offset", -4.5)] {
        set(&mut truth, n, v);
    }
    let mut u = drive(500, 30, -2.0, 2.0).generate(6).remove(0);
    u[..30].fill(0.0);
    let data = noise_free(&truth, &[], u, TS);
    // The record holds sticking and sliding both ways.
    let mut at_rest = truth.clone();
    at_rest.initial_state = given(&[]);
    let r = simulate::run(
        &CompiledModel::new(&at_rest).unwrap(),
        &at_rest.values(),
        &data,
    )
    .unwrap();
    let stuck = truth.mode_names().iter().position(|n| n == "stuck");
    let stuck_samples = r.modes.iter().filter(|q| **q == stuck).count();
    assert!(stuck_samples > 50, "{stuck_samples} samples stuck");
    let v: Vec<f64> = r.x.chunks(2).map(|x| x[1]).collect();
    assert!(v.iter().any(|v| *v > 0.01) && v.iter().any(|v| *v < -0.01));
    recovers_within(&truth, &data, "positioning-axis.toml", &SMALL_SEARCH, 1e-3);
}

/// A Nelder-Mead restart that does not lower the best cost ends a stage's
/// restarts (the next would repeat it from the same point): on a noisy
/// record of the axis, ten restarts allowed give the parameters and
/// diagnostics three give, after the same runs, fewer than three per
/// stage.
#[test]
fn restarts_end_at_the_first_that_finds_nothing_lower() {
    let mut truth = load("positioning-axis.toml");
    for (n, v) in [("M", 110.0), ("Fv", 170.0), ("Fc", 25.0), ("offset", -4.5)] {
        set(&mut truth, n, v);
    }
    let data = simulated(&truth, &drive(500, 30, -2.0, 2.0), 6, 1e-4);
    let file = example("positioning-axis.toml");
    let fit = |restarts: &str| {
        let mut settings = SMALL_SEARCH.to_vec();
        settings.extend(["local_iters=3000", restarts]);
        let m = fit(
            &data,
            &Priors::default(),
            file.to_str().unwrap(),
            &settings,
            1,
        );
        let runs: u64 = m.info.diagnostics.method["termination"]["nelder_mead"]
            .as_object()
            .unwrap()
            .values()
            .map(|v| v.as_u64().unwrap())
            .sum();
        (m.values(), m.info.diagnostics, runs)
    };
    let (values, diagnostics, ran) = fit("restarts=3");
    assert!(!diagnostics.method.contains_key("swarm_skipped"));
    // Two stages (segmented, free run), each with up to three restarts.
    assert!(ran < 2 * 3, "{ran} Nelder-Mead runs");
    assert_eq!(fit("restarts=10"), (values, diagnostics, ran));
}

/// The cascaded tanks (the Cascaded Tanks benchmark's physics): pump gain,
/// both outlets, both overflow levels, the share of the upper overflow
/// that reaches the lower tank and the sensor offset recovered within 0.1 %
/// from 400 noise-free samples at 4 s (random pump voltages in [0, 10] V
/// held 200 s), on which both tanks overflow, alone and together; the
/// record starts from levels of 3 and 4 V, the upper one estimated with
/// the parameters within 1e-3 of it.
#[test]
fn cascaded_tanks_parameters_are_recovered() {
    let mut truth = load("cascaded-tanks.toml");
    for (n, v) in [
        ("k", 0.03),
        ("k1", 0.06),
        ("k2", 0.045),
        ("h1max", 9.0),
        ("h2max", 9.5),
        ("p", 0.4),
        ("off", 0.3),
    ] {
        set(&mut truth, n, v);
    }
    let ts = 4.0;
    let u = Excitation {
        n: 400,
        hold: 50,
        low: 0.0,
        high: 10.0,
        ts: Some(ts),
        inputs: 1,
    }
    .generate(7)
    .remove(0);
    let x0 = [("h1", 3.0), ("h2", 4.0)];
    let data = noise_free(&truth, &x0, u, ts);
    let mut from_x0 = truth.clone();
    from_x0.initial_state = given(&x0);
    let c = CompiledModel::new(&from_x0).unwrap();
    let r = simulate::run(&c, &from_x0.values(), &data).unwrap();
    let names = truth.mode_names();
    for mode in [
        "filling",
        "upper_overflow",
        "lower_overflow",
        "both_overflow",
    ] {
        let l = names.iter().position(|n| n == mode);
        let count = r.modes.iter().filter(|q| **q == l).count();
        eprintln!("{mode}: {count} samples");
        assert!(count > 0, "the record never in {mode}");
    }
    let fitted = recovers_within(
        &truth,
        &data,
        "cascaded-tanks.toml",
        &[
            "particles=8",
            "swarm_iters=10",
            "starts=3",
            "local_iters=150",
        ],
        1e-3,
    );
    // The upper tank's initial level, estimated with the parameters.
    let h1 = fitted.info.diagnostics.method["initial_states"]["h1"]
        .as_f64()
        .unwrap();
    assert!((h1 - 3.0).abs() <= 3e-3, "h1(0) = {h1}");
}

/// The coupled drives (the Coupled Electric Drives benchmark's physics, its
/// output the unsigned pulley speed) fitted on three noise-free records of
/// binary inputs of amplitudes 0.5, 1 and 1.5 V, each from rest, as the
/// benchmark's three records are: all five parameters within 0.5 %. On one
/// record the drives' gain and the exponent of the input's power law are
/// not separable (a binary input of amplitude `A` shows only `k*A^pw`): at
/// `A = 1` the exponent has no effect at all, and the fit says so.
#[test]
fn coupled_drives_are_recovered_from_three_records_of_three_amplitudes() {
    let mut truth = load("coupled-drives.toml");
    for (n, v) in [
        ("k", 2.2),
        ("tm", 0.17),
        ("wn", 20.0),
        ("z", 0.15),
        ("pw", 1.8),
    ] {
        set(&mut truth, n, v);
    }
    let ts = 0.02;
    let records: Vec<Dataset> = [(0.5, 11), (1.0, 12), (1.5, 13)]
        .into_iter()
        .map(|(amplitude, seed)| {
            let levels = Excitation {
                n: 200,
                hold: 4,
                low: -1.0,
                high: 1.0,
                ts: Some(ts),
                inputs: 1,
            }
            .generate(seed)
            .remove(0);
            let u = levels.iter().map(|v| amplitude * v.signum()).collect();
            noise_free(&truth, &[], u, ts)
        })
        .collect();
    let joined = Dataset::join(&records).unwrap();
    recovers_within(&truth, &joined, "coupled-drives.toml", &SMALL_SEARCH, 5e-3);
    let file = example("coupled-drives.toml");
    let alone = fit(
        &records[1],
        &Priors::default(),
        file.to_str().unwrap(),
        &SMALL_SEARCH,
        1,
    );
    let insensitive = &alone.info.diagnostics.method["zero_sensitivity"];
    assert_eq!(insensitive, &serde_json::json!(["pw"]), "{insensitive}");
}

/// Nominal values that cannot be simulated on the record (an output gain
/// of zero, which the measured rule cannot invert) leave `nominal_cost`
/// null, and the search fits from elsewhere in the bounds.
#[test]
fn nominal_values_that_cannot_run_leave_the_nominal_cost_null() {
    let truth = load("positioning-axis.toml");
    let mut u = drive(300, 30, -2.0, 2.0).generate(6).remove(0);
    u[..30].fill(0.0);
    let data = noise_free(&truth, &[], u, TS);
    let text = std::fs::read_to_string(example("positioning-axis.toml"))
        .unwrap()
        .replace(
            "outputs = [{ name = \"q\", value = \"q\" }]",
            "outputs = [{ name = \"q\", value = \"c*q\" }]",
        )
        + "\n[[parameters]]\nname = \"c\"\nvalue = 0.0\nbounds = [0.0, 1.5]\n";
    let file = std::env::temp_dir().join(format!("hysid-gain-{}.toml", std::process::id()));
    std::fs::write(&file, text).unwrap();
    let fitted = fit(
        &data,
        &Priors::default(),
        file.to_str().unwrap(),
        &SMALL_SEARCH,
        1,
    );
    std::fs::remove_file(&file).unwrap();
    let d = &fitted.info.diagnostics.method;
    assert!(d["nominal_cost"].is_null(), "{d:?}");
    assert!(d["cost"].as_f64().unwrap().is_finite(), "{d:?}");
}
