"""hysid.Estimator: identification in scikit-learn's manner (parameters in
the constructor, ``fit`` returning the estimator, ``get_params`` and
``set_params`` for ``sklearn.base.clone``)."""

from __future__ import annotations

import inspect
import os
from typing import Any, Dict, Iterable, List, Optional, Union

import numpy as np
import numpy.typing as npt

from ._hysid import InputError, Model
from ._record import Record, Rows, one_record, records

#: The bound on the mode count an :class:`Estimator` gives by default, so
#: that ``Estimator().fit(record)`` runs: the back-end fits 1 .. 3 modes and
#: keeps the count that simulates held-out rows best.
DEFAULT_MAX_MODES = 3


class Estimator:
    """Identifies a :class:`hysid.Model` from a record, in scikit-learn's
    manner.

    The parameters are those of :func:`hysid.identify`, stored unchanged
    (they are checked by :meth:`fit`, and ``sklearn.base.clone`` copies
    them): ``method``, ``na``, ``nb``, ``modes``, ``max_modes``, ``auto``,
    ``priors``, ``options``, ``seed``, ``select_rows``, ``folds``,
    ``refit_starts``, ``grid``, ``warmup``, ``standardize``,
    ``time_budget``, ``select_records``. The record gives the sampling
    time and the names; :meth:`fit` and :meth:`metrics` also take a list
    of records of one system.

    One default differs from :func:`hysid.identify`'s: ``max_modes=3``, so
    that the default back-end, ``cluster``, which needs a mode count, runs
    as ``Estimator().fit(record)``: it fits 1 to 3 modes and keeps the count
    whose model simulates held-out rows best. That default gives way to
    any other source of the count: ``modes``, the priors' ``modes`` or
    ``max_modes``, and ``auto`` (which searches its own range); it still
    bounds ``bounded``'s count unless ``max_modes=None`` (a ``max_modes=3``
    given is taken as this default). For a back-end
    without discrete modes to choose (``physical``) give
    ``max_modes=None``.

    After :meth:`fit`, ``model_`` is the fitted :class:`hysid.Model`.
    ``warmup`` is also the number of samples :meth:`score` and
    :meth:`metrics` leave out, as ``hysid validate`` does.

    Example::

        est = hysid.Estimator(method="arx", na=2, nb=2).fit(record[:5000])
        est.score(record[5000:])       # FIT in percent, as hysid validate
    """

    def __init__(
        self,
        method: str = "cluster",
        na: int = 2,
        nb: int = 2,
        modes: Optional[int] = None,
        max_modes: Optional[int] = DEFAULT_MAX_MODES,
        auto: bool = False,
        priors: Union[Dict[str, Any], str, os.PathLike, None] = None,
        options: Optional[Dict[str, Any]] = None,
        seed: int = 0,
        select_rows: Rows = None,
        folds: Optional[int] = None,
        refit_starts: Optional[int] = None,
        grid: Optional[Dict[str, Iterable[Any]]] = None,
        warmup: int = 10,
        standardize: bool = False,
        time_budget: Optional[float] = None,
        select_records: Optional[int] = None,
    ) -> None:
        """Stores the parameters unchanged; :meth:`fit` checks them."""
        self.method = method
        self.na = na
        self.nb = nb
        self.modes = modes
        self.max_modes = max_modes
        self.auto = auto
        self.priors = priors
        self.options = options
        self.seed = seed
        self.select_rows = select_rows
        self.folds = folds
        self.refit_starts = refit_starts
        self.grid = grid
        self.warmup = warmup
        self.standardize = standardize
        self.time_budget = time_budget
        self.select_records = select_records

    @classmethod
    def _param_names(cls) -> List[str]:
        """The constructor's parameters, in order."""
        return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]

    def get_params(self, deep: bool = True) -> Dict[str, Any]:
        """The parameters by name, as given to the constructor or
        :meth:`set_params` (``deep`` is scikit-learn's; no parameter is an
        estimator)."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params: Any) -> "Estimator":
        """Sets parameters by name and returns the estimator; an unknown
        name raises :class:`hysid.InputError`. The fitted model, if any, is
        kept until the next :meth:`fit`."""
        known = self._param_names()
        for name, value in params.items():
            if name not in known:
                raise InputError(f"set_params: Estimator has no parameter '{name}' (parameters: {', '.join(known)})")
            setattr(self, name, value)
        return self

    def fit(
        self,
        data: Union[Record, List[Record], npt.ArrayLike],
        y: Optional[npt.ArrayLike] = None,
        *,
        ts: Optional[float] = None,
        input_names: Optional[List[str]] = None,
        output_name: Optional[str] = None,
    ) -> "Estimator":
        """Identifies the model and returns the estimator, with ``model_``
        set.

        ``data`` is a :class:`hysid.Record`, a list of records of one
        system (one model fitted on all of them, each from its own initial
        state; ``select_records=K`` with ``auto`` holds out the last ``K``),
        or the inputs ``u`` (``(N,)`` or ``(N, m)``) with the outputs ``y``
        (``(N,)`` or ``(N, 1)``) and, optionally, ``ts`` and the names. The
        record's names are kept in the model (``model_.input_names``,
        ``model_.output_name``).
        """
        from . import identify, methods

        takes = {m["name"]: m["priors"] for m in methods()}
        max_modes = self.max_modes
        given = isinstance(self.priors, dict) and ("modes" in self.priors or "max_modes" in self.priors)
        if max_modes == DEFAULT_MAX_MODES and (self.modes is not None or self.auto or given):
            max_modes = None
        if max_modes == DEFAULT_MAX_MODES and "max_modes" not in takes.get(self.method, ["max_modes"]):
            raise InputError(
                f"max_modes={DEFAULT_MAX_MODES} (the Estimator's default): method '{self.method}' takes no "
                "mode count; give max_modes=None"
            )
        found = self._records(data, y, ts, input_names, output_name, "fit")
        record = found[0]
        several = len(found) > 1
        self.model_ = identify(
            [r.u for r in found] if several else record.u,
            [r.y for r in found] if several else record.y,
            method=self.method,
            na=self.na,
            nb=self.nb,
            modes=self.modes,
            max_modes=max_modes,
            priors=self.priors,
            options=self.options,
            seed=self.seed,
            ts=record.ts,
            auto=self.auto,
            select_rows=self.select_rows,
            folds=self.folds,
            select_records=self.select_records,
            refit_starts=self.refit_starts,
            grid=self.grid,
            warmup=self.warmup,
            standardize=self.standardize,
            time_budget=self.time_budget,
            input_names=record.input_names,
            output_name=record.output_name,
        )
        return self

    def simulate(
        self,
        data: Union[Record, List[Record], npt.ArrayLike],
        *,
        y0: Optional[npt.ArrayLike] = None,
        ts: Optional[float] = None,
    ) -> npt.NDArray[np.float64]:
        """The fitted model's free-run simulation driven by the inputs
        alone: ``data`` is a :class:`hysid.Record` (its ``u`` and ``ts``;
        its ``y`` is not used) or the inputs ``u``.

        The simulation starts as the model's initial-state rule says, with
        zeros (or ``y0`` when given) for the measured outputs that rule
        reads: a PWARX model starts from zero outputs in its first
        ``max(na, nb)`` samples, as ``hysid simulate --excite`` does with
        ``--y0 0``; a mechanical model that reads its state from the
        outputs starts at rest at position 0; a model whose file gives its
        initial state starts from that state. Returns ``y`` of shape
        ``(N,)``; ``model_.simulate`` also returns the active modes."""
        model = self._fitted()
        u = data
        if _records_given(data):
            record = one_record(data, "data")
            u = record.u
            if ts is None:
                ts = record.ts
        y, _ = model.simulate(u, y0=y0, ts=ts)
        return y

    def predict_one_step(
        self,
        data: Union[Record, List[Record], npt.ArrayLike],
        y: Optional[npt.ArrayLike] = None,
    ) -> npt.NDArray[np.float64]:
        """The fitted model's one-step-ahead prediction of each output from
        the measured past inputs and outputs: ``data`` is a
        :class:`hysid.Record`, or the inputs ``u`` with the outputs ``y``.
        Returns the predicted ``y`` of shape ``(N,)``; the first samples,
        before the model's regressor is complete (``max(na, nb)`` for a
        PWARX model), are the measured outputs."""
        model = self._fitted()
        record = self._records(data, y, None, None, None, "predict_one_step")
        if len(record) > 1:
            raise InputError(f"predict_one_step: {len(record)} records given; this takes one record at a time")
        record = record[0]
        prediction, _ = model.predict(record.u, record.y, ts=record.ts)
        return prediction

    def metrics(
        self,
        data: Union[Record, List[Record], npt.ArrayLike],
        y: Optional[npt.ArrayLike] = None,
    ) -> Dict[str, Any]:
        """The fitted model's scores on a record, leaving out the first
        ``warmup`` samples: the dictionary of ``hysid validate --json``
        (``fit_sim``, ``rmse_sim``, ``fit_pred``, ``rmse_pred``,
        ``coverage``, ...). ``data`` is a :class:`hysid.Record`, a list of
        records (each scored in ``records``, the figures over all), or ``u``
        with ``y``."""
        model = self._fitted()
        found = self._records(data, y, None, None, None, "metrics")
        if len(found) > 1:
            return model.validate([r.u for r in found], [r.y for r in found], warmup=self.warmup,
                                  ts=found[0].ts)
        record = found[0]
        return model.validate(record.u, record.y, warmup=self.warmup, ts=record.ts)

    def score(
        self,
        data: Union[Record, List[Record], npt.ArrayLike],
        y: Optional[npt.ArrayLike] = None,
    ) -> float:
        """FIT of the free-run simulation in percent (100 is a perfect
        fit; higher is better), the figure ``hysid validate`` prints for
        the same model and rows: ``metrics(data, y)["fit_sim"]``."""
        return float(self.metrics(data, y)["fit_sim"])

    def _fitted(self) -> Model:
        """The fitted model, or an error saying to fit first."""
        model = getattr(self, "model_", None)
        if model is None:
            raise InputError("this Estimator is not fitted yet: call fit(record) first")
        return model

    @staticmethod
    def _records(
        data: Any,
        y: Optional[npt.ArrayLike],
        ts: Optional[float],
        input_names: Optional[List[str]],
        output_name: Optional[str],
        call: str,
    ) -> List[Record]:
        """The records of ``data`` (a record, a list of records) or the
        record of the arrays ``data`` and ``y``."""
        if _records_given(data):
            given = [n for n, v in (("y", y), ("ts", ts), ("input_names", input_names),
                                    ("output_name", output_name)) if v is not None]
            if given:
                raise InputError(f"{call}: {', '.join(given)} given with a record, which has its own")
            return records(data, "data")
        if y is None:
            raise InputError(f"{call}: y is missing (give a hysid.Record, or u and y)")
        return [Record(data, y, ts=ts, input_names=input_names, output_name=output_name)]

    #: scikit-learn before 1.6 reads the kind of estimator from here.
    _estimator_type = "regressor"

    def __sklearn_tags__(self) -> Any:
        """scikit-learn's tags (1.6 and later ask every estimator for them):
        a regressor whose ``fit`` needs ``y``. Asked for by scikit-learn
        alone, so scikit-learn is imported only then."""
        from sklearn.utils import RegressorTags, Tags, TargetTags

        return Tags(
            estimator_type="regressor",
            target_tags=TargetTags(required=True),
            regressor_tags=RegressorTags(),
        )

    def __repr__(self) -> str:
        """The parameters that differ from their defaults, as scikit-learn
        shows an estimator."""
        defaults = {p.name: p.default for p in inspect.signature(Estimator.__init__).parameters.values()}
        shown = [f"{k}={v!r}" for k, v in self.get_params().items() if defaults.get(k, object()) != v]
        return f"Estimator({', '.join(shown)})"


def _records_given(data: Any) -> bool:
    """True for a :class:`Record` or a list of records (an empty list
    too, refused by :func:`records`); False for arrays and lists of
    numbers (the inputs ``u``)."""
    if isinstance(data, Record):
        return True
    return isinstance(data, (list, tuple)) and (not data or any(isinstance(r, Record) for r in data))
