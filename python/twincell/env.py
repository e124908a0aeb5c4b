"""The twin as a Gymnasium environment: one episode is one trial of a scenario, judged by the
twin at its end.

``make_env(scenario, perception="camera"|"oracle", seed=None, **overrides)`` returns a
``CellEnv``. Each ``step`` advances one control period: ``PHYSICS_STEPS_PER_CONTROL`` physics
steps (8 of the default 1/240 s, so 1/30 s); ``env.unwrapped.control_period_s`` gives it for
the scenario's time step. See docs/python.md for the observation, the action and ``info``.
"""

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from . import _native

PHYSICS_STEPS_PER_CONTROL = 8
MAX_JAW_WIDTH_M = 0.1
MAX_JAW_FORCE_N = 100.0

_ACTION_KEYS = ("arm_mode", "joints", "tool_pose", "jaw_width", "jaw_force", "belt", "frame")
_ACTION_KEY_SET = frozenset(_ACTION_KEYS)
_OPTION_KEYS = ("trial",)
# Bounds of a tool pose target: [x, y, z] m in the world, [roll, pitch, yaw] rad.
_POSE_LOW = np.array([-2.0, -2.0, -1.0, -math.pi, -math.pi, -math.pi])
_POSE_HIGH = np.array([2.0, 2.0, 3.0, math.pi, math.pi, math.pi])


def _read_only(array):
    array.flags.writeable = False
    return array


def _one_number(key, value):
    """A scalar, or an array of one number, as a float; anything else names the key."""
    if type(value) is float:
        number = value
    elif type(value) is np.ndarray and value.shape == (1,) and value.dtype.kind == "f":
        number = float(value[0])
    else:
        number = None
    if number is not None:
        if not math.isfinite(number):
            raise ValueError(f"action[{key!r}]: {number} is not a finite number")
        return number
    array = np.asarray(value)
    if array.dtype.kind not in "biuf":
        raise TypeError(f"action[{key!r}]: expected a number, got {type(value).__name__}")
    if array.size != 1 or array.ndim > 1:
        raise ValueError(
            f"action[{key!r}]: expected one number (shape (1,)), got shape {array.shape}"
        )
    number = float(array.reshape(-1)[0])
    if not math.isfinite(number):
        raise ValueError(f"action[{key!r}]: {number} is not a finite number")
    return number


def _flag(key, value):
    if type(value) is int and value in (0, 1):
        return bool(value)
    array = np.asarray(value)
    if array.size != 1 or array.dtype.kind not in "biu":
        raise ValueError(f"action[{key!r}]: expected 0 or 1, got {value!r}")
    flag = int(array.reshape(-1)[0])
    if flag not in (0, 1):
        raise ValueError(f"action[{key!r}]: expected 0 or 1, got {flag}")
    return bool(flag)


