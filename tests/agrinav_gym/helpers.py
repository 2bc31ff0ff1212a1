"""Small scenarios so each env test builds its world in milliseconds."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym

import agrinav_gym  # noqa: F401  (registers the AgriNav/ ids)

from ..fields import FLAT, STILL, TINY

__all__ = ["FLAT", "STILL", "TINY", "lane_pose", "make", "make_camera", "mesh_camera"]


def make(env_id: str = "AgriNav/FurrowFollow-v3", **kwargs: Any) -> gym.Env:
    kwargs.setdefault("scenario_overrides", TINY)
    return gym.make(env_id, **kwargs)


def make_camera(robot: dict[str, Any] | None = None, camera: dict[str, Any] | None = None) -> Any:
    """The env's depth camera for the given config sections, built as the env builds it."""
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.robot import RobotGeometry, robot_interface
    from agrinav_gym.sensors.depth import DepthCamera

    cfg = EnvConfig.from_dict({"robot": robot or {}, "camera": camera or {}})
    return DepthCamera(cfg.camera, robot_interface(cfg, RobotGeometry.from_urdf()).camera)


def mesh_camera(width: int, height: int, renderer: str, threads: int = 1) -> Any:
    """The mesh camera of the default robot at width x height with ``renderer``."""
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.robot import RobotGeometry, robot_interface
    from agrinav_gym.sensors.mesh_camera import MeshCamera

    cfg = EnvConfig.from_dict({"camera": {"width": width, "height": height, "renderer": renderer}})
    return MeshCamera(cfg.camera, robot_interface(cfg, RobotGeometry.from_urdf()).camera, threads)


def lane_pose(scn: Any, k: int = 40, turn: float = 0.0) -> tuple[Any, Any]:
    """Base rotation and position at route point ``k`` of a scenario, facing along the rows
    (turned by ``turn`` rad), on the terrain."""
    import numpy as np

    xy = scn.route.xy[k]
    pos = np.array([xy[0], xy[1], float(scn.terrain.height_at(*xy)) + 0.11])
    c, s = math.cos(scn.rows.angle + turn), math.sin(scn.rows.angle + turn)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), pos
