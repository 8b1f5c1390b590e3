//! The back-end contract: priors honoured or refused, determinism, the
//! model file, and the bridge to the per-mode discrete-time form.

use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::{Priors, Tie};
use hysid_mechanical::simulate as mechanical;
use hysid_mechanical::{MechanicalInitialState, MechanicalModel};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use hysid_model::model::RunStatus;
use hysid_model::regressors::RegressorSpec;
use hysid_physical::{HEAD_MODEL_TOML, Physical, bridge, head_model};

const TS: f64 = 0.0025;
/// The head's model file and small budgets: these tests check the
/// contract, not the optimum. Their records are the nominal head's, which
/// would skip the swarm ([`the_swarm_is_skipped_where_the_nominal_values_fit_to_the_noise`]),
/// so the rule is off.
const QUICK: [&str; 8] = [
    crate::HEAD_MODEL_SET,
    "swarm_skip=0",
    "particles=6",
    "swarm_iters=3",
    "local_iters=30",
    "restarts=1",
    "starts=2",
    "lm_iters=3",
];

fn data(n: usize, seed: u64) -> Dataset {
    data_between(n, seed, -0.2, 0.0)
}

/// The head model's response to inputs held 120 samples at levels drawn in
/// `[low, high]`.
fn data_between(n: usize, seed: u64, low: f64, high: f64) -> Dataset {
    let mut m = head_model();
    m.initial_state = MechanicalInitialState::Given {
        position: 0.0,
        velocity: 0.0,
    };
    let u = Excitation {
        n,
        hold: 120,
        low,
        high,
        ts: Some(TS),
        inputs: 1,
    }
    .generate(seed)
    .remove(0);
    let r = mechanical::run(
        &m,
        &m.values(),
        &Dataset::siso(u.clone(), vec![0.0; n], Some(TS)).unwrap(),
    )
    .unwrap();
    Dataset::siso(u, r.y, Some(TS)).unwrap()
}

fn run(d: &Dataset, priors: &Priors, extra: &[&str], seed: u64) -> Result<Model, IdentifyError> {
    let problem = Problem {
        data: d,
        orders: RegressorSpec::new(2, 2, 1),
        priors,
        priors_origin: Some("p.toml"),
    };
    let key = |s: &str| s.split('=').next().unwrap_or("").to_string();
    let mut set: Vec<&str> = QUICK
        .iter()
        .copied()
        .filter(|q| !extra.iter().any(|e| key(e) == key(q)))
        .collect();
    set.extend_from_slice(extra);
    Physical.run(
        &problem,
        &Settings::parse(&set).unwrap(),
        &RunContext::quiet(seed),
    )
}

fn mech(m: &Model) -> &MechanicalModel {
    match m {
        Model::Mechanical(x) => x,
        _ => panic!("kind {}", m.kind()),
    }
}

fn value(m: &MechanicalModel, n: &str) -> f64 {
    m.parameters[m.parameter_index(n).unwrap()].value
}

#[test]
fn built_in_model_is_the_file() {
    let file = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/pick-and-place/head.toml"
    ))
    .unwrap();
    assert_eq!(file, HEAD_MODEL_TOML);
    let m = head_model();
    assert_eq!(m.parameters.len(), 12);
    assert!(
        m.parameters
            .iter()
            .all(|p| p.value >= p.bounds[0] && p.value <= p.bounds[1])
    );
}

