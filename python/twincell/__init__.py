"""twincell from Python: the digital twin's stages as functions over numpy arrays, and the
cell as a Gymnasium environment.

- ``make_env(scenario, perception="camera"|"oracle", seed=None, **overrides)``: a
  ``gymnasium.Env`` whose episodes are the scenario's trials, judged by the twin at their end.
- ``run_trials(scenario, policy, out)``: a controller over a scenario's trials, with the
  twin's report files (trials.jsonl, report.json, junit.xml, report.html).
- ``detect(image)``: the part detector on an RGB frame (numpy uint8, H x W x 3).
- ``measure(image, calibration=None)``: the paper's bore metrology, in pixels, and in
  millimetres on the end-face plane with a camera calibration.
- ``ik(pose, scenario=None, link="flange")`` and ``fk(q, ...)``: the arm's closed-form
  kinematics, of the built-in AUBO i5 or of a scenario's arm.
- ``plan_pick(percept, scenario)``: the twin's collision-checked grasp search.

Bad arguments raise ``ValueError`` or ``TypeError`` naming the argument and the reason.
"""

from ._native import detect, fk, ik, measure, plan_pick
from .env import PHYSICS_STEPS_PER_CONTROL, CellEnv, make_env, run_trials

__all__ = [
    "PHYSICS_STEPS_PER_CONTROL",
    "CellEnv",
    "detect",
    "fk",
    "ik",
    "make_env",
    "measure",
    "plan_pick",
    "run_trials",
]
