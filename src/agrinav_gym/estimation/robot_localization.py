"""robot_localization as a Nav2 user runs it: ``ekf_node`` in ``two_d_mode`` plus
``navsat_transform_node`` (Humble; docs/localisation.md "The estimator a Nav2 user runs").

Unlike ``ekf`` (the oracle), this filter knows nothing of the simulator's error models: every
reading is white noise with the covariance its driver reports, and the parameters are
robot_localization's defaults or the drivers' documented values (``RobotLocalizationConfig``).

* **State** (``two_d_mode``): x, y, yaw (world), vx, vy, vyaw (base_link), ax, ay
  (``two_d_mode: false``: ``robot_localization_3d.py``, which shares everything below but the
  state, the prediction and what each reading measures).
* **Prediction** (``Ekf::predict``): the omnidirectional model, ``P = J P Jᵀ + Q·Δt`` with
  Q robot_localization's ``process_noise_covariance`` default.
* **Readings**, as Nav2's GPS tutorial configures them: ``odom0`` the wheel odometry's twist
  (vx, vy = 0, vyaw: the controller's yaw rate through its wheel-separation multiplier χ) with
  the controller's twist covariance; ``imu0`` the IMU's yaw with its driver's orientation
  covariance (and, optionally, its yaw rate and its horizontal acceleration with gravity
  removed through the IMU's roll and pitch, as the Nav2 export configures it); ``odom1``
  navsat_transform's GPS odometry (x, y) with the fix's reported covariance. Each is one
  measurement, ``Ekf::correct``: a Mahalanobis test against its ``*_rejection_threshold`` (the
  whole reading is dropped when ``νᵀS⁻¹ν ≥ threshold²``), then the Joseph-form update;
  variances below 1e-9 are floored.
* **navsat_transform**: the datum is the first fix, tied to the filter's pose at that moment,
  so the map frame is the world shifted (its rotation, the filter's yaw less the heading
  navsat reads, is zero when both come from the same IMU). A fix is the antenna's position:
  without a base_link → gps transform (``gps_lever_arm`` false) it is taken as base_link's;
  with one, the antenna offset is removed through the filter's yaw (roll and pitch are zero in
  ``two_d_mode``). UTM's scale and grid convergence cancel: fixes and goals pass through the
  same transform.
* **Time**: the u-blox driver stamps a fix with its epoch, so it reaches the filter one latency
  late. With ``smooth_lagged_data`` off (the default) a reading older than the filter's last
  one is fused into the current state without a prediction — as if current
  (``FilterBase::processMeasurement``); with it on, the filter reverts to its state before the
  reading (within ``history_length_s``; else the oldest it kept) and replays the readings since
  (``RosFilter::revertTo``).
* **Start**: the stack has been running with the robot at rest, so the filter starts from its
  first readings — position from the first fix through the datum, yaw from the IMU, velocities
  from the odometry — each with its reading's covariance (robot_localization initialises a
  variable from the first measurement of it). Without a fix the start pose is the
  ``init_position_sigma`` prior (as the oracle's) until the first fix sets the datum.

Each update of the planar filter runs in the compiled kernel ``rl_update``
(``render/csrc/rl.c``) where the extension is built; this module's numpy filter is its twin and
reference (the same operations in the same order; numpy's matrix products and LAPACK's inverse
round differently, so the two agree to rounding, tests bound how closely).
"""

from __future__ import annotations

import ctypes
import math
import struct
from dataclasses import dataclass

import numpy as np

from ..config import LocalisationConfig
from ..interface import GNSS_NONE
from ..render import native as _native
from .readings import FloatArray, Readings

N = 8
X, Y, PSI, VX, VY, W, AX, AY = range(N)
MIN_VARIANCE = 1e-9  # Ekf::correct: a smaller measurement variance is raised to this
#: the node's own ``gravitational_acceleration`` default (it knows nothing of the simulator's)
GRAVITY = 9.80665
_ODOM, _IMU, _IMU_RATE, _IMU_ACCEL, _GPS = range(5)  # order of readings with equal stamps
_SOURCE = ("odom", "imu", "imu", "imu", "gps")  # what each reading counts as when rejected
_REJECTED = ("odom", "imu", "gps")  # the kernel's rejected[] counts, in order
#: a step's readings as the kernel takes them (csrc/native.h: RL_READING)
_PACK = struct.Struct(f"{_native.RL_READING}d")


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Measurement:
    """One reading as robot_localization queues it: its stamp, the state variables it
    measures, their values and variances, and its Mahalanobis threshold (None: never)."""

    time: float
    order: int
    index: tuple[int, ...]
    z: FloatArray
    var: FloatArray
    threshold: float | None


