"""GNSS/INS blend: each fix through the lever arm, wheel odometry between fixes."""

from __future__ import annotations

import math

import numpy as np

from .readings import FloatArray, Readings


class GnssInsBlend:
    """The antenna sits on a 0.6 m mast, so a few degrees of roll on a furrow ridge move it
    centimetres sideways; like a GNSS/INS, each fix is brought back to base_link through the
    lever arm rotated by the IMU's attitude estimate. Between fixes the position is dead-
    reckoned with the odometry speed along the IMU heading. No filtering: the fix's noise
    passes straight through (an ideal RTK-fixed receiver is what makes this adequate)."""

    name = "blend"

    def __init__(self) -> None:
        self.xy = np.zeros(2)
        self.yaw = 0.0

    def reset(self, x: float, y: float, yaw: float, rng: np.random.Generator) -> None:
        # replaced by the first fix; dead-reckoned from here only if the receiver has none
        self.xy = np.array([x, y], np.float64)
        self.yaw = yaw

    def update(self, r: Readings, dt: float) -> None:
        roll, pitch, yaw = (float(v) for v in r.rpy)
        c, s = math.cos(yaw), math.sin(yaw)
        if r.gnss_new:
            ax, _, ah = (float(v) for v in r.antenna_lever)
            cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
            # R = Rz(yaw)·Ry(pitch)·Rx(roll) applied to the lever arm (ax, 0, ah)
            lx = cp * ax + sp * cr * ah
            ly = -sr * ah
            ant = r.gnss_enu
            self.xy = np.array([ant[0] - (c * lx - s * ly), ant[1] - (s * lx + c * ly)])
        else:
            v = float(r.odom[0])
            self.xy = self.xy + v * dt * np.array([c, s])
        self.yaw = yaw

    @property
    def pose(self) -> tuple[float, float, float]:
        return float(self.xy[0]), float(self.xy[1]), self.yaw

    @property
    def covariance(self) -> FloatArray:
        return np.full((3, 3), np.nan)  # the blend keeps no uncertainty
