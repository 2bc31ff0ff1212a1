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
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import RobotInterface, decode_odom
from scenario_gen.schema import from_mapping, load_yaml, param, parse_yaml

from .base import Obs, Policy
from .geometry import DepthProjector, local_plan

FloatArray = NDArray[np.float64]
REJECT = math.inf


CRITICS = (
    "RotateToGoal",
    "Oscillation",
    "BaseObstacle",
    "GoalAlign",
    "PathAlign",
    "PathDist",
    "GoalDist",
)


@dataclass(frozen=True)
class DWBParams:
    """DWB parameters with Nav2's names (see config/dwb_furrow.yaml for the values used and the
    reason for each change from Nav2's defaults)."""

    max_vel_x: float = param(1.0, "fastest forward speed sampled, m/s", 0.0, 10)
    min_vel_x: float = param(0.0, "slowest forward speed sampled, m/s", -10, 10)
    max_vel_theta: float = param(1.5, "fastest yaw rate sampled, rad/s", 0.0, 20)
    acc_lim_x: float = param(0.6, "linear acceleration limit, m/s²", 0.0, 50)
    decel_lim_x: float = param(-0.6, "linear deceleration limit (negative), m/s²", -50, 0)
    acc_lim_theta: float = param(1.5, "angular acceleration limit, rad/s²", 0.0, 100)
    decel_lim_theta: float = param(-1.5, "angular deceleration limit (negative), rad/s²", -100, 0)
    vx_samples: int = param(20, "forward-speed samples in the dynamic window", 1, 200)
    vtheta_samples: int = param(20, "yaw-rate samples in the dynamic window", 1, 200)
    sim_time: float = param(1.7, "rollout horizon, s", 0.1, 10)
    linear_granularity: float = param(0.05, "rollout step along the path, m", 0.001, 1)
    angular_granularity: float = param(0.025, "rollout step in heading, rad", 0.001, 1)
    costmap_resolution: float = param(0.05, "local costmap cell size, m", 0.01, 1)
    forward_point_distance: float = param(
        0.325, "Path/GoalAlign score a point this far ahead, m", 0.0, 5
    )
    xy_goal_tolerance: float = param(0.25, "goal reached within, m", 0.0, 5)
    oscillation_reset_dist: float = param(0.05, "distance that clears an oscillation flag, m", 0, 5)
    obstacle_min_height: float = param(
        0.15, "depth points lower than this above the ground are soil/ridges, m", 0.0, 2
    )
    prune_distance: float = param(2.0, "local plan length ahead of the robot, m", 0.1, 50)
    scales: dict[str, float] = param(
        {
            "RotateToGoal": 32.0,
            "Oscillation": 1.0,
            "BaseObstacle": 0.02,
            "GoalAlign": 24.0,
            "PathAlign": 32.0,
            "PathDist": 32.0,
            "GoalDist": 24.0,
        },
        "critic scales (total score = Σ scale × critic, lowest wins)",
        0.0,
        1e6,
        choices=CRITICS,
    )

    @classmethod
    def from_yaml(cls, path: str | Path | None = None) -> DWBParams:
        """Parameters from a YAML file (default: the shipped furrow-tuned config)."""
        if path is None:
            text = resources.files("policies.config").joinpath("dwb_furrow.yaml").read_text()
            data = parse_yaml(text, "dwb_furrow.yaml")
        else:
            data = load_yaml(path, "dwb params")
        base = cls().scales
        if isinstance(data.get("scales"), dict):
            data["scales"] = {**base, **data["scales"]}
        params: DWBParams = from_mapping(cls, data, "dwb.")
        return params


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
        robot: RobotInterface,
        params: str | Path | None = None,
        inscribed_radius: float = 0.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(observation_space, action_space, robot, **kwargs)
        self.p = DWBParams.from_yaml(params)
        self.config_name = Path(params).name if params is not None else "dwb_furrow.yaml"
        self.project = (
            DepthProjector(robot.camera, robot.base_height)
            if "depth" in observation_space.spaces
            else None
        )
        # 0 by default: in 0.75 m rows a 0.62 m robot is always within its inscribed radius of
        # the canopy, so only points on the robot's own path are lethal (see the YAML).
        self.inscribed = inscribed_radius
        self.dt = robot.control_dt
        self.reset()

    def describe(self) -> str:
        return f"dwb ({self.config_name})"

    def reset(self) -> None:
        self.last: tuple[float, float] | None = None
        self.moved = 0.0
        self.v, self.w = 0.0, 0.0

    def scores(self, obs: Obs) -> tuple[FloatArray, dict[str, FloatArray], FloatArray]:
        p = self.p
        if "odom" in obs:
            self.v, self.w = decode_odom(obs["odom"])
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
