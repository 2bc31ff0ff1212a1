"""State estimation: the pose a real robot would know, from its sensors only.

The env feeds every control step's ``Readings`` to a ``StateEstimator``; the ``route``
observation and every controller see its ``pose``, never ground truth. ``blend`` is the GNSS/INS
blend (a GNSS fix brought to base_link through the lever arm rotated by the IMU attitude, wheel
odometry between fixes); ``ekf`` a robot_localization-style EKF with GNSS latency (the default);
``ideal`` ground truth, for debugging only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from scenario_gen.errors import InputError

from .readings import FloatArray, Readings, StateEstimator

if TYPE_CHECKING:
    from ..config import LocalisationConfig


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


__all__ = ["FloatArray", "Readings", "StateEstimator", "make_estimator"]
