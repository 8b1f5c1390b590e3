//! `hysid sweep`: one back-end over a grid of option values (for example
//! the local dataset size `c` and the mode count of `cluster`, or `delta`
//! of `bounded`), each point scored by free-run simulation FIT on the
//! selection rows. It is an experiment with one `[[sweep]]`, built from the
//! command line; several data files are records of one system, as an
//! experiment file's `[[data.records]]`. Its best point is a choice made on
//! those rows: scored on test rows, it is an oracle figure.

use crate::error::CliError;
use crate::error::Result;
use crate::progress::TerminalProgress;
use crate::selection::{DataArgs, SignalArgs, SignalDefaults};
use hysid::compare::experiment::MODEL_FILE_OPTION;
use hysid::compare::{
    DataEntry, DataPart, DataSpec, Experiment, ExperimentError, ExperimentWarning, Origin,
    RecordSpec, RunSpec, ScoredRows, SweepSpec,
};
use hysid::select::GivenBesideGrid;
use hysid_core::model::SignalNames;
use hysid_core::options::Settings;
use hysid_core::priors::{ModeCountNeed, Priors};
use hysid_core::search::{SearchSpace, Setup};
use hysid_model::data::RowRange;
use hysid_model::regressors::RegressorSpec;
use std::path::{Path, PathBuf};

/// Arguments of `hysid sweep`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Data file(s) (.csv or .mat): several are records of one system, one
    /// model fitted on all, every point scored on all.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Back-end (see `hysid methods`).
    #[arg(short = 'm', long = "method")]
    pub method: String,
    /// Grid axis KEY=V1,V2,... (repeatable): a back-end option, or modes, na, nb.
    #[arg(long = "grid", value_name = "KEY=V1,V2,..", required = true)]
    pub grid: Vec<String>,
    /// Rows used for identification (after decimation); with several data
    /// files, once for every file or once per file.
    #[arg(long = "identify-rows", required = true, allow_hyphen_values = true)]
    pub identify_rows: Vec<RowRange>,
    /// Rows every point is scored on (after decimation): selection rows
    /// when the sweep chooses options (outside --identify-rows and away
    /// from the test rows); `--validate-rows` is the same flag. With
    /// several data files, once for every file or once per file.
    #[arg(
        long = "select-rows",
        alias = "validate-rows",
        required = true,
        allow_hyphen_values = true
    )]
    pub select_rows: Vec<RowRange>,
    /// Scored samples left out at the start.
    #[arg(long, default_value_t = 10, value_parser = crate::selection::parse_count)]
    pub warmup: usize,
    /// Output lags [default: 2], unless swept.
    #[arg(long)]
    pub na: Option<usize>,
    /// Input lags [default: 2], unless swept.
    #[arg(long)]
    pub nb: Option<usize>,
    /// Number of modes (the prior `modes`), unless swept.
    #[arg(long)]
    pub modes: Option<usize>,
    /// Prior file (TOML, or JSON named .json).
    #[arg(long)]
    pub prior: Option<PathBuf>,
    /// Fixed back-end option KEY=VALUE (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Seed of every run.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also write report.md, report.json and the models into this folder.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub signals: SignalArgs,
}

impl Args {
    /// The identification and selection rows of data file `i` (from 0).
    fn rows_of(&self, i: usize) -> (RowRange, RowRange) {
        let of = |rows: &[RowRange]| rows.get(i).or(rows.first()).copied().unwrap_or_default();
        (of(&self.identify_rows), of(&self.select_rows))
    }

    /// The data file of `entry`.
    fn file_of(&self, entry: DataEntry) -> &Path {
        let i = match entry {
            DataEntry::Main => 0,
            DataEntry::Record(k) => k,
        };
        self.data.get(i).unwrap_or(&self.data[0])
    }

    /// The orders `na`, `nb` of the points that do not sweep them.
    fn orders(&self) -> (usize, usize) {
        (
            self.na.unwrap_or(DEFAULT_ORDER),
            self.nb.unwrap_or(DEFAULT_ORDER),
        )
    }
}

/// `--na` and `--nb` where they are not given.
const DEFAULT_ORDER: usize = 2;

