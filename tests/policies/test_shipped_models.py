"""The shipped PPO checkpoints load and beat a random policy by a wide margin."""

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401
from policies import SHIPPED, make_policy, shipped_model

from ..fields import drive

GEOMETRY = "field_route_geometry_ppo"
ROBOT_LOCALIZATION = "field_route_robot_localization_ppo"
FIELD = {
    "field": {"width": 6.0, "length": 16.0},
    "layout": {"headland": 2.5},
    "terrain": {"margin": 4.0},
}


def _returns(env: gym.Env, act: Any, seeds: range) -> list[float]:
    return [drive(env, act, seed=10**9 + s).total_reward for s in seeds]


#: every checkpoint in the package: the ``ppo:shipped`` one of each env, and the route policy
#: fine-tuned on curved and contour rows and with robot_localization's pose (used by path)
CHECKPOINTS = [(e, str(shipped_model(e))) for e in sorted(SHIPPED)] + [
    ("AgriNav/FieldRoute-v3", str(shipped_model("AgriNav/FieldRoute-v3").parent / name))
    for name in (GEOMETRY, ROBOT_LOCALIZATION)
]


@pytest.mark.parametrize(("env_id", "path"), CHECKPOINTS)
def test_shipped_checkpoint_beats_random(env_id: str, path: str) -> None:
    folder = Path(path)
    for name in (
        "checkpoint.json",
        "policy.npz",
        "command.txt",
        "config.yml",
        "learning_curve.png",
        "README.md",
    ):
        assert (folder / name).is_file(), name
    env = gym.make(env_id, scenario_overrides=FIELD)
    try:
        shipped = folder == shipped_model(env_id)
        pi = make_policy("ppo:shipped" if shipped else f"ppo:{folder}", env)
        rng = np.random.default_rng(0)
        ppo = _returns(env, pi.act, range(2))
        rand = _returns(env, lambda _o: rng.uniform(-1, 1, 2).astype(np.float32), range(2))
        # random driving ends in the crop within seconds; the policy drives the route
        assert min(ppo) > max(rand) + 50.0, (ppo, rand)
    finally:
        env.close()


def test_a_checkpoint_driven_on_another_env_is_noted_not_silent() -> None:
    """The spaces fit, so it runs; the user is told which env it learned, as a Notice the
    commands print in one line."""
    from scenario_gen.errors import Notice

    from ..fields import TINY

    env = gym.make("AgriNav/FieldRoute-v3", scenario_overrides=TINY)
    try:
        with pytest.warns(Notice, match="trained on AgriNav/FurrowFollow-v3; it drives Agri"):
            make_policy(f"ppo:{shipped_model('AgriNav/FurrowFollow-v3')}", env)
    finally:
        env.close()
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY)
    try:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("error", Notice)
            make_policy("ppo:shipped", env)  # its own env: nothing to say
    finally:
        env.close()
