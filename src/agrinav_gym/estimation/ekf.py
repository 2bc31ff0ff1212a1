"""An EKF in the style of robot_localization's ``ekf_localization_node`` in ``two_d_mode``.

State: x, y, yaw, vx, vy, vyaw, ax, ay (robot_localization's 2D subset: position and yaw in
the world frame, velocities and accelerations in base_link) plus three error states the real
sensors need for a consistent filter: the IMU's heading error (Gauss-Markov, MTi-300 1° RMS),
the GNSS fix error east/north (Gauss-Markov with the fix mode's σ and correlation time —
treated as white, a correlated RTK error would make the filter far too confident) and the wheel
odometry's speed scale error (tyre slip and deflection make wheel speed read 3–10 % high; a
random walk, learnt from the GNSS track while moving).

Prediction is robot_localization's omnidirectional model with its process noise scaled by the
step (``P = F P Fᵀ + Q·dt``). Every control step fuses wheel odometry (vx; vyaw through the
skid-steer's effective track χ), the skid-steer's vy = 0, the gyro's yaw rate, the IMU's yaw
and, optionally, its horizontal specific force with gravity removed by the IMU attitude
(``imu0_remove_gravitational_acceleration``). GNSS fixes go through a navsat_transform-like
measurement: the antenna position is base_link plus the lever arm rotated by the IMU's roll and
pitch and the *state's* yaw. A fix is applied at its epoch (its age says how old it is): the
filter keeps its recent posteriors and readings, applies the fix there and re-runs the steps
since (robot_localization's history-based handling of lagged data).

Each update runs in the compiled kernel ``ekf_update`` (``render/csrc/ekf.c``) where the
extension is built; this module's numpy filter is its twin and reference (the same operations
in the same order; numpy's matrix products and LAPACK's solve round differently, so the two
agree to rounding, tests bound how closely).
"""

from __future__ import annotations

import ctypes
import math
import struct
from collections import deque

import numpy as np
from scipy.linalg.lapack import dposv

from ..config import LocalisationConfig
from ..interface import FIX_LEVELS, GNSS_NONE, GNSS_RTK_FIXED, GNSS_RTK_FLOAT, GNSS_STANDALONE
from ..render import native as _native
from .readings import FloatArray, Readings

