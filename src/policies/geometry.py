"""Helpers shared by the classical controllers: the local plan from the route observation and
robot-frame points from the depth image."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agrinav_gym.interface import CameraModel, decode_route
from scenario_gen.arrays import FloatArray


class DepthProjector:
    """Back-projects a z-depth image into robot-frame points, z measured from the ground plane
    under the wheels (the camera's public calibration and the base height). The pixel rays are
    computed once."""

    def __init__(self, camera: CameraModel, base_height: float) -> None:
        rays = camera.pixel_rays()
        self.ray_y = rays[:, 1].copy()
        self.ray_z = rays[:, 2].copy()
        self.rot = camera.rotation
        self.mount = np.asarray(camera.position, np.float64) + np.array([0.0, 0.0, base_height])
        self.shape = (camera.height, camera.width)

    def points(self, depth: NDArray[np.float32]) -> FloatArray:
        """(n, 3) points of the valid (non-zero) pixels."""
        z = np.asarray(depth, np.float64).ravel()
        ok = z > 0
        cam = np.stack([z[ok], self.ray_y[ok] * z[ok], self.ray_z[ok] * z[ok]], axis=1)
        out: FloatArray = cam @ self.rot.T + self.mount
        return out


def regulated_speed(
    v: float, curvature: float, min_radius: float, remaining: float, approach: float, v_min: float
) -> float:
    """Nav2 RPP's speed regulation: slow down in turns tighter than ``min_radius`` and within
    ``approach`` metres of the route's end (never below ``v_min`` there)."""
    radius = 1.0 / max(abs(curvature), 1e-9)
    if radius < min_radius:
        v *= radius / min_radius
    if remaining < approach:
        v = max(v * remaining / approach, v_min)
    return v


def local_plan(
    route_obs: NDArray[np.float32], step: float = 0.05
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The route observation as a dense polyline in the robot frame, starting beside the robot.

    The observation holds points route_spacing, 2·route_spacing, ... ahead of the robot's
    projection on the route; one point is extrapolated back so the plan also covers the robot's
    own position. A plan that ends at a goal (``task.waypoint_goals``) repeats the goal; with
    only the goal left the plan is the line from the robot to it.
    """
    pts, tags = decode_route(route_obs)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-6])  # a goal's plan repeats its last point
    pts, tags = pts[keep], tags[keep]
    if len(pts) >= 2:
        pts = np.vstack([2 * pts[0] - pts[1], pts])
        tags = np.concatenate([tags[:1], tags])
    elif len(pts) == 1 and np.hypot(*pts[0]) > 1e-6:
        # within one point spacing of a goal: the straight line to it, as a planner's path
        # from the robot to the goal would be
        pts = np.vstack([np.zeros(2), pts])
        tags = np.concatenate([tags, tags])
    if len(pts) < 2:
        return pts, tags
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    s = np.arange(0.0, arc[-1] + 1e-9, step)
    # the plan ends at the route's end, as a planner's path ends at its goal: short of it by up
    # to a step, a controller's goal window the size of the navigator's closes outside it
    if arc[-1] - s[-1] > 1e-6:
        s = np.append(s, arc[-1])
    else:
        s[-1] = arc[-1]
    dense = np.column_stack([np.interp(s, arc, pts[:, 0]), np.interp(s, arc, pts[:, 1])])
    dense_tags = tags[np.minimum(np.searchsorted(arc, s, side="right") - 1, len(tags) - 1)]
    return dense, dense_tags