/// Refuses, before anything runs, a grid point the back-end would refuse:
/// a key that `--set`, `--modes` or the prior file's `modes` also fixes, a
/// key that is neither one of its options nor `modes`, `na` or `nb`, a
/// value it does not take
/// ([`hysid::select::candidate_setups`]), and the priors as the back-end
/// checks them without data. An unknown
/// method is left to the experiment's own check, which names the known ones.
fn check_grid(
    args: &Args,
    given: &Settings,
    signals: &SignalArgs,
    priors: &Priors,
    space: &SearchSpace,
) -> Result<()> {
    let origin = args.prior.as_ref().map(|p| p.display().to_string());
    let origin = origin.as_deref();
    let beside = GivenBesideGrid {
        options: given,
        modes: args.modes,
        prior_modes: priors.modes,
        priors_origin: origin,
        orders: [args.na, args.nb],
    };
    beside.check(space)?;
    let registry = hysid::registry();
    let Some(backend) = registry.get(&args.method) else {
        return Ok(());
    };
    let setup = Setup {
        orders: RegressorSpec::new(args.orders().0, args.orders().1, signals.inputs().len()),
        priors: priors.clone(),
        settings: given.clone(),
    };
    // The priors as the back-end checks them at every point (whose
    // orders may be swept), named by their file.
    (priors.ensure_honoured(backend.name(), backend.honours(), origin))?;
    for (_, point) in hysid::select::candidate_setups(backend, &setup, space)? {
        // A swept mode count is a prior of every point.
        (point
            .priors
            .ensure_honoured(backend.name(), backend.honours(), None))
        .map_err(|e| CliError::input(format!("--grid modes: {e}")))?;
        (backend.check_priors(&point.settings, &point.priors, point.orders, origin))
            .map_err(|e| CliError::input(e.to_string()))?;
        let need = backend.mode_count_need(&point.settings);
        if !need.met_by(&point.priors) {
            let (prior, bound) = match need {
                ModeCountNeed::Count => ("modes = S", crate::error::NO_COUNT_FROM_A_BOUND),
                _ => ("modes = S / max_modes = S", ""),
            };
            return Err(CliError::input(format!(
                "method '{}' needs the number of modes: --modes S, --grid modes=S1,S2,.., or \
                 {prior} in the prior file{bound}",
                backend.name(),
            )));
        }
    }
    Ok(())
}

/// The signals the sweep reads: the flags' (`u` and `y` where they name
/// none) or, where the method's model file (`given`'s) declares inputs and
/// the record lacks `u`, those, read as `identify` reads them and named.
fn signals_read(args: &Args, given: &Settings) -> Result<SignalArgs> {
    let declared = hysid::registry()
        .require(&args.method)?
        .declared_signals(given)?;
    // Without a model file's names the flags' names are checked here and
    // the record is read once, by the sweep.
    if declared == SignalNames::default() {
        args.signals.selection(RowRange::default())?;
        return Ok(args.signals.clone());
    }
    let record = DataArgs {
        signals: args.signals.clone(),
        rows: Vec::new(),
    };
    let data =
        (record.reading(SignalDefaults::declared(declared.clone()))).load_one(&args.data[0])?;
    if let Some(own) = &declared.inputs {
        super::warn_of_order(own, &data, "the model file names");
    }
    Ok(SignalArgs {
        input: Some(data.input_names()),
        output: Some(data.output.name.clone()),
        ..args.signals.clone()
    })
}

/// The sweep: the method over `space`, with the options `given`; the
/// first axis is its `vary`, the one its figure is drawn against (the
/// others' order does not matter).
fn sweep_spec(args: &Args, given: &Settings, space: &SearchSpace) -> Result<SweepSpec> {
    let text = |v: &str| toml::Value::String(v.to_string());
    let set = given
        .pairs()
        .iter()
        .map(|(k, v)| (k.clone(), text(v)))
        .collect();
    let Some((first, others)) = space.axes.split_first() else {
        return Err(CliError::input("--grid: give at least one axis"));
    };
    let grid = others
        .iter()
        .map(|a| (a.key.clone(), a.values.iter().map(|v| text(v)).collect()))
        .collect();
    Ok(SweepSpec {
        run: RunSpec {
            name: args.method.clone(),
            method: args.method.clone(),
            na: None,
            nb: None,
            modes: None,
            use_priors: true,
            priors: None,
            set,
            seed: None,
            seeds: vec![],
            auto: false,
            provenance: None,
        },
        vary: Some(first.key.clone()),
        values: first.values.iter().map(|v| text(v)).collect(),
        grid,
    })
}

