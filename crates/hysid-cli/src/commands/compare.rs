//! `hysid compare`: several back-ends side by side on one experiment.

use crate::error::CliError;
use crate::error::Result;
use crate::progress::TerminalProgress;
use hysid::compare::{Experiment, ExperimentError, FigureFormat};
use hysid_model::data::DataError;
use std::path::PathBuf;

/// Arguments of `hysid compare`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Experiment file (TOML), see docs/compare.md.
    pub experiment: PathBuf,
    /// Output folder for report.md, report.json and models/ (default: `out/<experiment file name without .toml>`).
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// File format of the figures: svg (default) or png (to paste; text in
    /// an embedded font).
    #[arg(long, default_value = "svg", value_parser = parse_format)]
    pub format: FigureFormat,
}

fn parse_format(s: &str) -> std::result::Result<FigureFormat, String> {
    let format: FigureFormat = s.parse()?;
    if !format.is_built() {
        return Err(format!(
            "'{s}': this hysid was built without PNG figures (cargo install --path crates/hysid-cli --features png)"
        ));
    }
    Ok(format)
}

/// Where a record lacks an input the experiment reads, the inputs a run's
/// model file declares, for the user to name in `[data] input`.
fn model_inputs_hint(exp: &Experiment, e: &ExperimentError) -> Option<String> {
    let ExperimentError::Data {
        source: DataError::Missing { name, .. },
        ..
    } = e
    else {
        return None;
    };
    let records = exp
        .data
        .records
        .iter()
        .flat_map(|r| r.input.iter().flatten());
    let an_input = exp.data.input.iter().chain(records).any(|i| i == name);
    let (run, inputs) =
        (exp.declared_inputs()).filter(|(_, own)| an_input && !own.contains(name))?;
    Some(format!(
        "; the model file of '{}' declares the inputs {}: name the record's in [data] input",
        run.name,
        inputs.join(", ")
    ))
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let exp = Experiment::load(&args.experiment).map_err(|e| CliError::input(e.to_string()))?;
    let dir = args.out.unwrap_or_else(|| {
        let stem = args
            .experiment
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        PathBuf::from("out").join(stem)
    });
    let inputs = [exp.input_files(), vec![args.experiment.as_path()]].concat();
    super::a_folder(&dir, &inputs)?;
    for w in exp.warnings() {
        eprintln!("hysid: warning: {}: {w}", args.experiment.display());
    }
    let progress = TerminalProgress::new();
    let mut comparison = exp.run(&progress).map_err(|e| {
        let hint = model_inputs_hint(&exp, &e).unwrap_or_default();
        CliError::input(format!("{}: {e}{hint}", args.experiment.display()))
    })?;
    // The record has the inputs read: the run read them.
    if let Some(w) = exp.unread_declared_inputs() {
        eprintln!("hysid: warning: {}: {w}", args.experiment.display());
    }
    if let Some(w) = hysid::compare::constant_output(&comparison.results) {
        eprintln!("hysid: warning: {}: {w}", args.experiment.display());
    }
    comparison.figures = args.format;
    hysid::compare::write_report(&mut comparison, &dir)
        .map_err(|e| CliError::failure(format!("{}: {e}", dir.display())))?;
    print!("{}", hysid::compare::report::markdown(&comparison));
    eprintln!(
        "hysid: report written to {}",
        dir.join("report.md").display()
    );
    let failed = comparison
        .results
        .iter()
        .filter(|r| r.error.is_some())
        .count();
    if failed == comparison.results.len() {
        return Err(CliError::failure("every run failed; see the report"));
    }
    Ok(())
}
