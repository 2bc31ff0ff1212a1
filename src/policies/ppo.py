"""Learned policy: a stable-baselines3 PPO checkpoint (plus its VecNormalize statistics)."""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from .base import Obs, Policy


class PPOPolicy(Policy):
    name = "ppo"

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        path: str | Path = "",
        **params: Any,
    ) -> None:
        super().__init__(observation_space, action_space, **params)
        from stable_baselines3 import PPO

        p = Path(path)
        model_file = p / "model.zip" if p.is_dir() else p
        if not model_file.is_file():
            raise FileNotFoundError(f"ppo policy: no model at {model_file}")
        self.model = PPO.load(model_file, device="cpu")
        want = set(self.model.observation_space.spaces)  # type: ignore[attr-defined]
        if want - set(observation_space.spaces):
            raise ValueError(
                f"ppo model {model_file} was trained on observations {sorted(want)}; "
                f"the env provides {sorted(observation_space.spaces)}"
            )
        self.keys = sorted(want)
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
