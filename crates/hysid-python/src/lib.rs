//! # hysid-python
//!
//! The extension module `hysid._hysid` of the Python package `hysid`
//! (`python/hysid/`): identification, simulation, validation and
//! comparison on numpy arrays, through the library calls the `hysid`
//! program makes, with its model files, priors, options and one-line
//! errors (`hysid.InputError` for bad input, `hysid.MethodError` for a
//! method that failed, both `hysid.HysidError`; module `error`).
//! Identification runs without the GIL and stops cleanly on Ctrl-C (module
//! `interrupt`).

mod args;
mod error;
mod interrupt;
mod model;
mod record;

use error::Failure;
use hysid::identify::{Auto, Identify, Mode};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::search::SearchSpace;
use hysid_model::data::{DEFAULT_TIME, DataSelection, Dataset, RowRange};
use model::Model;
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::ffi::CString;
use std::path::PathBuf;

/// `text` (JSON) as Python objects.
pub(crate) fn json<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// A `UserWarning` with `text`, attributed to the user's code.
pub(crate) fn warn(py: Python<'_>, text: &str) -> PyResult<()> {
    warn_as::<PyUserWarning>(py, text)
}

/// A warning of category `W` with `text`, attributed to the first caller
/// outside the `hysid` package ([`callers_in_package`]): the line of the
/// user's code that asked for the work, not the package's wrapper.
pub(crate) fn warn_as<W: pyo3::PyTypeInfo>(py: Python<'_>, text: &str) -> PyResult<()> {
    let text = CString::new(text).unwrap_or_default();
    let level = 1 + callers_in_package(py).unwrap_or(0);
    PyErr::warn(py, &py.get_type::<W>(), &text, level)
}

/// How many of the innermost Python frames run the `hysid` package's own
/// files (its wrappers around this extension), found from the package's
/// folder; `None` when the stack or the package cannot be read.
fn callers_in_package(py: Python<'_>) -> Option<i32> {
    let file: PathBuf = py
        .import("hysid")
        .ok()?
        .getattr("__file__")
        .ok()?
        .extract()
        .ok()?;
    let folder = file.parent()?.to_path_buf();
    let mut frame = py
        .import("sys")
        .ok()?
        .call_method1("_getframe", (0,))
        .ok()?;
    let mut count = 0;
    while !frame.is_none() {
        let name: PathBuf = frame
            .getattr("f_code")
            .ok()?
            .getattr("co_filename")
            .ok()?
            .extract()
            .ok()?;
        if !name.starts_with(&folder) {
            break;
        }
        count += 1;
        frame = frame.getattr("f_back").ok()?;
    }
    Some(count)
}

/// A `UserWarning` when `model` simulates `data` worse than the affine ARX
/// model of its orders fitted on `data` (`hysid::against_affine`), as the
/// program's `validate` warns.
pub(crate) fn warn_if_below_affine(
    py: Python<'_>,
    model: &hysid_core::model::Model,
    data: &Dataset,
    warmup: usize,
    rows: &str,
) -> PyResult<()> {
    let priors = Priors::default();
    let compared = py.detach(|| hysid::against_affine(model, data, &priors, warmup));
    match compared {
        Some(c) if c.below() => warn(py, &c.warning(rows)),
        _ => Ok(()),
    }
}

/// The back-ends as a list of dictionaries: name, summary, options (key,
/// type, default, doc), priors honoured and what `auto` tries.
#[pyfunction]
fn methods(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    let list = hysid::registry().describe();
    let text = serde_json::to_string(&list).map_err(|e| Failure::method(e.to_string()))?;
    json(py, &text)
}

/// Reads a CSV or MAT record with the program's selection rules; returns
/// `(u, y, ts)` with `u` of shape `(N, m)`.
#[pyfunction]
#[pyo3(signature = (path, inputs=None, output=None, decimate=1, rows=None, ts=None, time=None))]
#[allow(clippy::too_many_arguments)]
fn load<'py>(
    py: Python<'py>,
    path: PathBuf,
    inputs: Option<Vec<String>>,
    output: Option<String>,
    decimate: usize,
    rows: Option<String>,
    ts: Option<f64>,
    time: Option<String>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Option<f64>)> {
    if decimate == 0 {
        return Err(Failure::input("decimate=0: must be at least 1").into());
    }
    let rows = parse_rows("rows", rows.as_deref())?.unwrap_or_default();
    let selection = DataSelection {
        inputs: inputs.unwrap_or_else(|| vec!["u".into()]),
        output: output.unwrap_or_else(|| "y".into()),
        decimate,
        rows,
        ts,
        time: time.unwrap_or_else(|| DEFAULT_TIME.into()),
    };
    record::check_names(&selection, "inputs", "output")?;
    let data = py
        .detach(|| hysid_io::load(&path, &selection))
        .map_err(Failure::from)?;
    Ok((
        record::inputs_array(py, &data).into_any(),
        record::vector(py, data.y().to_vec()).into_any(),
        data.ts,
    ))
}

