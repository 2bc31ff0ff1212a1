"""What every DWB critic shares: the cycle's inputs, the score arrays and the critic base."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import BoolArray, FloatArray

from .costmap import Grid
from .trajectories import Rollouts


@dataclass
class Cycle:
    """What DWBLocalPlanner hands every critic's prepare(): the robot's pose and velocity in the
    costmap frame, the global goal, the transformed plan and the costmap."""

    pose: tuple[float, float, float]
    velocity: tuple[float, float]
    goal: tuple[float, float, float]
    plan: FloatArray  # (n, 3) x, y, θ
    grid: Grid
    costmap: NDArray[np.uint8]  # master grid [mx, my]
    time: float = 0.0  # s since the controller started (Oscillation's reset time)


@dataclass
class Scores:
    score: FloatArray
    legal: BoolArray
    reason: str = ""  # the exception text, for the figure's legend
    reasons: NDArray[np.int8] = field(default_factory=lambda: np.zeros(0, np.int8))


class Critic:
    name = "Critic"

    def __init__(self, scale: float) -> None:
        self._scale = scale

    @property
    def scale(self) -> float:
        return self._scale

    def reset(self) -> None:
        pass

    def prepare(self, c: Cycle) -> bool:
        return True

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        raise NotImplementedError

    def debrief(self, cmd: tuple[float, float], c: Cycle) -> None:
        pass


def _free(n: int) -> BoolArray:
    return np.ones(n, bool)


# ----------------------------------------------------------------------------- plan helpers
