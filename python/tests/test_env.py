"""The Gymnasium environment: Gymnasium's own checker on paper_50 in both perception modes,
deterministic resets, the judge's info at the episode's end (and no truth before it in camera
mode), and bad calls raising exceptions that name the argument and the reason."""

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import twincell

from conftest import PAPER_50


@pytest.fixture(scope="module")
def oracle():
    env = twincell.make_env(PAPER_50, perception="oracle")
    yield env
    env.close()


@pytest.mark.parametrize("perception", ["camera", "oracle"])
def test_gymnasiums_checker_passes_on_paper_50(perception):
    env = twincell.make_env(PAPER_50, perception=perception)
    assert isinstance(env, gym.Env)
    check_env(env, skip_render_check=True)
    env.close()


def hold(obs, **extra):
    return dict({"joints": obs["joint_positions"].copy()}, **extra)


def test_reset_picks_the_scenarios_trial_and_repeats_it(oracle):
    first, info = oracle.reset(seed=731, options={"trial": 5})
    assert info == {"trial": 5, "scenario_seed": 731}
    again, _ = oracle.reset(options={"trial": 5})
    other, _ = oracle.reset(options={"trial": 6})
    assert np.array_equal(first["truth"]["part_pose"], again["truth"]["part_pose"])
    assert not np.array_equal(first["truth"]["part_pose"], other["truth"]["part_pose"])
    # Without options the next trial follows.
    _, info = oracle.reset()
    assert info["trial"] == 7


def test_camera_mode_shows_no_truth_until_the_judge_speaks():
    env = twincell.make_env(PAPER_50, perception="camera")
    obs, info = env.reset(options={"trial": 0})
    assert "truth" not in obs and "truth" not in info
    assert obs["frame_index"][0] == 0 and not obs["frame"].any()
    obs, reward, terminated, truncated, info = env.step(hold(obs, frame=1))
    assert "truth" not in obs and "truth" not in info and "success" not in info
    assert obs["frame_index"][0] == 1
    calibration = env.unwrapped.calibration
    shape = (calibration["height_px"], calibration["width_px"], 3)
    assert obs["frame"].shape == shape and obs["frame"].dtype == np.uint8
    assert obs["frame"].std() > 5.0, "the frame shows the cell"
    verdict = env.finish()
    assert verdict["success"] is False and verdict["failure"] == "wrong_bin"
    assert verdict["truth"]["part_type"] in env.part_types
    env.close()


def test_the_photo_eye_and_belt_report_the_part_arriving(oracle):
    obs, _ = oracle.reset(options={"trial": 2})
    steps = 0
    while not obs["photo_eye"]:
        obs, reward, terminated, truncated, info = oracle.step(hold(obs, belt=1))
        steps += 1
        assert not (terminated or truncated) and steps < 400
    assert obs["belt_speed"][0] > 0 and obs["belt_position"][0] > 0
    # The part or its bottle, whichever the belt brings first, stands at the eye.
    truth = obs["truth"]
    xs = [truth["part_pose"][0, 3]] + [p[0, 3] for p in truth["bottle_poses"][: truth["bottle_count"]]]
    eye_x = oracle.scenario["conveyor"]["photo_eye_x_m"]
    assert min(abs(x - eye_x) for x in xs) < 0.05
    np.testing.assert_allclose(obs["sim_time"][0], steps * oracle.control_period_s)


# -- bad calls: each raises naming the argument and the reason ---------------------------------


def test_a_wrong_action_shape_names_the_key(oracle):
    obs, _ = oracle.reset(options={"trial": 0})
    with pytest.raises(ValueError, match=r"action\['joints'\]: expected 6 joint angles"):
        oracle.step({"joints": np.zeros(5)})
    with pytest.raises(ValueError, match=r"action\['tool_pose'\]: expected \[x, y, z, roll"):
        oracle.step({"tool_pose": np.zeros((2, 3))})
    with pytest.raises(ValueError, match=r"action\['jaw_width'\]: expected one number"):
        oracle.step(hold(obs, jaw_width=np.zeros(3)))
    with pytest.raises(TypeError, match=r"action: expected a dict"):
        oracle.step(np.zeros(6))
    with pytest.raises(ValueError, match=r"action: unknown key 'gripper'"):
        oracle.step(hold(obs, gripper=1))


