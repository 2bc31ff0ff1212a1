"""A synthetic drive through the real sensor models, for estimator tests without physics.

The truth is a robot on flat ground driving an S-curve; the GNSS, IMU and wheel-odometry
models are the env's own (sensors/), the odometry reading its skid-steer slip: speed a few
percent high, yaw rate χ times the true one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from agrinav_gym.config import (
    GnssConfig,
    GnssFixConfig,
    ImuConfig,
    LocalisationConfig,
    OdomConfig,
)
from agrinav_gym.estimation import Readings, StateEstimator, make_estimator
from agrinav_gym.robot import RobotState
from agrinav_gym.sensors.gnss import Gnss
from agrinav_gym.sensors.imu import Imu, WheelOdometry

DT, CHI, RADIUS, TRACK = 0.05, 2.1, 0.11, 0.47
SLIP = 0.04  # wheel speed reads this much above the ground speed


@dataclass
class Drive:
    errors: np.ndarray  # (T, 3): estimate − truth (x, y, yaw)
    covariances: np.ndarray  # (T, 3, 3)
    modes: list[str]
    truth: np.ndarray  # (T, 3): x, y, yaw

    def along_across(self) -> np.ndarray:
        """(T, 2): the position error along and across the true heading."""
        c, s = np.cos(self.truth[:, 2]), np.sin(self.truth[:, 2])
        e = self.errors
        return np.column_stack([c * e[:, 0] + s * e[:, 1], -s * e[:, 0] + c * e[:, 1]])


def _truth(t: float, x: float, y: float, yaw: float) -> tuple[RobotState, float, float]:
    v = 0.8 * min(1.0, t / 2.0)
    w = 0.3 * math.sin(0.2 * t)
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    wl = (v * (1 + SLIP) - CHI * 0.5 * TRACK * w) / RADIUS
    wr = (v * (1 + SLIP) + CHI * 0.5 * TRACK * w) / RADIUS
    state = RobotState(
        np.array([x, y, 0.11]),
        rot,
        np.array([0.0, 0.0, yaw]),
        np.array([v * c, v * s, 0.0]),
        np.array([0.0, 0.0, w]),
        [wl, wr, wl, wr],
    )
    return state, v, w


def drive(
    kind: str,
    mode: str,
    seed: int,
    seconds: float = 40.0,
    latency: float = 0.1,
    loc: LocalisationConfig | None = None,
    estimator: StateEstimator | None = None,
) -> Drive:
    """Run ``kind`` (or ``estimator``) over a synthetic drive with a receiver held in
    ``mode``."""
    rng = np.random.default_rng(seed)
    gcfg = GnssConfig(mode=mode, latency_s=latency, fix=GnssFixConfig(model="constant"))
    gnss, imu = Gnss(gcfg, DT), Imu(ImuConfig(), DT)
    odo = WheelOdometry(OdomConfig(), RADIUS, TRACK)
    lever = np.array([gcfg.antenna_x, 0.0, gcfg.antenna_height])
    est = estimator or make_estimator(kind, loc or LocalisationConfig(), CHI, DT)
    x = y = yaw = t = 0.0

    def readings(st: RobotState, odom: np.ndarray) -> Readings:
        f, g, rpy = imu.measure(st.rot, st.vel, st.ang, st.rpy, rng)
        truth = np.array([st.pos[0], st.pos[1], st.rpy[2]])
        return Readings(
            gnss.reading, gnss.updated, gnss.mode, gnss.sigma, gnss.age, f, g, rpy, odom, lever,
            truth,
        )  # fmt: skip

    st, _, _ = _truth(t, x, y, yaw)
    imu.reset(rng)
    gnss.reset(st.pos + st.rot @ lever, rng)
    est.reset(x, y, yaw, rng)
    est.update(readings(st, np.zeros(2)), DT)
    errors, covs, modes, truth = [], [], [], []
    for _ in range(round(seconds / DT)):
        for _ in range(10):  # integrate the truth finer than the control step
            _, v, w = _truth(t, x, y, yaw)
            x += v * math.cos(yaw) * DT / 10
            y += v * math.sin(yaw) * DT / 10
            yaw += w * DT / 10
            t += DT / 10
        st, _, _ = _truth(t, x, y, yaw)
        gnss.step(st.pos + st.rot @ lever, rng, DT)
        est.update(readings(st, odo.measure(st.wheels, rng)), DT)
        ex, ey, eyaw = est.pose
        errors.append([ex - x, ey - y, (eyaw - yaw + math.pi) % (2 * math.pi) - math.pi])
        covs.append(est.covariance)
        modes.append(gnss.mode)
        truth.append([x, y, yaw])
    return Drive(np.asarray(errors), np.asarray(covs), modes, np.asarray(truth))
