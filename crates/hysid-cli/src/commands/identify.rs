//! `hysid identify`: one back-end on one record.

use crate::Result;
use crate::error::CliError;
use crate::progress::TerminalProgress;
use crate::selection::DataArgs;
use hysid::select::{Plan, Request};
use hysid_core::backend::{Deadline, Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::search::SearchSpace;
use hysid_estimation::pwarx::run_standardized;
use hysid_model::data::RowRange;
use hysid_model::model::Selection;
use hysid_model::regressors::RegressorSpec;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `hysid identify`.
#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Data file (.csv or .mat).
    pub data: PathBuf,
    /// Back-end (see `hysid methods`).
    #[arg(short = 'm', long = "method")]
    pub method: String,
    /// Number of past outputs in the regressor.
    #[arg(long, default_value_t = 2)]
    pub na: usize,
    /// Number of past values of each input in the regressor.
    #[arg(long, default_value_t = 2)]
    pub nb: usize,
    /// Number of modes (the prior `modes`; overrides the prior file).
    #[arg(long)]
    pub modes: Option<usize>,
    /// Largest number of modes, the count chosen by the back-end (the prior
    /// `max_modes`; overrides the prior file).
    #[arg(long)]
    pub max_modes: Option<usize>,
    /// Prior file (TOML), see docs/priors.md.
    #[arg(long)]
    pub prior: Option<PathBuf>,
    /// Back-end option KEY=VALUE (repeatable), see `hysid methods`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Identify on standardised data (zero mean, unit variance); the model is
    /// written in original units with the statistics recorded.
    #[arg(long)]
    pub standardize: bool,
    /// Time budget in seconds: long back-ends return their best model by then.
    // Hyphen values are taken, so `-inf` is refused as a budget, not read as a flag.
    #[arg(long, allow_hyphen_values = true)]
    pub time_budget: Option<f64>,
    /// Output model file (JSON).
    #[arg(short = 'o', long = "out", value_name = "MODEL.json")]
    pub out: PathBuf,
    /// Choose the back-end's options on selection rows inside the
    /// identification rows (free-run simulation FIT), then fit the choice on
    /// all of them; see docs/selection.md.
    #[arg(long, conflicts_with = "standardize")]
    pub auto: bool,
    /// With --auto: the selection rows A..B, in the rows of the file (after
    /// decimation); they must start or end the identification rows. Default:
    /// the last 20 % of them (fewer than 100: also as many at their start).
    #[arg(long, value_parser = parse_rows, requires = "auto")]
    pub select_rows: Option<RowRange>,
    /// With --auto: instead of one split, K contiguous blocks on a rolling
    /// origin (block j scored by the model fitted on the blocks before it).
    #[arg(long, requires = "auto", conflicts_with = "select_rows")]
    pub folds: Option<usize>,
    /// With --auto: starts of the refit of the choice on all the
    /// identification rows when the back-end's seed can change its fit
    /// (the start that simulates those rows best is written).
    #[arg(long, requires = "auto", default_value_t = hysid::select::DEFAULT_REFIT_STARTS, value_parser = crate::selection::parse_at_least_one)]
    pub refit_starts: usize,
    /// With --auto: a grid axis KEY=V1,V2,... (repeatable; a back-end option,
    /// or modes, na, nb) replacing the back-end's search space.
    #[arg(long = "grid", value_name = "KEY=V1,V2,..", requires = "auto")]
    pub grid: Vec<String>,
    /// Samples at the start of the scored rows left out of a free-run score
    /// (the selection rows, and the comparison with the affine model).
    #[arg(long, default_value_t = 10, value_parser = crate::selection::parse_count)]
    pub warmup: usize,
    #[command(flatten)]
    pub select: DataArgs,
}

