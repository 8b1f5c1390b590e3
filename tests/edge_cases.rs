//! Numerical edge cases and time budgets: each
//! back-end on noise-free data, a constant output, collinear regressors,
//! huge and tiny magnitudes, fewer samples than parameters, c larger than N,
//! more modes than the samples allow, delta <= 0, and a model whose
//! simulation diverges. Every case ends in a clear outcome: a model with
//! finite parameters (exact on noise-free data), or exit code 2 (bad input)
//! or 1 (the method failed) with one line naming the problem. Never 101,
//! never a hang: the records are tiny. The outcomes are tabulated in
//! docs/errors.md, "Numerical edge cases".

use crate::common;

use common::{fail, hysid, ok, one_line_error, report, s, write};
use std::path::{Path, PathBuf};

/// What a run ended with.
enum Outcome {
    /// Exit 0: the model written, and stderr.
    Model(serde_json::Value, String),
    /// Exit 1 or 2 with a one-line message.
    Error(i32, String),
}

/// Runs `identify` with `args` (the output path is added) and checks the
/// outcome is clear: a model whose parameters are all finite, or a one-line
/// error with exit code 1 or 2, and no file then. Anything else (a panic,
/// another exit code, a non-finite parameter) is recorded as a failure and
/// gives `None`.
fn identify(case: &str, dir: &Path, args: &[&str]) -> Option<Outcome> {
    let out = dir.join("model.json");
    let _ = std::fs::remove_file(&out);
    let mut a = vec!["identify"];
    a.extend_from_slice(args);
    a.extend_from_slice(&["-o", s(&out)]);
    let o = hysid(&a);
    match o.status.code() {
        Some(0) => {
            let text = match std::fs::read_to_string(&out) {
                Ok(t) => t,
                Err(e) => {
                    fail(case, format!("exit 0 but no model: {e}"));
                    return None;
                }
            };
            let model: serde_json::Value = serde_json::from_str(&text).unwrap();
            if let Some(bad) = non_finite(&model) {
                fail(case, format!("non-finite parameter {bad} in {text}"));
                return None;
            }
            // The outcome, for the table in docs/errors.md (--nocapture).
            eprintln!(
                "outcome | {case} | exit 0 | {} mode(s) {}",
                thetas(&model).len(),
                model["info"]["diagnostics"]["status"]
                    .as_str()
                    .unwrap_or_default()
            );
            Some(Outcome::Model(
                model,
                String::from_utf8_lossy(&o.stderr).into_owned(),
            ))
        }
        Some(code @ (1 | 2)) => match one_line_error(&o, code) {
            Ok(line) if !out.exists() => {
                eprintln!("outcome | {case} | exit {code} | {line}");
                Some(Outcome::Error(code, line))
            }
            Ok(_) => {
                fail(case, "failed but left a model behind".into());
                None
            }
            Err(e) => {
                fail(case, e);
                None
            }
        },
        other => {
            fail(
                case,
                format!(
                    "exit {other:?}; stderr: {}",
                    String::from_utf8_lossy(&o.stderr)
                ),
            );
            None
        }
    }
}

/// The first parameter (theta entry, region coefficient or mechanical
/// value) that is not a finite number.
fn non_finite(model: &serde_json::Value) -> Option<String> {
    let mut found = None;
    let mut visit = |v: &serde_json::Value, path: &str| {
        if found.is_none() && (v.is_null() || v.as_f64().is_some_and(|x| !x.is_finite())) {
            found = Some(path.to_string());
        }
    };
    if let Some(modes) = model["modes"].as_array() {
        for (i, m) in modes.iter().enumerate() {
            for (j, t) in m["theta"].as_array().into_iter().flatten().enumerate() {
                visit(t, &format!("modes[{i}].theta[{j}]"));
            }
            for row in m["region"]["a"].as_array().into_iter().flatten() {
                for x in row.as_array().into_iter().flatten() {
                    visit(x, &format!("modes[{i}].region.a"));
                }
            }
        }
    }
    for p in model["parameters"].as_array().into_iter().flatten() {
        visit(&p["value"], &format!("parameter {}", p["name"]));
    }
    found
}

/// Expects a model; returns it.
fn expect_model(case: &str, o: Option<Outcome>) -> Option<serde_json::Value> {
    match o? {
        Outcome::Model(m, _) => Some(m),
        Outcome::Error(code, line) => {
            fail(case, format!("expected a model, got exit {code}: {line}"));
            None
        }
    }
}

