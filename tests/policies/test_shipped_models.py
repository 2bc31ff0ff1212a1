"""The shipped PPO checkpoints load and beat a random policy by a wide margin."""

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401
from policies import SHIPPED, make_policy, shipped_model

from ..fields import drive

FIELD = {
    "field": {"width": 6.0, "length": 16.0},
    "layout": {"headland": 2.5},
    "terrain": {"margin": 4.0},
}


def _returns(env: gym.Env, act: Any, seeds: range) -> list[float]:
    return [drive(env, act, seed=10**9 + s).total_reward for s in seeds]


@pytest.mark.parametrize("env_id", sorted(SHIPPED))
def test_shipped_checkpoint_beats_random(env_id: str) -> None:
    folder = shipped_model(env_id)
    for name in (
        "checkpoint.json",
        "policy.npz",
        "command.txt",
        "config.yml",
        "learning_curve.png",
    ):
        assert (folder / name).is_file(), name
    env = gym.make(env_id, scenario_overrides=FIELD)
    try:
        pi = make_policy("ppo:shipped", env)
        rng = np.random.default_rng(0)
        ppo = _returns(env, pi.act, range(2))
        rand = _returns(env, lambda _o: rng.uniform(-1, 1, 2).astype(np.float32), range(2))
        # random driving ends in the crop within seconds; the policy drives the route
        assert min(ppo) > max(rand) + 50.0, (ppo, rand)
    finally:
        env.close()