def test_nan_targets_name_the_key_and_element(oracle):
    obs, _ = oracle.reset(options={"trial": 0})
    q = obs["joint_positions"].copy()
    q[3] = np.nan
    with pytest.raises(ValueError, match=r"action\['joints'\]: element 3 is nan"):
        oracle.step({"joints": q})
    with pytest.raises(ValueError, match=r"action\['tool_pose'\]: element 0 is inf"):
        oracle.step({"tool_pose": [np.inf, 0, 0.9, 0, 0, 0]})
    with pytest.raises(ValueError, match=r"action\['jaw_force'\]: nan is not a finite"):
        oracle.step(hold(obs, jaw_force=np.nan))
    far = obs["joint_positions"].copy()
    far[1] = 5.0
    with pytest.raises(ValueError, match=r"action\['joints'\]: joint 2 target 5.0000 rad is outside"):
        oracle.step({"joints": far})
    # Refused actions changed nothing: the trial still stands at time 0.
    obs, *_ = oracle.step(hold(obs))
    np.testing.assert_allclose(obs["sim_time"][0], oracle.control_period_s)


def test_a_closed_env_raises():
    env = twincell.make_env(PAPER_50, perception="oracle")
    obs, _ = env.reset()
    env.close()
    env.close()  # closing twice is harmless
    assert env.closed
    with pytest.raises(RuntimeError, match=r"env: the environment is closed"):
        env.step(hold(obs))
    with pytest.raises(RuntimeError, match=r"env: the environment is closed"):
        env.reset()


def test_an_unknown_override_key_names_it():
    with pytest.raises(ValueError, match=r"overrides: .*conveyor\.sped_m_s"):
        twincell.make_env(PAPER_50, perception="oracle", **{"conveyor.sped_m_s": 0.2})
    with pytest.raises(ValueError, match=r'perception: .*"camera" or "oracle"'):
        twincell.make_env(PAPER_50, perception="lidar")
    with pytest.raises(ValueError, match=r"options: unknown key 'trail'"):
        twincell.make_env(PAPER_50, perception="oracle").reset(options={"trail": 3})


def test_an_override_changes_the_cell():
    env = twincell.make_env(PAPER_50, perception="oracle", conveyor__speed_m_s=0.2)
    assert env.scenario["conveyor"]["speed_m_s"] == 0.2
    env.close()


def test_async_vector_envs_step_trials_in_parallel():
    envs = gym.vector.AsyncVectorEnv(
        [lambda: twincell.make_env(PAPER_50, perception="oracle") for _ in range(2)]
    )
    try:
        # Gymnasium seeds sub-environment i with seed + i: scenario seeds 731 and 732.
        obs, info = envs.reset(seed=731, options={"trial": 3})
        assert obs["joint_positions"].shape == (2, 6)
        assert list(info["scenario_seed"]) == [731, 732]
        single = twincell.make_env(PAPER_50, perception="oracle")
        for i, seed in enumerate([731, 732]):
            alone, _ = single.reset(seed=seed, options={"trial": 3})
            np.testing.assert_array_equal(obs["truth"]["part_pose"][i], alone["truth"]["part_pose"])
        single.close()
        action = {
            "arm_mode": np.zeros(2, dtype=np.int64),
            "joints": obs["joint_positions"].copy(),
            "tool_pose": np.zeros((2, 6)),
            "jaw_width": np.full((2, 1), 0.09),
            "jaw_force": np.full((2, 1), 60.0),
            "belt": np.ones(2, dtype=np.int64),
            "frame": np.zeros(2, dtype=np.int64),
        }
        for _ in range(5):
            obs, reward, terminated, truncated, info = envs.step(action)
        assert (obs["belt_speed"][:, 0] > 0).all()
        np.testing.assert_allclose(obs["sim_time"][:, 0], 5 * 8 / 240)
    finally:
        envs.close()


class GiveUpAtTheEye:
    """Runs the belt until the photo-eye trips, then gives up: a policy for run_trials."""

    def reset(self, env, obs):
        self.steps = 0

    def __call__(self, obs):
        if obs["photo_eye"]:
            return None
        return {"joints": obs["joint_positions"], "belt": 1}


def test_run_trials_writes_the_twins_report(tmp_path):
    report = twincell.run_trials(PAPER_50, GiveUpAtTheEye(), tmp_path, trials=3,
                                 perception="oracle")
    assert report["trials"] == 3 and report["successes"] == 0
    assert report["failures"] == {"wrong_bin": 3}
    assert report["perception"] == "oracle" and report["seed"] == 731
    for name in ("trials.jsonl", "report.json", "junit.xml", "report.html"):
        assert (tmp_path / name).is_file(), name
    lines = (tmp_path / "trials.jsonl").read_text().splitlines()
    assert [json.loads(line)["trial"] for line in lines] == [0, 1, 2]
