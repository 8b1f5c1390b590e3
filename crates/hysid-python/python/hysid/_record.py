"""hysid.Record: one experiment's inputs, output, sampling time and names,
from numpy arrays, a pandas DataFrame or a record file."""

from __future__ import annotations

import math
import numbers
import os
from typing import Any, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _hysid
from ._hysid import InputError

Rows = Union[str, Tuple[Optional[int], Optional[int]], slice, range, None]


def _rows(name: str, rows: Rows) -> Optional[str]:
    """A row selection as the program's ``A..B`` text."""
    if rows is None or isinstance(rows, str):
        return rows
    if isinstance(rows, (slice, range)):
        if rows.step not in (None, 1):
            raise InputError(f"{name}: a step other than 1 is not a row range (use decimate)")
        start, stop = rows.start, rows.stop
    elif isinstance(rows, tuple) and len(rows) == 2:
        start, stop = rows
    else:
        raise InputError(f"{name}: expected 'A..B', (A, B), range(A, B) or slice(A, B), got {rows!r}")
    for bound in (start, stop):
        if bound is not None and (isinstance(bound, bool) or not isinstance(bound, numbers.Integral)):
            raise InputError(f"{name}: row bounds must be whole numbers, got {bound!r}")
    a = "" if start is None else str(int(start))
    b = "" if stop is None else str(int(stop))
    return f"{a}..{b}"


def _seconds(name: str, given: Any) -> Optional[float]:
    """A sampling time given as argument ``name``: ``None``, or a positive
    finite number of seconds (not a bool); an :class:`InputError` naming
    the argument otherwise."""
    if given is None:
        return None
    if isinstance(given, bool) or not isinstance(given, numbers.Real):
        raise InputError(f"{name}={given!r}: must be a number of seconds")
    if not (math.isfinite(given) and given > 0):
        raise InputError(f"{name}={given!r}: must be a positive number of seconds")
    return float(given)


def _names(name: str, given: Union[str, Sequence[str], None]) -> Optional[List[str]]:
    """Signal names given as one name, a comma-separated list or a sequence."""
    if given is None:
        return None
    if isinstance(given, str):
        return given.split(",")
    try:
        return [str(s) for s in given]
    except TypeError:
        raise InputError(f"{name}: expected a name or a list of names, got {given!r}") from None


