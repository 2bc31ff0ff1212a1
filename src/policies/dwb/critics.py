"""Nav2's DWB critics (dwb_critics, Humble), scoring every trajectory at once.

Each critic returns (score, legal) arrays over the trajectories; an illegal trajectory is one
for which Nav2's critic throws IllegalTrajectoryException. ``scale`` is what
``getScale()`` returns: MapGrid critics (PathDist, GoalDist, PathAlign, GoalAlign) report
``resolution × 0.5 × scale``, so Humble's 32/24 weigh 0.8/0.6 per cell at 5 cm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from .costmap import INSCRIBED, LETHAL, NO_INFORMATION, Grid
from .params import (
    BaseObstacleParams,
    GoalAlignParams,
    GoalDistParams,
    ObstacleFootprintParams,
    OscillationParams,
    PathAlignParams,
    PathDistParams,
    PreferForwardParams,
    RotateToGoalParams,
)
from .trajectories import Rollouts

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass
class Cycle:
    """What DWBLocalPlanner hands every critic's prepare(): the robot's pose and velocity in the
    costmap frame, the global goal, the transformed plan and the costmap."""

    pose: tuple[float, float, float]
    velocity: tuple[float, float]
    goal: tuple[float, float, float]
    plan: FloatArray  # (n, 3) x, y, θ
    grid: Grid
    costmap: NDArray[np.uint8]  # master grid [mx, my]
    time: float = 0.0  # s since the controller started (Oscillation's reset time)


@dataclass
class Scores:
    score: FloatArray
    legal: BoolArray
    reason: str = ""  # the exception text, for the figure's legend
    reasons: NDArray[np.int8] = field(default_factory=lambda: np.zeros(0, np.int8))


class Critic:
    name = "Critic"

    def __init__(self, scale: float) -> None:
        self._scale = scale

    @property
    def scale(self) -> float:
        return self._scale

    def reset(self) -> None:
        pass

    def prepare(self, c: Cycle) -> bool:
        return True

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        raise NotImplementedError

    def debrief(self, cmd: tuple[float, float], c: Cycle) -> None:
        pass


def _free(n: int) -> BoolArray:
    return np.ones(n, bool)


# ----------------------------------------------------------------------------- plan helpers
def adjust_plan_resolution(plan: FloatArray, resolution: float) -> FloatArray:
    """nav_2d_utils::adjustPlanResolution (Humble): points inserted where two plan poses are
    more than two cells apart (with its integer step count, gaps of 2-3 cells stay)."""
    if len(plan) < 2:
        return plan
    d = np.hypot(np.diff(plan[:, 0]), np.diff(plan[:, 1]))
    min_sq = resolution * resolution * 4.0
    long = d * d > min_sq
    if not long.any():
        return plan  # a dense plan: the usual case
    steps = np.where(long, ((d - math.sqrt(min_sq)) / resolution).astype(np.int64) - 1, 0)
    # Nav2 interpolates x, y from the previous *input* pose and theta from the first pose's
    # theta (its `last` keeps the first pose's theta); theta is unused by the critics
    extra = np.maximum(steps - 1, 0)
    out = np.empty((len(plan) + int(extra.sum()), plan.shape[1]))
    pos = np.arange(len(plan)) + np.concatenate([[0], np.cumsum(extra)])
    out[pos] = plan
    seg = np.repeat(np.arange(len(d)), extra)
    j = np.arange(len(seg)) - np.repeat(np.cumsum(extra) - extra, extra) + 1
    delta = (plan[seg + 1] - plan[seg]) / steps[seg, None]
    ins = plan[seg] + j[:, None] * delta
    ins[:, 2] = plan[0, 2] + j * (plan[seg + 1, 2] - plan[0, 2]) / steps[seg]
    out[np.repeat(pos[:-1], extra) + j] = ins
    return out


def plan_cells_on_map(plan: FloatArray, c: Cycle) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The adjusted plan's cells from its first on-map pose to the pose before it leaves."""
    adj = adjust_plan_resolution(plan, c.grid.resolution)
    if len(adj) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    mx, my, ok = c.grid.world_to_map(adj[:, 0], adj[:, 1])
    ok = ok.copy()
    ok[ok] &= c.costmap[mx[ok], my[ok]] != NO_INFORMATION
    if not ok.any():
        return mx[:0], my[:0]
    first = int(np.argmax(ok))
    off = np.flatnonzero(~ok[first:])
    stop = first + (int(off[0]) if len(off) else len(ok) - first)
    return mx[first:stop], my[first:stop]


