//! `hysid compare EXPERIMENT.toml -o DIR`: several back-ends run on the same
//! data with the same priors, in parallel (rayon) and deterministically
//! (each run has its own seed; results keep the file's order), scored on the
//! same validation part, and reported side by side (`report.md`,
//! `report.json`, every identified model under `models/`).

pub mod experiment;
pub mod report;
pub mod truth;

pub use experiment::{
    DataEntry, DataPart, DataSpec, Experiment, ExperimentError, ExperimentWarning, Provenance,
    RecordSpec, RunSpec, ScoredRows, SweepSpec, value_text,
};
pub use hysid_plot::FigureFormat;
pub use report::{ReportFolderError, check_report_folder, write_report};

use crate::identify::{Auto, Identify, Mode};
use hysid_core::backend::{Progress, Registry};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::{ModeCountNeed, Priors};
use hysid_core::simulate::{GivenStateLater, ValidationReport, ValidationWarning, validate};
use hysid_io::load_each;
use hysid_model::data::{DataError, DataSelection, Dataset, RowRange};
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::Simulation;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// One run after expansion of sweeps.
#[derive(Debug, Clone)]
pub struct Job {
    /// Label (unique).
    pub name: String,
    /// The sweep it belongs to, with the varied key and value.
    pub sweep: Option<SweepPoint>,
    /// Back-end.
    pub method: String,
    /// Orders.
    pub na: usize,
    /// Orders.
    pub nb: usize,
    /// Priors after merging.
    pub priors: Priors,
    /// Options.
    pub settings: Settings,
    /// Seed.
    pub seed: u64,
    /// The `[[run]]` it repeats with one of its `seeds`.
    pub seed_group: Option<String>,
    /// The group's other seeds, when its fit does not depend on the seed
    /// ([`Identify::seeded`]): this run stands for them, and they do not run.
    pub same_for_seeds: Vec<u64>,
    /// Options chosen on the selection rows (`auto = true`).
    pub auto: bool,
    /// Where its options come from.
    pub origin: Origin,
}

/// Where a run's options come from, as the report labels it
/// ([`Origin::label`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    /// Chosen on selection rows inside the identification rows (`auto`).
    SelectionRows,
    /// Declared: a setting of a published study.
    Paper,
    /// Declared: chosen on the scored rows.
    Oracle,
    /// Declared: the user's own.
    User,
    /// Not declared by the experiment file.
    Unstated,
    /// A point of a sweep.
    SweepPoint,
    /// The sweep's point of highest `fit_sim` on the scored rows (the
    /// first of equals): an oracle figure when those are test rows.
    SweepBest,
}

impl Origin {
    /// The run's declared provenance, or the program's label of an `auto`
    /// run.
    fn of_run(r: &RunSpec) -> Self {
        match (r.auto, r.provenance) {
            (true, _) => Origin::SelectionRows,
            (false, Some(Provenance::Paper)) => Origin::Paper,
            (false, Some(Provenance::Oracle)) => Origin::Oracle,
            (false, Some(Provenance::User)) => Origin::User,
            (false, None) => Origin::Unstated,
        }
    }

    /// The label in the report's provenance column, for runs scored on
    /// `rows`.
    pub fn label(self, rows: ScoredRows) -> &'static str {
        match (self, rows) {
            (Origin::SelectionRows, _) => "chosen on selection rows",
            (Origin::Paper, _) => "paper setting",
            (Origin::Oracle, ScoredRows::Validation) => "oracle (chosen on these test rows)",
            (Origin::Oracle, ScoredRows::Selection) => "chosen on these selection rows",
            (Origin::User, _) => "user setting",
            (Origin::Unstated, _) => "not stated",
            (Origin::SweepPoint, _) => "sweep point",
            (Origin::SweepBest, ScoredRows::Validation) => {
                "oracle (best of the sweep on these test rows)"
            }
            (Origin::SweepBest, ScoredRows::Selection) => {
                "best of the sweep on these selection rows"
            }
        }
    }
}

/// Position of a run in a sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepPoint {
    /// Sweep name.
    pub sweep: String,
    /// Varied keys and their values (as text), in axis order.
    pub values: Vec<(String, String)>,
}

