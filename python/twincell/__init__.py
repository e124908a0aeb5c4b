"""twincell from Python: the digital twin's stages as functions over numpy arrays.

- ``detect(image)``: the part detector on an RGB frame (numpy uint8, H x W x 3).
- ``measure(image, calibration=None)``: the paper's bore metrology, in pixels, and in
  millimetres on the end-face plane with a camera calibration.
- ``ik(pose, scenario=None, link="flange")`` and ``fk(q, ...)``: the arm's closed-form
  kinematics, of the built-in AUBO i5 or of a scenario's arm.
- ``plan_pick(percept, scenario)``: the twin's collision-checked grasp search.

Bad arguments raise ``ValueError`` or ``TypeError`` naming the argument and the reason.
"""

from ._native import detect, fk, ik, measure, plan_pick

__all__ = ["detect", "fk", "ik", "measure", "plan_pick"]