/// The sampling time of the times `t` of the column `name`, as the
/// program takes it from a file's time column ([`hysid_io::sampling_time`]).
#[pyfunction]
fn sampling_time(name: &str, t: Vec<f64>) -> PyResult<f64> {
    hysid_io::sampling_time(&t).map_err(|e| {
        let place = match e {
            hysid_io::TimeStepError::TooShort(_) => format!("time: column '{name}' has "),
            _ => format!("time: column '{name}', row {}: ", e.sample() + 1),
        };
        Failure::input(format!("{place}{e}")).into()
    })
}

/// A checked record as Python receives it: `(u, y, input_names,
/// output_name)`.
type CheckedRecord<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>, Vec<String>, String);

/// Checks a record as `identify` checks it (shapes, lengths, finite
/// values, the sampling time, the names); returns `(u, y, input_names,
/// output_name)` with `u` of shape `(N, m)`, `y` of shape `(N,)` and the
/// default names filled in. `hysid.Record` is made through it.
#[pyfunction]
#[pyo3(signature = (u, y, ts=None, input_names=None, output_name=None))]
fn check_record<'py>(
    py: Python<'py>,
    u: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    ts: Option<f64>,
    input_names: Option<Vec<String>>,
    output_name: Option<String>,
) -> PyResult<CheckedRecord<'py>> {
    let data = record::from_arrays(u, y, ts, input_names, output_name)?;
    if data.is_empty() {
        return Err(Failure::input("u, y: a record needs at least one sample").into());
    }
    Ok((
        record::inputs_array(py, &data).into_any(),
        record::vector(py, data.y().to_vec()).into_any(),
        data.input_names(),
        data.output.name.clone(),
    ))
}

/// A row range `A..B` given as text (the Python layer turns tuples and
/// slices into it).
fn parse_rows(name: &str, rows: Option<&str>) -> Result<Option<RowRange>, Failure> {
    rows.map(|r| {
        r.parse::<RowRange>()
            .map_err(|e| Failure::input(format!("{name}: {e}")))
    })
    .transpose()
}

/// Priors from a dictionary in the prior file's shape, or from the path of
/// a prior file (TOML).
fn priors(py: Python<'_>, given: Option<&Bound<'_, PyAny>>) -> PyResult<(Priors, Option<String>)> {
    let Some(given) = given else {
        return Ok((Priors::default(), None));
    };
    if given.is_instance_of::<PyDict>() {
        let text: String = py
            .import("json")?
            .call_method1("dumps", (given,))
            .and_then(|t| t.extract())
            .map_err(|e| {
                Failure::input(format!("priors: not expressible as a prior file ({e})"))
            })?;
        return Ok((
            Priors::from_json(&text, "priors").map_err(Failure::from)?,
            Some("priors".into()),
        ));
    }
    let path: PathBuf = given.extract().map_err(|_| {
        Failure::input("priors: expected a dictionary in the prior file's shape or a file path")
    })?;
    Ok((
        Priors::load(&path).map_err(Failure::from)?,
        Some(path.display().to_string()),
    ))
}

/// Back-end options `{key: value}` as the program's `--set key=value`:
/// booleans as `true`/`false`, `None` as `none`, numbers and text as
/// written.
fn settings(options: Option<&Bound<'_, PyDict>>) -> PyResult<Settings> {
    let mut pairs = Vec::new();
    for (k, v) in options.into_iter().flat_map(|d| d.iter()) {
        let key: String = k
            .extract()
            .map_err(|_| Failure::input(format!("options: the key {k} is not text")))?;
        let value = if let Ok(b) = v.extract::<bool>() {
            b.to_string()
        } else if v.is_none() {
            "none".to_string()
        } else if v.is_instance_of::<PyString>() {
            v.extract::<String>()?
        } else if v.extract::<f64>().is_ok() {
            v.str()?.to_string()
        } else {
            return Err(Failure::input(format!(
                "option {key}: {} is not a number, a boolean or text",
                v.repr()?
            ))
            .into());
        };
        pairs.push((key, value));
    }
    Ok(Settings::from_pairs(pairs))
}

