"""Nav2's progress checker as a termination: a stalled robot fails after movement_time_allowance,
a moving one never does, and it is off unless configured."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym

STOP = np.zeros(2, np.float32)


def _steps_until_end(config: dict[str, object], action: np.ndarray, limit: int) -> tuple[int, dict]:
    env = gym.make("AgriNav/FurrowFollow-v3", config=config, max_episode_steps=limit)
    try:
        env.reset(seed=3)
        for n in range(1, limit + 1):
            _, _, term, trunc, info = env.step(action)
            if term or trunc:
                return n, info
        raise AssertionError("the time limit should have ended the episode")
    finally:
        env.close()


def test_a_stalled_robot_fails_after_the_allowance() -> None:
    n, info = _steps_until_end({"task": {"progress_time": 2.0}}, STOP, 200)
    assert info["termination"] == "progress"
    assert n == pytest.approx(2.0 * 20, abs=1)  # 20 Hz control: 40 steps standing still


def test_no_progress_check_unless_configured() -> None:
    n, info = _steps_until_end({}, STOP, 60)
    assert n == 60 and "termination" not in info


def test_a_robot_that_keeps_moving_is_never_stopped() -> None:
    # 0.5 m/s leaves a 0.5 m disc in ~1 s (plus the 0.6 m/s² ramp): well inside 2 s each time
    slow = np.array([0.5, 0.0], np.float32)
    _, info = _steps_until_end({"task": {"progress_time": 2.0}}, slow, 120)
    assert info.get("termination") != "progress"


def test_the_progress_settings_are_checked() -> None:
    with pytest.raises(agrinav_gym.InputError) as e:
        gym.make("AgriNav/FurrowFollow-v3", config={"task": {"progress_time": -1}})
    assert "task.progress_time" in str(e.value)
