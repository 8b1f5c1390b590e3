//! The structure study of the pick-and-place head: candidate gray-box
//! structures, each fitted with the `physical` back-end on rows 0..4000
//! (decimated by 10) and scored by free-run FIT on the selection rows
//! 4000..5000 (warm-up 10), seeds 1-3; the candidate of best median
//! selection score is refitted on rows 0..5000 and only it is scored on the
//! test rows 5000..6001.
//!
//! `cargo run --release -p hysid-physical --example structure_study [-- [--selection-only] CANDIDATE.. KEY=VALUE..]`
//!
//! Candidates are files under `models/pick-and-place/` (default: the base
//! head and every file of `structures/`); arguments of the form
//! `KEY=VALUE` are `physical` options given to every fit (for example
//! `swarms=3`). Prints, per candidate and seed,
//! the selection FIT and the fitted parameters with their standard errors,
//! then the choice and its test FIT (median and range over the seeds).
//! `--selection-only` stops after the selection scores, without the test
//! rows: a new candidate is scored that way against the table of
//! docs/physical.md, and the test rows are not looked at.

use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_model::data::{DataSelection, Dataset, RowRange};
use hysid_model::regressors::RegressorSpec;
use hysid_model::statistics::upper_median;
use hysid_physical::Physical;
use std::path::{Path, PathBuf};

const SEEDS: [u64; 3] = [1, 2, 3];

fn rows(root: &Path, start: usize, end: usize) -> Dataset {
    let sel = DataSelection {
        decimate: 10,
        rows: RowRange {
            start: Some(start),
            end: Some(end),
        },
        ..DataSelection::default()
    };
    hysid_io::load(&root.join("headdata_1v6.mat"), &sel).expect("the embedded record")
}

fn fit(file: &Path, options: &[String], data: &Dataset, seed: u64) -> Model {
    let priors = Priors::default();
    let problem = Problem {
        data,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &priors,
        priors_origin: None,
    };
    let set = format!("model={}", file.display());
    let settings: Vec<&str> = std::iter::once(set.as_str())
        .chain(options.iter().map(String::as_str))
        .collect();
    Physical
        .run(
            &problem,
            &Settings::parse(&settings).expect("physical options"),
            &RunContext::quiet(seed),
        )
        .unwrap_or_else(|e| panic!("{}: {e}", file.display()))
}

fn fit_sim(model: &Model, data: &Dataset) -> f64 {
    hysid_core::simulate::validate(model, data, 10)
        .expect("the record suits the model")
        .0
        .fit_sim
}

/// `name = value ± standard error` of every free parameter.
fn parameters(model: &Model) -> String {
    let Some(params) = model.info().diagnostics.method.get("parameters") else {
        return String::new();
    };
    let Some(map) = params.as_object() else {
        return String::new();
    };
    map.iter()
        .map(|(name, p)| {
            format!(
                "{name} = {:.4} ± {:.2e}",
                p["value"].as_f64().unwrap_or(f64::NAN),
                p["std_error"].as_f64().unwrap_or(f64::NAN)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The base head, then every `.toml` file of `structures/` in name order.
fn default_candidates(root: &Path) -> Vec<String> {
    let mut files: Vec<String> = std::fs::read_dir(root.join("structures"))
        .expect("models/pick-and-place/structures")
        .filter_map(|e| {
            let name = e.ok()?.file_name().into_string().ok()?;
            name.ends_with(".toml")
                .then(|| format!("structures/{name}"))
        })
        .collect();
    files.sort();
    std::iter::once("head-graybox.toml".to_string())
        .chain(files)
        .collect()
}

fn main() {
    let root = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/pick-and-place"
    ));
    let (flags, args): (Vec<String>, Vec<String>) =
        std::env::args().skip(1).partition(|a| a.starts_with("--"));
    let selection_only = match flags.as_slice() {
        [] => false,
        [f] if f == "--selection-only" => true,
        _ => panic!("unknown flags {flags:?}: the only flag is --selection-only"),
    };
    let (options, args): (Vec<String>, Vec<String>) =
        args.into_iter().partition(|a| a.contains('='));
    let candidates: Vec<String> = if args.is_empty() {
        default_candidates(&root)
    } else {
        args
    };
    let (fit_rows, selection, ident, test) = (
        rows(&root, 0, 4000),
        rows(&root, 4000, 5000),
        rows(&root, 0, 5000),
        rows(&root, 5000, 6001),
    );
    let mut scores = Vec::new();
    for c in &candidates {
        let file = root.join(c);
        let mut sel = Vec::new();
        for seed in SEEDS {
            let m = fit(&file, &options, &fit_rows, seed);
            let s = fit_sim(&m, &selection);
            println!(
                "{c} seed {seed}: selection FIT {s:.3} %; {}",
                parameters(&m)
            );
            sel.push(s);
        }
        let median = upper_median(&mut sel).unwrap_or(f64::NAN);
        println!("{c}: median selection FIT {median:.3} %");
        scores.push((median, c.clone()));
    }
    let (best, choice) = scores
        .iter()
        .cloned()
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .expect("at least one candidate");
    println!("chosen on the selection rows: {choice} ({best:.3} %)");
    if selection_only {
        return;
    }
    let file = root.join(&choice);
    let mut tests = Vec::new();
    for seed in SEEDS {
        let m = fit(&file, &options, &ident, seed);
        let t = fit_sim(&m, &test);
        println!(
            "{choice} refitted on 0..5000, seed {seed}: test FIT {t:.3} %; {}",
            parameters(&m)
        );
        tests.push(t);
    }
    let (lo, hi) = tests
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| {
            (a.min(t), b.max(t))
        });
    let median = upper_median(&mut tests).unwrap_or(f64::NAN);
    println!("test FIT of the choice: median {median:.3} % (range {lo:.3}-{hi:.3})");
}
