"""State estimation: the pose a real robot would know, from its sensors only.

The env feeds every control step's ``Readings`` to a ``StateEstimator``; the ``route``
observation and every controller see its ``pose``, never ground truth. ``blend`` is the GNSS/INS
blend (a GNSS fix brought to base_link through the lever arm rotated by the IMU attitude, wheel
odometry between fixes); ``ekf`` a robot_localization-style EKF with GNSS latency (the default);
``ideal`` ground truth, for debugging only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from scenario_gen.errors import InputError

if TYPE_CHECKING:
    from ..config import LocalisationConfig

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Readings:
    """One control step's sensor outputs, as the robot's computer receives them."""

    gnss_enu: FloatArray  # (3,) antenna fix, ENU m (last fix, held between updates)
    gnss_new: bool  # a new fix arrived this control step (after latency)
    gnss_mode: str  # "rtk_fixed" | "rtk_float" | "standalone" | "none"
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


def make_estimator(
    kind: str,
    cfg: LocalisationConfig | None = None,
    skid_factor: float = 1.0,
    dt: float = 0.05,
) -> StateEstimator:
    """``ekf`` (robot_localization-style EKF), ``blend`` (GNSS/INS blend, no filter) or
    ``ideal`` (ground truth, debugging only). ``skid_factor`` is the drive's χ (the EKF reads
    odometry yaw rates through it), ``dt`` the control period."""
    from .blend import GnssInsBlend
    from .ekf import Ekf
    from .ideal import IdealEstimator

    if kind == "blend":
        return GnssInsBlend()
    if kind == "ideal":
        return IdealEstimator()
    if kind == "ekf":
        from ..config import LocalisationConfig as Cfg

        return Ekf(cfg if cfg is not None else Cfg(), skid_factor, dt)
    raise InputError("config.localisation.kind", kind, "allowed: ekf, blend, ideal")


__all__ = ["Readings", "StateEstimator", "make_estimator"]