/// What a run produced.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    /// Label.
    pub name: String,
    /// Back-end.
    pub method: String,
    /// Sweep position, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sweep: Option<SweepPoint>,
    /// The `[[run]]` this result repeats with one of its seeds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed_group: Option<String>,
    /// The group's seeds this run stands for, its fit not depending on
    /// the seed ([`Job::same_for_seeds`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub same_for_seeds: Vec<u64>,
    /// Where its options come from.
    pub origin: Origin,
    /// Seed of the run.
    pub seed: u64,
    /// Output lags of the model written (of the run, where it failed or
    /// its model has no regressor).
    pub na: usize,
    /// Input lags of the model written (of the run, where it failed or
    /// its model has no regressor).
    pub nb: usize,
    /// Options given (`--set`).
    pub options: Vec<(String, String)>,
    /// Number of modes of the identified model.
    pub modes: Option<usize>,
    /// Validation scores.
    pub report: Option<ValidationReport>,
    /// Identification time in seconds.
    pub seconds: f64,
    /// The error, when the run failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Model file written, relative to the output folder.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_file: Option<String>,
    /// The model (not serialised in the report).
    #[serde(skip)]
    pub model: Option<Model>,
    /// The validation simulation (for plots).
    #[serde(skip)]
    pub simulation: Option<Simulation>,
    /// How the simulated modes follow the true ones (`[data] truth`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mode_recovery: Option<truth::ModeRecovery>,
}

/// The result of an experiment.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// Title.
    pub title: String,
    /// Description.
    pub description: String,
    /// Data file and split, as text.
    pub data: String,
    /// What the experiment asks for that its readers should be told
    /// ([`Experiment::warnings`]), as text.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The scored records in order, each as its file's name, rows and
    /// (where they are not `[data]`'s) signals: the columns of the
    /// per-record table.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub scored_records: Vec<String>,
    /// The samples every run's scores leave out at the start of each
    /// record: the warm-up asked for, or more ([`RaisedWarmup`]).
    pub warmup: usize,
    /// Where `warmup` is longer than the warm-up asked for, and why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warmup_raised: Option<RaisedWarmup>,
    /// What the scored rows are (validation or selection rows).
    #[serde(skip)]
    pub scored_rows: ScoredRows,
    /// Runs in file order (runs, then sweep points).
    pub results: Vec<RunResult>,
    /// Validation record (for plots).
    #[serde(skip)]
    pub validation: Option<Dataset>,
    /// The format the figures are written in (the report links them).
    #[serde(skip)]
    pub figures: FigureFormat,
    /// Row of the record where the validation part starts (for time axes).
    pub validation_first_row: usize,
    /// Axis label of the output in figures.
    pub output_label: String,
    /// Axis label of the inputs in figures.
    pub input_label: String,
    /// The figures [`write_report`] drew (none before it runs): what the
    /// report links.
    #[serde(skip)]
    pub drawn: Drawn,
}

/// A report's warm-up lengthened past the one asked for, so that every
/// run is scored on the same samples: a run whose simulation starts later
/// (an initial state read from a longer warm-up, regressors with longer
/// lags) would otherwise be scored on fewer.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RaisedWarmup {
    /// The warm-up asked for (`[data] warmup`, `--warmup`).
    pub asked: usize,
    /// The first run, in report order, whose simulation starts latest.
    pub run: String,
}

/// The figures of a report, as [`write_report`] drew them: each a path
/// relative to the report's directory.
#[derive(Debug, Clone, Default)]
pub struct Drawn {
    /// The figure of every run together.
    all: Option<String>,
    /// The runs drawn.
    runs: Vec<DrawnRun>,
    /// The sweeps with a figure: the sweep's name and its figure.
    sweeps: Vec<(String, String)>,
}

/// The figures of one run.
#[derive(Debug, Clone)]
struct DrawnRun {
    name: String,
    simulation: String,
    modes: String,
    /// Its regions, where it has a partition to draw.
    regions: Option<String>,
}

fn merge(shared: &Priors, run: &RunSpec) -> Priors {
    let mut p = if run.use_priors {
        shared.clone()
    } else {
        Priors::default()
    };
    if let Some(extra) = &run.priors {
        // Every field named (no `..`): a new kind of prior does not compile
        // until it is merged here, so none is dropped silently.
        let Priors {
            modes,
            max_modes,
            saturation,
            tie,
            fixed,
            bounds,
            switching,
            equality,
        } = extra.clone();
        p.modes = modes.or(p.modes);
        p.max_modes = max_modes.or(p.max_modes);
        p.saturation.extend(saturation);
        p.tie.extend(tie);
        p.fixed.extend(fixed);
        p.bounds.extend(bounds);
        if !switching.is_empty() {
            p.switching = switching;
        }
        p.equality.extend(equality);
    }
    if run.modes.is_some() {
        p.modes = run.modes;
    }
    p
}

