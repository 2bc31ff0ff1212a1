"""One table of env definitions, registered idempotently under the ``AgriNav/`` namespace.

User scenarios become envs with ``register_scenario`` / ``register_scenario_bank``; they may
never replace a built-in id, and their kwargs stay JSON-serialisable (a directory, not a
``Scenario`` object), so ``gym.spec(id).to_json()`` works for every registered env.
"""

from __future__ import annotations

import json
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gymnasium.envs.registration import load_env_creator, register, registry

from scenario_gen import Scenario
from scenario_gen.errors import InputError

NAMESPACE = "AgriNav"


@dataclass(frozen=True)
class EnvDef:
    name: str  # what users see: AgriNav/<name>-v<version>
    version: int
    entry_point: str
    max_episode_steps: int

    @property
    def id(self) -> str:
        return f"{NAMESPACE}/{self.name}-v{self.version}"


# Step limits: a default-field lane (22 m) at the slowest shipped controller's 0.3 m/s is 73 s,
# 1,470 steps at 20 Hz; the paper's zigzag (≈ 60 m with the U-turn) at 0.3 m/s is 4,000.
#: v3: the robot settles on its tyres before the first observation; the tyre model, the EKF and
#: the route tracking in compiled kernels (the EKF to rounding, not to the bit).
#: v2: flat planting by default (no ridges under every field: docs/physics.md).
#: v1: drivable default fields, tyre–soil physics, the EKF's pose in the route observation,
#: canopy-driven GNSS fix modes, fitted plant proxies (docs/design.md "Version history").
ENVS = (
    EnvDef("FurrowFollow", 3, "agrinav_gym.envs.furrow_follow:make_furrow_follow", 1500),
    EnvDef("FurrowFollowDepth", 3, "agrinav_gym.envs.furrow_follow:make_furrow_follow_depth", 1500),
    EnvDef("FieldRoute", 3, "agrinav_gym.envs.field_route:make_field_route", 4000),
)
ENV_IDS = tuple(d.id for d in ENVS)
_BY_NAME = {d.name: d for d in ENVS}


def check_env_id(env_id: Any, field: str = "env") -> str:
    """``env_id`` if it names an AgriNav env (built-in or made by ``register_scenario``).

    ``gym.make("module:Id")`` imports ``module`` first, so an id read from a spec file, a
    checkpoint or a command line is checked here before it reaches ``gym.make``: a file can
    never name code to run."""
    entry_points = {d.entry_point for d in ENVS}
    if isinstance(env_id, str) and env_id.startswith("agrinav_gym:"):
        env_id = env_id.removeprefix("agrinav_gym:")  # this package: importing it is safe
    if isinstance(env_id, str) and env_id.startswith(f"{NAMESPACE}/") and ":" not in env_id:
        spec = registry.get(env_id)
        if spec is not None and spec.entry_point in entry_points:
            return env_id
    ids = sorted(i for i, s in registry.items() if s.entry_point in entry_points)
    raise InputError(field, env_id, f"allowed: a registered AgriNav env id ({', '.join(ids)})")


def successor(env_id: Any) -> str | None:
    """The registered id of a built-in env that ``env_id`` names at an older version
    (``AgriNav/FieldRoute-v2`` -> ``AgriNav/FieldRoute-v3``); None for anything else."""
    if not isinstance(env_id, str):
        return None
    m = re.fullmatch(rf"{NAMESPACE}/(\w+)-v(\d{{1,6}})", env_id)
    d = _BY_NAME.get(m[1]) if m else None
    if m is None or d is None or int(m[2]) >= d.version:
        return None
    return d.id


def register_envs() -> None:
    """Register the built-in ids (idempotent: importing twice is harmless)."""
    for d in ENVS:
        _register(d.id, d, {})


def _register(env_id: str, d: EnvDef, kwargs: dict[str, Any]) -> str:
    if env_id in registry:
        del registry[env_id]
    register(
        id=env_id,
        entry_point=d.entry_point,
        max_episode_steps=d.max_episode_steps,
        kwargs=kwargs,
    )
    return env_id