/// Expects exit `code` with a message containing every needle.
fn expect_error(case: &str, o: Option<Outcome>, code: i32, needles: &[&str]) {
    match o {
        None => {}
        Some(Outcome::Model(m, _)) => fail(case, format!("expected exit {code}, got a model {m}")),
        Some(Outcome::Error(c, line)) => {
            if c != code {
                fail(case, format!("expected exit {code}, got {c}: {line}"));
            }
            for n in needles {
                if !line.contains(n) {
                    fail(case, format!("message lacks '{n}': {line}"));
                }
            }
        }
    }
}

/// The parameters of every mode.
fn thetas(m: &serde_json::Value) -> Vec<Vec<f64>> {
    m["modes"]
        .as_array()
        .map(|modes| {
            modes
                .iter()
                .filter_map(|m| {
                    m["theta"]
                        .as_array()
                        .map(|t| t.iter().filter_map(serde_json::Value::as_f64).collect())
                })
                .collect()
        })
        .unwrap_or_default()
}

/// `truth` recovered by one of the modes to `tol` (relative to the largest
/// entry of `truth`).
fn recovers(case: &str, m: &serde_json::Value, truth: &[f64], tol: f64) {
    let scale = truth.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let ok = thetas(m).iter().any(|t| {
        t.len() == truth.len()
            && t.iter()
                .zip(truth)
                .all(|(a, b)| (a - b).abs() <= tol * scale)
    });
    if !ok {
        fail(
            case,
            format!("{truth:?} not recovered to {tol}: {:?}", thetas(m)),
        );
    }
}

/// A pseudo-random input in [-1, 1), the same on every platform.
fn input(n: usize, seed: u64) -> Vec<f64> {
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % 1000) as f64 / 500.0 - 1.0
        })
        .collect()
}

/// y(k) = a y(k-1) + b u(k-1) + c, with (a, b, c) chosen by the sign of
/// y(k-1) among `modes` (one mode: always the first).
fn pwarx(u: &[f64], modes: &[[f64; 3]]) -> Vec<f64> {
    let mut y = vec![0.0; u.len()];
    for k in 1..u.len() {
        let m = if modes.len() > 1 && y[k - 1] < 0.0 {
            &modes[1]
        } else {
            &modes[0]
        };
        y[k] = m[0] * y[k - 1] + m[1] * u[k - 1] + m[2];
    }
    y
}

/// Writes `t,u,y` (ts = 0.01 s) with `u` and `y` scaled by `scale`.
fn csv(dir: &Path, name: &str, u: &[f64], y: &[f64], scale: f64) -> PathBuf {
    let mut text = String::from("t,u,y\n");
    for k in 0..u.len() {
        text.push_str(&format!(
            "{},{:e},{:e}\n",
            k as f64 * 0.01,
            u[k] * scale,
            y[k] * scale
        ));
    }
    write(dir, name, text)
}

const ONE: [f64; 3] = [0.6, 0.8, 0.2];
const TWO: [[f64; 3]; 2] = [[0.5, 1.0, 0.3], [-0.4, 0.8, -0.2]];

/// The multi-mode back-ends with what they need on a record of output scale
/// `scale` (bounded: an error bound).
fn multi(scale: f64) -> Vec<(&'static str, Vec<String>)> {
    vec![
        ("cluster", vec!["--modes".into(), "2".into()]),
        (
            "bounded",
            vec!["--set".into(), format!("delta={:e}", 0.01 * scale)],
        ),
    ]
}

/// Runs `identify data -m method extra...` (with `--na 1 --nb 1` unless
/// `extra` sets the orders).
/// The options that make `-m physical` fit the mounting head.
fn head() -> Vec<String> {
    vec!["--set".into(), common::HEAD_MODEL_SET.into()]
}

fn run(case: &str, dir: &Path, data: &Path, method: &str, extra: &[String]) -> Option<Outcome> {
    let mut a = vec![s(data), "-m", method];
    if !extra.iter().any(|x| x == "--na") {
        a.extend_from_slice(&["--na", "1", "--nb", "1"]);
    }
    a.extend(extra.iter().map(String::as_str));
    identify(&format!("{case} [{method}]"), dir, &a)
}