impl Experiment {
    /// Runs and sweep points, in file order.
    pub fn jobs(&self) -> Result<Vec<Job>, ExperimentError> {
        self.jobs_under(&self.warnings())
    }

    /// [`Experiment::jobs`] with the file's `warnings` known.
    fn jobs_under(&self, warnings: &[ExperimentWarning]) -> Result<Vec<Job>, ExperimentError> {
        // Scored rows that are identification rows may be selection rows:
        // an automatic choice there is labelled as one on the test rows.
        let overlapping =
            (warnings.iter()).any(|w| matches!(w, ExperimentWarning::ValidationOverlaps { .. }));
        let job = |r: &RunSpec, name: String, sweep: Option<SweepPoint>| Job {
            name,
            origin: match Origin::of_run(r) {
                _ if sweep.is_some() => Origin::SweepPoint,
                Origin::SelectionRows if overlapping => Origin::Oracle,
                origin => origin,
            },
            sweep,
            seed_group: None,
            same_for_seeds: Vec::new(),
            auto: r.auto,
            method: r.method.clone(),
            na: r.na.unwrap_or(self.na),
            nb: r.nb.unwrap_or(self.nb),
            priors: merge(&self.priors, r),
            settings: r.settings(),
            seed: r.seed.unwrap_or(self.seed),
        };
        let registry = crate::registry();
        let inputs = self.data.input.len();
        let mut jobs: Vec<Job> = Vec::new();
        for r in &self.runs {
            let run = job(r, r.name.clone(), None);
            check_job(&registry, &run, inputs, "run", |_| "set")?;
            for &seed in &r.seeds {
                jobs.push(Job {
                    name: format!("{} [seed={seed}]", r.name),
                    seed,
                    seed_group: Some(r.name.clone()),
                    ..run.clone()
                });
            }
            if r.seeds.is_empty() {
                jobs.push(run);
            }
        }
        for s in &self.sweeps {
            for point in s.space().candidates() {
                let mut r = s.run.clone();
                for (key, text) in &point.values {
                    let as_count = || -> Result<usize, ExperimentError> {
                        text.parse::<usize>().map_err(|_| ExperimentError::Invalid {
                            path: "experiment".into(),
                            message: format!(
                                "[[sweep]] '{}': {key} = {text} is not a count",
                                s.run.name
                            ),
                        })
                    };
                    match key.as_str() {
                        "modes" => r.modes = Some(as_count()?),
                        "na" => r.na = Some(as_count()?),
                        "nb" => r.nb = Some(as_count()?),
                        _ => {
                            r.set.insert(key.clone(), toml::Value::String(text.clone()));
                        }
                    }
                }
                let shown: Vec<(String, String)> = (point.values.into_iter())
                    .map(|(k, v)| {
                        let v = s.shown(&k, &v).to_string();
                        (k, v)
                    })
                    .collect();
                let label = shown
                    .iter()
                    .map(|(k, v)| format!("{k}={v}"))
                    .collect::<Vec<_>>()
                    .join(", ");
                let point = SweepPoint {
                    sweep: s.run.name.clone(),
                    values: shown,
                };
                let point = job(&r, format!("{} [{label}]", s.run.name), Some(point));
                check_job(&registry, &point, inputs, "sweep", |key| {
                    if s.vary.as_deref() == Some(key) {
                        "vary"
                    } else if s.grid.contains_key(key) {
                        "grid"
                    } else {
                        "set"
                    }
                })?;
                jobs.push(point);
            }
        }
        // Each job's files have a name of their own (case aside), and none
        // is the figure of all runs together (`runs-simulation`).
        let mut files =
            std::collections::HashMap::from([("runs".to_string(), "the figure of all runs")]);
        for j in &jobs {
            let file = experiment::file_name(&j.name);
            if let Some(other) = files.insert(file.clone(), &j.name) {
                return Err(ExperimentError::Invalid {
                    path: "experiment".into(),
                    message: format!(
                        "'{other}' and '{}' would write their results to one file name, '{file}': rename one",
                        j.name
                    ),
                });
            }
        }
        Ok(jobs)
    }

