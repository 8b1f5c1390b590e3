//! Arguments of the model's methods read as the program reads its flags:
//! a value of the wrong type or out of range is a `hysid.InputError` that
//! names the argument, never a `TypeError` or `OverflowError` from the
//! conversion. (The package's functions check theirs in Python first.)

use crate::error::Failure;
use pyo3::prelude::*;
use pyo3::types::PyBool;

/// `repr(obj)`, for a message.
fn shown(obj: &Bound<'_, PyAny>) -> String {
    obj.repr().map(|r| r.to_string()).unwrap_or_default()
}

/// Argument `name` as a `T`, refused unless Python gives one (a bool is
/// refused: Python would read it as 0 or 1) with "must be `what`".
fn extracted<'py, T: for<'a> FromPyObject<'a, 'py>>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    what: &str,
) -> Result<T, Failure> {
    let refused = || Failure::input(format!("{name}={}: must be {what}", shown(obj)));
    if obj.is_instance_of::<PyBool>() {
        return Err(refused());
    }
    obj.extract::<T>().map_err(|_| refused())
}

/// Argument `name` as a count: a whole number from 0 to 2**64 - 1 (a
/// Python or numpy integer, not a bool), as the package's functions check
/// theirs.
pub fn count(name: &str, obj: &Bound<'_, PyAny>) -> Result<usize, Failure> {
    extracted(name, obj, "a whole number >= 0 and < 2**64")
}

/// Argument `name`, when given, as a number of seconds (positivity and
/// finiteness are the record's checks).
pub fn seconds(name: &str, obj: Option<&Bound<'_, PyAny>>) -> Result<Option<f64>, Failure> {
    obj.map(|obj| extracted(name, obj, "a number of seconds"))
        .transpose()
}
