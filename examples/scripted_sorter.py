"""A user's own controller for the twin, in plain Python and numpy: it sorts paper_50 in camera
mode through twincell's Gymnasium environment, using only the observation (photo-eye, joints,
jaws, the camera frame with its calibration) and the twin's `detect` and `measure`.

    python examples/scripted_sorter.py [SCENARIO] [--trials N] [--seed S] [--out DIR]

With --out, the trials run through ``twincell.run_trials`` and the twin writes its report
there (trials.jsonl, report.json, junit.xml, report.html), as ``twincell run`` does.

Its strategy: run the belt until the photo-eye trips, stop, take a frame; find the part nearest
the pick station with `detect`, measure its bore with `measure` on each catalogue type's
end-face plane and take the type whose bore diameter fits best; grasp it from above with the
jaws closing across the line to the nearest bottle; carry it over its bin (its type's, or the
reject bin when the roundness is past tolerance), lower it, open, and rise.
"""

import argparse
import math
from pathlib import Path

import numpy as np

import twincell

ROOT = Path(__file__).resolve().parents[1]
# The TCP's height above the part's bottom while grasping, and the clearances, m.
GRASP_ABOVE_BOTTOM_M = 0.025
SAFE_ABOVE_BELT_M = 0.30
OPEN_CLEARANCE_M = 0.012
# Tool speed along straight lines, m per control period (1/30 s): 0.15 m/s.
STEP_M = 0.005
# Largest joint speed of the moves between stations, rad/s (the arm's limits are 2.6-3.14).
JOINT_SPEED_RAD_S = 1.2


def project(calibration, point):
    """Pixel of a world point."""
    camera_from_world = np.linalg.inv(calibration["world_from_camera"])
    x, y, z = (camera_from_world @ np.append(point, 1.0))[:3]
    return np.array([calibration["fx_px"] * x / z + calibration["cx_px"],
                     calibration["fy_px"] * y / z + calibration["cy_px"]])


def to_plane(calibration, pixel, height_m):
    """The world point on the plane z = height_m seen at `pixel`."""
    ray = np.array([(pixel[0] - calibration["cx_px"]) / calibration["fx_px"],
                    (pixel[1] - calibration["cy_px"]) / calibration["fy_px"], 1.0])
    world_from_camera = calibration["world_from_camera"]
    direction = world_from_camera[:3, :3] @ ray
    origin = world_from_camera[:3, 3]
    return origin + direction * (height_m - origin[2]) / direction[2]


