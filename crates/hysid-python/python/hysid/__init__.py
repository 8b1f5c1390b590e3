"""hysid: identify hybrid systems (piecewise ARX models, hybrid automata)
from data.

The functions here are those of the ``hysid`` program, on numpy arrays:

- :func:`methods` lists the back-ends (``hysid methods``);
- :func:`load` reads a CSV or MAT record (the program's selection rules);
- :func:`identify` fits a :class:`Model` (``hysid identify``);
- :class:`Model` simulates, predicts, validates (``hysid validate``) and
  reads and writes the program's model files;
- :func:`compare` runs an experiment file (``hysid compare``);
- :class:`Record` holds one experiment (inputs, output, sampling time,
  names) from numpy arrays, a pandas DataFrame or a record file;
- :class:`Estimator` identifies in scikit-learn's manner (``fit``,
  ``score``, ``get_params``, ``set_params``).

Bad input raises :class:`InputError` (a ``ValueError``), a method that ran
and failed raises :class:`MethodError` (a ``RuntimeError``); both are
:class:`HysidError`, with the program's one-line message. Identification
releases the GIL, and Ctrl-C stops it. Figures: :mod:`hysid.plot` (needs
matplotlib).
"""

from __future__ import annotations

import copyreg
import numbers
import os
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _hysid
from ._hysid import HysidError, InputError, MethodError, Model
from ._record import Record, Rows, _names, _rows, _seconds
from ._estimator import Estimator, _records_given

__all__ = [
    "Estimator",
    "HysidError",
    "InputError",
    "MethodError",
    "Model",
    "Record",
    "compare",
    "identify",
    "load",
    "methods",
]
__version__ = "0.1.0"

# Shown (help, repr, pickle) as the package's, where users find them.
Record.__module__ = "hysid"
Estimator.__module__ = "hysid"


def _option_text(value: Any) -> str:
    """An option's value as the program's `--set` reads it, as `options=`
    takes it: `True` as `true`, `None` as `none`, numbers and text as
    written."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "none"
    return str(value)


def _model_from_json(text: str) -> Model:
    """A model from its file's JSON text (how a pickled model is restored)."""
    return Model.from_json(text)


# A model pickles (and copies) as its model file's JSON text, so that a
# fitted Estimator pickles too.
copyreg.pickle(Model, lambda model: (_model_from_json, (model.to_json(),)))


def _counts(*, optional: bool = False, **given: Any) -> None:
    """Refuses a count (orders, modes, seeds, folds, ...) that is not a
    whole number from 0 to 2**64 - 1 (``None`` too, unless ``optional``),
    with an :class:`InputError` naming the argument."""
    what = "a whole number >= 0 and < 2**64"
    _types(optional=optional, **{name: (value, numbers.Integral, what) for name, value in given.items()})
    for name, value in given.items():
        if value is not None and not 0 <= value < 2**64:
            raise InputError(f"{name}={value}: must be {what}")


def _types(*, optional: bool = True, **given: Any) -> None:
    """Refuses an argument of the wrong type with an :class:`InputError`
    naming it: ``(value, allowed types, what they are)`` by name; ``None``
    allowed where ``optional``."""
    for name, (value, allowed, what) in given.items():
        if value is None and optional:
            continue
        if isinstance(value, bool) or not isinstance(value, allowed):
            raise InputError(f"{name}={value!r}: must be {what}")


def _flags(**given: Any) -> None:
    """Refuses a switch that is not ``True`` or ``False`` (numpy's too)."""
    for name, value in given.items():
        if not isinstance(value, (bool, np.bool_)):
            raise InputError(f"{name}={value!r}: must be True or False")


def methods() -> List[Dict[str, Any]]:
    """The registered back-ends: for each, a dictionary with ``name``,
    ``summary``, ``options`` (``key``, ``ty``, ``default``, ``doc``), the
    ``priors`` it honours and what ``auto`` tries (``search``)."""
    return _hysid.methods()


def load(
    path: Union[str, os.PathLike],
    inputs: Union[str, Sequence[str], None] = None,
    output: Optional[str] = None,
    decimate: int = 1,
    rows: Rows = None,
    ts: Optional[float] = None,
    time: Optional[str] = None,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], Optional[float]]:
    """Reads a ``.csv`` or ``.mat`` record.

    ``inputs`` (default ``"u"``) and ``output`` (default ``"y"``) name the
    columns or variables; ``decimate=K`` keeps samples 0, K, 2K, ...
    without a filter; ``rows`` (``"A..B"``, ``(A, B)`` or a range) applies
    after decimation; ``time`` (default ``"t"``) names the column or
    variable of the time in seconds, whose first step is the sampling time;
    ``ts`` is the sampling time when the file has none. Returns
    ``(u, y, ts)`` with ``u`` of shape ``(N, m)``, without the signals'
    names; :meth:`Record.load` returns the same as a :class:`Record`,
    with the names (which :class:`Estimator` keeps in its model).
    """
    _counts(decimate=decimate)
    _types(output=(output, str, "a name"), time=(time, str, "a name"))
    ts = _seconds("ts", ts)
    if isinstance(inputs, str):
        inputs = [s for s in inputs.split(",")]
    return _hysid.load(
        os.fspath(path),
        inputs=None if inputs is None else list(inputs),
        output=output,
        decimate=decimate,
        rows=_rows("rows", rows),
        ts=ts,
        time=time,
    )


