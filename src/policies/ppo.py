"""Learned policy: a stable-baselines3 PPO checkpoint (plus its VecNormalize statistics)."""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import RobotInterface
from scenario_gen.errors import InputError

from .base import Obs, Policy


class PPOPolicy(Policy):
    name = "ppo"

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        path: str | Path = "",
        **params: Any,
    ) -> None:
        super().__init__(observation_space, action_space, robot, **params)
        from stable_baselines3 import PPO

        p = Path(path)
        model_file = p / "model.zip" if p.is_dir() else p
        if not model_file.is_file():
            raise InputError("policy", f"ppo:{path}", "allowed: a checkpoint folder or model.zip")
        self.model = PPO.load(model_file, device="cpu")
        check_spaces(
            self.model.observation_space,
            observation_space,
            self.model.action_space,
            action_space,
            str(path),
        )
        self.keys = sorted(self.model.observation_space.spaces)  # type: ignore[attr-defined]
        self.norm = None
        stats = model_file.parent / "vecnormalize.pkl"
        if stats.is_file():
            with open(stats, "rb") as f:
                self.norm = pickle.load(f)

    def act(self, obs: Obs) -> NDArray[np.float32]:
        o = {k: obs[k] for k in self.keys}
        if self.norm is not None:
            o = self.norm.normalize_obs({k: v[None] for k, v in o.items()})
            o = {k: v[0] for k, v in o.items()}
        action, _ = self.model.predict(o, deterministic=True)
        return self._clip(np.asarray(action, np.float64))


def check_spaces(
    trained_obs: Any, env_obs: spaces.Dict, trained_act: Any, env_act: spaces.Box, where: str
) -> None:
    """A checkpoint only runs on the observations and actions it was trained on."""
    for key, sp in trained_obs.spaces.items():
        mine = env_obs.spaces.get(key)
        if not isinstance(mine, spaces.Box):
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