N = 12
X, Y, PSI, VX, VY, W, AX, AY, BIAS, EE, EN, SCALE = range(N)
G = 9.81
DIFFUSE = 1e6  # m², a position prior the first fix overrides completely
LEVEL = {mode: i for i, mode in enumerate(FIX_LEVELS)}
#: a step's readings and fix, as the kernel takes them (csrc/native.h: EKF_READING, EKF_GNSS)
_PACK = struct.Struct(f"{_native.EKF_READING + _native.EKF_GNSS}d")


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class Ekf:
    """See the module docstring; ``skid_factor`` is the controller's χ (odometry ω / χ);
    ``native`` picks the kernel (True) or the numpy twin (False); None: the kernel where the
    extension is built (``AGRINAV_NATIVE=0`` disables it)."""

    name = "ekf"

    def __init__(
        self, cfg: LocalisationConfig, skid_factor: float, dt: float, native: bool | None = None
    ) -> None:
        self.cfg = cfg
        self.chi = skid_factor
        self.dt = dt
        self.tau = {
            GNSS_RTK_FIXED: cfg.gnss_tau_rtk_fixed_s,
            GNSS_RTK_FLOAT: cfg.gnss_tau_rtk_float_s,
            GNSS_STANDALONE: cfg.gnss_tau_standalone_s,
        }
        self.sb = math.radians(cfg.heading_bias_deg)
        self.phi_b = math.exp(-dt / cfg.heading_bias_tau_s)
        self.gyro_var = math.radians(cfg.gyro_sigma_deg_s) ** 2
        # per step: posterior state and covariance, its readings, the GNSS error mode and variance
        self._hist: deque[tuple[FloatArray, FloatArray, Readings, str | None, float]] = deque(
            maxlen=max(2, math.ceil(cfg.history_s / dt) + 1)
        )
        self.s = np.zeros(N)
        self.P = np.eye(N)
        self.gnss_mode: str | None = None
        self._gnss_var = 0.0
        self.k = 0
        self._F = np.eye(N)
        # step measurements: odometry v, odometry ω, vy = 0, gyro ω, IMU yaw, accel x, accel y
        self._H = np.zeros((7, N))
        self._H[0, VX] = self._H[1, W] = self._H[2, VY] = self._H[3, W] = 1.0
        self._H[4, PSI] = self._H[4, BIAS] = 1.0
        self._H[5, AX] = self._H[6, AY] = 1.0
        # the IMU's yaw error is the BIAS state; what is left is its output resolution
        self._R = np.array(
            [0.0, 0.0, cfg.lateral_sigma**2, self.gyro_var, math.radians(0.01) ** 2]
            + [cfg.accel_sigma**2] * 2
        )
        self.native = _native.available() if native is None else native
        if self.native:
            self._kernel_setup()

    def _kernel_setup(self) -> None:
        """The kernel's constants, state and history buffers (filled once, by name)."""
        c = self.cfg
        cap = self._hist.maxlen
        assert cap is not None
        tau = [0.0] * len(FIX_LEVELS)
        for mode, t in self.tau.items():
            tau[LEVEL[mode]] = t
        config = _native.EkfConfig(
            chi=self.chi, phi_b=self.phi_b, q_bias=self.sb * self.sb * (1.0 - self.phi_b**2),
            pose_noise=c.pose_noise, yaw_noise=c.yaw_noise, velocity_noise=c.velocity_noise,
            yaw_accel_noise=c.yaw_accel_noise, accel_noise=c.accel_noise,
            odom_scale_noise=c.odom_scale_noise, tau=tau, r_step=self._R.tolist(),
            odom_speed_rel=c.odom_speed_rel, odom_yaw_rel=c.odom_yaw_rel,
            odom_floor=c.odom_floor, gnss_white=c.gnss_white, history_s=c.history_s,
            use_accel=int(c.use_accel),
        )  # fmt: skip
        self._s, self._P = np.zeros(N), np.zeros((N, N))
        self._filter = _native.EkfFilter(
            s=self._s, P=self._P, mode=-1, gnss_var=0.0, k=-1, capacity=cap, count=0, head=0,
            hist_s=np.zeros((cap, N)), hist_P=np.zeros((cap, N * N)),
            hist_r=np.zeros((cap, _native.EKF_READING)), hist_var=np.zeros(cap),
            hist_mode=np.zeros(cap, np.int32),
        )  # fmt: skip
        self._io = np.zeros(_native.EKF_READING + _native.EKF_GNSS)
        self._iov = self._io.data.cast("B")
        self._args = _native.EkfUpdateArgs(
            config=config,
            filter=self._filter,
            dt=self.dt,
            reading=self._io[: _native.EKF_READING],
            gnss=self._io[_native.EKF_READING :],
        )
        self._call = _native.kernel("ekf_update")
        self._ref = ctypes.byref(self._args)

    # ------------------------------------------------------------------ protocol
    def reset(self, x: float, y: float, yaw: float, rng: np.random.Generator) -> None:
        """Start near the given pose, drawn from the configured prior: the heading is the
        IMU's; the position is replaced by the first fix when there is one (else it is the
        last known position, e.g. from the headland, off by about ``init_position_sigma``)."""
        c = self.cfg
        sp, sy = c.init_position_sigma, math.radians(c.init_yaw_sigma_deg)
        # a child stream: the env's own draws (sensor noise) stay the same whatever the estimator
        d = rng.spawn(1)[0].standard_normal(3)
        self.s = np.zeros(N)
        self.s[:3] = x + sp * d[0], y + sp * d[1], _wrap(yaw + sy * d[2])
        var = np.zeros(N)
        var[:3] = sp * sp, sp * sp, sy * sy
        var[VX : AY + 1] = 1e-4  # at rest
        var[BIAS] = self.sb * self.sb
        var[SCALE] = c.odom_scale_sigma**2
        self.P = np.diag(var)
        self.gnss_mode = None
        self._gnss_var = 0.0
        self.k = -1  # the first update is step 0 (the reset readings)
        self._hist.clear()
        if self.native:  # the kernel's buffers hold the state from here on
            self._s[:], self._P[:] = self.s, self.P
            self.s, self.P = self._s, self._P
            f = self._filter
            f.mode, f.gnss_var, f.k, f.count, f.head = -1, 0.0, -1, 0, 0

    def update(self, r: Readings, dt: float) -> None:
        if self.native:
            self._kernel_update(r, dt)
            return
        self.k += 1
        if self.k > 0:
            self._predict(dt)
        elif r.gnss_new and r.gnss_mode != GNSS_NONE:
            # navsat_transform's way: the first fix places the robot; the start prior only
            # stands in when the receiver has no fix yet
            self.P[X, :] = self.P[:, X] = self.P[Y, :] = self.P[:, Y] = 0.0
            self.P[X, X] = self.P[Y, Y] = DIFFUSE
        self._fuse_step(r)
        self._remember(r)
        if r.gnss_new and r.gnss_mode != GNSS_NONE:
            self._fuse_lagged_fix(r, dt)

    def _kernel_update(self, r: Readings, dt: float) -> None:
        odom, rpy, enu, sigma, lever = r.odom, r.rpy, r.gnss_enu, r.gnss_sigma, r.antenna_lever
        _PACK.pack_into(
            self._iov, 0,
            odom[0], odom[1], r.gyro[2], rpy[0], rpy[1], rpy[2], r.accel[0], r.accel[1],
            1.0 if r.gnss_new else 0.0, LEVEL[r.gnss_mode], enu[0], enu[1], sigma[0], sigma[1],
            r.gnss_age, lever[0], lever[2],
        )  # fmt: skip
        args = self._args
        if dt != args.dt:
            args.dt = dt
        status = self._call(self._ref)
        f = self._filter
        self.k, self._gnss_var = f.k, f.gnss_var
        self.gnss_mode = FIX_LEVELS[f.mode] if f.mode >= 0 else None
        if status == _native.NOT_POSITIVE:
            raise np.linalg.LinAlgError("EKF innovation covariance not positive (ekf_update)")
        if status:
            raise _native.failed("ekf_update", status)

    @property
    def pose(self) -> tuple[float, float, float]:
        return float(self.s[X]), float(self.s[Y]), float(self.s[PSI])

    @property
    def covariance(self) -> FloatArray:
        return self.P[:3, :3].copy()

    # ------------------------------------------------------------------ filter steps
    def _predict(self, dt: float) -> None:
        x, y, psi, vx, vy, w, ax, ay, b, ee, en, sc = self.s.tolist()
        ch, sh = math.cos(psi), math.sin(psi)
        h2 = 0.5 * dt * dt
        F = self._F
        F[X, PSI] = (-vx * sh - vy * ch) * dt + (-ax * sh - ay * ch) * h2
        F[Y, PSI] = (vx * ch - vy * sh) * dt + (ax * ch - ay * sh) * h2
        F[X, VX], F[X, VY], F[X, AX], F[X, AY] = ch * dt, -sh * dt, ch * h2, -sh * h2
        F[Y, VX], F[Y, VY], F[Y, AX], F[Y, AY] = sh * dt, ch * dt, sh * h2, ch * h2
        F[PSI, W] = F[VX, AX] = F[VY, AY] = dt
        F[BIAS, BIAS] = self.phi_b
        q = self._q(dt)
        phi = 1.0
        if self.gnss_mode is not None:
            phi = math.exp(-dt / self.tau[self.gnss_mode])
            q[EE] = q[EN] = self._gnss_var * (1.0 - phi * phi)
        F[EE, EE] = F[EN, EN] = phi
        self.s = np.array(
            [
                x + (vx * ch - vy * sh) * dt + (ax * ch - ay * sh) * h2,
                y + (vx * sh + vy * ch) * dt + (ax * sh + ay * ch) * h2,
                _wrap(psi + w * dt),
                vx + ax * dt,
                vy + ay * dt,
                w,
                ax,
                ay,
                b * self.phi_b,
                ee * phi,
                en * phi,
                sc,
            ]
        )
        P = F @ self.P @ F.T
        P.flat[:: N + 1] += q
        self.P = P

    def _q(self, dt: float) -> FloatArray:
        """Process noise of one step (robot_localization: the density times dt)."""
        c = self.cfg
        q = np.zeros(N)
        q[X] = q[Y] = c.pose_noise * dt
        q[PSI] = c.yaw_noise * dt
        q[VX] = q[VY] = c.velocity_noise * dt
        q[W] = c.yaw_accel_noise * dt
        q[AX] = q[AY] = c.accel_noise * dt
        q[BIAS] = self.sb * self.sb * (1.0 - self.phi_b**2)
        q[SCALE] = c.odom_scale_noise * dt
        return q

    def _fuse_step(self, r: Readings) -> None:
        """Odometry (v, ω/χ), vy = 0, gyro, IMU yaw and accelerometer: one stacked update."""
        c = self.cfg
        _, _, psi, vx, vy, w, ax, ay, b, _, _, sc = self.s.tolist()
        v_odom = float(r.odom[0])
        w_odom = float(r.odom[1]) / self.chi
        m = 7 if c.use_accel else 5
        H = self._H[:m]
        H[0, VX], H[0, SCALE] = 1.0 + sc, vx
        nu = [
            v_odom - vx * (1.0 + sc),
            w_odom - w,
            -vy,
            float(r.gyro[2]) - w,
            _wrap(float(r.rpy[2]) - psi - b),
        ]
        R = self._R[:m].copy()
        R[0] = (c.odom_speed_rel * abs(v_odom) + c.odom_floor) ** 2
        R[1] = (c.odom_yaw_rel * abs(w_odom) + c.odom_floor) ** 2
        if c.use_accel:
            # body-frame horizontal acceleration: gravity removed with the IMU's roll/pitch
            roll, pitch = float(r.rpy[0]), float(r.rpy[1])
            nu.append(float(r.accel[0]) + G * math.sin(pitch) - (ax - w * vy))
            nu.append(float(r.accel[1]) - G * math.cos(pitch) * math.sin(roll) - (ay + w * vx))
            H[5, W], H[5, VY] = -vy, -w
            H[6, W], H[6, VX] = vx, w
        self._correct(np.array(nu), H, R)

    def _fuse_gnss(self, r: Readings) -> None:
        mode = r.gnss_mode
        if mode != self.gnss_mode:  # a new error process: forget the old one's estimate
            self.gnss_mode = mode
            self._gnss_var = float(np.mean(np.asarray(r.gnss_sigma[:2]) ** 2))
            for i in (EE, EN):
                self.s[i] = 0.0
                self.P[i, :] = 0.0
                self.P[:, i] = 0.0
                self.P[i, i] = self._gnss_var
        s = self.s
        roll, pitch = float(r.rpy[0]), float(r.rpy[1])
        ax_, _, ah = (float(v) for v in r.antenna_lever)
        lx = math.cos(pitch) * ax_ + math.sin(pitch) * math.cos(roll) * ah
        ly = -math.sin(roll) * ah
        ch, sh = math.cos(s[PSI]), math.sin(s[PSI])
        h = np.array([s[X] + ch * lx - sh * ly + s[EE], s[Y] + sh * lx + ch * ly + s[EN]])
        H = np.zeros((2, N))
        H[0, X] = H[1, Y] = H[0, EE] = H[1, EN] = 1.0
        H[0, PSI], H[1, PSI] = -sh * lx - ch * ly, ch * lx - sh * ly
        var = self.cfg.gnss_white**2
        self._correct(np.asarray(r.gnss_enu[:2], np.float64) - h, H, np.array([var, var]))

    def _correct(self, nu: FloatArray, H: FloatArray, R: FloatArray) -> None:
        P = self.P
        PHt = P @ H.T
        S = H @ PHt
        S.flat[:: len(R) + 1] += R
        # S is symmetric positive definite: LAPACK's Cholesky solve, without numpy.linalg's
        # per-call checks (a quarter of the filter's time at these sizes)
        _, Kt, info = dposv(S, PHt.T)
        if info != 0:
            raise np.linalg.LinAlgError(f"EKF innovation covariance not positive ({info})")
        K = Kt.T
        self.s = self.s + K @ nu
        self.s[PSI] = _wrap(self.s[PSI])
        P = P - K @ PHt.T
        self.P = 0.5 * (P + P.T)

    def _remember(self, r: Readings, at: int | None = None) -> None:
        entry = (self.s.copy(), self.P.copy(), r, self.gnss_mode, self._gnss_var)
        if at is None:
            self._hist.append(entry)
        else:
            self._hist[at] = entry

    def _fuse_lagged_fix(self, r: Readings, dt: float) -> None:
        """Apply the fix at its epoch, then replay the steps since from the stored readings."""
        if r.gnss_age > self.cfg.history_s + 1e-9:
            return  # older than the history: dropped, as robot_localization drops stale data
        start = len(self._hist) - 1 - min(round(r.gnss_age / dt), len(self._hist) - 1)
        s, P, r_start, self.gnss_mode, self._gnss_var = self._hist[start]
        self.s, self.P = s.copy(), P.copy()
        self._fuse_gnss(r)
        self._remember(r_start, start)
        for i in range(start + 1, len(self._hist)):
            ri = self._hist[i][2]
            self._predict(dt)
            self._fuse_step(ri)
            self._remember(ri, i)
