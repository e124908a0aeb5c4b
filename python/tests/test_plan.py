"""twincell.plan_pick: the twin's grasp search on the caller's percept, checked by the
kinematics of its answer; an out-of-reach part is a failed plan, not an exception; bad
percepts raise naming the key."""

import tomllib

import numpy as np
import pytest

import twincell
from conftest import PAPER_50

SCENARIO = tomllib.loads(PAPER_50.read_text())
BASE = np.array(SCENARIO["robot"]["base_xyz_m"])
BELT = SCENARIO["conveyor"]
PART_TYPES = [p["name"] for p in SCENARIO["part_types"]]
# The scenario's home (the default of src/scenario: paper_50 sets none).
HOME = np.array([-1.153817, 0.458529, 1.673047, -0.356278, np.pi / 2, 0.416979])


def tcp_in_world(q):
    return twincell.fk(q, scenario=PAPER_50, link="tcp")[:3, 3] + BASE


def test_the_approach_ends_with_the_tcp_on_the_part():
    rng = np.random.default_rng(7)
    lateral = SCENARIO["parts"]["max_lateral_offset_m"]
    for part_type in PART_TYPES:
        xy = [BELT["photo_eye_x_m"] + rng.uniform(-0.03, 0.03),
              BELT["belt_center_m"][1] + rng.uniform(-lateral, lateral)]
        # Start from a pose near home, drawn anew each time.
        start = HOME + rng.uniform(-0.2, 0.2, size=6)
        plan = twincell.plan_pick(
            {"part_type": part_type, "part_xy": xy}, PAPER_50, q_now=start
        )
        assert plan["success"], plan
        q = plan["approach"]["q"]
        t = plan["approach"]["t_s"]
        assert q.shape == (len(t), 6)
        assert np.all(np.diff(t) > 0)
        np.testing.assert_allclose(q[0], start, atol=1e-9)
        end = tcp_in_world(q[-1])
        np.testing.assert_allclose(end[:2], xy, atol=1e-3)
        np.testing.assert_allclose(q[-1], plan["lift_path"][0], atol=1e-9)
        np.testing.assert_allclose(plan["lift_path"][-1], plan["lift_end"], atol=1e-12)
        # The lift goes straight up from the grasp.
        lifted = tcp_in_world(plan["lift_end"])
        np.testing.assert_allclose(lifted[:2], xy, atol=1e-3)
        assert lifted[2] > end[2] + 0.05


def test_a_bottle_beside_the_part_is_kept_clear_of_or_named():
    xy = [BELT["photo_eye_x_m"], BELT["belt_center_m"][1]]
    free = twincell.plan_pick({"part_type": "axle_b28", "part_xy": xy}, PAPER_50)
    near = twincell.plan_pick(
        {"part_type": "axle_b28", "part_xy": xy,
         "obstacles": [{"kind": "bottle", "xy": [xy[0], xy[1] + 0.08]},
                       {"kind": "part", "part_type": "axle_a20", "xy": [xy[0] - 0.09, xy[1]]}]},
        PAPER_50,
    )
    assert free["success"] and near["success"], near
    # The jaws close across the line to the nearest obstacle, so the plans differ.
    assert not np.allclose(free["pregrasp"], near["pregrasp"])
    # A bottle standing on the part leaves no collision-free grasp.
    blocked = twincell.plan_pick(
        {"part_type": "axle_b28", "part_xy": xy,
         "obstacles": [{"kind": "bottle", "xy": xy}]},
        PAPER_50,
    )
    assert not blocked["success"]
    assert blocked["reason"] == "collision", blocked


def test_a_part_out_of_reach_is_a_failed_plan():
    plan = twincell.plan_pick({"part_type": "axle_a20", "part_xy": [2.5, -0.45]}, PAPER_50)
    assert plan == {"success": False, "reason": "unreachable", "detail": plan["detail"]}
    assert "2.500" in plan["detail"]


@pytest.mark.parametrize(
    "percept, error, start, words",
    [
        ([0.0, 0.0], TypeError, "percept:", "dict"),
        ({"part_xy": [0.05, -0.45]}, ValueError, "percept:", "part_type"),
        ({"part_type": "axle_z99", "part_xy": [0.05, -0.45]}, ValueError,
         'percept["part_type"]:', "axle_a20"),
        ({"part_type": "axle_a20", "part_xy": [0.05, float("nan")]}, ValueError,
         'percept["part_xy"]:', "nan"),
        ({"part_type": "axle_a20", "part_xy": [0.05]}, ValueError, 'percept["part_xy"]:',
         "[x, y]"),
        ({"part_type": "axle_a20", "part_xy": [0.05, -0.45], "colour": "red"}, ValueError,
         "percept:", "unknown key"),
        ({"part_type": "axle_a20", "part_xy": [0.05, -0.45], "obstacles": [{"kind": "cat"}]},
         ValueError, 'percept["obstacles"][0]["kind"]:', "cat"),
        ({"part_type": "axle_a20", "part_xy": [0.05, -0.45],
          "obstacles": [{"kind": "bottle"}]}, ValueError, 'percept["obstacles"][0]:', "xy"),
    ],
)
def test_a_bad_percept_raises_naming_the_key(percept, error, start, words):
    with pytest.raises(error) as caught:
        twincell.plan_pick(percept, PAPER_50)
    message = str(caught.value)
    assert message.startswith(start), message
    assert words in message, message


def test_a_start_outside_the_joint_limits_raises():
    percept = {"part_type": "axle_a20", "part_xy": [0.05, -0.45]}
    with pytest.raises(ValueError, match=r"^q_now:"):
        twincell.plan_pick(percept, PAPER_50, q_now=[0, 0, 0, 0, 0, 4.0])
    with pytest.raises(ValueError, match=r"^q_now: element 0 is nan"):
        twincell.plan_pick(percept, PAPER_50, q_now=[float("nan"), 0, 0, 0, 0, 0])
