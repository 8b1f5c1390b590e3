//! Every command shown in `README.md` and `docs/*.md` (lines of fenced code
//! blocks that start with `hysid`, `cargo` or `target/release/`):
//!
//! - a `hysid` command names a subcommand that exists and only flags that
//!   subcommand accepts (its `--help`), placeholders (`DATA`, `[..]`)
//!   included: a renamed or misspelt flag in the docs fails here;
//! - a `cargo` command names packages, examples and benches that exist;
//! - the commands listed in [`RUN`] are run as written (outputs into a
//!   temporary folder) and what their text quotes is checked; every other
//!   concrete command (one without placeholders such as `DATA`, `[..]`,
//!   `...`) is listed in [`NOT_RUN`] with the reason, so a new command in
//!   the docs must be classified.

use crate::common;

use common::{hysid, s};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A command of a documentation file, continuation lines joined, the
/// trailing comment cut off.
struct Shown {
    file: String,
    line: usize,
    text: String,
}

fn shown_commands() -> Vec<Shown> {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    let mut out = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        let mut fenced = false;
        let mut i = 0;
        while i < lines.len() {
            let l = lines[i].trim();
            if l.starts_with("```") {
                fenced = !fenced;
            } else if fenced
                && ["hysid ", "cargo ", "target/release/"]
                    .iter()
                    .any(|p| l.starts_with(p))
            {
                let start = i + 1;
                let mut cmd = l.to_string();
                while cmd.ends_with('\\') && i + 1 < lines.len() {
                    i += 1;
                    cmd.pop();
                    cmd.push(' ');
                    cmd.push_str(lines[i].trim());
                }
                let cmd = cmd.split(" # ").next().unwrap();
                let cmd = cmd.split_whitespace().collect::<Vec<_>>().join(" ");
                out.push(Shown {
                    file: name.clone(),
                    line: start,
                    text: cmd,
                });
            }
            i += 1;
        }
    }
    out
}

/// The long flags `hysid SUB --help` lists.
fn flags_of(sub: &str) -> BTreeSet<String> {
    let o = hysid(&[sub, "--help"]);
    assert!(o.status.success(), "hysid {sub} --help");
    String::from_utf8_lossy(&o.stdout)
        .split_whitespace()
        .filter_map(|w| w.strip_prefix("--"))
        .map(|w| {
            w.trim_end_matches([',', '.', ')', ']'])
                .split(['=', '<', '['])
                .next()
                .unwrap()
                .to_string()
        })
        .filter(|w| !w.is_empty())
        .collect()
}