def manhattan_field(grid: Grid, mx: NDArray[np.int64], my: NDArray[np.int64]) -> FloatArray:
    """MapGridCritic::propogateManhattanDistances from the given source cells.

    Humble's MapGridQueue accepts every cell and orders the queue by Manhattan distance to each
    cell's source, so the propagation is a best-first search whose result is, for every cell,
    the smallest |dx| + |dy| to a source cell: a taxicab distance transform
    (tests/policies/test_dwb_nav2.py checks it against a literal port of costmap_queue).
    """
    n = grid.size_x * grid.size_y
    unreachable = float(n) + 1.0
    if len(mx) == 0:
        return np.full((grid.size_x, grid.size_y), unreachable)
    src = np.zeros((grid.size_x, grid.size_y), bool)
    src[mx, my] = True
    out: FloatArray = ndimage.distance_transform_cdt(~src, metric="taxicab").astype(np.float64)
    return out


def forward_points(poses: FloatArray, distance: float) -> FloatArray:
    """getForwardPose: the point ``distance`` ahead of each pose, same heading."""
    out = poses.copy()
    out[..., 0] = poses[..., 0] + distance * np.cos(poses[..., 2])
    out[..., 1] = poses[..., 1] + distance * np.sin(poses[..., 2])
    return out


# ----------------------------------------------------------------------------- map-grid critics
class MapGridCritic(Critic):
    stop_on_failure = True
    shifted = False  # scores a point ahead of each pose instead of the pose

    def __init__(self, scale: float, aggregation_type: str) -> None:
        super().__init__(scale)
        self.aggregation = aggregation_type
        self.values: FloatArray | None = None
        self.resolution = 0.05

    @property
    def scale(self) -> float:
        return self.resolution * 0.5 * self._scale

    def _reset(self, c: Cycle) -> None:
        self.resolution = c.grid.resolution
        n = c.grid.size_x * c.grid.size_y
        self.obstacle_score = float(n)
        self.unreachable_score = float(n) + 1.0
        self.values = np.full((c.grid.size_x, c.grid.size_y), self.unreachable_score)

    def points(self, poses: FloatArray) -> FloatArray:
        return poses

    def score(self, ro: Rollouts, c: Cycle) -> Scores:
        assert self.values is not None
        n = len(ro.poses)
        rows = np.arange(n)
        if self.aggregation == "last" and not self.stop_on_failure:
            # only the last pose is scored (PathAlign, GoalAlign)
            pts = self.points(ro.last())
            mx, my, on = c.grid.world_to_map(pts[:, 0], pts[:, 1])
            vals = self.values[np.where(on, mx, 0), np.where(on, my, 0)]
            return Scores(np.where(on, vals, 0.0), on, "Trajectory Goes Off Grid.")
        if self.aggregation == "last" and not self.shifted and ro.cells is not None:
            # Humble's MapGridQueue never marks obstacles and reaches every cell from any
            # source, so a pose is unreachable only when prepare found no plan on the map:
            # the per-pose check reduces to "every pose on the grid" (and a plan to score).
            mx, my, on = ro.cells
            legal = ro.on_grid() & bool((self.values != self.unreachable_score).any())
            last = ro.length - 1
            on_last = on[rows, last]
            s = self.values[
                np.where(on_last, mx[rows, last], 0), np.where(on_last, my[rows, last], 0)
            ]
            why = (
                "Trajectory Goes Off Grid." if legal.any() else "Trajectory Hits Unreachable Area."
            )
            return Scores(np.where(legal, s, 0.0), legal, why)
        use = ro.mask()
        if not self.shifted and ro.cells is not None:
            mx, my, on = ro.cells
        else:
            pts = self.points(ro.poses)
            mx, my, on = c.grid.world_to_map(pts[..., 0], pts[..., 1])
        legal = np.asarray(~(use & ~on).any(axis=1), bool)
        vals = self.values[np.where(on, mx, 0), np.where(on, my, 0)]
        reason = "Trajectory Goes Off Grid."
        if self.stop_on_failure:
            bad = use & on & ((vals == self.obstacle_score) | (vals == self.unreachable_score))
            legal &= ~bad.any(axis=1)
            if bad.any():
                reason = "Trajectory Hits Unreachable Area."
        if self.aggregation == "last":
            s = vals[rows, ro.length - 1]
        elif self.aggregation == "sum":
            s = np.where(use, vals, 0.0).sum(axis=1)
        else:  # product: Nav2 stops multiplying once the running product is 0
            s = np.multiply.accumulate(np.where(use, vals, 1.0), axis=1)[:, -1]
        return Scores(np.where(legal, s, 0.0), np.asarray(legal, bool), reason)


