//! Gray-box initial states the rule leaves unknown, from the program:
//! `validate` and `simulate --data` estimate them from the record's
//! warm-up and report them; bad rules are one-line errors naming the file.

use crate::common;

use common::{hysid, ok, one_line_error, s, write};
use std::path::{Path, PathBuf};

/// Two first-order lags in cascade with the output `output` and the
/// initial state `initial`.
fn cascade(output: &str, initial: &str) -> String {
    format!(
        r#"kind = "gray_box"
format = 1
internal_step = 0.025
states = ["x1", "x2"]
inputs = ["u"]
outputs = [{{ name = "y", value = "{output}" }}]
initial_state = {initial}
parameters = [
    {{ name = "a", value = 0.8, bounds = [0.2, 4.0] }},
    {{ name = "b", value = 2.0, bounds = [0.2, 4.0] }},
    {{ name = "c", value = 1.5, bounds = [0.2, 4.0] }},
    {{ name = "off", value = -0.3, bounds = [-2.0, 2.0] }},
]

[[modes]]
name = "only"
flow = {{ x1 = "-a*x1 + u", x2 = "b*(x1 - x2)" }}
"#
    )
}

/// The cascade's true initial state.
const TRUTH: &str = r#"{ from = "given", values = { x1 = 2.25, x2 = 0.5 } }"#;

/// `record.csv` in `d`: the model `truth` driven by held random levels,
/// 200 samples of 50 ms, seed 1.
fn record_of(d: &Path, truth: &str) -> PathBuf {
    let file = write(d, "truth.toml", truth);
    let record = d.join("record.csv");
    ok(&[
        "simulate",
        s(&file),
        "--excite",
        "n=200,hold=10,low=-1,high=1,ts=0.05",
        "--seed",
        "1",
        "-o",
        s(&record),
    ]);
    record
}

const ESTIMATE: &str =
    r#"{ from = "measured", samples = 10, position = "x2", estimate = { x1 = [-5.0, 5.0] } }"#;

/// `validate` prints the state estimated from the warm-up and its JSON
/// carries it; rows after the warm-up changed leave it unchanged;
/// `simulate --data` reports it on stderr.
#[test]
fn validate_and_simulate_report_the_estimated_initial_state() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let record = record_of(d, &cascade("c*x2 + off", TRUTH));
    let model = write(d, "estimate.toml", cascade("c*x2 + off", ESTIMATE));
    let text = ok(&["validate", s(&model), s(&record), "--warmup", "10"]);
    assert!(text.contains("initial   x1 = 2.2"), "{text}");
    let estimate = |data: &std::path::Path| -> f64 {
        let json = ok(&["validate", s(&model), s(data), "--warmup", "10", "--json"]);
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        v["initial_states"]["x1"].as_f64().unwrap()
    };
    let x1 = estimate(&record);
    assert!((x1 - 2.25).abs() <= 1e-6 * 2.25, "{x1}");

    // The same record with every row after the warm-up changed.
    let csv = std::fs::read_to_string(&record).unwrap();
    let mut lines: Vec<String> = csv.lines().map(str::to_string).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let y = header.iter().position(|h| *h == "y").unwrap();
    for line in lines.iter_mut().skip(11) {
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        cells[y] = format!("{}", cells[y].parse::<f64>().unwrap() + 1.5);
        *line = cells.join(",");
    }
    let changed = write(d, "changed.csv", lines.join("\n") + "\n");
    assert_eq!(estimate(&changed).to_bits(), x1.to_bits());

    // A given rule with an estimate scores no sample its warm-up read,
    // whatever --warmup.
    let given = write(
        d,
        "given.toml",
        cascade(
            "c*x2 + off",
            r#"{ from = "given", values = { x2 = 0.5 }, estimate = { x1 = [-5.0, 5.0] }, samples = 10 }"#,
        ),
    );
    let json = ok(&["validate", s(&given), s(&record), "--warmup", "0", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["n"], 190, "{v}");
    let text = ok(&["validate", s(&given), s(&record), "--warmup", "0"]);
    let said = "190 samples (warm-up 0; 10 samples left out: the model's initial state reads them)";
    assert!(text.contains(said), "{text}");

    let out = d.join("sim.csv");
    let o = hysid(&["simulate", s(&model), "--data", s(&record), "-o", s(&out)]);
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("initial state estimated from the warm-up: x1 = 2.2"),
        "{err}"
    );

    // Driven by an excitation, a run that estimates its state starts at
    // sample 0: no row holds --y0, and none is said to.
    let o = hysid(&[
        "simulate",
        s(&model),
        "--excite",
        "n=50,hold=10,low=1,high=2,ts=0.05",
        "--y0",
        "0.7",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("the rows before it hold"), "{err}");
}

/// A state the warm-up does not show (it reaches the output only past a
/// dead zone it never leaves) is reported as its starting guess, in the
/// text and the JSON; a state it shows is not.
#[test]
fn a_state_the_warm_up_does_not_show_is_named_as_its_guess() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let seen = cascade("c*x2 + off", ESTIMATE);
    let hidden = seen.replace("b*(x1 - x2)", "b*(max(x1 - 6, 0) - x2)");
    assert_ne!(seen, hidden);
    let record = record_of(d, &seen);
    let report = |text: &str| -> (String, serde_json::Value) {
        let model = write(d, "m.toml", text);
        let args = ["validate", s(&model), s(&record), "--warmup", "10"];
        let json = ok(&[&args[..], &["--json"]].concat());
        (ok(&args), serde_json::from_str(&json).unwrap())
    };
    let (text, json) = report(&hidden);
    assert!(
        text.contains("x1 = 0.0 (not determined: moving it changes none of the warm-up's outputs)"),
        "{text}"
    );
    assert_eq!(json["unseen_initial_states"], serde_json::json!(["x1"]));
    let (text, json) = report(&seen);
    assert!(!text.contains("starting guess"), "{text}");
    assert!(json.get("unseen_initial_states").is_none(), "{json}");
}

