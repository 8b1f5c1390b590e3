//! `hysid compare`: several back-ends side by side on one experiment.

use crate::error::CliError;
use crate::error::Result;
use crate::progress::TerminalProgress;
use hysid::compare::{Experiment, FigureFormat};
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
    super::a_folder(&dir)?;
    for w in exp.warnings() {
        eprintln!("hysid: warning: {}: {w}", args.experiment.display());
    }
    let progress = TerminalProgress::new();
    let mut comparison = exp
        .run(&progress)
        .map_err(|e| CliError::input(format!("{}: {e}", args.experiment.display())))?;
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
