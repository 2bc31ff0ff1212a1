"""IMU (Xsens MTi-300-like) and wheel odometry.

Gyro and accelerometer: white noise with the datasheet noise densities sampled at the control
rate (σ = density·√rate), plus a bias that wanders as a Gauss-Markov process whose std is the
in-run bias stability. Orientation estimate: true roll/pitch/heading plus time-correlated
errors with the datasheet RMS. Specific force is measured, not acceleration: at rest the
accelerometer reads +9.81 m/s² up.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..config import ImuConfig, OdomConfig
from .noise import GaussMarkov

G = 9.81
DEG = math.pi / 180.0
MICRO_G = 1e-6 * G


class Imu:
    def __init__(self, cfg: ImuConfig, dt: float) -> None:
        self.cfg = cfg
        self.dt = dt
        rate = 1.0 / dt
        self.gyro_sigma = cfg.gyro_noise_deg_s_rthz * DEG * math.sqrt(rate)
        self.accel_sigma = cfg.accel_noise_ug_rthz * MICRO_G * math.sqrt(rate)
        # One 9-state process (gyro bias, accelerometer bias, orientation error): one draw a step.
        sigma = np.concatenate(
            [
                np.full(3, cfg.gyro_bias_deg_h * DEG / 3600.0),
                np.full(3, cfg.accel_bias_ug * MICRO_G),
                np.array([cfg.roll_pitch_rms_deg, cfg.roll_pitch_rms_deg, cfg.heading_rms_deg])
                * DEG,
            ]
        )
        tau = np.array([cfg.bias_tau_s] * 6 + [cfg.orientation_tau_s] * 3)
        self.slow = GaussMarkov(sigma, tau, dt, 9)
        self.white = np.array([self.accel_sigma] * 3 + [self.gyro_sigma] * 3)
        self.prev_vel = np.zeros(3)

    def reset(self, rng: np.random.Generator, vel: NDArray[np.float64] | None = None) -> None:
        """Restart the noise processes; ``vel`` is the base's velocity now (world frame), from
        which the first reading's acceleration is differenced (default: at rest)."""
        self.slow.reset(rng)
        self.prev_vel = np.zeros(3) if vel is None else np.asarray(vel, np.float64).copy()

    def measure(
        self,
        rot: NDArray[np.float64],
        vel: NDArray[np.float64],
        ang: NDArray[np.float64],
        rpy: NDArray[np.float64],
        rng: np.random.Generator,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(specific force, angular rate) in the body frame and the (roll, pitch, yaw) estimate.

        ``rot`` is body->world, ``vel``/``ang`` are world-frame velocities.
        """
        acc = (vel - self.prev_vel) / self.dt
        self.prev_vel = vel
        f_body = rot.T @ (acc + np.array([0.0, 0.0, G]))
        w_body = rot.T @ ang
        slow = self.slow.step(rng)
        white = self.white * rng.standard_normal(6)
        f = f_body + slow[3:6] + white[:3]
        w = w_body + slow[:3] + white[3:]
        est = rpy + slow[6:]
        est[2] = (est[2] + math.pi) % (2 * math.pi) - math.pi
        return f, w, est


class WheelOdometry:
    """v and ω from wheel speeds with the nominal track: skid slip makes ω (and so pose) drift."""

    def __init__(self, cfg: OdomConfig, radius: float, track: float) -> None:
        self.cfg = cfg
        self.radius = radius
        self.track = track

    def measure(self, wheel_speeds: list[float], rng: np.random.Generator) -> NDArray[np.float64]:
        w = np.asarray(wheel_speeds) * (1.0 + self.cfg.noise * rng.standard_normal(4))
        left, right = 0.5 * (w[0] + w[2]) * self.radius, 0.5 * (w[1] + w[3]) * self.radius
        return np.array([0.5 * (left + right), (right - left) / self.track])
