//! `hysid.Model`: any model hysid identifies, loads or writes, with its
//! simulation, prediction and validation on numpy arrays.

use crate::args;
use crate::error::Failure;
use crate::record::{self, dataset, input_columns, output};
use hysid_core::model::Model as AnyModel;
use hysid_core::simulate;
use hysid_model::geometry::Polyhedron;
use hysid_model::simulate::{Simulation, SimulationOptions};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::PyRuntimeWarning;
use pyo3::prelude::*;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A hysid model: a PWARX model, a hybrid automaton, a mechanical or a
/// gray-box model.
///
/// Files are the program's: a model saved here loads in `hysid validate`,
/// and a model written by `hysid identify` loads here.
#[pyclass(module = "hysid", name = "Model", frozen)]
pub struct Model {
    pub(crate) inner: AnyModel,
}

/// A simulation's outputs and active modes (`-1` before it starts).
type Outputs<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<i64>>);

/// A polyhedron `{z : A z <= b}` as `(A, b)`.
type Inequalities<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

impl Model {
    /// Wraps a model.
    pub fn new(inner: AnyModel) -> Self {
        Self { inner }
    }

    /// A record of the model's inputs `u` with outputs `y`; the sampling
    /// time is `ts`, else the one the model was identified at.
    fn record(
        &self,
        u: &Bound<'_, PyAny>,
        y: Vec<f64>,
        ts: Option<f64>,
    ) -> Result<hysid_model::data::Dataset, Failure> {
        let columns = input_columns(u)?;
        dataset(columns, y, ts.or(self.inner.info().ts), None, None)
    }
}

/// `(A, b)` with `{z : A z <= b}` the polyhedron `p` in `dim` coordinates;
/// each equality is two inequalities.
fn inequalities<'py>(py: Python<'py>, p: &Polyhedron, dim: usize) -> Inequalities<'py> {
    let mut rows: Vec<(Vec<f64>, f64)> = p.a.iter().cloned().zip(p.b.iter().copied()).collect();
    for (a, b) in p.a_eq.iter().zip(&p.b_eq) {
        rows.push((a.clone(), *b));
        rows.push((a.iter().map(|v| -v).collect(), -b));
    }
    let a = Array2::from_shape_fn((rows.len(), dim), |(i, j)| {
        rows[i].0.get(j).copied().unwrap_or(0.0)
    });
    let b: Vec<f64> = rows.iter().map(|r| r.1).collect();
    (a.into_pyarray(py), PyArray1::from_vec(py, b))
}

/// A Python warning when the discrete-time `model` meets a record of
/// another sampling time ([`simulate::sampling_time_mismatch`]), or a
/// physical model's internal step is far from it ([`simulate::StepScale`]).
fn warn_sampling_time(
    py: Python<'_>,
    model: &AnyModel,
    data: &hysid_model::data::Dataset,
) -> PyResult<()> {
    if let Some(coarse) = simulate::StepScale::of(model, data) {
        crate::warn(py, &coarse.to_string())?;
    }
    match simulate::sampling_time_mismatch(model, data) {
        Some((record, own)) => crate::warn(
            py,
            &format!(
                "the record's sampling time {record} s differs from the {own} s the model was \
                 identified at: its lags mean other times (decimate or ts left out?)"
            ),
        ),
        None => Ok(()),
    }
}

/// A Python warning naming the definitions of a gray-box `model` that no
/// expression reads ([`simulate::UnreadDefinitions`]).
fn warn_unread_definitions(py: Python<'_>, model: &AnyModel) -> PyResult<()> {
    match simulate::UnreadDefinitions::of(model) {
        Some(unread) => crate::warn(py, &unread.to_string()),
        None => Ok(()),
    }
}

/// A `RuntimeWarning` for each of the simulation's warnings (it diverged,
/// it reached the Zeno bound).
fn warn_divergence(py: Python<'_>, sim: &Simulation) -> PyResult<()> {
    for warning in sim.warnings() {
        crate::warn_as::<PyRuntimeWarning>(py, &warning.to_string())?;
    }
    Ok(())
}

/// A `hysid.Record` given in place of the inputs `u`: its inputs, its
/// outputs (in place of `y`, which must then be left out) and its sampling
/// time (in place of `ts`, likewise); the arguments as given otherwise.
type Given<'py> = (
    Bound<'py, PyAny>,
    Option<Bound<'py, PyAny>>,
    Option<Bound<'py, PyAny>>,
);