def identify(
    u: Union[npt.ArrayLike, Sequence[npt.ArrayLike], Record, Sequence[Record]],
    y: Union[npt.ArrayLike, Sequence[npt.ArrayLike], None] = None,
    method: str = "cluster",
    na: int = 2,
    nb: int = 2,
    modes: Optional[int] = None,
    priors: Union[Dict[str, Any], str, os.PathLike, None] = None,
    options: Optional[Dict[str, Any]] = None,
    seed: int = 0,
    ts: Optional[float] = None,
    *,
    max_modes: Optional[int] = None,
    auto: bool = False,
    select_rows: Rows = None,
    folds: Optional[int] = None,
    select_records: Optional[int] = None,
    refit_starts: Optional[int] = None,
    grid: Optional[Dict[str, Iterable[Any]]] = None,
    warmup: int = 10,
    standardize: bool = False,
    time_budget: Optional[float] = None,
    input_names: Optional[Sequence[str]] = None,
    output_name: Optional[str] = None,
) -> Model:
    """Identifies a model with back-end ``method`` (see :func:`methods`).

    ``u``: inputs, shape ``(N,)`` or ``(N, m)``; ``y``: outputs, ``(N,)``
    or ``(N, 1)``; or a :class:`Record` (or a list of records) in place of
    ``u``, giving ``y``, ``ts`` and the names. Several records of one
    system: ``y`` a list of numpy
    arrays and ``u`` a list of as many (``identify([u1, u2], [y1, y2])``);
    one model is fitted on all, nothing spans two records, each starts from
    its own initial state, and ``select_records=K`` (with ``auto``) holds
    out the last ``K`` records for selection.
    ``na``, ``nb``: ARX orders of the regressor. ``modes``: the number of
    modes (exact); ``max_modes``: the largest, the count chosen by the
    back-end. ``priors``: a dictionary in the prior file's shape (e.g.
    ``{"saturation": [{"level": 16.0, "bound": "max"}]}``) or the path of a
    prior file. ``options``: the back-end's options by name, as ``--set``
    takes them. ``seed``: seed of every random choice. ``ts``: sampling time
    in seconds.

    ``auto=True`` chooses the options on selection rows inside the given
    rows (``select_rows``, default the last 20 %; or ``folds``), over the
    back-end's search space or ``grid`` (``{"c": [40, 80], "modes": [2,
    3]}``), then refits on all rows (from ``refit_starts`` seeds, default
    3, when the seed can change the fit, and from the choice's own fit on
    the fit rows; the start that simulates those rows best is kept);
    ``model.info["selection"]`` records the candidates, the choice and the
    refit's starts. ``standardize=True`` identifies on
    standardised data. ``time_budget``: seconds after which long back-ends
    return their best model. ``warmup``: samples left out of free-run scores.

    Without ``auto``, a ``UserWarning`` says when the model simulates its
    identification rows worse than an affine ARX model of the same orders.
    ``input_names`` and ``output_name`` name the signals in the model
    (``model.input_names``, ``model.output_name``).

    Bad input raises :class:`InputError`; a back-end that ran and failed
    raises :class:`MethodError`. :class:`Estimator` is the same in
    scikit-learn's manner.
    """
    if _records_given(u) or y is None:
        # Records, or arrays without y (refused, saying what is missing).
        found = Estimator._records(u, y, ts, input_names, output_name, "identify")
        first = found[0]
        u, y = ([r.u for r in found], [r.y for r in found]) if len(found) > 1 else (first.u, first.y)
        ts, input_names, output_name = first.ts, first.input_names, first.output_name
    _counts(na=na, nb=nb, seed=seed, warmup=warmup)
    _counts(optional=True, modes=modes, max_modes=max_modes, folds=folds,
            select_records=select_records, refit_starts=refit_starts)
    _types(optional=False, method=(method, str, "a method name"))
    _flags(auto=auto, standardize=standardize)
    _types(
        output_name=(output_name, str, "a name"),
        time_budget=(time_budget, numbers.Real, "a number of seconds"),
        options=(options, dict, "a dictionary of options by name"),
        priors=(priors, (dict, str, os.PathLike), "a dictionary or the path of a prior file"),
        grid=(grid, dict, "a dictionary of values by option"),
    )
    ts = _seconds("ts", ts)
    grid_items = None
    if grid is not None:
        # One value (a number, a text) is a list of one, not of its characters.
        one = (str, bytes, numbers.Number)
        listed = {k: [values] if isinstance(values, one) else list(values) for k, values in grid.items()}
        for k, values in listed.items():
            if not values:
                raise InputError(f"grid {k}: no values")
        texts = {k: [_option_text(v) for v in values] for k, values in listed.items()}
        for k, values in texts.items():
            for v in values:
                if "," in v:
                    raise InputError(f"grid {k}={v!r}: a value cannot hold a comma")
        grid_items = [f"{k}={','.join(values)}" for k, values in texts.items()]
    if priors is not None and not isinstance(priors, dict):
        priors = os.fspath(priors)
    return _hysid.identify(
        u,
        y,
        method=method,
        na=na,
        nb=nb,
        modes=modes,
        max_modes=max_modes,
        priors=priors,
        options=options,
        seed=seed,
        ts=ts,
        auto=auto,
        select_rows=_rows("select_rows", select_rows),
        folds=folds,
        select_records=select_records,
        refit_starts=refit_starts,
        grid=grid_items,
        warmup=warmup,
        standardize=standardize,
        time_budget=time_budget,
        input_names=_names("input_names", input_names),
        output_name=output_name,
    )


def compare(experiment: Union[str, os.PathLike], out_dir: Union[str, os.PathLike]) -> Dict[str, Any]:
    """Runs an experiment file (TOML, as ``hysid compare``), writes
    ``report.md``, ``report.json``, the figures and the models into
    ``out_dir``, and returns the report as a dictionary. In a folder that
    holds an earlier report, that report's models and figures the new one
    does not write are removed."""
    return _hysid.compare(os.fspath(experiment), os.fspath(out_dir))