#[test]
fn every_hysid_command_shown_uses_existing_subcommands_and_flags() {
    let subs = [
        "methods", "identify", "validate", "simulate", "compare", "sweep", "convert", "show",
    ];
    let mut wrong = Vec::new();
    let mut checked = 0;
    for c in shown_commands() {
        let Some(rest) = c.text.strip_prefix("hysid ") else {
            continue;
        };
        let sub = rest.split_whitespace().next().unwrap_or("");
        if !subs.contains(&sub) {
            wrong.push(format!(
                "{}:{}: no subcommand '{sub}': {}",
                c.file, c.line, c.text
            ));
            continue;
        }
        // Without an elision (`...`, `[..]`), the required arguments are there.
        let words: Vec<&str> = rest.split_whitespace().collect();
        let elided = rest.contains("...") || rest.contains('[');
        let needs: &[(&str, &str)] = match sub {
            "identify" => &[("-m", "--method"), ("-o", "--out")],
            "simulate" => &[("-o", "--out")],
            "sweep" => &[("-m", "--method"), ("--grid", "--grid")],
            _ => &[],
        };
        for (short, long) in needs {
            if !elided
                && !words
                    .iter()
                    .any(|w| w == short || w == long || w.starts_with(&format!("{long}=")))
            {
                wrong.push(format!(
                    "{}:{}: hysid {sub} without {long}: {}",
                    c.file, c.line, c.text
                ));
            }
        }
        let flags = flags_of(sub);
        for w in rest.split_whitespace() {
            let w = w.trim_start_matches(['[', '(']);
            if let Some(flag) = w.strip_prefix("--") {
                let flag = flag
                    .trim_end_matches([']', ')', '.'])
                    .split('=')
                    .next()
                    .unwrap();
                if !flags.contains(flag) {
                    wrong.push(format!(
                        "{}:{}: hysid {sub} has no --{flag}: {}",
                        c.file, c.line, c.text
                    ));
                }
            }
        }
        checked += 1;
    }
    assert!(checked > 30, "only {checked} commands found");
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn every_cargo_command_shown_names_what_exists() {
    let mut wrong = Vec::new();
    for c in shown_commands() {
        if !c.text.starts_with("cargo ") {
            continue;
        }
        let words: Vec<&str> = c.text.split_whitespace().collect();
        let after = |flag: &str| {
            words
                .iter()
                .position(|w| *w == flag)
                .and_then(|i| words.get(i + 1))
                .copied()
        };
        let Some(package) = after("-p") else {
            continue;
        };
        let dir = root().join("crates").join(package);
        if !dir.join("Cargo.toml").exists() {
            wrong.push(format!("{}:{}: no package {package}", c.file, c.line));
            continue;
        }
        for (flag, folder) in [("--example", "examples"), ("--bench", "benches")] {
            if let Some(name) = after(flag).filter(|n| !n.starts_with('-'))
                && !dir.join(folder).join(format!("{name}.rs")).exists()
            {
                wrong.push(format!(
                    "{}:{}: {package} has no {flag} {name}",
                    c.file, c.line
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// What a command run as shown must give.
enum Quote {
    /// Texts its standard output contains.
    Stdout(&'static [&'static str]),
    /// Texts its standard error contains.
    Stderr(&'static [&'static str]),
    /// Samples per mode in the `mode` column of the CSV it writes.
    ModeCounts(&'static [(&'static str, usize)]),
}

/// Commands run as the docs show them, with what the text quotes of their
/// output. Repository paths are read from the repository; the file after
/// `-o` goes to a temporary folder.
const RUN: &[(&str, &str, Quote)] = &[
    (
        "gray-box-models.md",
        "hysid simulate models/examples/ball-on-table.toml --excite n=1001,hold=50,low=-40,high=40,ts=0.01 --seed 1 -o ball.csv",
        Quote::ModeCounts(&[("fly", 891), ("carried", 110)]),
    ),
    (
        "README.md",
        "hysid methods cluster",
        Quote::Stdout(&["Ferrari-Trecate", "restarts (int, default 15)", "regions"]),
    ),
    (
        "physical.md",
        "hysid validate head-fitted.json models/pick-and-place/headdata_1v6.mat --decimate 10 --rows 5000..6001 --warmup 10 --json",
        Quote::Stdout(&[
            "\"fit_sim\":93.447",
            "\"rmse_sim\":0.3423",
            "\"fit_pred\":99.81",
            "\"mode_counts\":[0,287,242,0,462]",
        ]),
    ),
    (
        "physical.md",
        "hysid simulate models/pick-and-place/head.toml --excite n=2000,hold=120,low=-0.2,high=0.0,ts=0.0025 --seed 3 -o sim.csv",
        Quote::ModeCounts(&[
            ("free", 595),
            ("impact", 466),
            ("lower_saturation", 195),
            ("stick", 735),
        ]),
    ),
    (
        "physical.md",
        "hysid simulate models/pick-and-place/head.toml --excite n=4000,hold=120,low=-0.2,high=0.1,ts=0.0025 --seed 3 --noise 0.005 -o both-saturations.csv",
        Quote::ModeCounts(&[
            ("free", 813),
            ("impact", 730),
            ("lower_saturation", 207),
            ("upper_saturation", 1194),
            ("stick", 1047),
        ]),
    ),
    (
        "performance-physical.md",
        "hysid convert models/pick-and-place/head.toml -o head-gray.toml",
        Quote::Stderr(&["the gray-box form of"]),
    ),
    (
        "cluster.md",
        "hysid identify models/pick-and-place/headdata_1v6.mat -m cluster --modes 20 --set discard=0 --decimate 10 --rows 0..3000 --time-budget 3 -o m.json",
        Quote::Stderr(&["time budget reached during the mrlp region estimation"]),
    ),
];

/// Concrete commands the docs show that this test does not run, by prefix,
/// with the reason.
const NOT_RUN: &[(&str, &str)] = &[
    (
        "hysid identify models/pick-and-place/headdata_1v6.mat --decimate 10 --rows 0..5000 -m physical --set model=MODEL --seed S",
        "twelve timed fits in release (two models, three seeds, two rounds); their figures are the table beside them",
    ),
    (
        "hysid identify models/pick-and-place/headdata_1v6.mat --decimate 10 --rows 0..5000 -m physical --set model=models/pick-and-place/head.toml --seed 1 --set restarts=0",
        "one of five timed fits in release; its figures are the table beside it",
    ),
    (
        "cargo run --release -p hysid-physical --example structure_study",
        "24 fits of the real record, about 17 minutes; its figures are the table beside it",
    ),
    (
        "hysid identify models/pick-and-place/headdata_1v6.mat -m physical --decimate 10 --rows 0..5000 --seed 1 --set model=models/pick-and-place/head-graybox.toml",
        "a 14-s fit in release; its figure is the table beside it, the same as the mechanical head's",
    ),
    (
        "cargo test --workspace",
        "the test command: this test is part of it",
    ),
    (
        "cargo run --release -p hysid-cli -- compare",
        "the main job (2 to 5 minutes in release on 2 cores); its figures are the committed report it regenerates, which the README's results table is checked against",
    ),
    (
        "hysid compare models/pick-and-place/",
        "an experiment of 3-100 s in release; its figures are the committed report under docs/pick-and-place",
    ),
    (
        "hysid simulate m.json",
        "m.json is the model identified from the user's DATA on the line above",
    ),
    (
        "hysid sweep models/pick-and-place/headdata_1v6.mat",
        "nine cluster fits on 4000 rows: seconds in release, minutes in a debug build",
    ),
    (
        "hysid identify models/pick-and-place/headdata_1v6.mat -m physical",
        "a physical fit (2 s in release, over a minute in debug); its output is the committed head-fitted.json, validated in RUN",
    ),
    (
        "hysid identify models/pick-and-place/headdata_1v6.mat -m cluster --na 2 --nb 2 --decimate 10 --rows 0..5000 --auto",
        "an automatic selection with the alternation and refined candidates (12-25 s in release, minutes in debug); its test figure is the seed-1 row of the committed auto report",
    ),
    (
        "hysid validate m.json models/pick-and-place/headdata_1v6.mat",
        "m.json is the model of the --auto command above it",
    ),
    (
        "hysid identify ident.csv",
        "ident.csv and valid.csv are files the reader makes from a simulated record, as the text describes",
    ),
    ("hysid validate head.json valid.csv", "see ident.csv"),
    ("hysid validate plain.json valid.csv", "see ident.csv"),
    (
        "hysid identify data.csv",
        "data.csv stands for the reader's record",
    ),
    (
        "cargo run --release -p hysid-bounded --example",
        "an example of minutes; its existence is checked above",
    ),
    (
        "cargo run --release -p hysid-cluster --example",
        "an example of minutes; its existence is checked above",
    ),
    (
        "cargo run -p hysid --example plot_pick_and_place",
        "regenerates two figures of the gallery; its existence is checked above",
    ),
    (
        "cargo run -p hysid-plot --example gallery",
        "regenerates the figure gallery; its existence is checked above",
    ),
    (
        "target/release/examples/",
        "an example binary that the `cargo build --release` line above it builds; seconds to minutes",
    ),
    ("cargo bench", "a benchmark build"),
    ("cargo build --release", "a release build for a benchmark"),
    ("cargo install cargo-fuzz", "installs a tool"),
    (
        "cargo install --path crates/hysid-cli",
        "installs the program (a release build)",
    ),
    (
        "hysid identify rec.csv",
        "rec.csv stands for the reader's record; cli::your_own_record_identified_validated_and_plotted runs the same commands on a simulated one",
    ),
    ("hysid validate m.json rec.csv", "see rec.csv"),
    (
        "hysid identify DATA_EMPS.mat",
        "the EMPS benchmark's estimation record, published at nonlinearbenchmark.org and not in the repository",
    ),
    (
        "hysid validate emps.json DATA_EMPS",
        "the EMPS benchmark's records, not in the repository",
    ),
    (
        "hysid identify dataBenchmark.mat",
        "the Cascaded Tanks benchmark's record, published at nonlinearbenchmark.org and not in the repository",
    ),
    (
        "hysid validate tanks.json dataBenchmark.mat",
        "the Cascaded Tanks benchmark's record, not in the repository",
    ),
];

/// Whether `command` holds a placeholder (`DATA`, `OUT_DIR`, `[..]`, `...`,
/// `<hash>`): a synopsis, not a command to run.
fn is_synopsis(command: &str) -> bool {
    command.contains('[')
        || command.contains("...")
        || command.contains('<')
        || command.split_whitespace().any(|w| {
            w.len() >= 3
                && w.chars()
                    .all(|c| c.is_ascii_uppercase() || c == '_' || c == '.')
        })
}

#[test]
fn every_concrete_command_shown_is_run_or_has_a_reason() {
    let mut unclassified = Vec::new();
    for c in shown_commands() {
        let runs = RUN.iter().any(|(_, command, _)| *command == c.text);
        let reason = NOT_RUN.iter().any(|(prefix, _)| c.text.starts_with(prefix));
        if !is_synopsis(&c.text) && !runs && !reason {
            unclassified.push(format!("{}:{}: {}", c.file, c.line, c.text));
        }
    }
    assert!(
        unclassified.is_empty(),
        "run these in RUN or give the reason in NOT_RUN:\n{}",
        unclassified.join("\n")
    );
}

#[test]
fn commands_run_as_shown_give_what_the_text_quotes() {
    let shown: Vec<String> = shown_commands().into_iter().map(|c| c.text).collect();
    let dir = tempfile::tempdir().unwrap();
    for (file, command, quote) in RUN {
        assert!(
            shown.iter().any(|c| c == command),
            "{file} no longer shows: {command}"
        );
        let words: Vec<&str> = command.split_whitespace().skip(1).collect();
        let mut written = None;
        let args: Vec<String> = words
            .iter()
            .enumerate()
            .map(|(i, w)| {
                if i > 0 && words[i - 1] == "-o" {
                    let p = dir.path().join(w);
                    written = Some(p.clone());
                    s(&p).to_string()
                } else if *w == "head-fitted.json" || w.starts_with("models/") {
                    let p = if w.starts_with("models/") {
                        root().join(w)
                    } else {
                        root().join("models/pick-and-place").join(w)
                    };
                    s(&p).to_string()
                } else {
                    w.to_string()
                }
            })
            .collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = hysid(&args);
        let (out, err) = (
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr),
        );
        assert!(o.status.success(), "{command}: {err}");
        match quote {
            Quote::Stdout(texts) | Quote::Stderr(texts) => {
                let stream = if matches!(quote, Quote::Stdout(_)) {
                    &out
                } else {
                    &err
                };
                for t in *texts {
                    assert!(stream.contains(t), "{file}: {command}: lacks {t}: {stream}");
                }
            }
            Quote::ModeCounts(counts) => {
                let csv = std::fs::read_to_string(written.as_ref().unwrap()).unwrap();
                for (mode, n) in *counts {
                    let found = csv
                        .lines()
                        .filter(|l| l.ends_with(&format!(",{mode}")))
                        .count();
                    assert_eq!(found, *n, "{file}: {command}: samples in mode {mode}");
                }
            }
        }
    }
}

/// The README is a newcomer's page: at most 120 lines.
#[test]
fn the_readme_stays_short() {
    let lines = std::fs::read_to_string(root().join("README.md"))
        .unwrap()
        .lines()
        .count();
    assert!(lines <= 120, "README.md has {lines} lines");
}

/// Every recommendation of docs/choosing.md (a row of its table) links a
/// section of docs/results.md that exists.
#[test]
fn every_choice_links_a_measured_figure() {
    let slug = |heading: &str| -> String {
        heading
            .trim()
            .to_lowercase()
            .chars()
            .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-')
            .map(|c| if c == ' ' { '-' } else { c })
            .collect()
    };
    let results = std::fs::read_to_string(root().join("docs/results.md")).unwrap();
    let anchors: BTreeSet<String> = results
        .lines()
        .filter_map(|l| l.strip_prefix("## "))
        .map(slug)
        .collect();
    let choosing = std::fs::read_to_string(root().join("docs/choosing.md")).unwrap();
    let rows: Vec<&str> = choosing
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| you know"))
        .collect();
    assert!(rows.len() >= 5, "{rows:?}");
    for row in rows {
        let links: Vec<&str> = row
            .split("(results.md#")
            .skip(1)
            .map(|rest| rest.split(')').next().unwrap())
            .collect();
        assert!(!links.is_empty(), "no figure linked: {row}");
        for a in links {
            assert!(
                anchors.contains(a),
                "results.md has no section #{a}: {anchors:?}"
            );
        }
    }
}