    /// The identification and the scored records: the rows of `[data]
    /// file`, joined by those of every `[[data.records]]` that has them.
    fn records(&self) -> Result<(Dataset, Dataset), ExperimentError> {
        let data = &self.data;
        let main = |rows: Option<RowRange>| {
            rows.map(|rows| (DataEntry::Main, data.file.as_path(), data.selection(rows)))
        };
        let mut ident: Vec<_> = main(data.identification).into_iter().collect();
        let mut valid: Vec<_> = main(data.validation).into_iter().collect();
        for (k, r) in data.records.iter().enumerate() {
            let entry = DataEntry::Record(k + 1);
            if let Some(rows) = r.identification {
                ident.push((entry, r.file.as_path(), data.record_selection(r, rows)));
            }
            if let Some(rows) = r.validation {
                valid.push((entry, r.file.as_path(), data.record_selection(r, rows)));
            }
        }
        let read = |records: &[(DataEntry, &Path, DataSelection)], part| {
            let files: Vec<(&Path, DataSelection)> =
                records.iter().map(|(_, p, s)| (*p, s.clone())).collect();
            load_each(&files).map_err(|e| {
                let entry = e.record.map_or(DataEntry::Main, |at| records[at].0);
                match e.source {
                    source @ DataError::Rows { .. } => ExperimentError::Rows {
                        entry,
                        part,
                        source,
                    },
                    source => ExperimentError::Data { entry, source },
                }
            })
        };
        Ok((
            read(&ident, DataPart::Identification)?,
            read(&valid, DataPart::Scored)?,
        ))
    }

    /// What the report says of the data: the file, its rows and the other
    /// records'.
    fn data_text(&self) -> String {
        let d = &self.data;
        let rows =
            |what: &str, rows: Option<RowRange>| rows.map(|rows| format!("{what} rows {rows}"));
        let own: Vec<String> = [
            d.own_signals(),
            Some(format!("decimate {}", d.decimate)),
            rows("identification", d.identification),
            rows(self.scored_rows.word(), d.validation),
        ]
        .into_iter()
        .flatten()
        .collect();
        let mut text = format!("{} ({})", d.file.display(), own.join(", "));
        for r in &d.records {
            let parts: Vec<String> = [
                d.other_signals(r),
                rows("identification", r.identification),
                rows(self.scored_rows.word(), r.validation),
            ]
            .into_iter()
            .flatten()
            .collect();
            text.push_str(&format!(" + {} ({})", r.file.display(), parts.join(", ")));
        }
        text
    }

    /// The scored records, as [`Comparison::scored_records`] names them
    /// (none when the scored rows are one record).
    fn scored_records(&self) -> Vec<String> {
        let d = &self.data;
        let name = |p: &std::path::Path| {
            p.file_name().map_or_else(
                || p.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            )
        };
        let others = (d.records.iter()).filter_map(|r| {
            let rows = r.validation?;
            let signals = (d.other_signals(r))
                .map(|s| format!(" ({s})"))
                .unwrap_or_default();
            Some(format!("{} {rows}{signals}", name(&r.file)))
        });
        let first = d.validation.map(|rows| {
            let signals = (d.own_signals())
                .map(|s| format!(" ({s})"))
                .unwrap_or_default();
            format!("{} {rows}{signals}", name(&d.file))
        });
        let mut all: Vec<String> = first.into_iter().chain(others).collect();
        // Files of one name in other folders: numbered in order.
        if (1..all.len()).any(|i| all[..i].contains(&all[i])) {
            all = (all.iter().enumerate())
                .map(|(i, label)| format!("{}. {label}", i + 1))
                .collect();
        }
        if all.len() > 1 { all } else { Vec::new() }
    }