def _user_id(name: Any, task: Any, kwargs: dict[str, Any]) -> tuple[str, EnvDef]:
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
        raise InputError("name", name, "allowed: a plain name like 'MyField' (letters, digits, _)")
    if name in _BY_NAME:
        raise InputError(
            "name",
            name,
            f"is a built-in env; allowed: any other name ({', '.join(_BY_NAME)} taken)",
        )
    if task not in _BY_NAME:
        raise InputError("task", task, f"allowed: one of {', '.join(_BY_NAME)}")
    d = _BY_NAME[task]
    if isinstance(kwargs.get("config"), dict):  # first: its own errors name the field
        from .config import EnvConfig

        EnvConfig.from_dict(kwargs["config"])
    try:
        json.dumps(kwargs, allow_nan=False)  # NaN would write a spec that is not JSON
    except (TypeError, ValueError) as exc:
        raise InputError(
            "kwargs", sorted(kwargs), f"must be JSON-serialisable for EnvSpec.to_json ({exc})"
        ) from None
    # what gym.make would refuse, refused now: unknown keywords and a bad config
    allowed = getattr(load_env_creator(d.entry_point), "allowed", None)
    unknown = sorted(k for k in kwargs if allowed is not None and k not in allowed)
    if unknown:
        raise InputError("kwargs", unknown, f"unknown; allowed: {', '.join(allowed or ())}")
    if kwargs.get("config") is not None:
        from .config import EnvConfig

        EnvConfig.from_dict(kwargs["config"])
    return f"{NAMESPACE}/{name}-v{d.version}", d


def register_scenario(
    name: str, scenario: str | Path, /, task: str = "FurrowFollow", **kwargs: Any
) -> str:
    """Register ``AgriNav/<name>-v<N>`` (the task's version): ``task`` on the scenario saved in
    ``scenario``. The env is built once here, so kwargs ``gym.make`` would refuse are refused
    now (and nothing is registered)."""
    _given_once("scenario", kwargs)
    if isinstance(scenario, Scenario):
        raise InputError(
            "scenario",
            "a Scenario object",
            "allowed: a saved scenario directory (scenario_gen.save(scn, dir) first), so the "
            "env spec stays serialisable",
        )
    if not isinstance(scenario, (str, Path)) or not (Path(scenario) / "scenario.json").is_file():
        raise InputError("scenario", str(scenario), "allowed: a directory holding scenario.json")
    kwargs = {"scenario": str(Path(scenario).resolve()), **kwargs}
    env_id, d = _user_id(name, task, kwargs)
    return _register_checked(env_id, d, kwargs)


def register_scenario_bank(
    name: str, directory: str | Path, /, task: str = "FurrowFollow", **kwargs: Any
) -> str:
    """Register ``AgriNav/<name>-v<N>`` sampling a scenario of the bank ``directory`` each
    reset (checked as ``register_scenario`` checks)."""
    from .scenarios import Bank

    _given_once("bank", kwargs)
    Bank(directory)  # refuse an empty or missing bank now
    kwargs = {"bank": str(Path(directory).resolve()), **kwargs}
    env_id, d = _user_id(name, task, kwargs)
    return _register_checked(env_id, d, kwargs)


def _given_once(key: str, kwargs: dict[str, Any]) -> None:
    if key in kwargs:
        raise InputError(
            f"kwargs.{key}", kwargs[key], f"given twice; allowed: the {key} argument only"
        )


def _register_checked(env_id: str, d: EnvDef, kwargs: dict[str, Any]) -> str:
    """Register, build the env once and close it; on any refusal the registry is as it was."""
    import gymnasium as gym

    from .scenarios import FixedFieldWarning

    before = registry.get(env_id)
    _register(env_id, d, kwargs)
    try:
        with warnings.catch_warnings():  # the notice is for the user's own envs, not this one
            warnings.simplefilter("ignore", FixedFieldWarning)
            gym.make(env_id).close()
    except BaseException:
        del registry[env_id]
        if before is not None:
            registry[env_id] = before
        raise
    return env_id
