//! `hysid simulate`: a model driven by measured inputs or a generated
//! excitation, written as CSV (`t`, inputs, `y`, `mode`).

use crate::error::CliError;
use crate::error::Result;
use crate::selection::{DataArgs, SignalDefaults};
use hysid_core::model::Model;
use hysid_core::simulate::simulate;
use hysid_model::data::{Dataset, Signal};
use hysid_model::excitation::{Excitation, ExcitationError};
use hysid_model::simulate::{SimError, SimulationOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Arguments of `hysid simulate`.
#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Model file (.json, or .toml for hand-written models).
    pub model: PathBuf,
    /// Drive the model with the inputs of this data file (its first outputs
    /// give the initial condition).
    #[arg(long, conflicts_with = "excite")]
    pub data: Option<PathBuf>,
    /// Generate the input: `n=N,hold=H,low=A,high=B[,ts=SECONDS][,inputs=M]`,
    /// levels uniform on [A, B] held for H samples (the founding paper's input).
    #[arg(long)]
    pub excite: Option<String>,
    /// Initial output value before the first simulated sample (with
    /// --excite; 0 when not given).
    #[arg(long)]
    pub y0: Option<f64>,
    /// Start from this state at sample 0, in place of the model file's
    /// initial-state rule: a value for every state, `NAME=V,NAME=V`
    /// (`--x0 y=0.5,v=0`); state-space and physical models.
    #[arg(long, value_name = "NAME=V,..", value_parser = parse_state, conflicts_with = "y0")]
    pub x0: Option<BTreeMap<String, f64>>,
    /// Standard deviation of white Gaussian noise added to the written output.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Seed of the excitation and of the noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output CSV file.
    #[arg(short = 'o', long = "out", value_name = "OUT.csv")]
    pub out: PathBuf,
    #[command(flatten)]
    pub select: DataArgs,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let y0 = checked_numbers(&args)?;
    let inputs = std::iter::once(&args.model).chain(&args.data);
    super::not_an_input("-o", &args.out, inputs.map(PathBuf::as_path))?;
    csv_name(&args.out)?;
    let model = super::load_model(&args.model)?;
    let model = match &args.x0 {
        Some(state) => {
            (model.starting_from(state)).map_err(|e| CliError::input(format!("--x0: {e}")))?
        }
        None => {
            super::warn_given_state(&args.model, &model, &args.select.rows);
            model
        }
    };
    let data = driving_record(&args, &model, y0)?;
    super::warn_sampling_time(&args.model, &model, &data, args.excite.is_some());
    super::warn_unread_definitions(&args.model, &model);
    super::warn_input_order(&args.model, &model, &data);
    if let Some(y0) = args.y0
        && model.initial_state_given()
    {
        eprintln!(
            "hysid: warning: --y0 {y0} is not read: {} gives the initial state",
            args.model.display()
        );
    }
    // A record too short for the model is named by its file and rows.
    let failed = |e: SimError| match (&e, &args.data) {
        (SimError::TooShort { .. }, Some(path)) => {
            let rows = (args.select.rows_of(0))
                .map(|r| format!(" --rows {r}"))
                .unwrap_or_default();
            CliError::input(format!("{}{rows}: {e}", path.display()))
        }
        _ => CliError::simulation(&args.model, e),
    };
    let sim = simulate(&model, &data, SimulationOptions::default()).map_err(failed)?;
    let states = hysid_core::simulate::initial_states(&model, &data).map_err(failed)?;
    if !states.values.is_empty() {
        let warmup = if args.data.is_some() {
            "the warm-up".to_string()
        } else {
            format!("the warm-up, its output held at --y0 {y0}")
        };
        eprintln!(
            "hysid: initial state estimated from {warmup}: {}",
            super::states_text(&states)
        );
    }
    let physical = matches!(model, Model::GrayBox(_) | Model::Mechanical(_));
    if args.excite.is_some() && physical && sim.start > 0 && states.values.is_empty() {
        // The rows before the run's start are the warm-up a physical
        // model's initial state reads, not a response to the input beside
        // them (a record to fit with an estimated state starts after them).
        // A rule that estimates states runs from sample 0: every row is
        // simulated.
        eprintln!(
            "hysid: the run starts at row {}: the rows before it hold --y0 {} (what the model's \
             initial state reads), not a response to their input",
            sim.start, y0
        );
    }
    if let Some(outside) = hysid_core::simulate::OutsideRegions::of(&model, &sim) {
        eprintln!("hysid: warning: {outside}");
    }
    for warning in sim.warnings() {
        eprintln!("hysid: warning: {warning}");
    }
    let mut y = sim.y.clone();
    if args.noise > 0.0 {
        let mut rng = ChaCha8Rng::seed_from_u64(args.seed ^ 0x9E37_79B9_7F4A_7C15);
        let normal =
            Normal::new(0.0, args.noise).map_err(|e| CliError::input(format!("--noise: {e}")))?;
        for v in &mut y {
            *v += normal.sample(&mut rng);
        }
    }
    let names = model.mode_names();
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = Vec::new();
    if data.ts.is_some() {
        header.push("t".into());
    }
    header.extend(data.input_names());
    header.push("y".into());
    header.push("mode".into());
    let io = |e: csv::Error| CliError::failure(format!("writing CSV: {e}"));
    w.write_record(&header).map_err(io)?;
    // With --data, `t` is the time of the sample in the record: the first
    // selected row is row `first` of the file (after decimation), as the
    // figures of `compare` count it.
    let first = if args.data.is_some() {
        args.select.selection()?.rows.start.unwrap_or(0)
    } else {
        0
    };
    for (k, yk) in y.iter().enumerate() {
        let mut row: Vec<String> = Vec::with_capacity(header.len());
        if let Some(ts) = data.ts {
            row.push(time_text(first + k, ts));
        }
        for i in 0..data.inputs.len() {
            row.push(format!("{}", data.u(i)[k]));
        }
        row.push(format!("{yk}"));
        row.push(sim.modes[k].map(|q| names[q].clone()).unwrap_or_default());
        w.write_record(&row).map_err(io)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| CliError::failure(format!("writing CSV: {e}")))?;
    hysid_io::write(&args.out, &bytes)
        .map_err(|e| CliError::input(format!("{}: {e}", args.out.display())))?;
    eprintln!(
        "hysid: simulated {} samples -> {}",
        data.len(),
        args.out.display()
    );
    Ok(())
}

