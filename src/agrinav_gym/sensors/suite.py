"""The robot's sensors read together each control step, in a fixed order (same seed, same draws)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..config import EnvConfig
from ..estimation import Readings
from ..robot import RobotGeometry, RobotState
from .fixmode import Canopy
from .gnss import Gnss
from .imu import Imu, WheelOdometry


class SensorSuite:
    """GNSS on the rear mast, IMU in the base, wheel odometry."""

    def __init__(self, cfg: EnvConfig, geometry: RobotGeometry, dt: float) -> None:
        self.cfg = cfg
        self.dt = dt
        self.gnss = Gnss(cfg.gnss, dt)
        self.imu = Imu(cfg.imu, dt)
        self.odometry = WheelOdometry(cfg.odom, geometry.wheel_radius, geometry.track)
        g = cfg.gnss
        self.lever = np.array([g.antenna_x, 0.0, g.antenna_height])
        self._canopy: Canopy | None = None

    def set_gnss_mode(self, mode: str) -> None:
        """The receiver's best mode (e.g. standalone: no base-station corrections)."""
        self.set_gnss(mode)

    def set_gnss(self, mode: str | None = None, fix: dict[str, Any] | None = None) -> None:
        """The receiver's best mode and fix-model fields (``gnss.fix.<name>``) for this episode;
        the config's values where one is not given."""
        base = self.cfg.gnss
        cfg = replace(
            base, mode=base.mode if mode is None else mode, fix=replace(base.fix, **(fix or {}))
        )
        if cfg != self.gnss.cfg:
            self.gnss = Gnss(cfg, self.dt)
            self.gnss.set_canopy(self._canopy)

    def set_canopy(self, canopy: Canopy | None) -> None:
        """The crop over the antenna (the fix-mode model's sky); call when the field changes."""
        self._canopy = canopy
        self.gnss.set_canopy(canopy)

    def antenna(self, s: RobotState) -> np.ndarray:
        return s.pos + s.rot @ self.lever

    def reset(self, s: RobotState, rng: np.random.Generator) -> Readings:
        self.imu.reset(rng, s.vel)
        self.gnss.reset(self.antenna(s), rng)
        return self._pack(s, self.imu.measure(s.rot, s.vel, s.ang, s.rpy, rng), np.zeros(2))

    def step(self, s: RobotState, rng: np.random.Generator) -> Readings:
        self.gnss.step(self.antenna(s), rng, self.dt)
        imu = self.imu.measure(s.rot, s.vel, s.ang, s.rpy, rng)
        return self._pack(s, imu, self.odometry.measure(s.wheels, rng))

    def _pack(
        self, s: RobotState, imu: tuple[np.ndarray, np.ndarray, np.ndarray], odom: np.ndarray
    ) -> Readings:
        f, w, rpy = imu
        return Readings(
            gnss_enu=self.gnss.reading,
            gnss_new=self.gnss.updated,
            gnss_mode=self.gnss.mode,
            gnss_sigma=self.gnss.sigma,
            gnss_age=self.gnss.age,
            accel=f,
            gyro=w,
            rpy=rpy,
            odom=odom,
            antenna_lever=self.lever,
            truth=np.array([s.pos[0], s.pos[1], s.rpy[2]]),
        )
