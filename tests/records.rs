//! Several records of one system, from the program: `identify` fits one
//! model on all of them (every back-end), `validate` scores each record as
//! on its own and all together; bad combinations are one-line errors.

use crate::common;

use common::{hysid, ok, one_line_error, s, two_mode_record_as as record, write};
use std::path::{Path, PathBuf};

fn json(text: &str) -> serde_json::Value {
    serde_json::from_str(text).unwrap()
}

/// Every PWARX back-end fits two records together, and its two-mode model
/// predicts them better than the affine one; `validate` on both scores each
/// record exactly as on its own and pools their samples.
#[test]
fn every_backend_fits_several_records_and_validate_scores_each() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = record(d, "a.csv", 160, 11, 0.01);
    let b = record(d, "b.csv", 120, 12, 0.01);
    let model = d.join("m.json");
    let mut affine = f64::NAN;
    for method in [
        "arx", "cluster", "bounded", "klinreg", "bayes", "parc", "milp",
    ] {
        let mut args = vec![
            "identify",
            s(&a),
            s(&b),
            "-m",
            method,
            "--na",
            "1",
            "--nb",
            "1",
        ];
        if method != "arx" {
            args.extend(["--modes", "2"]);
        }
        if method == "bounded" {
            args.extend(["--set", "delta=auto"]);
        }
        // The exact program takes 40 samples by default: 20 of each record.
        let samples = if method == "milp" {
            args.extend(["--rows", "..21"]);
            42
        } else {
            280
        };
        args.extend(["-o", s(&model)]);
        let o = hysid(&args);
        assert!(
            o.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let said = String::from_utf8_lossy(&o.stderr);
        assert!(
            said.contains(&format!("from {samples} samples of 2 records")),
            "{method}: {said}"
        );
        let whole = json(&ok(&["validate", s(&model), s(&a), s(&b), "--json"]));
        let parts = whole["records"].as_array().unwrap();
        assert_eq!(parts.len(), 2, "{method}");
        for (part, file) in parts.iter().zip([&a, &b]) {
            // Each part names its file; the rest is the file's own report.
            let mut part = part.clone();
            let named = part.as_object_mut().unwrap().remove("file");
            assert_eq!(named, Some(s(file).into()), "{method}");
            let alone = json(&ok(&["validate", s(&model), s(file), "--json"]));
            assert_eq!(part, alone, "{method}: {}", file.display());
        }
        assert_eq!(whole["n"], 150 + 110, "{method}");
        let fit_pred = whole["fit_pred"].as_f64().unwrap();
        eprintln!(
            "{method}: fit_pred {fit_pred:.2} %, fit_sim {}",
            whole["fit_sim"]
        );
        if method == "arx" {
            affine = fit_pred;
        } else {
            assert!(
                fit_pred > affine + 5.0,
                "{method}: {fit_pred} against {affine}"
            );
        }
    }
}

/// An affine ARX model fitted on two records is the least-squares fit of
/// each record's rows: the same as the fit on the two records written one
/// after the other into one file and read back as two records cut at the
/// seam (`--rows` per record), and not the fit on that file as one record,
/// whose first rows of the second part regress on the first part's last
/// samples.
#[test]
fn two_records_give_the_fit_of_their_rows_and_not_of_their_concatenation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = record(d, "a.csv", 150, 21, 0.01);
    let b = record(d, "b.csv", 150, 22, 0.01);
    let theta = |args: &[&str]| {
        let m = d.join("arx.json");
        let mut all = vec!["identify"];
        all.extend(args);
        all.extend(["-m", "arx", "--na", "2", "--nb", "2", "-o", s(&m)]);
        ok(&all);
        json(&std::fs::read_to_string(&m).unwrap())["modes"][0]["theta"].clone()
    };
    // One file holding `a`'s rows, then `b`'s (the time column dropped: it
    // would restart).
    let keep = |text: &str| -> Vec<String> {
        text.lines()
            .map(|l| {
                let cells: Vec<&str> = l.split(',').collect();
                cells[1..].join(",")
            })
            .collect()
    };
    let (rows_a, rows_b) = (
        keep(&std::fs::read_to_string(&a).unwrap()),
        keep(&std::fs::read_to_string(&b).unwrap()),
    );
    assert!(
        rows_a[0].contains('u') && rows_a[0] == rows_b[0],
        "{}",
        rows_a[0]
    );
    let mut text = rows_a.join("\n");
    for row in &rows_b[1..] {
        text.push('\n');
        text.push_str(row);
    }
    let joined = write(d, "joined.csv", text + "\n");
    let together = theta(&[s(&a), s(&b)]);
    let cut = theta(&[s(&joined), s(&joined), "--rows", "..150", "--rows", "150.."]);
    assert_eq!(together, cut);
    let across = theta(&[s(&joined)]);
    assert_ne!(together, across);
}

