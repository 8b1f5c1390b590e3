//! End-to-end tests of the `hysid` program: the contract of
//! `docs/cli.md` and `docs/file-formats.md` (commands, files, exit codes, no
//! partial output).

use crate::common;

use common::{hysid, ok, one_line_error, s, two_mode_record};
use std::path::{Path, PathBuf};

/// Exit code 2, a one-line message containing every `needle`, and no file at `out`.
fn bad(args: &[&str], needles: &[&str], out: &Path) {
    let err = one_line_error(&hysid(args), 2).unwrap_or_else(|e| panic!("{args:?}: {e}"));
    for n in needles {
        assert!(err.contains(n), "{args:?}: message lacks '{n}': {err}");
    }
    assert!(!out.exists(), "{args:?}: left an output file behind");
}

/// A record from the ARX model y(k) = 0.6 y(k-1) - 0.1 y(k-2) + 0.8 u(k-1) + 0.3 u(k-2) + 0.2,
/// written by `hysid simulate` itself from a hand-written model file.
fn arx_record(dir: &Path) -> PathBuf {
    let model = dir.join("true.json");
    std::fs::write(
        &model,
        r#"{"kind":"pwarx","na":2,"nb":2,"inputs":1,
            "modes":[{"theta":[0.6,-0.1,0.8,0.3,0.2],"region":{"a":[],"b":[]}}]}"#,
    )
    .unwrap();
    let data = dir.join("data.csv");
    ok(&[
        "simulate",
        s(&model),
        "--excite",
        "n=400,hold=3,low=-1,high=1,ts=0.01",
        "--seed",
        "5",
        "-o",
        s(&data),
    ]);
    data
}

/// `hysid methods | head`: a reader that stops reading ends the program
/// quietly, not with an internal error, with or without `RUST_BACKTRACE`
/// (which prints the report of a real panic).
#[test]
fn a_closed_standard_output_ends_quietly() {
    for backtrace in ["0", "1"] {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_hysid"))
            .arg("methods")
            .env("RUST_BACKTRACE", backtrace)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.is_empty(), "RUST_BACKTRACE={backtrace}: {err}");
        assert!(out.status.success(), "{:?}", out.status);
    }
}

#[test]
fn methods_lists_arx_with_its_options() {
    let out = ok(&["methods"]);
    assert!(out.contains("model files: gray_box format 1"), "{out}");
    assert!(out.lines().any(|l| l.starts_with("arx")), "{out}");
    assert!(out.contains("ridge"));
    let arx = ok(&["methods", "arx"]);
    assert!(arx.contains("--auto tries: the orders"), "{arx}");
    assert!(arx.contains("seed: does not change the model"), "{arx}");
    let bayes = ok(&["methods", "bayes"]).replace("\n          ", " ");
    assert!(
        bayes.contains("seed: can change the model with posterior = particles"),
        "{bayes}"
    );
    assert!(arx.lines().any(|l| l.starts_with("    ridge (")), "{arx}");
    // Every line of the list and of one method in full fits 120 columns.
    for text in [&out, &arx, &ok(&["methods", "cluster"])] {
        let long: Vec<&str> = text.lines().filter(|l| l.chars().count() > 120).collect();
        assert!(long.is_empty(), "{long:?}");
    }
    // `identify -h` groups its flags under headings, one short line each.
    let help = ok(&["identify", "-h"]);
    let long: Vec<&str> = help.lines().filter(|l| l.chars().count() > 100).collect();
    assert!(long.is_empty(), "{long:?}");
    for heading in ["Method:", "Priors:", "Selection:", "Data:", "Output:"] {
        assert!(help.lines().any(|l| l == heading), "{heading} in {help}");
    }
    let bad = hysid(&["methods", "nosuch"]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{err}");
    assert!(
        err.contains("unknown method") && err.contains("cluster"),
        "{err}"
    );
    let json: serde_json::Value = serde_json::from_str(&ok(&["methods", "--json"])).unwrap();
    assert_eq!(json[0]["name"], "arx");
    // With a name, that back-end's object; an unknown one is refused.
    let one: serde_json::Value =
        serde_json::from_str(&ok(&["methods", "cluster", "--json"])).unwrap();
    assert_eq!(one["name"], "cluster");
    assert_eq!(one, json[1]);
    assert_eq!(
        hysid(&["methods", "nosuch", "--json"]).status.code(),
        Some(2)
    );
    // No command: the help with the list of commands, a usage error.
    let none = hysid(&[]);
    let err = String::from_utf8_lossy(&none.stderr);
    assert_eq!(none.status.code(), Some(2), "{err}");
    assert!(
        err.contains("Commands:") && err.contains("identify"),
        "{err}"
    );
    assert!(
        json[1]["search"]
            .as_str()
            .unwrap()
            .contains("c: the five largest of 4, 6"),
        "{json}"
    );
    // arx is a least-squares fit; cluster's K-means starts are drawn.
    assert_eq!(
        (&json[0]["seeded"], &json[1]["seeded"]),
        (&false.into(), &true.into())
    );
    assert!(arx.contains("seed: does not change the model"), "{arx}");
}

/// A record whose columns have the user's names: `--time` names the time
/// column (the sampling time is its first step), and the model names its
/// signals as the file does; a time column that is not there is an error
/// naming it.
#[test]
fn a_record_with_its_own_column_names() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let text = std::fs::read_to_string(&data).unwrap();
    let (header, rows) = text.split_once('\n').unwrap();
    assert!(header.starts_with("t,u,y"), "{header}");
    let renamed = dir.path().join("rec.csv");
    let header = header.replacen("t,u,y", "time,force,pos", 1);
    std::fs::write(&renamed, format!("{header}\n{rows}")).unwrap();
    let model = dir.path().join("m.json");
    let args = |time: &str| {
        vec![
            "identify".to_string(),
            s(&renamed).to_string(),
            "--time".into(),
            time.into(),
            "--input".into(),
            "force".into(),
            "--output".into(),
            "pos".into(),
            "-m".into(),
            "arx".into(),
            "--na".into(),
            "1".into(),
            "--nb".into(),
            "1".into(),
            "-o".into(),
            s(&model).to_string(),
        ]
    };
    let run = |time: &str| {
        let a = args(time);
        hysid(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let out = run("time");
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["info"]["input_names"], serde_json::json!(["force"]));
    assert_eq!(m["info"]["output_name"], "pos");
    assert!(
        (m["info"]["ts"].as_f64().unwrap() - 0.01).abs() < 1e-12,
        "{m}"
    );
    std::fs::remove_file(&model).unwrap();
    let out = run("clock");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("'clock'") && err.contains("time"), "{err}");
    assert!(!model.exists());
}

/// The README's "Your own record": identify with options chosen inside the
/// rows given, validate on rows the fit did not see, draw the figure.
#[test]
fn your_own_record_identified_validated_and_plotted() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let text = std::fs::read_to_string(&data).unwrap();
    let rec = dir.path().join("rec.csv");
    std::fs::write(&rec, text.replacen("t,u,y", "time,force,pos", 1)).unwrap();
    let (model, figure) = (dir.path().join("m.json"), dir.path().join("fit.svg"));
    let signals = ["--time", "time", "--input", "force", "--output", "pos"];
    let mut identify = vec!["identify", s(&rec)];
    identify.extend(signals);
    identify.extend([
        "--rows",
        "0..220",
        "-m",
        "cluster",
        "--auto",
        "-o",
        s(&model),
    ]);
    ok(&identify);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["info"]["input_names"], serde_json::json!(["force"]));
    assert_eq!(m["info"]["output_name"], "pos");
    // The signals the model was identified on are read without naming them.
    let mut validate = vec!["validate", s(&model), s(&rec), "--time", "time"];
    validate.extend(["--rows", "220..", "--plot", s(&figure)]);
    let printed = ok(&validate);
    let fit = printed
        .lines()
        .find_map(|l| l.strip_prefix("fit_sim"))
        .and_then(|l| l.split_whitespace().next())
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("no fit_sim: {printed}"));
    let svg = std::fs::read_to_string(&figure).unwrap();
    assert!(
        svg.starts_with("<svg") || svg.starts_with("<?xml"),
        "not an SVG"
    );
    for needle in ["measured pos", "simulated", &format!("fit_sim {fit:.1} %")] {
        assert!(svg.contains(needle), "the figure lacks '{needle}'");
    }
    // A figure this build cannot write is refused before anything is printed.
    let pdf = dir.path().join("fit.pdf");
    validate.pop();
    validate.push(s(&pdf));
    bad(&validate, &["--plot", "fit.pdf", ".svg"], &pdf);
}

#[test]
fn simulate_identify_validate_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let header = std::fs::read_to_string(&data).unwrap();
    assert!(header.starts_with("t,u,y,mode\n"), "{}", &header[..40]);
    let model = dir.path().join("m.json");
    ok(&[
        "identify",
        s(&data),
        "-m",
        "arx",
        "--na",
        "2",
        "--nb",
        "2",
        "-o",
        s(&model),
    ]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["kind"], "pwarx");
    let theta: Vec<f64> = m["modes"][0]["theta"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    for (a, b) in theta.iter().zip([0.6, -0.1, 0.8, 0.3, 0.2]) {
        assert!((a - b).abs() < 1e-9, "{theta:?}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["validate", s(&model), s(&data), "--json"])).unwrap();
    for key in [
        "n",
        "warmup",
        "fit_sim",
        "rmse_sim",
        "fit_pred",
        "rmse_pred",
        "coverage",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["n"], 390);
    assert!(v["fit_sim"].as_f64().unwrap() > 99.999_999);
    assert_eq!(v["coverage"], 1.0);
}

#[test]
fn standardized_identification_is_reported_in_original_units() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let model = dir.path().join("m.json");
    ok(&[
        "identify",
        s(&data),
        "-m",
        "arx",
        "--standardize",
        "-o",
        s(&model),
    ]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let theta: Vec<f64> = m["modes"][0]["theta"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    for (a, b) in theta.iter().zip([0.6, -0.1, 0.8, 0.3, 0.2]) {
        assert!((a - b).abs() < 1e-9, "{theta:?}");
    }
    assert!(m["info"]["scaling"]["output"]["std"].as_f64().unwrap() > 0.0);
    // A tie on the offset is refused naming the tie and its file.
    let priors = common::write(
        dir.path(),
        "tied.toml",
        "modes = 2\n[[tie]]\nparams = [\"a1\"]\n[[tie]]\nparams = [\"c\"]\n",
    );
    let refused = hysid(&[
        "identify",
        s(&data),
        "-m",
        "cluster",
        "--prior",
        s(&priors),
        "--standardize",
        "-o",
        s(&model),
    ]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(
        err.contains("[[tie]] #2 of ") && err.contains("tied.toml"),
        "{err}"
    );
}

#[test]
fn same_seed_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let (a, b) = (dir.path().join("a.json"), dir.path().join("b.json"));
    ok(&[
        "identify",
        s(&data),
        "-m",
        "arx",
        "--seed",
        "9",
        "-o",
        s(&a),
    ]);
    ok(&[
        "identify",
        s(&data),
        "-m",
        "arx",
        "--seed",
        "9",
        "-o",
        s(&b),
    ]);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let (c, d) = (dir.path().join("c.csv"), dir.path().join("d.csv"));
    for p in [&c, &d] {
        ok(&[
            "simulate",
            s(&a),
            "--excite",
            "n=50,hold=5,low=0,high=1",
            "--noise",
            "0.1",
            "--seed",
            "3",
            "-o",
            s(p),
        ]);
    }
    assert_eq!(std::fs::read(&c).unwrap(), std::fs::read(&d).unwrap());
}

#[test]
fn bad_csv_files_name_file_row_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never.json");
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "nan.csv",
            "u,y\n1,2\n3,NaN\n4,5\n",
            &["nan.csv", "row 2", "column 'y'", "non-finite"],
        ),
        (
            "text.csv",
            "u,y\n1,2\n3,4\nabc,5\n",
            &["text.csv", "row 3", "column 'u'", "'abc'"],
        ),
        (
            "ragged.csv",
            "u,y\n1,2\n3\n4,5\n",
            &["ragged.csv", "row 2", "1 fields"],
        ),
        (
            "missing.csv",
            "u,z\n1,2\n3,4\n",
            &["missing.csv", "no column 'y'"],
        ),
        ("empty.csv", "", &["empty.csv"]),
    ];
    for (name, text, needles) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        bad(
            &[
                "identify",
                s(&p),
                "-m",
                "arx",
                "--na",
                "1",
                "--nb",
                "1",
                "-o",
                s(&out),
            ],
            needles,
            &out,
        );
    }
}