#[test]
fn noise_free_data_is_recovered_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u = input(120, 1);
    let one = csv(d, "one.csv", &u, &pwarx(&u, &[ONE]), 1.0);
    let m = expect_model("noise-free arx", run("noise-free", d, &one, "arx", &[]));
    if let Some(m) = m {
        recovers("noise-free arx", &m, &ONE, 1e-9);
    }
    let u = input(240, 2);
    let two = csv(d, "two.csv", &u, &pwarx(&u, &TWO), 1.0);
    for (method, extra) in multi(1.0) {
        let case = format!("noise-free {method}");
        if let Some(m) = expect_model(&case, run("noise-free", d, &two, method, &extra)) {
            recovers(&case, &m, &TWO[0], 1e-6);
            recovers(&case, &m, &TWO[1], 1e-6);
        }
    }
    report();
}

#[test]
fn constant_output_and_collinear_regressors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u = input(120, 3);
    let flat = csv(d, "flat.csv", &u, &vec![3.0; u.len()], 1.0);
    let ones = vec![1.0; 120];
    let held = csv(d, "held.csv", &ones, &pwarx(&ones, &[ONE]), 1.0);
    let zeros = csv(d, "zeros.csv", &vec![0.0; 120], &vec![0.0; 120], 1.0);
    for (name, data) in [
        ("constant output", &flat),
        ("constant input", &held),
        ("all zero", &zeros),
    ] {
        let mut methods = vec![("arx", vec![]), ("physical", head())];
        methods.extend(multi(1.0));
        for (method, extra) in methods {
            let case = format!("{name} [{method}]");
            if data == &zeros && method == "cluster" {
                // Every local dataset is the same: one cluster, and the
                // prior asks for exactly 2 modes (a smaller model would
                // drop it).
                expect_error(
                    &case,
                    run(name, d, data, method, &extra),
                    1,
                    &["exactly 2 modes were asked for, but only 1 of the 2 clusters"],
                );
                continue;
            }
            // Every other one ends in a model (an error would be a
            // failure too); on the flat record every mode predicts the
            // constant output exactly.
            let m = expect_model(&case, run(name, d, data, method, &extra));
            if let Some(m) = m
                && data == &flat
                && method != "physical"
            {
                for t in thetas(&m) {
                    let p = t[0] * 3.0 + t[2];
                    if (p - 3.0).abs() > 1e-6 || t[1].abs() > 1e-6 {
                        fail(&case, format!("does not reproduce y = 3: {t:?}"));
                    }
                }
            }
        }
    }
    report();
}

/// FIT over a constant output is undefined: `validate` says so beside the
/// figure, in its text and its JSON, and not where the output varies.
#[test]
fn validate_says_fit_is_undefined_on_a_constant_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u = input(120, 3);
    let varying = csv(d, "varying.csv", &u, &pwarx(&u, &[ONE]), 1.0);
    let flat = csv(d, "flat.csv", &u, &vec![3.0; u.len()], 1.0);
    let model = d.join("m.json");
    ok(&[
        "identify",
        s(&varying),
        "-m",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "-o",
        s(&model),
    ]);
    let warning = "the scored output is constant: FIT is undefined there";
    let on_flat = hysid(&["validate", s(&model), s(&flat), "--json"]);
    assert!(on_flat.status.success());
    let stderr = String::from_utf8_lossy(&on_flat.stderr);
    assert!(
        stderr.contains(&format!("hysid: warning: {warning}")),
        "{stderr}"
    );
    let report: serde_json::Value = serde_json::from_slice(&on_flat.stdout).unwrap();
    assert_eq!(report["constant_output"], true, "{report}");
    assert_eq!(report["fit_sim"], 0.0, "{report}");
    let on_varying = hysid(&["validate", s(&model), s(&varying), "--json"]);
    let stderr = String::from_utf8_lossy(&on_varying.stderr);
    assert!(!stderr.contains(warning), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&on_varying.stdout).unwrap();
    assert!(report.get("constant_output").is_none(), "{report}");
    // `compare` says it once, in its report and on stderr, where the rows
    // it scores are constant.
    for (scored, constant) in [("flat.csv", true), ("varying.csv", false)] {
        let experiment = d.join("experiment.toml");
        std::fs::write(
            &experiment,
            format!(
                "title = \"flat\"\nna = 1\nnb = 1\n[data]\nfile = \"varying.csv\"\n\
                 identification = \"0..80\"\n[[data.records]]\nfile = \"{scored}\"\n\
                 validation = \"80..\"\n[[run]]\nname = \"arx\"\nmethod = \"arx\"\n"
            ),
        )
        .unwrap();
        let out = d.join(format!("out-{scored}"));
        let o = hysid(&["compare", s(&experiment), "-o", s(&out)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (stdout, stderr) = (
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr),
        );
        assert_eq!(
            stdout.contains(&format!("**Warning:** {warning}")),
            constant,
            "{stdout}"
        );
        assert_eq!(
            stderr.matches(warning).count(),
            usize::from(constant),
            "{stderr}"
        );
    }
}

