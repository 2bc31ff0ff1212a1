"""The DWB controller as a policy: Nav2's controller server loop on the env's observations.

Frames: the local costmap and the trajectories live in an odometry frame the policy integrates
itself (wheel speed, and the gyro's yaw rate as a robot_localization odom EKF would fuse it);
the route observation (the global plan, in the robot frame of the *estimated* pose) is
transformed into it with the robot's odometry pose, as tf's map → odom → base_link would.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import (
    OBS_DEPTH,
    OBS_IMU,
    OBS_ODOM,
    OBS_ROUTE,
    RobotInterface,
    decode_imu,
    decode_odom,
    decode_route,
)
from scenario_gen.arrays import FloatArray
from scenario_gen.schema import to_mapping

from ..base import Obs, Policy
from ..geometry import DepthProjector, local_plan
from .costmap import Grid, VoxelLayer, footprint_radii, inflate, pad_footprint, rectangle_footprint
from .critics import Cycle
from .params import SHIPPED, DWBParams
from .planner import Evaluation, LocalPlanner, transform_global_plan
from .shim import RotationShim
from .trajectories import Kinematics

MIN_X_VELOCITY_THRESHOLD = 0.001  # controller_server: odometry below this reads 0
MIN_THETA_VELOCITY_THRESHOLD = 0.001
TRAIL_JOIN = 0.5  # m: a new plan further than this from the kept one starts afresh


def pick(v: float | None, robot_value: float) -> float:
    """A configured limit, or the robot's own where the config says null."""
    return robot_value if v is None else v


def kinematics(p: DWBParams, robot: RobotInterface) -> Kinematics:
    """FollowPath's kinematic parameters, the robot's limits where the config says null."""
    fp = p.FollowPath
    return Kinematics(
        min_vel_x=fp.min_vel_x,
        max_vel_x=pick(fp.max_vel_x, robot.v_max),
        max_vel_theta=pick(fp.max_vel_theta, robot.w_max),
        min_speed_xy=fp.min_speed_xy,
        max_speed_xy=pick(fp.max_speed_xy, robot.v_max),
        min_speed_theta=fp.min_speed_theta,
        acc_lim_x=pick(fp.acc_lim_x, robot.a_max),
        decel_lim_x=pick(fp.decel_lim_x, -robot.a_max),
        acc_lim_theta=pick(fp.acc_lim_theta, robot.alpha_max),
        decel_lim_theta=pick(fp.decel_lim_theta, -robot.alpha_max),
    )


def shim_rates(p: DWBParams, robot: RobotInterface) -> tuple[float, float]:
    """The rotation shim's in-place yaw rate and angular acceleration, the robot's where null."""
    rs = p.rotation_shim
    return (
        pick(rs.rotate_to_heading_angular_vel, robot.w_max),
        pick(rs.max_angular_accel, robot.alpha_max),
    )


def resolved_config(p: DWBParams, robot: RobotInterface) -> dict[str, Any]:
    """The configuration as a mapping under Nav2's names with the robot's own values where it
    says null (its limits and footprint rectangle): what a Nav2 parameter file needs."""
    out = to_mapping(p)
    kin = kinematics(p, robot)
    out["FollowPath"].update(dataclasses.asdict(kin))
    shim = out["rotation_shim"]
    shim["rotate_to_heading_angular_vel"], shim["max_angular_accel"] = shim_rates(p, robot)
    if out["local_costmap"]["footprint"] is None:
        out["local_costmap"]["footprint"] = rectangle_footprint(*robot.footprint).tolist()
    return out


def config_label(params: str | Path | dict[str, Any] | None) -> str:
    """How a benchmark row names the config: a shipped one's name (nav2, furrow, tuned), a
    user's file by its file name (``tuned.yaml`` is not the shipped ``tuned``), or ``trial``
    for changes given as a mapping."""
    if params is None:
        return "furrow"
    if isinstance(params, dict):
        return "trial"
    text = str(params)
    return text if text in SHIPPED else Path(text.rstrip("/")).name or text


