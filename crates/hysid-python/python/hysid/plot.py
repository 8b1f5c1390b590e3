"""Figures with matplotlib (``pip install matplotlib``): a model's
free-run simulation against a record, and a two-dimensional slice of a
PWARX model's regions (where holes between regions show as white)."""

from __future__ import annotations

from typing import Any, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

from ._hysid import InputError, Model


def _pyplot():
    try:
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("hysid.plot needs matplotlib: pip install matplotlib") from e
    return plt


def _inputs(u: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Inputs as an ``(N, m)`` array."""
    u = np.asarray(u, dtype=float)
    return u.reshape(-1, 1) if u.ndim == 1 else u


def _output(y: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The output as an ``(N,)`` array (an ``(N, 1)`` column is one output)."""
    y = np.asarray(y, dtype=float)
    return y.ravel() if y.ndim == 2 and y.shape[1] == 1 else y


def _record(model: Model, u: npt.ArrayLike, y: npt.ArrayLike) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """``u`` as ``(N, m)`` and ``y`` as ``(N,)``, checked against each other
    and the model's inputs."""
    u, y = _inputs(u), _output(y)
    if u.ndim != 2 or u.shape[1] != model.inputs:
        raise InputError(f"u: expected shape (N, {model.inputs}) for the model's inputs, got {u.shape}")
    if y.ndim != 1:
        raise InputError(f"y: expected shape (N,) or (N, 1), got {y.shape}")
    if len(y) != len(u):
        raise InputError(f"y: {len(y)} samples, u has {len(u)}")
    return u, y


def _mode_colours(n: int) -> Any:
    """A colour per mode: the first ``n`` of a qualitative map, or a
    continuous one beyond 20 modes."""
    import matplotlib
    from matplotlib.colors import ListedColormap

    for name in ("tab10", "tab20"):
        base = matplotlib.colormaps[name]
        if n <= base.N:
            return ListedColormap(base.colors[:n])
    return matplotlib.colormaps["viridis"]


def regressors(model: Model, u: npt.ArrayLike, y: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The PWARX regressors ``x(k) = [y(k-1) .. y(k-na), u_i(k-1) ..
    u_i(k-nb)]`` of a record, one row per sample ``k >= max(na, nb)``."""
    if model.orders is None:
        raise InputError(f"a {model.kind} model has no ARX regressor")
    na, nb = model.orders
    u, y = _record(model, u, y)
    start = max(na, nb)
    rows = range(start, len(y))
    cols = [y[[k - j for k in rows]] for j in range(1, na + 1)]
    for i in range(u.shape[1]):
        cols += [u[[k - j for k in rows], i] for j in range(1, nb + 1)]
    return np.column_stack(cols) if cols else np.zeros((len(rows), 0))


def regressor_names(model: Model) -> List[str]:
    """Names of the regressor coordinates, as :func:`regressors` orders them."""
    if model.orders is None:
        raise InputError(f"a {model.kind} model has no ARX regressor")
    na, nb = model.orders
    names = [f"y(k-{j})" for j in range(1, na + 1)]
    for i in range(model.inputs):
        tag = "u" if model.inputs == 1 else f"u{i + 1}"
        names += [f"{tag}(k-{j})" for j in range(1, nb + 1)]
    return names


def simulation(
    model: Model,
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    ax: Optional[Sequence[Any]] = None,
    ts: Optional[float] = None,
) -> Any:
    """Measured ``y`` against the model's free-run simulation driven by
    ``u`` (started from the measured outputs), with the active mode below.
    Returns the figure."""
    plt = _pyplot()
    u, y = _record(model, u, y)
    sim, mode = model.simulate(u, y0=y, ts=ts)
    step = ts or model.ts or 1.0
    t = np.arange(len(y)) * step
    if ax is None:
        fig, ax = plt.subplots(2, 1, sharex=True, figsize=(8, 5), height_ratios=(3, 1))
    else:
        fig = ax[0].figure
    ax[0].plot(t, y, label="measured", color="black", linewidth=1)
    ax[0].plot(t, sim, label="simulated", color="tab:red", linewidth=1)
    ax[0].set_ylabel("y")
    ax[0].legend(loc="best")
    shown = np.where(mode >= 0, mode + 1, np.nan)
    ax[1].step(t, shown, where="post", color="tab:blue", linewidth=1)
    ax[1].set_ylabel("mode")
    ax[1].set_xlabel("time [s]" if (ts or model.ts) else "sample")
    return fig


def regions(
    model: Model,
    dims: Tuple[int, int] = (0, 1),
    at: Optional[Any] = None,
    lims: Optional[Tuple[Tuple[float, float], Tuple[float, float]]] = None,
    data: Optional[Tuple[npt.ArrayLike, npt.ArrayLike]] = None,
    resolution: int = 200,
    ax: Any = None,
) -> Any:
    """A slice of a PWARX model's regions through regressor coordinates
    ``dims``, the others held at ``at`` (default: the mean of ``data``'s
    regressors, else zero). ``lims`` bounds the two axes (default: the
    range of ``data``'s regressors, else [-1, 1]). ``data=(u, y)`` also
    draws the record's regressors. Points in no region (holes) are white.
    Returns the figure."""
    plt = _pyplot()
    if model.kind != "pwarx":
        raise InputError(f"regions are drawn for PWARX models; this one is {model.kind}")
    names = regressor_names(model)
    d = len(names)
    if len(dims) != 2:
        raise InputError(f"dims={dims}: two coordinates")
    if isinstance(resolution, bool) or not isinstance(resolution, int) or resolution < 2:
        raise InputError(f"resolution={resolution!r}: must be a whole number >= 2")
    i, j = dims
    if not (0 <= i < d and 0 <= j < d and i != j):
        raise InputError(f"dims={dims}: two different coordinates in 0..{d - 1} ({', '.join(names)})")
    x = regressors(model, *data) if data is not None else None
    if x is not None and len(x) == 0:
        raise InputError("data: no regressor (the record is shorter than the model's lags)")
    centre = np.asarray(at, dtype=float) if at is not None else (x.mean(axis=0) if x is not None else np.zeros(d))
    if centre.shape != (d,):
        raise InputError(f"at: expected {d} values ({', '.join(names)}), got shape {centre.shape}")
    if lims is None:
        lims = tuple((x[:, k].min(), x[:, k].max()) if x is not None else (-1.0, 1.0) for k in (i, j))
    gx = np.linspace(*lims[0], resolution)
    gy = np.linspace(*lims[1], resolution)
    X, Y = np.meshgrid(gx, gy)
    points = np.tile(centre, (X.size, 1))
    points[:, i], points[:, j] = X.ravel(), Y.ravel()
    owner = np.full(X.size, np.nan)
    for q, (A, b) in enumerate(model.regions):
        inside = np.all(points @ A.T <= b + 1e-9, axis=1) if len(b) else np.ones(X.size, bool)
        owner[np.isnan(owner) & inside] = q + 1
    if ax is None:
        fig, ax = plt.subplots(figsize=(6, 5))
    else:
        fig = ax.figure
    n = model.mode_count
    mesh = ax.pcolormesh(X, Y, owner.reshape(X.shape), cmap=_mode_colours(n), vmin=0.5, vmax=n + 0.5, shading="auto")
    if x is not None:
        ax.scatter(x[:, i], x[:, j], s=2, color="black", alpha=0.4)
    ax.set_xlabel(names[i])
    ax.set_ylabel(names[j])
    fig.colorbar(mesh, ax=ax, label="mode", ticks=range(1, model.mode_count + 1))
    return fig
