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

/// Runs `hysid` with `CI` unset and stderr a pipe (not a terminal).
fn hysid_off_terminal(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_hysid"))
        .args(args)
        .env_remove("CI")
        .stderr(std::process::Stdio::piped())
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

/// A two-mode PWARX record (switching on the sign of y(k-1)) and a small
/// experiment on it: two ARX runs, a two-mode cluster run, and a sweep.
fn small_experiment(dir: &Path) -> std::path::PathBuf {
    let truth = dir.join("truth.json");
    std::fs::write(
        &truth,
        r#"{"kind":"pwarx","na":2,"nb":1,"inputs":1,
            "modes":[{"theta":[1.2,-0.5,0.7,0.1],"region":{"a":[[1,0,0]],"b":[0]}},
                     {"theta":[0.9,-0.3,1.4,-0.2],"region":{"a":[[-1,0,0]],"b":[0]}}]}"#,
    )
    .unwrap();
    let data = dir.join("data.csv");
    let (code, _, err) = hysid(&[
        "simulate",
        s(&truth),
        "--excite",
        "n=600,hold=7,low=-1,high=1,ts=0.01",
        "--noise",
        "0.01",
        "--seed",
        "2",
        "-o",
        s(&data),
    ]);
    assert_eq!(code, 0, "{err}");
    let exp = dir.join("exp.toml");
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
output_label = "position y [mm]"
input_label = "drive u [V]"
[[run]]
name = "plain"
method = "arx"
[[run]]
name = "ridge"
method = "arx"
set = { ridge = 10.0 }
[[run]]
name = "two modes"
method = "cluster"
modes = 2
set = { c = 12 }
[[sweep]]
name = "orders"
method = "arx"
vary = "na"
values = [1, 3]
"#,
    )
    .unwrap();
    exp
}

/// [`small_experiment`]'s file and its text up to its first `[[run]]`, to
/// which a test adds runs of its own.
fn small_experiment_head(dir: &Path) -> (std::path::PathBuf, String) {
    let exp = small_experiment(dir);
    let text = std::fs::read_to_string(&exp).unwrap();
    let head = text[..text.find("[[run]]").unwrap()].to_string();
    (exp, head)
}

