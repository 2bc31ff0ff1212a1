"""DWB (Nav2-like dynamic window controller) with the Nav2 critics.

Velocity samples span the dynamic window (current velocity ± acceleration × sim_time, as Nav2's
XYThetaIterator does), each is rolled out over ``sim_time`` with the acceleration limits
(StandardTrajectoryGenerator), scored by the critics, and the lowest total Σ scale × critic
wins. Map-grid critics (PathDist, GoalDist, PathAlign, GoalAlign) count distance in costmap
cells, as Nav2's map-grid does. The local plan is the route observation (estimated pose) and
the local costmap comes from the depth image: policies see observations only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from gymnasium import spaces
from numpy.typing import NDArray

from .base import Obs, Policy
from .geometry import DepthProjector, local_plan

FloatArray = NDArray[np.float64]
REJECT = math.inf


@dataclass
class DWBParams:
    max_vel_x: float = 1.0
    min_vel_x: float = 0.0
    max_vel_theta: float = 1.5
    acc_lim_x: float = 0.6
    decel_lim_x: float = -0.6
    acc_lim_theta: float = 1.5
    decel_lim_theta: float = -1.5
    vx_samples: int = 20
    vtheta_samples: int = 20
    sim_time: float = 1.7
    linear_granularity: float = 0.05
    angular_granularity: float = 0.025
    costmap_resolution: float = 0.05
    forward_point_distance: float = 0.325
    xy_goal_tolerance: float = 0.25
    oscillation_reset_dist: float = 0.05
    obstacle_min_height: float = 0.15
    prune_distance: float = 1.0
    scales: dict[str, float] = field(
        default_factory=lambda: {
            "RotateToGoal": 32.0,
            "Oscillation": 1.0,
            "BaseObstacle": 0.02,
            "GoalAlign": 24.0,
            "PathAlign": 32.0,
            "PathDist": 32.0,
            "GoalDist": 24.0,
        }
    )

    @classmethod
    def from_yaml(cls, path: str | Path | None = None) -> DWBParams:
        text = (
            Path(path).read_text()
            if path is not None
            else resources.files("policies.config").joinpath("dwb_furrow.yaml").read_text()
        )
        data = yaml.safe_load(text) or {}
        unknown = set(data) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"dwb params: unknown keys {sorted(unknown)}")
        return cls(**data)


# ----------------------------------------------------------------------------- trajectories
def velocity_samples(v0: float, w0: float, p: DWBParams) -> FloatArray:
    """(n, 2) twists in the dynamic window reachable within sim_time."""

    def axis(cur: float, lo: float, hi: float, acc: float, dec: float, n: int) -> FloatArray:
        a = max(lo, cur + dec * p.sim_time)
        b = min(hi, cur + acc * p.sim_time)
        if b < a:
            a = b = min(max(cur, lo), hi)
        return np.linspace(a, b, max(n, 1)) if n > 1 else np.array([b])

    vs = axis(v0, p.min_vel_x, p.max_vel_x, p.acc_lim_x, p.decel_lim_x, p.vx_samples)
    ws = axis(
        w0, -p.max_vel_theta, p.max_vel_theta, p.acc_lim_theta, p.decel_lim_theta, p.vtheta_samples
    )
    V, W = np.meshgrid(vs, ws, indexing="ij")
    return np.column_stack([V.ravel(), W.ravel()])


def rollout(
    twists: FloatArray, v0: float, w0: float, p: DWBParams, steps: int | None = None
) -> FloatArray:
    """Poses (n, steps + 1, 3) from the origin, velocities ramping under the acceleration limits."""
    if steps is None:
        dist = max(
            float(np.abs(twists[:, 0]).max()) * p.sim_time / p.linear_granularity,
            float(np.abs(twists[:, 1]).max()) * p.sim_time / p.angular_granularity,
        )
        # Nav2 discretizes by distance (linear 0.05 m, angular 0.025 rad); the critics read the
        # last pose and the cells under the poses, so 40 points bound the cost at no loss there.
        steps = max(1, min(math.ceil(dist), 40))
    dt = p.sim_time / steps
    n = len(twists)
    poses = np.zeros((n, steps + 1, 3))
    v = np.full(n, v0)
    w = np.full(n, w0)
    x = np.zeros(n)
    y = np.zeros(n)
    th = np.zeros(n)
    for k in range(steps):
        v = np.clip(twists[:, 0], v + p.decel_lim_x * dt, v + p.acc_lim_x * dt)
        w = np.clip(twists[:, 1], w + p.decel_lim_theta * dt, w + p.acc_lim_theta * dt)
        x = x + v * np.cos(th) * dt
        y = y + v * np.sin(th) * dt
        th = th + w * dt
        poses[:, k + 1, 0], poses[:, k + 1, 1], poses[:, k + 1, 2] = x, y, th
    return poses


# ----------------------------------------------------------------------------- critics
def _nearest_cells(points: FloatArray, targets: FloatArray, res: float) -> FloatArray:
    d = np.linalg.norm(points[:, None, :] - targets[None, :, :], axis=2)
    return d.min(axis=1) / res


def path_dist(traj: FloatArray, plan: FloatArray, res: float) -> FloatArray:
    """Cells from each trajectory's last pose to the nearest plan point (Nav2 PathDist)."""
    return _nearest_cells(traj[:, -1, :2], plan, res)