/// A range that leaves out the true state (2.25): the estimate stops on
/// its bound, and `validate` says so in the text and the JSON.
#[test]
fn a_state_estimated_on_its_bound_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let record = record_of(d, &cascade("c*x2 + off", TRUTH));
    let narrow = ESTIMATE.replace("[-5.0, 5.0]", "[-5.0, 1.0]");
    let model = write(d, "narrow.toml", cascade("c*x2 + off", &narrow));
    let args = ["validate", s(&model), s(&record), "--warmup", "10"];
    let text = ok(&args);
    assert!(
        text.contains(
            "x1 = 1.0 (on a bound of its estimate range: the warm-up may ask for a value outside it)"
        ),
        "{text}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&ok(&[&args[..], &["--json"]].concat())).unwrap();
    assert_eq!(json["initial_states_at_bound"], serde_json::json!(["x1"]));
}

/// An estimate of an unknown state, bounds with low above high, an output
/// map not affine in the measured state, and a `steady` rule without a rest
/// state: each a one-line error naming the file, exit code 2.
#[test]
fn bad_initial_state_rules_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let record = write(
        d,
        "record.csv",
        (0..40)
            .map(|k| {
                format!(
                    "{},{},{}\n",
                    k as f64 * 0.05,
                    (k % 7) as f64 * 0.1,
                    k as f64 * 0.01
                )
            })
            .fold("t,u,y\n".to_string(), |a, l| a + &l),
    );
    let cases = [
        (
            "unknown.toml",
            cascade(
                "x2",
                r#"{ from = "measured", position = "x2", estimate = { x3 = [0.0, 1.0] } }"#,
            ),
            "'x3' is not a state",
        ),
        (
            "bounds.toml",
            cascade(
                "x2",
                r#"{ from = "given", estimate = { x1 = [2.0, 1.0] } }"#,
            ),
            "estimate of 'x1': need finite bounds [low, high] with low <= high",
        ),
        (
            "affine.toml",
            cascade("c*x2^2 + off", r#"{ from = "measured", position = "x2" }"#),
            "output 'y' = 'c*x2^2 + off' is not affine in 'x2'",
        ),
        (
            "rest.toml",
            cascade("x2", r#"{ from = "steady" }"#).replace("-a*x1 + u", "1 + x1^2"),
            "initial state: no rest state under the first input",
        ),
        (
            "warmup.toml",
            cascade(
                "x2",
                r#"{ from = "given", values = { x1 = 0.5 }, samples = 10 }"#,
            ),
            "samples: a given rule reads a warm-up only to estimate states",
        ),
        (
            // A reset outside its target's invariant is an error; so is a
            // given state outside the mode the rule names.
            "outside.toml",
            cascade(
                "x2",
                r#"{ from = "given", values = { x1 = 2.0 }, mode = "only" }"#,
            )
            .replace(
                "name = \"only\"\n",
                "name = \"only\"\ninvariant = [\"x1 <= 1\"]\n",
            ),
            "lies outside the invariant of the mode it names, 'only'",
        ),
    ];
    for (name, text, needle) in cases {
        let model = write(d, name, text);
        let err = one_line_error(&hysid(&["validate", s(&model), s(&record)]), 2)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(err.contains(name) && err.contains(needle), "{name}: {err}");
    }
    // The affine map's error also gives the line of the output.
    let err = one_line_error(
        &hysid(&["validate", s(&d.join("affine.toml")), s(&record)]),
        2,
    )
    .unwrap();
    assert!(err.contains("affine.toml, line 6"), "{err}");
}

/// A physical fit says what its diagnostics hold about the values: a
/// parameter and an estimated initial state that ended at a bound, and a
/// parameter the rows do not determine, each one warning line; a fit with
/// none says nothing more.
#[test]
fn identify_warns_of_values_at_a_bound_and_parameters_without_effect() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let record = record_of(d, &cascade("c*x2 + off", TRUTH));
    let fit = |text: String, prior: &str| -> String {
        let model = write(d, "m.toml", text);
        let prior = write(d, "p.toml", prior);
        let out = d.join("fit.json");
        let o = hysid(&[
            "identify",
            s(&record),
            "-m",
            "physical",
            "--set",
            &format!("model={}", s(&model)),
            "--prior",
            s(&prior),
            "--seed",
            "1",
            "-o",
            s(&out),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    // Everything free and within its bounds: no warning.
    let free = "[fixed]\nc = 1.5\noff = -0.3\n";
    let said = fit(cascade("c*x2 + off", ESTIMATE), free);
    assert!(!said.contains("warning"), "{said}");
    // `a` held above its value, and `c` free in a model whose output does
    // not read it.
    let said = fit(
        cascade("1.5*x2 + off", ESTIMATE),
        "[fixed]\noff = -0.3\n[bounds]\na = [1.5, 4.0]\n",
    );
    assert!(
        said.contains("hysid: warning: physical: a = 1.5 ended at a bound"),
        "{said}"
    );
    assert!(
        said.contains("hysid: warning: physical: c: no effect on the identification rows"),
        "{said}"
    );
    // `x1` estimated above its own value.
    let narrow = ESTIMATE.replace("[-5.0, 5.0]", "[3.0, 5.0]");
    let said = fit(
        cascade("c*x2 + off", &narrow),
        "[fixed]\na = 0.8\nc = 1.5\noff = -0.3\n",
    );
    assert!(
        said.contains("the estimated initial state x1 = 3 ended at a bound of its estimate"),
        "{said}"
    );
}
