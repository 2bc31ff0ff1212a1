"""AgriNav Gym: Summit-XL furrow-following environments built from ``scenario_gen`` scenarios.

>>> import gymnasium as gym
>>> import agrinav_gym  # registers the AgriNav/ namespace
>>> env = gym.make("AgriNav/FurrowFollow-v0")
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gymnasium.envs.registration import register, registry

from scenario_gen import Scenario, ScenarioError

from .config import EnvConfig
from .metrics import cross_track_metrics

TASKS = {
    "furrow": ("agrinav_gym.envs.furrow_follow:FurrowFollowEnv", 600),
    "furrow_depth": ("agrinav_gym.envs.furrow_follow:FurrowFollowDepthEnv", 600),
    "route": ("agrinav_gym.envs.field_route:FieldRouteEnv", 4000),
}
ENV_IDS = ("AgriNav/FurrowFollow-v0", "AgriNav/FurrowFollowDepth-v0", "AgriNav/FieldRoute-v0")


def _register(env_id: str, task: str, **kwargs: Any) -> str:
    if task not in TASKS:
        raise ScenarioError("task", task, f"allowed: one of {', '.join(TASKS)}")
    entry, steps = TASKS[task]
    if env_id in registry:  # idempotent: re-importing or re-registering is harmless
        del registry[env_id]
    register(id=env_id, entry_point=entry, max_episode_steps=steps, kwargs=kwargs)
    return env_id


def register_envs() -> None:
    for env_id, task in zip(ENV_IDS, ("furrow", "furrow_depth", "route"), strict=True):
        _register(env_id, task)


def register_scenario(
    name: str, scenario: Scenario | str | Path, task: str = "furrow", **kwargs: Any
) -> str:
    """Register ``AgriNav/<name>-v0`` on a Scenario or a saved scenario directory."""
    if not name or "/" in name or "-v" in name:
        raise ScenarioError("name", name, "allowed: a plain name like 'MyField' (no '/', '-v')")
    if not isinstance(scenario, Scenario) and not (Path(scenario) / "scenario.json").is_file():
        raise ScenarioError(
            "scenario", str(scenario), "allowed: a Scenario or a directory holding scenario.json"
        )
    src = scenario if isinstance(scenario, Scenario) else str(Path(scenario).resolve())
    return _register(f"AgriNav/{name}-v0", task, scenario=src, **kwargs)


def register_scenario_bank(
    name: str, directory: str | Path, task: str = "furrow", **kwargs: Any
) -> str:
    """Register ``AgriNav/<name>-v0`` sampling a saved scenario from ``directory`` each reset."""
    from .scenarios import Bank

    Bank(directory)  # refuse an empty or missing bank now
    return _register(f"AgriNav/{name}-v0", task, bank=str(Path(directory).resolve()), **kwargs)


register_envs()

__all__ = [
    "ENV_IDS",
    "EnvConfig",
    "cross_track_metrics",
    "register_envs",
    "register_scenario",
    "register_scenario_bank",
]
