"""Long runs with interventions: a stall, a corridor exit or a stalk contact puts the robot back
on the route and the run goes on; the distance between them is what field trials report."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401
from baselines.episodes import RESUME_AHEAD, run_with_interventions
from baselines.report import table
from policies import make_policy

from ..fields import TINY as SHORT

CONFIG = {"task": {"progress_time": 2.0, "max_crops_hit": 0}}


def _env() -> Any:
    return gym.make(
        "AgriNav/FurrowFollow-v3", scenario_overrides=SHORT, config=CONFIG, observations=["route"]
    )


class _StallsFirst:
    """RPP that stands still for its first ``n`` actions: a scripted stall."""

    def __init__(self, env: Any, n: int) -> None:
        self.rpp, self.n, self.calls = make_policy("rpp", env), n, 0

    def reset(self) -> None:
        self.rpp.reset()

    def act(self, obs: Any) -> Any:
        self.calls += 1
        return np.zeros(2, np.float32) if self.calls <= self.n else self.rpp.act(obs)

    def describe(self) -> str:
        return "rpp after a stall"


def test_a_stall_is_an_intervention_and_the_run_goes_on_to_the_end() -> None:
    env = _env()
    try:
        # 45 still steps: the 2 s checker fires at 40, then the robot has 1.75 s to move 0.5 m
        ep = run_with_interventions(env, _StallsFirst(env, 45), 0, "stall")
        assert [i["kind"] for i in ep.interventions or []] == ["progress"]
        assert ep.interventions[0]["step"] == pytest.approx(40, abs=1)  # 2 s at 20 Hz
        assert ep.termination == "success" and ep.metrics["completion"] > 95
        length = env.unwrapped.route.length
        # by itself the robot drove the whole route but the metre it was carried
        assert length - 1.0 - RESUME_AHEAD < ep.autonomous_m < length - RESUME_AHEAD + 0.05
    finally:
        env.close()


def test_resume_puts_the_robot_on_the_route_and_stepping_works_again() -> None:
    env = _env()
    try:
        u = env.unwrapped
        env.reset(seed=1)
        term = False
        while not term:  # full speed, turning: out of the lane
            _, _, term, _, info = env.step(np.array([1.0, 1.0], np.float32))
        assert info["termination"] in ("corridor", "crops_hit")
        before = u.arc
        _, info = u.resume_on_route(0.5)
        assert abs(info["cte"]) < 0.03 and u.arc == pytest.approx(before + 0.5, abs=0.05)
        _, _, term, _, info = env.step(np.zeros(2, np.float32))
        assert not term  # the contact count starts afresh: no instant second intervention
        assert info["metrics"]["crops_hit"] >= 0
    finally:
        env.close()


def test_the_table_reports_distance_between_interventions() -> None:
    rec = {
        "policy": "p",
        "scenario": "long",
        "seed": 0,
        "termination": "success",
        "completion": 99.0,
        "crops_hit": 1,
        "poses": 10,
        "interventions": 2,
        "intervention_kinds": {"progress": 1, "crops_hit": 1},
        "autonomous_m": 120.0,
    }
    none = {**rec, "seed": 1, "interventions": 0, "intervention_kinds": {}, "autonomous_m": 80.0}
    md = table([rec, none], "long", "")
    row = next(line for line in md.splitlines() if line.startswith("| long | p | 200 |"))
    assert "| 2 | 100.0 |" in row and "crops_hit 1, progress 1" in row
    # a second policy on the same seeds: its rate paired with the first's, seed by seed
    # (rates 1/100 m − 2/120 m and 3/100 m − 0/80 m)
    q = [
        {**rec, "policy": "q", "interventions": 1, "autonomous_m": 100.0},
        {**none, "policy": "q", "interventions": 3, "autonomous_m": 100.0},
    ]
    md = table([rec, none, *q], "long", "")
    pair = next(line for line in md.splitlines() if line.startswith("| long | q − p |"))
    mean = ((1.0 - 200.0 / 120.0) + 3.0) / 2
    assert pair.startswith(f"| long | q − p | {mean:+.2f} [") and pair.endswith("(2) |")
    assert "q − p" not in table([rec, none], "long", "")


class _StallsLate:
    """RPP that stands still for 81 steps (4 s + 1) once past 75 % of the route: an intervention in
    the route's second lane, where a search from the route's start finds the wrong lane."""

    def __init__(self, env: Any) -> None:
        self.env, self.rpp, self.still = env.unwrapped, make_policy("rpp", env), 0

    def reset(self) -> None:
        self.rpp.reset()

    def act(self, obs: Any) -> Any:
        u = self.env
        if self.still < 81 and u.arc > 0.75 * u.route.length:
            self.still += 1
            return np.zeros(2, np.float32)
        return self.rpp.act(obs)

    def describe(self) -> str:
        return "rpp with a late stall"


def test_after_an_intervention_in_the_second_lane_the_route_observation_is_right() -> None:
    env = gym.make(
        "AgriNav/FieldRoute-v3",
        scenario_overrides={**SHORT, "field": {"width": 5.0, "length": 10.0}},
        # 4 s: RPP slows to a crawl in the 0.5 m-radius U-turn, 2 s would stop it there
        config={"task": {"progress_time": 4.0, "max_crops_hit": 0}},
        observations=["route"],
    )
    try:
        ep = run_with_interventions(env, _StallsLate(env), 0, "stall late")
        stops = ep.interventions or []
        # the scripted stall is the last intervention: once put back on the second lane the
        # robot drives on to the end (a route observation searched from the route's start
        # sent it to the first lane, and every intervention led to the next)
        length = env.unwrapped.route.length
        assert stops[-1]["kind"] == "progress" and stops[-1]["at_m"] > 0.75 * length
        assert ep.termination == "success"
    finally:
        env.close()