class Record:
    """One experiment: inputs ``u`` of shape ``(N, m)``, output ``y`` of
    shape ``(N,)``, sampling time ``ts`` in seconds (``None`` when unknown)
    and the signals' names ``input_names`` and ``output_name``.

    ``Record(u, y, ts=None, input_names=None, output_name=None)`` is
    :meth:`from_numpy`. The arrays are checked as :func:`hysid.identify`
    checks them (lengths, finite values, a positive sampling time, names
    neither empty nor repeated); a failed check raises
    :class:`hysid.InputError`. ``record[a:b]`` is the record of rows
    ``a..b``; ``len(record)`` is ``N``.

    One record is one experiment. :meth:`hysid.Estimator.fit` and
    :meth:`~hysid.Estimator.metrics` take a list of records of one system
    (one model fitted on all, each record scored on its own and all
    together); simulation and prediction take one record (a list of one is
    that record).
    """

    u: npt.NDArray[np.float64]
    y: npt.NDArray[np.float64]
    ts: Optional[float]
    input_names: List[str]
    output_name: str

    def __init__(
        self,
        u: npt.ArrayLike,
        y: npt.ArrayLike,
        ts: Optional[float] = None,
        input_names: Optional[Sequence[str]] = None,
        output_name: Optional[str] = None,
    ) -> None:
        """Checks and stores the record; see :meth:`from_numpy`."""
        ts = _seconds("ts", ts)
        if output_name is not None and not isinstance(output_name, str):
            raise InputError(f"output_name={output_name!r}: must be a name")
        u, y, names, output = _hysid.check_record(
            u,
            y,
            ts=ts,
            input_names=_names("input_names", input_names),
            output_name=output_name,
        )
        self.u = u
        self.y = y
        self.ts = ts
        self.input_names = names
        self.output_name = output

    @classmethod
    def from_numpy(
        cls,
        u: npt.ArrayLike,
        y: npt.ArrayLike,
        ts: Optional[float] = None,
        input_names: Optional[Sequence[str]] = None,
        output_name: Optional[str] = None,
    ) -> "Record":
        """A record from arrays: ``u`` of shape ``(N,)`` (one input) or
        ``(N, m)``, ``y`` of shape ``(N,)`` or ``(N, 1)``; ``ts`` the
        sampling time in seconds. Names default to the program's: ``u``
        (one input) or ``u1 .. um``, and ``y``."""
        return cls(u, y, ts=ts, input_names=input_names, output_name=output_name)

    @classmethod
    def from_dataframe(
        cls,
        df: Any,
        inputs: Union[str, Sequence[str]],
        output: str,
        time: Optional[str] = None,
        ts: Optional[float] = None,
    ) -> "Record":
        """A record from the columns of a pandas DataFrame: ``inputs`` (a
        column name or a list of them) and ``output`` (one column) keep
        their names. ``time`` names a column of times (in seconds, or
        timestamps) whose first step is the sampling time (as the program
        reads a record's time column); ``ts`` gives the sampling time
        instead. pandas itself is not imported: any object with ``columns``
        and ``df[name]`` whose columns convert to float arrays will do."""
        columns = getattr(df, "columns", None)
        if columns is None:
            raise InputError(f"df: expected a pandas DataFrame, got {type(df).__name__}")
        # One text is one column name (a DataFrame's names may hold commas).
        # One label is one column (a DataFrame's names may hold commas, or
        # be numbers); the record's names are the labels as text.
        one = (str, numbers.Number)
        labels = [inputs] if isinstance(inputs, one) else list(inputs)
        if not labels:
            raise InputError("inputs: no input column named")
        if not isinstance(output, one):
            raise InputError(f"output: expected one column label, got {output!r}")
        known = list(columns)

        def present(argument: str, name: Any) -> None:
            if name not in known:
                shown = ", ".join(str(c) for c in known)
                raise InputError(f"{argument}: no column {name!r} in the DataFrame (columns: {shown})")

        def column(argument: str, name: Any) -> npt.NDArray[np.float64]:
            present(argument, name)
            try:
                return np.asarray(df[name], dtype=np.float64)
            except (TypeError, ValueError) as e:
                raise InputError(f"{argument}: column {name!r} is not numeric ({e})") from None

        u = np.column_stack([column("inputs", n) for n in labels])
        y = column("output", output)
        names = [str(n) for n in labels]
        if time is not None:
            if ts is not None:
                raise InputError(f"time='{time}' and ts={ts}: give the sampling time one way")
            present("time", time)
            if time in labels or time == output:
                raise InputError(f"time: column '{time}' is also a signal; the time must be another column")
            series = df[time]
            # Timestamps with a time zone: their instants, in UTC.
            accessor = getattr(series, "dt", None)
            if getattr(accessor, "tz", None) is not None:
                series = accessor.tz_convert(None)
            t = np.asarray(series)
            if t.dtype.kind in "mM" and len(t):
                # Timestamps or durations: seconds from the first.
                seconds = (t - t[0]) / np.timedelta64(1, "s")
            else:
                seconds = column("time", time)
            ts = _hysid.sampling_time(time, np.asarray(seconds, dtype=np.float64).tolist())
        return cls(u, y, ts=ts, input_names=names, output_name=str(output))

    @classmethod
    def load(
        cls,
        path: Union[str, os.PathLike],
        inputs: Union[str, Sequence[str], None] = None,
        output: Optional[str] = None,
        time: Optional[str] = None,
        decimate: int = 1,
        rows: Rows = None,
        ts: Optional[float] = None,
    ) -> "Record":
        """Reads a ``.csv`` or ``.mat`` record with the program's selection
        rules, as :func:`hysid.load` does (same arguments: ``inputs``
        default ``"u"``, ``output`` default ``"y"``, ``time`` default
        ``"t"``, ``decimate``, ``rows``, ``ts``), keeping the names."""
        from . import load

        names = _names("inputs", inputs)
        u, y, found_ts = load(path, inputs=names, output=output, decimate=decimate, rows=rows, ts=ts, time=time)
        return cls(u, y, ts=found_ts, input_names=names or ["u"], output_name=output or "y")

    def __len__(self) -> int:
        """Number of samples ``N``."""
        return len(self.y)

    def __getitem__(self, rows: slice) -> "Record":
        """The record of the rows ``rows`` (a slice with step 1)."""
        if not isinstance(rows, slice):
            raise InputError(f"rows: a record is cut by a slice (record[a:b]), got {rows!r}")
        if rows.step not in (None, 1):
            raise InputError("rows: a step other than 1 changes the sampling time (use decimate when loading)")
        return Record(self.u[rows], self.y[rows], self.ts, self.input_names, self.output_name)

    def to_dataframe(self) -> Any:
        """The record as a pandas DataFrame (needs pandas): a time column
        ``t`` in seconds when ``ts`` is known, the inputs, then the output,
        by their names."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Record.to_dataframe needs pandas: pip install pandas") from e
        columns = {}
        if self.ts is not None and "t" not in self.input_names + [self.output_name]:
            columns["t"] = np.arange(len(self)) * self.ts
        for i, name in enumerate(self.input_names):
            columns[name] = self.u[:, i]
        columns[self.output_name] = self.y
        return pd.DataFrame(columns)

    def __repr__(self) -> str:
        """``Record(N=..., inputs=[...], output=..., ts=...)``."""
        return (
            f"Record(N={len(self)}, inputs={self.input_names!r}, output={self.output_name!r}, ts={self.ts!r})"
        )


def records(given: Any, argument: str = "record") -> List[Record]:
    """The records in ``given``: a :class:`Record` or a non-empty list of
    them, all with as many inputs and the same sampling time (the model
    takes the first record's names)."""
    if isinstance(given, Record):
        return [given]
    if isinstance(given, (list, tuple)) and all(isinstance(r, Record) for r in given):
        if not given:
            raise InputError(f"{argument}: an empty list of records")
        first = given[0]
        for i, r in enumerate(given[1:], start=2):
            if len(r.input_names) != len(first.input_names):
                raise InputError(
                    f"{argument}: record {i} has {len(r.input_names)} input(s), record 1 {len(first.input_names)}"
                )
            if r.ts != first.ts:
                raise InputError(f"{argument}: record {i} has ts={r.ts!r}, record 1 ts={first.ts!r}")
        return list(given)
    raise InputError(f"{argument}: expected a hysid.Record (or u and y arrays), got {type(given).__name__}")


def one_record(given: Any, argument: str = "record") -> Record:
    """The record in ``given``: a :class:`Record` or a list of one; a list
    of several raises :class:`InputError`."""
    found = records(given, argument)
    if len(found) > 1:
        raise InputError(f"{argument}: {len(found)} records given; this takes one record at a time")
    return found[0]
