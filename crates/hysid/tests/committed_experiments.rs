//! The committed experiments still load and expand into the runs the
//! reports were made from, so a schema change cannot silently break the
//! README's main job or the saturation experiments (nothing is run here);
//! every fixed-option run says where its options come from.

use hysid::compare::{Experiment, Origin};
use std::path::{Path, PathBuf};

fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/pick-and-place")
}

/// Loads `file`, checks its data file exists, and returns the job names.
fn jobs(file: &str) -> Vec<(String, String, Option<String>)> {
    let path = models().join(file);
    let e = Experiment::load(&path).unwrap_or_else(|err| panic!("{file}: {err}"));
    assert!(
        e.data.file.is_file(),
        "{file}: data file {} missing",
        e.data.file.display()
    );
    e.jobs()
        .unwrap_or_else(|err| panic!("{file}: {err}"))
        .into_iter()
        .map(|j| (j.name, j.method, j.sweep.map(|s| s.sweep)))
        .collect()
}

#[test]
fn the_main_job_expands_into_its_runs_and_sweep_points() {
    let j = jobs("experiment.toml");
    let runs = j.iter().filter(|(_, _, s)| s.is_none()).count();
    let mut sweeps: Vec<&str> = j.iter().filter_map(|(_, _, s)| s.as_deref()).collect();
    sweeps.dedup();
    assert_eq!((j.len(), runs), (79, 45), "{j:?}");
    assert_eq!(sweeps, ["arx orders", "cluster c", "bounded delta"]);
    for m in [
        "arx", "cluster", "bounded", "physical", "klinreg", "parc", "bayes",
    ] {
        assert!(j.iter().any(|(_, method, _)| method == m), "no {m} run");
    }
    assert!(j.iter().any(|(n, _, _)| n == "cluster c [c=320, modes=5]"));
}

/// The main job opens with the honest comparison: every back-end's
/// options chosen on the selection rows (five seeds for the seeded ones),
/// then the physical model; the paper's section 4 settings and the oracle
/// ones follow.
#[test]
fn the_main_job_opens_with_the_runs_chosen_on_selection_rows() {
    let e = Experiment::load(&models().join("experiment.toml")).unwrap();
    let jobs = e.jobs().unwrap();
    let first_fixed = jobs
        .iter()
        .position(|j| j.origin != Origin::SelectionRows)
        .unwrap();
    let chosen = &jobs[..first_fixed];
    for m in ["arx", "cluster", "bounded", "klinreg", "parc", "bayes"] {
        let seeds = chosen.iter().filter(|j| j.method == m).count();
        assert!(seeds >= if m == "arx" { 1 } else { 5 }, "{m}: {seeds}");
    }
    assert_eq!(jobs[first_fixed].method, "physical");
    let origin = |name: &str| jobs.iter().find(|j| j.name == name).unwrap().origin;
    assert_eq!(origin("cluster(5 modes, c=320)"), Origin::Oracle);
    assert_eq!(origin("cluster(3 modes, c=35)"), Origin::Paper);
}

/// Every experiment file under `models/` declares the provenance of each
/// run whose options are fixed (a run without `auto`).
#[test]
fn every_fixed_option_run_declares_its_provenance() {
    let mut files = Vec::new();
    let mut folders = vec![models().join("..")];
    while let Some(dir) = folders.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|e| e == "toml") {
                let text = std::fs::read_to_string(&path).unwrap();
                let table: toml::Table = text.parse().unwrap();
                if table.contains_key("run") || table.contains_key("sweep") {
                    files.push(path);
                }
            }
        }
    }
    assert!(files.len() >= 5, "{files:?}");
    let mut missing = Vec::new();
    let mut physical = 0;
    for f in &files {
        let e = Experiment::load(f).unwrap_or_else(|err| panic!("{}: {err}", f.display()));
        for r in e.runs.iter().filter(|r| !r.auto && r.provenance.is_none()) {
            missing.push(format!("{}: [[run]] '{}'", f.display(), r.name));
        }
        // physical fits the model file it names, resolved against the
        // experiment's folder.
        for r in e.runs.iter().filter(|r| r.method == "physical") {
            physical += 1;
            let model = r.set.get("model").and_then(|v| v.as_str()).unwrap_or("");
            assert!(
                Path::new(model).is_file(),
                "{}: '{}' names no model file ({model:?})",
                f.display(),
                r.name
            );
        }
    }
    assert!(physical >= 3, "{physical} physical runs");
    assert!(
        missing.is_empty(),
        "runs without provenance:\n{}",
        missing.join("\n")
    );
}

#[test]
fn the_saturation_experiments_expand_and_know_both_stops() {
    for file in ["simulated/both.toml", "simulated/lower.toml"] {
        let j = jobs(file);
        assert!(j.len() > 6, "{file}: {j:?}");
        assert!(
            j.iter()
                .any(|(n, _, s)| s.is_none() && n.contains("saturation priors")),
            "{file}: no run with the stop priors"
        );
    }
    let e = Experiment::load(&models().join("simulated/both.toml")).unwrap();
    let with_priors = e
        .jobs()
        .unwrap()
        .into_iter()
        .find(|j| j.name == "cluster(4 modes, c=40), saturation priors")
        .expect("the section-5 run");
    let levels: Vec<f64> = with_priors
        .priors
        .saturation
        .iter()
        .map(|s| s.level)
        .collect();
    assert_eq!(levels, [0.0, 25.0]);
    assert_eq!(with_priors.priors.modes, Some(4));
}

/// The ties experiment: a run's own `[[equality]]` and `[[tie]]` reach its
/// job (and only its job), the runs without priors get none.
#[test]
fn the_ties_experiment_gives_each_run_its_own_priors() {
    let e = Experiment::load(&models().join("ties.toml")).unwrap();
    let jobs = e.jobs().unwrap();
    assert!(jobs.len() >= 16, "{}", jobs.len());
    for j in &jobs {
        let p = &j.priors;
        assert_eq!(
            p.equality.len(),
            usize::from(j.name.contains("equality")),
            "{}",
            j.name
        );
        assert_eq!(!p.tie.is_empty(), j.name.contains("tie"), "{}", j.name);
        if j.name.contains("equality") {
            let c = &p.equality[0].coefficients;
            assert_eq!((c["b1"], c["b2"]), (1.0, -1.0), "{}", j.name);
        }
    }
    for m in ["arx", "cluster", "bounded"] {
        assert!(
            jobs.iter()
                .any(|j| j.method == m && j.name.contains("equality")),
            "no {m} equality run"
        );
    }
}
