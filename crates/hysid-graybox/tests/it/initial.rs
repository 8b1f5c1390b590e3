//! Initial states a rule leaves unknown (`estimate`), rest states
//! (`steady`) and the measured rule through an affine output map (a
//! sensor's gain and offset).

use crate::from_toml;
use hysid_graybox::simulate::{estimate, run, run_from};
use hysid_graybox::{CompiledModel, GrayBoxModel, initial_states};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use hysid_model::simulate::SimError;
use proptest::prelude::*;

const TS: f64 = 0.05;

/// A gray-box model from its TOML text (without `kind`).
pub(crate) fn model(text: &str) -> GrayBoxModel {
    let m: GrayBoxModel = from_toml(text, None);
    m.validate().unwrap();
    m
}

/// One state `x`, the output `y = x`, the initial state `initial` and the
/// flow `flow` of its one mode.
fn one_state(initial: &str, flow: &str) -> GrayBoxModel {
    model(&format!(
        r#"
format = 1
internal_step = 0.01
states = ["x"]
inputs = ["u"]
outputs = [{{ name = "y", value = "x" }}]
initial_state = {initial}

[[modes]]
name = "only"
flow = {{ x = "{flow}" }}
"#
    ))
}

/// Two first-order lags in cascade, `x1 -> x2`, the output `output`, the
/// initial state `initial`.
pub(crate) fn cascade(output: &str, initial: &str) -> String {
    format!(
        r#"
format = 1
internal_step = 0.01
states = ["x1", "x2"]
inputs = ["u"]
outputs = [{{ name = "y", value = "{output}" }}]
initial_state = {initial}

[[parameters]]
name = "a"
value = 1.5
bounds = [0.1, 5.0]

[[parameters]]
name = "b"
value = 2.0
bounds = [0.1, 5.0]

[[parameters]]
name = "c"
value = 2.5
bounds = [0.5, 4.0]

[[parameters]]
name = "off"
value = -0.4
bounds = [-1.0, 1.0]

[[modes]]
name = "only"
flow = {{ x1 = "-a*x1 + u", x2 = "b*(x1 - x2)" }}
"#
    )
}

fn input(n: usize, seed: u64) -> Vec<f64> {
    Excitation {
        n,
        hold: 7,
        low: -1.0,
        high: 1.0,
        ts: Some(TS),
        inputs: 1,
    }
    .generate(seed)
    .remove(0)
}

/// The output of `m`'s run on the input `u` (the outputs it reads are 0).
fn simulated(m: &GrayBoxModel, u: &[f64]) -> Dataset {
    let n = u.len();
    let clean = Dataset::siso(u.to_vec(), vec![0.0; n], Some(TS)).unwrap();
    let c = CompiledModel::new(m).unwrap();
    let r = run(&c, &m.values(), &clean).unwrap();
    Dataset::siso(u.to_vec(), r.y, Some(TS)).unwrap()
}

/// A record of `output` from the state `(x1, x2)` at sample 0.
pub(crate) fn record(output: &str, x1: f64, x2: f64, n: usize, seed: u64) -> Dataset {
    let truth = model(&cascade(
        output,
        &format!("{{ from = \"given\", values = {{ x1 = {x1}, x2 = {x2} }} }}"),
    ));
    simulated(&truth, &input(n, seed))
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-12)
}

/// The unmeasured first lag's state, estimated from the warm-up of a
/// noise-free record, is the true one to 1e-6 (relative), through a
/// bare output and through a sensor map with gain and offset; the
/// measured state is the output read back through the map.
#[test]
fn an_estimated_state_is_recovered_from_the_warm_up() {
    for (output, seed) in [("x2", 1), ("c*x2 + off", 2)] {
        for (x1, x2) in [(2.3, 0.7), (-1.1, 0.2)] {
            let data = record(output, x1, x2, 120, seed);
            let m = model(&cascade(
                output,
                r#"{ from = "measured", samples = 10, position = "x2", estimate = { x1 = [-5.0, 5.0] } }"#,
            ));
            let states = initial_states(&m, &data).unwrap();
            assert_eq!(states.len(), 1);
            assert_eq!((states[0].name.as_str(), states[0].seen), ("x1", true));
            assert!(!states[0].at_bound);
            assert!(
                close(states[0].value, x1, 1e-6),
                "{output}: {} against {x1}",
                states[0].value
            );
            let c = CompiledModel::new(&m).unwrap();
            let r = run(&c, &m.values(), &data).unwrap();
            assert_eq!(r.start, 9);
            assert!(
                close(r.x[1], x2, 1e-12),
                "{output}: x2 {} against {x2}",
                r.x[1]
            );
            for k in 0..data.len() {
                assert!((r.y[k] - data.y()[k]).abs() < 1e-6, "{output}: sample {k}");
            }
        }
    }
}