def goal_dist(traj: FloatArray, goal: FloatArray, res: float) -> FloatArray:
    """Cells from each trajectory's last pose to the local goal (Nav2 GoalDist)."""
    return _nearest_cells(traj[:, -1, :2], goal[None, :], res)


def forward_point(traj: FloatArray, distance: float) -> FloatArray:
    end = traj[:, -1]
    return np.column_stack(
        [end[:, 0] + distance * np.cos(end[:, 2]), end[:, 1] + distance * np.sin(end[:, 2])]
    )


def path_align(traj: FloatArray, plan: FloatArray, res: float, distance: float) -> FloatArray:
    """PathDist scored at a point ``distance`` ahead of the last pose (Nav2 PathAlign)."""
    return _nearest_cells(forward_point(traj, distance), plan, res)


def goal_align(traj: FloatArray, goal: FloatArray, res: float, distance: float) -> FloatArray:
    """GoalDist scored at a point ``distance`` ahead of the last pose (Nav2 GoalAlign)."""
    return _nearest_cells(forward_point(traj, distance), goal[None, :], res)


def rotate_to_goal(
    traj: FloatArray, twists: FloatArray, goal: FloatArray, goal_yaw: float, tolerance: float
) -> FloatArray:
    """Inside the goal tolerance: reject translation, score the final heading error."""
    if float(np.hypot(*goal)) > tolerance:
        return np.zeros(len(traj))
    err = np.abs((traj[:, -1, 2] - goal_yaw + math.pi) % (2 * math.pi) - math.pi)
    return np.where(np.abs(twists[:, 0]) > 1e-6, REJECT, err)


def oscillation(
    twists: FloatArray, last: tuple[float, float] | None, moved: float, reset_dist: float
) -> FloatArray:
    """Reject a sign flip of v or ω before the robot has moved ``reset_dist`` since the last."""
    if last is None or moved >= reset_dist:
        return np.zeros(len(twists))
    flip = np.zeros(len(twists), bool)
    for i, prev in enumerate(last):
        if abs(prev) > 1e-6:
            flip |= np.sign(twists[:, i]) == -np.sign(prev)
    return np.where(flip, REJECT, 0.0)


def base_obstacle(
    traj: FloatArray, grid: NDArray[np.float64] | None, origin: FloatArray, res: float
) -> FloatArray:
    """Sum of costmap costs under the poses; a lethal (254) cell rejects the trajectory."""
    if grid is None:
        return np.zeros(len(traj))
    ij = np.floor((traj[:, :, :2] - origin) / res).astype(int)
    inside = (
        (ij[..., 0] >= 0)
        & (ij[..., 0] < grid.shape[0])
        & (ij[..., 1] >= 0)
        & (ij[..., 1] < grid.shape[1])
    )
    cost = np.where(
        inside,
        grid[np.clip(ij[..., 0], 0, grid.shape[0] - 1), np.clip(ij[..., 1], 0, grid.shape[1] - 1)],
        0.0,
    )
    return np.where((cost >= 254).any(axis=1), REJECT, cost.sum(axis=1))