fn unpacked<'py>(
    py: Python<'py>,
    u: &Bound<'py, PyAny>,
    y: Option<&Bound<'py, PyAny>>,
    ts: Option<&Bound<'py, PyAny>>,
) -> PyResult<Given<'py>> {
    let record = py.import("hysid._record")?.getattr("Record")?;
    if !u.is_instance(&record)? {
        return Ok((u.clone(), y.cloned(), ts.cloned()));
    }
    let given: Vec<&str> = [("y", y.is_some()), ("ts", ts.is_some())]
        .into_iter()
        .filter_map(|(name, given)| given.then_some(name))
        .collect();
    if !given.is_empty() {
        return Err(Failure::input(format!(
            "{} given with a record, which has its own",
            given.join(", ")
        ))
        .into());
    }
    let ts = Some(u.getattr("ts")?).filter(|t| !t.is_none());
    Ok((u.getattr("u")?, Some(u.getattr("y")?), ts))
}

/// [`unpacked`] for a method that reads measured outputs: `y` (given, or
/// the record's) is required.
type Measured<'py> = (
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Option<Bound<'py, PyAny>>,
);

fn measured<'py>(
    py: Python<'py>,
    u: &Bound<'py, PyAny>,
    y: Option<&Bound<'py, PyAny>>,
    ts: Option<&Bound<'py, PyAny>>,
) -> PyResult<Measured<'py>> {
    let (u, y, ts) = unpacked(py, u, y, ts)?;
    let y = y.ok_or_else(|| Failure::input("y is missing (give a hysid.Record, or u and y)"))?;
    Ok((u, y, ts))
}

