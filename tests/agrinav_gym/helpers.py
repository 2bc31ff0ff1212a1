"""Small scenarios so each env test builds its world in milliseconds."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

import agrinav_gym  # noqa: F401  (registers the AgriNav/ ids)

TINY: dict[str, Any] = {
    "field": {"width": 6.0, "length": 14.0},
    "layout": {"headland": 2.0},
    "terrain": {"margin": 4.0},
}
FLAT: dict[str, Any] = {
    **TINY,
    "terrain": {"source": "plane", "margin": 4.0},
    "furrows": {"enabled": False, "roughness": 0.0},
}
STILL = {"task": {"start_lateral_std": 0.0, "start_heading_std_deg": 0.0}}


def make(env_id: str = "AgriNav/FurrowFollow-v0", **kwargs: Any) -> gym.Env:
    kwargs.setdefault("scenario_overrides", TINY)
    return gym.make(env_id, **kwargs)