#[test]
fn bad_options_and_files_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let out = dir.path().join("never.json");
    let d = s(&data);
    let o = s(&out);
    bad(
        &["identify", d, "-m", "nosuch", "-o", o],
        &["unknown method 'nosuch'", "arx"],
        &out,
    );
    // Named as such before the record is read: one without `u` would
    // otherwise be refused for the column.
    let no_u = dir.path().join("no-u.csv");
    let text = std::fs::read_to_string(&data).unwrap();
    let header = text.lines().next().unwrap();
    std::fs::write(&no_u, text.replacen(header, &header.replace('u', "v"), 1)).unwrap();
    let grid = [
        "--grid",
        "na=1,2",
        "--identify-rows",
        "0..100",
        "--select-rows",
        "100..200",
    ];
    for args in [
        vec!["identify", s(&no_u), "-m", "nosuch", "-o", o],
        [&["sweep", s(&no_u), "-m", "nosuch"][..], &grid].concat(),
    ] {
        bad(&args, &["unknown method 'nosuch'", "arx"], &out);
    }
    // A mistyped flag or command names the one meant.
    bad(
        &["identify", d, "-m", "arx", "--priors", "p.toml", "-o", o],
        &[
            "unexpected argument '--priors'",
            "a similar one exists: '--prior'",
        ],
        &out,
    );
    bad(&["identfy", d], &["a similar one exists: 'identify'"], &out);
    bad(
        &["identify", d, "-m", "arx", "--set", "rigde=1", "-o", o],
        &["rigde", "ridge"],
        &out,
    );
    bad(
        &["identify", d, "-m", "arx", "--set", "ridge=abc", "-o", o],
        &["ridge=abc"],
        &out,
    );
    bad(
        &["identify", d, "-m", "arx", "--modes", "3", "-o", o],
        &["modes = 3"],
        &out,
    );
    bad(
        &["identify", d, "-m", "cluster", "-o", o],
        &[
            "method 'cluster' needs the number of modes",
            "--modes S",
            "--max-modes S",
        ],
        &out,
    );
    // Every PWARX back-end that needs its mode count takes a bound too: the
    // pipeline chooses the count under it.
    bad(
        &["identify", d, "-m", "klinreg", "-o", o],
        &[
            "method 'klinreg' needs the number of modes",
            "--modes S",
            "--max-modes S",
            "--auto",
        ],
        &out,
    );
    bad(
        &[
            "identify",
            d,
            "-m",
            "cluster",
            "--modes",
            "3",
            "--max-modes",
            "2",
            "-o",
            o,
        ],
        &["--modes 3 --max-modes 2", "exceeds max_modes = 2"],
        &out,
    );
    let three = dir.path().join("three.toml");
    std::fs::write(&three, "modes = 3\n").unwrap();
    bad(
        &[
            "identify",
            d,
            "-m",
            "bounded",
            "--set",
            "max_modes=2",
            "--prior",
            s(&three),
            "-o",
            o,
        ],
        &["prior modes = 3 exceeds the option max_modes = 2"],
        &out,
    );
    bad(
        &["identify", d, "-m", "arx", "--rows", "500..", "-o", o],
        &["--rows 500..", "no sample"],
        &out,
    );
    bad(
        &["identify", d, "-m", "arx", "--input", "v", "-o", o],
        &["no column 'v'"],
        &out,
    );
    bad(
        &["identify", "nope.csv", "-m", "arx", "-o", o],
        &["nope.csv"],
        &out,
    );
    bad(
        &["identify", d, "-m", "arx", "--decimate", "0", "-o", o],
        &["decimate"],
        &out,
    );
    let prior = dir.path().join("p.toml");
    std::fs::write(&prior, "mdoes = 3\n").unwrap();
    bad(
        &["identify", d, "-m", "arx", "--prior", s(&prior), "-o", o],
        &["p.toml", "mdoes"],
        &out,
    );
    // No silent stand-in: the physical back-end fits the model file it is given.
    bad(
        &["identify", d, "-m", "physical", "-o", o],
        &[
            "--set model=FILE or",
            "docs/gray-box-models.md",
            "models/pick-and-place/head.toml",
        ],
        &out,
    );
    std::fs::write(&prior, "switching = [\"y1\"]\n").unwrap();
    bad(
        &[
            "identify",
            d,
            "-m",
            "physical",
            "--set",
            common::HEAD_MODEL_SET,
            "--prior",
            s(&prior),
            "-o",
            o,
        ],
        &["does not honour", "switching", "p.toml"],
        &out,
    );
    std::fs::write(&prior, "[fixed]\nq9 = 1.0\n").unwrap();
    bad(
        &["identify", d, "-m", "arx", "--prior", s(&prior), "-o", o],
        &["q9"],
        &out,
    );
    let model = dir.path().join("broken.json");
    std::fs::write(&model, "{\"kind\":\"pwarx\",\"na\":1}").unwrap();
    bad(&["validate", s(&model), d], &["broken.json"], &out);
    let csv_out = dir.path().join("never.csv");
    bad(
        &[
            "simulate",
            s(&model),
            "--excite",
            "n=5,hold=1,low=0,high=1",
            "-o",
            s(&csv_out),
        ],
        &["broken.json"],
        &csv_out,
    );
}

#[test]
fn a_failed_run_never_overwrites_a_good_model() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let model = dir.path().join("m.json");
    ok(&["identify", s(&data), "-m", "arx", "-o", s(&model)]);
    let before = std::fs::read(&model).unwrap();
    let o = hysid(&[
        "identify",
        s(&data),
        "-m",
        "arx",
        "--set",
        "ridge=-1",
        "-o",
        s(&model),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&model).unwrap(), before);
    let leftovers = std::fs::read_dir(dir.path()).unwrap().filter(|e| {
        e.as_ref()
            .unwrap()
            .file_name()
            .to_string_lossy()
            .ends_with(".tmp")
    });
    assert_eq!(leftovers.count(), 0);
}

#[test]
fn help_and_usage_exit_codes() {
    assert_eq!(hysid(&["--help"]).status.code(), Some(0));
    assert_eq!(hysid(&["identify", "--help"]).status.code(), Some(0));
    assert_eq!(hysid(&["identify"]).status.code(), Some(2));
    assert_eq!(hysid(&["frobnicate"]).status.code(), Some(2));
}

#[test]
fn hand_written_automaton_with_lower_dimensional_guard_simulates() {
    let dir = tempfile::tempdir().unwrap();
    let model = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/examples/bouncing-ball.toml"
    );
    let out = dir.path().join("ball.csv");
    ok(&[
        "simulate",
        model,
        "--excite",
        "n=301,hold=301,low=0,high=0,ts=0.01",
        "-o",
        s(&out),
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    let y: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert_eq!(y.len(), 301);
    assert!(
        y.iter().all(|&v| v >= -1e-9),
        "the ball went through the floor"
    );
    let apex = y[70..140].iter().cloned().fold(0.0, f64::max);
    assert!(
        (apex - 1.125).abs() < 0.01,
        "apex after the first bounce {apex}"
    );
}

/// A model whose file gives its initial state does not read `--y0`: the
/// run says so, and writes what it writes without it; a model whose state
/// comes from the warm-up reads it.
#[test]
fn y0_is_read_where_the_initial_state_comes_from_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let run = |model: &str, y0: Option<&str>| {
        let out = dir.path().join("run.csv");
        let model = format!("{root}/{model}");
        let mut args = vec![
            "simulate",
            &model,
            "--excite",
            "n=40,hold=5,low=-1,high=1,ts=0.02",
            "--seed",
            "1",
            "-o",
            s(&out),
        ];
        if let Some(y0) = y0 {
            args.extend(["--y0", y0]);
        }
        let stderr = common::ok_stderr(&args);
        (stderr, std::fs::read_to_string(&out).unwrap())
    };
    let given = "models/examples/coupled-drives.toml";
    let (stderr, with) = run(given, Some("3"));
    assert!(
        stderr.contains("warning: --y0 3 is not read:")
            && stderr.contains("coupled-drives.toml gives the initial state"),
        "{stderr}"
    );
    assert_eq!(with, run(given, None).1);
    // The head's state is read from the warm-up's outputs: no warning,
    // and another response.
    let measured = "models/pick-and-place/head.toml";
    let (stderr, with) = run(measured, Some("0.5"));
    assert!(!stderr.contains("is not read"), "{stderr}");
    assert_ne!(with, run(measured, None).1);
}

/// `simulate --x0` starts a physical model from the state given, in
/// place of its file's rule (the axis reads its state from the warm-up):
/// at rest under no input, the axis sticks where it was put; pushed, it
/// slides on and sticks farther. A mechanical model takes the states of its
/// gray-box form. Every state must be named, and a PWARX model has none.
#[test]
fn x0_starts_a_physical_model_from_the_state_given() {
    let dir = tempfile::tempdir().unwrap();
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let out = dir.path().join("run.csv");
    let args = |model: &str, x0: &str| {
        let model = format!("{root}/{model}");
        let excite = "n=30,hold=5,low=0,high=0,ts=0.01";
        [
            "simulate",
            &model,
            "--excite",
            excite,
            "--x0",
            x0,
            "-o",
            s(&out),
        ]
        .map(str::to_string)
    };
    let outputs = |model: &str, x0: &str| {
        let args = args(model, x0);
        ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let text = std::fs::read_to_string(&out).unwrap();
        (text.lines().skip(1))
            .map(|l| l.split(',').nth(2).unwrap().parse::<f64>().unwrap())
            .collect::<Vec<f64>>()
    };
    let axis = "models/examples/positioning-axis.toml";
    let still = outputs(axis, "q=0.25,v=0");
    assert_eq!(still.len(), 30);
    assert!(still.iter().all(|&y| y == 0.25), "{still:?}");
    let pushed = outputs(axis, "v=0.05, q=0.25");
    assert_eq!(pushed[0], 0.25);
    assert!(pushed[29] > 0.25 && pushed[29] == pushed[28], "{pushed:?}");
    let head = outputs("models/pick-and-place/head.toml", "y=1.5,v=0");
    assert_eq!(head[0], 1.5, "{head:?}");
    std::fs::remove_file(&out).unwrap();
    for (model, x0, message) in [
        (
            axis,
            "q=0.25",
            "--x0: no value for the state 'v' (give every state: q, v)",
        ),
        (
            axis,
            "q=0.25,v=0,w=1",
            "--x0: 'w' is not a state of the model (its states: q, v)",
        ),
        (axis, "q=inf,v=0", "--x0: q = inf is not finite"),
        (
            "docs/pick-and-place/models/arx_2_2.json",
            "y=1",
            "--x0: a pwarx model has no state to give",
        ),
    ] {
        let args = args(model, x0);
        let o = hysid(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let line = one_line_error(&o, 2).unwrap();
        assert!(line.contains(message), "{line}");
    }
    assert!(!out.exists(), "no partial output");
}

/// A record without `y` is read by the output name the gray-box file
/// declares (`speed`): the model's own simulation, so renamed, scores
/// 100 %.
#[test]
fn a_record_is_read_by_the_declared_output_name() {
    let dir = tempfile::tempdir().unwrap();
    let model = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/examples/coupled-drives.toml"
    );
    let sim = dir.path().join("sim.csv");
    ok(&[
        "simulate",
        model,
        "--excite",
        "n=200,hold=5,low=-1.5,high=1.5,ts=0.02",
        "--seed",
        "1",
        "-o",
        s(&sim),
    ]);
    let text = std::fs::read_to_string(&sim).unwrap();
    let (header, rows) = text.split_once('\n').unwrap();
    assert_eq!(header, "t,u,y,mode");
    let renamed = common::write(dir.path(), "speed.csv", format!("t,u,speed,mode\n{rows}"));
    let json = ok(&["validate", model, s(&renamed), "--json"]);
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!(report["fit_sim"].as_f64().unwrap() > 99.999, "{report}");
    // The text names each mode with its count.
    let text = ok(&["validate", model, s(&renamed)]);
    assert!(
        text.contains("modes     driven 190 (scored samples per mode in the simulation)"),
        "{text}"
    );
}