class CellEnv(gym.Env):
    """One scenario's sorting cell; an episode is one of its trials."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, scenario, perception="camera", seed=None, render_mode=None, **overrides):
        if perception not in ("camera", "oracle"):
            raise ValueError(f'perception: {perception!r} is not "camera" or "oracle"')
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f'render_mode: {render_mode!r} is not None or "rgb_array"')
        if seed is not None and (not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ValueError(f"seed: expected a non-negative integer or None, got {seed!r}")
        self.scenario_path = Path(scenario)
        self.perception = perception
        self.render_mode = render_mode
        self._native = _native.CellEnv(str(self.scenario_path), perception, overrides or None)
        self.scenario = json.loads(self._native.scenario_json)
        self.control_period_s = self._native.control_period_s
        self.calibration = self._native.calibration
        self._base_seed = int(seed) if seed is not None else int(self.scenario["seed"])
        self._trial = None
        self._ended = False
        width, height = self.calibration["width_px"], self.calibration["height_px"]
        self._frame_shape = (height, width, 3)
        self._frame = np.zeros(self._frame_shape, dtype=np.uint8)
        self._frames = 0
        c = self.calibration
        self._intrinsics = np.array([c["fx_px"], c["fy_px"], c["cx_px"], c["cy_px"]])
        self._world_from_camera = np.array(c["world_from_camera"], dtype=np.float64)
        self.part_types = [t["name"] for t in self.scenario["part_types"]]
        self.bins = [b["name"] for b in self.scenario["bins"]]
        bottle = self.scenario["bottle"]
        self.max_bottles = int(bottle["count_range"][1]) if bottle["enabled"] else 0
        limits = self._native.joint_limits
        self.joint_limits = _read_only(limits)
        self._jaw = (MAX_JAW_WIDTH_M * 0.9, float(self.scenario["gripper"]["grip_force_n"]))

        inf = np.inf
        observation = {
            "joint_positions": spaces.Box(-2 * math.pi, 2 * math.pi, (6,), np.float64),
            "joint_velocities": spaces.Box(-inf, inf, (6,), np.float64),
            "jaw_width": spaces.Box(0.0, 2 * MAX_JAW_WIDTH_M, (1,), np.float64),
            "jaw_force": spaces.Box(0.0, inf, (2,), np.float64),
            "photo_eye": spaces.Discrete(2),
            "belt_position": spaces.Box(-inf, inf, (1,), np.float64),
            "belt_speed": spaces.Box(-inf, inf, (1,), np.float64),
            "sim_time": spaces.Box(0.0, inf, (1,), np.float64),
            "frame": spaces.Box(0, 255, (height, width, 3), np.uint8),
            "frame_index": spaces.Box(0, 2**62, (1,), np.int64),
            "camera_intrinsics": spaces.Box(0.0, inf, (4,), np.float64),
            "world_from_camera": spaces.Box(-inf, inf, (4, 4), np.float64),
        }
        if perception == "oracle":
            observation["truth"] = spaces.Dict({
                "part_type": spaces.Discrete(len(self.part_types)),
                "part_pose": spaces.Box(-inf, inf, (4, 4), np.float64),
                "roundness_mm": spaces.Box(0.0, inf, (1,), np.float64),
                "bore_diameter_mm": spaces.Box(0.0, inf, (1,), np.float64),
                # len(bins) when no bin is right.
                "correct_bin": spaces.Discrete(len(self.bins) + 1),
                "bottle_poses": spaces.Box(-inf, inf, (self.max_bottles, 4, 4), np.float64),
                "bottle_count": spaces.Discrete(self.max_bottles + 1),
            })
        self.observation_space = spaces.Dict(observation)
        self.action_space = spaces.Dict({
            # 0: `joints` are the targets; 1: `tool_pose` is, through the twin's IK.
            "arm_mode": spaces.Discrete(2),
            "joints": spaces.Box(limits[:, 0], limits[:, 1], (6,), np.float64),
            "tool_pose": spaces.Box(_POSE_LOW, _POSE_HIGH, (6,), np.float64),
            "jaw_width": spaces.Box(0.0, MAX_JAW_WIDTH_M, (1,), np.float64),
            "jaw_force": spaces.Box(0.0, MAX_JAW_FORCE_N, (1,), np.float64),
            "belt": spaces.Discrete(2),
            "frame": spaces.Discrete(2),
        })

    # -- the episode ------------------------------------------------------------------------

    def reset(self, *, seed=None, options=None):
        """Starts a trial: ``options={"trial": i}`` picks the scenario's trial ``i``; ``seed``
        is the scenario seed trials are drawn from (kept for later resets). Without a trial,
        a new seed starts at trial 0 and no seed goes on to the next trial."""
        super().reset(seed=seed)
        options = {} if options is None else options
        if not isinstance(options, dict):
            raise TypeError(f"options: expected a dict or None, got {type(options).__name__}")
        for key in options:
            if key not in _OPTION_KEYS:
                raise ValueError(f"options: unknown key {key!r} (known: {', '.join(_OPTION_KEYS)})")
        if seed is not None:
            if seed < 0:
                raise ValueError(f"seed: expected a non-negative integer, got {seed}")
            self._base_seed = int(seed)
        if "trial" in options:
            trial = options["trial"]
            if not isinstance(trial, (int, np.integer)) or isinstance(trial, bool) or trial < 0:
                raise ValueError(f"options['trial']: expected a non-negative integer, got {trial!r}")
            trial = int(trial)
        elif seed is not None or self._trial is None:
            trial = 0
        else:
            trial = self._trial + 1
        raw = self._native.reset(trial, self._base_seed)
        self._trial = trial
        self._ended = False
        self._frame = np.zeros(self._frame_shape, dtype=np.uint8)
        self._frames = 0
        self._jaw = (float(raw["jaw_width"][0]), float(self.scenario["gripper"]["grip_force_n"]))
        return self._observation(raw), {"trial": trial, "scenario_seed": self._base_seed}

    def step(self, action):
        if self._native.closed:
            self._native.reset(0)  # raises: the environment is closed
        joints, tool_pose, jaw_width, jaw_force, belt, frame = self._parse(action)
        raw, record, ik_unreachable, timed_out = self._native.step(
            joints, tool_pose, jaw_width, jaw_force, belt, frame
        )
        self._jaw = (jaw_width, jaw_force)
        obs = self._observation(raw)
        info = {"trial": self._trial, "ik_unreachable": ik_unreachable}
        if record is None:
            return obs, 0.0, False, False, info
        self._ended = True
        info.update(self._verdict(json.loads(record)))
        reward = 1.0 if info["success"] else 0.0
        return obs, reward, not timed_out, timed_out, info

    def finish(self):
        """Ends the running trial now (a controller that gives up) and returns the judge's
        ``info`` for it, as ``step`` gives at an episode's end."""
        record = self._native.finish()
        if record is None:
            raise RuntimeError("finish: no episode has started: call reset first")
        self._ended = True
        return self._verdict(json.loads(record))

    def render(self):
        """The last frame the controller asked for (``render_mode="rgb_array"``)."""
        if self.render_mode == "rgb_array":
            return self._frame.copy()
        return None

    def close(self):
        self._native.close()

    @property
    def closed(self):
        return self._native.closed

    @property
    def world_from_base(self):
        """The arm's base in the world, 4 x 4 (tool poses for ``twincell.ik(pose,
        scenario, link="tcp")`` are in the base's frame)."""
        return self._native.world_from_base

    @property
    def belt_top_z_m(self):
        """Top of the belt, world z, m (parts stand on it)."""
        return self._native.belt_top_z_m

    # -- conversions ------------------------------------------------------------------------

    def _parse(self, action):
        if not isinstance(action, dict):
            raise TypeError(f"action: expected a dict, got {type(action).__name__}")
        for key in action.keys() - _ACTION_KEY_SET:
            if key not in _ACTION_KEY_SET:
                raise ValueError(f"action: unknown key {key!r} (known: {', '.join(_ACTION_KEYS)})")
        if "arm_mode" in action:
            mode = int(_flag("arm_mode", action["arm_mode"]))
        elif "tool_pose" in action and "joints" not in action:
            mode = 1
        else:
            mode = 0
        key = "tool_pose" if mode == 1 else "joints"
        if key not in action:
            raise ValueError(f"action: arm_mode {mode} needs the key {key!r}")
        target = action[key]
        jaw_width = _one_number("jaw_width", action.get("jaw_width", self._jaw[0]))
        jaw_force = _one_number("jaw_force", action.get("jaw_force", self._jaw[1]))
        belt = _flag("belt", action.get("belt", 0))
        frame = _flag("frame", action.get("frame", 0))
        if mode == 0:
            return target, None, jaw_width, jaw_force, belt, frame
        return None, target, jaw_width, jaw_force, belt, frame

    def _observation(self, raw):
        # Every observation owns its arrays (Gymnasium's rule: users keep them). A frame comes
        # only after the step that asked for it; the others carry a blank one: a read-only
        # view of one fresh zero byte (allocating and clearing 3.7 MB took 200 us a step).
        frame = raw.get("frame")
        if frame is not None:
            self._frame = frame
            self._frames += 1
        else:
            raw["frame"] = np.broadcast_to(np.zeros(1, dtype=np.uint8), self._frame_shape)
        raw["frame_index"] = np.array([self._frames], dtype=np.int64)
        raw["camera_intrinsics"] = self._intrinsics.copy()
        raw["world_from_camera"] = self._world_from_camera.copy()
        truth = raw.get("truth")
        if truth is not None:
            poses = np.zeros((self.max_bottles, 4, 4))
            count = min(len(truth["bottle_poses"]), self.max_bottles)
            for i in range(count):
                poses[i] = truth["bottle_poses"][i]
            truth["bottle_poses"] = poses
            truth["bottle_count"] = count
            if truth["correct_bin"] is None:
                truth["correct_bin"] = len(self.bins)
        return raw

    @staticmethod
    def _verdict(record):
        return {
            "success": record["outcome"] == "success",
            "failure": record["failure"],
            "detail": record["detail"],
            "placed_bin": record["placed_bin"],
            "distractor_touched": record["distractor_touched"],
            "distractor_picked": record["distractor_picked"],
            "truth": record["part"],
            "record": record,
        }


