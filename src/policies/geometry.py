"""Helpers shared by the classical controllers: the local plan from the route observation and
robot-frame points from the depth image."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: base_link above the wheels' footprint plane (the URDF's wheel radius), m
BASE_HEIGHT = 0.11


class DepthProjector:
    """Back-projects a z-depth image into robot-frame points, z measured from the footprint plane.

    ``camera`` is the env's public calibration: ``hfov``, ``vfov``, ``pitch`` (rad, + down),
    ``x`` and ``height`` of the mount on base_link. The pixel rays are computed once.
    """

    def __init__(self, camera: dict[str, float], shape: tuple[int, ...]) -> None:
        h, w = shape[-2:]
        fx = 0.5 * w / math.tan(camera["hfov"] / 2)
        fy = 0.5 * h / math.tan(camera["vfov"] / 2)
        u, v = np.meshgrid(np.arange(w) - 0.5 * (w - 1), np.arange(h) - 0.5 * (h - 1))
        self.ray_y = (-u / fx).ravel()
        self.ray_z = (-v / fy).ravel()
        cp, sp = math.cos(camera["pitch"]), math.sin(camera["pitch"])
        self.rot = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
        self.mount = np.array([camera["x"], 0.0, camera["height"] + BASE_HEIGHT])

    def points(self, depth: NDArray[np.float32]) -> FloatArray:
        """(n, 3) points of the valid (non-zero) pixels."""
        z = np.asarray(depth, np.float64).ravel()
        ok = z > 0
        cam = np.stack([z[ok], self.ray_y[ok] * z[ok], self.ray_z[ok] * z[ok]], axis=1)
        out: FloatArray = cam @ self.rot.T + self.mount
        return out


def local_plan(
    route_obs: NDArray[np.float32], step: float = 0.05
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The route observation as a dense polyline in the robot frame, starting beside the robot.

    The observation holds points 0.4, 0.8, ... m ahead of the robot's projection on the route;
    one point is extrapolated back so the plan also covers the robot's own position.
    """
    r = np.asarray(route_obs, np.float64).reshape(-1, 3)
    pts, tags = r[:, :2], r[:, 2] > 0.5
    if len(pts) >= 2:
        pts = np.vstack([2 * pts[0] - pts[1], pts])
        tags = np.concatenate([tags[:1], tags])
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-6])  # the route's end repeats its last point
    pts, tags = pts[keep], tags[keep]
    if len(pts) < 2:
        return pts, tags
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    s = np.arange(0.0, arc[-1] + 1e-9, step)
    dense = np.column_stack([np.interp(s, arc, pts[:, 0]), np.interp(s, arc, pts[:, 1])])
    dense_tags = tags[np.minimum(np.searchsorted(arc, s, side="right") - 1, len(tags) - 1)]
    return dense, dense_tags
