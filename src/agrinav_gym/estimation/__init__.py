"""State estimation: the pose a real robot would know, from its sensors only.

The env feeds every control step's ``Readings`` to a ``StateEstimator``; the ``route``
observation and every controller see its ``pose``, never ground truth. ``blend`` is the GNSS/INS
blend (a GNSS fix brought to base_link through the lever arm rotated by the IMU attitude, wheel
odometry between fixes); ``ekf`` a robot_localization-style EKF with GNSS latency whose noise
models are the simulator's own (the default; also named ``ekf-oracle``: an upper bound);
``robot_localization`` robot_localization as a Nav2 user runs it; ``ideal`` ground truth, for
debugging only.
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
    """``ekf`` (robot_localization-style EKF with the simulator's noise models; ``ekf-oracle``
    is another name for it), ``robot_localization`` (robot_localization as a Nav2 user runs
    it), ``blend`` (GNSS/INS blend, no filter) or ``ideal`` (ground truth, debugging only).
    ``skid_factor`` is the drive's χ (the filters read odometry yaw rates through it), ``dt``
    the control period."""
    from ..config import LocalisationConfig as Cfg
    from .blend import GnssInsBlend
    from .ekf import Ekf
    from .ideal import IdealEstimator
    from .robot_localization import RobotLocalizationEkf
    from .robot_localization_3d import RobotLocalizationEkf3D

    if kind == "blend":
        return GnssInsBlend()
    if kind == "ideal":
        return IdealEstimator()
    if kind in ("ekf", "ekf-oracle"):
        ekf = Ekf(cfg if cfg is not None else Cfg(), skid_factor, dt)
        ekf.name = kind
        return ekf
    if kind == "robot_localization":
        c = cfg if cfg is not None else Cfg()
        if not c.robot_localization.two_d_mode:
            return RobotLocalizationEkf3D(c, skid_factor, dt)
        return RobotLocalizationEkf(c, skid_factor, dt)
    raise InputError(
        "config.localisation.kind",
        kind,
        "allowed: ekf, ekf-oracle, robot_localization, blend, ideal",
    )


__all__ = ["FloatArray", "Readings", "StateEstimator", "make_estimator"]
