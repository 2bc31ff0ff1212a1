"""Depth furrow follower: find the lane between two crop rows in the depth image, centre on it.

Depth pixels are back-projected with the camera's intrinsics and mount into the robot frame;
points standing above the ground are crop. A line is fitted to each row (left, right) over
0.5-3 m ahead, the lane centreline is their mean, and the robot steers on its lateral offset
and heading. No GNSS and no route: the perception-only counterpart of a depth-trained PPO.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import OBS_DEPTH, RobotInterface

from .base import Obs, Policy
from .geometry import DepthProjector


class DepthFurrowFollower(Policy):
    name = "depth"
    requires = (OBS_DEPTH,)

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        speed: float = 0.6,
        k_lateral: float = 2.0,
        k_heading: float = 1.5,
        min_height: float = 0.12,
        near: float = 0.5,
        far: float = 3.0,
        **params: Any,
    ) -> None:
        super().__init__(observation_space, action_space, robot, **params)
        self.speed, self.k_lat, self.k_head = speed, k_lateral, k_heading
        self.min_height, self.near, self.far = min_height, near, far
        self.project = DepthProjector(robot.camera, robot.base_height)
        # The lane's half-width as last measured with both rows in view. The field's row
        # spacing is not the controller's to know: until it has measured it, one row gives the
        # lane's direction but not its centre.
        self.half_width: float | None = None
        self.lost = 0

    def reset(self) -> None:
        self.lost = 0
        self.half_width = None

    def describe(self) -> str:
        return f"depth row follower ({self.speed:g} m/s, rows {self.near:g}-{self.far:g} m ahead)"

    def lane(self, depth: NDArray[np.float32]) -> tuple[float | None, float] | None:
        """(lateral offset of the lane centre or None if unknown, its heading) in the robot
        frame, or None when no row is in view."""
        pts = self.project.points(depth)
        crop = pts[(pts[:, 2] > self.min_height) & (pts[:, 0] > self.near) & (pts[:, 0] < self.far)]
        fits: list[tuple[float, float] | None] = []
        for side in (1, -1):
            s = crop[np.sign(crop[:, 1]) == side]
            if len(s) < 8:
                fits.append(None)
                continue
            # the row's inner edge: the points nearest the lane at each distance
            bins = np.floor(s[:, 0] / 0.25).astype(int)
            edge = []
            for b in np.unique(bins):
                m = bins == b
                k = np.argmin(np.abs(s[m, 1]))
                edge.append(s[m][k, :2])
            e = np.asarray(edge)
            if len(e) < 3:
                fits.append(None)
                continue
            fits.append(_theil_sen(e[:, 0], e[:, 1]))
        left, right = fits
        if left is not None and right is not None:
            self.half_width = float(np.clip((left[0] - right[0]) / 2, 0.2, 1.5))
            return 0.5 * (left[0] + right[0]), math.atan(0.5 * (left[1] + right[1]))
        hw = self.half_width
        if left is not None:
            return (None if hw is None else left[0] - hw), math.atan(left[1])
        if right is not None:
            return (None if hw is None else right[0] + hw), math.atan(right[1])
        return None

    def act(self, obs: Obs) -> NDArray[np.float32]:
        est = self.lane(obs[OBS_DEPTH])
        if est is None:  # no rows in view (headland, or taller crops than the view): go slow
            self.lost += 1
            return self._twist(0.3 * self.speed, 0.0)
        self.lost = 0
        offset, heading = est
        w = (0.0 if offset is None else self.k_lat * offset) + self.k_head * heading
        v = self.speed / (1.0 + 2.0 * abs(heading))
        return self._twist(v, w)


def _theil_sen(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float]:
    """(intercept, slope) of a median-of-slopes line: a bin that sees the next row through a
    gap in the near one (an edge a metre off) does not tilt the fit, as it would least squares.
    """
    i, j = np.triu_indices(len(x), 1)
    dx = x[j] - x[i]
    ok = dx > 1e-9
    slope = float(np.median((y[j] - y[i])[ok] / dx[ok])) if ok.any() else 0.0
    return float(np.median(y - slope * x)), slope
