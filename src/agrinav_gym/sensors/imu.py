"""IMU (Xsens MTi-300-like) and wheel odometry.

Gyro and accelerometer: white noise with the datasheet noise densities sampled at the control
rate (σ = density·√rate), plus a bias that wanders as a Gauss-Markov process whose std is the
datasheet's in-run bias stability. A datasheet gives that figure as the floor of the Allan
deviation, and a Gauss-Markov process's Allan deviation peaks at ≈ 0.62 × its std (at an
averaging time ≈ 1.9 τ), so the simulated bias is ≈ 0.6 × as unstable as the datasheet's
(measured: 5.5–6.8 °/h for 10 °/h). Orientation estimate: true roll/pitch/heading plus
time-correlated errors with the datasheet RMS. Specific force is measured, not acceleration:
at rest the accelerometer reads +9.81 m/s² up.
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
        # Python floats, element by element in numpy's order: for 3-vectors numpy's per-call
        # cost is most of the work
        dt = self.dt
        (vx, vy, vz), (px, py, pz) = vel.tolist(), self.prev_vel.tolist()
        self.prev_vel = vel
        # specific force: acceleration + gravity's reaction (the + 0.0 as numpy adds it)
        gx, gy, gz = (vx - px) / dt + 0.0, (vy - py) / dt + 0.0, (vz - pz) / dt + G
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rot.tolist()
        wx, wy, wz = ang.tolist()
        slow = self.slow.step_list(rng)
        white = (self.white * rng.standard_normal(6)).tolist()
        # body frame: rot.T @ v
        f = np.array(
            [
                (r00 * gx + r10 * gy) + r20 * gz + slow[3] + white[0],
                (r01 * gx + r11 * gy) + r21 * gz + slow[4] + white[1],
                (r02 * gx + r12 * gy) + r22 * gz + slow[5] + white[2],
            ]
        )
        w = np.array(
            [
                (r00 * wx + r10 * wy) + r20 * wz + slow[0] + white[3],
                (r01 * wx + r11 * wy) + r21 * wz + slow[1] + white[4],
                (r02 * wx + r12 * wy) + r22 * wz + slow[2] + white[5],
            ]
        )
        roll, pitch, yaw = rpy.tolist()
        est = np.array(
            [
                roll + slow[6],
                pitch + slow[7],
                (yaw + slow[8] + math.pi) % (2 * math.pi) - math.pi,
            ]
        )
        return f, w, est


class WheelOdometry:
    """v and ω from wheel speeds with the nominal track: skid slip makes ω (and so pose) drift."""

    def __init__(self, cfg: OdomConfig, radius: float, track: float) -> None:
        self.cfg = cfg
        self.radius = radius
        self.track = track

    def measure(self, wheel_speeds: list[float], rng: np.random.Generator) -> NDArray[np.float64]:
        k = self.cfg.noise
        w = [
            v * (1.0 + k * z)
            for v, z in zip(wheel_speeds, rng.standard_normal(4).tolist(), strict=True)
        ]
        left, right = 0.5 * (w[0] + w[2]) * self.radius, 0.5 * (w[1] + w[3]) * self.radius
        return np.array([0.5 * (left + right), (right - left) / self.track])
