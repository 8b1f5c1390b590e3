"""Type stubs of the extension module hysid._hysid (Rust, pyo3)."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
PathLike = Union[str, os.PathLike]

class HysidError(ValueError):
    """Bad input or a failed identification: the message is the program's one line."""

class Model:
    """A hysid model: a PWARX model, a hybrid automaton or a mechanical model."""

    @staticmethod
    def load(path: PathLike) -> Model: ...
    @staticmethod
    def from_json(text: str) -> Model: ...
    def to_json(self) -> str: ...
    def save(self, path: PathLike) -> None: ...
    @property
    def kind(self) -> str: ...
    @property
    def method(self) -> str: ...
    @property
    def mode_count(self) -> int: ...
    @property
    def mode_names(self) -> List[str]: ...
    @property
    def inputs(self) -> int: ...
    @property
    def orders(self) -> Optional[Tuple[int, int]]: ...
    @property
    def ts(self) -> Optional[float]: ...
    @property
    def thetas(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def regions(self) -> List[Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]]: ...
    @property
    def stops(self) -> List[Tuple[float, str]]: ...
    @property
    def info(self) -> Dict[str, Any]: ...
    def simulate(
        self, u: ArrayLike, y0: Optional[ArrayLike] = None, ts: Optional[float] = None
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]: ...
    def predict(
        self, u: ArrayLike, y: ArrayLike, ts: Optional[float] = None
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]: ...
    def validate(
        self, u: ArrayLike, y: ArrayLike, warmup: int = 10, ts: Optional[float] = None
    ) -> Dict[str, Any]: ...

def methods() -> List[Dict[str, Any]]: ...
def load(
    path: PathLike,
    inputs: Optional[List[str]] = None,
    output: Optional[str] = None,
    decimate: int = 1,
    rows: Optional[str] = None,
    ts: Optional[float] = None,
    time: Optional[str] = None,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], Optional[float]]: ...
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
    refit_starts: Optional[int] = None,
    grid: Optional[Sequence[str]] = None,
    warmup: int = 10,
    standardize: bool = False,
    time_budget: Optional[float] = None,
    input_names: Optional[List[str]] = None,
    output_name: Optional[str] = None,
) -> Model: ...
def compare(experiment: PathLike, out_dir: PathLike) -> Dict[str, Any]: ...
