//! The committed experiments still load and expand into the runs the
//! reports were made from, so a schema change cannot silently break the
//! README's main job or the saturation experiments (nothing is run here).

use hysid::compare::Experiment;
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
    assert_eq!((j.len(), runs), (49, 15), "{j:?}");
    assert_eq!(sweeps, ["arx orders", "cluster c", "bounded delta"]);
    for m in [
        "arx", "cluster", "bounded", "physical", "klinreg", "parc", "bayes",
    ] {
        assert!(j.iter().any(|(_, method, _)| method == m), "no {m} run");
    }
    assert!(j.iter().any(|(n, _, _)| n == "cluster c [c=320, modes=5]"));
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
