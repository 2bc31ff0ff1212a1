"""Nav2's DWB critics (dwb_critics, Humble), scoring every trajectory at once: the obstacle,
oscillation, rotate-to-goal and prefer-forward critics here, the MapGrid ones in ``mapgrid``.

Each critic returns (score, legal) arrays over the trajectories; an illegal trajectory is one
for which Nav2's critic throws IllegalTrajectoryException. ``scale`` is what
``getScale()`` returns: MapGrid critics (PathDist, GoalDist, PathAlign, GoalAlign) report
``resolution × 0.5 × scale``, so Humble's 32/24 weigh 0.8/0.6 per cell at 5 cm.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .costmap import INSCRIBED, LETHAL, NO_INFORMATION
from .critic_base import BoolArray, Critic, Cycle, FloatArray, Scores, _free
from .mapgrid import (
    GoalAlignCritic,
    GoalDistCritic,
    MapGridCritic,
    PathAlignCritic,
    PathDistCritic,
    adjust_plan_resolution,
    forward_points,
    manhattan_field,
    plan_cells_on_map,
)
from .params import (
    BaseObstacleParams,
    ObstacleFootprintParams,
    OscillationParams,
    PreferForwardParams,
    RotateToGoalParams,
)
from .trajectories import Rollouts

__all__ = [
    "BaseObstacleCritic",
    "BoolArray",
    "Critic",
    "Cycle",
    "FloatArray",
    "GoalAlignCritic",
    "GoalDistCritic",
    "MapGridCritic",
    "ObstacleFootprintCritic",
    "OscillationCritic",
    "PathAlignCritic",
    "PathDistCritic",
    "PreferForwardCritic",
    "RotateToGoalCritic",
    "Scores",
    "adjust_plan_resolution",
    "forward_points",
    "line_cells",
    "manhattan_field",
    "plan_cells_on_map",
]


class BaseObstacleCritic(Critic):
    """The cost of the cell under each pose: off the map, lethal, inscribed or unknown is
    illegal (the robot treated as a circle of the inscribed radius); the score is the last
    pose's cost (or the sum)."""

    name = "BaseObstacle"

    def __init__(self, p: BaseObstacleParams) -> None:
        super().__init__(p.scale)
        self.sum_scores = p.sum_scores

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        n = len(ro.poses)
        use = ro.mask()
        mx, my, on = (
            ro.cells
            if ro.cells is not None
            else c.grid.world_to_map(ro.poses[..., 0], ro.poses[..., 1])
        )
        cost = np.where(on, c.costmap[np.where(on, mx, 0), np.where(on, my, 0)], 0).astype(
            np.float64
        )
        off = (use & ~on).any(axis=1)
        hit = (use & on & (cost >= INSCRIBED)).any(axis=1)
        legal = ~(off | hit)
        s = (
            np.where(use, cost, 0.0).sum(axis=1)
            if self.sum_scores
            else cost[np.arange(n), ro.length - 1]
        )
        reason = "Trajectory Hits Obstacle." if hit.any() else "Trajectory Goes Off Grid."
        return Scores(np.where(legal, s, 0.0), np.asarray(legal, bool), reason)