/// A range that leaves out the true state: the estimate stops on its
/// bound, and says so.
#[test]
fn an_estimate_on_its_bound_is_flagged() {
    let data = record("x2", 2.3, 0.7, 120, 1);
    for (range, bound) in [("[-5.0, 1.0]", 1.0), ("[2.5, 5.0]", 2.5)] {
        let m = model(&cascade(
            "x2",
            &format!(
                r#"{{ from = "measured", samples = 10, position = "x2", estimate = {{ x1 = {range} }} }}"#
            ),
        ));
        let states = initial_states(&m, &data).unwrap();
        assert_eq!(states[0].value, bound, "{range}");
        assert!(states[0].seen && states[0].at_bound, "{range}");
    }
}

/// A guess at a flat spot of the warm-up's cost (the first lag's state
/// reaches the output only beyond a dead zone it does not leave from the
/// guess) takes no step; the estimate starts again inside the bounds and
/// recovers the true state.
#[test]
fn an_estimate_leaves_a_flat_spot_of_its_guess() {
    let text = |initial: &str| cascade("x2", initial).replace("b*(x1 - x2)", "b*max(x1 - 1, 0)");
    let truth = model(&text(
        r#"{ from = "given", values = { x1 = 3.0, x2 = 0.5 } }"#,
    ));
    let data = simulated(&truth, &input(120, 4));
    let m = model(&text(
        r#"{ from = "measured", samples = 10, position = "x2", estimate = { x1 = [-5.0, 5.0] } }"#,
    ));
    let states = initial_states(&m, &data).unwrap();
    assert!(
        close(states[0].value, 3.0, 1e-6),
        "x1 = {}",
        states[0].value
    );
    // Out of the dead zone, the warm-up shows it.
    assert!(states[0].seen);
}

/// A `given` rule may estimate some states: the others keep their values.
#[test]
fn a_given_rule_estimates_the_listed_states_only() {
    let data = record("x2", 1.7, 0.3, 80, 3);
    let m = model(&cascade(
        "x2",
        r#"{ from = "given", values = { x2 = 0.3, x1 = 1.0 }, estimate = { x1 = [0.0, 4.0] }, samples = 12 }"#,
    ));
    let states = initial_states(&m, &data).unwrap();
    assert!(close(states[0].value, 1.7, 1e-6), "{states:?}");
    let c = CompiledModel::new(&m).unwrap();
    let r = run(&c, &m.values(), &data).unwrap();
    assert_eq!(r.start, 11);
    assert_eq!(r.x[1], 0.3);
}

/// The estimate reads the warm-up alone: rows after it changed (outputs
/// and inputs) leave it unchanged, bit for bit, and so the run up to the
/// end of the warm-up.
#[test]
fn the_estimate_reads_nothing_after_the_warm_up() {
    let data = record("c*x2 + off", 0.9, -0.2, 100, 4);
    let m = model(&cascade(
        "c*x2 + off",
        r#"{ from = "measured", samples = 8, position = "x2", estimate = { x1 = [-5.0, 5.0] } }"#,
    ));
    let mut changed = data.clone();
    for k in 8..changed.len() {
        changed.output.values[k] += 3.0 + k as f64;
        changed.inputs[0].values[k] = -changed.inputs[0].values[k];
    }
    let a = initial_states(&m, &data).unwrap();
    let b = initial_states(&m, &changed).unwrap();
    assert_eq!(a, b);
    let c = CompiledModel::new(&m).unwrap();
    let ra = run(&c, &m.values(), &data).unwrap();
    let rb = run(&c, &m.values(), &changed).unwrap();
    assert_eq!(ra.y[..8], rb.y[..8]);
    // A record shorter than the warm-up cannot estimate.
    let short = Dataset::siso(vec![0.0; 5], vec![0.0; 5], Some(TS)).unwrap();
    assert!(matches!(
        estimate(&c, &m.values(), &short),
        Err(SimError::TooShort { needed: 8, .. })
    ));
}