/// The `report.json` a comparison wrote into `out`.
fn report_json(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

/// The figure links `(plots/....svg)` or `(plots/....png)` of a report.
fn linked_plots(md: &str) -> Vec<String> {
    md.split("](")
        .skip(1)
        .filter_map(|rest| rest.split_once(')').map(|(link, _)| link.to_string()))
        .filter(|l| l.starts_with("plots/") && (l.ends_with(".svg") || l.ends_with(".png")))
        .collect()
}

#[test]
fn report_matches_the_models_it_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let exp = small_experiment(dir.path());
    let data = dir.path().join("data.csv");
    let out = dir.path().join("out");
    let (code, stdout, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let report = report_json(&out);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert_eq!(stdout, md);
    let results = report["results"].as_array().unwrap();
    assert_eq!(results.len(), 5);
    let names: Vec<&str> = results
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "plain",
            "ridge",
            "two modes",
            "orders [na=1]",
            "orders [na=3]"
        ]
    );
    for r in results {
        let model = out.join(r["model_file"].as_str().unwrap());
        let written: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
        let modes = written["modes"].as_array().unwrap().len();
        assert_eq!(r["modes"], modes, "modes of {}", r["name"]);
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
        let f = |key: &str| v[key].as_f64().unwrap();
        // The runs declare no provenance; the sweep's better point is
        // labelled oracle (checked below).
        let provenance = match r["origin"].as_str().unwrap() {
            "unstated" => "not stated",
            "sweep_point" => "sweep point",
            "sweep_best" => "oracle (best of the sweep on these test rows)",
            other => panic!("{}: origin {other}", r["name"]),
        };
        let row = format!(
            "| {} | {provenance} | {} | {} | {} | {modes} | {:.2} | {:.4} | {:.2} | {:.3} |",
            r["name"].as_str().unwrap(),
            r["method"].as_str().unwrap(),
            r["na"],
            r["nb"],
            f("fit_sim"),
            f("rmse_sim"),
            f("fit_pred"),
            f("coverage"),
        );
        assert!(md.contains(&row), "missing row {row} in\n{md}");
    }
    assert_eq!(results[2]["modes"], 2, "the cluster run has two modes");
    let origins: Vec<&str> = results
        .iter()
        .map(|r| r["origin"].as_str().unwrap())
        .collect();
    let sweep_fit = |k: usize| results[k]["report"]["fit_sim"].as_f64().unwrap();
    let best = if sweep_fit(4) > sweep_fit(3) { 4 } else { 3 };
    assert_eq!(origins[..3], ["unstated"; 3]);
    assert_eq!(origins[best], "sweep_best", "{origins:?}");
    assert_eq!(origins[7 - best], "sweep_point", "{origins:?}");
    // On this two-mode record the two-mode model simulates better than ARX.
    let fit = |k: usize| results[k]["report"]["fit_sim"].as_f64().unwrap();
    assert!(
        fit(2) > fit(0) + 5.0,
        "cluster {} against arx {}",
        fit(2),
        fit(0)
    );

    // Every linked figure exists; the two-mode run has a region figure with
    // units from the experiment's labels; the footer says what is there.
    let links = linked_plots(&md);
    for l in &links {
        assert!(out.join(l).is_file(), "{l} is linked but missing");
    }
    assert!(
        links.contains(&"plots/two_modes-regions.svg".to_string()),
        "{links:?}"
    );
    assert!(!links.iter().any(|l| l.starts_with("plots/plain-regions")));
    assert!(
        links.contains(&"plots/orders-sweep.svg".to_string()),
        "{links:?}"
    );
    let mut on_disk: Vec<String> = std::fs::read_dir(out.join("plots"))
        .unwrap()
        .map(|e| format!("plots/{}", e.unwrap().file_name().to_string_lossy()))
        .collect();
    on_disk.sort();
    let mut linked = links.clone();
    linked.sort();
    linked.dedup();
    assert_eq!(linked, on_disk, "every figure written is linked");
    assert!(
        md.contains("the 2 sweep points have no figures of their own"),
        "{md}"
    );
    let regions = std::fs::read_to_string(out.join("plots/two_modes-regions.svg")).unwrap();
    assert!(regions.contains("y(k-1) [mm]"), "output lags in mm");
    assert!(regions.contains("u(k-1) [V]"), "input lags in V");
    let sweep = std::fs::read_to_string(out.join("plots/orders-sweep.svg")).unwrap();
    assert!(sweep.contains("na [-]") && sweep.contains("modes [-]"));
}