/// Identifies a model from inputs `u` (`(N,)` or `(N, m)`) and outputs `y`
/// (`(N,)` or `(N, 1)`) with back-end `method`; the arguments are those of
/// `hysid identify` (see the package's docstrings).
#[pyfunction]
#[pyo3(signature = (
    u, y, method="cluster", na=2, nb=2, modes=None, max_modes=None, priors=None,
    options=None, seed=0, ts=None, auto=false, select_rows=None, folds=None,
    select_records=None, refit_starts=None, grid=None, warmup=10, standardize=false, time_budget=None, input_names=None,
    output_name=None
))]
#[allow(clippy::too_many_arguments)]
fn identify<'py>(
    py: Python<'py>,
    u: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    method: &str,
    na: usize,
    nb: usize,
    modes: Option<usize>,
    max_modes: Option<usize>,
    priors: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
    seed: u64,
    ts: Option<f64>,
    auto: bool,
    select_rows: Option<String>,
    folds: Option<usize>,
    select_records: Option<usize>,
    refit_starts: Option<usize>,
    grid: Option<Vec<String>>,
    warmup: usize,
    standardize: bool,
    time_budget: Option<f64>,
    input_names: Option<Vec<String>>,
    output_name: Option<String>,
) -> PyResult<Model> {
    let data = record::one_or_joined(u, y, |u, y| {
        record::from_arrays(u, y, ts, input_names.clone(), output_name.clone())
    })?;
    let (priors, priors_origin) = self::priors(py, priors)?;
    let (select_rows, grid) = (
        parse_rows("select_rows", select_rows.as_deref())?,
        grid.unwrap_or_default(),
    );
    if !auto
        && (select_rows.is_some()
            || folds.is_some()
            || select_records.is_some()
            || refit_starts.is_some()
            || !grid.is_empty())
    {
        return Err(Failure::input(
            "select_rows, folds, select_records, refit_starts and grid need auto=True",
        )
        .into());
    }
    if data.record_count() > 1 && select_rows.is_some() {
        return Err(Failure::input(
            "select_rows: not with several records; hold out whole records with select_records=K",
        )
        .into());
    }
    if auto && standardize {
        return Err(Failure::input("auto=True and standardize=True cannot be combined").into());
    }
    let mode = if auto {
        let grid = (!grid.is_empty())
            .then(|| SearchSpace::parse_grid(&grid))
            .transpose()
            .map_err(|e| Failure::input(e.render("grid")))?;
        Mode::Auto(Auto {
            select_rows,
            folds,
            select_records,
            refit_starts: refit_starts.unwrap_or(hysid::select::DEFAULT_REFIT_STARTS),
            grid,
        })
    } else if standardize {
        Mode::Standardized
    } else {
        Mode::Plain
    };
    let request = Identify {
        priors,
        priors_origin,
        modes,
        max_modes,
        options: settings(options)?,
        seed,
        time_budget,
        warmup,
        mode,
        ..Identify::new(method, &data).orders(na, nb)
    };
    let registry = hysid::registry();
    let identified = interrupt::run(py, |stop| {
        Identify {
            stop: Some(stop),
            ..request.clone()
        }
        .run(&registry)
        .map_err(Failure::from)
    })??;
    // As the program: a run cut short (a time budget, an iteration bound),
    // or one with warnings, says so.
    if let Some(note) = identified.model.info().diagnostics.note() {
        warn(py, &format!("{method}: {note}"))?;
    }
    for warning in identified.fit_warnings(&request) {
        warn(py, &format!("{method}: {warning}"))?;
    }
    if let Some(warning) = identified.affine_warning(&request) {
        warn(py, &warning)?;
    }
    Ok(Model::new(identified.model))
}

/// Runs the experiment file `experiment` (TOML, as `hysid compare`), writes
/// its report and models into `out_dir`, and returns the report (what
/// `report.json` holds) as a dictionary.
#[pyfunction]
fn compare<'py>(
    py: Python<'py>,
    experiment: PathBuf,
    out_dir: PathBuf,
) -> PyResult<Bound<'py, PyAny>> {
    let folder = |inputs: &[&std::path::Path]| {
        hysid::compare::check_report_folder(&out_dir, inputs)
            .map_err(|e| Failure::input(format!("out_dir='{}': {e}", out_dir.display())))
    };
    // The folder first, as the argument before the file is read; then
    // against the files the experiment reads.
    folder(&[])?;
    let exp =
        hysid::compare::Experiment::load(&experiment).map_err(|e| Failure::input(e.to_string()))?;
    folder(&exp.input_files())?;
    // As the program says them: the warnings, and the file with a run's error.
    for w in exp.warnings() {
        warn(py, &format!("{}: {w}", experiment.display()))?;
    }
    let mut comparison = py
        .detach(|| exp.run(&hysid_core::backend::NoProgress))
        .map_err(|e| Failure::input(format!("{}: {e}", experiment.display())))?;
    if let Some(w) = exp.unread_declared_inputs() {
        warn(py, &format!("{}: {w}", experiment.display()))?;
    }
    if let Some(w) = hysid::compare::constant_output(&comparison.results) {
        warn(py, &format!("{}: {w}", experiment.display()))?;
    }
    // As the program's exit code 1: the report could not be written.
    hysid::compare::write_report(&mut comparison, &out_dir)
        .map_err(|e| Failure::method(format!("{}: {e}", out_dir.display())))?;
    let text = serde_json::to_string(&comparison).map_err(|e| Failure::method(e.to_string()))?;
    json(py, &text)
}

/// The module `hysid._hysid`.
#[pymodule]
fn _hysid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    error::register(m)?;
    m.add_class::<Model>()?;
    m.add_function(wrap_pyfunction!(methods, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(check_record, m)?)?;
    m.add_function(wrap_pyfunction!(sampling_time, m)?)?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    Ok(())
}
