//! One module per subcommand.

use crate::error::{CliError, Result};
use hysid_core::model::Model;
use hysid_model::data::{Dataset, RowRange};
use std::path::{Path, PathBuf};

pub mod compare;
pub mod convert;
pub mod identify;
pub mod methods;
pub mod show;
pub mod simulate;
pub mod sweep;
pub mod validate;

/// Estimated initial states as `x1 = 2.5, x2 = -0.1, x3 = 2.9e-16`
/// (shortest round-trip form of each value, with an exponent where it is
/// tiny or huge).
pub(crate) fn states_text(states: &hysid_core::simulate::InitialStates) -> String {
    (states.values.iter())
        .map(|(name, v)| {
            if states.unseen.contains(name) {
                format!("{name} = {v:?} (not determined: moving it changes none of the warm-up's outputs)")
            } else if states.at_bound.contains(name) {
                format!("{name} = {v:?} (on a bound of its estimate range: the warm-up may ask for a value outside it)")
            } else {
                format!("{name} = {v:?}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Refuses a report folder `-o` that cannot take the report, or whose
/// report would replace or remove one of `inputs`
/// ([`hysid::compare::check_report_folder`]), before anything runs.
pub(crate) fn a_folder(out: &Path, inputs: &[&Path]) -> Result<()> {
    hysid::compare::check_report_folder(out, inputs)
        .map_err(|e| CliError::input(format!("-o {}: {e}", out.display())))
}

/// Refuses an output file that is one of the command's input files (the
/// same file by its resolved path), before anything runs: writing it would
/// replace the record or model it reads.
pub(crate) fn not_an_input<'a>(
    flag: &str,
    out: &Path,
    inputs: impl IntoIterator<Item = &'a Path>,
) -> Result<()> {
    let Ok(target) = std::fs::canonicalize(out) else {
        return Ok(()); // not there yet: no input can be it
    };
    for input in inputs.into_iter().flat_map(with_bases) {
        if std::fs::canonicalize(input).is_ok_and(|p| p == target) {
            return Err(CliError::input(format!(
                "{flag} {}: is an input of this command; give another file",
                out.display()
            )));
        }
    }
    Ok(())
}

/// `input` and, for a model file that extends others, the files of its
/// chain: a command reads them all.
fn with_bases(input: &Path) -> Vec<PathBuf> {
    let model_file = (input.extension().and_then(|e| e.to_str()))
        .is_some_and(|e| e.eq_ignore_ascii_case("toml") || e.eq_ignore_ascii_case("json"));
    match model_file.then(|| hysid_graybox::extends::read(input)) {
        Some(Ok(resolved)) => resolved.sources.into_iter().map(|s| s.path).collect(),
        _ => vec![input.to_path_buf()],
    }
}

/// Reads the model file `path`; a data file given in its place (the
/// arguments swapped) is named as such rather than failing to parse.
pub(crate) fn load_model(path: &Path) -> Result<Model> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_lowercase);
    if let Some(ext @ ("csv" | "mat")) = extension.as_deref() {
        return Err(CliError::input(format!(
            "{}: a data file (.{ext}) where the model file (.json or .toml) is expected; the model comes first",
            path.display()
        )));
    }
    Ok(Model::load(path)?)
}

/// A warning when the model of `file` starts from a state its file gives
/// and the record's rows start later than its first (`rows`): the state is
/// applied there, where the system may be elsewhere.
pub(crate) fn warn_given_state(file: &Path, model: &Model, rows: &[RowRange]) {
    let starts = rows.iter().filter_map(|r| r.start);
    if let Some(later) = hysid_core::simulate::GivenStateLater::of(model, starts) {
        eprintln!("hysid: warning: {}: {later}", file.display());
    }
}

/// A warning when the record's inputs are the model's in another order
/// (those it was identified on, or those its file declares): inputs are
/// read in the order given, so a swap is a different input.
pub(crate) fn warn_input_order(file: &Path, model: &Model, data: &Dataset) {
    let Some(own) = model.signal_names().inputs else {
        return;
    };
    let how = if model.info().input_names.is_empty() {
        "declares"
    } else {
        "was identified on"
    };
    warn_of_order(&own, data, &format!("{} {how}", file.display()));
}

/// A warning when the record's inputs are `own` in another order, `whose`
/// saying whose order `own` is.
pub(crate) fn warn_of_order(own: &[String], data: &Dataset, whose: &str) {
    let given = data.input_names();
    let mut sorted = (own.to_vec(), given.clone());
    sorted.0.sort();
    sorted.1.sort();
    if own.len() > 1 && own != given && sorted.0 == sorted.1 {
        eprintln!(
            "hysid: warning: the inputs are read in the order given ({}); {whose} them in the \
             order {}",
            given.join(", "),
            own.join(", ")
        );
    }
}

/// The prior file `path`, with a warning where it holds no prior (an
/// empty or all-comment file: the wrong file, or a cut one).
pub(crate) fn load_priors(path: &Path) -> crate::error::Result<hysid_core::priors::Priors> {
    let priors = hysid_core::priors::Priors::load(path)?;
    if priors == hysid_core::priors::Priors::default() {
        eprintln!("hysid: warning: {}: no prior in it", path.display());
    }
    Ok(priors)
}

/// A warning naming the definitions of the gray-box model of `file` that
/// no expression reads ([`hysid_core::simulate::UnreadDefinitions`]).
pub(crate) fn warn_unread_definitions(file: &Path, model: &Model) {
    if let Some(unread) = hysid_core::simulate::UnreadDefinitions::of(model) {
        eprintln!("hysid: warning: {}: {unread}", file.display());
    }
}

/// A warning when the discrete-time model of `file` was identified at
/// another sampling time than the record's, or the excitation's when
/// `excited` ([`hysid_core::simulate::sampling_time_mismatch`]).
pub(crate) fn warn_sampling_time(file: &Path, model: &Model, data: &Dataset, excited: bool) {
    if let Some(coarse) = hysid_core::simulate::StepScale::of(model, data) {
        eprintln!("hysid: warning: {}: {coarse}", file.display());
    }
    if let Some((record, own)) = hysid_core::simulate::sampling_time_mismatch(model, data) {
        let (what, hint) = if excited {
            (format!("the excitation's sampling time {record} s"), "")
        } else {
            (
                format!("the record's sampling time {record} s"),
                " (a --decimate or --ts left out?)",
            )
        };
        eprintln!(
            "hysid: warning: {what} differs from the {own} s {} was identified at: its lags mean \
             other times{hint}",
            file.display()
        );
    }
}
