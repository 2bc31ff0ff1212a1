"""AgriNav Gym: Summit-XL furrow-following environments built from ``scenario_gen`` scenarios.

>>> import gymnasium as gym
>>> import agrinav_gym  # registers the AgriNav/ namespace
>>> env = gym.make("AgriNav/FurrowFollow-v3")
"""

from __future__ import annotations

from scenario_gen.errors import InputError

from .config import EnvConfig
from .interface import CameraModel, RobotInterface
from .metrics import EpisodeMetrics
from .registration import (
    ENV_IDS,
    ENVS,
    check_env_id,
    register_envs,
    register_scenario,
    register_scenario_bank,
)
from .vector import make_vec

register_envs()

__all__ = [
    "ENVS",
    "ENV_IDS",
    "CameraModel",
    "EnvConfig",
    "EpisodeMetrics",
    "InputError",
    "RobotInterface",
    "check_env_id",
    "make_vec",
    "register_envs",
    "register_scenario",
    "register_scenario_bank",
]
