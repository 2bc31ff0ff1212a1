"""Feature extractor for PPO: a small CNN for depth images plus the vector observations."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import torch
from stable_baselines3.common.policies import MultiInputActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from agrinav_gym.interface import OBS_DEPTH


class DepthAndVector(BaseFeaturesExtractor):
    """Depth (1, H, W) in metres -> 3 conv layers -> 128; vectors concatenated through."""

    def __init__(
        self, observation_space: gym.spaces.Dict, cnn_dim: int = 128, max_range: float = 6.0
    ) -> None:
        vec_keys = [k for k in sorted(observation_space.spaces) if k != OBS_DEPTH]
        vec_dim = sum(int(observation_space.spaces[k].shape[0]) for k in vec_keys)  # type: ignore[index,misc]
        has_depth = OBS_DEPTH in observation_space.spaces
        super().__init__(observation_space, features_dim=vec_dim + (cnn_dim if has_depth else 0))
        self.vec_keys = vec_keys
        self.max_range = max_range
        self.cnn: nn.Module | None = None
        if has_depth:
            shape = observation_space.spaces[OBS_DEPTH].shape
            assert shape is not None
            conv = nn.Sequential(
                nn.Conv2d(1, 16, 5, stride=2),
                nn.ReLU(),
                nn.Conv2d(16, 32, 3, stride=2),
                nn.ReLU(),
                nn.Conv2d(32, 32, 3, stride=1),
                nn.ReLU(),
                nn.Flatten(),
            )
            with torch.no_grad():
                n = conv(torch.zeros(1, *shape)).shape[1]
            self.cnn = nn.Sequential(conv, nn.Linear(n, cnn_dim), nn.ReLU())

    def forward(self, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        parts = [obs[k] for k in self.vec_keys]
        if self.cnn is not None:
            parts.append(self.cnn(obs[OBS_DEPTH] / self.max_range))
        return torch.cat(parts, dim=1)


class DepthMultiInputPolicy(MultiInputActorCriticPolicy):
    """PPO's multi-input actor-critic with the depth CNN as its feature extractor.

    A named class (rather than ``policy_kwargs`` holding a class) so hyperparameter files —
    ours and rl-baselines3-zoo's, which imports a dotted ``policy`` name — and checkpoints
    refer to it as plain text."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("features_extractor_class", DepthAndVector)
        super().__init__(*args, **kwargs)