/// The experiment the sweep is: `sweep` on the command line's records
/// (the first as `[data]`, the others as `[[data.records]]`), scored on
/// their selection rows.
fn experiment(args: &Args, signals: &SignalArgs, priors: Priors, sweep: SweepSpec) -> Experiment {
    let files: Vec<String> = args.data.iter().map(|f| f.display().to_string()).collect();
    let (identification, validation) = args.rows_of(0);
    let records = (args.data.iter().enumerate().skip(1))
        .map(|(i, file)| {
            let (identification, validation) = args.rows_of(i);
            RecordSpec {
                file: file.clone(),
                input: None,
                output: None,
                identification: Some(identification),
                validation: Some(validation),
            }
        })
        .collect();
    Experiment {
        title: format!("{} sweep on {}", args.method, files.join(", ")),
        description: String::new(),
        data: DataSpec {
            file: args.data[0].clone(),
            input: signals.inputs(),
            input_named: signals.input.is_some(),
            output: signals.output(),
            decimate: args.signals.decimate,
            ts: args.signals.ts,
            time: args.signals.time.clone(),
            identification: Some(identification),
            validation: Some(validation),
            warmup: args.warmup,
            selection: None,
            folds: None,
            select_records: None,
            records,
            refit_starts: hysid::select::DEFAULT_REFIT_STARTS,
            output_label: None,
            input_label: None,
            truth: None,
        },
        na: args.orders().0,
        nb: args.orders().1,
        seed: args.seed,
        priors,
        runs: vec![],
        scored_rows: ScoredRows::Selection,
        sweeps: vec![sweep],
    }
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    for (flag, rows) in [
        ("--identify-rows", &args.identify_rows),
        ("--select-rows", &args.select_rows),
    ] {
        crate::selection::once_or_per_file(flag, rows.len(), args.data.len())?;
    }
    let given = Settings::parse(&args.set)?;
    let space =
        SearchSpace::parse_grid(&args.grid).map_err(|e| CliError::input(e.render("--grid")))?;
    let sweep = sweep_spec(&args, &given, &space)?;
    // The model files: `--set model=FILE`, or those of `--grid model=..`.
    let models: Vec<&Path> = sweep.model_files().collect();
    if let Some(dir) = &args.out {
        let inputs: Vec<&Path> = (args.data.iter().map(PathBuf::as_path))
            .chain(args.prior.as_deref())
            .chain(models.iter().copied())
            .collect();
        super::a_folder(dir, &inputs)?;
    }
    let mut priors = match &args.prior {
        Some(p) => super::load_priors(p)?,
        None => Priors::default(),
    };
    if args.modes.is_some() {
        priors.modes = args.modes;
    }
    // The inputs are those the first model file declares.
    let first_model = match (given.get(MODEL_FILE_OPTION), models.first()) {
        (None, Some(file)) => given.with(MODEL_FILE_OPTION, &file.display().to_string()),
        _ => given.clone(),
    };
    let signals = signals_read(&args, &first_model)?;
    check_grid(&args, &given, &signals, &priors, &space)?;
    let exp = experiment(&args, &signals, priors, sweep);
    exp.check().map_err(|e| CliError::input(e.to_string()))?;
    // The points are scored on the selection rows: rows they were fitted
    // on would score them on what they have seen.
    let overlap = exp.warnings().into_iter().find_map(|w| match w {
        ExperimentWarning::ValidationOverlaps {
            entry,
            identification,
            validation,
            ..
        } => Some((entry, identification, validation)),
        _ => None,
    });
    if let Some((entry, identification, validation)) = overlap {
        let of = match args.data.len() {
            1 => String::new(),
            _ => format!(" of {}", args.file_of(entry).display()),
        };
        return Err(CliError::input(format!(
            "--select-rows {validation} overlap --identify-rows {identification}{of}: the points \
             would be scored on rows they were fitted on"
        )));
    }
    let progress = TerminalProgress::new();
    let mut comparison = exp.run(&progress).map_err(|e| match e {
        // The record is the command line's: no `[data]` to name.
        ExperimentError::Data { source, .. } => signals.data_error(source),
        e => CliError::input(match &e {
            ExperimentError::Rows { part, source, .. } => {
                let flag = match part {
                    DataPart::Identification => "--identify-rows",
                    DataPart::Scored => "--select-rows",
                };
                source.rows_named(flag).unwrap_or_else(|| e.to_string())
            }
            ExperimentError::Warmup {
                warmup, samples, ..
            } => format!(
                "--warmup {warmup}: the selection rows hold {samples} samples, none scored after the warm-up"
            ),
            _ => e.to_string(),
        }),
    })?;
    if let Some(dir) = &args.out {
        hysid::compare::write_report(&mut comparison, dir)
            .map_err(|e| CliError::failure(format!("{}: {e}", dir.display())))?;
        eprintln!(
            "hysid: report written to {}",
            dir.join("report.md").display()
        );
    }
    print!("{}", hysid::compare::report::markdown(&comparison));
    if let Some(first) = comparison
        .results
        .iter()
        .map(|r| r.error.as_deref())
        .collect::<Option<Vec<&str>>>()
        .and_then(|errors| errors.first().copied())
    {
        return Err(CliError::failure(format!(
            "every point of the sweep failed (the first: {first})"
        )));
    }
    if let Some((best, fit)) = comparison
        .results
        .iter()
        .find(|r| r.origin == Origin::SweepBest)
        .and_then(|r| Some((r, r.report.as_ref()?.fit_sim)))
    {
        eprintln!(
            "hysid: best fit_sim {fit:.2} % at {} (on the rows it was chosen on: quote it only if they are selection rows, else as an oracle figure)",
            best.name
        );
    }
    Ok(())
}
