//! `hysid identify`: one back-end on one record, or on several records of
//! one system.

use crate::error::CliError;
use crate::error::Result;
use crate::progress::TerminalProgress;
use crate::selection::{DataArgs, SignalDefaults};
use hysid::compare::experiment::MODEL_FILE_OPTION;
use hysid::identify::{Auto, Identify, Mode};
use hysid::select::SelectError;
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::search::SearchSpace;
use hysid_model::data::RowRange;
use hysid_model::model::{ScoredCandidate, Selection};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `hysid identify`. `-h` gives each flag's first sentence,
/// `--help` the whole text; the flags are grouped under headings.
#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Data file(s) (.csv or .mat).
    ///
    /// Several files are records of one system: one model is fitted on
    /// all of them, nothing spans two records, and each starts from its own
    /// initial state.
    #[arg(required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Back-end (see `hysid methods`).
    #[arg(short = 'm', long = "method", help_heading = "Method")]
    pub method: String,
    /// Number of past outputs in the regressor.
    #[arg(long, default_value_t = 2, help_heading = "Method")]
    pub na: usize,
    /// Number of past values of each input in the regressor.
    #[arg(long, default_value_t = 2, help_heading = "Method")]
    pub nb: usize,
    /// Back-end option KEY=VALUE (repeatable).
    ///
    /// The options and their defaults: `hysid methods NAME`.
    #[arg(long = "set", value_name = "KEY=VALUE", help_heading = "Method")]
    pub set: Vec<String>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0, help_heading = "Method")]
    pub seed: u64,
    /// Identify on standardised data.
    ///
    /// Zero mean, unit variance; the model is written in original units with
    /// the statistics recorded.
    #[arg(long, help_heading = "Method")]
    pub standardize: bool,
    /// Time budget in seconds.
    ///
    /// Long back-ends return their best model by then, marked cut short.
    // Hyphen values are taken, so `-inf` is refused as a budget, not read as a flag.
    #[arg(long, allow_hyphen_values = true, help_heading = "Method")]
    pub time_budget: Option<f64>,
    /// Number of modes (the prior `modes`).
    ///
    /// Overrides the prior file's.
    #[arg(long, help_heading = "Priors")]
    pub modes: Option<usize>,
    /// Largest number of modes; the count is chosen.
    ///
    /// The prior `max_modes` (overrides the prior file's): the count is
    /// chosen by hold-out simulation FIT, or by the back-end itself.
    #[arg(long, help_heading = "Priors")]
    pub max_modes: Option<usize>,
    /// Prior file (TOML, or JSON named .json), see docs/priors.md.
    #[arg(long, help_heading = "Priors")]
    pub prior: Option<PathBuf>,
    /// Choose the options on selection rows (docs/selection.md).
    ///
    /// The candidates are fitted on the identification rows before the
    /// selection rows and scored by free-run simulation FIT on them; the
    /// choice is then fitted on all the identification rows.
    #[arg(long, conflicts_with = "standardize", help_heading = "Selection")]
    pub auto: bool,
    /// With --auto: the selection rows A..B.
    ///
    /// In the rows of the file (after decimation); they must start or end
    /// the identification rows. Default: the last 20 % of them (fewer than
    /// 100: also as many at their start).
    #[arg(
        long,
        requires = "auto",
        allow_hyphen_values = true,
        help_heading = "Selection"
    )]
    pub select_rows: Option<RowRange>,
    /// With --auto: K rolling folds instead of one split.
    ///
    /// K contiguous blocks on a rolling origin, block j scored by the model
    /// fitted on the blocks before it.
    #[arg(
        long,
        requires = "auto",
        conflicts_with = "select_rows",
        help_heading = "Selection"
    )]
    pub folds: Option<usize>,
    /// With --auto and several data files: hold out the last K files.
    ///
    /// The candidates are fitted on the records before them and scored on
    /// them (instead of selection rows).
    #[arg(
        long,
        requires = "auto",
        conflicts_with_all = ["select_rows", "folds"],
        help_heading = "Selection"
    )]
    pub select_records: Option<usize>,
    /// With --auto: seeded starts of the refit of the choice.
    ///
    /// Used when the back-end's seed can change its fit; the choice also
    /// starts from its own fit on the fit rows. The start that simulates
    /// the identification rows best is written.
    #[arg(long, requires = "auto", default_value_t = hysid::select::DEFAULT_REFIT_STARTS, value_parser = crate::selection::parse_at_least_one, help_heading = "Selection")]
    pub refit_starts: usize,
    /// With --auto: a grid axis KEY=V1,V2,.. (repeatable).
    ///
    /// A back-end option, or modes, na, nb; the axes replace the back-end's
    /// search space.
    #[arg(
        long = "grid",
        value_name = "KEY=V1,V2,..",
        requires = "auto",
        help_heading = "Selection"
    )]
    pub grid: Vec<String>,
    /// Samples left out at the start of a free-run score.
    ///
    /// Of the selection rows, and of the comparison with the affine model.
    #[arg(long, default_value_t = 10, value_parser = crate::selection::parse_count, help_heading = "Selection")]
    pub warmup: usize,
    #[command(flatten, next_help_heading = "Data")]
    pub select: DataArgs,
    /// Output model file (JSON).
    #[arg(
        short = 'o',
        long = "out",
        value_name = "MODEL.json",
        help_heading = "Output"
    )]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let registry = hysid::registry();
    if args.data.len() > 1 && args.select_rows.is_some() {
        return Err(CliError::input(
            "--select-rows: not with several data files; hold out whole records with --select-records K",
        ));
    }
    let options = Settings::parse(&args.set)?;
    let model_file = options.get(MODEL_FILE_OPTION).map(Path::new);
    let inputs = (args.data.iter().chain(&args.prior).map(PathBuf::as_path)).chain(model_file);
    super::not_an_input("-o", &args.out, inputs)?;
    // A physical model file's declared inputs are read where none are named.
    // An unknown method is named before the record is read by its defaults.
    let declared = registry.require(&args.method)?.declared_signals(&options)?;
    let select = (args.select.clone()).reading(SignalDefaults::declared(declared.clone()));
    let data = select.load(&args.data)?;
    if let Some(own) = &declared.inputs {
        super::warn_of_order(own, &data, "the model file names");
    }
    // A step far from the record's sampling time is said before the fit,
    // which it may slow a thousandfold.
    if let Some(file) = model_file
        && let Ok(own) = Model::load(file)
    {
        super::warn_sampling_time(file, &own, &data, false);
    }
    let mode = if args.auto {
        let grid = (!args.grid.is_empty())
            .then(|| SearchSpace::parse_grid(&args.grid))
            .transpose()
            .map_err(|e| CliError::input(e.render("--grid")))?;
        Mode::Auto(Auto {
            select_rows: args.select_rows,
            folds: args.folds,
            select_records: args.select_records,
            refit_starts: args.refit_starts,
            grid,
        })
    } else if args.standardize {
        Mode::Standardized
    } else {
        Mode::Plain
    };
    let request = Identify {
        method: args.method.clone(),
        data: &data,
        first_row: args.select.first_row(),
        na: args.na,
        nb: args.nb,
        priors: match &args.prior {
            Some(p) => super::load_priors(p)?,
            None => Priors::default(),
        },
        priors_origin: args.prior.as_ref().map(|p| p.display().to_string()),
        modes: args.modes,
        max_modes: args.max_modes,
        options,
        seed: args.seed,
        time_budget: args.time_budget,
        stop: None,
        warmup: args.warmup,
        mode,
    };
    let started = Instant::now();
    let identified = request
        .run_with(&registry, &TerminalProgress::new())
        .map_err(|e| match e {
            // Selection rows the user did not give are named by the rows
            // they come from.
            hysid::identify::Error::Select(SelectError::Rows { rows, reason })
                if args.select_rows.is_none() =>
            {
                CliError::input(format!(
                    "--auto: the default selection rows {rows} (the last {} % of the identification rows): {reason}; give more rows or --select-rows",
                    hysid::select::DEFAULT_SELECTION_PERCENT
                ))
            }
            // A record too short to score: named by its file and rows.
            hysid::identify::Error::ShortRecord(short) => {
                let (record, i) = (short.record, short.record - 1);
                let file = args.data.get(i).map_or_else(
                    || format!("record {record}"),
                    |p| p.display().to_string(),
                );
                let rows = (args.select.rows_of(i))
                    .map(|r| format!(" --rows {r}"))
                    .unwrap_or_default();
                CliError::input(format!("{file}{rows}: {short} (--warmup)"))
            }
            // Too few samples for the orders and modes: named by the
            // records and rows they were selected from.
            hysid::identify::Error::Identify(e) if e.is_sample_shortage() => {
                let files: Vec<String> = args.data.iter().map(|p| p.display().to_string()).collect();
                let rows: Vec<String> = args.select.rows.iter().map(|r| format!(" --rows {r}")).collect();
                CliError::input(format!(
                    "{}{} ({} samples): {e}",
                    files.join(", "),
                    rows.concat(),
                    data.len()
                ))
            }
            e => e.into(),
        })?;
    let elapsed = started.elapsed();
    let model = &identified.model;
    hysid_io::save_model(model, &args.out)?;
    eprintln!(
        "hysid: {} identified a {} model with {} mode(s) from {} samples{} in {:.3} s -> {}",
        args.method,
        model.kind(),
        model.mode_count(),
        data.len(),
        match data.record_count() {
            1 => String::new(),
            n => format!(" of {n} records"),
        },
        elapsed.as_secs_f64(),
        args.out.display()
    );
    // A run cut short (by --time-budget or an iteration bound), or one with
    // warnings, says so.
    if let Some(note) = model.info().diagnostics.note() {
        eprintln!("hysid: {}: {note}", args.method);
    }
    for warning in identified.fit_warnings(&request) {
        eprintln!("hysid: warning: {}: {warning}", args.method);
    }
    // A model file's given initial state was fitted at the first row read.
    if let Some(file) = request.options.get(MODEL_FILE_OPTION) {
        super::warn_given_state(Path::new(file), model, &args.select.rows);
    }
    if let Some(selection) = &model.info().selection {
        report_selection(&args.method, selection);
    }
    if let Some(warning) = identified.affine_warning(&request) {
        let hint = if model.info().selection.is_none() {
            "; try --auto"
        } else {
            ""
        };
        eprintln!("hysid: warning: {warning}{hint}");
    }
    Ok(())
}