def line_cells(
    x0: NDArray[np.int64], y0: NDArray[np.int64], x1: NDArray[np.int64], y1: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64], BoolArray]:
    """nav2_util::LineIterator for many lines: (..., K) cells and which of the K are on the
    line (Bresenham from (x0, y0) to (x1, y1), both ends included)."""
    dx, dy = np.abs(x1 - x0), np.abs(y1 - y0)
    sx = np.where(x1 >= x0, 1, -1)
    sy = np.where(y1 >= y0, 1, -1)
    xmajor = dx >= dy
    den = np.where(xmajor, dx, dy)
    numadd = np.where(xmajor, dy, dx)
    k = np.arange(int(den.max()) + 1 if den.size else 1)
    kk = k.reshape((1,) * den.ndim + (-1,))
    minor = (den[..., None] // 2 + kk * numadd[..., None]) // np.maximum(den, 1)[..., None]
    x = x0[..., None] + sx[..., None] * np.where(xmajor[..., None], kk, minor)
    y = y0[..., None] + sy[..., None] * np.where(xmajor[..., None], minor, kk)
    return x, y, kk <= den[..., None]


class ObstacleFootprintCritic(BaseObstacleCritic):
    """The footprint's outline, rasterised edge by edge, at every pose: the pose's cost is the
    highest cost on the outline; a lethal or unknown cell, or a corner off the map, is illegal.
    Inscribed cells are legal here: the outline itself tells whether the robot touches."""

    name = "ObstacleFootprint"

    def __init__(self, p: ObstacleFootprintParams, footprint: FloatArray) -> None:
        Critic.__init__(self, p.scale)
        self.sum_scores = p.sum_scores
        self.footprint = np.asarray(footprint, np.float64)

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        n = len(ro.poses)
        use = ro.mask()
        g = c.grid
        cells = (
            ro.cells if ro.cells is not None else g.world_to_map(ro.poses[..., 0], ro.poses[..., 1])
        )
        off = (use & ~cells[2]).any(axis=1)
        cos, sin = np.cos(ro.poses[..., 2]), np.sin(ro.poses[..., 2])
        fx, fy = self.footprint[:, 0], self.footprint[:, 1]
        wx = ro.poses[..., 0, None] + fx * cos[..., None] - fy * sin[..., None]
        wy = ro.poses[..., 1, None] + fx * sin[..., None] + fy * cos[..., None]
        cx, cy, con = g.world_to_map(wx, wy)
        off |= (use[..., None] & ~con).any(axis=(1, 2))
        ok = use & con.all(axis=2)
        # A pose's outline depends only on its corners' cells, and successive poses share
        # them: each distinct set of corner cells is rasterised once.
        nv = len(self.footprint)
        bits = max(int(max(g.size_x, g.size_y)).bit_length(), 1)
        key = np.zeros(cx.shape[:2], np.int64) if nv * 2 * bits <= 62 else None
        if key is not None:
            for i in range(nv):
                key = (key << bits) | np.where(ok, cx[..., i], 0)
                key = (key << bits) | np.where(ok, cy[..., i], 0)
            _uniq, first, inv = np.unique(key[ok], return_index=True, return_inverse=True)
            corner_x = cx[ok][first]
            corner_y = cy[ok][first]
        else:
            inv = np.arange(int(ok.sum()))
            corner_x, corner_y = cx[ok], cy[ok]
        a = np.arange(nv)
        b = (a + 1) % nv  # edges i -> i+1, then the closing edge last -> first
        lx, ly, live = line_cells(corner_x[:, a], corner_y[:, a], corner_x[:, b], corner_y[:, b])
        cost = np.where(
            live, c.costmap[np.clip(lx, 0, g.size_x - 1), np.clip(ly, 0, g.size_y - 1)], 0
        )
        bad = ((cost == LETHAL) | (cost == NO_INFORMATION)).any(axis=(1, 2))
        pose_cost = np.zeros(cx.shape[:2])
        pose_bad = np.zeros(cx.shape[:2], bool)
        pose_cost[ok] = cost.max(axis=(1, 2))[inv.ravel()]
        pose_bad[ok] = bad[inv.ravel()]
        hit = pose_bad.any(axis=1)
        legal = ~(off | hit)
        if self.sum_scores:
            s = np.where(use, pose_cost, 0.0).sum(axis=1)
        else:
            s = pose_cost[np.arange(n), ro.length - 1]
        reason = "Trajectory Hits Obstacle." if hit.any() else "Footprint Goes Off Grid."
        return Scores(np.where(legal, s, 0.0), np.asarray(legal, bool), reason)


# ----------------------------------------------------------------------------- stateful critics
class _Trend:
    """OscillationCritic::CommandTrend."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.sign = 0
        self.positive_only = False
        self.negative_only = False

    def update(self, v: float) -> bool:
        flag = False
        if v < 0.0:
            if self.sign > 0:
                self.negative_only, flag = True, True
            self.sign = -1
        elif v > 0.0:
            if self.sign < 0:
                self.positive_only, flag = True, True
            self.sign = 1
        return flag

    def oscillating(self, v: FloatArray) -> BoolArray:
        out: BoolArray = (self.positive_only & (v < 0.0)) | (self.negative_only & (v > 0.0))
        return out

    def flipped(self) -> bool:
        return self.positive_only or self.negative_only


class OscillationCritic(Critic):
    """Once v (or ω, while nearly stopped) changed sign, the opposite sign is illegal until
    the robot has moved ``oscillation_reset_dist`` or turned ``oscillation_reset_angle`` since
    the flip (or ``oscillation_reset_time`` passed)."""

    name = "Oscillation"

    def __init__(self, p: OscillationParams) -> None:
        super().__init__(p.scale)
        self.p = p
        self.x = _Trend()
        self.th = _Trend()
        self.pose = (0.0, 0.0, 0.0)
        self.flip_pose = (0.0, 0.0, 0.0)
        self.flip_time = 0.0

    def reset(self) -> None:
        self.x.reset()
        self.th.reset()

    def prepare(self, c: Cycle) -> bool:
        self.pose = c.pose
        return True

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        bad = self.x.oscillating(ro.twists[:, 0]) | self.th.oscillating(ro.twists[:, 1])
        return Scores(np.zeros(len(ro.twists)), ~bad, "Trajectory is oscillating.")

    def debrief(self, cmd: tuple[float, float], c: Cycle) -> None:
        flag = self.x.update(cmd[0])
        if self.p.x_only_threshold < 0.0 or abs(cmd[0]) <= self.p.x_only_threshold:
            flag |= self.th.update(cmd[1])
        if flag:
            self.flip_pose, self.flip_time = self.pose, c.time
        if (self.x.flipped() or self.th.flipped()) and self._reset_available(c.time):
            self.reset()

    def _reset_available(self, now: float) -> bool:
        p = self.p
        dx, dy = self.pose[0] - self.flip_pose[0], self.pose[1] - self.flip_pose[1]
        if p.oscillation_reset_dist >= 0 and dx * dx + dy * dy > p.oscillation_reset_dist**2:
            return True
        if (
            p.oscillation_reset_angle >= 0
            and abs(self.pose[2] - self.flip_pose[2]) > p.oscillation_reset_angle
        ):
            return True
        return p.oscillation_reset_time >= 0 and now - self.flip_time > p.oscillation_reset_time


def shortest_angular_distance(a: FloatArray, b: float) -> FloatArray:
    """angles::shortest_angular_distance(a, b) = normalize_angle(b - a)."""
    d = np.fmod(np.fmod(b - a, 2 * math.pi) + 2 * math.pi, 2 * math.pi)
    out: FloatArray = np.where(d > math.pi, d - 2 * math.pi, d)
    return out


class RotateToGoalCritic(Critic):
    """Inside xy_goal_tolerance of the global goal: first slow down (any twist not slower than
    the current speed is illegal), then, once below trans_stopped_velocity, rotate in place
    (any translation is illegal); scored by the heading error at the trajectory's end."""

    name = "RotateToGoal"

    def __init__(self, p: RotateToGoalParams, xy_goal_tolerance: float, stopped: float) -> None:
        super().__init__(p.scale)
        self.p = p
        self.tol_sq = xy_goal_tolerance**2
        self.stopped_sq = stopped**2
        self.reset()

    def reset(self) -> None:
        self.in_window = False
        self.rotating = False
        self.speed_sq = 0.0
        self.goal_yaw = 0.0

    def prepare(self, c: Cycle) -> bool:
        d = (c.pose[0] - c.goal[0]) ** 2 + (c.pose[1] - c.goal[1]) ** 2
        self.in_window = self.in_window or d <= self.tol_sq
        self.speed_sq = c.velocity[0] ** 2
        self.rotating = self.rotating or (self.in_window and self.speed_sq <= self.stopped_sq)
        self.goal_yaw = c.goal[2]
        return True

    def _rotation(self, ro: Rollouts) -> FloatArray:
        n = len(ro.poses)
        if self.p.lookahead_time >= 0.0:
            # projectPose: linear interpolation between the poses around the lookahead time
            t = np.minimum(self.p.lookahead_time / ro.dt, ro.length - 1.0)
            i = np.floor(t).astype(np.int64)
            j = np.minimum(i + 1, ro.length - 1)
            r = t - i
            yaw = ro.poses[np.arange(n), i, 2] * (1 - r) + ro.poses[np.arange(n), j, 2] * r
        else:
            yaw = ro.poses[np.arange(n), ro.length - 1, 2]
        return np.abs(shortest_angular_distance(yaw, self.goal_yaw))

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        n = len(ro.twists)
        if not self.in_window:
            return Scores(np.zeros(n), _free(n))
        v = ro.twists[:, 0]
        if not self.rotating:
            sq = v * v
            legal = ~(sq >= self.speed_sq)
            s = sq * self.p.slowing_factor + self._rotation(ro)
            return Scores(np.where(legal, s, 0.0), legal, "Not slowing down near goal.")
        legal = ~(np.abs(v) > 0)
        return Scores(
            np.where(legal, self._rotation(ro), 0.0), legal, "Nonrotation command near goal."
        )


class PreferForwardCritic(Critic):
    name = "PreferForward"

    def __init__(self, p: PreferForwardParams) -> None:
        super().__init__(p.scale)
        self.p = p

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        v, w = ro.twists[:, 0], ro.twists[:, 1]
        p = self.p
        s = np.abs(w) * p.theta_scale
        s = np.where((v < p.strafe_x) & (np.abs(w) < p.strafe_theta), p.penalty, s)
        s = np.where(v < 0.0, p.penalty, s)
        return Scores(s, _free(len(v)))