/// `--auto --select-records K` fits the candidates on the records before
/// the last K and scores them on those; the split is recorded in rows of
/// the joined records.
#[test]
fn auto_holds_out_whole_records() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let files: Vec<PathBuf> = (0..3)
        .map(|i| record(d, &format!("r{i}.csv"), 120, 31 + i, 0.01))
        .collect();
    let model = d.join("auto.json");
    let mut args = vec!["identify"];
    args.extend(files.iter().map(|f| s(f)));
    args.extend(["-m", "cluster", "--na", "1", "--nb", "1", "--auto"]);
    args.extend([
        "--select-records",
        "1",
        "--grid",
        "modes=1,2",
        "-o",
        s(&model),
    ]);
    ok(&args);
    let m = json(&std::fs::read_to_string(&model).unwrap());
    let split = &m["info"]["selection"]["splits"][0];
    assert_eq!(split["fit_rows"], "record 1 and record 2", "{split}");
    assert_eq!(split["select_rows"], "record 3", "{split}");
    assert_eq!(m["modes"].as_array().unwrap().len(), 2);
}

/// Records that cannot be joined, `--rows` counts that fit neither rule,
/// selection rows with several records, held-out records that leave no
/// record to fit and a record no longer than a physical model's initial
/// state: one line each, exit code 2, no model written.
#[test]
fn bad_combinations_of_records_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = record(d, "a.csv", 80, 41, 0.01);
    let b = record(d, "b.csv", 80, 42, 0.01);
    let slow = record(d, "slow.csv", 80, 43, 0.02);
    let out = d.join("never.json");
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec![s(&a), s(&slow)],
            format!(
                "{}: sampling time 0.02 s differs from record 1's 0.01 s",
                slow.display()
            ),
        ),
        (
            vec![s(&a), s(&b), s(&a), "--rows", "0..50", "--rows", "0..60"],
            "--rows: given 2 times for 3 data files".into(),
        ),
        (
            vec![s(&a), s(&b), "--auto", "--select-rows", "60.."],
            "--select-rows: not with several data files".into(),
        ),
        (
            vec![s(&a), s(&b), "--auto", "--select-records", "2"],
            "--select-records 2: must be between 1 and the number of records less one (1)".into(),
        ),
        (
            vec![s(&a), "--auto", "--select-records", "1"],
            "--select-records 1: holding out records needs two or more".into(),
        ),
    ];
    let physical = format!("model={}", common::HEAD_MODEL);
    let cases = cases.into_iter().chain([(
        vec![
            s(&a),
            s(&b),
            "--rows",
            "..60",
            "--rows",
            "..5",
            "-m",
            "physical",
            "--set",
            &physical,
        ],
        format!(
            "{} --rows ..5: 5 sample(s), no more than the warm-up of 10 that every free-run score leaves out",
            b.display()
        ),
    )]);
    // A record no score could read past the warm-up, with or without
    // --auto, named by its file and rows (--auto wrote a model whose
    // refit no start could score; without it the affine comparison was
    // left out without a word).
    let short = |rows: &'static str, extra: &[&'static str]| {
        let mut given = vec![s(&a), s(&b), "--rows", "..60", "--rows", rows];
        given.extend(extra);
        (
            given,
            format!(
                "{} --rows {rows}: {} sample(s), no more than the warm-up of 10",
                b.display(),
                rows.trim_start_matches(".."),
            ),
        )
    };
    let cases = cases.chain([
        short("..9", &["-m", "cluster", "--modes", "2", "--auto"]),
        short("..1", &["-m", "cluster", "--modes", "2"]),
        short("..10", &[]),
    ]);
    for (given, want) in cases {
        let mut args = vec!["identify"];
        args.extend(&given);
        if !given.contains(&"-m") {
            args.extend(["-m", "arx"]);
        }
        args.extend(["-o", s(&out)]);
        let o = hysid(&args);
        let line = one_line_error(&o, 2).unwrap_or_else(|e| panic!("{given:?}: {e}"));
        assert!(line.contains(&want), "{given:?}: {line}");
        assert!(!out.exists(), "{given:?} wrote a model");
    }
}

