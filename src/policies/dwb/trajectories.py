"""Nav2's XYThetaIterator (the dynamic window) and StandardTrajectoryGenerator, vectorised.

The twists come out in the iterator's order (v outer, ω inner) because Nav2 keeps the first
of equally scored twists. Rollouts reproduce ``generateTrajectory`` to the floating-point
operation: per-twist step count from the linear/angular granularity, velocities ramped by
``projectVelocity`` each step, forward-Euler poses, the last pose repeated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray

EPSILON = 1e-5  # one_d_velocity_iterator.hpp


@dataclass(frozen=True)
class Kinematics:
    """KinematicParameters with the robot's values filled in (x and θ; y is always 0)."""

    min_vel_x: float
    max_vel_x: float
    max_vel_theta: float
    min_speed_xy: float
    max_speed_xy: float
    min_speed_theta: float
    acc_lim_x: float
    decel_lim_x: float
    acc_lim_theta: float
    decel_lim_theta: float


def project_velocity(v0: float, accel: float, decel: float, dt: float, target: float) -> float:
    """Nav2's projectVelocity: one ramp step from v0 toward target."""
    if v0 < target:
        return min(target, v0 + accel * dt)
    return max(target, v0 + decel * dt)


def axis_samples(
    current: float, vmin: float, vmax: float, acc: float, dec: float, dt: float, n: int
) -> list[float]:
    """The values a OneDVelocityIterator returns, in order (zero inserted when crossed)."""
    current = min(max(current, vmin), vmax)
    hi = project_velocity(current, acc, dec, dt, vmax)
    lo = project_velocity(current, acc, dec, dt, vmin)
    if abs(lo - hi) < EPSILON:
        increment = 1.0
    else:
        increment = (hi - lo) / max(1, max(2, n) - 1)
    out = []
    cur, return_zero, zero_now = lo, True, False
    while not cur > hi + EPSILON:
        out.append(0.0 if zero_now else cur)
        if return_zero and cur < 0.0 < cur + increment and cur + increment <= hi + EPSILON:
            zero_now, return_zero = True, False
        else:
            cur += increment
            zero_now = False
    return out


def dynamic_window(
    v0: float, w0: float, k: Kinematics, sim_time: float, nv: int, nw: int
) -> FloatArray:
    """(n, 2) twists (v, ω) of XYThetaIterator in its iteration order, invalid ones skipped.

    The window is the current velocity ± the acceleration limits × ``sim_time`` (Nav2 passes
    sim_time as the acceleration time), clipped to the velocity limits.
    """
    vs = axis_samples(v0, k.min_vel_x, k.max_vel_x, k.acc_lim_x, k.decel_lim_x, sim_time, nv)
    ws = axis_samples(
        w0, -k.max_vel_theta, k.max_vel_theta, k.acc_lim_theta, k.decel_lim_theta, sim_time, nw
    )
    V, W = np.meshgrid(np.asarray(vs), np.asarray(ws), indexing="ij")
    tw = np.column_stack([V.ravel(), W.ravel()])
    vsq = tw[:, 0] ** 2
    ok = np.ones(len(tw), bool)
    if k.max_speed_xy >= 0:
        ok &= ~(vsq > k.max_speed_xy**2 + EPSILON)
    if k.min_speed_xy >= 0 and k.min_speed_theta >= 0:
        ok &= ~(
            (vsq + EPSILON < k.min_speed_xy**2) & (np.abs(tw[:, 1]) + EPSILON < k.min_speed_theta)
        )
    ok &= ~((vsq == 0.0) & (tw[:, 1] == 0.0))
    return tw[ok]


@dataclass
class Rollouts:
    """Poses of every twist's trajectory, padded to a common length by repeating the last."""

    twists: FloatArray  # (n, 2) commanded (v, ω): the trajectory's ``velocity``
    poses: FloatArray  # (n, m, 3) x, y, θ in the costmap frame
    length: NDArray[np.int64]  # valid poses per trajectory (start, steps, repeated last)
    dt: FloatArray  # (n,) time step of each trajectory
    #: the poses' costmap cells (mx, my, on the map), filled once per cycle by the planner
    cells: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]] | None = None
    _on_grid: NDArray[np.bool_] | None = None

    def mask(self) -> NDArray[np.bool_]:
        """(n, m) True for real poses, False for padding."""
        return np.arange(self.poses.shape[1])[None, :] < self.length[:, None]

    def on_grid(self) -> NDArray[np.bool_]:
        """(n,) every real pose on the costmap (needs ``cells``)."""
        assert self.cells is not None
        if self._on_grid is None:
            self._on_grid = np.asarray(~(self.mask() & ~self.cells[2]).any(axis=1), bool)
        out: NDArray[np.bool_] = self._on_grid
        return out

    def last(self) -> FloatArray:
        """(n, 3) each trajectory's last pose."""
        out: FloatArray = self.poses[np.arange(len(self.poses)), self.length - 1]
        return out

    def subset(self, idx: NDArray[np.int64]) -> Rollouts:
        m = int(self.length[idx].max())
        cells = None
        if self.cells is not None:
            cells = (self.cells[0][idx, :m], self.cells[1][idx, :m], self.cells[2][idx, :m])
        return Rollouts(
            self.twists[idx], self.poses[idx, :m], self.length[idx], self.dt[idx], cells
        )


