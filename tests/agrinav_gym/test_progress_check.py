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


def test_recoveries_run_nav2s_default_tree_on_a_scripted_stall() -> None:
    """A policy that never moves: every 10 s the progress checker fires and the tree answers
    in Humble's order — clear the local costmap and retry FollowPath, then the round robin
    (clear both costmaps, spin 1.57 rad, wait 5 s, back up 0.30 m) — and after the sixth
    round-robin recovery the goal fails. The behaviours move the robot though the policy
    asks for nothing."""
    from agrinav_gym.recoveries import ROUND_ROBIN

    config = {
        "task": {"progress_time": 10.0, "recoveries": True},
        "localisation": {"kind": "ideal"},
    }
    env = gym.make("AgriNav/FurrowFollow-v3", config=config, max_episode_steps=10_000)
    try:
        env.reset(seed=3)
        u = env.unwrapped
        events: list[tuple[int, str]] = []
        yaw0 = float(u.state.rpy[2])
        spun = backed = 0.0
        for n in range(1, 10_001):
            before = (*u._xy(), float(u.state.rpy[2]))
            _, _, term, trunc, info = env.step(STOP)
            if "recovery" in info and (not events or events[-1][1] != info["recovery"]):
                events.append((n, info["recovery"]))
            if info.get("recovery") == "spin":
                spun += abs((float(u.state.rpy[2]) - before[2] + np.pi) % (2 * np.pi) - np.pi)
            if info.get("recovery") == "backup":
                backed += float(np.hypot(u._xy()[0] - before[0], u._xy()[1] - before[1]))
            if term or trunc:
                break
        kinds = [k for _, k in events]
        expected = []
        for k in range(6):
            expected += ["clear_local_costmap", ROUND_ROBIN[k % 4]]
        assert kinds == [*expected, "clear_local_costmap", "abort"]
        assert info["termination"] == "progress"
        # the first failure after 10 s standing still, the next after a fresh 10 s
        assert [n for n, _ in events[:2]] == pytest.approx([200, 400], abs=1)
        # two spins of 1.57 rad (round-robin steps 2 and 6) and one back-up of 0.30 m, each
        # stopped the step after the (ideal) estimate gets there: at most a step's turn at
        # 1 rad/s, a step's travel at 0.05 m/s and the millimetres the chassis rocks on the soil
        step = u.dt
        assert 2 * 1.57 <= spun <= 2 * (1.57 + 1.0 * step) + 0.005
        assert 0.30 <= backed <= 0.30 + 0.05 * step + 0.005
        assert abs(float(u.state.rpy[2]) - yaw0) > 1.0  # it was turned, not driven by the policy
    finally:
        env.close()


def test_recoveries_need_the_progress_checker() -> None:
    with pytest.raises(agrinav_gym.InputError) as e:
        gym.make("AgriNav/FurrowFollow-v3", config={"task": {"recoveries": True}})
    assert "task.recoveries" in str(e.value) and "progress_time" in str(e.value)


def test_the_route_clock_truncates_after_its_seconds_per_metre() -> None:
    """``task.seconds_per_metre``: truncated (not terminated) at ⌈route length × s/m ÷ dt⌉
    steps, with no termination named; the registered limit still applies past it."""
    spm = 0.5
    env = gym.make("AgriNav/FurrowFollow-v3", config={"task": {"seconds_per_metre": spm}})
    try:
        env.reset(seed=3)
        u = env.unwrapped
        expected = int(np.ceil(u.route.length * spm / u.dt))
        assert expected < 1500  # the registered limit would end it later
        n, term, trunc = 0, False, False
        while not (term or trunc) and n <= expected:
            _, _, term, trunc, info = env.step(STOP)
            n += 1
        assert (n, term, trunc) == (expected, False, True) and "termination" not in info
        assert "time limit 0.5 s per metre of route" in u.conditions()["navigator"]
    finally:
        env.close()


def test_the_fieldroute_suites_run_on_the_route_clock() -> None:
    """unseen, ood and sensitivity: 20 s per metre (the progress checker's 10 s per 0.5 m),
    with the TimeLimit wrapper's backstop behind it."""
    from baselines import suites

    for name in ("unseen", "ood", "sensitivity"):
        for case in suites.suite(name):
            assert case.config["task"]["seconds_per_metre"] == 20.0, (name, case.group)
            assert case.max_steps == suites.ROUTE_CLOCK_BACKSTOP
