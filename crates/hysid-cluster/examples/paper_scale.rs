//! The founding paper's sections 4 and 5 at its own data size. Juloski,
//! Heemels and Ferrari-Trecate (IFAC ADHS 2003) identify on about 250
//! points; the protocol of `docs/cli.md` identifies on 4000-5000 rows, so
//! the paper's `c` values mean a far smaller share of the data there.
//!
//! For each of the paper's settings (orders, modes, `c`), `cluster` is run
//! on eight 250-row windows of the identification rows (seed 1) and on all
//! of them, at the paper's `c` and at the same `c / N` (`c` times the
//! ratio of the row counts), and every model is scored by free-run
//! simulation FIT on the test rows, which choose nothing here. The table
//! gives the median and range over the windows.
//!
//! ```text
//! cargo run --release -p hysid-cluster --example paper_scale
//! ```

use hysid_cluster::Cluster;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::simulate::validate;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::data::{DataSelection, Dataset, RowRange};
use hysid_model::regressors::RegressorSpec;
use hysid_model::statistics::median;
use std::path::{Path, PathBuf};

/// A record: file, decimation, identification and test rows.
struct Record {
    name: &'static str,
    file: &'static str,
    decimate: usize,
    ident: (usize, usize),
    test: (usize, usize),
}

/// One of the paper's settings: `(na, nb, modes, c)`; `c = 0` is the
/// theoretical minimum `n + 2`.
type Setting = (usize, usize, usize, usize);

const WINDOW: usize = 250;
const WINDOWS: usize = 8;

fn load(root: &Path, r: &Record, rows: (usize, usize)) -> Dataset {
    let selection = DataSelection {
        decimate: r.decimate,
        rows: RowRange {
            start: Some(rows.0),
            end: Some(rows.1),
        },
        ..Default::default()
    };
    hysid_io::load(&root.join(r.file), &selection).expect("the bundled record")
}

/// Test-row FIT of `cluster` on `data`, or `None` when the run fails.
fn score(data: &Dataset, test: &Dataset, (na, nb, modes, c): Setting) -> Option<f64> {
    let priors = Priors {
        modes: Some(modes),
        ..Default::default()
    };
    let problem = Problem {
        data,
        orders: RegressorSpec::new(na, nb, 1),
        priors: &priors,
        priors_origin: None,
    };
    let set = Settings::parse(&[format!("c={c}")]).ok()?;
    let model = Pwarx(Cluster)
        .run(&problem, &set, &RunContext::quiet(1))
        .ok()?;
    let (report, _, _) = validate(&model, test, 10).ok()?;
    report.fit_sim.is_finite().then_some(report.fit_sim)
}

fn summary(fits: &[Option<f64>]) -> String {
    let mut ok: Vec<f64> = fits.iter().flatten().copied().collect();
    let failed = fits.len() - ok.len();
    if ok.is_empty() {
        return format!("all {failed} failed");
    }
    ok.sort_by(f64::total_cmp);
    let (lowest, highest) = (ok[0], ok[ok.len() - 1]);
    let median = median(&mut ok).unwrap_or(f64::NAN);
    let tail = if failed > 0 {
        format!(", {failed} failed")
    } else {
        String::new()
    };
    format!("{median:.1} ({lowest:.1} to {highest:.1}{tail})")
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../models/pick-and-place");
    let records = [
        (
            Record {
                name: "real record (section 4)",
                file: "headdata_1v6.mat",
                decimate: 10,
                ident: (0, 5000),
                test: (5000, 6001),
            },
            vec![
                (2, 1, 2, 0),
                (2, 1, 2, 25),
                (2, 1, 2, 40),
                (2, 1, 2, 55),
                (2, 1, 2, 90),
                (2, 2, 2, 0),
                (2, 2, 2, 40),
                (2, 2, 2, 55),
                (2, 2, 2, 90),
                (2, 2, 3, 35),
            ],
        ),
        (
            Record {
                name: "lower saturation, simulated (section 5)",
                file: "simulated/lower-saturation.csv",
                decimate: 1,
                ident: (0, 4000),
                test: (4000, 6000),
            },
            vec![(2, 2, 3, 25)],
        ),
        (
            Record {
                name: "both saturations, simulated (section 5)",
                file: "simulated/both-saturations.csv",
                decimate: 1,
                ident: (0, 4000),
                test: (4000, 6000),
            },
            vec![(2, 2, 4, 40)],
        ),
    ];
    for (record, settings) in &records {
        let test = load(&root, record, record.test);
        let full = load(&root, record, record.ident);
        let rows = record.ident.1 - record.ident.0;
        let step = (rows - WINDOW) / (WINDOWS - 1);
        let windows: Vec<Dataset> = (0..WINDOWS)
            .map(|w| {
                let a = record.ident.0 + w * step;
                load(&root, record, (a, a + WINDOW))
            })
            .collect();
        println!(
            "\n{} (test rows {}..{})\n",
            record.name, record.test.0, record.test.1
        );
        println!(
            "| na, nb | modes | c | 250-row windows: median (range) | all {rows} rows | all rows, same c/N |"
        );
        println!("|---|---|---|---|---|---|");
        for &(na, nb, modes, c) in settings {
            let c = if c == 0 { na + nb + 2 } else { c };
            let scaled = c * rows / WINDOW;
            let fits: Vec<Option<f64>> = windows
                .iter()
                .map(|w| score(w, &test, (na, nb, modes, c)))
                .collect();
            let show = |f: Option<f64>| f.map_or("failed".to_string(), |v| format!("{v:.1}"));
            println!(
                "| {na}, {nb} | {modes} | {c} | {} | {} | {} (c = {scaled}) |",
                summary(&fits),
                show(score(&full, &test, (na, nb, modes, c))),
                show(score(&full, &test, (na, nb, modes, scaled))),
            );
        }
    }
}