#[test]
fn honours_fixed_ties_and_bounds_and_is_deterministic() {
    let d = data(600, 3);
    let mut pri = Priors::default();
    pri.fixed.insert("yc".into(), 12.5);
    pri.tie.push(Tie {
        params: vec!["d1".into(), "d2".into()],
    });
    pri.bounds.insert("c1".into(), [600.0, 610.0]);
    let a = run(&d, &pri, &[], 5).unwrap();
    let m = mech(&a);
    assert_eq!(value(m, "yc"), 12.5);
    assert_eq!(value(m, "d1"), value(m, "d2"));
    let c1 = value(m, "c1");
    assert!((600.0..=610.0).contains(&c1), "c1 {c1}");
    assert_eq!(
        m.parameters[m.parameter_index("c1").unwrap()].bounds,
        [600.0, 610.0]
    );
    assert!(
        m.info.diagnostics.method["cost"]
            .as_f64()
            .unwrap()
            .is_finite()
    );
    assert!(m.info.diagnostics.method["parameters"]["c1"]["sensitivity"].is_number());
    assert_eq!(m.info.method, "physical");
    // Same seed, same bytes; the file reads back.
    let b = run(&d, &pri, &[], 5).unwrap();
    assert_eq!(a.to_json(), b.to_json());
    assert_eq!(Model::from_json(&a.to_json(), "mem").unwrap(), a);
}