/// Runs whose simulations start at different samples (here regressors of
/// 1 and 4 lags, with a warm-up of 1) are all scored from the latest
/// start, as `hysid validate` scores each with that warm-up, and the
/// report says why its warm-up is longer than the one asked for.
#[test]
fn every_run_is_scored_on_the_same_samples() {
    let dir = tempfile::tempdir().unwrap();
    let (exp, head) = small_experiment_head(dir.path());
    let head = head.replace("warmup = 5", "warmup = 1");
    let runs = ["short lags", "long lags"];
    std::fs::write(
        &exp,
        format!(
            "{head}[[run]]\nname = \"{}\"\nmethod = \"arx\"\nna = 1\nnb = 1\n\
             [[run]]\nname = \"{}\"\nmethod = \"arx\"\nna = 4\nnb = 4\n",
            runs[0], runs[1]
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let report = report_json(&out);
    assert_eq!(report["warmup"], 4);
    assert_eq!(report["warmup_raised"]["asked"], 1);
    assert_eq!(report["warmup_raised"]["run"], "long lags");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains(
            "leave out the first 4 samples: the warm-up of 1 asked for, lengthened so that every \
             run is scored on the same samples (the simulation of long lags starts at sample 4)."
        ),
        "{md}"
    );
    let results = report["results"].as_array().unwrap();
    for (r, name) in results.iter().zip(runs) {
        assert_eq!(r["name"], name);
        assert_eq!(
            r["report"]["n"], 196,
            "{name}: 200 validation samples, 4 left out"
        );
        let (code, v, err) = hysid(&[
            "validate",
            s(&out.join(r["model_file"].as_str().unwrap())),
            s(&dir.path().join("data.csv")),
            "--rows",
            "400..",
            "--warmup",
            "4",
            "--json",
        ]);
        assert_eq!(code, 0, "{err}");
        let v: serde_json::Value = serde_json::from_str(&v).unwrap();
        assert_eq!(v["fit_sim"], r["report"]["fit_sim"], "{name}");
    }
}

#[test]
fn compare_off_a_terminal_prints_no_progress_bar() {
    let dir = tempfile::tempdir().unwrap();
    let exp = small_experiment(dir.path());
    let out = dir.path().join("out");
    let (code, stdout, err) = hysid_off_terminal(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.starts_with("# small"), "{stdout}");
    // indicatif draws with carriage returns and its template text; off a
    // terminal nothing of it reaches stderr.
    assert!(!err.contains('\r'), "progress output on stderr: {err:?}");
    assert!(
        !err.contains("identifying"),
        "progress output on stderr: {err:?}"
    );
    // The only line on stderr is the closing message.
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "{err:?}");
    assert!(lines[0].starts_with("hysid: report written to "), "{err:?}");
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

/// `--format png`: every figure the report links is a PNG image in
/// `plots/`, no SVG is written; an unknown format is refused up front.
#[cfg(feature = "png")]
#[test]
fn figures_as_png_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let exp = small_experiment(dir.path());
    let out = dir.path().join("out");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out), "--format", "png"]);
    assert_eq!(code, 0, "{err}");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let plots = linked_plots(&md);
    assert!(!plots.is_empty());
    for p in &plots {
        assert!(p.ends_with(".png"), "{p}");
        let bytes = std::fs::read(out.join(p)).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{p}");
    }
    let svgs = std::fs::read_dir(out.join("plots"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "svg")
        })
        .count();
    assert_eq!(svgs, 0);
    let bad = dir.path().join("bad");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&bad), "--format", "gif"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--format") && err.contains("svg or png"),
        "{err}"
    );
    assert!(!bad.exists());
}

/// `[data] folds = K`: an `auto` run chooses its options on `K` rolling
/// folds of the identification rows, as `hysid identify --auto --folds K`
/// does, and its model records the `K - 1` splits; giving both `folds` and
/// `selection` is refused, and so is `refit_starts = 0`.
#[test]
fn auto_runs_choose_on_folds() {
    let dir = tempfile::tempdir().unwrap();
    let (exp, head) = small_experiment_head(dir.path());
    let folded = head.replace("warmup = 5\n", "warmup = 5\nfolds = 4\n")
        + "[[run]]\nname = \"auto\"\nmethod = \"arx\"\nauto = true\nna = 4\nnb = 4\n";
    std::fs::write(&exp, &folded).unwrap();
    let out = dir.path().join("out");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let report = report_json(&out);
    let file = report["results"][0]["model_file"].as_str().unwrap();
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(file)).unwrap()).unwrap();
    let splits = model["info"]["selection"]["splits"].as_array().unwrap();
    assert_eq!(splits.len(), 3, "{splits:?}");
    // The report's orders are the model's: auto chose them below the
    // run's na = nb = 4.
    let row = &report["results"][0];
    assert_eq!((&row["na"], &row["nb"]), (&model["na"], &model["nb"]));
    assert_ne!((row["na"].as_u64(), row["nb"].as_u64()), (Some(4), Some(4)));
    assert_eq!(splits[0]["fit_rows"], "0..100");
    assert_eq!(splits[2]["select_rows"], "300..400");

    let both = folded.replace("folds = 4\n", "folds = 4\nselection = \"300..400\"\n");
    std::fs::write(&exp, both).unwrap();
    let out = dir.path().join("out2");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 2);
    assert!(err.contains("selection and folds"), "{err}");
    assert!(!out.exists());

    let none = folded.replace("folds = 4\n", "folds = 4\nrefit_starts = 0\n");
    std::fs::write(&exp, none).unwrap();
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 2);
    assert!(err.contains("refit_starts must be in 1..=100000"), "{err}");
    assert!(!out.exists());
}