/// The velocity reading divides the output's slope by the sensor's gain:
/// a mass gliding at a constant speed under `y = c*x + off` is read at its
/// speed.
#[test]
fn the_velocity_reading_divides_by_the_gain() {
    let m = model(
        r#"
format = 1
internal_step = 0.01
states = ["x", "v"]
inputs = ["u"]
outputs = [{ name = "y", value = "off + c*x" }]
initial_state = { from = "measured", samples = 5, position = "x", velocity = "v" }
parameters = [
    { name = "c", value = -2.5, bounds = [-4.0, 4.0] },
    { name = "off", value = 0.75, bounds = [-1.0, 1.0] },
]

[[modes]]
name = "glide"
flow = { x = "v", v = "0" }
"#,
    );
    let (x0, v0) = (0.4, 1.3);
    let n = 30;
    let y: Vec<f64> = (0..n)
        .map(|k| 0.75 - 2.5 * (x0 + v0 * k as f64 * TS))
        .collect();
    let data = Dataset::siso(vec![0.0; n], y.clone(), Some(TS)).unwrap();
    let c = CompiledModel::new(&m).unwrap();
    let r = run(&c, &m.values(), &data).unwrap();
    assert_eq!(r.start, 4);
    assert!(close(r.x[8], x0 + v0 * 4.0 * TS, 1e-12), "x {}", r.x[8]);
    assert!(close(r.x[9], v0, 1e-9), "v {}", r.x[9]);
    for (k, (a, b)) in r.y.iter().zip(&y).enumerate().skip(4) {
        assert!((a - b).abs() < 1e-9, "sample {k}");
    }
}