class PathDistCritic(MapGridCritic):
    name = "PathDist"

    def __init__(self, p: PathDistParams) -> None:
        super().__init__(p.scale, p.aggregation_type)

    def prepare(self, c: Cycle) -> bool:
        self._reset(c)
        mx, my = plan_cells_on_map(c.plan, c)
        if len(mx) == 0:
            return False
        self.values = manhattan_field(c.grid, mx, my)
        return True


class GoalDistCritic(MapGridCritic):
    name = "GoalDist"

    def __init__(self, p: GoalDistParams) -> None:
        super().__init__(p.scale, p.aggregation_type)

    def prepare(self, c: Cycle) -> bool:
        return self._prepare_plan(c.plan, c)

    def _prepare_plan(self, plan: FloatArray, c: Cycle) -> bool:
        self._reset(c)
        mx, my = plan_cells_on_map(plan, c)
        if len(mx) == 0:
            return False
        self.values = manhattan_field(c.grid, mx[-1:], my[-1:])  # getLastPoseOnCostmap
        return True


class PathAlignCritic(PathDistCritic):
    name = "PathAlign"
    stop_on_failure = False
    shifted = True

    def __init__(self, p: PathAlignParams) -> None:
        super().__init__(PathDistParams(p.scale, p.aggregation_type))
        self.forward = p.forward_point_distance
        self.zero_scale = False

    @property
    def scale(self) -> float:
        return 0.0 if self.zero_scale else self.resolution * 0.5 * self._scale

    def prepare(self, c: Cycle) -> bool:
        dx, dy = c.pose[0] - c.goal[0], c.pose[1] - c.goal[1]
        # near the goal, keeping the nose on the path destabilises the robot
        self.zero_scale = dx * dx + dy * dy <= self.forward * self.forward
        if self.zero_scale:
            return True
        return super().prepare(c)

    def points(self, poses: FloatArray) -> FloatArray:
        return forward_points(poses, self.forward)


class GoalAlignCritic(GoalDistCritic):
    name = "GoalAlign"
    stop_on_failure = False
    shifted = True

    def __init__(self, p: GoalAlignParams) -> None:
        super().__init__(GoalDistParams(p.scale, p.aggregation_type))
        self.forward = p.forward_point_distance

    def prepare(self, c: Cycle) -> bool:
        # the nose is drawn to where it will be when the centre reaches the local goal
        angle = math.atan2(c.goal[1] - c.pose[1], c.goal[0] - c.pose[0])
        target = c.plan.copy()
        if len(target):
            target[-1, 0] += self.forward * math.cos(angle)
            target[-1, 1] += self.forward * math.sin(angle)
        return self._prepare_plan(target, c)

    def points(self, poses: FloatArray) -> FloatArray:
        return forward_points(poses, self.forward)


# ----------------------------------------------------------------------------- obstacle critics
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