@dataclass(frozen=True)
class _Saved:
    time: float
    s: FloatArray
    P: FloatArray


class RobotLocalizationEkf:
    """See the module docstring; ``skid_factor`` is the controller's wheel-separation
    multiplier χ (the odometry's yaw rate / χ); ``native`` picks the kernel (True) or the numpy
    twin (False); None: the kernel where the extension is built."""

    name = "robot_localization"
    #: state size, the angles whose innovations and values wrap, and (x, y, yaw)'s indices
    n = N
    angles: tuple[int, ...] = (PSI,)
    pose_index: tuple[int, int, int] = (X, Y, PSI)

    def __init__(
        self, cfg: LocalisationConfig, skid_factor: float, dt: float, native: bool | None = None
    ) -> None:
        self.cfg = cfg
        self.rl = cfg.robot_localization
        self.chi = skid_factor
        self.dt = dt
        self.Q = np.diag(self._process_noise())
        rl = self.rl
        self.odom_var = np.asarray(rl.odom_twist_variance, np.float64)
        self.yaw_var = math.radians(rl.imu_yaw_sigma_deg) ** 2
        self.rate_var = math.radians(rl.imu_yaw_rate_sigma_deg_s) ** 2
        self.accel_var = np.full(2, rl.imu_accel_sigma**2)
        self.s = np.zeros(self.n)
        self.P = np.eye(self.n) * rl.initial_covariance
        self.t_last = 0.0
        self.k = 0
        self.anchored = False  # navsat_transform has its datum (the first fix)
        #: smooth_lagged_data: states saved after each stamp, and the readings processed
        self._states: list[_Saved] = []
        self._done: list[Measurement] = []
        self._rejected = {"odom": 0, "imu": 0, "gps": 0}
        #: the kernel (True) or the numpy twin; None: the kernel where it is built
        self.native = _native.available() if native is None else native
        if self.native:
            self._kernel_setup()

    def _kernel_setup(self) -> None:
        """The kernel's constants, state and history buffers (filled once, by name)."""
        rl = self.rl
        never = float("nan")

        def threshold(t: float | None) -> float:
            return never if t is None else float(t)

        config = _native.RlConfig(
            chi=self.chi, dt=self.dt, q=np.diag(self.Q).tolist(),
            odom_var=self.odom_var.tolist(), yaw_var=self.yaw_var, rate_var=self.rate_var,
            accel_var=self.accel_var.tolist(),
            odom_threshold=threshold(rl.odom_rejection_threshold),
            imu_threshold=threshold(rl.imu_rejection_threshold),
            accel_threshold=threshold(rl.imu_accel_rejection_threshold),
            gps_threshold=threshold(rl.gps_rejection_threshold), history_s=rl.history_length_s,
            smooth=int(rl.smooth_lagged_data), fuse_rate=int(rl.fuse_imu_yaw_rate),
            fuse_accel=int(rl.fuse_imu_acceleration), lever_arm=int(rl.gps_lever_arm),
        )  # fmt: skip
        # states are saved at control-step stamps: those within the history, one older, and
        # the step in hand; each stamp holds at most five readings (odom, imu yaw, rate and
        # acceleration, and one late fix)
        cap = math.ceil(rl.history_length_s / self.dt) + 4
        done = 5 * cap + 10
        size = ctypes.sizeof(_native.RlMeasurement)
        self._s, self._P = np.zeros(N), np.zeros((N, N))
        self._filter = _native.RlFilter(
            s=self._s, P=self._P, t_last=0.0, k=-1, anchored=0, rejected=[0, 0, 0],
            capacity=cap, count=0, head=0, hist_t=np.zeros(cap), hist_s=np.zeros((cap, N)),
            hist_P=np.zeros((cap, N * N)), done_capacity=done, done_count=0, done_head=0,
            done=np.zeros(done * size, np.uint8), queue_capacity=done + 8,
            queue=np.zeros((done + 8) * size, np.uint8),
        )  # fmt: skip
        self._io = np.zeros(_native.RL_READING)
        self._iov = self._io.data.cast("B")
        self._args = _native.RlUpdateArgs(config=config, filter=self._filter, reading=self._io)
        self._call = _native.kernel("rl_update")
        self._ref = ctypes.byref(self._args)

    # ------------------------------------------------------------------ protocol
    def reset(self, x: float, y: float, yaw: float, rng: np.random.Generator) -> None:
        c = self.cfg
        sp = c.init_position_sigma
        # a child stream, as the oracle's: the env's own draws stay the same whatever estimates
        d = rng.spawn(1)[0].standard_normal(2)
        self.s = np.zeros(self.n)
        ix, iy, iyaw = self.pose_index
        self.s[ix], self.s[iy], self.s[iyaw] = x + sp * d[0], y + sp * d[1], yaw
        self.P = np.eye(self.n) * self.rl.initial_covariance
        self.P[ix, ix] = self.P[iy, iy] = max(sp * sp, MIN_VARIANCE)
        self.t_last = 0.0
        self.k = -1
        self.anchored = False
        self._states.clear()
        self._done.clear()
        self._rejected = {"odom": 0, "imu": 0, "gps": 0}
        if self.native:  # the kernel's buffers hold the state from here on
            self._s[:], self._P[:] = self.s, self.P
            self.s, self.P = self._s, self._P
            self._filter.set(
                t_last=0.0, k=-1, anchored=0, rejected=[0, 0, 0], count=0, head=0,
                done_count=0, done_head=0,
            )  # fmt: skip

    def update(self, r: Readings, dt: float) -> None:
        if self.native:
            self._kernel_update(r)
            return
        self.k += 1
        now = self.k * self.dt
        if self.k == 0:
            self._start(r)
            return
        queue = self._readings(r, now)
        if self.rl.smooth_lagged_data and queue and queue[0].time < self.t_last:
            queue = self._revert(queue[0].time) + queue
            queue.sort(key=lambda m: (m.time, m.order))
        for m in queue:
            self._process(m)
            if self.rl.smooth_lagged_data:
                self._done.append(m)
                self._save()
        if self.rl.smooth_lagged_data:
            self._expire()

    def _kernel_update(self, r: Readings) -> None:
        odom, rpy, enu, sigma, lever = r.odom, r.rpy, r.gnss_enu, r.gnss_sigma, r.antenna_lever
        fix = 1.0 if r.gnss_new and r.gnss_mode != GNSS_NONE else 0.0
        _PACK.pack_into(
            self._iov, 0,
            odom[0], odom[1], rpy[0], rpy[1], rpy[2], r.gyro[2], r.accel[0], r.accel[1],
            fix, enu[0], enu[1], sigma[0], sigma[1], r.gnss_age, lever[0], lever[1],
        )  # fmt: skip
        status = self._call(self._ref)
        f = self._filter
        self.k, self.t_last, self.anchored = f.k, f.t_last, bool(f.anchored)
        if status == _native.NOT_POSITIVE:
            raise np.linalg.LinAlgError("innovation covariance singular (rl_update)")
        if status:
            raise _native.failed("rl_update", status)

    @property
    def rejected(self) -> dict[str, int]:
        """Readings dropped by the Mahalanobis test, by source (diagnostics and tests).

        Read on demand from the kernel: it changes rarely, and building it every step costs."""
        if self.native:
            return dict(zip(_REJECTED, self._filter.rejected, strict=True))
        return dict(self._rejected)

    @property
    def pose(self) -> tuple[float, float, float]:
        ix, iy, iyaw = self.pose_index
        return float(self.s[ix]), float(self.s[iy]), float(self.s[iyaw])

    @property
    def covariance(self) -> FloatArray:
        return self.P[np.ix_(self.pose_index, self.pose_index)].copy()

    def _process_noise(self) -> FloatArray:
        return np.asarray(self.rl.process_noise, np.float64)

    # ------------------------------------------------------------------ readings
    def _start(self, r: Readings) -> None:
        """The filter as the stack left it before the episode: its first readings."""
        twist = self._odom(r, 0.0)
        self.s[VX], self.s[VY], self.s[W] = twist.z
        self.P[VX, VX], self.P[VY, VY], self.P[W, W] = np.maximum(twist.var, MIN_VARIANCE)
        self.s[PSI] = _wrap(float(r.rpy[2]))
        self.P[PSI, PSI] = max(self.yaw_var, MIN_VARIANCE)
        if self.rl.fuse_imu_acceleration:
            acc = self._imu_accel(r, 0.0)
            self.s[AX], self.s[AY] = acc.z
            self.P[AX, AX], self.P[AY, AY] = np.maximum(acc.var, MIN_VARIANCE)
        self._start_position(r)

    def _start_position(self, r: Readings) -> None:
        """The first fix (if there is one) sets the position and navsat's datum; the filter's
        clock starts."""
        if r.gnss_new and r.gnss_mode != GNSS_NONE:
            fix = self._gps(r, 0.0)
            self.s[X], self.s[Y] = fix.z
            self.P[X, X], self.P[Y, Y] = np.maximum(fix.var, MIN_VARIANCE)
            self.anchored = True
        self.t_last = 0.0
        if self.rl.smooth_lagged_data:
            self._save()

    def _readings(self, r: Readings, now: float) -> list[Measurement]:
        out = [self._odom(r, now), self._imu_orientation(r, now)]
        if self.rl.fuse_imu_yaw_rate:
            out.append(self._imu_rate(r, now))
        if self.rl.fuse_imu_acceleration:
            out.append(self._imu_accel(r, now))
        if r.gnss_new and r.gnss_mode != GNSS_NONE:
            # stamped at its epoch: a whole number of control steps ago (on the same clock)
            fix = self._gps(r, (self.k - round(r.gnss_age / self.dt)) * self.dt)
            if not self.anchored:
                # navsat_transform's datum: the first fix is tied to the filter's pose now,
                # i.e. in the world frame the estimate moves onto the fix
                self.s[X], self.s[Y] = fix.z
                self.anchored = True
            else:
                out.append(fix)
        out.sort(key=lambda m: (m.time, m.order))
        return out

    def _odom(self, r: Readings, t: float) -> Measurement:
        z = np.array([float(r.odom[0]), 0.0, float(r.odom[1]) / self.chi])
        return Measurement(
            t, _ODOM, (VX, VY, W), z, self.odom_var.copy(), self.rl.odom_rejection_threshold
        )

    def _imu_orientation(self, r: Readings, t: float) -> Measurement:
        z = np.array([float(r.rpy[2])])
        return Measurement(
            t, _IMU, (PSI,), z, np.array([self.yaw_var]), self.rl.imu_rejection_threshold
        )

    def _imu_rate(self, r: Readings, t: float) -> Measurement:
        rate = np.array([float(r.gyro[2])])
        thr = self.rl.imu_rejection_threshold
        return Measurement(t, _IMU_RATE, (W,), rate, np.array([self.rate_var]), thr)

    def _imu_accel(self, r: Readings, t: float) -> Measurement:
        """imu0's linear acceleration with ``remove_gravitational_acceleration``: the specific
        force less gravity as the IMU's own roll and pitch place it in the body frame
        (RosFilter::prepareAcceleration); x and y only in ``two_d_mode``."""
        roll, pitch = float(r.rpy[0]), float(r.rpy[1])
        g = GRAVITY * math.cos(pitch)
        z = np.array(
            [
                float(r.accel[0]) + GRAVITY * math.sin(pitch),
                float(r.accel[1]) - g * math.sin(roll),
            ]
        )
        return Measurement(
            t, _IMU_ACCEL, (AX, AY), z, self.accel_var.copy(), self.rl.imu_accel_rejection_threshold
        )

    def _gps(self, r: Readings, t: float) -> Measurement:
        """navsat_transform's GPS odometry: the fix (at base_link unless the lever arm is
        known) with the receiver's reported horizontal variance."""
        e, n = float(r.gnss_enu[0]), float(r.gnss_enu[1])
        if self.rl.gps_lever_arm:
            lx, ly = float(r.antenna_lever[0]), float(r.antenna_lever[1])
            c, s = math.cos(self.s[PSI]), math.sin(self.s[PSI])
            e, n = e - (c * lx - s * ly), n - (s * lx + c * ly)
        var = np.asarray(r.gnss_sigma[:2], np.float64) ** 2
        return Measurement(t, _GPS, (X, Y), np.array([e, n]), var, self.rl.gps_rejection_threshold)

    # ------------------------------------------------------------------ filter
    def _process(self, m: Measurement) -> None:
        """FilterBase::processMeasurement: predict up to a newer reading, then correct; an
        older one corrects the current state and leaves the filter's time alone."""
        delta = m.time - self.t_last
        if delta > 0.0:
            self._predict(delta)
        self._correct(m)
        if delta >= 0.0:
            self.t_last = m.time

    def _predict(self, dt: float) -> None:
        x, y, psi, vx, vy, w, ax, ay = self.s.tolist()
        c, s = math.cos(psi), math.sin(psi)
        h2 = 0.5 * dt * dt
        J = np.eye(N)
        J[X, VX], J[X, VY], J[X, AX], J[X, AY] = c * dt, -s * dt, c * h2, -s * h2
        J[Y, VX], J[Y, VY], J[Y, AX], J[Y, AY] = s * dt, c * dt, s * h2, c * h2
        J[PSI, W] = J[VX, AX] = J[VY, AY] = dt
        J[X, PSI] = (-s * vx - c * vy) * dt + (-s * ax - c * ay) * h2
        J[Y, PSI] = (c * vx - s * vy) * dt + (c * ax - s * ay) * h2
        self.s = np.array(
            [
                x + (c * vx - s * vy) * dt + (c * ax - s * ay) * h2,
                y + (s * vx + c * vy) * dt + (s * ax + c * ay) * h2,
                _wrap(psi + w * dt),
                vx + ax * dt,
                vy + ay * dt,
                w,
                ax,
                ay,
            ]
        )
        self.P = J @ self.P @ J.T + self.Q * dt

    def _correct(self, m: Measurement) -> bool:
        """Ekf::correct; False when the Mahalanobis test dropped the reading."""
        idx = list(m.index)
        H = np.zeros((len(idx), self.n))
        H[np.arange(len(idx)), idx] = 1.0
        R = np.diag(np.maximum(np.abs(m.var), MIN_VARIANCE))
        PHt = self.P @ H.T
        S_inv = np.linalg.inv(H @ PHt + R)
        K = PHt @ S_inv
        nu = m.z - self.s[idx]
        for i, j in enumerate(idx):
            if j in self.angles:
                nu[i] = _wrap(float(nu[i]))
        if m.threshold is not None and float(nu @ S_inv @ nu) >= m.threshold**2:
            self._rejected[_SOURCE[m.order]] += 1
            return False
        self.s = self.s + K @ nu
        for j in self.angles:
            self.s[j] = _wrap(float(self.s[j]))
        G = np.eye(self.n) - K @ H
        self.P = G @ self.P @ G.T + K @ R @ K.T
        return True

    # ------------------------------------------------------------------ lagged data
    def _save(self) -> None:
        if self._states and self._states[-1].time == self.t_last:
            self._states[-1] = _Saved(self.t_last, self.s.copy(), self.P.copy())
        else:
            self._states.append(_Saved(self.t_last, self.s.copy(), self.P.copy()))

    def _revert(self, time: float) -> list[Measurement]:
        """RosFilter::revertTo(time − 1 ns): the last state saved before ``time`` (the oldest
        kept if the history is too short) and the readings processed since, to replay."""
        t = time - 1e-9
        last = None
        while self._states and self._states[-1].time > t:
            last = self._states.pop()
        if self._states:
            last = self._states[-1]
        if last is None:
            return []
        self.s, self.P, self.t_last = last.s.copy(), last.P.copy(), last.time
        replay = []
        while self._done and self._done[-1].time > t:
            m = self._done.pop()
            if last.time <= m.time:
                replay.append(m)
        return replay

    def _expire(self) -> None:
        """RosFilter::clearExpiredHistory: drop what is older than ``history_length_s``."""
        cut = self.t_last - self.rl.history_length_s
        while len(self._states) > 1 and self._states[0].time < cut:
            self._states.pop(0)
        while self._done and self._done[0].time < cut:
            self._done.pop(0)