/// `hysid methods` prints the priors each back-end honours; a back-end
/// refuses a prior it cannot honour with one line naming the entry and the
/// file (exit 2); `[[equality]]` entries are honoured by arx, and a bad
/// one is named with its unknown parameter.
#[test]
fn methods_declare_priors_and_backends_refuse_or_honour_them() {
    let out = ok(&["methods"]);
    let block = |name: &str| -> String {
        let mut lines = out.lines().skip_while(|l| !l.starts_with(name));
        let first = lines.next().unwrap_or_else(|| panic!("no {name} in {out}"));
        let rest: Vec<&str> = lines.take_while(|l| l.starts_with(' ')).collect();
        format!("{first}\n{}", rest.join("\n"))
    };
    for name in [
        "arx", "bounded", "cluster", "physical", "klinreg", "parc", "bayes", "milp",
    ] {
        assert!(
            block(name).contains("priors honoured:"),
            "{name}: {}",
            block(name)
        );
    }
    let honoured = |name: &str| -> String {
        block(name)
            .lines()
            .find(|l| l.trim_start().starts_with("priors honoured:"))
            .unwrap()
            .to_string()
    };
    for name in ["arx", "bounded"] {
        let l = honoured(name);
        for kind in [
            "modes",
            "max_modes",
            "[[saturation]]",
            "[[tie]]",
            "[fixed]",
            "[bounds]",
            "switching",
            "[[equality]]",
        ] {
            assert!(l.contains(kind), "{name} lacks {kind}: {l}");
        }
    }
    assert!(
        honoured("physical").ends_with("priors honoured: [fixed], [bounds], [[tie]]"),
        "{}",
        honoured("physical")
    );

    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let prior = dir.path().join("stops.toml");
    std::fs::write(&prior, "[[saturation]]\nlevel = 25.0\nbound = \"max\"\n").unwrap();
    let out_model = dir.path().join("phys.json");
    bad(
        &[
            "identify",
            s(&data),
            "-m",
            "physical",
            "--set",
            common::HEAD_MODEL_SET,
            "--prior",
            s(&prior),
            "-o",
            s(&out_model),
        ],
        &["'physical'", "[[saturation]]", "stops.toml"],
        &out_model,
    );

    // arx honours an equality exactly: b1 = b2 (the truth has 0.8, 0.3).
    let eq = dir.path().join("eq.toml");
    std::fs::write(
        &eq,
        "[[equality]]\ncoefficients = { b1 = 1.0, b2 = -1.0 }\n",
    )
    .unwrap();
    let model = dir.path().join("eq.json");
    ok(&[
        "identify",
        s(&data),
        "-m",
        "arx",
        "--na",
        "2",
        "--nb",
        "2",
        "--prior",
        s(&eq),
        "-o",
        s(&model),
    ]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let t = &m["modes"][0]["theta"];
    let (b1, b2) = (t[2].as_f64().unwrap(), t[3].as_f64().unwrap());
    assert!((b1 - b2).abs() <= 1e-9 * (1.0 + b1.abs()), "{t}");

    let typo = dir.path().join("typo.toml");
    std::fs::write(
        &typo,
        "[[equality]]\ncoefficients = { b1 = 1.0, b9 = -1.0 }\n",
    )
    .unwrap();
    let never = dir.path().join("never.json");
    bad(
        &[
            "identify",
            s(&data),
            "-m",
            "arx",
            "--na",
            "2",
            "--nb",
            "2",
            "--prior",
            s(&typo),
            "-o",
            s(&never),
        ],
        &["[[equality]] #1", "'b9'"],
        &never,
    );
}

#[test]
fn a_panic_is_one_line_and_exit_code_1() {
    // A panic is a bug; the program still ends with one line and exit code
    // 1, never Rust's 101. The internal test hook HYSID_TEST_PANIC=1 panics
    // at the start of the command (docs/errors.md): no known input reaches
    // a panic.
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let out = dir.path().join("m.json");
    let args = ["identify", s(&data), "-m", "arx", "-o", s(&out)];
    let run = |hook: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_hysid"))
            .args(args)
            .env("CI", "1")
            .env("HYSID_TEST_PANIC", hook)
            // With RUST_BACKTRACE set the default panic report is printed too.
            .env_remove("RUST_BACKTRACE")
            .output()
            .unwrap()
    };
    let err = one_line_error(&run("1"), 1).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        err.starts_with(
            "hysid: error: internal error: HYSID_TEST_PANIC=1: deliberate panic (second line) at "
        ),
        "{err}"
    );
    assert!(err.contains("main.rs:"), "{err}");
    assert!(err.ends_with(" (please report)"), "{err}");
    assert!(!out.exists(), "left an output file behind");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "left a temporary behind");
    // Any other value is no hook.
    let o = run("0");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());
}

#[test]
fn a_time_budget_too_long_to_represent_is_no_deadline() {
    // Duration::from_secs_f64(1e20) panicked (the limit is about 1.8e19 s).
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let mut models = Vec::new();
    for (i, t) in ["1e20", "1e300", "1.7976931348623157e308", "1e9"]
        .iter()
        .enumerate()
    {
        let out = dir.path().join(format!("m{i}.json"));
        ok(&[
            "identify",
            s(&data),
            "-m",
            "cluster",
            "--modes",
            "1",
            "--time-budget",
            t,
            "-o",
            s(&out),
        ]);
        models.push(std::fs::read(&out).unwrap());
    }
    // No deadline was hit: every run is the same full run.
    assert!(models.windows(2).all(|w| w[0] == w[1]));
}

/// The first `rows` data rows of a CSV file (header kept).
fn truncated_csv(dir: &Path, data: &Path, rows: usize) -> PathBuf {
    let text = std::fs::read_to_string(data).unwrap();
    let head: Vec<&str> = text.lines().take(rows + 1).collect();
    let out = dir.join("truncated.csv");
    std::fs::write(&out, head.join("\n") + "\n").unwrap();
    out
}

/// `--auto` refits the choice from `--refit-starts` seeds only where the
/// seed can change the fit: once for `bayes` with its exact Gaussian
/// posterior, three times with a random order (a refined choice has one
/// start more, from its own fit, which no seed draws).
#[test]
fn auto_refits_from_one_start_where_the_seed_is_not_used() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let out = dir.path().join("m.json");
    let starts = |extra: &[&str]| {
        let mut args = vec![
            "identify",
            s(&data),
            "-m",
            "bayes",
            "--na",
            "1",
            "--nb",
            "1",
            "--modes",
            "2",
            "--auto",
            "--refit-starts",
            "3",
            "-o",
            s(&out),
        ];
        args.extend(extra);
        ok(&args);
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let starts = m["info"]["selection"]["refit"].as_array().unwrap();
        starts
            .iter()
            .filter(|r| r.get("from_candidate").is_none())
            .count()
    };
    assert_eq!(starts(&[]), 1);
    assert_eq!(starts(&["--set", "order=random"]), 3);
}