#[test]
fn huge_and_tiny_magnitudes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u = input(120, 4);
    let y = pwarx(&u, &[ONE]);
    let u2 = input(240, 5);
    let y2 = pwarx(&u2, &TWO);
    for scale in [1e12, 1e-12] {
        let one = csv(d, &format!("one-{scale:e}.csv"), &u, &y, scale);
        let case = format!("scale {scale:e} [arx]");
        if let Some(m) = expect_model(&case, run(&format!("scale {scale:e}"), d, &one, "arx", &[]))
        {
            recovers(&case, &m, &[ONE[0], ONE[1], ONE[2] * scale], 1e-6);
        }
        let two = csv(d, &format!("two-{scale:e}.csv"), &u2, &y2, scale);
        for (method, extra) in multi(scale) {
            let case = format!("scale {scale:e} [{method}]");
            if let Some(m) = expect_model(
                &case,
                run(&format!("scale {scale:e}"), d, &two, method, &extra),
            ) {
                let t = TWO.map(|t| [t[0], t[1], t[2] * scale]);
                recovers(&case, &m, &t[0], 1e-3);
                recovers(&case, &m, &t[1], 1e-3);
            }
        }
    }
    report();
}

#[test]
fn too_few_samples_too_many_modes_and_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u = input(4, 6);
    let tiny = csv(d, "tiny.csv", &u, &pwarx(&u, &[ONE]), 1.0);
    let orders = ["--na", "2", "--nb", "2"].map(String::from);
    for (method, mut extra) in [("arx", vec![]), ("physical", head())]
        .into_iter()
        .chain(multi(1.0))
    {
        extra.extend(orders.iter().cloned());
        let case = format!("fewer samples than parameters [{method}]");
        let o = run("fewer samples than parameters", d, &tiny, method, &extra);
        if method == "physical" {
            // The mechanical model has its own parameter count (11 free
            // parameters of the head, 10 samples for the initial state).
            expect_error(
                &case,
                o,
                2,
                &[
                    "4 samples for 11 free parameters and the initial state",
                    "need at least 22 (its warm-up reads 10: the model file's rule, or \
                     init_samples)",
                ],
            );
        } else {
            expect_error(&case, o, 2, &["samples", "parameters"]);
        }
    }
    let u = input(60, 7);
    let small = csv(d, "small.csv", &u, &pwarx(&u, &TWO), 1.0);
    let set = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    expect_error(
        "c larger than N",
        run(
            "c larger than N",
            d,
            &small,
            "cluster",
            &set(&["--modes", "2", "--set", "c=500"]),
        ),
        2,
        &["c=500"],
    );
    expect_error(
        "more modes than samples allow [cluster]",
        run(
            "more modes than samples allow",
            d,
            &small,
            "cluster",
            &set(&["--modes", "40"]),
        ),
        2,
        &["40"],
    );
    // Every back-end of a mode count refuses it before fitting.
    for method in ["bounded", "klinreg", "parc", "bayes", "milp"] {
        let delta = ["--set", "delta=0.01"];
        let extra: &[&str] = if method == "bounded" { &delta } else { &[] };
        expect_error(
            &format!("more modes than samples allow [{method}]"),
            run(
                "more modes than samples allow",
                d,
                &small,
                method,
                &set(&[&["--modes", "40"], extra].concat()),
            ),
            2,
            &["regressors cannot identify 40 modes of 3 parameters"],
        );
    }
    // A count the record could hold but delta does not call for: bounded
    // finds the modes delta explains the data with, then fails the prior.
    expect_error(
        "fewer modes than the prior [bounded]",
        run(
            "fewer modes than the prior",
            d,
            &small,
            "bounded",
            &set(&["--modes", "9", "--set", "delta=0.01"]),
        ),
        1,
        &["fewer than the prior modes = 9"],
    );
    for delta in ["0", "-1", "-0", "nan", "inf"] {
        expect_error(
            &format!("delta={delta}"),
            run(
                "delta",
                d,
                &small,
                "bounded",
                &set(&["--set", &format!("delta={delta}")]),
            ),
            2,
            &["--set delta=", "must be a finite number > 0"],
        );
    }
    report();
}