    /// Loads the data once, then runs every job in parallel and scores it.
    pub fn run(&self, progress: &dyn Progress) -> Result<Comparison, ExperimentError> {
        let (ident, valid) = self.records()?;
        let shortest = (valid.record_ranges().iter()).map(|r| r.len()).min();
        if let Some(samples) = shortest.filter(|&n| n <= self.data.warmup) {
            return Err(ExperimentError::Warmup {
                warmup: self.data.warmup,
                samples,
                word: self.scored_rows.word(),
            });
        }
        // A truth column is refused beside records, and [data] without them
        // has its validation rows.
        let true_modes = match self.data.truth.as_ref().zip(self.data.validation) {
            None => None,
            Some((column, rows)) => Some(
                truth::load(&self.data.file, column, self.data.decimate, rows).map_err(|e| {
                    ExperimentError::Truth {
                        path: self.data.file.display().to_string(),
                        source: Box::new(e),
                    }
                })?,
            ),
        };
        let registry = crate::registry();
        let warnings = self.warnings();
        let jobs = self.jobs_under(&warnings)?;
        if let Some(job) = jobs.iter().find(|j| j.auto) {
            request(job, &ident, &self.data)
                .check_selection()
                .map_err(|e| ExperimentError::Selection(self.data.selection_error(e)))?;
        }
        let jobs = once_where_seed_free(jobs, &registry, &ident, &self.data);
        progress.start(jobs.len() as u64, "identifying");
        let results: Vec<RunResult> = jobs
            .par_iter()
            .map(|job| {
                let r = run_job(&registry, job, &ident, &valid, &self.data);
                progress.advance(1);
                r
            })
            .collect();
        progress.finish();
        let (mut results, warmup, warmup_raised) = scored_alike(results, &valid, self.data.warmup);
        if let Some(t) = &true_modes {
            for r in &mut results {
                if let Some(sim) = &r.simulation {
                    match t.score(sim, warmup) {
                        Ok(m) => r.mode_recovery = m,
                        Err(e) => r.error = Some(format!("true modes: {e}")),
                    }
                }
            }
        }
        label_sweep_best(&mut results);
        let mut warnings: Vec<String> = warnings.iter().map(ToString::to_string).collect();
        warnings.extend(given_state_warnings(&results, &self.data));
        if let Some(w) = constant_output(&results) {
            warnings.push(w.to_string());
        }
        Ok(Comparison {
            title: self.title.clone(),
            description: self.description.clone(),
            data: self.data_text(),
            scored_records: self.scored_records(),
            warnings,
            scored_rows: self.scored_rows,
            warmup,
            warmup_raised,
            results,
            validation: Some(valid),
            figures: FigureFormat::Svg,
            validation_first_row: self.data.first_row(DataPart::Scored),
            output_label: self
                .data
                .output_label
                .clone()
                .unwrap_or_else(|| format!("output {}", self.data.output)),
            input_label: self
                .data
                .input_label
                .clone()
                .unwrap_or_else(|| format!("input {}", self.data.input.join(", "))),
            drawn: Drawn::default(),
        })
    }
}

/// [`ValidationWarning::ConstantOutput`] where the scored output of
/// `results` is constant (every run is scored on the same samples, so it
/// is the data's).
pub fn constant_output(results: &[RunResult]) -> Option<ValidationWarning> {
    (results.iter().filter_map(|r| r.report.as_ref()))
        .any(|v| v.constant_output)
        .then_some(ValidationWarning::ConstantOutput)
}

/// For each run (its seeds and sweep points once) whose model starts from
/// the state its file gives, where a record's rows of `data` start after
/// its first row ([`GivenStateLater`]): the run's name and the warning.
fn given_state_warnings(results: &[RunResult], data: &DataSpec) -> Vec<String> {
    let parts = [(data.identification, data.validation)].into_iter().chain(
        data.records
            .iter()
            .map(|r| (r.identification, r.validation)),
    );
    let starts: Vec<usize> = (parts.flat_map(|(a, b)| [a, b]))
        .filter_map(|rows| rows?.start)
        .collect();
    let mut out: Vec<String> = Vec::new();
    for r in results {
        let Some(later) = (r.model.as_ref()).and_then(|m| GivenStateLater::of(m, starts.clone()))
        else {
            continue;
        };
        let name = (r.sweep.as_ref().map(|s| &s.sweep))
            .or(r.seed_group.as_ref())
            .unwrap_or(&r.name);
        let line = format!("'{name}': {later}");
        if !out.contains(&line) {
            out.push(line);
        }
    }
    out
}