def step_counts(
    twists: FloatArray,
    sim_time: float,
    linear_granularity: float,
    angular_granularity: float,
    discretize_by_time: bool = False,
    time_granularity: float = 0.5,
) -> NDArray[np.int64]:
    """StandardTrajectoryGenerator::getTimeSteps' step count of each twist."""
    if discretize_by_time:
        n = np.full(len(twists), math.ceil(sim_time / time_granularity), np.int64)
    else:
        lin = np.abs(twists[:, 0]) * sim_time / linear_granularity
        ang = np.abs(twists[:, 1]) * sim_time / angular_granularity
        n = np.ceil(np.maximum(lin, ang)).astype(np.int64)
    return np.maximum(n, 1)


def _ramp(
    v0: float, target: FloatArray, acc: float, dec: float, dt: FloatArray, m: int
) -> FloatArray:
    """(n, m) velocities after 1..m projectVelocity steps: the running sum is the C++ loop's
    own sequence of additions until it reaches the target, where it then stays."""
    up = target > v0
    seq = np.empty((len(target), m + 1))
    seq[:, 0] = v0
    seq[:, 1:] = (np.where(up, acc, dec) * dt)[:, None]
    np.cumsum(seq, axis=1, out=seq)
    # min(target, ·) while accelerating, max(target, ·) while braking; target == v0 stays
    hi = np.where(up | (target == v0), target, np.inf)
    lo = np.where(up, -np.inf, target)
    out: FloatArray = np.clip(seq[:, 1:], lo[:, None], hi[:, None])
    return out


def rollout(
    twists: FloatArray,
    pose: tuple[float, float, float],
    vel: tuple[float, float],
    k: Kinematics,
    sim_time: float,
    counts: NDArray[np.int64],
    include_last_point: bool = True,
) -> Rollouts:
    """generateTrajectory for every twist from ``pose`` at velocity ``vel`` (v, ω)."""
    n = len(twists)
    m = int(counts.max()) if n else 1
    dt = sim_time / counts.astype(np.float64)
    extra = int(include_last_point)
    # The heading sequence depends on (ω, step count) only, shared by most twists of one ω:
    # it and its cos/sin are computed once per distinct pair.
    _ws, wi = np.unique(twists[:, 1], return_inverse=True)
    keys, first, inv = np.unique(
        wi.ravel() * (m + 1) + counts, return_index=True, return_inverse=True
    )
    inv = inv.ravel()
    cu = counts[first]
    dtu = sim_time / cu.astype(np.float64)
    wu = _ramp(vel[1], twists[first, 1], k.acc_lim_theta, k.decel_lim_theta, dtu, m)
    deadu = np.arange(m)[None, :] >= cu[:, None]
    # theta_{i+1} = theta_i + w_{i+1} dt; x_{i+1} = x_i + (v_{i+1} cos(theta_i)) dt, summed in
    # the loop's order; padded steps add exact zeros, so the padding repeats the last pose
    thu = np.zeros((len(keys), m + 1 + extra))
    thu[:, 0] = pose[2]
    np.multiply(wu, dtu[:, None], out=thu[:, 1 : m + 1])
    thu[:, 1 : m + 1][deadu] = 0.0
    np.cumsum(thu, axis=1, out=thu)
    trig = (np.cos(thu[:, :m]), np.sin(thu[:, :m]))
    v = _ramp(vel[0], twists[:, 0], k.acc_lim_x, k.decel_lim_x, dt, m)
    dead = np.arange(m)[None, :] >= counts[:, None]
    dts = dt[:, None]
    poses = np.empty((n, m + 1 + extra, 3))
    poses[:, :, 2] = thu[inv]
    for axis, p0 in ((0, pose[0]), (1, pose[1])):
        q = np.zeros((n, m + 1 + extra))
        q[:, 0] = p0
        np.multiply(v, trig[axis][inv], out=q[:, 1 : m + 1])
        q[:, 1 : m + 1] *= dts
        q[:, 1 : m + 1][dead] = 0.0
        np.cumsum(q, axis=1, out=q)
        poses[:, :, axis] = q
    length = counts + 1 + extra
    return Rollouts(twists, poses, length.astype(np.int64), dt)