/// `swarms = K` runs K searches, the first from the run's seed: its cost
/// is never above the single search's of the same seed, the kept search is
/// recorded, and with these small budgets and the swarm's best as the only
/// local start (not the nominal values, which generated the record) the
/// other seeds do find lower costs (a search that reused the run's seed
/// would always keep the first). The searches run in parallel, and the
/// result does not depend on the thread count.
#[test]
fn more_swarms_keep_the_search_of_least_cost() {
    let d = data(600, 3);
    let cost = |m: &Model| mech(m).info.diagnostics.method["cost"].as_f64().unwrap();
    let mut kept_other = false;
    for seed in 1..=4 {
        let one = run(&d, &Priors::default(), &["starts=1"], seed).unwrap();
        let four = run(&d, &Priors::default(), &["starts=1", "swarms=4"], seed).unwrap();
        assert!(
            cost(&four) <= cost(&one),
            "seed {seed}: {} > {}",
            cost(&four),
            cost(&one)
        );
        let kept = mech(&four).info.diagnostics.method["swarm_kept"]
            .as_u64()
            .unwrap();
        assert!(kept < 4);
        kept_other |= kept > 0;
        assert!(
            !mech(&one)
                .info
                .diagnostics
                .method
                .contains_key("swarm_kept")
        );
        let again = run(&d, &Priors::default(), &["starts=1", "swarms=4"], seed).unwrap();
        assert_eq!(four.to_json(), again.to_json());
        // The searches run in parallel: one thread gives the same bytes.
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let serial = one_thread
            .install(|| run(&d, &Priors::default(), &["starts=1", "swarms=4"], seed).unwrap());
        assert_eq!(four.to_json(), serial.to_json());
    }
    assert!(kept_other, "every seed kept its first search");
    let e = run(&d, &Priors::default(), &["swarms=0"], 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("swarms"), "{e}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(6))]
    /// For random priors: the fixed value comes back unchanged, the tied
    /// parameters are equal to the last bit, the bounded one stays inside
    /// its bounds.
    #[test]
    fn random_priors_hold_in_the_fitted_model(
        yc in 8.0f64..17.0,
        tie in 0usize..3,
        lo in 400.0f64..850.0, width in 1.0f64..50.0,
        seed in 1u64..1000,
    ) {
        let d = data(400, 7);
        let pairs = [["d1", "d2"], ["f1", "f2"], ["c1", "c2"]];
        let tied = pairs[tie];
        let mut pri = Priors::default();
        pri.fixed.insert("yc".into(), yc);
        pri.tie.push(Tie { params: tied.iter().map(|s| s.to_string()).collect() });
        let bounded = if tied.contains(&"c1") { "ku" } else { "c1" };
        let (lo, hi) = if bounded == "ku" { (-1.5e5, -1.5e5 + 100.0 * width) } else { (lo, lo + width) };
        pri.bounds.insert(bounded.into(), [lo, hi]);
        let m = run(&d, &pri, &[], seed).unwrap();
        let m = mech(&m);
        proptest::prop_assert_eq!(value(m, "yc").to_bits(), yc.to_bits());
        proptest::prop_assert_eq!(value(m, tied[0]).to_bits(), value(m, tied[1]).to_bits());
        let v = value(m, bounded);
        proptest::prop_assert!(v >= lo && v <= hi, "{} = {} outside [{}, {}]", bounded, v, lo, hi);
    }
}

#[test]
fn refuses_what_it_cannot_honour() {
    let d = data(300, 4);
    let pri = Priors {
        modes: Some(3),
        ..Default::default()
    };
    let e = run(&d, &pri, &[], 1).unwrap_err().to_string();
    assert!(e.contains("does not honour") && e.contains("modes"), "{e}");
    let pri = Priors {
        switching: vec!["y1".into()],
        ..Default::default()
    };
    assert!(run(&d, &pri, &[], 1).is_err());
    let mut pri = Priors::default();
    pri.fixed.insert("a1".into(), 0.0);
    let e = run(&d, &pri, &[], 1).unwrap_err().to_string();
    assert!(e.contains("a1") && e.contains("ku"), "{e}");
    assert!(e.starts_with("p.toml: [fixed]"), "{e}");
    // A fixed value outside the model's bounds would write a model that
    // does not read back; so would a tie that carries it to another one.
    let mut pri = Priors::default();
    pri.fixed.insert("yc".into(), 30.0);
    let e = run(&d, &pri, &[], 1).unwrap_err().to_string();
    assert!(e.contains("yc = 30") && e.contains("[8, 17]"), "{e}");
    let mut pri = Priors::default();
    pri.fixed.insert("c1".into(), 950.0);
    pri.bounds.insert("c1".into(), [900.0, 1000.0]);
    assert!(run(&d, &pri, &[], 1).is_ok_and(|m| {
        let Model::Mechanical(m) = m else {
            return false;
        };
        m.parameters[m.parameter_index("c1").unwrap()].value == 950.0
    }));
    let mut pri = Priors::default();
    pri.tie.push(Tie {
        params: vec!["c1".into(), "c2".into()],
    });
    pri.fixed.insert("c1".into(), 600.0);
    pri.fixed.insert("c2".into(), 500.0);
    assert!(
        run(&d, &pri, &[], 1)
            .unwrap_err()
            .to_string()
            .contains("tied")
    );
    // A tie of one parameter ties nothing here (a PWARX tie of one
    // parameter ties it across the modes).
    let mut pri = Priors::default();
    pri.tie.push(Tie {
        params: vec!["c1".into()],
    });
    let e = run(&d, &pri, &[], 1).unwrap_err();
    assert!(e.is_bad_input(), "{e}");
    assert!(
        e.to_string()
            .contains("[[tie]] #1: one parameter ('c1') ties nothing"),
        "{e}"
    );
    let mut pri = Priors::default();
    pri.bounds.insert("c1".into(), [950.0, 990.0]);
    pri.tie.push(Tie {
        params: vec!["c1".into(), "c2".into()],
    });
    assert!(
        run(&d, &pri, &[], 1)
            .unwrap_err()
            .to_string()
            .contains("no admissible")
    );
    let e = run(&d, &Priors::default(), &["model=/nonexistent/m.toml"], 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("model"), "{e}");
    let no_ts = Dataset::siso(d.u(0).to_vec(), d.y().to_vec(), None).unwrap();
    assert!(
        run(&no_ts, &Priors::default(), &[], 1)
            .unwrap_err()
            .to_string()
            .contains("sampling time")
    );
}

#[test]
fn refuses_to_run_without_a_model_file() {
    let d = data(400, 3);
    let problem = Problem {
        data: &d,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &Priors::default(),
        priors_origin: None,
    };
    for set in [&[][..], &["model=  "][..], &["particles=6"][..]] {
        let e = Physical
            .run(
                &problem,
                &Settings::parse(set).unwrap(),
                &RunContext::quiet(1),
            )
            .unwrap_err();
        assert!(
            matches!(
                e,
                IdentifyError::Options(hysid_core::options::OptionError::Missing {
                    key: "model",
                    ..
                })
            ),
            "{set:?}: {e}"
        );
        assert!(e.to_string().contains("option model=FILE or"), "{e}");
    }
}

#[test]
fn reads_a_model_file() {
    let dir = std::env::temp_dir().join(format!("hysid-physical-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("head.toml");
    std::fs::write(
        &path,
        HEAD_MODEL_TOML.replace("value = 12.0", "value = 13.0"),
    )
    .unwrap();
    let d = data(300, 6);
    let set = format!("model={}", path.display());
    let m = run(
        &d,
        &Priors::default(),
        &[set.as_str(), "particles=0", "local_iters=0", "lm_iters=0"],
        1,
    )
    .unwrap();
    assert_eq!(
        value(mech(&m), "yc"),
        13.0,
        "no search: the file's values come back"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// In a sliding regime without events, the bridge's ARX(2,2) mode predicts
/// the simulator's output exactly (zero-order hold is exact for held inputs).
#[test]
fn bridge_modes_reproduce_the_simulator_in_their_regime() {
    let mut m = head_model();
    m.initial_state = MechanicalInitialState::Given {
        position: 1.0,
        velocity: 0.0,
    };
    // A strong constant push down from y = 1: slides down freely, no stop or
    // contact within 30 samples (75 ms).
    let n = 30;
    let u = vec![-0.06; n];
    let r = mechanical::run(
        &m,
        &m.values(),
        &Dataset::siso(u.clone(), vec![0.0; n], Some(TS)).unwrap(),
    )
    .unwrap();
    assert!(
        r.modes[1..].iter().all(|q| *q == Some(1)),
        "free slide: {:?}",
        r.modes
    );
    assert!(r.v[1..].iter().all(|v| *v > 0.0));
    let p = bridge::to_pwarx(&m, TS);
    Model::Pwarx(p.clone()).validate().unwrap();
    let mode = p
        .modes
        .iter()
        .find(|q| q.name.as_deref() == Some("slip+[]"))
        .unwrap();
    for k in 2..n {
        let x = [r.y[k - 1], r.y[k - 2], u[k - 1], u[k - 2], 1.0];
        let pred: f64 = mode.theta.iter().zip(x).map(|(a, b)| a * b).sum();
        assert!((pred - r.y[k]).abs() < 1e-7, "k {k}: {pred} vs {}", r.y[k]);
    }
    let names: Vec<_> = p.modes.iter().map(|q| q.name.clone().unwrap()).collect();
    assert_eq!(
        names,
        [
            "slip+[]",
            "slip-[]",
            "slip+[board]",
            "slip-[board]",
            "stick",
            "stop[upper]",
            "stop[lower]"
        ]
    );
}

/// The runs a stage's termination counts record, whatever their ends.
fn runs(ends: &serde_json::Value) -> u64 {
    ends.as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum()
}

#[test]
fn the_termination_of_every_stage_is_recorded_and_an_iteration_limit_reported() {
    let d = data(400, 3);
    let diag = |m: &Model| m.info().diagnostics.to_map();
    // One Nelder-Mead iteration cannot meet its 1e-12 spread tolerance.
    let m = run(&d, &Priors::default(), &["local_iters=1"], 1).unwrap();
    let g = diag(&m);
    let t = &g["termination"];
    assert_eq!(t["particle_swarm"], "max_iterations", "{t}");
    assert!(
        t["nelder_mead"]["max_iterations"].as_u64().unwrap() >= 1,
        "{t}"
    );
    assert_eq!(t["last_local_run"], "max_iterations", "{t}");
    let lm = runs(&t["levenberg_marquardt"]);
    // One LM run per start: starts = 2 in the segmented stage, 1 in the
    // free-run stage; one Nelder-Mead run (restarts = 1) per stage.
    assert_eq!(lm, 3, "{t}");
    assert_eq!(t["nelder_mead"]["max_iterations"], 2, "{t}");
    let status = g["status"].as_str().unwrap();
    assert!(
        status.starts_with(
            "iteration limit reached: the last Nelder-Mead run stopped at local_iters = 1"
        ),
        "{status}"
    );
    // Enough iterations: the last run converges and no status is written.
    let m = run(&d, &Priors::default(), &["local_iters=4000"], 1).unwrap();
    let g = diag(&m);
    assert_eq!(g["termination"]["last_local_run"], "converged", "{g:?}");
    assert!(!g.contains_key("status"), "{g:?}");
}

/// `restarts = 0`: the local stages are Levenberg-Marquardt alone (one run
/// per start, no Nelder-Mead), and they bring the swarm's best point to a
/// fit of the noise-free record.
#[test]
fn no_restarts_leave_levenberg_marquardt_alone() {
    let d = data(400, 3);
    let m = run(&d, &Priors::default(), &["restarts=0", "lm_iters=20"], 1).unwrap();
    let g = m.info().diagnostics.to_map();
    let t = &g["termination"];
    assert!(t.get("nelder_mead").is_none(), "{t}");
    let lm = runs(&t["levenberg_marquardt"]);
    assert_eq!(lm, 3, "{t}");
    // From the swarm's best point (segmented cost 0.64 on this record) to
    // a free run within 1e-4 of the output's variance.
    let cost = g["cost"].as_f64().unwrap();
    let y = d.y();
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let variance = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64;
    assert!(
        cost < 1e-4 * variance,
        "{cost} against the variance {variance}"
    );
}

#[test]
fn a_record_no_candidate_can_simulate_is_a_method_failure() {
    // Outputs of +-1e20 alternating each sample: no simulation follows
    // them (the squared error is ~1e40, past the failure threshold 1e30, or
    // the simulation is not finite), so every candidate fails.
    let mut d = data(200, 5);
    for (k, v) in d.output.values.iter_mut().enumerate() {
        *v = if k % 2 == 0 { 1e20 } else { -1e20 };
    }
    let e = run(&d, &Priors::default(), &[], 1).unwrap_err();
    assert!(!e.is_bad_input(), "{e}");
    assert!(
        e.to_string()
            .starts_with("physical: every candidate simulation failed or diverged"),
        "{e}"
    );
}

/// A model file whose own values fail on the record with a fault of the
/// model (a transition into a mode whose invariant the state does not
/// meet) is bad input naming the file and the fault, not a failure of the
/// search.
#[test]
fn a_model_that_fails_at_its_own_values_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lag.toml");
    std::fs::write(
        &path,
        r#"
kind = "gray_box"
format = 1
internal_step = 0.0025
states = ["x"]
inputs = ["u"]
outputs = [{ name = "y", value = "x" }]
initial_state = { from = "given", values = { x = 0 }, mode = "low" }

[[parameters]]
name = "th"
value = -0.01
bounds = [-0.02, 0.0]

[[modes]]
name = "low"
flow = { x = "u - x" }

[[modes]]
name = "high"
flow = { x = "u - x" }
invariant = ["x >= 1"]

[[transitions]]
from = "low"
to = "high"
guard = "x <= th"
"#,
    )
    .unwrap();
    let set = format!("model={}", path.display());
    let e = run(&data(300, 6), &Priors::default(), &[set.as_str()], 1).unwrap_err();
    assert!(e.is_bad_input(), "{e}");
    let text = e.to_string();
    assert!(
        text.starts_with(&format!(
            "{}: the model fails on this record",
            path.display()
        )) && text.contains("transition low -> high fires at a state (it has no reset)"),
        "{text}"
    );
}

#[test]
fn a_spent_time_budget_is_reported_as_the_status() {
    let d = data(400, 3);
    let problem = Problem {
        data: &d,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &Priors::default(),
        priors_origin: None,
    };
    let ctx = RunContext {
        deadline: hysid_core::backend::Deadline::at(std::time::Instant::now()),
        ..RunContext::quiet(1)
    };
    let m = Physical
        .run(&problem, &Settings::parse(&QUICK).unwrap(), &ctx)
        .unwrap();
    assert_eq!(m.info().diagnostics.run_status, RunStatus::TimeBudget);
    let g = &m.info().diagnostics.to_map();
    let status = g["status"].as_str().unwrap();
    assert!(
        status.starts_with("time budget reached during the particle swarm stage after ")
            && status.ends_with(" simulations: best parameters found by then"),
        "{status}"
    );
    let t = &g["termination"];
    assert_eq!(t["particle_swarm"], "time_budget", "{t}");
    // No local run begins after the deadline, and no Jacobian is formed
    // for the standard errors.
    for stage in ["levenberg_marquardt", "nelder_mead", "last_local_run"] {
        assert!(t.get(stage).is_none(), "{t}");
    }
    assert_eq!(g["jacobian"], "not_computed");
    assert!(
        g["confidence_method"]
            .as_str()
            .unwrap()
            .starts_with("none: the time budget")
    );
    let parameters = g["parameters"].as_object().unwrap();
    assert!(!parameters.is_empty());
    for (name, p) in parameters {
        assert!(p["std_error"].is_null(), "{name}: {p}");
        assert_eq!(p["identifiability"], "no_standard_error", "{name}: {p}");
    }
}

/// A record that never reaches the lower stop says nothing about its
/// position: `y_low` comes back at its nominal value, marked not
/// identifiable, not wherever the search left it; every parameter says
/// what the rows determine about it.
#[test]
fn a_parameter_the_rows_do_not_reach_stays_nominal() {
    let d = data_between(400, 3, -0.1, 0.0);
    let nominal = value(&head_model(), "y_low");
    assert!(
        d.y().iter().all(|&y| y < nominal - 1.0),
        "the record must stay clear of the lower stop"
    );
    for seed in [1, 2] {
        let m = run(&d, &Priors::default(), &[], seed).unwrap();
        assert_eq!(value(mech(&m), "y_low"), nominal, "seed {seed}");
        let p = &m.info().diagnostics.method["parameters"];
        assert_eq!(
            p["y_low"]["identifiability"], "not_identifiable",
            "seed {seed}"
        );
        assert!(p["y_low"]["std_error"].is_null());
        for (name, entry) in p.as_object().unwrap() {
            let kind = entry["identifiability"].as_str().unwrap();
            assert_eq!(
                kind == "estimated",
                !entry["std_error"].is_null(),
                "{name}: {entry}"
            );
        }
    }
}

/// The swarm is skipped where Levenberg-Marquardt from the nominal values
/// fits the record to its noise: on a record of the nominal head with
/// noise added the fit runs neither the swarm nor the segmented stage, says
/// why, runs fewer simulations and reaches the cost of the fit with the
/// swarm. Where the rule does not hold, the fit is the one without the
/// rule, plus the simulations of that descent.
#[test]
fn the_swarm_is_skipped_where_the_nominal_values_fit_to_the_noise() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut d = data(800, 3);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let noise = Normal::new(0.0, 0.02).unwrap();
    for v in d.output.values.iter_mut() {
        *v += noise.sample(&mut rng);
    }
    let diag = |m: &Model| m.info().diagnostics.to_map();
    let fit_with = |extra: &[&str]| {
        let set: Vec<&str> = extra.iter().copied().chain(["lm_iters=20"]).collect();
        let m = run(&d, &Priors::default(), &set, 1).unwrap();
        (diag(&m), m)
    };
    let fit = |skip: &str| fit_with(&[skip]);
    let (skipped, skipped_model) = fit("swarm_skip=1.5");
    let (full, full_model) = fit("swarm_skip=0");
    let why = &skipped["swarm_skipped"];
    let (reached, floor) = (
        why["nominal_descent_cost"].as_f64().unwrap(),
        why["noise_floor"].as_f64().unwrap(),
    );
    assert!(reached <= floor, "{why}");
    let sigma = skipped["noise_estimate"].as_f64().unwrap();
    assert!(
        (floor - 1.5 * sigma * sigma).abs() <= 1e-12 * floor,
        "{why}"
    );
    assert!(skipped["termination"].get("particle_swarm").is_none());
    assert!(!skipped.contains_key("swarm_cost"));
    assert!(!skipped.contains_key("segmented_cost"));
    assert!(!full.contains_key("swarm_skipped"));
    let evals = |g: &std::collections::BTreeMap<String, serde_json::Value>| {
        g["evaluations"].as_u64().unwrap()
    };
    assert!(
        evals(&skipped) < evals(&full),
        "{} >= {}",
        evals(&skipped),
        evals(&full)
    );
    let cost =
        |g: &std::collections::BTreeMap<String, serde_json::Value>| g["cost"].as_f64().unwrap();
    assert!(
        cost(&skipped) <= 1.01 * cost(&full),
        "{} against {}",
        cost(&skipped),
        cost(&full)
    );
    // Several searches: without the swarm they would all be the same, so
    // one runs.
    let (several, several_model) = fit_with(&["swarm_skip=1.5", "swarms=3"]);
    assert!(several.contains_key("swarm_skipped"));
    assert!(!several.contains_key("swarm_kept"));
    assert_eq!(evals(&several), evals(&skipped));
    assert_eq!(mech(&several_model).values(), mech(&skipped_model).values());
    // A floor below the noise variance (half of it): the descent is tried
    // (the nominal cost lies within 100 floors) and fails the rule; the
    // swarm runs, and the fit is the one without the rule, plus the
    // descent's simulations. A floor far below the nominal cost: the
    // descent is not even tried.
    for (factor, tried) in [("swarm_skip=0.5", true), ("swarm_skip=1e-9", false)] {
        let (never, never_model) = fit(factor);
        assert!(!never.contains_key("swarm_skipped"), "{factor}");
        assert_eq!(never["termination"], full["termination"], "{factor}");
        assert_eq!(evals(&never) > evals(&full), tried, "{factor}");
        assert_eq!(evals(&never) == evals(&full), !tried, "{factor}");
        assert_eq!(mech(&never_model).values(), mech(&full_model).values());
        assert_eq!(cost(&never).to_bits(), cost(&full).to_bits());
    }
}

/// The fit keeps the model file's initial-state rule (its warm-up, or its
/// given state) and writes it back; `init_samples` sets another warm-up.
#[test]
fn the_file_s_initial_state_rule_is_kept_unless_init_samples_is_set() {
    let dir = std::env::temp_dir().join(format!("hysid-physical-initial-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let d = data(300, 6);
    let measured = "initial_state = { from = \"measured\", samples = 10 }";
    // The warm-up written back (`None`: the given state); a measured
    // start's velocity tolerance follows the record's noise.
    let cases: [(&str, &[&str], Option<usize>); 3] = [
        (
            "initial_state = { from = \"measured\", samples = 20 }",
            &[],
            Some(20),
        ),
        (
            "initial_state = { from = \"given\", position = 0.0, velocity = 0.0 }",
            &[],
            None,
        ),
        (
            "initial_state = { from = \"measured\", samples = 20 }",
            &["init_samples=5"],
            Some(5),
        ),
    ];
    for (i, (rule, extra, want)) in cases.into_iter().enumerate() {
        assert!(HEAD_MODEL_TOML.contains(measured));
        let path = dir.join(format!("head-{i}.toml"));
        std::fs::write(&path, HEAD_MODEL_TOML.replace(measured, rule)).unwrap();
        let set = format!("model={}", path.display());
        let mut settings = vec![set.as_str(), "particles=0", "local_iters=0", "lm_iters=0"];
        settings.extend_from_slice(extra);
        let m = run(&d, &Priors::default(), &settings, 1).unwrap();
        let written = match mech(&m).initial_state {
            MechanicalInitialState::Measured { samples, .. } => Some(samples),
            MechanicalInitialState::Given { .. } => None,
        };
        assert_eq!(written, want, "{rule} {extra:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