/// An experiment file with `[[data.records]]`: the identification rows of
/// the file and of one more record are fitted together, and the runs are
/// scored on the validation rows of the file and of a third record, as
/// `identify` and `validate` do with several files.
#[test]
fn an_experiment_joins_the_records_it_lists() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    record(d, "a.csv", 200, 51, 0.01);
    record(d, "b.csv", 120, 52, 0.01);
    record(d, "c.csv", 100, 53, 0.01);
    let experiment = write(
        d,
        "experiment.toml",
        r#"title = "records"
na = 1
nb = 1
[data]
file = "a.csv"
identification = "0..150"
validation = "150.."

[[data.records]]
file = "b.csv"
identification = ".."

[[data.records]]
file = "c.csv"
validation = ".."

[[run]]
name = "arx"
method = "arx"
"#,
    );
    let out = d.join("out");
    ok(&["compare", s(&experiment), "-o", s(&out)]);
    let report = json(&std::fs::read_to_string(out.join("report.json")).unwrap());
    let run = &report["results"][0];
    let model = out.join("models/arx.json");
    let (a, b, c) = (d.join("a.csv"), d.join("b.csv"), d.join("c.csv"));
    let alone = d.join("alone.json");
    ok(&[
        "identify",
        s(&a),
        s(&b),
        "--rows",
        "0..150",
        "--rows",
        "..",
        "-m",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "-o",
        s(&alone),
    ]);
    let theta = |p: &Path| json(&std::fs::read_to_string(p).unwrap())["modes"].clone();
    assert_eq!(theta(&model), theta(&alone));
    let scored = json(&ok(&[
        "validate",
        s(&model),
        s(&a),
        s(&c),
        "--rows",
        "150..",
        "--rows",
        "..",
        "--json",
    ]));
    assert_eq!(run["report"]["fit_sim"], scored["fit_sim"], "{run}");
    assert_eq!(run["report"]["records"].as_array().unwrap().len(), 2);
    let markdown = std::fs::read_to_string(out.join("report.md")).unwrap();
    let per_record = format!(
        "| arx | {:.2} | {:.2} |",
        scored["records"][0]["fit_sim"].as_f64().unwrap(),
        scored["records"][1]["fit_sim"].as_f64().unwrap()
    );
    assert!(markdown.contains(&per_record), "{markdown}");
    // The per-record columns are named by the scored records (b.csv fits
    // only).
    assert!(
        markdown.contains("| run | a.csv 150.. | c.csv .. |"),
        "{markdown}"
    );
    assert_eq!(
        report["scored_records"],
        serde_json::json!(["a.csv 150..", "c.csv .."])
    );
    let data = report["data"].as_str().unwrap();
    assert!(data.contains("b.csv (identification rows ..)"), "{data}");
    assert!(data.contains("c.csv (validation rows ..)"), "{data}");
    // A record sampled otherwise is refused in one line naming its file.
    let slow = record(d, "slow.csv", 100, 54, 0.02);
    let text = std::fs::read_to_string(&experiment).unwrap();
    let bad = write(d, "bad.toml", text.replace("\"c.csv\"", "\"slow.csv\""));
    let o = hysid(&["compare", s(&bad), "-o", s(&d.join("never"))]);
    let line = one_line_error(&o, 2).unwrap();
    let want = format!(
        "{}: sampling time 0.02 s differs from record 1's 0.01 s",
        slow.display()
    );
    assert!(line.contains(&want), "{line}");
}