/// Where every candidate of the back-end failed, `--auto` writes the
/// affine model and says why: milp's exact program refuses records above
/// its sample limit.
#[test]
fn auto_says_why_the_affine_model_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let out = dir.path().join("m.json");
    let o = hysid(&[
        "identify",
        s(&data),
        "-m",
        "milp",
        "--na",
        "1",
        "--nb",
        "1",
        "--auto",
        "-o",
        s(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("every milp candidate failed (")
            && err.contains("exceed option max_samples = 40")
            && err.contains("the affine arx model is written"),
        "{err}"
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(m["info"]["method"], "arx");
}

/// On a noise-free record of two modes every candidate of two or more
/// modes simulates the selection rows exactly, up to rounding: they tie,
/// and the one-standard-error rule takes two modes (ranked by their
/// rounding, `cluster` chose three), which simulate the next rows exactly.
#[test]
fn auto_ties_exact_candidates_and_takes_the_fewest_modes() {
    let dir = tempfile::tempdir().unwrap();
    let truth = common::write(
        dir.path(),
        "truth.json",
        r#"{"kind":"pwarx","na":2,"nb":2,"inputs":1,"modes":[
            {"theta":[0.5,-0.1,1.0,0.2,0.5],"region":{"a":[[1,0,0,0]],"b":[0]}},
            {"theta":[0.7,-0.2,-0.6,0.3,-0.4],"region":{"a":[[-1,0,0,0]],"b":[0]}}]}"#,
    );
    let data = dir.path().join("data.csv");
    let excite = "n=2000,hold=5,low=-2,high=2,ts=0.01";
    ok(&[
        "simulate",
        s(&truth),
        "--excite",
        excite,
        "--seed",
        "1",
        "-o",
        s(&data),
    ]);
    let out = dir.path().join("m.json");
    ok(&[
        "identify",
        s(&data),
        "--rows",
        "0..1600",
        "-m",
        "cluster",
        "--auto",
        "-o",
        s(&out),
    ]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let selection = &m["info"]["selection"];
    let exact = |c: &serde_json::Value| c["fit_sim"].as_f64().is_some_and(|f| f > 99.9999);
    let candidates = selection["candidates"].as_array().unwrap();
    let modes = |c: &serde_json::Value| c["modes"].as_u64().unwrap();
    assert!(
        candidates.iter().any(|c| exact(c) && modes(c) > 2),
        "{selection}"
    );
    let chosen = &candidates[selection["chosen"].as_u64().unwrap() as usize];
    assert!(exact(chosen) && modes(chosen) == 2, "{chosen}");
    let o = ok(&["validate", s(&out), s(&data), "--rows", "1600..", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&o).unwrap();
    let fit = v["fit_sim"].as_f64().unwrap();
    assert!(fit > 99.99, "{fit}");
}

#[test]
fn auto_chooses_inside_the_identification_rows_only() {
    // Rows after the identification rows are test rows: deleting them from
    // the file must not change what --auto returns, byte for byte.
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 400);
    let short = truncated_csv(dir.path(), &data, 300);
    let (a, b) = (dir.path().join("a.json"), dir.path().join("b.json"));
    let auto = [
        "-m",
        "cluster",
        "--na",
        "1",
        "--nb",
        "1",
        "--auto",
        "--grid",
        "c=20,40",
        "--grid",
        "modes=1,2",
        "--seed",
        "1",
    ];
    let mut args = vec!["identify", s(&data), "--rows", "0..300", "-o", s(&a)];
    args.extend(auto);
    ok(&args);
    let mut args = vec!["identify", s(&short), "-o", s(&b)];
    args.extend(auto);
    ok(&args);
    let (ma, mb) = (
        std::fs::read_to_string(&a).unwrap(),
        std::fs::read_to_string(&b).unwrap(),
    );
    assert_eq!(ma, mb);
    let m: serde_json::Value = serde_json::from_str(&ma).unwrap();
    let sel = &m["info"]["selection"];
    // 60 default selection rows, fewer than 100: the block at the start
    // of the identification rows is scored too.
    assert_eq!(sel["splits"][0]["fit_rows"], "60..300");
    assert_eq!(sel["splits"][0]["select_rows"], "0..60");
    assert_eq!(sel["splits"][1]["fit_rows"], "0..240");
    assert_eq!(sel["splits"][1]["select_rows"], "240..300");
    let cands = sel["candidates"].as_array().unwrap();
    // Four grid points; the best of each mode count refined (two modes:
    // `sim` and `sim_regions`; one mode: `sim`); then the affine reference.
    assert_eq!(cands.len(), 8, "{sel}");
    let refine: Vec<&str> = cands[4..7]
        .iter()
        .map(|c| {
            c["values"].as_array().unwrap().last().unwrap()[1]
                .as_str()
                .unwrap()
        })
        .collect();
    assert_eq!(refine, ["sim", "sim_regions", "sim"], "{sel}");
    assert_eq!(cands[7]["method"], "arx");
    let score = |c: &serde_json::Value| c["fit_sim"].as_f64().unwrap_or(f64::NEG_INFINITY);
    let (chosen, best) = (
        sel["chosen"].as_u64().unwrap() as usize,
        sel["best"].as_u64().unwrap() as usize,
    );
    assert!(
        cands.iter().all(|c| score(c) <= score(&cands[best])),
        "{sel}"
    );
    // The one-standard-error rule never chooses more modes than the best.
    assert!(
        cands[chosen]["modes"].as_u64() <= cands[best]["modes"].as_u64(),
        "{sel}"
    );
    // The two-mode record is not affine: two modes simulate it better.
    assert_eq!(m["modes"].as_array().unwrap().len(), 2, "{sel}");
}

#[test]
fn auto_selection_rows_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let out = dir.path().join("m.json");
    let base = ["identify", s(&data), "-m", "arx", "--auto", "-o", s(&out)];
    for (extra, needle) in [
        (
            vec!["--select-rows", "100..200"],
            "--select-rows 100..200: must start or end",
        ),
        (
            vec!["--rows", "50..", "--select-rows", "10..60"],
            "before the first identification row 50",
        ),
        (vec!["--grid", "na=two"], "--grid na=two: not a count"),
        (vec!["--grid", "na"], "--grid"),
        (vec!["--folds", "1"], "--folds 1: at least 2 folds"),
        (
            vec!["--refit-starts", "0"],
            "'0' is not a whole number of at least 1",
        ),
    ] {
        let mut args = base.to_vec();
        args.extend(extra);
        bad(&args, &[needle], &out);
    }
    // Every candidate's options are checked before any is fitted: a grid
    // key the back-end lacks, a value it refuses, a given option it lacks.
    for (extra, needle) in [
        (
            vec!["--grid", "cc=1,2"],
            "--grid cc: method 'arx' has no such option",
        ),
        (vec!["--grid", "ridge=1,x"], "--grid ridge=x"),
        (vec!["--grid", "modes=0,2"], "--grid modes=0"),
        (
            vec!["--set", "ridgee=1"],
            "--set ridgee: method 'arx' has no such option",
        ),
        // An axis a given option or the exact mode count also fixes: the
        // grid would override it.
        (
            vec!["--grid", "ridge=0,1", "--set", "ridge=2"],
            "--grid ridge: also fixed by --set ridge=2; give it in one place",
        ),
        (
            vec!["--grid", "modes=1", "--modes", "1"],
            "--grid modes: also fixed by --modes 1",
        ),
    ] {
        let mut args = base.to_vec();
        args.extend(extra);
        bad(&args, &[needle], &out);
    }
    let prior = common::write(dir.path(), "one.toml", "modes = 1\n");
    let args = [&base[..], &["--grid", "modes=1", "--prior", s(&prior)]].concat();
    bad(
        &args,
        &[
            "--grid modes: also fixed by the prior modes = 1 of",
            "one.toml",
        ],
        &out,
    );
    // A mode count the method cannot meet is refused before any candidate
    // is fitted, as without --auto.
    let two = common::write(dir.path(), "two.toml", "modes = 2\n");
    let args = [&base[..], &["--prior", s(&two)]].concat();
    let said = "prior modes = 2: method 'arx' identifies exactly one ordinary mode";
    bad(&args, &[said], &out);
    // A grid point whose orders lack a name of the priors is refused, as
    // sweep refuses it; the declared space's such points fail, and are
    // counted on stderr.
    let a2 = common::write(dir.path(), "a2.toml", "[fixed]\na2 = -0.5\n");
    let args = [&base[..], &["--grid", "na=1,2", "--prior", s(&a2)]].concat();
    bad(&args, &["a2.toml: [fixed]: unknown name 'a2'"], &out);
    let fitted = dir.path().join("fitted.json");
    let mut args = [&base[..], &["--prior", s(&a2)]].concat();
    args[6] = s(&fitted);
    let o = hysid(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let said = "hysid: --auto: 2 of the 5 candidate(s) could not be fitted and scored (the first: ";
    assert!(
        err.contains(said) && err.contains("unknown name 'a2'"),
        "{err}"
    );
    // Selection rows the user did not give are named by where they come from.
    bad(
        &[base.to_vec(), vec!["--rows", "0..30"]].concat(),
        &["--auto: the default selection rows", "--select-rows"],
        &out,
    );
    // Selection rows where the output rests cannot rank the candidates.
    let text = std::fs::read_to_string(&data).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let y = lines[0].split(',').position(|c| c == "y").unwrap();
    for line in &mut lines[1 + 300..] {
        let mut cells: Vec<&str> = line.split(',').collect();
        cells[y] = "0.5";
        *line = cells.join(",");
    }
    let rests = common::write(dir.path(), "rests.csv", &(lines.join("\n") + "\n"));
    let mut args = base.to_vec();
    args[1] = s(&rests);
    bad(
        &args,
        &[
            "--auto: the default selection rows 320.. (the last 20 % of the identification rows): the output is constant on rows 320..400 after the warm-up, so FIT cannot rank the candidates there; give more rows or --select-rows",
        ],
        &out,
    );
    let chosen = dir.path().join("chosen.json");
    let mut moving = [&args[..], &["--select-rows", "0..80"]].concat();
    moving[6] = s(&chosen);
    let o = hysid(&moving);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // --grid and --refit-starts without --auto are usage errors.
    for extra in [["--grid", "na=1"], ["--refit-starts", "2"]] {
        let mut args = vec!["identify", s(&data), "-m", "arx", "-o", s(&out)];
        args.extend(extra);
        bad(&args, &["--auto"], &out);
    }
}

#[test]
fn sweep_refuses_unknown_keys_and_fails_when_every_point_fails() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let rows = ["--identify-rows", "0..300", "--select-rows", "300.."];
    // `sweep DATA -m arx` over the rows with `extra`, refused: its message.
    let refused = |extra: &[&str]| {
        let mut args = vec!["sweep", s(&data), "-m", "arx"];
        args.extend(extra);
        args.extend(rows);
        one_line_error(&hysid(&args), 2).unwrap()
    };
    let err = refused(&["--grid", "bogus=1,2"]);
    assert!(
        err.contains("--grid bogus: method 'arx' has no such option (options: ridge"),
        "{err}"
    );
    assert!(err.contains("preset; or modes, na, nb)"), "{err}");
    let prior = common::write(dir.path(), "p.toml", "[[tie]]\nparams = [\"a2\"]\n");
    for (extra, needle) in [
        // A value the back-end refuses, or a count that is not one, is
        // refused before any point runs, naming the flag.
        (&["--grid", "ridge=0,x"][..], "--grid ridge=x"),
        (&["--grid", "na=1,-2"], "--grid na=-2: not a count"),
        (&["--grid", "ridge=0,0"], "--grid ridge=0: given twice"),
        // A swept option that a flag fixes too.
        (
            &["--grid", "ridge=0,1", "--set", "ridge=2"],
            "--grid ridge: also fixed by --set ridge=2",
        ),
        (
            &["--grid", "na=1,2", "--na", "3"],
            "--grid na: also fixed by --na 3",
        ),
        // A prior the back-end cannot take at some point, named by its file.
        (
            &["--grid", "na=1,2", "--prior", s(&prior)],
            "p.toml: [[tie]] params: unknown name 'a2'",
        ),
    ] {
        let err = refused(extra);
        assert!(err.contains(needle), "{extra:?}: {err}");
    }
    // A signal the record lacks is named by the file (a sweep has no [data]).
    let err = refused(&["--grid", "na=1,2", "--output", "yy"]);
    assert!(
        err.contains("data.csv: no column 'yy'") && !err.contains("[data]"),
        "{err}"
    );
    // The figure is drawn against the first --grid key.
    let out = dir.path().join("drawn");
    let mut args = vec![
        "sweep",
        s(&data),
        "-m",
        "arx",
        "--grid",
        "nb=1,2",
        "--grid",
        "na=1,2",
    ];
    args.extend(rows);
    args.extend(["-o", s(&out)]);
    assert!(hysid(&args).status.success());
    let figure = std::fs::read_to_string(out.join("plots/arx-sweep.svg")).unwrap();
    assert!(figure.contains("against nb"), "{}", &figure[..400]);
    // cluster without a mode count is refused before any point runs.
    let mut args = vec!["sweep", s(&data), "-m", "cluster", "--grid", "c=20,40"];
    args.extend(rows);
    let err = one_line_error(&hysid(&args), 2).unwrap();
    assert!(
        err.contains("'cluster' needs the number of modes: --modes S, --grid modes="),
        "{err}"
    );
    // milp needs it unless it is given an error bound.
    let mut args = vec![
        "sweep",
        s(&data),
        "-m",
        "milp",
        "--grid",
        "theta_max=10,100",
    ];
    args.extend(rows);
    let err = one_line_error(&hysid(&args), 2).unwrap();
    assert!(err.contains("'milp' needs the number of modes"), "{err}");
    // A bound on the count is not enough for it.
    let bound = common::write(dir.path(), "bound.toml", "max_modes = 3\n");
    args.extend(["--prior", s(&bound)]);
    let err = one_line_error(&hysid(&args), 2).unwrap();
    let said = "or modes = S in the prior file (a max_modes bound alone does not give it)";
    assert!(err.ends_with(said), "{err}");
    // More modes than the rows identify fail at every point: exit code 1,
    // the report written with -o (with no sweep figure: nothing to draw).
    let out = dir.path().join("failed");
    let mut args = vec!["sweep", s(&data), "-m", "cluster", "--modes", "100"];
    args.extend(["--grid", "c=20,40"]);
    args.extend(rows);
    args.extend(["-o", s(&out)]);
    let o = hysid(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("every point of the sweep failed"), "{err}");
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(!report.contains("-sweep.svg"), "{report}");
}

