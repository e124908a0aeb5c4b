"""twincell.ik and twincell.fk: round trips over the whole joint space, the command line's
answers, and bad poses raising with the argument named."""

import numpy as np
import pytest

import twincell
from conftest import PAPER_50, run_cli

LIMIT = 3.04


def random_joints(rng, count):
    return rng.uniform(-LIMIT, LIMIT, size=(count, 6))


@pytest.mark.parametrize("scenario", [None, PAPER_50])
@pytest.mark.parametrize("link", ["flange", "tcp"])
def test_every_pose_of_a_joint_vector_solves_back_to_it(scenario, link):
    rng = np.random.default_rng(27)
    missed = 0
    for q in random_joints(rng, 150):
        pose = twincell.fk(q, scenario=scenario, link=link)
        solutions = twincell.ik(pose, scenario=scenario, link=link)
        assert solutions.ndim == 2 and solutions.shape[1] == 6
        assert len(solutions) >= 1
        for s in solutions:
            np.testing.assert_allclose(
                twincell.fk(s, scenario=scenario, link=link), pose, atol=1e-8
            )
            assert np.all(np.abs(s) <= LIMIT + 1e-12)
        # q itself is among them, unless it sits so near a singularity that another branch
        # stands in for it (the wrapped distance of each joint).
        wrapped = np.abs((solutions - q + np.pi) % (2 * np.pi) - np.pi)
        if wrapped.max(axis=1).min() > 1e-6:
            missed += 1
    assert missed <= 3


def test_the_same_solutions_as_the_command_line(twincell_bin):
    rng = np.random.default_rng(2727)
    for q in random_joints(rng, 5):
        fk_cli = run_cli(twincell_bin, "fk", *map(repr, q.tolist()), "--json")
        np.testing.assert_allclose(twincell.fk(q), np.array(fk_cli["matrix"]), atol=1e-12)
        pose = fk_cli["xyz"] + fk_cli["rpy"]
        cli = run_cli(twincell_bin, "ik", *map(repr, pose), "--json")["solutions"]
        np.testing.assert_allclose(twincell.ik(pose), np.array(cli).reshape(-1, 6), atol=1e-12)


def test_an_unreachable_pose_has_no_solution():
    solutions = twincell.ik([3.0, 0.0, 0.5, 0.0, 0.0, 0.0])
    assert solutions.shape == (0, 6)


@pytest.mark.parametrize(
    "pose, error, words",
    [
        ([0.3, 0.1, 0.4, float("nan"), 0.0, 0.0], ValueError, "element 3 is nan"),
        ([0.3, 0.1, 0.4, 0.0, 0.0, float("inf")], ValueError, "not a finite"),
        ([0.3, 0.1, 0.4, 0.0, 0.0], ValueError, "shape [5]"),
        (np.eye(3), ValueError, "4 x 4"),
        (np.diag([2.0, 1.0, 1.0, 1.0]), ValueError, "rigid"),
        (np.diag([-1.0, 1.0, 1.0, 1.0]), ValueError, "rigid"),
        ("north", ValueError, "shape []"),
        ([[1, 2], [3]], TypeError, "pose"),
    ],
)
def test_a_bad_pose_raises_naming_it(pose, error, words):
    with pytest.raises(error) as caught:
        twincell.ik(pose)
    message = str(caught.value)
    assert message.startswith("pose:"), message
    assert words in message, message


def test_bad_joints_links_and_scenarios_raise_naming_them(tmp_path):
    with pytest.raises(ValueError, match=r"^q: .*shape \[7\]"):
        twincell.fk(np.zeros(7))
    with pytest.raises(ValueError, match=r"^q: element 2 is nan"):
        twincell.fk([0, 0, float("nan"), 0, 0, 0])
    with pytest.raises(ValueError, match=r'^link: "elbow"'):
        twincell.ik([0.3, 0.1, 0.4, 0, 0, 0], link="elbow")
    with pytest.raises(ValueError, match=r"^scenario:"):
        twincell.ik([0.3, 0.1, 0.4, 0, 0, 0], scenario=tmp_path / "missing.toml")
    with pytest.raises(ValueError, match=r"^scenario:.*no_such_key"):
        twincell.ik([0.3, 0.1, 0.4, 0, 0, 0], scenario=PAPER_50, **{"robot.no_such_key": 1})
    with pytest.raises(ValueError, match=r"^overrides: overrides need a scenario"):
        twincell.ik([0.3, 0.1, 0.4, 0, 0, 0], **{"robot.speed_fraction": 0.5})
