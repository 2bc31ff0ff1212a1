"""Regulated pure pursuit (Nav2 RPP-like): a carrot on the route, curvature-regulated speed."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import OBS_ODOM, OBS_ROUTE, RobotInterface, decode_odom

from .base import Obs, Policy
from .geometry import local_plan, regulated_speed
from .params import Param, check_params

#: what ``RegulatedPurePursuit.describe`` states itself
_RPP_SHOWN = (
    "desired_linear_vel",
    "lookahead_time",
    "min_lookahead",
    "max_lookahead",
    "allow_reversing",
)


class RegulatedPurePursuit(Policy):
    """Nav2 defaults, with lookahead scaled by speed (0.3-0.9 m at 1.5 s of travel).

    ``allow_reversing`` (Nav2's parameter of that name, off by default as there) drives routes
    with cusps, such as the three-point headland turn: the lookahead stops at the first cusp
    ahead (the first point where consecutive route segments point apart, Nav2's
    ``findVelocitySignChange``), the carrot may lie behind the robot, and the speed takes the
    sign of the carrot's x; the robot slows to the cusp as to a goal, and never rotates in
    place (Nav2 refuses ``use_rotate_to_heading`` with reversing)."""

    name = "rpp"
    requires = (OBS_ROUTE,)
    #: what each parameter may be (m, s, rad; policies.params)
    PARAMS: ClassVar[dict[str, Param]] = {
        "desired_linear_vel": Param(0.0, 5.0, lo_open=True),
        "lookahead_time": Param(0.0, 20.0, lo_open=True),
        "min_lookahead": Param(0.0, 20.0, lo_open=True),
        "max_lookahead": Param(0.0, 20.0, lo_open=True),
        "min_radius": Param(0.0, 100.0),
        "rotate_to_heading_min_angle": Param(0.0, math.pi),
        "rotate_to_heading_angular_vel": Param(0.0, 10.0, lo_open=True),
        "approach_dist": Param(0.0, 20.0),
        "min_approach_vel": Param(0.0, 5.0),
        "allow_reversing": Param(flag=True),
    }
    ORDERED = (("min_lookahead", "max_lookahead"),)

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        desired_linear_vel: float = 0.8,
        lookahead_time: float = 1.5,
        min_lookahead: float = 0.3,
        max_lookahead: float = 0.9,
        min_radius: float = 0.9,
        rotate_to_heading_min_angle: float = 0.785,
        rotate_to_heading_angular_vel: float = 1.5,
        approach_dist: float = 0.6,
        min_approach_vel: float = 0.05,
        allow_reversing: bool = False,
        **params: Any,
    ) -> None:
        mine = {k: v for k, v in locals().items() if k in self.PARAMS}
        check_params(self.name, self.PARAMS, mine, self.ORDERED)
        super().__init__(observation_space, action_space, robot, **params)
        self.keep_params(mine)
        self.note_above_robot("desired_linear_vel", desired_linear_vel, robot.v_max, "m/s")
        self.v_des = min(desired_linear_vel, robot.v_max)
        self.t_look, self.l_min, self.l_max = lookahead_time, min_lookahead, max_lookahead
        self.r_min = min_radius
        self.rot_angle, self.rot_vel = rotate_to_heading_min_angle, rotate_to_heading_angular_vel
        self.approach, self.v_approach_min = approach_dist, min_approach_vel
        self.reversing = bool(allow_reversing)
        self.v = 0.0

    def reset(self) -> None:
        self.v = 0.0

    def describe(self) -> str:
        return (
            f"rpp (Nav2 RPP-like: {self.v_des:g} m/s, lookahead {self.l_min:g}-{self.l_max:g} m "
            f"over {self.t_look:g} s{', reversing at cusps' if self.reversing else ''}"
            + self.changed_params(_RPP_SHOWN)
            + ")"
        )

    def act(self, obs: Obs) -> NDArray[np.float32]:
        if OBS_ODOM in obs:
            self.v = decode_odom(obs[OBS_ODOM]).v
        plan, _ = local_plan(obs[OBS_ROUTE])
        look = float(np.clip(abs(self.v) * self.t_look, self.l_min, self.l_max))
        if self.reversing:
            return self._reversing_act(plan, look)
        d = np.hypot(plan[:, 0], plan[:, 1])
        ahead = np.flatnonzero((d >= look) & (plan[:, 0] > -0.2))
        carrot = plan[ahead[0]] if len(ahead) else plan[-1]
        angle = math.atan2(carrot[1], carrot[0])
        if abs(angle) > self.rot_angle:  # rotate in place towards the path first
            return self._twist(0.0, math.copysign(self.rot_vel, angle))
        l2 = float(carrot @ carrot)
        curvature = 2.0 * float(carrot[1]) / max(l2, 1e-6)
        remaining = float(np.hypot(*plan[-1]))
        v = regulated_speed(
            self.v_des, curvature, self.r_min, remaining, self.approach, self.v_approach_min
        )
        w = float(np.clip(v * curvature, -self.robot.w_max, self.robot.w_max))
        return self._twist(v, w)

    def _reversing_act(self, plan: NDArray[np.float64], look: float) -> NDArray[np.float32]:
        cusp = first_cusp(plan)
        if cusp is not None:
            plan = plan[: cusp + 1]
            look = min(look, float(np.hypot(*plan[-1])))
        d = np.hypot(plan[:, 0], plan[:, 1])
        ahead = np.flatnonzero(d >= look)
        carrot = plan[ahead[0]] if len(ahead) else plan[-1]
        sign = 1.0 if carrot[0] >= 0.0 else -1.0
        l2 = float(carrot @ carrot)
        curvature = 2.0 * float(carrot[1]) / max(l2, 1e-6)
        remaining = float(np.hypot(*plan[-1]))  # to the cusp or the route's end: stop there
        v = sign * regulated_speed(
            self.v_des, curvature, self.r_min, remaining, self.approach, self.v_approach_min
        )
        w = float(np.clip(v * curvature, -self.robot.w_max, self.robot.w_max))
        return self._twist(v, w)


def first_cusp(plan: NDArray[np.float64]) -> int | None:
    """Index of the first point where the path turns back on itself (the segments before and
    after it point apart), or None."""
    seg = np.diff(plan, axis=0)
    if len(seg) < 2:
        return None
    back = np.flatnonzero(np.einsum("ij,ij->i", seg[:-1], seg[1:]) < 0.0)
    return int(back[0]) + 1 if len(back) else None
