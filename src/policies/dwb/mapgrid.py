"""Nav2's MapGrid critics (PathDist, GoalDist, PathAlign, GoalAlign): plan cells on the costmap,
a Manhattan distance field from them, and ``getScale()`` = resolution × 0.5 × scale."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from .costmap import NO_INFORMATION, Grid
from .critic_base import Critic, Cycle, FloatArray, Scores
from .params import GoalAlignParams, GoalDistParams, PathAlignParams, PathDistParams
from .trajectories import Rollouts


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
