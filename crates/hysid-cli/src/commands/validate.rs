//! `hysid validate`: scores of a model on a record, or on several records
//! (each, and all together).

use crate::error::CliError;
use crate::error::Result;
use crate::selection::{DataArgs, SignalDefaults};
use hysid::plot::{FigureFormat, SimulationFigure};
use hysid_core::priors::Priors;
use hysid_core::simulate::{ValidationReport, validate};
use std::path::PathBuf;

/// Arguments of `hysid validate`.
#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Model file (.json, or .toml for hand-written models).
    pub model: PathBuf,
    /// Data file(s) (.csv or .mat).
    ///
    /// Several files are records of one system: each is scored from its
    /// own initial state and warm-up, and all together.
    #[arg(required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Samples at the start that are not scored.
    #[arg(long, default_value_t = 10, value_parser = crate::selection::parse_count)]
    pub warmup: usize,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Also draw the measured and simulated output (and the input) into
    /// this figure: FILE.svg, or FILE.png in a build with the png feature.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub select: DataArgs,
}

/// Runs the command.
pub fn run(mut args: Args) -> Result<()> {
    if let Some(plot) = &args.plot {
        let inputs = std::iter::once(&args.model).chain(&args.data);
        super::not_an_input("--plot", plot, inputs.map(PathBuf::as_path))?;
    }
    let model = super::load_model(&args.model)?;
    args.select = args.select.reading(SignalDefaults::of_model(&model));
    let data = args.select.load(&args.data)?;
    for (file, range) in args.data.iter().zip(data.record_ranges()) {
        if args.warmup >= range.len() {
            return Err(CliError::input(format!(
                "--warmup {} leaves no sample to score: {} has {} samples after selection",
                args.warmup,
                file.display(),
                range.len()
            )));
        }
    }
    // A figure this build cannot write is refused before any work.
    if let Some(path) = &args.plot {
        FigureFormat::of_path(path).map_err(|e| CliError::input(format!("--plot: {e}")))?;
    }
    super::warn_sampling_time(&args.model, &model, &data, false);
    super::warn_unread_definitions(&args.model, &model);
    super::warn_input_order(&args.model, &model, &data);
    super::warn_given_state(&args.model, &model, &args.select.rows);
    let (report, sim, _) =
        validate(&model, &data, args.warmup).map_err(|e| CliError::simulation(&args.model, e))?;
    if let Some(path) = &args.plot {
        let first_row = args.select.first_row();
        let figure = SimulationFigure::from_dataset(
            format!("{}: fit_sim {:.1} %", args.model.display(), report.fit_sim),
            &data,
            first_row,
            data.output.name.clone(),
            "input",
        )
        .with_warmup(args.warmup)
        .with_simulation("simulated", &sim);
        hysid::plot::simulation_plot(path, &figure)
            .map_err(|e| CliError::input(format!("--plot: {e}")))?;
    }
    for warning in report.warnings() {
        eprintln!("hysid: warning: {warning}");
    }
    crate::affine::warn_if_below(
        &model,
        &data,
        &Priors::default(),
        args.warmup,
        "these rows",
        "",
    );
    if args.json {
        // Each record's report names its file and rows, as the text does.
        let mut json = serde_json::to_value(&report).expect("json");
        if let Some(records) = json.get_mut("records").and_then(|r| r.as_array_mut()) {
            for (i, (r, file)) in records.iter_mut().zip(&args.data).enumerate() {
                r["file"] = file.display().to_string().into();
                if let Some(rows) = args.select.rows_of(i) {
                    r["rows"] = rows.to_string().into();
                }
            }
        }
        println!("{json}");
    } else {
        println!(
            "model     {} ({} mode(s), {})",
            args.model.display(),
            model.mode_count(),
            model.kind()
        );
        println!(
            "scored    {} samples ({})",
            report.n,
            left_out(&report, data.len())
        );
        println!(
            "fit_sim   {:8.3} %   rmse_sim  {:.6}",
            unsigned_zero(report.fit_sim),
            report.rmse_sim
        );
        println!(
            "fit_pred  {:8.3} %   rmse_pred {:.6}",
            unsigned_zero(report.fit_pred),
            report.rmse_pred
        );
        println!(
            "coverage  {:8.4}     coverage_sim {:.4}",
            report.coverage, report.coverage_sim
        );
        let counts = (model.mode_names().iter())
            .zip(&report.mode_counts)
            .map(|(name, count)| format!("{name} {count}"))
            .collect::<Vec<_>>();
        println!(
            "modes     {} (scored samples per mode in the simulation)",
            counts.join(", ")
        );
        if !report.initial.values.is_empty() {
            println!(
                "initial   {} (estimated from the warm-up)",
                super::states_text(&report.initial)
            );
        }
        for (file, r) in args.data.iter().zip(&report.records) {
            print!(
                "record    {}: fit_sim {:.3} %  rmse_sim {:.6}  fit_pred {:.3} %  ({} samples)",
                file.display(),
                unsigned_zero(r.fit_sim),
                r.rmse_sim,
                unsigned_zero(r.fit_pred),
                r.n
            );
            if !r.initial.values.is_empty() {
                print!("  initial {}", super::states_text(&r.initial));
            }
            println!();
        }
    }
    Ok(())
}

/// `v`, or `0.0` when it shows as zero with three decimals: a FIT of
/// `-1e-13` (a constant model, up to rounding) prints `0.000`, not `-0.000`.
fn unsigned_zero(v: f64) -> f64 {
    if (v * 1e3).round() == 0.0 { 0.0 } else { v }
}

/// The samples `report` leaves out of a record of `len` samples: the
/// warm-up asked for, and the samples the model's initial state reads
/// where it reads more (an ARX history, a gray-box warm-up).
fn left_out(report: &ValidationReport, len: usize) -> String {
    let records = report.records.len().max(1);
    let read = len.saturating_sub(report.n);
    if read > report.warmup * records {
        let all = if records > 1 { " in all" } else { "" };
        format!(
            "warm-up {}; {read} samples left out{all}: the model's initial state reads them",
            report.warmup
        )
    } else {
        format!("warm-up {}", report.warmup)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_fit_that_rounds_to_zero_prints_without_sign() {
        assert_eq!(format!("{:.3}", super::unsigned_zero(-1e-13)), "0.000");
        assert_eq!(format!("{:.3}", super::unsigned_zero(-0.0)), "0.000");
        assert_eq!(format!("{:.3}", super::unsigned_zero(-0.002)), "-0.002");
    }
}
