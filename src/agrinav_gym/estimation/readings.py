"""What every estimator consumes and provides: one control step's ``Readings`` and the
``StateEstimator`` protocol."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from scenario_gen.arrays import FloatArray


@dataclass(frozen=True)
class Readings:
    """One control step's sensor outputs, as the robot's computer receives them."""

    gnss_enu: FloatArray  # (3,) antenna fix, ENU m (last fix, held between updates)
    gnss_new: bool  # a new fix arrived this control step (after latency)
    gnss_mode: str  # the current fix: one of interface.FIX_LEVELS
    gnss_sigma: FloatArray  # (3,) the receiver's reported 1-sigma (ENU), m
    gnss_age: float  # s since the fix was taken
    accel: FloatArray  # (3,) body specific force, m/s²
    gyro: FloatArray  # (3,) body rate, rad/s
    rpy: FloatArray  # (3,) IMU attitude estimate, rad (with its errors)
    odom: FloatArray  # (2,) wheel-odometry v m/s, w rad/s
    antenna_lever: FloatArray  # (3,) antenna position in base_link, m
    #: ground-truth (x, y, yaw) of base_link: for the ``ideal`` estimator (debugging) only
    truth: FloatArray | None = None


class StateEstimator(Protocol):
    name: str

    def reset(self, x: float, y: float, yaw: float, rng: np.random.Generator) -> None: ...

    def update(self, r: Readings, dt: float) -> None: ...

    @property
    def pose(self) -> tuple[float, float, float]: ...

    @property
    def covariance(self) -> FloatArray: ...