/// Rows beyond the record are named by the flag or key that gave them:
/// `sweep`'s own flags, an experiment's `identification` and `validation`.
#[test]
fn rows_beyond_the_record_name_their_flag_or_key() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    for (rows, needle) in [
        (
            ["--identify-rows", "300..100000", "--select-rows", "0..100"],
            "--identify-rows 300..100000 ends beyond the",
        ),
        (
            [
                "--identify-rows",
                "0..300",
                "--select-rows",
                "90000..100000",
            ],
            "--select-rows 90000..100000 ends beyond the",
        ),
    ] {
        let mut args = vec!["sweep", s(&data), "-m", "arx", "--grid", "na=1,2"];
        args.extend(rows);
        let err = one_line_error(&hysid(&args), 2).unwrap();
        assert!(err.contains(needle) && err.contains("data.csv"), "{err}");
        assert!(!err.contains("--rows") && !err.contains("[data]"), "{err}");
    }
    // Selection rows that overlap the fit rows would score the points on
    // rows they were fitted on.
    let args = [
        "sweep",
        s(&data),
        "-m",
        "arx",
        "--grid",
        "na=1,2",
        "--identify-rows",
        "0..300",
        "--select-rows",
        "250..400",
    ];
    let err = one_line_error(&hysid(&args), 2).unwrap();
    assert!(
        err.contains("--select-rows 250..400 overlap --identify-rows 0..300"),
        "{err}"
    );
    let exp = dir.path().join("exp.toml");
    std::fs::write(
        &exp,
        format!(
            "title = \"t\"\n[data]\nfile = {:?}\nidentification = \"0..300\"\nvalidation = \"300..100000\"\n[[run]]\nname = \"a\"\nmethod = \"arx\"\n",
            s(&data)
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let err = one_line_error(&hysid(&["compare", s(&exp), "-o", s(&out)]), 2).unwrap();
    assert!(
        err.contains("validation 300..100000 ends beyond the"),
        "{err}"
    );
}

/// An output file that is one of the command's inputs is refused before
/// anything runs, and the input is left as it was; a data file given where
/// the model file goes is named as such.
#[test]
fn an_input_is_never_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let model = dir.path().join("true.json");
    let before = std::fs::read(&data).unwrap();
    for args in [
        vec!["identify", s(&data), "-m", "arx", "-o", s(&data)],
        vec!["simulate", s(&model), "--data", s(&data), "-o", s(&data)],
        vec!["validate", s(&model), s(&data), "--plot", s(&data)],
    ] {
        let err = one_line_error(&hysid(&args), 2).unwrap();
        assert!(
            err.contains("is an input of this command"),
            "{args:?}: {err}"
        );
        assert_eq!(std::fs::read(&data).unwrap(), before, "{args:?}");
    }
    let model_before = std::fs::read(&model).unwrap();
    let err = one_line_error(
        &hysid(&["simulate", s(&model), "--data", s(&data), "-o", s(&model)]),
        2,
    )
    .unwrap();
    assert!(err.contains("is an input"), "{err}");
    assert_eq!(std::fs::read(&model).unwrap(), model_before);
    // The model file a physical fit reads, and the base it extends, are
    // inputs too.
    let base = dir.path().join("base.toml");
    let ball = common::repository_text("models/examples/ball-on-table.toml");
    std::fs::write(&base, &ball).unwrap();
    let derived = dir.path().join("derived.toml");
    std::fs::write(&derived, "extends = \"base.toml\"\n").unwrap();
    for out in [&derived, &base] {
        let set = format!("model={}", derived.display());
        let args = [
            "identify",
            s(&data),
            "-m",
            "physical",
            "--set",
            &set,
            "-o",
            s(out),
        ];
        let err = one_line_error(&hysid(&args), 2).unwrap();
        assert!(err.contains("is an input of this command"), "{err}");
    }
    assert_eq!(std::fs::read_to_string(&base).unwrap(), ball);
    let err = one_line_error(&hysid(&["validate", s(&data), s(&data)]), 2).unwrap();
    assert!(
        err.contains("a data file (.csv) where the model file"),
        "{err}"
    );
    // So are an experiment file and a prior file.
    let experiment = common::write(
        dir.path(),
        "e.toml",
        "title = \"t\"\n[data]\nfile = \"d.csv\"\n[[run]]\nname = \"a\"\nmethod = \"arx\"\n",
    );
    let prior = common::write(dir.path(), "p.toml", "modes = 2\n[fixed]\na1 = 0.5\n");
    for (file, what) in [
        (&experiment, "an experiment file"),
        (&prior, "a prior file"),
    ] {
        for command in ["validate", "show"] {
            let mut args = vec![command, s(file)];
            if command == "validate" {
                args.push(s(&data));
            }
            let err = one_line_error(&hysid(&args), 2).unwrap();
            assert!(
                err.contains(what) && err.contains("not a model file (which names its kind"),
                "{err}"
            );
        }
    }
    // Rows that start with a hyphen are refused as rows, not read as a flag.
    let out = dir.path().join("m.json");
    bad(
        &[
            "identify",
            s(&data),
            "-m",
            "arx",
            "--rows",
            "-5..10",
            "-o",
            s(&out),
        ],
        &["--rows"],
        &out,
    );
}

/// Too few samples for the orders and modes are named by the file and the
/// rows they were selected from.
#[test]
fn too_few_samples_name_their_rows() {
    let dir = tempfile::tempdir().unwrap();
    let data = arx_record(dir.path());
    let out = dir.path().join("m.json");
    let args = [
        "identify",
        s(&data),
        "-m",
        "cluster",
        "--modes",
        "2",
        "--rows",
        "0..10",
        "-o",
        s(&out),
    ];
    bad(
        &args,
        &[
            "data.csv --rows 0..10 (10 samples)",
            "cannot identify 2 modes",
        ],
        &out,
    );
    // The back-ends' own shortages are named the same way.
    for (method, modes, rows, want) in [
        ("arx", None, "0..5", "free parameters"),
        ("cluster", Some("1"), "0..7", "local datasets"),
    ] {
        let mut args = vec![
            "identify",
            s(&data),
            "-m",
            method,
            "--rows",
            rows,
            "-o",
            s(&out),
        ];
        if let Some(count) = modes {
            args.extend(["--modes", count]);
        }
        let named = format!("data.csv --rows {rows} (");
        bad(&args, &[named.as_str(), want], &out);
    }
    // A record too short to simulate: the data, not the model.
    let model = dir.path().join("true.json");
    let csv = dir.path().join("x.csv");
    let args = [
        "simulate",
        s(&model),
        "--data",
        s(&data),
        "--rows",
        "399..",
        "-o",
        s(&csv),
    ];
    bad(
        &args,
        &["data.csv --rows 399..: the record has 1 samples"],
        &csv,
    );
}

/// `--max-modes` is the prior `max_modes`: cluster chooses the count.
#[test]
fn max_modes_on_the_command_line_lets_cluster_choose() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 600);
    let out = dir.path().join("m.json");
    ok(&[
        "identify",
        s(&data),
        "-m",
        "cluster",
        "--max-modes",
        "3",
        "-o",
        s(&out),
    ]);
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let choice = model["info"]["diagnostics"]["mode_choice"]
        .as_array()
        .unwrap();
    assert_eq!(choice.len(), 3, "{choice:?}");
}

/// One convention each, so that files round-trip: a model with a stop
/// keeps the record's input name (its simulated CSV feeds `validate`
/// again), `t` is the time of the sample in the record (`--rows` does not
/// restart it at 0), printed without rounding residue, and unnamed modes
/// are `mode 1`, `mode 2`, ... in the model file and the CSV, as in the
/// figures.
#[test]
fn simulated_files_round_trip_with_one_convention() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 600);
    let prior = dir.path().join("p.toml");
    std::fs::write(&prior, "[[saturation]]\nlevel = 3.0\nbound = \"max\"\n").unwrap();
    let model = dir.path().join("m.json");
    ok(&[
        "identify",
        s(&data),
        "-m",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "--prior",
        s(&prior),
        "-o",
        s(&model),
    ]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["kind"], "hybrid_automaton");
    assert_eq!(m["inputs"], serde_json::json!(["u"]));
    assert_eq!(m["modes"][0]["name"], "mode 1");
    let sim = dir.path().join("sim.csv");
    ok(&[
        "simulate",
        s(&model),
        "--data",
        s(&data),
        "--rows",
        "100..200",
        "-o",
        s(&sim),
    ]);
    let text = std::fs::read_to_string(&sim).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,u,y,mode"));
    let first: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(first[0], "1", "t of row 100 at ts = 0.01");
    assert!(
        text.lines()
            .skip(1)
            .all(|l| l.split(',').next().unwrap().len() <= 5),
        "{text}"
    );
    assert!(text.contains(",mode 1\n"), "{}", &text[..200]);
    ok(&["validate", s(&model), s(&sim), "--json"]);
}

/// A MAT-file written by scipy (no comma after `MAT-file` in its header)
/// is read by `identify`; a level-4 file is refused in one line, exit 2.
#[test]
fn mat_files_from_scipy_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let mats = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../hysid-io/tests/data/mat");
    let out = dir.path().join("m.json");
    let file = mats.join("scipy_f64_col_compressed.mat");
    ok(&[
        "identify",
        s(&file),
        "-m",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "-o",
        s(&out),
    ]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let theta: Vec<f64> = m["modes"][0]["theta"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    for (a, b) in theta.iter().zip([0.5, 1.0, 0.0]) {
        assert!((a - b).abs() < 1e-9, "{theta:?}");
    }
    let level4 = mats.join("level4.mat");
    let never = dir.path().join("never.json");
    bad(
        &["identify", s(&level4), "-m", "arx", "-o", s(&never)],
        &["level4.mat", "a level-4 MAT-file"],
        &never,
    );
}

/// The columns `y` and `mode` of a `simulate` CSV.
fn simulated(csv: &Path) -> (Vec<f64>, Vec<String>) {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (y, mode) = (column("y"), column("mode"));
    lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            (cells[y].parse::<f64>().unwrap(), cells[mode].to_string())
        })
        .unzip()
}

/// `convert` writes the head as a gray-box model (TOML or JSON, as named)
/// that simulates as the mechanical file does: the same outputs and the
/// same mode names at every sample of a record that visits them all; so
/// does a head whose slip mode is shared by the sets of contacts and
/// whose sticking is labelled by them.
#[test]
fn convert_writes_the_gray_box_form_of_a_mechanical_model() {
    let dir = tempfile::tempdir().unwrap();
    let head_text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/pick-and-place/head.toml"
    ))
    .unwrap();
    let relabelled = head_text
        .replace("kind = \"slip\"\ncontacts = []", "kind = \"slip\"")
        .replace(
            "[[modes]]\nname = \"impact\"\nkind = \"slip\"\ncontacts = [\"board\"]",
            "[[modes]]\nname = \"stuck on board\"\nkind = \"stick\"\ncontacts = [\"board\"]",
        );
    assert_ne!(relabelled, head_text);
    let excite = "n=3000,hold=120,low=-0.3,high=0.05,ts=0.0025";
    let run = |model: &std::path::Path, name: &str| {
        let out = dir.path().join(name);
        ok(&[
            "simulate",
            s(model),
            "--excite",
            excite,
            "--seed",
            "1",
            "-o",
            s(&out),
        ]);
        simulated(&out)
    };
    for (file, text, distinct) in [
        ("head", &head_text, "impact"),
        ("relabelled", &relabelled, "stuck on board"),
    ] {
        let mechanical = dir.path().join(format!("{file}.toml"));
        std::fs::write(&mechanical, text).unwrap();
        let (y, modes) = run(&mechanical, &format!("{file}.csv"));
        for distinct in [
            "free",
            distinct,
            "stick",
            "upper_saturation",
            "lower_saturation",
        ] {
            assert!(
                modes.iter().any(|m| m == distinct),
                "{file}: no sample in {distinct}"
            );
        }
        for name in ["gray.toml", "gray.json"] {
            let gray = dir.path().join(format!("{file}-{name}"));
            ok(&["convert", s(&mechanical), "-o", s(&gray)]);
            let text = std::fs::read_to_string(&gray).unwrap();
            assert!(text.contains("gray_box"), "{name}: {}", &text[..80]);
            let (y2, modes2) = run(&gray, &format!("{file}-{name}.csv"));
            assert_eq!(modes, modes2, "{file}, {name}");
            let worst = y
                .iter()
                .zip(&y2)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "{file}, {name}: max |y difference| {worst}");
        }
    }
}

