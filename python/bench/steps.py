"""Steps per second of the Gymnasium environment from Python against the same trial stepped
natively, in one run: the same actions on the same trial, once through ``env.step`` (the
action dict checked and converted, the observation built as numpy arrays) and once through
the library's step loop (``CellEnv.replay``, no Python per step).

    python python/bench/steps.py [--steps 300] [--repeats 3] [--perception oracle]

Prints both rates and the Python path's extra cost in per cent (the best of the repeats).
"""

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

import twincell

ROOT = Path(__file__).resolve().parents[2]


def actions_for(env, home, steps):
    """The belt run for the first half, then joint 1 swept: dicts for env.step."""
    out = []
    for k in range(steps):
        q = home.copy()
        q[0] += 0.3 * math.sin(k * 0.05)
        out.append({"joints": q, "jaw_width": np.array([0.09]), "jaw_force": np.array([60.0]),
                    "belt": int(k < steps // 2), "frame": 0})
    return out


def as_native(action):
    return (action["joints"], None, float(action["jaw_width"][0]),
            float(action["jaw_force"][0]), bool(action["belt"]), bool(action["frame"]))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--scenario", default=str(ROOT / "scenarios/paper_50.toml"))
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--perception", default="oracle", choices=["camera", "oracle"])
    parser.add_argument("--trial", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    env = twincell.make_env(args.scenario, perception=args.perception)
    obs, _ = env.reset(options={"trial": args.trial})
    actions = actions_for(env, obs["joint_positions"].copy(), args.steps)
    native_actions = [as_native(a) for a in actions]
    python_s, native_s = [], []
    for _ in range(args.repeats):
        env.reset(options={"trial": args.trial})
        started = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        python_s.append(time.perf_counter() - started)
        env.reset(options={"trial": args.trial})
        native_s.append(env.unwrapped._native.replay(native_actions))
    env.close()
    python_rate = args.steps / min(python_s)
    native_rate = args.steps / min(native_s)
    extra = (min(python_s) / min(native_s) - 1.0) * 100.0
    result = {
        "scenario": Path(args.scenario).name, "perception": args.perception,
        "trial": args.trial, "steps": args.steps,
        "physics_steps_per_step": twincell.PHYSICS_STEPS_PER_CONTROL,
        "python_steps_per_s": round(python_rate, 1), "native_steps_per_s": round(native_rate, 1),
        "python_extra_cost_percent": round(extra, 2),
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{result['scenario']} ({args.perception}), trial {args.trial}, {args.steps} steps "
              f"of {twincell.PHYSICS_STEPS_PER_CONTROL} physics steps, best of {args.repeats}:")
        print(f"  from Python: {python_rate:8.1f} steps/s")
        print(f"  natively:    {native_rate:8.1f} steps/s")
        print(f"  Python costs {extra:+.1f} %")


if __name__ == "__main__":
    main()