/// An experiment may fit on some records and score on another alone: its
/// `[data]` file then gives only validation rows (or only identification
/// rows), and the scores are those of `validate` on that record.
#[test]
fn an_experiment_fits_on_some_records_and_scores_on_another() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    record(d, "a.csv", 200, 61, 0.01);
    record(d, "b.csv", 150, 62, 0.01);
    record(d, "c.csv", 120, 63, 0.01);
    let experiment = write(
        d,
        "experiment.toml",
        r#"title = "fit on a and b, score on c"
na = 1
nb = 1
[data]
file = "c.csv"
validation = ".."

[[data.records]]
file = "a.csv"
identification = ".."

[[data.records]]
file = "b.csv"
identification = ".."

[[run]]
name = "arx"
method = "arx"
"#,
    );
    let out = d.join("out");
    ok(&["compare", s(&experiment), "-o", s(&out)]);
    let report = json(&std::fs::read_to_string(out.join("report.json")).unwrap());
    let alone = d.join("alone.json");
    let (a, b, c) = (d.join("a.csv"), d.join("b.csv"), d.join("c.csv"));
    let fit = [
        "identify",
        s(&a),
        s(&b),
        "-m",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
    ];
    ok(&[&fit[..], &["-o", s(&alone)]].concat());
    let theta = |p: &Path| json(&std::fs::read_to_string(p).unwrap())["modes"].clone();
    assert_eq!(theta(&out.join("models/arx.json")), theta(&alone));
    let scored = json(&ok(&["validate", s(&alone), s(&c), "--json"]));
    assert_eq!(report["results"][0]["report"]["fit_sim"], scored["fit_sim"]);
    let data = report["data"].as_str().unwrap();
    assert!(
        data.starts_with(&format!("{} (decimate 1, validation rows ..)", c.display())),
        "{data}"
    );
    // An auto run on the rows of one record counts its selection rows in
    // that record's file, as `identify --rows` does.
    let one = write(
        d,
        "one.toml",
        "title = \"x\"\nna = 1\nnb = 1\n[data]\nfile = \"c.csv\"\nvalidation = \"..\"\n\
             [[data.records]]\nfile = \"a.csv\"\nidentification = \"50..\"\n\
             [[run]]\nname = \"auto\"\nmethod = \"arx\"\nauto = true\n",
    );
    let out = d.join("one");
    ok(&["compare", s(&one), "-o", s(&out)]);
    let auto = d.join("auto.json");
    let fit = [
        "identify",
        s(&a),
        "--rows",
        "50..",
        "-m",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
    ];
    ok(&[&fit[..], &["--auto", "-o", s(&auto)]].concat());
    let splits = |p: &Path| {
        json(&std::fs::read_to_string(p).unwrap())["info"]["selection"]["splits"].clone()
    };
    assert_eq!(splits(&out.join("models/auto.json")), splits(&auto));
    // Without a part anywhere, the file is refused naming it.
    for (text, needle) in [
        (
            "validation = \"..\"\n",
            "no validation rows: give them in [data] or in a [[data.records]] entry",
        ),
        (
            "[[data.records]]",
            "[data]: give identification rows (or list [[data.records]] that have them)",
        ),
    ] {
        let source = std::fs::read_to_string(&experiment).unwrap();
        let cut = match source.find(text) {
            Some(at) if text.starts_with("[[") => {
                source[..at].to_string() + "[[run]]\nname = \"arx\"\nmethod = \"arx\"\n"
            }
            _ => source.replacen(text, "", 1),
        };
        let bad = write(d, "bad.toml", cut);
        let line = one_line_error(&hysid(&["compare", s(&bad), "-o", s(&d.join("never"))]), 2);
        assert!(line.as_ref().unwrap().contains(needle), "{line:?}");
    }
    // A [data] file with neither part would be read for nothing.
    let source = std::fs::read_to_string(&experiment).unwrap();
    let neither = source.replacen("validation = \"..\"\n", "", 1).replacen(
        "identification = \"..\"\n\n[[run]]",
        "validation = \"..\"\n\n[[run]]",
        1,
    );
    let bad = write(d, "bad.toml", neither);
    let line = one_line_error(&hysid(&["compare", s(&bad), "-o", s(&d.join("never"))]), 2);
    assert!(
        line.unwrap()
            .contains("[data]: give identification or validation rows")
    );
}

