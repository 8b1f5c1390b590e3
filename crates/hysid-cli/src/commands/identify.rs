//! `hysid identify`: one back-end on one record.

use crate::Result;
use crate::error::CliError;
use crate::progress::TerminalProgress;
use crate::selection::DataArgs;
use hysid_core::backend::{Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::run_standardized;
use hysid_model::regressors::RegressorSpec;
use std::path::PathBuf;
use std::time::{Duration, Instant};

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
    #[command(flatten)]
    pub select: DataArgs,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let registry = hysid_backends::registry();
    let backend = registry.require(&args.method)?;
    let settings = Settings::parse(&args.set)?;
    let mut priors = match &args.prior {
        Some(p) => Priors::load(p)?,
        None => Priors::default(),
    };
    if let Some(s) = args.modes {
        if s == 0 {
            return Err(CliError::input("--modes must be at least 1"));
        }
        priors.modes = Some(s);
        priors
            .check()
            .map_err(|e| CliError::input(format!("--modes {s}: {e}")))?;
    }
    let deadline = match args.time_budget {
        // A budget too long to represent (`Duration` ends near 1.8e19 s, an
        // `Instant` may end sooner) is no deadline at all.
        Some(t) if t.is_finite() && t > 0.0 => Duration::try_from_secs_f64(t)
            .ok()
            .and_then(|d| Instant::now().checked_add(d)),
        Some(t) => {
            return Err(CliError::input(format!(
                "--time-budget {t}: must be a positive number of seconds"
            )));
        }
        None => None,
    };
    let data = hysid_io::load(&args.data, &args.select.selection()?)?;
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
    let model = if args.standardize {
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
    Ok(())
}
