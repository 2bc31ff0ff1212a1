"""A constant forward command with no sensors: the reference row a benchmark needs.

It reads nothing, so whatever it achieves is what the field and the simulator give for free.
On level, flat-planted ground it must leave the lane within a few metres of heading error
(docs/benchmark.md); if it finishes a field, the field (ridges, a wall of crop), not the
controllers, is doing the steering there.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import RobotInterface

from .base import Obs, Policy


class Blind(Policy):
    """Drive straight ahead at ``speed`` m/s (RPP's cruise speed by default), ω = 0."""

    name = "blind"
    requires = ()

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        speed: float = 0.8,
        **params: Any,
    ) -> None:
        super().__init__(observation_space, action_space, robot, **params)
        self.v = min(float(speed), robot.v_max)
        self.action = np.array([self.v / robot.v_max, 0.0], np.float32)

    def describe(self) -> str:
        return f"blind (constant {self.v:g} m/s, ω = 0, no sensors)"

    def act(self, obs: Obs) -> NDArray[np.float32]:
        return self.action.copy()