/// Records of one file under other signals: every entry of the report says
/// which signals it reads, `[data]`'s too.
#[test]
fn records_of_other_signals_of_one_file_are_named_by_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (a, b) = (
        record(d, "a.csv", 150, 71, 0.01),
        record(d, "b.csv", 150, 72, 0.01),
    );
    let (a, b) = (
        std::fs::read_to_string(a).unwrap(),
        std::fs::read_to_string(b).unwrap(),
    );
    // The columns of a beside those of b but its time, renamed u2, y2, ....
    let joined: Vec<String> = (a.lines().zip(b.lines()).enumerate())
        .map(|(i, (x, y))| {
            let rest: Vec<String> = (y.split(',').skip(1))
                .map(|v| {
                    if i == 0 {
                        format!("{v}2")
                    } else {
                        v.to_string()
                    }
                })
                .collect();
            format!("{x},{}", rest.join(","))
        })
        .collect();
    write(d, "both.csv", joined.join("\n") + "\n");
    let experiment = write(
        d,
        "experiment.toml",
        "title = \"x\"\nna = 1\nnb = 1\n[data]\nfile = \"both.csv\"\nidentification = \"0..100\"\n\
         validation = \"100..\"\n[[data.records]]\nfile = \"both.csv\"\ninput = [\"u2\"]\n\
         output = \"y2\"\nvalidation = \"100..\"\n[[run]]\nname = \"arx\"\nmethod = \"arx\"\n",
    );
    let out = d.join("out");
    ok(&["compare", s(&experiment), "-o", s(&out)]);
    let markdown = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        markdown.contains("(u -> y, decimate 1, identification rows 0..100"),
        "{markdown}"
    );
    assert!(
        markdown.contains("both.csv (u2 -> y2, validation rows 100..)"),
        "{markdown}"
    );
    assert!(
        markdown.contains("| run | both.csv 100.. (u -> y) | both.csv 100.. (u2 -> y2) |"),
        "{markdown}"
    );
}

/// `sweep` on several records is the experiment that lists them as
/// `[[data.records]]`: the same points, the same pooled and per-record
/// scores; its row flags are given once for all or once per file, and
/// rows that overlap are refused naming the record.
#[test]
fn a_sweep_on_several_records_is_their_experiment() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (a, b) = (
        record(d, "a.csv", 200, 61, 0.01),
        record(d, "b.csv", 160, 62, 0.01),
    );
    let experiment = write(
        d,
        "experiment.toml",
        r#"title = "records"
na = 1
nb = 1
seed = 3
[data]
file = "a.csv"
identification = "0..150"
validation = "150.."

[[data.records]]
file = "b.csv"
identification = "0..100"
validation = "100.."

[priors]
modes = 2

[[sweep]]
name = "cluster"
method = "cluster"
vary = "c"
values = [8, 16]
"#,
    );
    let out = d.join("out");
    ok(&["compare", s(&experiment), "-o", s(&out)]);
    let listed = json(&std::fs::read_to_string(out.join("report.json")).unwrap());
    let swept = d.join("swept");
    let sweep = |more: &[&str]| {
        let mut args = vec![
            "sweep",
            s(&a),
            s(&b),
            "-m",
            "cluster",
            "--grid",
            "c=8,16",
            "--modes",
            "2",
            "--na",
            "1",
            "--nb",
            "1",
            "--seed",
            "3",
        ];
        args.extend_from_slice(more);
        hysid(&args)
    };
    let o = sweep(&[
        "--identify-rows",
        "0..150",
        "--identify-rows",
        "0..100",
        "--select-rows",
        "150..",
        "--select-rows",
        "100..",
        "-o",
        s(&swept),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = json(&std::fs::read_to_string(swept.join("report.json")).unwrap());
    let points = |r: &serde_json::Value| -> Vec<(serde_json::Value, serde_json::Value)> {
        let results = r["results"].as_array().unwrap();
        (results.iter())
            .map(|p| {
                (
                    p["report"]["fit_sim"].clone(),
                    p["report"]["records"].clone(),
                )
            })
            .collect()
    };
    let scored = points(&report);
    assert_eq!(scored.len(), 2);
    assert!(
        (scored.iter())
            .all(|(fit, records)| fit.is_f64() && records.as_array().unwrap().len() == 2),
        "{scored:?}"
    );
    assert_eq!(scored, points(&listed));
    assert_eq!(report["scored_records"], listed["scored_records"]);
    // Once for every file: the same rows of each.
    let o = sweep(&["--identify-rows", "0..100", "--select-rows", "100..160"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("| run | a.csv 100..160 | b.csv 100..160 |"),
        "{text}"
    );
    // Selection rows after identification rows 0..100 of each: refused in
    // one line.
    let refused = |select: &[&str]| {
        let mut args = vec!["--identify-rows", "0..100"];
        for rows in select {
            args.extend(["--select-rows", rows]);
        }
        one_line_error(&sweep(&args), 2).unwrap()
    };
    let line = refused(&["100..", "100..", "100.."]);
    assert!(
        line.contains("--select-rows: given 3 times for 2 data files"),
        "{line}"
    );
    let line = refused(&["100..", "90.."]);
    let want = format!(
        "--select-rows 90.. overlap --identify-rows 0..100 of {}",
        b.display()
    );
    assert!(line.contains(&want), "{line}");
}