def make_env(scenario, perception="camera", seed=None, **overrides):
    """The Gymnasium environment of the scenario file ``scenario``: one episode is one trial,
    ``perception`` is ``"camera"`` (the truth only in the judge's ``info`` at the episode's
    end) or ``"oracle"`` (the observation carries it), ``seed`` the scenario seed (the file's
    when None), ``overrides`` ``--set``-style keys (``conveyor__speed_m_s=0.2`` for
    ``conveyor.speed_m_s``)."""
    keys = {key.replace("__", "."): value for key, value in overrides.items()}
    return CellEnv(scenario, perception=perception, seed=seed, **keys)


def run_trials(scenario, policy, out, trials=None, perception="camera", seed=None, **overrides):
    """Runs ``policy`` over the scenario's trials (its ``trials``, or ``trials`` of them) and
    writes the twin's report into ``out`` as ``twincell run`` does: ``trials.jsonl``,
    ``report.json``, ``junit.xml`` and ``report.html``. ``policy(obs)`` returns an action;
    when it has a ``reset(env, obs)`` method, that is called at each trial's start. A policy
    that stops before the twin's judge ends a trial (it returns None) gives the trial up
    (``env.finish()``). Returns the report (a dict)."""
    env = make_env(scenario, perception=perception, seed=seed, **overrides)
    try:
        count = int(env.scenario["trials"]) if trials is None else int(trials)
        records = []
        for trial in range(count):
            try:
                obs, _ = env.reset(options={"trial": trial})
            except RuntimeError:
                # The trial's cell could not be built: a failed record, as `twincell run` has.
                records.append(json.dumps(env.finish()["record"]))
                continue
            if hasattr(policy, "reset"):
                policy.reset(env, obs)
            while True:
                action = policy(obs)
                if action is None:
                    info = env.finish()
                    break
                obs, _, terminated, truncated, info = env.step(action)
                if terminated or truncated:
                    break
            records.append(json.dumps(info["record"]))
        return json.loads(env._native.write_batch(records, str(out)))
    finally:
        env.close()
