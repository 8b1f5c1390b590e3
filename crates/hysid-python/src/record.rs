//! Records between numpy and hysid: `u` as an `(N, m)` array (or `(N,)`
//! for one input), `y` as `(N,)` (or `(N, 1)`), into a checked [`Dataset`]
//! and back.

use crate::error::Failure;
use hysid_model::data::{DataSelection, Dataset, Signal, SignalNameError};
use numpy::ndarray::{Array2, ArrayD};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLikeDyn, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

/// `obj` as an array of floats (anything `numpy.asarray` takes); `name`
/// names the argument in the error. Complex numbers (numpy would drop their
/// imaginary parts) and masked samples (numpy would read the values under
/// the mask) are refused.
pub fn floats(name: &str, obj: &Bound<'_, PyAny>) -> Result<ArrayD<f64>, Failure> {
    let not_numbers = |e: PyErr| Failure::input(format!("{name}: not an array of numbers ({e})"));
    let numpy = obj.py().import("numpy").map_err(not_numbers)?;
    let masked = numpy
        .getattr("ma")
        .and_then(|ma| ma.call_method1("is_masked", (obj,)));
    if masked.and_then(|m| m.is_truthy()).map_err(not_numbers)? {
        return Err(Failure::input(format!(
            "{name}: masked samples; fill them or leave them out first"
        )));
    }
    // Converted once: the dtype is read and the floats taken from it.
    let array = numpy.call_method1("asarray", (obj,)).map_err(not_numbers)?;
    let kind = (array.getattr("dtype"))
        .and_then(|d| d.getattr("kind")?.extract::<String>())
        .map_err(not_numbers)?;
    if kind == "c" {
        return Err(Failure::input(format!(
            "{name}: complex numbers; give real ones"
        )));
    }
    let a = array
        .extract::<PyArrayLikeDyn<'_, f64, AllowTypeChange>>()
        .map_err(not_numbers)?;
    Ok(a.as_array().to_owned())
}

/// A shape as Python writes it: `(300,)`, `(300, 2)`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The inputs `u` as columns: `(N,)` is one input, `(N, m)` is `m`.
pub fn input_columns(u: &Bound<'_, PyAny>) -> Result<Vec<Vec<f64>>, Failure> {
    let a = floats("u", u)?;
    match a.shape() {
        [_] => Ok(vec![a.iter().copied().collect()]),
        [_, m] => Ok((0..*m)
            .map(|j| {
                a.index_axis(numpy::ndarray::Axis(1), j)
                    .iter()
                    .copied()
                    .collect()
            })
            .collect()),
        shape => Err(Failure::input(format!(
            "u: expected an array of shape (N,) or (N, m), got shape {}",
            shape_text(shape)
        ))),
    }
}

/// The outputs `y`, shape `(N,)` or `(N, 1)` (one output as a column).
pub fn output(y: &Bound<'_, PyAny>) -> Result<Vec<f64>, Failure> {
    let a = floats("y", y)?;
    match a.shape() {
        [_] | [_, 1] => Ok(a.iter().copied().collect()),
        shape => Err(Failure::input(format!(
            "y: expected an array of shape (N,) or (N, 1), got shape {}",
            shape_text(shape)
        ))),
    }
}

/// Default input names: `u` for one input (as the program's `--input`
/// default), `u1 .. um` for several.
fn input_names(m: usize, given: Option<Vec<String>>) -> Result<Vec<String>, Failure> {
    match given {
        Some(names) if names.len() != m => Err(Failure::input(format!(
            "input_names: {} name(s) for {m} input(s)",
            names.len()
        ))),
        Some(names) => Ok(names),
        None if m == 1 => Ok(vec!["u".into()]),
        None => Ok((1..=m).map(|i| format!("u{i}")).collect()),
    }
}

/// The signal names of `selection` checked as the program checks them;
/// `inputs` and `output` name the arguments that gave them.
pub fn check_names(selection: &DataSelection, inputs: &str, output: &str) -> Result<(), Failure> {
    selection.check_names().map_err(|e| match e {
        SignalNameError::Empty => {
            Failure::input(format!("{inputs}/{output}: an empty signal name"))
        }
        e => Failure::input(format!("{inputs}: {e}")),
    })
}

