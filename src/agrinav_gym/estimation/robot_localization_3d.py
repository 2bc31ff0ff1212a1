"""robot_localization with ``two_d_mode: false``: ``ekf_node``'s full 15-variable filter, as a
user on tilted or ridged ground sets it up (docs/localisation.md "Roll, pitch and the mast").

In ``two_d_mode`` the filter's roll and pitch are zero, so navsat_transform removes the GNSS
antenna's offset from base_link through yaw alone and a leaning mast reads as a lateral
position error (0.71 m · sin(roll) on the Summit-XL). Here the filter carries its attitude:

* **State**: x, y, z, roll, pitch, yaw (world), vx, vy, vz, vroll, vpitch, vyaw (base_link),
  ax, ay, az — robot_localization's order.
* **Prediction** (``Ekf::predict``): body velocities and accelerations rotated into the world
  by roll, pitch and yaw; body rates into Euler-angle rates; the Jacobian as its source writes
  it; ``P = J P Jᵀ + Q·Δt`` with Q its default 15-variable diagonal.
* **Readings**: ``odom0`` vx, vy = 0, vz = 0 (the controller's twist is planar in base_link)
  and vyaw; ``imu0`` roll, pitch and yaw with the driver's orientation covariance (and,
  optionally, its three body rates, and its acceleration with gravity removed through its own
  roll and pitch); ``odom1`` the GPS odometry's x, y (navsat_transform's altitude is not fused).
* **navsat_transform**: the antenna offset is rotated by the filter's whole attitude (the
  world → base_link transform it looks up) before it is removed from the fix.

Everything else (the Mahalanobis gates, the handling of lagged readings, the start from the
first readings) is the two-dimensional filter's (``robot_localization.py``).
"""

from __future__ import annotations

import math

import numpy as np

from scenario_gen.obstacles import rotation

from ..config import LocalisationConfig
from .readings import FloatArray, Readings
from .robot_localization import (
    _GPS,
    _IMU,
    _IMU_ACCEL,
    _IMU_RATE,
    _ODOM,
    GRAVITY,
    MIN_VARIANCE,
    Measurement,
    RobotLocalizationEkf,
    _wrap,
)

N3 = 15
X, Y, Z, ROLL, PITCH, YAW, VX, VY, VZ, VROLL, VPITCH, VYAW, AX, AY, AZ = range(N3)


