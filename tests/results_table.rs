//! The README's results table quotes the main job's committed report
//! (`docs/pick-and-place/report.md`, written by `hysid compare
//! models/pick-and-place/experiment.toml`): each row's median and range
//! over seeds, or its single figure, as the report gives them.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The README row's method cell, and the report's run it quotes.
const QUOTED: &[(&str, &str)] = &[
    ("`arx --auto` (baseline)", "arx auto (na, nb <= 2)"),
    ("`cluster --auto`", "cluster auto"),
    ("`bounded --auto`", "bounded auto"),
    ("`klinreg --auto`", "klinreg auto"),
    ("`parc --auto`", "parc auto"),
    ("`bayes --auto`", "bayes auto"),
    ("`physical` (head.toml)", "physical(head.toml)"),
];

/// The cells of the rows of the first table after the line `heading`.
fn table_after(text: &str, heading: &str) -> Vec<Vec<String>> {
    let start = text
        .find(heading)
        .unwrap_or_else(|| panic!("no '{heading}'"));
    text[start..]
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .skip(2)
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect()
        })
        .collect()
}

/// `median % (low-high...)` or `value %` as its numbers' texts.
fn quoted_figures(cell: &str) -> Vec<String> {
    let (value, rest) = cell.split_once(" %").expect("a figure in %");
    let mut out = vec![value.to_string()];
    if let Some(range) = rest.trim().strip_prefix('(') {
        let range = range.split([',', ')']).next().unwrap();
        let (lo, hi) = range.split_once('-').expect("a range low-high");
        out.extend([lo.to_string(), hi.to_string()]);
    }
    out
}

/// `x` with as many decimals as `like` has.
fn rounded_as(x: f64, like: &str) -> String {
    let decimals = like.split_once('.').map_or(0, |(_, d)| d.len());
    format!("{x:.decimals$}")
}

#[test]
fn the_readme_results_table_quotes_the_main_job_report() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let report = std::fs::read_to_string(root().join("docs/pick-and-place/report.md")).unwrap();
    let rows = table_after(&readme, "## Results");
    assert_eq!(rows.len(), QUOTED.len(), "{rows:?}");
    let seeds = table_after(&report, "Over seeds");
    let runs = table_after(&report, "| run | provenance | method |");
    for row in &rows {
        let (_, run) = QUOTED
            .iter()
            .find(|(cell, _)| *cell == row[0])
            .unwrap_or_else(|| panic!("README row {:?}: which report run does it quote?", row[0]));
        let figures = quoted_figures(&row[1]);
        // Over seeds: | run | provenance | seeds | scored | median | min | max | (rmse_sim's) |
        let reported: Vec<f64> = match seeds.iter().find(|r| r[0] == *run) {
            Some(r) => r[4..7].iter().map(|v| v.parse().unwrap()).collect(),
            None => {
                // One run: | run | provenance | method | na | nb | modes | fit_sim | ...
                let r = runs
                    .iter()
                    .find(|r| r[0] == *run)
                    .unwrap_or_else(|| panic!("no run '{run}' in the report"));
                assert_eq!(r[1], "chosen on selection rows", "{run}");
                vec![r[6].parse().unwrap()]
            }
        };
        if let Some(r) = seeds.iter().find(|r| r[0] == *run) {
            assert!(
                r[1] == "chosen on selection rows" || r[1] == "user setting",
                "{run}: {}",
                r[1]
            );
        }
        assert_eq!(figures.len(), reported.len(), "{run}: {}", row[1]);
        for (quoted, value) in figures.iter().zip(&reported) {
            assert_eq!(*quoted, rounded_as(*value, quoted), "{run}: {}", row[1]);
        }
    }
}

/// The report's table over seeds gives each group's median, least and
/// largest `rmse_sim`, as its runs' rows give them (an odd number of
/// scored runs: the median is one of them).
#[test]
fn the_seeds_table_gives_the_runs_rmse_median_and_range() {
    let report = std::fs::read_to_string(root().join("docs/pick-and-place/report.md")).unwrap();
    let seeds = table_after(&report, "Over seeds");
    let runs = table_after(&report, "| run | provenance | method |");
    assert!(!seeds.is_empty());
    for group in &seeds {
        let prefix = format!("{} [seed=", group[0]);
        let mut errors: Vec<&str> = (runs.iter())
            .filter(|r| r[0].starts_with(&prefix))
            .map(|r| r[7].as_str())
            .collect();
        errors.sort_by(|a, b| a.parse::<f64>().unwrap().total_cmp(&b.parse().unwrap()));
        assert_eq!(errors.len() % 2, 1, "{}: {errors:?}", group[0]);
        let expected = [
            errors[errors.len() / 2],
            errors[0],
            errors[errors.len() - 1],
        ];
        assert_eq!(group[7..10], expected, "{}", group[0]);
    }
}
