"""The Stanley path tracker with integral action: the offset-correcting controller of farm
autosteer.

Stanley (Hoffmann, Tomlin, Montemerlo and Thrun, "Autonomous Automobile Trajectory Tracking
for Off-Road Driving: Controller Design, Experimental Validation and Racing", ACC 2007) steers
by the heading error plus ``atan(k·e / (k_soft + v))`` of the cross-track error ``e`` at the
front axle. A skid-steer has no steering angle: the steering term δ becomes a yaw-rate demand
``ω = v·κ + k_heading·δ`` (κ the path's curvature ahead, the feedforward a car gets from its
steering geometry). Farm autosteer adds integral action on ``e`` so that a steady disturbance
— a side slope, a crabbing tyre, ridges — leaves no steady offset; the integral is clamped
(anti-windup) and frozen while the robot turns in place or is far off the line.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import OBS_ROUTE, RobotInterface

from .base import Obs, Policy
from .geometry import local_plan, regulated_speed
from .params import Param, check_params


class Stanley(Policy):
    """Stanley with integral action on the cross-track error (see the module docstring)."""

    name = "stanley"
    requires = (OBS_ROUTE,)
    #: what each parameter may be (m/s, 1/s, s, m, rad; policies.params)
    PARAMS: ClassVar[dict[str, Param]] = {
        "desired_linear_vel": Param(0.0, 5.0, lo_open=True),
        "k": Param(0.0, 100.0, lo_open=True),
        "k_soft": Param(0.0, 10.0, lo_open=True),
        "k_heading": Param(0.0, 100.0, lo_open=True),
        "integral_time": Param(0.0, 1e4, lo_open=True, none_ok=True),
        "integral_limit": Param(0.0, 10.0),
        "integral_band": Param(0.0, 10.0),
        "min_radius": Param(0.0, 100.0),
        "rotate_to_heading_min_angle": Param(0.0, math.pi),
        "approach_dist": Param(0.0, 20.0),
        "min_approach_vel": Param(0.0, 5.0),
    }

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        desired_linear_vel: float = 0.8,
        k: float = 2.5,
        k_soft: float = 0.3,
        k_heading: float = 2.0,
        integral_time: float | None = 6.0,
        integral_limit: float = 0.3,
        integral_band: float = 0.1,
        min_radius: float = 0.9,
        rotate_to_heading_min_angle: float = 0.785,
        approach_dist: float = 0.6,
        min_approach_vel: float = 0.05,
        **params: Any,
    ) -> None:
        mine = {k: v for k, v in locals().items() if k in self.PARAMS}
        check_params(self.name, self.PARAMS, mine)
        super().__init__(observation_space, action_space, robot, **params)
        self.keep_params(mine)
        self.note_above_robot("desired_linear_vel", desired_linear_vel, robot.v_max, "m/s")
        self.v_des = min(desired_linear_vel, robot.v_max)
        self.k, self.k_soft, self.k_heading = k, k_soft, k_heading
        # PI form: the integral term reaches the proportional one after integral_time seconds
        # of a steady error (None: no integral action, plain Stanley)
        self.k_i = 0.0 if integral_time is None else k / integral_time
        self.i_max, self.near = integral_limit, integral_band
        self.r_min, self.rot_angle = min_radius, rotate_to_heading_min_angle
        self.approach, self.v_approach_min = approach_dist, min_approach_vel
        self.dt = robot.control_dt
        self.integral = 0.0
        self.v = 0.0

    def reset(self) -> None:
        self.integral = 0.0
        self.v = 0.0

    def describe(self) -> str:
        return (
            f"stanley (+ integral: {self.v_des:g} m/s, k {self.k:g}, k_heading "
            f"{self.k_heading:g}, integral gain {self.k_i:.3g} /s"
            + self.changed_params(("desired_linear_vel", "k", "k_heading", "integral_time"))
            + ")"
        )

    def act(self, obs: Obs) -> NDArray[np.float32]:
        plan, tags = local_plan(obs[OBS_ROUTE])
        if len(plan) < 2:
            return self._twist(0.0, 0.0)
        # nearest plan point to the front axle (x = wheelbase / 2 ahead of base_link)
        front = np.array([0.5 * self.robot.wheelbase, 0.0])
        i = int(np.argmin(np.hypot(plan[:, 0] - front[0], plan[:, 1] - front[1])))
        j = min(i + 1, len(plan) - 1)
        a, b = plan[max(j - 1, 0)], plan[j]
        heading_err = math.atan2(b[1] - a[1], b[0] - a[0])  # path direction, robot frame
        # signed cross-track error of the front axle: positive when the path is to the left
        t = (b - a) / max(float(np.hypot(*(b - a))), 1e-9)
        rel = front - a
        e = -(t[0] * rel[1] - t[1] * rel[0])
        if abs(heading_err) > self.rot_angle:  # turn in place towards the path first
            return self._twist(0.0, math.copysign(self.robot.w_max, heading_err))
        if not tags[i]:  # a steady offset is a furrow's: the headland turn starts afresh
            self.integral = 0.0
        elif abs(e) < self.near:  # near the line only: no windup from a large transient
            self.integral = float(np.clip(self.integral + e * self.dt, -self.i_max, self.i_max))
        ahead = plan[min(i + 16, len(plan) - 1)]  # 0.8 m on: the curvature to feed forward
        kappa = 2.0 * float(ahead[1]) / max(float(ahead @ ahead), 1e-6)
        remaining = float(np.hypot(*plan[-1]))
        v = regulated_speed(
            self.v_des, kappa, self.r_min, remaining, self.approach, self.v_approach_min
        )
        delta = heading_err + math.atan2(self.k * e + self.k_i * self.integral, self.k_soft + v)
        w = float(np.clip(v * kappa + self.k_heading * delta, -self.robot.w_max, self.robot.w_max))
        return self._twist(v, w)
