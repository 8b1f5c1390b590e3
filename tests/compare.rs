//! `hysid compare` end to end: a small experiment, and its report checked
//! against the models it wrote (re-validated by `hysid validate`).

use std::path::Path;
use std::process::Command;

fn hysid(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_hysid"))
        .args(args)
        .env("CI", "1")
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn report_matches_the_models_it_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let truth = dir.path().join("truth.json");
    std::fs::write(
        &truth,
        r#"{"kind":"pwarx","na":2,"nb":1,"inputs":1,
            "modes":[{"theta":[1.2,-0.5,0.7,0.1],"region":{"a":[],"b":[]}}]}"#,
    )
    .unwrap();
    let data = dir.path().join("data.csv");
    let (code, _, err) = hysid(&[
        "simulate",
        s(&truth),
        "--excite",
        "n=600,hold=7,low=-1,high=1,ts=0.01",
        "--noise",
        "0.05",
        "--seed",
        "2",
        "-o",
        s(&data),
    ]);
    assert_eq!(code, 0, "{err}");
    let exp = dir.path().join("exp.toml");
    std::fs::write(
        &exp,
        r#"
title = "small"
na = 2
nb = 1
[data]
file = "data.csv"
identification = "0..400"
validation = "400.."
warmup = 5
[[run]]
name = "plain"
method = "arx"
[[run]]
name = "ridge"
method = "arx"
set = { ridge = 10.0 }
[[sweep]]
name = "orders"
method = "arx"
vary = "na"
values = [1, 3]
"#,
    )
    .unwrap();
    let out = dir.path().join("out");
    let (code, stdout, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert_eq!(stdout, md);
    let results = report["results"].as_array().unwrap();
    assert_eq!(results.len(), 4);
    let names: Vec<&str> = results
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["plain", "ridge", "orders [na=1]", "orders [na=3]"]);
    for r in results {
        let model = out.join(r["model_file"].as_str().unwrap());
        let (code, v, err) = hysid(&[
            "validate",
            s(&model),
            s(&data),
            "--rows",
            "400..",
            "--warmup",
            "5",
            "--json",
        ]);
        assert_eq!(code, 0, "{err}");
        let v: serde_json::Value = serde_json::from_str(&v).unwrap();
        for key in ["fit_sim", "rmse_sim", "fit_pred", "coverage", "n"] {
            assert_eq!(v[key], r["report"][key], "{key} of {}", r["name"]);
        }
        let row = format!(
            "| {} | arx | {} | {} | 1 | {:.2} |",
            r["name"].as_str().unwrap(),
            r["na"],
            r["nb"],
            v["fit_sim"].as_f64().unwrap()
        );
        assert!(md.contains(&row), "missing row {row} in\n{md}");
    }
    // The exact model beats the heavily regularised one.
    assert!(results[0]["report"]["fit_sim"].as_f64() > results[1]["report"]["fit_sim"].as_f64());
}

#[test]
fn a_bad_experiment_is_a_usage_error_with_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let exp = dir.path().join("exp.toml");
    std::fs::write(&exp, "title = \"x\"\n[data]\nfile = \"d.csv\"\nidentification = \"0..1\"\nvalidation = \"1..\"\n[[run]]\nname = \"a\"\nmethod = \"nosuch\"\n").unwrap();
    let out = dir.path().join("out");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 2);
    assert!(
        err.contains("exp.toml") && err.contains("unknown method 'nosuch'"),
        "{err}"
    );
    assert!(!out.exists());
}