/// A record from the inputs' columns and the outputs; the names checked
/// as the program checks them, lengths and finite values by
/// [`Dataset::new`].
pub fn dataset(
    columns: Vec<Vec<f64>>,
    y: Vec<f64>,
    ts: Option<f64>,
    names: Option<Vec<String>>,
    output_name: Option<String>,
) -> Result<Dataset, Failure> {
    let names = input_names(columns.len(), names)?;
    let selection = DataSelection {
        inputs: names.clone(),
        output: output_name.clone().unwrap_or_else(|| "y".into()),
        ..DataSelection::default()
    };
    check_names(&selection, "input_names", "output_name")?;
    let inputs = names
        .into_iter()
        .zip(columns)
        .map(|(name, values)| Signal { name, values })
        .collect();
    let output = Signal {
        name: output_name.unwrap_or_else(|| "y".into()),
        values: y,
    };
    Ok(Dataset::new(inputs, output, ts)?)
}

/// The record of Python's inputs `u` (`(N,)` or `(N, m)`) and outputs `y`
/// (`(N,)` or `(N, 1)`), checked as `identify` checks it ([`dataset`]).
pub fn from_arrays(
    u: &Bound<'_, PyAny>,
    y: &Bound<'_, PyAny>,
    ts: Option<f64>,
    names: Option<Vec<String>>,
    output_name: Option<String>,
) -> Result<Dataset, Failure> {
    dataset(input_columns(u)?, output(y)?, ts, names, output_name)
}

/// The inputs and the outputs of one record, as Python gave them.
type ArrayPair<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>);

/// Several records: `y` is a list or tuple of arrays (numpy's, or objects
/// numpy converts through `__array__`, such as pandas Series), and `u` a
/// list or tuple of as many. Anything else is one record (a list of
/// numbers, or of lists, is one array, as numpy reads it).
fn record_lists<'py>(
    u: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
) -> Result<Option<Vec<ArrayPair<'py>>>, Failure> {
    // An array of at least one dimension: a numpy scalar (`list(y)` of an
    // array holds them) has `__array__` too, but is a number.
    let array = |x: &Bound<'py, PyAny>| {
        let like = x.is_instance_of::<PyUntypedArray>() || x.hasattr("__array__").unwrap_or(false);
        let ndim = x.getattr("ndim").and_then(|n| n.extract::<usize>());
        like && ndim.map_or(true, |n| n >= 1)
    };
    let Some(ys) = items(y).filter(|ys| !ys.is_empty() && ys.iter().all(array)) else {
        return Ok(None);
    };
    let us = items(u).ok_or_else(|| {
        Failure::input(format!(
            "u: y is a list of {} records, u must be a list of as many input arrays",
            ys.len()
        ))
    })?;
    if us.len() != ys.len() {
        return Err(Failure::input(format!(
            "u: {} input record(s) for {} output record(s)",
            us.len(),
            ys.len()
        )));
    }
    Ok(Some(us.into_iter().zip(ys).collect()))
}

/// The items of a Python list or tuple; `None` for anything else.
fn items<'py>(obj: &Bound<'py, PyAny>) -> Option<Vec<Bound<'py, PyAny>>> {
    if let Ok(l) = obj.cast::<PyList>() {
        Some(l.iter().collect())
    } else {
        obj.cast::<PyTuple>().ok().map(|t| t.iter().collect())
    }
}

/// The record `read` makes of `u`, `y`, or, for lists of records
/// ([`record_lists`]), the records it makes of each pair, joined
/// ([`Dataset::join`]); an error names the record (counted from 1).
pub fn one_or_joined(
    u: &Bound<'_, PyAny>,
    y: &Bound<'_, PyAny>,
    read: impl Fn(&Bound<'_, PyAny>, &Bound<'_, PyAny>) -> Result<Dataset, Failure>,
) -> Result<Dataset, Failure> {
    let Some(pairs) = record_lists(u, y)? else {
        return read(u, y);
    };
    let records = pairs
        .iter()
        .enumerate()
        .map(|(i, (u, y))| read(u, y).map_err(|e| e.in_record(i + 1)))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Dataset::join(&records)?)
}

/// The inputs of `data` as an `(N, m)` array.
pub fn inputs_array<'py>(py: Python<'py>, data: &Dataset) -> Bound<'py, PyArray2<f64>> {
    let (n, m) = (data.len(), data.inputs.len());
    Array2::from_shape_fn((n, m), |(k, i)| data.u(i)[k]).into_pyarray(py)
}

/// A vector as a 1-D array.
pub fn vector<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_vec(py, v)
}

/// Active modes per sample as integers, `-1` where none is (before the
/// simulation starts).
pub fn modes<'py>(py: Python<'py>, modes: &[Option<usize>]) -> Bound<'py, PyArray1<i64>> {
    PyArray1::from_vec(
        py,
        modes.iter().map(|q| q.map_or(-1, |q| q as i64)).collect(),
    )
}
