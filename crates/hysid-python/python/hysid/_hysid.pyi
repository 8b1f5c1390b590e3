"""Type stubs of the extension module hysid._hysid (Rust, pyo3)."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
PathLike = Union[str, os.PathLike]

class HysidError(Exception):
    """Base class of the package's errors: InputError (bad input, a
    ValueError) and MethodError (the method failed, a RuntimeError). The
    message is the `hysid` program's one line."""

class InputError(HysidError, ValueError):
    """Bad input: data (shapes, lengths, non-finite values, names),
    arguments, options, priors, a record or model file. A ValueError; the
    program exits with code 2 on the same input."""

class MethodError(HysidError, RuntimeError):
    """The method ran on valid input and failed (a solver failure, every
    candidate or start failed, the data did not allow the fit asked for). A
    RuntimeError; the program exits with code 1 on the same input."""

class Model:
    """A hysid model: a PWARX model, a hybrid automaton, a mechanical or a
    gray-box model.

    Files are the program's: a model saved here loads in `hysid validate`,
    and a model written by `hysid identify` loads here."""

    @staticmethod
    def load(path: PathLike) -> Model:
        """Reads a model file (`.json`, or `.toml` for hand-written models)."""
    @staticmethod
    def from_json(text: str) -> Model:
        """Parses a model from its JSON text."""
    def to_json(self) -> str:
        """The model file's JSON text."""
    def save(self, path: PathLike) -> None:
        """Writes the model file atomically: TOML to a `.toml` path, JSON to any other."""
    def to_gray_box(self) -> Model:
        """A mechanical model written as the gray-box model of the same physics (`hysid convert`)."""
    def describe(self) -> str:
        """The model in words and equations, as `hysid show` prints it: each
        mode's equation and region, or the parameters with their standard
        errors, and how it was identified."""
    @property
    def kind(self) -> str:
        """`"pwarx"`, `"hybrid_automaton"`, `"mechanical"` or `"gray_box"`."""
    @property
    def method(self) -> str:
        """The back-end that identified the model (empty for hand-written ones)."""
    @property
    def mode_count(self) -> int:
        """Number of discrete modes."""
    @property
    def mode_names(self) -> List[str]:
        """Mode names, in mode order: the active `mode` of `simulate` and
        `predict` indexes them."""
    @property
    def inputs(self) -> int:
        """Number of inputs."""
    @property
    def input_names(self) -> List[str]:
        """Input names of the record it was identified on (the columns of a
        DataFrame, `input_names` of `identify`); empty when unknown."""
    @property
    def output_name(self) -> str:
        """Output name of the record it was identified on; empty when unknown."""
    @property
    def orders(self) -> Optional[Tuple[int, int]]:
        """ARX orders `(na, nb)`, or `None` for a model without them."""
    @property
    def ts(self) -> Optional[float]:
        """Sampling time in seconds of the data it was identified on, if known."""
    @property
    def thetas(self) -> Optional[npt.NDArray[np.float64]]:
        """PWARX parameters, one row per mode: `y(k) = theta . [x(k); 1]` with
        the regressor `x(k) = [y(k-1) .. y(k-na), u(k-1) .. u(k-nb)]` (input
        by input). `None` for other kinds."""
    @property
    def regions(self) -> List[Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]]:
        """Per mode, `(A, b)` with `{z : A z <= b}` its region: in regressor
        coordinates for a PWARX model, the invariant in `[x; u]` for a
        hybrid automaton (an equality is two rows). Empty for a mechanical
        model, whose modes are not polyhedra."""
    @property
    def stops(self) -> List[Tuple[float, str]]:
        """Known output stops as `(level, "max" | "min")`: a `max` stop bounds
        the output from above."""
    @property
    def info(self) -> Dict[str, Any]:
        """Provenance as a dictionary: method, options, seed, diagnostics and,
        under automatic selection, the candidates and the choice."""
    def simulate(
        self,
        u: Any,
        y0: Optional[ArrayLike] = None,
        ts: Optional[float] = None,
        x0: Optional[Dict[str, float]] = None,
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
        """Free-run simulation driven by `u`; `y0` (shape `(k,)` or `(k, 1)`)
        gives the outputs of the first samples (the initial condition; zeros
        when left out), or `x0` (a value for every state, by name) the
        state at the first sample, in place of the model's initial-state
        rule (`hysid simulate --x0`); `ts`: the sampling time in seconds (a
        continuous-time model needs it). A `hysid.Record` in place of `u`
        gives the inputs and `ts` (its outputs are not read, as
        `Estimator.simulate`). Returns `(y, mode)`."""
    def predict(
        self, u: Any, y: Optional[ArrayLike] = None, ts: Optional[float] = None
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
        """One-step-ahead prediction from the measured `u` and `y` (`y` of
        shape `(N,)` or `(N, 1)`; or a `hysid.Record` in place of `u`, `y`
        and `ts`). Returns `(y_pred, mode)`."""
    def validate(
        self, u: Any, y: Optional[ArrayLike] = None, warmup: int = 10, ts: Optional[float] = None
    ) -> Dict[str, Any]:
        """Scores the model on a record (or on lists of records: each in
        `records`, and all together), leaving out the first `warmup`
        samples: the dictionary of `hysid validate --json` (`fit_sim`,
        `rmse_sim`, `fit_pred`, `rmse_pred`, `coverage`, ...). A
        `hysid.Record` in place of `u` gives `u`, `y` and `ts`."""

def methods() -> List[Dict[str, Any]]:
    """The back-ends as a list of dictionaries: name, summary, options (key,
    ty, default, doc), priors honoured, what `auto` tries, and whether and
    how the seed is used (seeded, seed_use)."""

def load(
    path: PathLike,
    inputs: Optional[List[str]] = None,
    output: Optional[str] = None,
    decimate: int = 1,
    rows: Optional[str] = None,
    ts: Optional[float] = None,
    time: Optional[str] = None,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], Optional[float]]:
    """Reads a CSV or MAT record with the program's selection rules; returns
    `(u, y, ts)` with `u` of shape `(N, m)`."""

def sampling_time(name: str, t: List[float]) -> float:
    """The sampling time of the times `t` of the column `name`: their first
    step, every other step within 1 % of it, as the program reads a time
    column; an InputError naming the column and the row otherwise."""

def check_record(
    u: ArrayLike,
    y: ArrayLike,
    ts: Optional[float] = None,
    input_names: Optional[List[str]] = None,
    output_name: Optional[str] = None,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], List[str], str]:
    """Checks a record as `identify` checks it (shapes, lengths, finite
    values, the sampling time, the names); returns `(u, y, input_names,
    output_name)` with `u` of shape `(N, m)`, `y` of shape `(N,)` and the
    default names filled in."""

def identify(
    u: ArrayLike,
    y: ArrayLike,
    method: str = "cluster",
    na: int = 2,
    nb: int = 2,
    modes: Optional[int] = None,
    max_modes: Optional[int] = None,
    priors: Union[Dict[str, Any], str, None] = None,
    options: Optional[Dict[str, Any]] = None,
    seed: int = 0,
    ts: Optional[float] = None,
    auto: bool = False,
    select_rows: Optional[str] = None,
    folds: Optional[int] = None,
    select_records: Optional[int] = None,
    refit_starts: Optional[int] = None,
    grid: Optional[Sequence[str]] = None,
    warmup: int = 10,
    standardize: bool = False,
    time_budget: Optional[float] = None,
    input_names: Optional[List[str]] = None,
    output_name: Optional[str] = None,
) -> Model:
    """Identifies a model from inputs `u` (`(N,)` or `(N, m)`) and outputs `y`
    (`(N,)` or `(N, 1)`), or lists of such arrays (several records), with
    back-end `method`; the arguments are those of `hysid identify`."""

def compare(experiment: PathLike, out_dir: PathLike) -> Dict[str, Any]:
    """Runs the experiment file `experiment` (TOML, as `hysid compare`),
    writes its report and models into `out_dir`, and returns the report."""
