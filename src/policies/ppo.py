"""Learned policy: a PPO checkpoint in the safe format (``checkpoint``), deterministic actions.

With ``trust_checkpoint`` a Stable-Baselines3 ``model.zip`` (or rl-baselines3-zoo's run folder)
loads too, with its ``vecnormalize.pkl`` (``checkpoint.load_sb3_trusted``).

The checkpoint's observation and action spaces must equal the env's for the keys it uses, so a
policy never runs on inputs laid out differently from those it was trained on.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import RobotInterface
from scenario_gen.errors import InputError

from . import checkpoint
from .base import Obs, Policy


class PPOPolicy(Policy):
    name = "ppo"

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        path: str | Path = "",
        trust_checkpoint: bool = False,
        **params: Any,
    ) -> None:
        super().__init__(observation_space, action_space, robot, **params)
        p = Path(path)
        loaded = checkpoint.load_policy(p, trust_checkpoint, f"ppo:{path}")
        check_spaces(
            loaded.policy.observation_space,
            observation_space,
            loaded.policy.action_space,
            action_space,
            str(path),
        )
        self.net = loaded.policy
        self.normalize = loaded.normalizer
        self.meta = loaded.meta
        self.keys = sorted(loaded.policy.observation_space.spaces)
        self.source = p.name or str(p)

    def describe(self) -> str:
        steps = self.meta.get("num_timesteps")
        return f"ppo ({self.source}{f', {steps:,} steps' if steps else ''})"

    def act(self, obs: Obs) -> NDArray[np.float32]:
        o = {k: obs[k] for k in self.keys}
        if self.normalize is not None:
            o = self.normalize(o)
        action, _ = self.net.predict(o, deterministic=True)
        return self._clip(np.asarray(action, np.float64))


def check_spaces(
    trained_obs: Any, env_obs: spaces.Dict, trained_act: Any, env_act: spaces.Box, where: str
) -> None:
    """A checkpoint only runs on the observations and actions it was trained on."""
    if not isinstance(trained_obs, spaces.Dict):  # an SB3 model of another kind of env
        raise InputError(
            "policy",
            f"ppo:{where}",
            f"was trained on a {type(trained_obs).__name__} observation space; allowed: a "
            "policy of an AgriNav env's Dict observations",
        )
    for key, sp in trained_obs.spaces.items():
        mine = env_obs.spaces.get(key)
        if not isinstance(mine, spaces.Box) or not isinstance(sp, spaces.Box):
            raise InputError(
                "policy",
                f"ppo:{where}",
                f"was trained on observations {sorted(trained_obs.spaces)}; "
                f"the env provides {sorted(env_obs.spaces)}",
            )
        same = (
            mine.shape == sp.shape
            and np.allclose(mine.low, sp.low)
            and np.allclose(mine.high, sp.high)
        )
        if not same:
            raise InputError(
                "policy",
                f"ppo:{where}",
                f"observation {key!r} was {sp} in training; the env has {mine}",
            )
    if trained_act.shape != env_act.shape or not (
        np.allclose(trained_act.low, env_act.low) and np.allclose(trained_act.high, env_act.high)
    ):
        raise InputError(
            "policy",
            f"ppo:{where}",
            f"actions were {trained_act} in training; the env has {env_act}",
        )
