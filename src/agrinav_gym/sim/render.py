"""The ``rgb_array`` chase view: pybullet's TinyRenderer over the terrain and plant visuals."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ..config import RenderConfig
from .world import RobotState


def chase_view(client: int, s: RobotState, cfg: RenderConfig) -> NDArray[np.uint8]:
    x, y, z = (float(v) for v in s.pos)
    yaw = float(s.rpy[2])
    c, sn = math.cos(yaw), math.sin(yaw)
    eye = [x - cfg.distance * c, y - cfg.distance * sn, z + cfg.elevation]
    view = p.computeViewMatrix(eye, [x + c, y + sn, z], [0, 0, 1], physicsClientId=client)
    proj = p.computeProjectionMatrixFOV(60, cfg.width / cfg.height, 0.1, 60, physicsClientId=client)
    _, _, rgba, _, _ = p.getCameraImage(
        cfg.width, cfg.height, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=client
    )
    return np.asarray(rgba, np.uint8).reshape(cfg.height, cfg.width, 4)[:, :, :3].copy()