/// One line on what `--auto` chose, and whether the affine model won.
fn report_selection(method: &str, s: &Selection) {
    let chosen = &s.candidates[s.chosen];
    let values: Vec<String> = s
        .chosen_values()
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    let refinement = if s.refinement.is_empty() || s.kept_refinement().is_some() {
        ""
    } else {
        ", its refinements scored no higher"
    };
    let rows: Vec<String> = s
        .splits
        .iter()
        .map(|p| {
            format!(
                "fitted on rows {}, scored on rows {}",
                p.fit_rows, p.select_rows
            )
        })
        .collect();
    eprintln!(
        "hysid: --auto: {} candidate(s) {}; chose {} {} (selection FIT {:.2} %{refinement})",
        s.candidates.len(),
        rows.join("; "),
        chosen.method,
        if values.is_empty() {
            "with its defaults".into()
        } else {
            values.join(" ")
        },
        chosen.fit_sim.unwrap_or(f64::NAN),
    );
    let failed: Vec<&str> = (s.candidates.iter())
        .filter(|c| c.fit_sim.is_none())
        .filter_map(|c| c.error.as_deref())
        .collect();
    if let Some(first) = failed.first() {
        eprintln!(
            "hysid: --auto: {} of the {} candidate(s) could not be fitted and scored (the first: {first})",
            failed.len(),
            s.candidates.len()
        );
    }
    if s.chosen != s.best {
        let best = &s.candidates[s.best];
        let why = match &best.error {
            Some(e) => format!("it was not written: {e}"),
            None => "the choice has fewer modes and is within one standard error of it".into(),
        };
        eprintln!(
            "hysid: --auto: the best selection FIT was {:.2} % with {} mode(s); {why}",
            best.fit_sim.unwrap_or(f64::NAN),
            best.modes.unwrap_or(0)
        );
    }
    if s.refit.len() > 1 {
        let fits: Vec<String> = s
            .refit
            .iter()
            .map(|r| {
                let fit = r
                    .fit_sim
                    .map_or_else(|| "failed".into(), |f| format!("{f:.2}"));
                if r.diverges_backwards {
                    format!("{fit}, diverging on the rows played backwards")
                } else {
                    fit
                }
            })
            .collect();
        let last = if s.refit.last().is_some_and(|r| r.from_candidate) {
            ", the last from the candidate's fit on the fit rows"
        } else {
            ""
        };
        if let Some(kept) = s.refit.iter().position(|r| r.kept) {
            eprintln!(
                "hysid: --auto: refitted on all the identification rows from {} starts{last} (FIT {} %); start {} written",
                s.refit.len(),
                fits.join(" / "),
                kept + 1
            );
        }
    }
    if s.cut_short {
        eprintln!(
            "hysid: --auto: the time budget ran out before the selection ended: the fits after it \
             stopped at their first check and refit starts were left out (a longer --time-budget \
             searches more)"
        );
    }
    if chosen.method != method {
        eprintln!(
            "hysid: --auto: {}; the affine {} model is written",
            why_affine(s, method, chosen.fit_sim),
            chosen.method
        );
    }
}