/// A model written to a `.toml` name is TOML that reads back as the same
/// model (a fitted model's missing diagnostics left out); under any other
/// name (`.JSON`, none) it is JSON that reads back.
#[test]
fn a_model_written_as_toml_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 400);
    let score = |model: &Path| -> serde_json::Value {
        serde_json::from_str(&ok(&["validate", s(model), s(&data), "--json"])).unwrap()
    };
    let mut scores = Vec::new();
    for name in ["m.json", "m.toml", "m.JSON", "m"] {
        let model = dir.path().join(name);
        ok(&[
            "identify",
            s(&data),
            "-m",
            "cluster",
            "--modes",
            "2",
            "--seed",
            "1",
            "-o",
            s(&model),
        ]);
        scores.push(score(&model));
    }
    let text = std::fs::read_to_string(dir.path().join("m.toml")).unwrap();
    assert!(text.starts_with("kind = \"pwarx\""), "{}", &text[..40]);
    assert!(scores.iter().all(|score| *score == scores[0]), "{scores:?}");
}

/// `validate` and `simulate --data` warn where a discrete-time model meets
/// a record of another sampling time (a `--decimate` left out), and say
/// nothing on the model's own.
#[test]
fn another_sampling_time_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let model = dir.path().join("m.json");
    ok(&[
        "identify",
        s(&data),
        "--decimate",
        "2",
        "-m",
        "arx",
        "-o",
        s(&model),
    ]);
    let warned = |args: &[&str]| {
        let o = hysid(args);
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stderr).contains("differs from the")
    };
    let csv = dir.path().join("sim.csv");
    assert!(warned(&["validate", s(&model), s(&data)]));
    assert!(warned(&[
        "simulate",
        s(&model),
        "--data",
        s(&data),
        "-o",
        s(&csv)
    ]));
    assert!(!warned(&[
        "validate",
        s(&model),
        s(&data),
        "--decimate",
        "2"
    ]));
    let excited = |ts: &str| {
        warned(&[
            "simulate",
            s(&model),
            "--excite",
            &format!("n=50,hold=3,low=-1,high=1,ts={ts}"),
            "-o",
            s(&csv),
        ])
    };
    assert!(excited("0.01"));
    assert!(!excited("0.02"));
}

/// What `validate` and `simulate` say of a record that does not fit the
/// model's signals: a missing column names the model's own, inputs in
/// another order are warned of, and simulated samples outside every
/// region are counted; `--excite` drives every input of the model unless
/// told otherwise.
#[test]
fn the_model_s_own_signals_are_named_where_a_record_differs() {
    let dir = tempfile::tempdir().unwrap();
    let data = common::write(
        dir.path(),
        "rec.csv",
        (0..60)
            .map(|k| format!("{},{},{}\n", k % 7, (k * 3) % 5, k % 4))
            .fold("a,b,pos\n".to_string(), |t, row| t + &row),
    );
    let model = dir.path().join("m.json");
    let named = ["--input", "a,b", "--output", "pos"];
    let mut identify = vec!["identify", s(&data), "-m", "arx", "-o", s(&model)];
    identify.extend(named);
    ok(&identify);
    let csv = dir.path().join("sim.csv");
    // A record without `u` and `y` is read by the signals the model was
    // identified on.
    ok(&["validate", s(&model), s(&data)]);
    // What `simulate --excite` writes (the model's inputs, and `y`) reads
    // back: each signal the record lacks is swapped on its own.
    let excited = dir.path().join("excited.csv");
    let excite = "n=50,hold=5,low=0,high=1,ts=0.1";
    ok(&["simulate", s(&model), "--excite", excite, "-o", s(&excited)]);
    ok(&["validate", s(&model), s(&excited)]);
    let renamed = common::write(
        dir.path(),
        "renamed.csv",
        std::fs::read_to_string(&data)
            .unwrap()
            .replacen("a,b,pos", "u1,u2,y", 1),
    );
    bad(
        &["validate", s(&model), s(&renamed)],
        &[
            "no column 'a'",
            "the model was identified on --input a,b --output pos: name this record's signals",
        ],
        &csv,
    );
    bad(
        &[
            "validate",
            s(&model),
            s(&renamed),
            "--input",
            "u1,u2",
            "--output",
            "z",
        ],
        &[
            "no column 'z'",
            "; the model was identified on --input a,b --output pos",
        ],
        &csv,
    );
    ok(&[
        "validate",
        s(&model),
        s(&renamed),
        "--input",
        "u1,u2",
        "--output",
        "y",
    ]);
    bad(
        &["validate", s(&model), s(&model), s(&data)],
        &["m.json: a model file where a data file (.csv or .mat) is expected"],
        &csv,
    );
    let stderr = common::ok_stderr;
    let swapped = [
        "validate",
        s(&model),
        s(&data),
        "--input",
        "b,a",
        "--output",
        "pos",
    ];
    assert!(stderr(&swapped).contains("inputs are read in the order given (b, a)"));
    let mut given = vec!["validate", s(&model), s(&data)];
    given.extend(named);
    assert!(!stderr(&given).contains("order"));
    let excite = [
        "simulate",
        s(&model),
        "--excite",
        "n=30,hold=2,low=0,high=1",
        "-o",
        s(&csv),
    ];
    assert!(!stderr(&excite).contains("region"));
    let header = std::fs::read_to_string(&csv).unwrap();
    assert!(header.starts_with("a,b,y,mode"), "{}", &header[..20]);
    let holed = common::write(
        dir.path(),
        "hole.json",
        r#"{"kind":"pwarx","na":1,"nb":1,"inputs":1,"modes":[
            {"theta":[0.5,1.0,0.0],"region":{"a":[[1.0,0.0]],"b":[0.0]}},
            {"theta":[0.5,1.0,0.0],"region":{"a":[[-1.0,0.0]],"b":[-1.0]}}]}"#,
    );
    let hole = [
        "simulate",
        s(&holed),
        "--excite",
        "n=200,hold=10,low=-1,high=1",
        "-o",
        s(&csv),
    ];
    assert!(stderr(&hole).contains("simulated samples lie outside every region"));
    // A physical model's internal step longer than the sampling time (a
    // step written in milliseconds) is said, the file named.
    let text = common::repository_text("models/examples/ball-on-table.toml");
    let step = text
        .lines()
        .find(|l| l.starts_with("internal_step"))
        .unwrap();
    let coarse = common::write(
        dir.path(),
        "coarse.toml",
        text.replace(step, "internal_step = 1"),
    );
    let run = [
        "simulate",
        s(&coarse),
        "--excite",
        "n=50,hold=5,low=0,high=1,ts=0.01",
        "-o",
        s(&csv),
    ];
    let said = stderr(&run);
    assert!(
        said.contains("coarse.toml: internal_step = 1 s is longer than the sampling time 0.01 s"),
        "{said}"
    );
    // So is a step more than a thousand times finer (a time column in
    // milliseconds), by `simulate` and by a physical `identify` before
    // it fits.
    let finer = common::write(
        dir.path(),
        "finer.toml",
        text.replace(step, "internal_step = 5e-6"),
    );
    let fine_said = "finer.toml: the sampling time 0.01 s is 2000 integration steps of internal_step = 0.000005 s";
    let run = [&run[..1], &[s(&finer)], &run[2..]].concat();
    let said = stderr(&run);
    assert!(said.contains(fine_said), "{said}");
    let set = format!("model={}", finer.display());
    let fitted = dir.path().join("finer.json");
    let fit = [
        "identify",
        s(&csv),
        "-m",
        "physical",
        "--set",
        &set,
        "--set",
        "swarm_iters=1",
        "--set",
        "particles=2",
        "--set",
        "restarts=0",
        "--set",
        "lm_iters=1",
        "-o",
        s(&fitted),
    ];
    let said = stderr(&fit);
    assert!(said.contains(fine_said), "{said}");
    // A thousand exactly: a model stepping once per sample of a record
    // whose milliseconds were read as seconds; a hundred is not said.
    for (internal, said_too) in [("1e-5", true), ("1e-4", false)] {
        let file = common::write(
            dir.path(),
            "finer.toml",
            text.replace(step, &format!("internal_step = {internal}")),
        );
        let run = [&run[..1], &[s(&file)], &run[2..]].concat();
        let said = stderr(&run);
        let thousand = "the sampling time 0.01 s is 1000 integration steps";
        assert_eq!(said.contains("integration steps of"), said_too, "{said}");
        assert_eq!(said.contains(thousand), said_too, "{said}");
    }
    // A physical model's warm-up rows under --excite hold --y0: said, with
    // the row the run starts at (the head's measured rule reads 10 samples).
    let head = common::repository_text("models/pick-and-place/head.toml");
    let head = common::write(dir.path(), "head.toml", head);
    let excited = [
        "simulate",
        s(&head),
        "--excite",
        "n=40,hold=10,low=-0.1,high=-0.05,ts=0.0025",
        "-o",
        s(&csv),
    ];
    let said = stderr(&excited);
    assert!(
        said.contains("the run starts at row 9: the rows before it hold --y0 0"),
        "{said}"
    );
    assert!(!stderr(&excite).contains("the run starts"));
}

/// A time budget that runs out during `--auto` is said on stderr and
/// recorded in the model's selection; a search that ends within its
/// budget records nothing.
#[test]
fn auto_says_when_the_time_budget_cut_the_search() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let out = dir.path().join("m.json");
    let cut = |budget: &str| {
        let args = [
            "identify",
            s(&data),
            "-m",
            "cluster",
            "--na",
            "1",
            "--nb",
            "1",
            "--auto",
            "--time-budget",
            budget,
            "-o",
            s(&out),
        ];
        let o = hysid(&args);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(o.status.success(), "{err}");
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let recorded = m["info"]["selection"]["cut_short"] == true;
        assert_eq!(
            recorded,
            err.contains("the time budget ran out before the selection ended"),
            "{err}"
        );
        recorded
    };
    assert!(cut("0.000001"));
    assert!(!cut("1000"));
}

/// A sweep's report lists its figures without a `[[run]]` it has none of.
#[test]
fn a_sweep_report_names_only_its_own_figures() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let out = dir.path().join("sweep");
    let args = [
        "sweep",
        s(&data),
        "-m",
        "arx",
        "--grid",
        "na=1,2",
        "--identify-rows",
        "0..200",
        "--select-rows",
        "200..300",
        "-o",
        s(&out),
    ];
    ok(&args);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains("Figures (under plots/): the 2 sweep points have no figures of their own"),
        "{report}"
    );
    assert!(!report.contains("[[run]]` entries"), "{report}");
}