fn parse_rows(s: &str) -> std::result::Result<RowRange, String> {
    s.parse()
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let registry = hysid::registry();
    let backend = registry.require(&args.method)?;
    let settings = Settings::parse(&args.set)?;
    let mut priors = match &args.prior {
        Some(p) => Priors::load(p)?,
        None => Priors::default(),
    };
    for (flag, value, prior) in [
        ("--modes", args.modes, &mut priors.modes),
        ("--max-modes", args.max_modes, &mut priors.max_modes),
    ] {
        if let Some(s) = value {
            if s == 0 {
                return Err(CliError::input(format!("{flag} must be at least 1")));
            }
            *prior = Some(s);
        }
    }
    let given: Vec<String> = [("--modes", args.modes), ("--max-modes", args.max_modes)]
        .iter()
        .filter_map(|(flag, v)| v.map(|s| format!("{flag} {s}")))
        .collect();
    if !given.is_empty() {
        priors
            .check()
            .map_err(|e| CliError::input(format!("{}: {e}", given.join(" "))))?;
    }
    let deadline = match args.time_budget {
        Some(t) => Deadline::after_seconds(t).ok_or_else(|| {
            CliError::input(format!(
                "--time-budget {t}: must be a positive number of seconds"
            ))
        })?,
        None => Deadline::none(),
    };
    let data = hysid_io::load(&args.data, &args.select.selection()?)?;
    let first_row = args.select.rows.and_then(|r| r.start).unwrap_or(0);
    let origin = args.prior.as_ref().map(|p| p.display().to_string());
    let problem = Problem {
        data: &data,
        orders: RegressorSpec::new(args.na, args.nb, data.inputs.len()),
        priors: &priors,
        priors_origin: origin.as_deref(),
    };
    let progress = TerminalProgress::new();
    let ctx = RunContext {
        seed: args.seed,
        progress: &progress,
        deadline,
    };
    let started = Instant::now();
    let model = if args.auto {
        let space = if args.grid.is_empty() {
            backend.search_space(&problem)?.without_given(&settings)
        } else {
            SearchSpace::parse_grid(&args.grid).map_err(|e| CliError::input(e.render("--grid")))?
        };
        let plan = Plan {
            select: args.select_rows,
            folds: args.folds,
            warmup: args.warmup,
            first_row,
            refit_starts: args.refit_starts,
        };
        let affine = hysid::affine_reference(&registry, backend.name());
        let request = Request::from_problem(backend, affine, &problem, settings, space, plan);
        hysid::select::select(&request, &ctx)?
    } else if args.standardize {
        run_standardized(backend, &problem, &settings, &ctx)?
    } else {
        backend.run(&problem, &settings, &ctx)?
    };
    let elapsed = started.elapsed();
    hysid_io::save_model(&model, &args.out)?;
    eprintln!(
        "hysid: {} identified a {} model with {} mode(s) from {} samples in {:.3} s -> {}",
        backend.name(),
        model.kind(),
        model.mode_count(),
        data.len(),
        elapsed.as_secs_f64(),
        args.out.display()
    );
    // A run cut short (by --time-budget or an iteration bound), or one with
    // warnings, says so.
    let d = &model.info().diagnostics;
    if d.run_status.cut_short() || !d.status.is_empty() {
        eprintln!("hysid: {}: {}", backend.name(), d.status.join("; "));
    }
    match &model.info().selection {
        Some(selection) => report_selection(backend.name(), selection),
        None => crate::affine::warn_if_below(
            &model,
            &data,
            &priors,
            args.warmup,
            "its identification rows",
            "; try --auto",
        ),
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
        ", its refinements scored lower"
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
                r.fit_sim
                    .map_or_else(|| "failed".into(), |f| format!("{f:.2}"))
            })
            .collect();
        if let Some(kept) = s.refit.iter().position(|r| r.kept) {
            eprintln!(
                "hysid: --auto: refitted on all the identification rows from {} starts (FIT {} %); start {} written",
                s.refit.len(),
                fits.join(" / "),
                kept + 1
            );
        }
    }
    if chosen.method != method {
        eprintln!(
            "hysid: --auto: no {method} candidate simulated the selection rows better than the affine {} model; that model is written",
            chosen.method
        );
    }
}
