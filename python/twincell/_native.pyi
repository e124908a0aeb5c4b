# Signatures of the compiled module (python/src/), for editors and type checkers; the
# docstrings are in the module itself (help(twincell.ik)).
from os import PathLike
from typing import Any, Literal, Sequence

import numpy as np
import numpy.typing as npt

_Path = str | PathLike[str]
_Pose = Sequence[float] | npt.NDArray[np.floating[Any]]

def detect(
    image: npt.NDArray[np.uint8], model: _Path | None = None
) -> list[dict[str, Any]]: ...
def measure(
    image: npt.NDArray[np.uint8], calibration: dict[str, Any] | None = None
) -> dict[str, list[dict[str, Any]]]: ...
def ik(
    pose: _Pose,
    scenario: _Path | None = None,
    link: Literal["flange", "tcp"] = "flange",
    **overrides: Any,
) -> npt.NDArray[np.float64]: ...
def fk(
    q: Sequence[float] | npt.NDArray[np.floating[Any]],
    scenario: _Path | None = None,
    link: Literal["flange", "tcp"] = "flange",
    **overrides: Any,
) -> npt.NDArray[np.float64]: ...
def plan_pick(
    percept: dict[str, Any],
    scenario: _Path,
    q_now: Sequence[float] | npt.NDArray[np.floating[Any]] | None = None,
    **overrides: Any,
) -> dict[str, Any]: ...