/// Every output map affine in the measured state is inverted: the state
/// read from an output gives that output back.
fn round_trip(c: f64, off: f64, x: f64, u: f64) -> Result<(), TestCaseError> {
    let m = model(&format!(
        r#"
format = 1
internal_step = 0.1
states = ["x"]
inputs = ["u"]
outputs = [{{ name = "y", value = "if(u > 0, c*x, c*(x - 1) + c) + off*(1 + u^2)" }}]
initial_state = {{ from = "measured", samples = 1, position = "x" }}
parameters = [
    {{ name = "c", value = {c}, bounds = [-1000.0, 1000.0] }},
    {{ name = "off", value = {off}, bounds = [-1000.0, 1000.0] }},
]

[[modes]]
name = "still"
flow = {{ x = "0" }}
"#
    ));
    let y = if u > 0.0 { c * x } else { c * (x - 1.0) + c } + off * (1.0 + u * u);
    let data = Dataset::siso(vec![u; 2], vec![y; 2], Some(0.1)).unwrap();
    let compiled = CompiledModel::new(&m).unwrap();
    let r = run(&compiled, &m.values(), &data).unwrap();
    let scale = x.abs() + (y.abs() + off.abs() * (1.0 + u * u)) / c.abs();
    prop_assert!(
        (r.x[0] - x).abs() <= 1e-12 * scale,
        "x {} against {}",
        r.x[0],
        x
    );
    prop_assert!(
        (r.y[0] - y).abs() <= 1e-12 * (y.abs() + c.abs() * scale),
        "y {} against {}",
        r.y[0],
        y
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn the_inverse_sensor_map_round_trips(
        gain in 0.01f64..100.0,
        negative in any::<bool>(),
        off in -100.0f64..100.0,
        x in -50.0f64..50.0,
        u in -2.0f64..2.0,
    ) {
        round_trip(if negative { -gain } else { gain }, off, x, u)?;
    }
}

/// A gain of zero leaves the state unread: a typed error, no panic.
#[test]
fn a_sensor_of_zero_gain_is_an_error() {
    let m = model(&cascade(
        "c*x2 + off",
        r#"{ from = "measured", samples = 3, position = "x2" }"#,
    ));
    let mut m = m;
    let i = m.parameter_index("c").unwrap();
    m.parameters[i].bounds = [0.0, 4.0];
    m.parameters[i].value = 0.0;
    let data = Dataset::siso(vec![0.0; 10], vec![1.0; 10], Some(TS)).unwrap();
    let c = CompiledModel::new(&m).unwrap();
    let e = run(&c, &m.values(), &data).unwrap_err();
    assert!(matches!(e, SimError::InitialState(_)), "{e}");
}

/// `steady`: the cascade at rest under the first input (`x1 = x2 = u0 / a`),
/// in the first mode whose invariant holds there; a model without a rest
/// state is a typed error.
#[test]
fn steady_starts_at_rest_or_says_there_is_none() {
    let text = cascade("x2", r#"{ from = "steady", values = { x1 = 5.0 } }"#).replace(
        "[[modes]]\nname = \"only\"",
        "[[modes]]\nname = \"high\"\ninvariant = [\"x1 >= 1\"]\nflow = { x1 = \"-a*x1 + u\", x2 = \"b*(x1 - x2)\" }\n\n[[modes]]\nname = \"low\"",
    );
    let m = model(&text);
    let u0 = 0.6;
    let mut u = vec![u0; 20];
    u[10..].fill(-0.3);
    let data = Dataset::siso(u, vec![0.0; 20], Some(TS)).unwrap();
    let c = CompiledModel::new(&m).unwrap();
    let r = run(&c, &m.values(), &data).unwrap();
    assert_eq!(r.start, 0);
    for k in 0..10 {
        assert!(close(r.x[2 * k], u0 / 1.5, 1e-9), "x1 {}", r.x[2 * k]);
        assert!(
            close(r.x[2 * k + 1], u0 / 1.5, 1e-9),
            "x2 {}",
            r.x[2 * k + 1]
        );
    }
    // The rest state 0.4 is outside 'high' (x1 >= 1): the run is in 'low'.
    assert_eq!(r.modes[0], Some(1));
    // The same rest state from the estimate's run: nothing to estimate.
    assert_eq!(run_from(&c, &m.values(), &[], &data).unwrap(), r);

    // A nonlinear rest state: a tank's Torricelli outflow `c sqrt(x)`
    // balances the inflow `u` at `x = (u / c)^2`.
    let tank = one_state(
        r#"{ from = "steady", values = { x = 1.0 } }"#,
        "u - 0.3*sqrt(max(x, 0))",
    );
    let c = CompiledModel::new(&tank).unwrap();
    let r = run(&c, &tank.values(), &data).unwrap();
    assert!(close(r.x[0], (u0 / 0.3f64).powi(2), 1e-12), "x {}", r.x[0]);

    let none = one_state(r#"{ from = "steady" }"#, "1 + x^2 + u^2");
    let c = CompiledModel::new(&none).unwrap();
    let e = run(&c, &none.values(), &data).unwrap_err();
    assert!(
        matches!(&e, SimError::InitialState(m) if m.contains("no rest state")),
        "{e}"
    );
}

/// A file's estimate of an unknown state, bounds with low above high, a
/// state both measured and estimated, and an output map not affine in the
/// measured state are refused when the file is read.
#[test]
fn bad_rules_are_refused_when_read() {
    let cases = [
        (
            cascade(
                "x2",
                r#"{ from = "measured", position = "x2", estimate = { x3 = [0.0, 1.0] } }"#,
            ),
            "initial_state, estimate: 'x3' is not a state",
        ),
        (
            cascade(
                "x2",
                r#"{ from = "given", estimate = { x1 = [2.0, 1.0] } }"#,
            ),
            "estimate of 'x1': need finite bounds [low, high] with low <= high",
        ),
        (
            // Each bound finite, their distance not: the box-normalised
            // search would read NaN.
            cascade(
                "x2",
                r#"{ from = "given", estimate = { x1 = [-1e308, 1e308] } }"#,
            ),
            "estimate of 'x1': need finite bounds [low, high] with low <= high (and high - low finite)",
        ),
        (
            cascade(
                "x2",
                r#"{ from = "measured", position = "x2", estimate = { x2 = [0.0, 1.0] } }"#,
            ),
            "'x2' is measured by the rule; it cannot also be estimated",
        ),
        (
            cascade("x2^2 + off", r#"{ from = "measured", position = "x2" }"#),
            "output 'y' = 'x2^2 + off' is not affine in 'x2'",
        ),
        (
            cascade("c/x2", r#"{ from = "measured", position = "x2" }"#),
            "is not affine in 'x2'",
        ),
    ];
    for (text, needle) in cases {
        let m: GrayBoxModel = from_toml(&text, None);
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
    }
    // The rest of an affine map is free: other states, inputs, functions
    // of them.
    model(&cascade(
        "(x2 - off)/c + sin(x1)*u",
        r#"{ from = "measured", position = "x2" }"#,
    ));
}

/// The line of an unknown estimated state is the line of its key: not a
/// comment that mentions it, nor a word or string that contains it.
#[test]
fn an_unknown_estimated_state_is_found_at_its_key() {
    let text = format!(
        "# w: the angular speed, not a state of this model\n\
         # (a wheel would need one)\n{}",
        cascade(
            "x2",
            r#"{ from = "measured", position = "x2", estimate = { w = [0.0, 1.0] } }"#,
        )
    );
    let at = text.lines().position(|l| l.contains("estimate")).unwrap() + 1;
    let m: GrayBoxModel = from_toml(&text, None);
    let e = m.validate().unwrap_err();
    assert!(e.to_string().contains("'w' is not a state"), "{e}");
    assert_eq!(e.line_in(&text), Some(at));
    // Written nowhere but in comments and other words: no line.
    let elsewhere = text.replace("estimate = { w = [0.0, 1.0] }", "estimate = {}");
    assert_eq!(e.line_in(&elsewhere), None);
}
