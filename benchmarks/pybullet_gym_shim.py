"""pybullet's own racecar envs (``pybullet_envs.bullet``), loadable without the old ``gym``.

pybullet ships its example envs inside the wheel, written for the old ``gym`` package and
``pkg_resources``, neither of which is installed here (and ``pybullet_envs/__init__.py``
registers every one of its envs with gym on import). ``racecar_envs()`` gives the two racecar
modules the few names they import — ``gym.Env``, ``gym.spaces``, ``gym.utils.seeding``,
``pkg_resources.parse_version`` — from Gymnasium for the time of their import, without running
that ``__init__.py``; of the stand-ins nothing is left in ``sys.modules`` afterwards (the racecar
modules themselves stay). The envs keep their own old API: ``reset() -> obs`` and
``step(action) -> (obs, reward, done, info)``; build the ZED env with ``renders=False`` (its
default opens pybullet's GUI).
"""

from __future__ import annotations

import contextlib
import os
import sys
import types
from collections.abc import Iterator
from typing import Any

import gymnasium
from gymnasium.utils import seeding

_FAKES = ("gym", "gym.spaces", "gym.utils", "gym.utils.seeding", "pkg_resources")


def _parse_version(v: str) -> tuple[int, ...]:
    return tuple(int(p) for p in v.split(".")[:3] if p.isdigit())


@contextlib.contextmanager
def _old_gym() -> Iterator[None]:
    gym = types.ModuleType("gym")
    gym.Env = gymnasium.Env  # type: ignore[attr-defined]
    gym.spaces = gymnasium.spaces  # type: ignore[attr-defined]
    gym.__version__ = "0.26.2"  # type: ignore[attr-defined]
    utils = types.ModuleType("gym.utils")
    utils.seeding = seeding  # type: ignore[attr-defined]
    gym.utils = utils  # type: ignore[attr-defined]
    pkg = types.ModuleType("pkg_resources")
    pkg.parse_version = _parse_version  # type: ignore[attr-defined]
    fakes = dict(zip(_FAKES, (gym, gymnasium.spaces, utils, seeding, pkg), strict=True))
    import pybullet_data

    site = os.path.dirname(os.path.dirname(pybullet_data.__file__))
    for name, sub in (("pybullet_envs", "pybullet_envs"), ("pybullet_envs.bullet", "bullet")):
        pkg_mod = types.ModuleType(name)  # the packages without their __init__.py
        base = os.path.join(site, "pybullet_envs")
        pkg_mod.__path__ = [base if sub == "pybullet_envs" else os.path.join(base, sub)]
        fakes[name] = pkg_mod
    added = [n for n in fakes if n not in sys.modules]
    for n in added:
        sys.modules[n] = fakes[n]
    try:
        yield
    finally:
        for n in added:
            sys.modules.pop(n, None)


def racecar_envs() -> tuple[Any, Any]:
    """(RacecarGymEnv, RacecarZEDGymEnv) classes."""
    with _old_gym():
        from pybullet_envs.bullet.racecarGymEnv import RacecarGymEnv
        from pybullet_envs.bullet.racecarZEDGymEnv import RacecarZEDGymEnv
    return RacecarGymEnv, RacecarZEDGymEnv


def sim_seconds(env: Any) -> float:
    """Simulated seconds one ``step`` of a racecar env advances (its action repeat × time step)."""
    return float(env._actionRepeat * env._timeStep)