class RobotLocalizationEkf3D(RobotLocalizationEkf):
    """See the module docstring; ``skid_factor`` as for the two-dimensional filter."""

    n = N3
    angles = (ROLL, PITCH, YAW)
    pose_index = (X, Y, YAW)

    def __init__(self, cfg: LocalisationConfig, skid_factor: float, dt: float) -> None:
        super().__init__(cfg, skid_factor, dt, native=False)  # the kernel is the planar filter
        vx, vy, vyaw = self.odom_var
        #: the controller reports one variance for its linear twist; vz takes vy's
        self.odom_var = np.array([vx, vy, vy, vyaw])
        rp = math.radians(self.rl.imu_roll_pitch_sigma_deg) ** 2
        self.attitude_var = np.array([rp, rp, self.yaw_var])
        self.accel_var = np.full(3, self.rl.imu_accel_sigma**2)

    def _process_noise(self) -> FloatArray:
        x, y, yaw, vx, vy, vyaw, ax, ay = self.rl.process_noise
        z, roll, pitch, vz, vroll, vpitch, az = self.rl.process_noise_3d
        q = (x, y, z, roll, pitch, yaw, vx, vy, vz, vroll, vpitch, vyaw, ax, ay, az)
        return np.asarray(q, np.float64)

    # ------------------------------------------------------------------ readings
    def _start(self, r: Readings) -> None:
        twist = self._odom(r, 0.0)
        att = self._imu_orientation(r, 0.0)
        for m in (twist, att):
            idx = list(m.index)
            self.s[idx] = m.z
            self.P[idx, idx] = np.maximum(m.var, MIN_VARIANCE)
        if self.rl.fuse_imu_acceleration:
            acc = self._imu_accel(r, 0.0)
            self.s[[AX, AY, AZ]] = acc.z
            self.P[[AX, AY, AZ], [AX, AY, AZ]] = np.maximum(acc.var, MIN_VARIANCE)
        self._start_position(r)

    def _odom(self, r: Readings, t: float) -> Measurement:
        z = np.array([float(r.odom[0]), 0.0, 0.0, float(r.odom[1]) / self.chi])
        return Measurement(
            t, _ODOM, (VX, VY, VZ, VYAW), z, self.odom_var.copy(), self.rl.odom_rejection_threshold
        )

    def _imu_orientation(self, r: Readings, t: float) -> Measurement:
        z = np.asarray(r.rpy[:3], np.float64).copy()
        thr = self.rl.imu_rejection_threshold
        return Measurement(t, _IMU, (ROLL, PITCH, YAW), z, self.attitude_var.copy(), thr)

    def _imu_rate(self, r: Readings, t: float) -> Measurement:
        z = np.asarray(r.gyro[:3], np.float64).copy()
        var = np.full(3, self.rate_var)
        thr = self.rl.imu_rejection_threshold
        return Measurement(t, _IMU_RATE, (VROLL, VPITCH, VYAW), z, var, thr)

    def _imu_accel(self, r: Readings, t: float) -> Measurement:
        """The specific force less gravity as the IMU's roll and pitch place it in the body
        frame (RosFilter::prepareAcceleration), all three axes."""
        roll, pitch = float(r.rpy[0]), float(r.rpy[1])
        g = GRAVITY * math.cos(pitch)
        z = np.array(
            [
                float(r.accel[0]) + GRAVITY * math.sin(pitch),
                float(r.accel[1]) - g * math.sin(roll),
                float(r.accel[2]) - g * math.cos(roll),
            ]
        )
        thr = self.rl.imu_accel_rejection_threshold
        return Measurement(t, _IMU_ACCEL, (AX, AY, AZ), z, self.accel_var.copy(), thr)

    def _gps(self, r: Readings, t: float) -> Measurement:
        """The fix less the antenna offset rotated by the filter's roll, pitch and yaw."""
        e, n = float(r.gnss_enu[0]), float(r.gnss_enu[1])
        if self.rl.gps_lever_arm:
            R = rotation(float(self.s[ROLL]), float(self.s[PITCH]), float(self.s[YAW]))
            off = R @ np.asarray(r.antenna_lever[:3], np.float64)
            e, n = e - float(off[0]), n - float(off[1])
        var = np.asarray(r.gnss_sigma[:2], np.float64) ** 2
        return Measurement(t, _GPS, (X, Y), np.array([e, n]), var, self.rl.gps_rejection_threshold)

    # ------------------------------------------------------------------ filter
    def _predict(self, dt: float) -> None:
        self.s, J = self.transition(self.s, dt)
        self.P = J @ self.P @ J.T + self.Q * dt

    def transition(self, s: FloatArray, dt: float) -> tuple[FloatArray, FloatArray]:
        """The state ``dt`` on, and the Jacobian robot_localization propagates P with."""
        roll, pitch, yaw = float(s[ROLL]), float(s[PITCH]), float(s[YAW])
        sr, cr = math.sin(roll), math.cos(roll)
        sp, cp = math.sin(pitch), math.cos(pitch)
        cpi = 1.0 / cp
        tp = sp * cpi
        R = rotation(roll, pitch, yaw)
        h2 = 0.5 * dt * dt
        F = np.eye(N3)
        F[X : Z + 1, VX : VZ + 1] = R * dt
        F[X : Z + 1, AX : AZ + 1] = R * h2
        F[ROLL, VROLL : VYAW + 1] = (dt, sr * tp * dt, cr * tp * dt)
        F[PITCH, VPITCH : VYAW + 1] = (cr * dt, -sr * dt)
        F[YAW, VPITCH : VYAW + 1] = (sr * cpi * dt, cr * cpi * dt)
        F[VX, AX] = F[VY, AY] = F[VZ, AZ] = dt

        # Jacobian: the transfer function plus its derivatives through the attitude
        v, a = s[VX : VZ + 1], s[AX : AZ + 1]
        u = v * dt + a * h2
        sy, cy = math.sin(yaw), math.cos(yaw)
        dR_droll = np.array(
            [
                [0.0, cy * sp * cr + sy * sr, -cy * sp * sr + sy * cr],
                [0.0, sy * sp * cr - cy * sr, -sy * sp * sr - cy * cr],
                [0.0, cp * cr, -cp * sr],
            ]
        )
        dR_dpitch = np.array(
            [
                [-cy * sp, cy * cp * sr, cy * cp * cr],
                [-sy * sp, sy * cp * sr, sy * cp * cr],
                [-cp, -sp * sr, -sp * cr],
            ]
        )
        dR_dyaw = np.array(
            [
                [-sy * cp, -sy * sp * sr - cy * cr, -sy * sp * cr + cy * sr],
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [0.0, 0.0, 0.0],
            ]
        )
        vp, vy_ = float(s[VPITCH]), float(s[VYAW])
        J = F.copy()
        J[X : Z + 1, ROLL] = dR_droll @ u
        J[X : Z + 1, PITCH] = dR_dpitch @ u
        J[X : Y + 1, YAW] = (dR_dyaw @ u)[:2]
        J[ROLL, ROLL] = 1.0 + (cr * tp * vp - sr * tp * vy_) * dt
        J[ROLL, PITCH] = (cpi * cpi * sr * vp + cpi * cpi * cr * vy_) * dt
        J[PITCH, ROLL] = (-sr * vp - cr * vy_) * dt
        J[YAW, ROLL] = (cr * cpi * vp - sr * cpi * vy_) * dt
        # the sign of the yaw-rate term is robot_localization's (Ekf::predict), not the
        # derivative's: the filter a user runs is the one modelled
        J[YAW, PITCH] = (sr * tp * cpi * vp - cr * tp * cpi * vy_) * dt

        new = F @ s
        for j in self.angles:
            new[j] = _wrap(float(new[j]))
        return new, J
