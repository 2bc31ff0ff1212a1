"""Nav2's waypoint follower in the route observation: a route planned through GPS waypoints is
handed over one leg at a time (the plan ends at the next waypoint until the estimate is within
the goal tolerance), each new goal restarts the progress checker, and a route without
waypoints or an env without the route observation is refused in one line."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym
from agrinav_gym.interface import decode_route
from baselines.suites import paper_waypoints
from policies import make_policy

GOALS = {"task": {"waypoint_goals": True, "progress_time": 10.0}, "localisation": {"kind": "ideal"}}
FIELD = {"field": {"width": 12.5, "length": 39.0}, "route": {"waypoints": paper_waypoints()}}


def _env(config: dict, **kw: object) -> gym.Env:
    return gym.make(
        "AgriNav/FieldRoute-v3", scenario="paper-p1", scenario_overrides=FIELD, config=config, **kw
    )


def test_the_plan_ends_at_each_waypoint_until_the_robot_reaches_it() -> None:
    env = _env(GOALS)
    try:
        obs, _ = env.reset(seed=0)
        u = env.unwrapped
        idx = u.scenario.info["route_goals"]
        goals = u.route.xy[idx[1:-1]]  # the corners; the route's end is the last goal
        assert len(goals) == 2
        pi = make_policy("rpp", env)
        pi.reset()
        seen, tol = 0, u.cfg.task.goal_tolerance
        for _ in range(3000):
            x, y, yaw = u.estimator.pose
            pts, _ = decode_route(obs["route"])
            far = (x + math.cos(yaw) * pts[-1, 0] - math.sin(yaw) * pts[-1, 1],
                   y + math.sin(yaw) * pts[-1, 0] + math.cos(yaw) * pts[-1, 1])  # fmt: skip
            if seen < len(goals):
                # never a point past the goal: the farthest one is the goal once it is in reach
                ahead = np.hypot(*(goals[seen] - (x, y)))
                if ahead < u.cfg.task.route_spacing * len(pts) - 0.5:
                    # float32 robot-frame coordinates within 4 m: exact to ~1e-6 m
                    assert np.hypot(*(np.asarray(far) - goals[seen])) < 1e-4
            obs, _, term, trunc, info = env.step(pi.act(obs))
            x, y, _ = u.estimator.pose
            if seen < len(goals) and np.hypot(*(goals[seen] - (x, y))) <= tol:
                seen += 1
            if term or trunc:
                break
        assert info["termination"] == "success" and seen == 2
    finally:
        env.close()


def test_a_new_goal_restarts_the_progress_checker() -> None:
    """Standing still at a corner after a goal is a fresh 10 s, as Nav2's controller server
    resets its progress checker for each goal."""
    env = _env(GOALS)
    try:
        obs, _ = env.reset(seed=0)
        u = env.unwrapped
        ro = u.obs_models["route"]
        pi = make_policy("rpp", env)
        pi.reset()
        left = len(ro.goals)
        while len(ro.goals) == left:
            before = u._anchor
            obs, *_ = env.step(pi.act(obs))
        # still inside the last anchor's disc (the robot slows to the goal), so only the new
        # goal can have moved the anchor here, to now
        x, y = u._xy()
        assert math.hypot(x - before[0], y - before[1]) <= u.cfg.task.progress_radius
        assert before[2] < u._anchor[2] == pytest.approx(u._steps * u.dt)
    finally:
        env.close()


def test_a_route_without_waypoints_is_refused() -> None:
    env = gym.make("AgriNav/FieldRoute-v3", scenario="paper-p1", config=GOALS)
    try:
        with pytest.raises(agrinav_gym.InputError) as e:
            env.reset(seed=0)
        assert "task.waypoint_goals" in str(e.value) and "route.waypoints" in str(e.value)
    finally:
        env.close()
    with pytest.raises(agrinav_gym.InputError) as e:
        _env(GOALS, observations=["imu", "odom"])
    assert "route observation" in str(e.value)


def test_off_by_default_the_plan_runs_on_past_the_waypoints() -> None:
    env = _env({"localisation": {"kind": "ideal"}})
    try:
        obs, _ = env.reset(seed=0)
        pts, _ = decode_route(obs["route"])
        assert len(np.unique(np.round(pts, 6), axis=0)) == len(pts)  # no goal repeated
        assert env.unwrapped.obs_models["route"].goals == []
    finally:
        env.close()


def test_stop_on_failure_false_skips_a_given_up_waypoint_and_counts_it() -> None:
    """A robot that never moves, no round-robin recoveries: each goal is given up after two
    progress-check failures (clear the local costmap and retry, then abort). With the
    follower's ``stop_on_failure: false`` the two corners are skipped in turn — counted in
    ``missed_waypoints``, each a new goal for the tree — and the route's end, which cannot be
    skipped, ends the episode; with the default the first give-up ends it."""
    from agrinav_gym.recoveries import ABORT, SKIP

    task = {**GOALS["task"], "recoveries": True, "recovery_retries": 0}
    for stop, skips in ((True, 0), (False, 2)):
        env = _env({**GOALS, "task": {**task, "stop_on_failure": stop}})
        try:
            env.reset(seed=0)
            u = env.unwrapped
            events, steps = [], 0
            while True:
                _, _, term, trunc, info = env.step(np.zeros(2, np.float32))
                steps += 1
                if "recovery" in info:
                    events.append((steps, info["recovery"]))
                if term or trunc:
                    break
            assert info["termination"] == "progress" and not trunc
            assert info["metrics"]["missed_waypoints"] == skips
            kinds = [k for _, k in events]
            assert kinds.count(SKIP) == skips and kinds[-1] == ABORT
            assert len(u.obs_models["route"].goals) == 2 - skips
            # each goal: two 10 s progress checks (200 steps at 20 Hz) from its start
            assert steps == pytest.approx(400 * (skips + 1), abs=2)
        finally:
            env.close()


def test_stop_on_failure_false_needs_the_follower_and_its_tree() -> None:
    with pytest.raises(agrinav_gym.InputError, match="config.task.stop_on_failure"):
        _env({**GOALS, "task": {**GOALS["task"], "stop_on_failure": False}})