#[pymethods]
impl Model {
    /// Reads a model file (`.json`, or `.toml` for hand-written models).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        Ok(Self::new(AnyModel::load(&path).map_err(Failure::from)?))
    }

    /// Parses a model from its JSON text.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        Ok(Self::new(
            AnyModel::from_json(text, "<json>").map_err(Failure::from)?,
        ))
    }

    /// The model file's JSON text.
    fn to_json(&self) -> String {
        self.inner.to_json()
    }

    /// Writes the model file atomically: TOML to a `.toml` path, JSON to
    /// any other.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        Ok(hysid_io::save_model(&self.inner, &path).map_err(Failure::from)?)
    }

    /// A mechanical model written as the gray-box model of the same
    /// physics (`hysid convert`).
    fn to_gray_box(&self) -> PyResult<Self> {
        let gray = self
            .inner
            .to_gray_box()
            .map_err(|e| Failure::input(e.to_string()))?;
        Ok(Self::new(AnyModel::GrayBox(gray)))
    }

    /// `"pwarx"`, `"hybrid_automaton"`, `"mechanical"` or `"gray_box"`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind()
    }

    /// The back-end that identified the model (empty for hand-written ones).
    #[getter]
    fn method(&self) -> String {
        self.inner.info().method.clone()
    }

    /// Number of discrete modes.
    #[getter]
    fn mode_count(&self) -> usize {
        self.inner.mode_count()
    }

    /// Mode names, in mode order: the active `mode` of `simulate` and
    /// `predict` indexes them.
    #[getter]
    fn mode_names(&self) -> Vec<String> {
        self.inner.mode_names()
    }

    /// Number of inputs.
    #[getter]
    fn inputs(&self) -> usize {
        self.inner.inputs()
    }

    /// ARX orders `(na, nb)`, or `None` for a model without them.
    #[getter]
    fn orders(&self) -> Option<(usize, usize)> {
        self.inner.orders().map(|o| (o.na, o.nb))
    }

    /// Input names of the record it was identified on (the columns of a
    /// DataFrame, `input_names` of `identify`); empty when unknown.
    #[getter]
    fn input_names(&self) -> Vec<String> {
        self.inner.info().input_names.clone()
    }

    /// Output name of the record it was identified on; empty when unknown.
    #[getter]
    fn output_name(&self) -> String {
        self.inner.info().output_name.clone()
    }

    /// Sampling time in seconds of the data it was identified on, if known.
    #[getter]
    fn ts(&self) -> Option<f64> {
        self.inner.info().ts
    }

    /// PWARX parameters, one row per mode: `y(k) = theta . [x(k); 1]` with
    /// the regressor `x(k) = [y(k-1) .. y(k-na), u(k-1) .. u(k-nb)]` (input
    /// by input). `None` for other kinds.
    #[getter]
    fn thetas<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        let AnyModel::Pwarx(m) = &self.inner else {
            return None;
        };
        let d = m.modes.first().map_or(0, |q| q.theta.len());
        let a = Array2::from_shape_fn((m.modes.len(), d), |(i, j)| m.modes[i].theta[j]);
        Some(a.into_pyarray(py))
    }

    /// Per mode, `(A, b)` with `{z : A z <= b}` its region: in regressor
    /// coordinates for a PWARX model, the invariant in `[x; u]` for a
    /// hybrid automaton (an equality is two rows). Empty for a mechanical
    /// model, whose modes are not polyhedra.
    #[getter]
    fn regions<'py>(&self, py: Python<'py>) -> Vec<Inequalities<'py>> {
        match &self.inner {
            AnyModel::Pwarx(m) => {
                let dim = m.spec().dim();
                m.modes
                    .iter()
                    .map(|q| inequalities(py, &q.region, dim))
                    .collect()
            }
            AnyModel::HybridAutomaton(m) => {
                let dim = m.states.len() + m.inputs.len();
                m.modes
                    .iter()
                    .map(|q| inequalities(py, &q.invariant, dim))
                    .collect()
            }
            AnyModel::Mechanical(_) | AnyModel::GrayBox(_) => Vec::new(),
        }
    }

    /// Known output stops as `(level, "max" | "min")`: a `max` stop bounds
    /// the output from above.
    #[getter]
    fn stops(&self) -> Vec<(f64, &'static str)> {
        self.inner
            .stops()
            .iter()
            .map(|s| (s.level, s.bound.name()))
            .collect()
    }

    /// Provenance as a dictionary: method, options, seed, diagnostics and,
    /// under automatic selection, the candidates and the choice.
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text =
            serde_json::to_string(self.inner.info()).map_err(|e| Failure::method(e.to_string()))?;
        crate::json(py, &text)
    }

    /// Free-run simulation driven by `u`; `y0` (shape `(k,)` or `(k, 1)`)
    /// gives the outputs of the first samples (the initial condition; zeros
    /// when left out), or `x0` (a dictionary with a value for every state)
    /// the state at the first sample, in place of the model's initial-state
    /// rule (`hysid simulate --x0`). A `hysid.Record` in place of `u` gives
    /// the inputs and `ts` (its outputs are not read, as
    /// `Estimator.simulate`). Returns `(y, mode)`.
    #[pyo3(signature = (u, y0=None, ts=None, x0=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        y0: Option<&Bound<'py, PyAny>>,
        ts: Option<&Bound<'py, PyAny>>,
        x0: Option<BTreeMap<String, f64>>,
    ) -> PyResult<Outputs<'py>> {
        let started;
        let model = match x0 {
            Some(_) if y0.is_some() => {
                return Err(Failure::input("x0 and y0: give one initial condition").into());
            }
            Some(state) => {
                started = (self.inner.starting_from(&state))
                    .map_err(|e| Failure::input(format!("x0: {e}")))?;
                &started
            }
            None => &self.inner,
        };
        // A record's inputs drive the run; its outputs are not read.
        let (u, _, ts) = unpacked(py, u, None, ts)?;
        let u = &u;
        let ts = args::seconds("ts", ts.as_ref())?;
        let n = input_columns(u)?.first().map_or(0, Vec::len);
        let mut y = vec![0.0; n];
        if let Some(y0) = y0 {
            let given = record::floats("y0", y0)?;
            let column = matches!(given.shape(), [_] | [_, 1]);
            if !column || given.len() > n {
                return Err(Failure::input(format!(
                    "y0: expected at most {n} initial outputs (shape (k,) or (k, 1)), got shape {}",
                    record::shape_text(given.shape())
                ))
                .into());
            }
            if let Some(k) = given.iter().position(|v| !v.is_finite()) {
                return Err(Failure::input(format!("y0: a non-finite value at sample {k}")).into());
            }
            y[..given.len()].copy_from_slice(&given.iter().copied().collect::<Vec<_>>());
        }
        let data = self.record(u, y, ts)?;
        warn_sampling_time(py, model, &data)?;
        warn_unread_definitions(py, model)?;
        let sim = py
            .detach(|| simulate::simulate(model, &data, SimulationOptions::default()))
            .map_err(Failure::from)?;
        warn_divergence(py, &sim)?;
        if let Some(outside) = simulate::OutsideRegions::of(model, &sim) {
            crate::warn(py, &outside.to_string())?;
        }
        Ok((
            record::vector(py, sim.y.clone()),
            record::modes(py, &sim.modes),
        ))
    }

    /// One-step-ahead prediction from the measured `u` and `y` (`y` of
    /// shape `(N,)` or `(N, 1)`; or a `hysid.Record` in place of `u`,
    /// `y` and `ts`). Returns `(y_pred, mode)`.
    #[pyo3(signature = (u, y=None, ts=None), text_signature = "($self, u, y=None, ts=None)")]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        y: Option<&Bound<'py, PyAny>>,
        ts: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Outputs<'py>> {
        let (u, y, ts) = measured(py, u, y, ts)?;
        let data = self.record(&u, output(&y)?, args::seconds("ts", ts.as_ref())?)?;
        let opts = SimulationOptions::for_data(&data);
        let pred = py
            .detach(|| simulate::predict(&self.inner, &data, opts))
            .map_err(Failure::from)?;
        Ok((
            record::vector(py, pred.y.clone()),
            record::modes(py, &pred.modes),
        ))
    }

    /// Scores the model on a record, leaving out the first `warmup`
    /// samples: the dictionary of `hysid validate --json` (`fit_sim`,
    /// `rmse_sim`, `fit_pred`, `rmse_pred`, `coverage`, ...). Lists of
    /// records (`u` and `y` lists of as many arrays) are scored each, in
    /// `records`, and together. A `hysid.Record` in place of `u` gives `u`,
    /// `y` and `ts`.
    #[pyo3(signature = (u, y=None, warmup=None, ts=None), text_signature = "($self, u, y=None, warmup=10, ts=None)")]
    fn validate<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        y: Option<&Bound<'py, PyAny>>,
        warmup: Option<&Bound<'py, PyAny>>,
        ts: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let warmup = warmup.map_or(Ok(10), |w| args::count("warmup", w))?;
        let (u, y, ts) = measured(py, u, y, ts)?;
        let ts = args::seconds("ts", ts.as_ref())?;
        let data = record::one_or_joined(&u, &y, |u, y| self.record(u, output(y)?, ts))?;
        for (i, range) in data.record_ranges().into_iter().enumerate() {
            if warmup >= range.len() {
                let which = if data.record_count() > 1 {
                    format!("record {} has", i + 1)
                } else {
                    "the record has".into()
                };
                return Err(Failure::input(format!(
                    "warmup={warmup} leaves no sample to score: {which} {} samples",
                    range.len()
                ))
                .into());
            }
        }
        warn_sampling_time(py, &self.inner, &data)?;
        warn_unread_definitions(py, &self.inner)?;
        let (report, _, _) = py
            .detach(|| simulate::validate(&self.inner, &data, warmup))
            .map_err(Failure::from)?;
        for warning in report.warnings() {
            crate::warn_as::<PyRuntimeWarning>(py, &warning.to_string())?;
        }
        crate::warn_if_below_affine(py, &self.inner, &data, warmup, "these rows")?;
        let text = serde_json::to_string(&report).map_err(|e| Failure::method(e.to_string()))?;
        crate::json(py, &text)
    }

    /// The model in words and equations, as `hysid show` prints it: each
    /// mode's equation and region, or the parameters with their standard
    /// errors, and how it was identified.
    fn describe(&self) -> String {
        hysid::describe::describe(&self.inner)
    }

    /// `print(model)`: [`Self::describe`].
    fn __str__(&self) -> String {
        self.describe()
    }

    fn __repr__(&self) -> String {
        let orders = self
            .inner
            .orders()
            .map(|o| format!(", na={}, nb={}", o.na, o.nb))
            .unwrap_or_default();
        let method = &self.inner.info().method;
        let method = if method.is_empty() {
            String::new()
        } else {
            format!(", method='{method}'")
        };
        format!(
            "Model(kind='{}'{method}, modes={}{orders})",
            self.inner.kind(),
            self.inner.mode_count()
        )
    }
}