class ScriptedSorter:
    """Sorts one part per episode; call `act(obs)` each step."""

    def __init__(self, env):
        self.env = env
        self.scenario = env.scenario
        self.calibration = env.calibration

    # As a policy for twincell.run_trials: reset at each trial, then one action per call.
    def reset(self, env, obs):
        self.env = env
        self._plan = self._steps(obs, env.belt_top_z_m, obs["joint_positions"].copy())
        self._started = False

    def __call__(self, obs):
        try:
            if not self._started:
                self._started = True
                return next(self._plan)
            return self._plan.send(obs)
        except StopIteration:
            return None

    def run_episode(self, trial, seed=None):
        env = self.env
        options = {"trial": trial}
        obs, _ = env.reset(seed=seed, options=options)
        belt_top = env.belt_top_z_m
        home = obs["joint_positions"].copy()
        steps = self._steps(obs, belt_top, home)
        info = {}
        action = next(steps)
        while True:
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                return info
            try:
                action = steps.send(obs)
            except StopIteration:
                return env.finish()

    # The controller as a generator: it yields actions and is sent observations.
    def _steps(self, obs, belt_top, home):
        wide = 0.09
        hold = {"joints": home, "jaw_width": wide, "jaw_force": 40.0, "belt": 0}
        # 1. The belt runs until the photo-eye trips, then stops and things settle.
        while not obs["photo_eye"]:
            obs = yield dict(hold, belt=1)
        for _ in range(12):
            obs = yield hold
        # 2. A frame, detection and measurement.
        obs = yield dict(hold, frame=1)
        target = self._perceive(obs["frame"], belt_top)
        if target is None:
            return
        xy, part, roundness_mm, bottle_xy = target
        height = part["height_mm"] / 1000.0
        radius = part["outer_diameter_mm"] / 2000.0
        accept = roundness_mm is not None and roundness_mm <= self.scenario["roundness_tolerance_mm"]
        bin_ = self._bin_for(part["name"], accept)
        # The jaws close along the tool's x axis: across the line to the bottle.
        yaw = 0.0 if bottle_xy is None else math.atan2(*(bottle_xy - xy)[::-1]) + math.pi / 2
        yaw = (yaw + math.pi / 2) % math.pi - math.pi / 2
        open_width = min(2 * (radius + OPEN_CLEARANCE_M), 0.1)
        grip_n = part.get("grip_force_n") or self.scenario["gripper"]["grip_force_n"]

        def pose(p):
            return np.array([p[0], p[1], p[2], math.pi, 0.0, yaw])

        above = np.array([xy[0], xy[1], belt_top + SAFE_ABOVE_BELT_M])
        grasp = np.array([xy[0], xy[1], belt_top + GRASP_ABOVE_BOTTOM_M])
        jaws = {"jaw_width": open_width, "jaw_force": 40.0}
        # 3. Over the part, down, close, up.
        for q in self._joint_move(obs["joint_positions"], self._solve(pose(above), home)):
            obs = yield dict(jaws, joints=q)
        for _ in range(10):
            obs = yield dict(jaws, tool_pose=pose(above))
        for tcp in self._line(above, grasp):
            obs = yield dict(jaws, tool_pose=pose(tcp))
        for _ in range(6):
            obs = yield dict(jaws, tool_pose=pose(grasp))
        jaws = {"jaw_width": 0.0, "jaw_force": grip_n}
        for _ in range(20):
            obs = yield dict(jaws, tool_pose=pose(grasp))
        for tcp in self._line(grasp, above):
            obs = yield dict(jaws, tool_pose=pose(tcp))
        # 4. Over the bin, down, open, up.
        floor = np.array(bin_["floor_center_m"])
        over_bin = np.array([floor[0], floor[1], above[2]])
        into_bin = np.array([floor[0], floor[1], floor[2] + GRASP_ABOVE_BOTTOM_M + 0.03])
        carry = self._solve(pose(over_bin), obs["joint_positions"])
        for q in self._joint_move(obs["joint_positions"], carry):
            obs = yield dict(jaws, joints=q)
        for _ in range(15):
            obs = yield dict(jaws, tool_pose=pose(over_bin))
        for tcp in self._line(over_bin, into_bin):
            obs = yield dict(jaws, tool_pose=pose(tcp))
        jaws = {"jaw_width": open_width, "jaw_force": 40.0}
        for _ in range(15):
            obs = yield dict(jaws, tool_pose=pose(into_bin))
        for tcp in self._line(into_bin, over_bin):
            obs = yield dict(jaws, tool_pose=pose(tcp))
        # 5. Wait for the judge (the part at rest, clear of the jaws).
        for _ in range(90):
            obs = yield dict(jaws, tool_pose=pose(over_bin))

    def _solve(self, tool_pose, near):
        """The joint angles that put the TCP at `tool_pose` (world) with the arm's shape
        (shoulder, elbow, wrist: joints 2-4) nearest `near`'s: the base may turn far, but a
        move between branches would swing the arm over its top."""
        x, y, z, roll, pitch, yaw = tool_pose
        c, s = math.cos, math.sin
        rotation = (np.array([[c(yaw), -s(yaw), 0], [s(yaw), c(yaw), 0], [0, 0, 1]])
                    @ np.array([[c(pitch), 0, s(pitch)], [0, 1, 0], [-s(pitch), 0, c(pitch)]])
                    @ np.array([[1, 0, 0], [0, c(roll), -s(roll)], [0, s(roll), c(roll)]]))
        world_from_tcp = np.eye(4)
        world_from_tcp[:3, :3] = rotation
        world_from_tcp[:3, 3] = [x, y, z]
        base_from_tcp = np.linalg.inv(self.env.world_from_base) @ world_from_tcp
        solutions = twincell.ik(base_from_tcp, self.env.scenario_path, link="tcp")
        if len(solutions) == 0:
            return np.asarray(near)
        near = np.asarray(near)
        return min(solutions, key=lambda q: np.abs(q - near)[1:4].sum() + 0.1 * np.abs(q - near).sum())

    def _joint_move(self, start, end):
        """Joint targets from `start` to `end`, eased in and out, no joint faster than
        JOINT_SPEED_RAD_S."""
        start, end = np.asarray(start), np.asarray(end)
        period = self.env.control_period_s
        # An eased (cosine) profile peaks at pi/2 times the mean speed.
        duration = np.abs(end - start).max() * math.pi / 2 / JOINT_SPEED_RAD_S
        count = max(1, int(math.ceil(duration / period)))
        for k in range(count):
            ease = (1 - math.cos(math.pi * (k + 1) / count)) / 2
            yield start + (end - start) * ease

    @staticmethod
    def _line(start, end):
        """Points along a straight tool line, STEP_M apart."""
        count = max(1, int(math.ceil(np.linalg.norm(end - start) / STEP_M)))
        return [start + (end - start) * (k + 1) / count for k in range(count)]

    def _bin_for(self, type_name, accept):
        bins = self.scenario["bins"]
        if accept:
            for b in bins:
                if type_name in b.get("accepts", []):
                    return b
        return next(b for b in bins if b.get("reject"))

    def _perceive(self, frame, belt_top):
        """The part at the station: its centre xy on the belt, its type, its roundness (mm,
        or None when not measured), and the nearest bottle's xy."""
        c = self.calibration
        conveyor = self.scenario["conveyor"]
        station = np.array([conveyor["photo_eye_x_m"], conveyor["belt_center_m"][1], belt_top])
        station_px = project(c, station)
        found = twincell.detect(frame)
        # The shipped detector's classes are `tube` and `foreign` (a model trained on a
        # catalogue names its types and `bottle`): anything foreign is in the way, never a part.
        foreign = ("foreign", "bottle")
        parts = [d for d in found if d["class"] not in foreign]
        bottles = [d for d in found if d["class"] in foreign]
        if not parts:
            return None
        centre = lambda d: np.array([(d["box"][0] + d["box"][2]) / 2, (d["box"][1] + d["box"][3]) / 2])
        box = min(parts, key=lambda d: np.linalg.norm(centre(d) - station_px))
        # Measure in the box (with a margin), the calibration's principal point moved with it.
        x0, y0, x1, y1 = (int(v) for v in box["box"])
        margin = 12
        x0, y0 = max(0, x0 - margin), max(0, y0 - margin)
        x1, y1 = min(frame.shape[1], x1 + margin), min(frame.shape[0], y1 + margin)
        crop = np.ascontiguousarray(frame[y0:y1, x0:x1])
        best = None
        for part in self.scenario["part_types"]:
            top = belt_top + part["height_mm"] / 1000.0
            window = dict(c, width_px=x1 - x0, height_px=y1 - y0, cx_px=c["cx_px"] - x0,
                          cy_px=c["cy_px"] - y0, plane_height_m=top)
            circles = twincell.measure(crop, window)["circles"]
            circles = [k for k in circles if "r_mm" in k]
            if not circles:
                continue
            bore = max(circles, key=lambda k: k["r"])
            miss = abs(2 * bore["r_mm"] - part["bore_diameter_mm"])
            if best is None or miss < best[0]:
                best = (miss, part, bore)
        if best is None:
            # No bore measured: take the box's centre on the belt's plane as the part's.
            part = max(self.scenario["part_types"], key=lambda t: t["outer_diameter_mm"])
            xy = to_plane(c, centre(box), belt_top + part["height_mm"] / 1000.0)[:2]
            roundness = None
        else:
            _, part, bore = best
            xy = np.array([bore["cx_mm"], bore["cy_mm"]]) / 1000.0
            roundness = bore["roundness_mm"]
        bottle_xy = None
        if bottles:
            height = self.scenario["bottle"]["height_m"]
            spots = [to_plane(c, centre(b), belt_top + height / 2)[:2] for b in bottles]
            bottle_xy = min(spots, key=lambda s: np.linalg.norm(s - xy))
        return xy, part, roundness, bottle_xy


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios/paper_50.toml"))
    parser.add_argument("--trials", type=int, default=50)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    if args.out:
        env = twincell.make_env(args.scenario, perception="camera", seed=args.seed)
        sorter = ScriptedSorter(env)
        env.close()
        report = twincell.run_trials(args.scenario, sorter, args.out, trials=args.trials,
                                     perception="camera", seed=args.seed)
        print(f"{report['successes']}/{report['trials']} sorted; failures {report['failures']}"
              f"; report in {args.out}")
        return
    env = twincell.make_env(args.scenario, perception="camera", seed=args.seed)
    sorter = ScriptedSorter(env)
    successes = 0
    for trial in range(args.trials):
        info = sorter.run_episode(trial)
        successes += bool(info.get("success"))
        print(f"trial {trial}: {'success' if info.get('success') else info.get('failure')}"
              f" {info.get('detail') or ''} (placed in {info.get('placed_bin')})", flush=True)
    print(f"{successes}/{args.trials} sorted")
    env.close()


if __name__ == "__main__":
    main()
