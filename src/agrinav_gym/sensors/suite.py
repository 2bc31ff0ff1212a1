"""The robot's sensors read together each control step, in a fixed order (same seed, same draws)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config import EnvConfig
from ..estimation import Readings
from ..sim.world import RobotGeometry, RobotState
from .gnss import Gnss, error_sigma
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
        self.sigma = error_sigma(cfg.gnss)

    def set_gnss_mode(self, mode: str) -> None:
        self.gnss = Gnss(replace(self.cfg.gnss, mode=mode), self.dt)
        self.sigma = error_sigma(self.gnss.cfg)

    def antenna(self, s: RobotState) -> np.ndarray:
        return s.pos + s.rot @ self.lever

    def reset(self, s: RobotState, rng: np.random.Generator) -> Readings:
        self.imu.reset(rng)
        self.gnss.reset(self.antenna(s), rng)
        return self._readings(s, rng, np.zeros(2))

    def step(self, s: RobotState, rng: np.random.Generator) -> Readings:
        self.gnss.step(self.antenna(s), rng, self.dt)
        imu = self.imu.measure(s.rot, s.vel, s.ang, s.rpy, rng)
        return self._pack(imu, self.odometry.measure(s.wheels, rng))

    def _readings(self, s: RobotState, rng: np.random.Generator, odom: np.ndarray) -> Readings:
        return self._pack(self.imu.measure(s.rot, s.vel, s.ang, s.rpy, rng), odom)

    def _pack(self, imu: tuple[np.ndarray, np.ndarray, np.ndarray], odom: np.ndarray) -> Readings:
        f, w, rpy = imu
        return Readings(
            gnss_enu=self.gnss.reading,
            gnss_new=self.gnss.updated,
            gnss_mode=self.gnss.cfg.mode,
            gnss_sigma=self.sigma,
            gnss_age=self.gnss.age,
            accel=f,
            gyro=w,
            rpy=rpy,
            odom=odom,
            antenna_lever=self.lever,
        )