/// `results` scored on the same samples: from the latest sample at which
/// any run's scores start in a record (`warmup`, or later where a
/// simulation starts later), every run is scored again from there. Returns
/// the results, the warm-up they share, and why it is longer than `warmup`
/// where it is.
fn scored_alike(
    mut results: Vec<RunResult>,
    valid: &Dataset,
    warmup: usize,
) -> (Vec<RunResult>, usize, Option<RaisedWarmup>) {
    let starts: Vec<Option<usize>> = (results.iter())
        .map(|r| r.report.as_ref().map(|v| first_scored(v, valid)))
        .collect();
    let latest = starts.iter().flatten().copied().max().unwrap_or(warmup);
    if latest <= warmup {
        return (results, warmup, None);
    }
    let run = (results.iter().zip(&starts))
        .find(|(_, s)| **s == Some(latest))
        .map(|(r, _)| r.name.clone())
        .unwrap_or_default();
    results.par_iter_mut().for_each(|r| {
        let Some(model) = &r.model else {
            return;
        };
        match validate(model, valid, latest) {
            Ok((report, sim, _)) => {
                r.report = Some(report);
                r.simulation = Some(sim);
            }
            Err(e) => {
                (r.report, r.simulation) = (None, None);
                r.error = Some(format!("validation: {e}"));
            }
        }
    });
    let raised = RaisedWarmup { asked: warmup, run };
    (results, latest, Some(raised))
}

/// The first sample `report` scores of a record of `data`, the latest over
/// its records.
fn first_scored(report: &ValidationReport, data: &Dataset) -> usize {
    if report.records.is_empty() {
        return data.len().saturating_sub(report.n);
    }
    (data.record_ranges().iter().zip(&report.records))
        .map(|(range, part)| range.len().saturating_sub(part.n))
        .max()
        .unwrap_or(0)
}

/// `job`'s priors and options as its back-end checks them before it fits
/// (a `modes` of 0, an option it does not take, a value it refuses, a
/// prior kind it does not honour, a name the model structure of `inputs`
/// inputs lacks, entries that cannot hold together, no mode count for a
/// back-end that needs one), so
/// that a malformed entry is refused before anything runs. `what` is
/// `run` or `sweep`; `source` names where an option's value comes from
/// (`set`, or a sweep's `vary` or `grid`). An unknown method is left to
/// [`Experiment::check`].
fn check_job(
    registry: &Registry,
    job: &Job,
    inputs: usize,
    what: &str,
    source: impl Fn(&str) -> &'static str,
) -> Result<(), ExperimentError> {
    let name = job.sweep.as_ref().map_or(job.name.as_str(), |p| &p.sweep);
    let invalid = |message: String| ExperimentError::Invalid {
        path: "experiment".into(),
        message: format!("[[{what}]] '{name}': {message}"),
    };
    job.priors
        .check()
        .map_err(|problem| invalid(problem.to_string()))?;
    if let Some(backend) = registry.get(&job.method) {
        backend
            .check_settings(&job.settings)
            .map_err(|e| invalid(e.render(e.key().map_or("set", &source))))?;
        // The entry is named already: the priors need no origin.
        (job.priors)
            .ensure_honoured(backend.name(), backend.honours(), None)
            .map_err(|e| invalid(e.to_string()))?;
        let orders = RegressorSpec::new(job.na, job.nb, inputs);
        (backend.check_priors(&job.settings, &job.priors, orders, None))
            .map_err(|e| invalid(e.to_string()))?;
        let need = backend.mode_count_need(&job.settings);
        if !job.auto && !need.met_by(&job.priors) {
            let give = match need {
                ModeCountNeed::Count => "modes = S",
                _ => "modes = S or max_modes = S",
            };
            let choose = match job.sweep {
                Some(_) => "sweep modes",
                None => "auto = true to choose it",
            };
            return Err(invalid(format!(
                "method '{}' needs the number of modes: give {give} (or {choose})",
                backend.name()
            )));
        }
    }
    Ok(())
}

/// Labels the point of highest `fit_sim` of each sweep (the first of
/// equals) [`Origin::SweepBest`].
fn label_sweep_best(results: &mut [RunResult]) {
    let mut best: Vec<(String, usize, f64)> = Vec::new();
    for (i, r) in results.iter().enumerate() {
        let (Some(point), Some(v)) = (&r.sweep, &r.report) else {
            continue;
        };
        let fit = if v.fit_sim.is_nan() {
            f64::NEG_INFINITY
        } else {
            v.fit_sim
        };
        match best.iter_mut().find(|(s, _, _)| *s == point.sweep) {
            Some(b) if fit > b.2 => *b = (point.sweep.clone(), i, fit),
            Some(_) => {}
            None => best.push((point.sweep.clone(), i, fit)),
        }
    }
    for (_, i, _) in best {
        results[i].origin = Origin::SweepBest;
    }
}