/// A transition that fires again and again at one point (a Zeno point):
/// `simulate`, `validate` and `identify` each say so on stderr.
#[test]
fn a_zeno_point_is_reported_by_every_command_that_runs_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = d.join("zeno.toml");
    std::fs::write(
        &model,
        r#"kind = "gray_box"
format = 1
internal_step = 0.001
states = ["T"]
inputs = ["u"]
outputs = ["T"]
initial_state = { from = "given", values = { T = 0.0 }, mode = "off" }
parameters = [{ name = "P", value = 2.0, bounds = [0.5, 5.0] }]
[[modes]]
name = "off"
flow = { T = "-T - 1 + u" }
[[modes]]
name = "on"
flow = { T = "-T + P + u" }
[[transitions]]
from = "off"
to = "on"
guard = "T <= 0"
[[transitions]]
from = "on"
to = "off"
guard = "T >= 0"
"#,
    )
    .unwrap();
    let record = d.join("z.csv");
    let zeno = "reached the bound of events per sub-step (a Zeno point";
    let said = |args: &[&str]| {
        let o = hysid(args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let excite = "n=100,hold=5,low=0,high=0.5,ts=0.1";
    let (m, r) = (s(&model), s(&record));
    let fitted = d.join("fit.json");
    for args in [
        vec!["simulate", m, "--excite", excite, "--seed", "1", "-o", r],
        vec!["validate", m, r],
        vec![
            "identify",
            r,
            "-m",
            "physical",
            "--set",
            &format!("model={m}"),
            "-o",
            s(&fitted),
        ],
    ] {
        let err = said(&args);
        assert!(err.contains(zeno), "{args:?}: {err}");
    }
}

/// Model files are swept as any option is: `sweep --grid model=A,B` fits
/// each, and an experiment's `vary = "model"` reads its files from the
/// experiment's folder; a swept file that does not exist is refused
/// before anything runs.
#[test]
fn model_files_can_be_swept() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let lag = |a: f64| {
        format!(
            "kind = \"gray_box\"\nformat = 1\ninternal_step = 0.01\nstates = [\"x\"]\n\
             inputs = [\"u\"]\noutputs = [\"x\"]\n\
             initial_state = {{ from = \"given\", values = {{ x = 0.0 }} }}\n\
             parameters = [{{ name = \"a\", value = {a}, bounds = [0.1, 10.0] }}]\n\
             [[modes]]\nname = \"only\"\nflow = {{ x = \"u - a*x\" }}\n"
        )
    };
    let (one, two) = (d.join("lag.toml"), d.join("lag2.toml"));
    std::fs::write(&one, lag(1.0)).unwrap();
    std::fs::write(&two, lag(3.0)).unwrap();
    let record = d.join("r.csv");
    let excite = "n=40,hold=5,low=0,high=1,ts=0.1";
    ok(&["simulate", s(&one), "--excite", excite, "-o", s(&record)]);
    let out = d.join("sweep");
    let grid = format!("model={},{}", one.display(), two.display());
    ok(&[
        "sweep",
        s(&record),
        "-m",
        "physical",
        "--grid",
        &grid,
        "--identify-rows",
        "0..20",
        "--select-rows",
        "20..40",
        "--warmup",
        "0",
        "--seed",
        "1",
        "-o",
        s(&out),
    ]);
    let names = |out: &Path| -> Vec<String> {
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        (report["results"].as_array().unwrap().iter())
            .inspect(|r| assert!(r["report"]["fit_sim"].is_number(), "{r}"))
            .map(|r| r["name"].as_str().unwrap().to_string())
            .collect()
    };
    assert_eq!(
        names(&out),
        ["physical [model=lag.toml]", "physical [model=lag2.toml]"]
    );
    let experiment = d.join("e.toml");
    let write = |second: &str| {
        let text = format!(
            "title = \"t\"\n[data]\nfile = \"r.csv\"\nidentification = \"0..20\"\n\
             validation = \"20..40\"\nwarmup = 0\n[[sweep]]\nname = \"lag\"\n\
             method = \"physical\"\nvary = \"model\"\nvalues = [\"lag.toml\", \"{second}\"]\n"
        );
        std::fs::write(&experiment, text).unwrap();
    };
    write("lag2.toml");
    let out = d.join("compare");
    ok(&["compare", s(&experiment), "-o", s(&out)]);
    assert_eq!(
        names(&out),
        ["lag [model=lag.toml]", "lag [model=lag2.toml]"]
    );
    write("lag3.toml");
    let err = one_line_error(&hysid(&["compare", s(&experiment), "-o", s(&out)]), 2).unwrap();
    assert!(
        err.contains("'lag': swept model = ") && err.ends_with("lag3.toml: no such file"),
        "{err}"
    );
}

/// A hand-written gray-box file's inputs are read where the record has no
/// `u` (by `validate`, and by `identify -m physical` fitting the file),
/// and named where the record has neither.
#[test]
fn a_gray_box_file_s_declared_inputs_are_read_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = d.join("lag.toml");
    std::fs::write(
        &model,
        r#"kind = "gray_box"
format = 1
internal_step = 0.01
states = ["x"]
inputs = ["F"]
outputs = ["x"]
initial_state = { from = "given", values = { x = 0.0 } }
parameters = [{ name = "a", value = 1.0, bounds = [0.1, 10.0] }]
[[modes]]
name = "only"
flow = { x = "F - a*x" }
"#,
    )
    .unwrap();
    let record = d.join("r.csv");
    let excite = "n=20,hold=5,low=0,high=1,ts=0.1";
    ok(&["simulate", s(&model), "--excite", excite, "-o", s(&record)]);
    ok(&["validate", s(&model), s(&record)]);
    let fitted = d.join("m.json");
    let set = format!("model={}", model.display());
    let identify = [
        "identify",
        s(&record),
        "-m",
        "physical",
        "--set",
        &set,
        "--seed",
        "1",
    ];
    ok(&[&identify[..], &["-o", s(&fitted)]].concat());
    ok(&["validate", s(&fitted), s(&record)]);
    // A record whose output is named as the file names it (`x`, not `y`)
    // is read so by `identify`, as by `validate`.
    let named = d.join("x.csv");
    let text = std::fs::read_to_string(&record).unwrap();
    std::fs::write(&named, text.replacen("t,F,y", "t,F,x", 1)).unwrap();
    let on_x = [&["identify", s(&named)], &identify[2..]].concat();
    ok(&[&on_x[..], &["-o", s(&d.join("x.json"))]].concat());
    ok(&["validate", s(&model), s(&named)]);
    // `sweep` reads them as `identify` does, and names them where the
    // record lacks the ones named.
    let long = d.join("long.csv");
    let excite_long = "n=40,hold=5,low=0,high=1,ts=0.1";
    ok(&[
        "simulate",
        s(&model),
        "--excite",
        excite_long,
        "-o",
        s(&long),
    ]);
    let sweep = [
        "sweep",
        s(&long),
        "-m",
        "physical",
        "--set",
        &set,
        "--grid",
        "segment=5,10",
        "--identify-rows",
        "0..20",
        "--select-rows",
        "20..40",
        "--warmup",
        "0",
    ];
    ok(&sweep);
    // A prior the file's parameters cannot take is refused before any
    // point runs, named by its file, as `identify` refuses it.
    let prior = d.join("p.toml");
    std::fs::write(&prior, "[bounds]\nb = [0.0, 1.0]\n").unwrap();
    let err = one_line_error(&hysid(&[&sweep[..], &["--prior", s(&prior)]].concat()), 2);
    let err = err.unwrap();
    assert!(
        err.contains("p.toml: [bounds]: unknown parameter 'b' (known: a)"),
        "{err}"
    );
    // So is a swept mode count the method does not take, named by its flag.
    let modes = [&sweep[..6], &["--grid", "modes=1,2"], &sweep[8..]].concat();
    let err = one_line_error(&hysid(&modes), 2).unwrap();
    assert!(
        err.contains("--grid modes: method 'physical' does not honour the prior modes"),
        "{err}"
    );
    let err = one_line_error(&hysid(&[&sweep[..], &["--input", "G"]].concat()), 2).unwrap();
    assert!(
        err.ends_with(
            "no column 'G' (available: t, F, y, mode); the model file declares --input F \
             --output x: name this record's signals with --input and --output"
        ),
        "{err}"
    );
    // An experiment reads `[data] input` (`u` by default); where the record
    // lacks it, the runs' model files' inputs are named.
    let experiment = d.join("e.toml");
    let write = |input: &str| {
        let text = format!(
            "title = \"t\"\n[data]\nfile = \"long.csv\"\n{input}identification = \"0..20\"\n\
             validation = \"20..40\"\n[[run]]\nname = \"lag\"\nmethod = \"physical\"\n\
             set = {{ model = \"lag.toml\" }}\nprovenance = \"user\"\n"
        );
        std::fs::write(&experiment, text).unwrap();
    };
    write("");
    let out = d.join("out");
    let compare = ["compare", s(&experiment), "-o", s(&out)];
    let err = one_line_error(&hysid(&compare), 2).unwrap();
    assert!(
        err.ends_with(
            "no column 'u' (available: t, F, y, mode); the model file of 'lag' declares the \
             inputs F: name the record's in [data] input"
        ),
        "{err}"
    );
    write("input = [\"F\"]\n");
    ok(&compare);
    // A state the file gives is applied at the first row read: said where
    // that is not the record's first, in the report (the validation rows
    // start at row 20) and by `validate`.
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains(
            "**Warning:** 'lag': its initial state is given by the file, not read from the \
             record: it is applied at row 20,"
        ),
        "{report}"
    );
    let given =
        "its initial state is given by the file, not read from the record: it is applied at row 5";
    let later = hysid(&["validate", s(&model), s(&record), "--rows", "5.."]);
    assert!(String::from_utf8_lossy(&later.stderr).contains(given));
    let rows = ["--rows", "5..", "-o", s(&fitted)];
    let later = hysid(&[&identify[..], &rows].concat());
    let said = String::from_utf8_lossy(&later.stderr);
    assert!(said.contains(&format!("lag.toml: {given}")), "{said}");
    let first = hysid(&["validate", s(&model), s(&record)]);
    assert!(!String::from_utf8_lossy(&first.stderr).contains("initial state is given"));
    // A record with `u` reads it, as the contract's default says.
    let with_u = d.join("u.csv");
    let text = std::fs::read_to_string(&record).unwrap();
    std::fs::write(&with_u, text.replacen("t,F,y", "t,u,y", 1)).unwrap();
    ok(&["validate", s(&model), s(&with_u)]);
    // One with both says which it reads.
    let both = d.join("both.csv");
    let lines: Vec<String> = (text.lines().enumerate())
        .map(|(i, line)| format!("{line},{}", if i == 0 { "u" } else { "0.5" }))
        .collect();
    std::fs::write(&both, lines.join("\n") + "\n").unwrap();
    let o = hysid(&["validate", s(&model), s(&both)]);
    assert!(o.status.success());
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        said.contains(
            "warning: the record has u and also F (the model file declares --input F): u is read, \
             as the default; give --input F to read F"
        ),
        "{said}"
    );
    let o = hysid(&["validate", s(&model), s(&both), "--input", "F"]);
    assert!(o.status.success() && !String::from_utf8_lossy(&o.stderr).contains("also F"));
    // So does an experiment whose [data] names no inputs; one that names
    // `u` reads it without a word.
    let on_both = d.join("both.toml");
    let compare_both = |input: &str| {
        let text = format!(
            "title = \"t\"\n[data]\nfile = \"both.csv\"\n{input}identification = \"0..10\"\n\
             validation = \"10..20\"\nwarmup = 2\n[[run]]\nname = \"lag\"\n\
             method = \"physical\"\nset = {{ model = \"lag.toml\" }}\n"
        );
        std::fs::write(&on_both, text).unwrap();
        let o = hysid(&["compare", s(&on_both), "-o", s(&d.join("out-both"))]);
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let said = compare_both("");
    assert!(
        said.contains(
            "both.toml: the record has u and also F (the model file of 'lag' declares F): u is \
             read, as the default; name F in [data] input to read it"
        ),
        "{said}"
    );
    assert!(!compare_both("input = [\"u\"]\n").contains("also F"));
    // A record with neither is refused naming both.
    let renamed = d.join("g.csv");
    std::fs::write(&renamed, text.replacen("t,F,y", "t,G,y", 1)).unwrap();
    let err = one_line_error(&hysid(&["validate", s(&model), s(&renamed)]), 2).unwrap();
    assert!(
        err.ends_with(
            "no column 'F' (available: t, G, y, mode); the model file declares --input F \
             --output x: name this record's signals with --input and --output"
        ),
        "{err}"
    );
    let err = one_line_error(
        &hysid(&["validate", s(&model), s(&renamed), "--input", "v"]),
        2,
    );
    assert!(
        err.unwrap()
            .ends_with("; the model file declares --input F --output x: name this record's signals with --input and --output")
    );
    ok(&["validate", s(&model), s(&renamed), "--input", "G"]);
    let renamed_record = [s(&renamed), "--input", "G"];
    let mut fit = identify.to_vec();
    fit.splice(1..2, renamed_record);
    ok(&[&fit[..], &["-o", s(&fitted)]].concat());
    // A fitted file is refitted on the signals it was fitted on.
    let again = d.join("again.json");
    let set_fitted = format!("model={}", fitted.display());
    let refit = [
        "identify",
        s(&renamed),
        "-m",
        "physical",
        "--set",
        &set_fitted,
    ];
    ok(&[&refit[..], &["--seed", "1", "-o", s(&again)]].concat());
    // A model file that cannot be read is named before the record is read.
    let set_missing = format!("model={}", d.join("nope.toml").display());
    let err = one_line_error(
        &hysid(&[
            "identify",
            s(&renamed),
            "-m",
            "physical",
            "--set",
            &set_missing,
            "-o",
            s(&again),
        ]),
        2,
    )
    .unwrap();
    assert!(
        err.contains("nope.toml") && !err.contains("no column"),
        "{err}"
    );
    // The time column is not a signal: no hint of the model's.
    let err = one_line_error(
        &hysid(&["validate", s(&model), s(&record), "--time", "tt"]),
        2,
    );
    assert!(!err.unwrap().contains("the model file declares"));
}