class DWB(Policy):
    """Nav2's DWB local planner with a rolling voxel costmap from the depth camera.

    ``params``: ``"nav2"`` (Humble's defaults with the robot's limits), ``"furrow"`` (the
    furrow-tuned changes, the default) or a YAML file of changes to ``dwb_nav2.yaml``.
    """

    name = "dwb"
    requires = (OBS_ROUTE, OBS_ODOM)

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        params: str | Path | dict[str, Any] | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(observation_space, action_space, robot, **kwargs)
        self.config = config_label(params)
        self.p = DWBParams.load(params)
        cm = self.p.local_costmap
        base = (
            np.asarray(cm.footprint, np.float64)
            if cm.footprint is not None
            else rectangle_footprint(*robot.footprint)
        )
        self.footprint = pad_footprint(base, cm.footprint_padding)
        self.inscribed, self.circumscribed = footprint_radii(self.footprint)
        self.kin = kinematics(self.p, robot)
        for key, limit, unit in (
            ("max_vel_x", robot.v_max, "m/s"),
            ("max_speed_xy", robot.v_max, "m/s"),
            ("max_vel_theta", robot.w_max, "rad/s"),
        ):
            self.note_above_robot(f"FollowPath.{key}", getattr(self.kin, key), limit, unit)
        self.planner = LocalPlanner(self.p.FollowPath, self.kin, self.footprint)
        self.size = (int(cm.width / cm.resolution), int(cm.height / cm.resolution))
        self.project = (
            DepthProjector(robot.camera, robot.base_height)
            if OBS_DEPTH in observation_space.spaces
            else None
        )
        self.camera = np.array(
            [*robot.camera.position[:2], robot.camera.position[2] + robot.base_height]
        )
        self.dt = robot.control_dt
        self.update_every = max(1, round(1.0 / (cm.update_frequency * self.dt)))
        self.use_imu = self.p.yaw_rate_source == "imu" and OBS_IMU in observation_space.spaces
        self.shim = (
            RotationShim(self.p.rotation_shim, *shim_rates(self.p, robot), self.dt, self.footprint)
            if self.p.rotation_shim.enabled
            else None
        )
        self.last: Evaluation | None = None
        self.reset()

    def clear_costmaps(self) -> None:
        """ClearEntireCostmap: every layer and the master grid back to their defaults."""
        self.layer.reset()
        self.master[:] = 0

    def describe(self) -> str:
        shim = ", rotation shim" if self.shim is not None else ""
        return f"dwb ({self.config}{shim})"

    def reset(self) -> None:
        cm = self.p.local_costmap
        self.pose = (0.0, 0.0, 0.0)  # odometry frame
        self.vel = (0.0, 0.0)
        self.steps = 0
        self.grid = Grid(0.0, 0.0, self.size[0], self.size[1], cm.resolution)
        self.layer = VoxelLayer(self.grid, cm.voxel_layer)
        self.layer.roll(0.0, 0.0)
        self.master = np.zeros(self.size, np.uint8)
        self.trail = np.zeros((0, 3))
        self.failures = 0
        self.goal: tuple[float, float, float] | None = None  # the last cycle's global goal
        self.planner.reset()
        if self.shim is not None:
            self.shim.reset()

    # ------------------------------------------------------------------ odometry and costmap
    def _odometry(self, obs: Obs) -> None:
        v, w = decode_odom(obs[OBS_ODOM])
        if self.use_imu:
            w = float(decode_imu(obs[OBS_IMU]).rate[2])
        if self.steps:  # the robot moved for one control period since the last call
            x, y, th = self.pose
            mid = th + 0.5 * w * self.dt
            self.pose = (
                x + v * math.cos(mid) * self.dt,
                y + v * math.sin(mid) * self.dt,
                th + w * self.dt,
            )
        self.vel = (
            v if abs(v) >= MIN_X_VELOCITY_THRESHOLD else 0.0,
            w if abs(w) >= MIN_THETA_VELOCITY_THRESHOLD else 0.0,
        )

    def to_world(self, pts: FloatArray) -> FloatArray:
        """Robot-frame (x, y[, ...]) points in the odometry frame."""
        x, y, th = self.pose
        c, s = math.cos(th), math.sin(th)
        out = pts.copy()
        out[:, 0] = x + c * pts[:, 0] - s * pts[:, 1]
        out[:, 1] = y + s * pts[:, 0] + c * pts[:, 1]
        return out

    def update_costmap(
        self, depth: NDArray[np.float32] | None, attitude: tuple[float, float] = (0.0, 0.0)
    ) -> None:
        """LayeredCostmap::updateMap: roll the window, the voxel layer, then inflation.
        ``attitude`` (roll, pitch) levels the cloud about the ground point under base_link
        (3-D odometry); (0, 0) keeps it in the wheels' plane (two_d_mode)."""
        self.layer.roll(self.pose[0], self.pose[1])
        if depth is not None and self.project is not None:
            body = np.vstack([self.project.points(depth), self.camera[None, :]])
            if attitude != (0.0, 0.0):
                cr, sr = math.cos(attitude[0]), math.sin(attitude[0])
                cp, sp = math.cos(attitude[1]), math.sin(attitude[1])
                # Ry(pitch) · Rx(roll): body -> yaw-aligned level frame (URDF rpy order)
                rot = np.array([[cp, sp * sr, sp * cr], [0.0, cr, -sr], [-sp, cp * sr, cp * cr]])
                body = body @ rot.T
            world = self.to_world(body)
            pts, origin = world[:-1], world[-1]
            self.layer.update(pts, origin, self.to_world(self.footprint))
        inf = self.p.local_costmap.inflation_layer
        self.master = inflate(self.layer.cost, self.grid.resolution, self.inscribed, inf)

    # ------------------------------------------------------------------ the global plan
    def _plan(
        self, route: NDArray[np.float32]
    ) -> tuple[FloatArray, tuple[float, float, float], int]:
        """The global plan (odometry frame, with the part behind the robot that Nav2 keeps
        after pruning) and the global goal. The route observation shows 4 m ahead; when its
        end is in view (the observation repeats the last point) that is the goal, otherwise
        its farthest point stands in for the goal's direction. The int is where the plan
        from the route observation starts (after the kept part)."""
        dense, _ = local_plan(route)
        raw, _ = decode_route(route)
        if len(dense) < 2:
            dense = (
                np.vstack([np.zeros(2), raw[-1:]])
                if len(raw)
                else np.array([[0.0, 0.0], [1.0, 0.0]])
            )
        heading = np.arctan2(np.diff(dense[:, 1]), np.diff(dense[:, 0]))
        heading = np.append(heading, heading[-1])
        rel = np.column_stack([dense, heading])
        plan = self.to_world(rel)
        plan[:, 2] = rel[:, 2] + self.pose[2]
        start = 0
        if len(self.trail):
            d = np.hypot(self.trail[:, 0] - plan[0, 0], self.trail[:, 1] - plan[0, 1])
            j = int(np.argmin(d))
            if d[j] <= TRAIL_JOIN:
                plan = np.vstack([self.trail[:j], plan])
                start = j
        g = plan[-1]
        return plan, (float(g[0]), float(g[1]), float(g[2])), start

    # ------------------------------------------------------------------ the control cycle
    def cycle(self, obs: Obs) -> Cycle:
        """Odometry, costmap (at update_frequency), plan: the inputs of one DWB cycle."""
        self._odometry(obs)
        if self.steps % self.update_every == 0:
            depth = obs[OBS_DEPTH][0] if OBS_DEPTH in obs and self.project is not None else None
            attitude = (0.0, 0.0)
            if not self.p.two_d_mode and OBS_IMU in obs:
                imu = decode_imu(obs[OBS_IMU])
                attitude = (imu.roll, imu.pitch)
            self.update_costmap(depth, attitude)
        plan, goal, start = self._plan(obs[OBS_ROUTE])
        last = self.goal
        # The route observation's end slides on by a control period's travel; one that jumps
        # further than the goal window is a new goal (the waypoint follower's next leg), and
        # setPlan resets every critic, so RotateToGoal lets go of the goal just reached.
        jump = self.p.FollowPath.xy_goal_tolerance
        new_goal = last is not None and math.hypot(goal[0] - last[0], goal[1] - last[1]) > jump
        if new_goal:
            self.planner.reset()
        self.goal = goal
        if self.shim is not None and (
            new_goal or last is None or self.steps % self.shim.plan_every == 0
        ):
            # the planner's path starts at the robot: the part kept behind it is DWB's own
            self.shim.set_plan(plan[start:])
        half = max(self.size) * self.grid.resolution / 2.0
        transformed, self.trail = transform_global_plan(plan, self.pose, half, self.p.FollowPath)
        return Cycle(
            self.pose, self.vel, goal, transformed, self.grid, self.master, self.steps * self.dt
        )

    def act(self, obs: Obs) -> NDArray[np.float32]:
        c = self.cycle(obs)
        self.cycle_inputs = c
        if self.shim is not None:
            w = self.shim.command(c.pose, c.velocity[1], c.grid, c.costmap)
            if w is not None:
                self.steps += 1
                return self._twist(0.0, w)
        ev = self.planner.evaluate(c)
        v, w = self.planner.command(ev, c)
        if ev.best < 0:
            # NoLegalTrajectories, or "Resulting plan has 0 poses": the controller server
            # publishes a zero twist and FollowPath fails; the default behaviour tree clears
            # the local costmap and retries on a freshly planned path
            self.failures += 1
            self.trail = np.zeros((0, 3))
            if self.p.clear_costmap_on_failure:
                self.clear_costmaps()
        self.last = ev
        self.steps += 1
        return self._twist(v, w)