/// `--x0`'s `NAME=V,NAME=V`: each name once, each value a number (the
/// model checks that it is finite, [`Model::starting_from`]).
fn parse_state(s: &str) -> std::result::Result<BTreeMap<String, f64>, String> {
    let mut state = BTreeMap::new();
    for part in s.split(',') {
        let Some((name, value)) = part.split_once('=') else {
            return Err(format!("'{part}' is not NAME=VALUE"));
        };
        let name = name.trim();
        let value = (value.trim().parse::<f64>())
            .map_err(|_| format!("'{part}': the value must be a number"))?;
        if name.is_empty() {
            return Err(format!("'{part}': a state name is missing"));
        }
        if state.insert(name.to_string(), value).is_some() {
            return Err(format!("'{name}' is given twice"));
        }
    }
    Ok(state)
}

/// `--noise` and `--y0` checked; the output before the first simulated
/// sample (`--y0`, 0 when not given).
fn checked_numbers(args: &Args) -> Result<f64> {
    if !(args.noise.is_finite() && args.noise >= 0.0) {
        return Err(CliError::input(format!(
            "--noise {}: must be a finite number >= 0",
            args.noise
        )));
    }
    if let Some(y0) = args.y0 {
        if !y0.is_finite() {
            return Err(CliError::input(format!(
                "--y0 {y0}: must be a finite number"
            )));
        }
        if args.data.is_some() {
            return Err(CliError::input(format!(
                "--y0 {y0}: only with --excite (with --data the record's first outputs are the \
                 initial condition)"
            )));
        }
    }
    Ok(args.y0.unwrap_or(0.0))
}