# ----------------------------------------------------------------------------- costmap
def depth_costmap(
    points: FloatArray,
    res: float,
    min_height: float,
    inscribed: float,
    size: float = 6.0,
) -> tuple[FloatArray, FloatArray]:
    """A robot-frame local costmap from depth points (``DepthProjector``): obstacles are points
    standing more than ``min_height`` above the footprint plane; lethal within ``inscribed``."""
    pts = points[points[:, 2] > min_height]
    n = int(size / res)
    origin = np.array([-1.0, -size / 2])
    grid = np.zeros((n, n))
    if len(pts):
        ij = np.floor((pts[:, :2] - origin) / res).astype(int)
        keep = (ij[:, 0] >= 0) & (ij[:, 0] < n) & (ij[:, 1] >= 0) & (ij[:, 1] < n)
        occ = np.zeros((n, n), bool)
        occ[ij[keep, 0], ij[keep, 1]] = True
        if occ.any():
            from scipy import ndimage

            dist = ndimage.distance_transform_edt(~occ) * res
            grid = np.where(
                dist <= inscribed,
                254.0,
                np.where(dist <= inscribed + 0.25, 252.0 * np.exp(-3.0 * (dist - inscribed)), 0.0),
            )
    return grid, origin


class DWB(Policy):
    name = "dwb"
    requires = ("route",)

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        params: str | Path | None = None,
        camera: dict[str, float] | None = None,
        inscribed_radius: float = 0.0,
        control_dt: float = 0.05,
        **kwargs: Any,
    ) -> None:
        super().__init__(observation_space, action_space, **kwargs)
        self.p = DWBParams.from_yaml(params)
        depth = observation_space.spaces.get("depth")
        self.project = (
            DepthProjector(camera, depth.shape)
            if camera is not None and depth is not None and depth.shape is not None
            else None
        )
        # 0 by default: in 0.75 m rows a 0.62 m robot is always within its inscribed radius of
        # the canopy, so only points on the robot's own path are lethal (see the YAML).
        self.inscribed = inscribed_radius
        self.dt = control_dt
        self.reset()

    def reset(self) -> None:
        self.last: tuple[float, float] | None = None
        self.moved = 0.0
        self.v, self.w = 0.0, 0.0

    def scores(self, obs: Obs) -> tuple[FloatArray, dict[str, FloatArray], FloatArray]:
        p = self.p
        if "odom" in obs:
            self.v, self.w = float(obs["odom"][0]), float(obs["odom"][1])
        twists = velocity_samples(self.v, self.w, p)
        traj = rollout(twists, self.v, self.w, p)
        plan, _ = local_plan(obs["route"])
        # Nav2 prunes the global plan to prune_distance ahead; its end is the local goal
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(plan, axis=0), axis=1))])
        plan = plan[: max(2, int(np.searchsorted(arc, p.prune_distance, side="right")))]
        goal = plan[-1]
        d = plan[-1] - plan[-2] if len(plan) > 1 else np.array([1.0, 0.0])
        goal_yaw = math.atan2(d[1], d[0])
        res = p.costmap_resolution
        grid, origin = None, np.zeros(2)
        if self.project is not None and "depth" in obs:
            pts = self.project.points(obs["depth"])
            grid, origin = depth_costmap(pts, res, p.obstacle_min_height, self.inscribed)
        parts = {
            "RotateToGoal": rotate_to_goal(traj, twists, goal, goal_yaw, p.xy_goal_tolerance),
            "Oscillation": oscillation(twists, self.last, self.moved, p.oscillation_reset_dist),
            "BaseObstacle": base_obstacle(traj, grid, origin, res),
            "GoalAlign": goal_align(traj, goal, res, p.forward_point_distance),
            "PathAlign": path_align(traj, plan, res, p.forward_point_distance),
            "PathDist": path_dist(traj, plan, res),
            "GoalDist": goal_dist(traj, goal, res),
        }
        total = sum(p.scales[k] * v for k, v in parts.items())
        return twists, parts, np.asarray(total, dtype=np.float64)

    def act(self, obs: Obs) -> NDArray[np.float32]:
        twists, _, total = self.scores(obs)
        if not np.isfinite(total).any():  # no valid trajectory: stop, as Nav2 would
            best = np.array([0.0, 0.0])
        else:
            best = twists[int(np.argmin(total))]
        v, w = float(best[0]), float(best[1])
        if self.last is not None and (np.sign(w) == -np.sign(self.last[1]) != 0):
            self.moved = 0.0
        self.moved += abs(self.v) * self.dt
        self.last = (v, w)
        return self._twist(v, w)
