"""A controller that reads no sensor must not follow the lane on flat planting: the ground
steers only as much as physics says. With no heading feedback a start-pose heading error of
a few degrees alone walks the robot out of its ±0.19 m clearance within ~5 m of a 22 m lane,
and soil roughness adds yaw disturbances that nothing corrects."""

from __future__ import annotations

import gymnasium as gym
import pytest

import agrinav_gym  # noqa: F401
from policies import make_policy

from ..fields import drive

FLAT = {"furrows": {"enabled": False}}


def _drive_blind(overrides: dict[str, object], seed: int) -> dict[str, object]:
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=overrides)
    try:
        return dict(drive(env, make_policy("blind", env), seed).info)
    finally:
        env.close()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_blind_constant_command_leaves_a_flat_planted_lane(seed: int) -> None:
    info = _drive_blind(FLAT, seed)
    assert info.get("termination") != "success" and not info["is_success"]
    completion = float(info["metrics"]["completion"])
    assert completion < 90.0, completion