/// A hand-written file's declared inputs given in another order are warned
/// of, by `validate` and by a physical `identify`, as a fitted model's are.
#[test]
fn a_swap_of_a_file_s_declared_inputs_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = d.join("two.toml");
    std::fs::write(
        &model,
        r#"kind = "gray_box"
format = 1
internal_step = 0.01
states = ["x"]
inputs = ["F1", "F2"]
outputs = ["x"]
initial_state = { from = "given", values = { x = 0.0 } }
parameters = [{ name = "a", value = 1.0, bounds = [0.1, 10.0] }]
[[modes]]
name = "only"
flow = { x = "F1 + 2*F2 - a*x" }
"#,
    )
    .unwrap();
    let record = d.join("r.csv");
    let excite = "n=40,hold=5,low=0,high=1,ts=0.1";
    ok(&["simulate", s(&model), "--excite", excite, "-o", s(&record)]);
    let said = common::ok_stderr;
    let swapped = ["--input", "F2,F1"];
    let warning = "the inputs are read in the order given (F2, F1)";
    let validate = said(&[&["validate", s(&model), s(&record)][..], &swapped].concat());
    assert!(
        validate.contains(warning) && validate.contains("declares them in the order F1, F2"),
        "{validate}"
    );
    let set = format!("model={}", model.display());
    let out = d.join("m.json");
    let fit = [
        "identify",
        s(&record),
        "-m",
        "physical",
        "--set",
        &set,
        "-o",
        s(&out),
    ];
    let identify = said(&[&fit[..], &swapped].concat());
    assert!(
        identify.contains(warning) && identify.contains("the model file names them"),
        "{identify}"
    );
    assert!(!said(&fit).contains("order"));
}

/// A definition no expression reads, here an `extends` file's misspelt
/// change of the base's, is named by every command that runs the model.
#[test]
fn a_definition_no_expression_reads_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = common::repository_text("models/examples/ball-on-table.toml")
        .replace("inputs = [\"a\"]", "inputs = [\"u\"]")
        .replace("a - 2*zeta", "u - 2*zeta");
    common::write(d, "base.toml", base);
    let changed = common::write(
        d,
        "changed.toml",
        "extends = \"base.toml\"\n[definitions]\ntable_ac = \"u - 3*zeta*wn*w - wn^2*z\"\n",
    );
    let said = "changed.toml: no expression reads the definition(s) table_ac: a misspelt name?";
    let record = d.join("record.csv");
    let excite = "n=100,hold=10,low=-1,high=1,ts=0.01";
    let out = common::ok_stderr;
    let simulate = [
        "simulate",
        s(&changed),
        "--excite",
        excite,
        "-o",
        s(&record),
    ];
    assert!(out(&simulate).contains(said));
    assert!(out(&["validate", s(&changed), s(&record)]).contains(said));
    let set = format!("model={}", s(&changed));
    let fitted = d.join("fitted.json");
    let err = out(&[
        "identify",
        s(&record),
        "-m",
        "physical",
        "--set",
        &set,
        "-o",
        s(&fitted),
    ]);
    assert!(
        err.contains("no expression reads the definition(s) table_ac"),
        "{err}"
    );
    let base = d.join("base.toml");
    assert!(!out(&["validate", s(&base), s(&record)]).contains("no expression reads"));
}

/// A prior file whose name ends in `.json` is read as JSON of the same
/// entries: the same model as the TOML file gives, and a JSON syntax
/// error names the file and the line. An empty prior file is warned of.
#[test]
fn a_json_prior_file_reads_as_its_toml_form() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    // `identify -m arx` with the prior file `prior`, writing `out`.
    let identify = |prior: &Path, out: &Path| {
        hysid(&[
            "identify",
            s(&data),
            "-m",
            "arx",
            "--prior",
            s(prior),
            "-o",
            s(out),
        ])
    };
    let fit = |prior: &Path, out: &str| -> String {
        let out = dir.path().join(out);
        let o = identify(prior, &out);
        assert!(o.status.success(), "{o:?}");
        std::fs::read_to_string(out).unwrap()
    };
    let toml = common::write(
        dir.path(),
        "p.toml",
        "[fixed]\nc = 0.25\n[bounds]\na1 = [0.0, 0.5]\n",
    );
    let json = common::write(
        dir.path(),
        "p.json",
        "{\"fixed\": {\"c\": 0.25}, \"bounds\": {\"a1\": [0.0, 0.5]}}",
    );
    let (a, b) = (fit(&toml, "a.json"), fit(&json, "b.json"));
    let modes =
        |text: &str| serde_json::from_str::<serde_json::Value>(text).unwrap()["modes"].clone();
    assert_eq!(modes(&a), modes(&b));
    assert_eq!(
        modes(&a)[0]["theta"].as_array().unwrap().last().unwrap(),
        0.25
    );
    let broken = common::write(dir.path(), "broken.json", "{\"fixed\": {\"c\": 0.25,}}");
    let out = dir.path().join("never.json");
    let err = one_line_error(&identify(&broken, &out), 2).unwrap();
    assert!(
        err.contains("broken.json") && err.contains("line 1"),
        "{err}"
    );
    assert!(!out.exists());
    // A file that holds no prior is read, and said to hold none.
    let empty = common::write(dir.path(), "empty.toml", "# to be written\n");
    let o = identify(&empty, &out);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("empty.toml: no prior in it"),
        "{err}"
    );
}

/// The terms of a linear form as `hysid show` writes it (`1.5 y(k-1) -
/// u(k-1) + 0.3`): each regressor's coefficient by name, the constant
/// under "".
fn linear_terms(form: &str) -> std::collections::BTreeMap<String, f64> {
    let mut terms = std::collections::BTreeMap::new();
    for term in form.replace(" - ", " + -").split(" + ") {
        let (sign, term) = match term.strip_prefix('-') {
            Some(rest) => (-1.0, rest),
            None => (1.0, term),
        };
        let (value, name) = match term.split_once(' ') {
            Some((c, name)) => (c.parse::<f64>().unwrap(), name.to_string()),
            None => match term.parse::<f64>() {
                Ok(c) => (c, String::new()),
                Err(_) => (1.0, term.to_string()),
            },
        };
        terms.insert(name, sign * value);
    }
    terms
}

/// `hysid show` writes each PWARX mode's equation with every coefficient
/// on the regressor it multiplies (read back, they are the file's theta
/// to the six digits written) and its region's rows; a fitted physical
/// model's parameters with their values and what the fit says of each; an
/// automaton's guard sets (equality rows too) and resets.
#[test]
fn show_writes_equations_regions_and_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_mode_record(dir.path(), 300);
    let model = dir.path().join("m.json");
    let identify = [
        "identify",
        s(&data),
        "-m",
        "cluster",
        "--na",
        "1",
        "--nb",
        "1",
        "--modes",
        "2",
        "-o",
    ];
    ok(&[&identify[..], &[s(&model)]].concat());
    let text = ok(&["show", s(&model)]);
    assert!(
        text.starts_with(&format!("{}: pwarx model, 2 mode(s)", s(&model))),
        "{text}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-5 * b.abs().max(1e-3);
    for (i, mode) in json["modes"].as_array().unwrap().iter().enumerate() {
        let lead = format!("mode {}: y(k) = ", i + 1);
        let line = text.lines().find(|l| l.starts_with(&lead)).unwrap();
        let terms = linear_terms(&line[lead.len()..]);
        let theta: Vec<f64> = serde_json::from_value(mode["theta"].clone()).unwrap();
        for (name, value) in ["y(k-1)", "u(k-1)", ""].iter().zip(&theta) {
            let written = terms.get(*name).copied().unwrap_or(0.0);
            assert!(
                close(written, *value),
                "{name}: {written} against {value} in {line}"
            );
        }
        let rows = mode["region"]["a"].as_array().unwrap().len();
        let at = text.find(line).unwrap() + line.len();
        let region = text[at..]
            .lines()
            .skip(1)
            .take_while(|l| l.starts_with("  "))
            .count();
        assert_eq!(region, rows.max(1), "{text}");
    }
    let head = "docs/pick-and-place/models/physical_head.toml___seed_1.json";
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let text = ok(&["show", &format!("{root}/{head}")]);
    let json: serde_json::Value = serde_json::from_str(&common::repository_text(head)).unwrap();
    let fitted = &json["info"]["diagnostics"]["parameters"];
    for p in json["parameters"].as_array().unwrap() {
        let name = p["name"].as_str().unwrap();
        let row = (text.lines())
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("no row for {name}: {text}"));
        let value: f64 = row.split_whitespace().nth(1).unwrap().parse().unwrap();
        assert!(close(value, p["value"].as_f64().unwrap()), "{row}");
        let said = match fitted[name]["identifiability"].as_str() {
            _ if p["fixed"] == true => "fixed".to_string(),
            Some(kind) => kind.replace('_', " "),
            None => panic!("{name} has no identifiability"),
        };
        assert!(row.ends_with(&said), "{row}");
    }
    let ball = format!("{root}/models/examples/bouncing-ball.toml");
    let text = ok(&["show", &ball]);
    assert!(
        text.contains(
            "transition fly -> fly:\n  guard v <= 0\n        y = 0\n  reset v := -0.75 v\n"
        ),
        "{text}"
    );
    let missing = dir.path().join("none.json");
    let err = one_line_error(&hysid(&["show", s(&missing)]), 2).unwrap();
    assert!(err.contains("none.json"), "{err}");
}