/// A `[[run]]` with `seeds` whose fit does not depend on the seed (`bayes`
/// with its exact Gaussian posterior) runs once for all its seeds, and the
/// report says so; one that does (`cluster`) runs every seed.
#[test]
fn a_seed_free_run_runs_once_for_its_seeds() {
    let dir = tempfile::tempdir().unwrap();
    let (exp, head) = small_experiment_head(dir.path());
    let seeded = head
        + "[[run]]\nname = \"bayes\"\nmethod = \"bayes\"\nmodes = 2\nseeds = [1, 2, 3]\n"
        + "[[run]]\nname = \"particles\"\nmethod = \"bayes\"\nmodes = 2\nseeds = [1, 2]\n"
        + "set = { posterior = \"particles\" }\n"
        + "[[run]]\nname = \"cluster\"\nmethod = \"cluster\"\nmodes = 2\nseeds = [1, 2]\n";
    std::fs::write(&exp, &seeded).unwrap();
    let out = dir.path().join("out");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let report = report_json(&out);
    let runs: Vec<(String, Vec<u64>)> = report["results"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            let same = r["same_for_seeds"]
                .as_array()
                .map(|a| a.iter().map(|v| v.as_u64().unwrap()).collect())
                .unwrap_or_default();
            (r["name"].as_str().unwrap().to_string(), same)
        })
        .collect();
    let names: Vec<&str> = runs.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "bayes [seed=1]",
            "particles [seed=1]",
            "particles [seed=2]",
            "cluster [seed=1]",
            "cluster [seed=2]"
        ]
    );
    assert_eq!(runs[0].1, [2, 3]);
    assert!(
        runs[1..].iter().all(|(_, same)| same.is_empty()),
        "{runs:?}"
    );
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains(
            "| bayes | not stated | 3 (one run: the fit does not depend on the seed) | 1 |"
        ),
        "{md}"
    );
    assert!(md.contains("| particles | not stated | 2 | 2 |"), "{md}");
}

/// A build without the `png` feature refuses `--format png` up front,
/// saying how to build it, and writes nothing.
#[cfg(not(feature = "png"))]
#[test]
fn png_figures_need_the_png_feature() {
    let dir = tempfile::tempdir().unwrap();
    let exp = small_experiment(dir.path());
    let out = dir.path().join("out");
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out), "--format", "png"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--format") && err.contains("--features png"),
        "{err}"
    );
    assert!(!out.exists());
}

