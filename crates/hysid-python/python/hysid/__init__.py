"""hysid: identify hybrid systems (piecewise ARX models, hybrid automata)
from data.

The functions here are those of the ``hysid`` program, on numpy arrays:

- :func:`methods` lists the back-ends (``hysid methods``);
- :func:`load` reads a CSV or MAT record (the program's selection rules);
- :func:`identify` fits a :class:`Model` (``hysid identify``);
- :class:`Model` simulates, predicts, validates (``hysid validate``) and
  reads and writes the program's model files;
- :func:`compare` runs an experiment file (``hysid compare``).

Bad input raises :class:`HysidError` (a ``ValueError``) with the program's
one-line message. Identification releases the GIL, and Ctrl-C stops it.
Figures: :mod:`hysid.plot` (needs matplotlib).
"""

from __future__ import annotations

import os
from typing import Any, Dict, Iterable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _hysid
from ._hysid import HysidError, Model

__all__ = ["HysidError", "Model", "compare", "identify", "load", "methods"]
__version__ = "0.1.0"

Rows = Union[str, Tuple[Optional[int], Optional[int]], slice, range, None]


def _rows(name: str, rows: Rows) -> Optional[str]:
    """A row selection as the program's ``A..B`` text."""
    if rows is None or isinstance(rows, str):
        return rows
    if isinstance(rows, (slice, range)):
        if rows.step not in (None, 1):
            raise HysidError(f"{name}: a step other than 1 is not a row range (use decimate)")
        start, stop = rows.start, rows.stop
    elif isinstance(rows, tuple) and len(rows) == 2:
        start, stop = rows
    else:
        raise HysidError(f"{name}: expected 'A..B', (A, B), range(A, B) or slice(A, B), got {rows!r}")
    a = "" if start is None else str(int(start))
    b = "" if stop is None else str(int(stop))
    return f"{a}..{b}"


def methods() -> list:
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
) -> Tuple[np.ndarray, np.ndarray, Optional[float]]:
    """Reads a ``.csv`` or ``.mat`` record.

    ``inputs`` (default ``"u"``) and ``output`` (default ``"y"``) name the
    columns or variables; ``decimate=K`` keeps samples 0, K, 2K, ...
    without a filter; ``rows`` (``"A..B"``, ``(A, B)`` or a range) applies
    after decimation; ``time`` (default ``"t"``) names the column or
    variable of the time in seconds, whose first step is the sampling time;
    ``ts`` is the sampling time when the file has none. Returns
    ``(u, y, ts)`` with ``u`` of shape ``(N, m)``.
    """
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
    u: Any,
    y: Any,
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
    refit_starts: Optional[int] = None,
    grid: Optional[Dict[str, Iterable[Any]]] = None,
    warmup: int = 10,
    standardize: bool = False,
    time_budget: Optional[float] = None,
    input_names: Optional[Sequence[str]] = None,
    output_name: Optional[str] = None,
) -> Model:
    """Identifies a model with back-end ``method`` (see :func:`methods`).

    ``u``: inputs, shape ``(N,)`` or ``(N, m)``; ``y``: outputs, ``(N,)``.
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
    3, when the seed can change the fit; the start that simulates those
    rows best is kept); ``model.info["selection"]`` records the
    candidates, the choice and the refit's starts. ``standardize=True`` identifies on
    standardised data. ``time_budget``: seconds after which long back-ends
    return their best model. ``warmup``: samples left out of free-run scores.

    Without ``auto``, a ``UserWarning`` says when the model simulates its
    identification rows worse than an affine ARX model of the same orders.
    """
    grid_items = None
    if grid is not None:
        grid_items = [f"{k}={','.join(str(v) for v in values)}" for k, values in grid.items()]
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
        refit_starts=refit_starts,
        grid=grid_items,
        warmup=warmup,
        standardize=standardize,
        time_budget=time_budget,
        input_names=None if input_names is None else list(input_names),
        output_name=output_name,
    )


def compare(experiment: Union[str, os.PathLike], out_dir: Union[str, os.PathLike]) -> dict:
    """Runs an experiment file (TOML, as ``hysid compare``), writes
    ``report.md``, ``report.json``, the figures and the models into
    ``out_dir``, and returns the report as a dictionary."""
    return _hysid.compare(os.fspath(experiment), os.fspath(out_dir))
