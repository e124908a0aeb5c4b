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

class CellEnv:
    """The library's step-by-step environment; `twincell.make_env` wraps it."""

    def __init__(
        self,
        scenario: _Path,
        perception: Literal["camera", "oracle"] = "camera",
        overrides: dict[str, Any] | None = None,
    ) -> None: ...
    def reset(self, trial: int, seed: int | None = None) -> dict[str, Any]: ...
    def step(
        self,
        joints: Any,
        tool_pose: Any,
        jaw_width: float,
        jaw_force: float,
        belt: bool,
        frame: bool,
    ) -> tuple[dict[str, Any], str | None, bool, bool]: ...
    def finish(self) -> str | None: ...
    def replay(self, actions: list[tuple[Any, Any, float, float, bool, bool]]) -> float: ...
    def write_batch(self, records: list[str], out: _Path) -> str: ...
    def close(self) -> None: ...
    @property
    def closed(self) -> bool: ...
    @property
    def control_period_s(self) -> float: ...
    @property
    def physics_steps_per_control(self) -> int: ...
    @property
    def scenario_seed(self) -> int: ...
    @property
    def scenario_json(self) -> str: ...
    @property
    def calibration(self) -> dict[str, Any]: ...
    @property
    def belt_top_z_m(self) -> float | None: ...
    @property
    def world_from_base(self) -> npt.NDArray[np.float64] | None: ...
    @property
    def joint_limits(self) -> npt.NDArray[np.float64]: ...