/// What an experiment names or lists that cannot work is refused before
/// anything runs, naming the entry: two names that give one file name, a
/// name without a letter or digit, a seed or a sweep value listed twice,
/// an empty `seeds`, a prior name the orders lack, a prior kind the
/// back-end does not honour.
#[test]
fn entries_that_cannot_work_are_refused_before_anything_runs() {
    let dir = tempfile::tempdir().unwrap();
    let (exp, head) = small_experiment_head(dir.path());
    let out = dir.path().join("out");
    let arx = |name: &str, extra: &str| {
        format!("[[run]]\nname = \"{name}\"\nmethod = \"arx\"\n{extra}\n")
    };
    for (runs, needle) in [
        (
            arx("m 1", "") + &arx("m/1", ""),
            "'m 1' and 'm/1' would write their results to one file name, 'm_1'",
        ),
        (
            arx("A", "") + &arx("a", ""),
            "'A' and 'a' would write their results to one file name, 'a'",
        ),
        (
            arx("Runs", ""),
            "'the figure of all runs' and 'Runs' would write their results to one file name",
        ),
        (arx("()", ""), "name '()': needs a letter or a digit"),
        (
            arx("a", "seeds = [1, 2, 1]"),
            "[[run]] 'a': seeds lists 1 twice",
        ),
        (arx("a", "seeds = []"), "an empty list: give the seeds"),
        (
            "[[sweep]]\nname = \"s\"\nmethod = \"arx\"\nvary = \"na\"\nvalues = [1, 2, 1]\n"
                .to_string(),
            "[[sweep]] 's': na lists 1 twice",
        ),
        (
            arx("s [na=1]", "")
                + "[[sweep]]\nname = \"s\"\nmethod = \"arx\"\nvary = \"na\"\nvalues = [1, 2]\n",
            "would write their results to one file name, 's__na_1'",
        ),
        (
            "[[sweep]]\nname = \"s\"\nmethod = \"arx\"\nvary = \"ridge\"\nvalues = [0, 1]\nset = { ridge = 2 }\n"
                .to_string(),
            "[[sweep]] 's': ridge is swept and also fixed (set = { ridge = ... })",
        ),
        (
            "[[run]]\nname = \"c\"\nmethod = \"cluster\"\nmodes = 3\npriors = { modes = 2 }\n"
                .to_string(),
            "[[run]] 'c': modes given twice (modes = 3 and priors = { modes = 2 }): give it in one place",
        ),
        (
            arx("a", "priors = { modes = 2 }"),
            "[[run]] 'a': prior modes = 2: method 'arx' identifies exactly one ordinary mode",
        ),
        (
            "[priors]\nmodes = 2\n[[sweep]]\nname = \"s\"\nmethod = \"cluster\"\nvary = \"modes\"\nvalues = [2, 3]\n"
                .to_string(),
            "[[sweep]] 's': modes is swept and also fixed ([priors] modes = ...)",
        ),
        (
            "[[sweep]]\nname = \"s\"\nmethod = \"arx\"\nvary = \"na\"\nvalues = [1, 2]\ngrid = { na = [3] }\n"
                .to_string(),
            "[[sweep]] 's': na is both vary and a grid key",
        ),
        (
            arx("a", "priors = { tie = [{ params = [\"a3\"] }] }"),
            "[[run]] 'a': prior [[tie]] params: unknown name 'a3'",
        ),
        (
            "[[run]]\nname = \"b\"\nmethod = \"bayes\"\nmodes = 2\npriors = { tie = [{ params = [\"b1\"] }] }\n"
                .to_string(),
            "[[run]] 'b': method 'bayes' does not honour the prior [[tie]]",
        ),
    ] {
        std::fs::write(&exp, format!("{head}{runs}")).unwrap();
        let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
        assert_eq!(code, 2, "{runs}: {err}");
        assert!(
            err.contains("exp.toml") && err.contains(needle),
            "{runs}: {err}"
        );
        assert!(!out.exists(), "{runs}");
    }
}

/// Scored rows that an entry of the same file and signals identifies on:
/// the warning is in the report, and an `auto` run there is labelled an
/// oracle; a second report into the folder removes the first one's models
/// and figures that it does not write.
#[test]
fn overlapping_rows_are_reported_and_a_folder_holds_one_report() {
    let dir = tempfile::tempdir().unwrap();
    let (exp, head) = small_experiment_head(dir.path());
    let out = dir.path().join("out");
    let records = "[[data.records]]\nfile = \"data.csv\"\nidentification = \"420..480\"\n";
    let runs = "[[run]]\nname = \"auto\"\nmethod = \"arx\"\nauto = true\n\
                [[run]]\nname = \"later gone\"\nmethod = \"arx\"\n";
    std::fs::write(&exp, format!("{head}{records}{runs}")).unwrap();
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let warning = "the validation rows 400.. overlap the identification rows 420..480 of \
                   [[data.records]] #1 (the same file and signals)";
    assert!(err.contains(warning), "{err}");
    let report = report_json(&out);
    assert!(report["warnings"][0].as_str().unwrap().contains(warning));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("| auto | oracle (chosen on these test rows) |"),
        "{md}"
    );
    assert!(out.join("models/later_gone.json").exists());
    // Without the overlap and the second run: no warning, the label of a
    // choice on selection rows, and the second run's files gone.
    let runs = "[[run]]\nname = \"auto\"\nmethod = \"arx\"\nauto = true\n";
    std::fs::write(&exp, format!("{head}{runs}")).unwrap();
    let (code, _, err) = hysid(&["compare", s(&exp), "-o", s(&out)]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("warning"), "{err}");
    assert!(report_json(&out).get("warnings").is_none());
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("| auto | chosen on selection rows |"), "{md}");
    let left: Vec<_> = std::fs::read_dir(out.join("models")).unwrap().collect();
    assert_eq!(left.len(), 1);
    let plots = std::fs::read_dir(out.join("plots")).unwrap();
    assert!(
        plots
            .into_iter()
            .all(|p| !p.unwrap().file_name().to_string_lossy().contains("later"))
    );
}