/// `jobs` with one job per seed group whose fit does not depend on the
/// seed ([`Identify::seeded`]): its first, standing for the group's other
/// seeds ([`Job::same_for_seeds`]). A group whose request fails that check
/// runs every seed, and each run reports the failure.
fn once_where_seed_free(
    jobs: Vec<Job>,
    registry: &Registry,
    ident: &Dataset,
    spec: &DataSpec,
) -> Vec<Job> {
    let mut out: Vec<Job> = Vec::with_capacity(jobs.len());
    // Each group seen, and the index in `out` of its one run when the
    // group is seed-free.
    let mut groups: Vec<(String, Option<usize>)> = Vec::new();
    for job in jobs {
        let Some(group) = job.seed_group.clone() else {
            out.push(job);
            continue;
        };
        match groups.iter().find(|(g, _)| *g == group).map(|(_, k)| *k) {
            Some(Some(k)) => out[k].same_for_seeds.push(job.seed),
            Some(None) => out.push(job),
            None => {
                let free = matches!(request(&job, ident, spec).seeded(registry), Ok(false));
                groups.push((group, free.then_some(out.len())));
                out.push(job);
            }
        }
    }
    out
}

/// The request that identifies `job` on `ident` (choosing its options on
/// the selection rows when it is an `auto` run).
fn request<'a>(job: &'a Job, ident: &'a Dataset, spec: &DataSpec) -> Identify<'a> {
    let mode = if job.auto {
        Mode::Auto(Auto {
            select_rows: spec.selection,
            folds: spec.folds,
            select_records: spec.select_records,
            refit_starts: spec.refit_starts,
            grid: None,
        })
    } else {
        Mode::Plain
    };
    Identify {
        first_row: spec.first_row(DataPart::Identification),
        priors: job.priors.clone(),
        priors_origin: Some("the experiment".into()),
        options: job.settings.clone(),
        seed: job.seed,
        warmup: spec.warmup,
        mode,
        ..Identify::new(&job.method, ident).orders(job.na, job.nb)
    }
}

/// Identifies `job` on `ident` ([`request`]).
fn identify(
    registry: &Registry,
    job: &Job,
    ident: &Dataset,
    spec: &DataSpec,
) -> Result<Model, String> {
    request(job, ident, spec)
        .run(registry)
        .map(|i| i.model)
        .map_err(|e| {
            if job.auto {
                format!("auto: {e}")
            } else {
                e.to_string()
            }
        })
}

fn run_job(
    registry: &Registry,
    job: &Job,
    ident: &Dataset,
    valid: &Dataset,
    spec: &DataSpec,
) -> RunResult {
    let warmup = spec.warmup;
    let mut out = RunResult {
        name: job.name.clone(),
        method: job.method.clone(),
        sweep: job.sweep.clone(),
        seed_group: job.seed_group.clone(),
        same_for_seeds: job.same_for_seeds.clone(),
        origin: job.origin,
        seed: job.seed,
        na: job.na,
        nb: job.nb,
        options: job.settings.pairs().to_vec(),
        modes: None,
        report: None,
        seconds: 0.0,
        error: None,
        model_file: None,
        model: None,
        simulation: None,
        mode_recovery: None,
    };
    let t0 = Instant::now();
    let model = identify(registry, job, ident, spec);
    out.seconds = t0.elapsed().as_secs_f64();
    match model {
        Err(e) => out.error = Some(e),
        Ok(m) => {
            out.modes = Some(m.mode_count());
            // An auto run may choose other orders than it was given.
            if let Some(orders) = m.orders() {
                (out.na, out.nb) = (orders.na, orders.nb);
            }
            match validate(&m, valid, warmup) {
                Ok((report, sim, _)) => {
                    out.report = Some(report);
                    out.simulation = Some(sim);
                }
                Err(e) => out.error = Some(format!("validation: {e}")),
            }
            out.model = Some(m);
        }
    }
    out
}