/// The record that drives the model: `--data`, read by the model's signal
/// names where it lacks `u` or `y`, or the `--excite` input with its
/// output held at `y0`.
fn driving_record(args: &Args, model: &Model, y0: f64) -> Result<Dataset> {
    let select = args.select.clone().reading(SignalDefaults::of_model(model));
    match (&args.data, &args.excite) {
        (Some(path), None) => select.load_one(path),
        (None, Some(spec)) => {
            let e = Excitation::parse_for(spec, model.inputs())
                .map_err(|e: ExcitationError| CliError::input(e.to_string()))?;
            if e.inputs != model.inputs() {
                return Err(CliError::input(format!(
                    "--excite inputs={}: the model has {} input(s)",
                    e.inputs,
                    model.inputs()
                )));
            }
            let names = input_names(model);
            let inputs = e
                .generate(args.seed)
                .into_iter()
                .zip(names)
                .map(|(values, name)| Signal { name, values })
                .collect();
            if let (Some(a), Some(b)) = (e.ts, args.select.signals.ts)
                && a != b
            {
                return Err(CliError::input(format!(
                    "--excite ts={a} and --ts {b}: two sampling times; give one"
                )));
            }
            let ts = e.ts.or(args.select.signals.ts).or(model.info().ts);
            let y = Signal {
                name: "y".into(),
                values: vec![y0; e.n],
            };
            Ok(Dataset::new(inputs, y, ts)?)
        }
        _ => Err(CliError::input(
            "give exactly one of --data DATA or --excite SPEC",
        )),
    }
}

/// `k ts` with as many decimals as `ts` has (at most 12), without the
/// rounding residue of the product (`14.995`, not `14.995000000000001`);
/// a `ts` of more decimals in full, so that the times still increase.
fn time_text(k: usize, ts: f64) -> String {
    let Some(decimals) = (0..=12).find(|&d| {
        let scaled = ts * 10f64.powi(d);
        (scaled - scaled.round()).abs() <= 1e-9 * scaled.abs()
    }) else {
        return format!("{}", k as f64 * ts);
    };
    let text = format!("{:.*}", decimals as usize, k as f64 * ts);
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

fn input_names(model: &Model) -> Vec<String> {
    let m = model.inputs();
    match model.signal_names().inputs {
        Some(names) => names,
        None if m == 1 => vec![hysid_model::data::DEFAULT_INPUT.into()],
        None => (1..=m).map(|i| format!("u{i}")).collect(),
    }
}

/// Refuses an output name that says another format than the CSV written
/// (`.mat`, `.json`, `.toml`): it would be misread.
fn csv_name(out: &std::path::Path) -> Result<()> {
    let extension = (out.extension()).map(|e| e.to_string_lossy().to_ascii_lowercase());
    match extension.filter(|e| ["mat", "json", "toml"].contains(&e.as_str())) {
        Some(e) => Err(CliError::input(format!(
            "-o {}: simulate writes CSV; name the file .csv, not .{e}",
            out.display()
        ))),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::time_text;

    #[test]
    fn times_have_the_decimals_of_the_sampling_time() {
        assert_eq!(time_text(2999, 0.005), "14.995");
        assert_eq!(time_text(3, 0.1), "0.3");
        assert_eq!(time_text(7, 2.0), "14");
        assert_eq!(time_text(0, 0.01), "0");
        // More decimals than 12: in full, still increasing.
        let times: Vec<f64> = (0..4)
            .map(|k| time_text(k, 1e-13).parse().unwrap())
            .collect();
        assert!(times.windows(2).all(|w| w[0] < w[1]), "{times:?}");
    }
}