/// Why no candidate of `method` was written, the affine reference scoring
/// `affine` on the selection rows: every one failed, the better ones were
/// refused at the refit on all the rows, the better ones are within one
/// standard error of the affine model (the rule prefers fewer modes), or
/// none simulated those rows better.
fn why_affine(s: &Selection, method: &str, affine: Option<f64>) -> String {
    let own: Vec<&ScoredCandidate> = s.candidates.iter().filter(|c| c.method == method).collect();
    let affine = affine.unwrap_or(f64::NEG_INFINITY);
    if own.iter().all(|c| c.fit_sim.is_none()) {
        let first = own.iter().find_map(|c| c.error.as_deref());
        return format!(
            "every {method} candidate failed ({})",
            first.unwrap_or("no candidate")
        );
    }
    let better = |c: &ScoredCandidate| c.fit_sim.is_some_and(|f| f > affine);
    if let Some(c) = own.iter().find(|c| better(c) && c.error.is_some()) {
        format!(
            "the {method} candidates that simulated the selection rows better were refused at the \
             refit on all the rows (the first: {})",
            c.error.as_deref().unwrap_or_default()
        )
    } else if own.iter().any(|c| better(c)) {
        format!(
            "the {method} candidates that simulated the selection rows better are within one \
             standard error of the affine model, which has fewer modes"
        )
    } else {
        format!("no {method} candidate simulated the selection rows better than the affine model")
    }
}