#[test]
fn a_diverging_simulation_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u = input(400, 8);
    let data = csv(d, "data.csv", &u, &pwarx(&u, &[ONE]), 1.0);
    let model = write(
        d,
        "unstable.json",
        r#"{"kind":"pwarx","na":1,"nb":1,"inputs":1,
            "modes":[{"theta":[1.5,1.0,0.0],"region":{"a":[],"b":[]}}]}"#,
    );
    let out = d.join("sim.csv");
    // Both commands finish (exit 0) and warn on one line where the output
    // left the range of the data by far; the simulation is held from there.
    for (what, args) in [
        ("validate", vec!["validate", s(&model), s(&data), "--json"]),
        (
            "simulate",
            vec!["simulate", s(&model), "--data", s(&data), "-o", s(&out)],
        ),
    ] {
        let o = hysid(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        eprintln!(
            "outcome | diverging simulation [{what}] | exit {:?} | {}",
            o.status.code(),
            err.lines().next().unwrap_or("")
        );
        assert_eq!(o.status.code(), Some(0), "{what}: {err}");
        assert!(
            err.lines()
                .any(|l| l.starts_with("hysid: warning: the simulation diverged at sample")),
            "{what}: {err}"
        );
        if what == "validate" {
            let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            assert!(report["diverged_at"].as_u64().is_some(), "{report}");
            assert_eq!(report["diverged_to"], "bound", "{report}");
        }
    }
}

/// A flow that takes the square root of a state driven below zero gives an
/// undefined output: said as such, not as a divergence of magnitude.
#[test]
fn an_undefined_simulated_output_is_named_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = write(
        d,
        "tank.toml",
        r#"kind = "gray_box"
format = 1
internal_step = 0.01
states = ["h"]
inputs = ["u"]
outputs = ["h"]
initial_state = { from = "given", values = { h = 1.0 } }
parameters = [{ name = "a", value = 1.0, bounds = [0.1, 10.0] }]
[[modes]]
name = "only"
flow = { h = "u - a*sqrt(h)" }
"#,
    );
    let data = d.join("drained.csv");
    let excite = "n=200,hold=20,low=-1,high=0,ts=0.1";
    let o = hysid(&["simulate", s(&model), "--excite", excite, "-o", s(&data)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("hysid: warning: the simulated output became undefined (NaN) at sample"),
        "{err}"
    );
    let o = hysid(&["validate", s(&model), s(&data), "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["diverged_to"], "undefined", "{report}");
    assert!(!String::from_utf8_lossy(&o.stderr).contains("diverged at"));
    // A fit names the undefined output of the file's own values: a search
    // where every candidate fails, and bad input where nothing is free.
    let fixed = write(
        d,
        "fixed.toml",
        std::fs::read_to_string(&model).unwrap().replace(
            "bounds = [0.1, 10.0] }",
            "bounds = [0.1, 10.0], fixed = true }",
        ),
    );
    let undefined = "own values, the simulated output became undefined (NaN) at sample";
    for (file, code, said) in [
        (&model, 1, "every candidate simulation failed or diverged"),
        (&fixed, 2, "nothing in the model is free to fit"),
    ] {
        let out = d.join("fitted.json");
        let set = format!("model={}", s(file));
        let o = hysid(&[
            "identify",
            s(&data),
            "-m",
            "physical",
            "--set",
            &set,
            "-o",
            s(&out),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{err}");
        assert!(err.contains(said), "{err}");
        assert!(err.contains(undefined), "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn a_tiny_time_budget_returns_the_best_model_with_a_status() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u = input(240, 9);
    let two = csv(d, "two.csv", &u, &pwarx(&u, &TWO), 1.0);
    let mut methods = multi(1.0);
    methods.push(("physical", head()));
    for (method, mut extra) in methods {
        extra.extend(["--time-budget", "0.001"].map(String::from));
        let case = format!("time budget [{method}]");
        match run("time budget 1 ms", d, &two, method, &extra) {
            Some(Outcome::Model(m, err)) => {
                let status = m["info"]["diagnostics"]["status"].as_str().unwrap_or("");
                if !status.contains("time budget") {
                    fail(
                        &case,
                        format!("no time-budget status: {}", m["info"]["diagnostics"]),
                    );
                }
                if !err.contains(status) {
                    fail(&case, format!("status not printed: {err}"));
                }
            }
            Some(Outcome::Error(c, l)) if !l.contains("time budget") => {
                fail(&case, format!("exit {c} without naming the budget: {l}"));
            }
            _ => {}
        }
    }
    report();
}
