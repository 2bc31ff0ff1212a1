"""Sensor models: GNSS (ZED-F9P-like), IMU (MTi-like), wheel odometry, depth (D455-like)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..config import CameraConfig
    from ..interface import CameraModel
    from .camera import Camera


def make_camera(cfg: CameraConfig, model: CameraModel) -> Camera:
    """The camera ``cfg.model`` names: ``proxy`` (analytic plants) or ``mesh`` (crop meshes)."""
    from .depth import DepthCamera
    from .mesh_camera import MeshCamera

    if cfg.model == "mesh":
        return MeshCamera(cfg, model, cfg.threads)
    return DepthCamera(cfg, model)
