"""Nav2's RotationShimController (``nav2_rotation_shim_controller``, Humble) in front of DWB.

Each new global plan arms it. While armed, the plan's first point at least
``forward_sampling_distance`` from the plan's start is looked at from the robot: further than
``angular_dist_threshold`` off its heading, the robot turns in place toward it at
``rotate_to_heading_angular_vel``, the step from the measured yaw rate bounded by
``max_angular_accel`` × the control period; within it (or when the plan has no such point, or
the turn's footprint would meet a lethal cell within ``simulate_ahead_time``) the shim disarms
and DWB drives until the next plan.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray

from .costmap import LETHAL, Grid
from .critics import line_cells
from .params import RotationShimParams


def footprint_cost(
    grid: Grid, costmap: NDArray[np.uint8], footprint: FloatArray, pose: tuple[float, float, float]
) -> int:
    """FootprintCollisionChecker::footprintCostAtPose: the highest cost on the footprint's
    outline (edges rasterised with LineIterator), lethal when a corner is off the map."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    wx = x + footprint[:, 0] * c - footprint[:, 1] * s
    wy = y + footprint[:, 0] * s + footprint[:, 1] * c
    mx, my, on = grid.world_to_map(wx, wy)
    if not on.all():
        return LETHAL
    a = np.arange(len(footprint))
    b = (a + 1) % len(footprint)
    lx, ly, live = line_cells(mx[a], my[a], mx[b], my[b])
    return int(costmap[lx[live], ly[live]].max())


class RotationShim:
    """The shim's state between control cycles; DWB calls ``set_plan`` on each new plan and
    ``command`` every cycle (``None``: DWB drives)."""

    def __init__(
        self,
        p: RotationShimParams,
        speed: float,
        accel: float,
        dt: float,
        footprint: FloatArray,
    ) -> None:
        """``speed`` and ``accel``: the turn's yaw rate and angular acceleration, resolved
        against the robot's limits (``policy.shim_rates``)."""
        self.p = p
        self.speed, self.accel = speed, accel
        self.dt = dt
        self.plan_every = max(1, round(1.0 / (p.plan_frequency * dt)))
        self.footprint = footprint
        self.reset()

    def reset(self) -> None:
        self.armed = False
        self.sample: tuple[float, float] | None = None
        self.turning = False

    def set_plan(self, plan: FloatArray) -> None:
        """A new global plan ((n, ≥2) in the odometry frame, from its start): arm, and keep the
        point that sets the heading (in the odometry frame, as Nav2 keeps the path in its own)."""
        self.armed = True
        d = np.hypot(plan[:, 0] - plan[0, 0], plan[:, 1] - plan[0, 1])
        far = np.flatnonzero(d >= self.p.forward_sampling_distance)
        far = far[far >= 1]
        self.sample = (float(plan[far[0], 0]), float(plan[far[0], 1])) if len(far) else None

    def command(
        self,
        pose: tuple[float, float, float],
        yaw_rate: float,
        grid: Grid,
        costmap: NDArray[np.uint8],
    ) -> float | None:
        """The in-place yaw rate, or ``None`` when DWB should drive."""
        self.turning = False
        if not self.armed:
            return None
        if self.sample is not None:
            x, y, th = pose
            dx, dy = self.sample[0] - x, self.sample[1] - y
            bx = math.cos(th) * dx + math.sin(th) * dy
            by = -math.sin(th) * dx + math.cos(th) * dy
            angle = math.atan2(by, bx)
            if abs(angle) > self.p.angular_dist_threshold:
                target = math.copysign(self.speed, angle)
                step = self.accel * self.dt
                w = min(max(target, yaw_rate - step), yaw_rate + step)
                if self._collision_free(pose, w, angle, grid, costmap):
                    self.turning = True
                    return w
        self.armed = False
        return None

    def _collision_free(
        self,
        pose: tuple[float, float, float],
        w: float,
        angle: float,
        grid: Grid,
        costmap: NDArray[np.uint8],
    ) -> bool:
        """isCollisionFree: the footprint at each control period of the turn up to
        ``simulate_ahead_time``, stopping where the plan would be handed to DWB."""
        remaining = abs(angle) - self.p.angular_dist_threshold
        t = 0.0
        while t < self.p.simulate_ahead_time:
            t += self.dt
            turned = w * t
            # Nav2 compares shortest_angular_distance(yaw, initial_yaw), i.e. -w·t, with the
            # rotation left before the hand-over: a turn to the right stops checking there, one
            # to the left is checked for the whole simulate_ahead_time (kept as Nav2 has it)
            if -turned >= remaining:
                break
            if (
                footprint_cost(grid, costmap, self.footprint, (pose[0], pose[1], pose[2] + turned))
                >= LETHAL
            ):
                return False
        return True
