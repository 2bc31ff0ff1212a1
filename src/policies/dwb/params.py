"""DWB parameters under Nav2's names, checked by ``scenario_gen.schema``.

The layout follows a Nav2 params file: ``FollowPath`` holds the DWBLocalPlanner, its
StandardTrajectoryGenerator/XYThetaIterator kinematics and one section per critic;
``local_costmap`` the rolling costmap with its voxel and inflation layers. Defaults are Nav2
Humble's (``nav2_bringup/params/nav2_params.yaml``, the plugins' code defaults where that file is
silent). ``None`` means "the robot's own value" (``RobotInterface``): Humble's file describes a
TurtleBot3. Every YAML is read as changes to ``config/dwb_nav2.yaml`` (the reference), so a
furrow-tuned file lists exactly what it changes.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dc_field
from importlib import resources
from pathlib import Path
from typing import Any

from scenario_gen.errors import InputError
from scenario_gen.schema import from_mapping, load_yaml, merge, param, parse_yaml

#: Every critic this package implements, under its Nav2 plugin name.
CRITICS = (
    "RotateToGoal",
    "Oscillation",
    "BaseObstacle",
    "ObstacleFootprint",
    "GoalAlign",
    "PathAlign",
    "PathDist",
    "GoalDist",
    "PreferForward",
)
#: Humble's nav2_params.yaml critic list, in its order (the scoring order).
NAV2_CRITICS = (
    "RotateToGoal",
    "Oscillation",
    "BaseObstacle",
    "GoalAlign",
    "PathAlign",
    "PathDist",
    "GoalDist",
)
#: the configs shipped in policies/config (``dwb:NAME``): Nav2 Humble's defaults, the furrow
#: changes, and the furrow changes plus what the tuning search chose (``dwb_tuned.yaml``)
SHIPPED = ("nav2", "furrow", "tuned")
AGGREGATION = ("last", "sum", "product")
#: a changes file's key naming the shipped config it changes (dwb_nav2.yaml when absent)
BASE_KEY = "base"


def _scale(default: float) -> Any:
    return param(default, "weight of this critic in the total Σ scale × score", 0.0, 1e6)


def _aggregation() -> Any:
    return param("last", "how the poses' cell values make the score", choices=AGGREGATION)


def _forward_point(default: float) -> Any:
    return param(default, "the point this far ahead of each pose is scored, m", 0.0, 5.0)


@dataclass(frozen=True)
class RotateToGoalParams:
    scale: float = _scale(32.0)
    slowing_factor: float = param(5.0, "weight of speed² while slowing in the goal window", 0, 1e3)
    lookahead_time: float = param(
        -1.0, "score the heading this far into the trajectory, s (< 0: its last pose)", -1, 10
    )


@dataclass(frozen=True)
class OscillationParams:
    scale: float = _scale(1.0)
    oscillation_reset_dist: float = param(
        0.05, "distance from the last sign flip that clears the flags, m (< 0: off)", -1, 10
    )
    oscillation_reset_angle: float = param(
        0.2, "heading change from the last sign flip that clears the flags, rad (< 0: off)", -1, 7
    )
    oscillation_reset_time: float = param(
        -1.0, "time since the last sign flip that clears the flags, s (< 0: off)", -1, 1e3
    )
    x_only_threshold: float = param(
        0.05, "below this |v| (m/s) flips of ω are tracked too (< 0: always)", -1, 10
    )


@dataclass(frozen=True)
class BaseObstacleParams:
    scale: float = _scale(0.02)
    sum_scores: bool = param(False, "sum the poses' cell costs instead of taking the last one")


@dataclass(frozen=True)
class ObstacleFootprintParams:
    scale: float = _scale(1.0)
    sum_scores: bool = param(False, "sum the poses' footprint costs instead of the last one")


@dataclass(frozen=True)
class PathDistParams:
    scale: float = _scale(32.0)
    aggregation_type: str = _aggregation()


@dataclass(frozen=True)
class GoalDistParams:
    scale: float = _scale(24.0)
    aggregation_type: str = _aggregation()


@dataclass(frozen=True)
class PathAlignParams:
    scale: float = _scale(32.0)
    aggregation_type: str = _aggregation()
    forward_point_distance: float = _forward_point(0.1)


@dataclass(frozen=True)
class GoalAlignParams:
    scale: float = _scale(24.0)
    aggregation_type: str = _aggregation()
    forward_point_distance: float = _forward_point(0.1)


@dataclass(frozen=True)
class PreferForwardParams:
    scale: float = _scale(1.0)
    penalty: float = param(1.0, "score of reversing or strafing-like commands", 0, 1e6)
    strafe_x: float = param(0.1, "below this v (m/s) with little ω counts as strafing", 0, 10)
    strafe_theta: float = param(0.2, "ω (rad/s) under which slow motion counts as strafing", 0, 10)
    theta_scale: float = param(10.0, "score per rad/s of |ω|", 0, 1e3)


def _robot(doc: str, lo: float, hi: float, above: bool = False) -> Any:
    return param(None, doc + " (null: the robot's own value)", lo, hi, above=above)


@dataclass(frozen=True)
class FollowPathParams:
    """DWBLocalPlanner, StandardTrajectoryGenerator, XYThetaIterator and KinematicParameters.

    The robot is skid-steer: y velocities are 0 (Nav2's min/max_vel_y 0, one y sample)."""

    min_vel_x: float = param(0.0, "slowest forward speed sampled, m/s", -10, 10)
    # 0: a window the robot cannot move forward in, refused rather than driven standing
    max_vel_x: float | None = _robot("fastest forward speed sampled, m/s", 0, 10, above=True)
    max_vel_theta: float | None = _robot("fastest yaw rate sampled, rad/s", 0, 20)
    min_speed_xy: float = param(
        0.0, "twists slower than this (and min_speed_theta) are skipped, m/s", 0, 10
    )
    max_speed_xy: float | None = _robot("twists faster than this are skipped, m/s", 0, 10)
    min_speed_theta: float = param(0.0, "see min_speed_xy, rad/s", 0, 20)
    acc_lim_x: float | None = _robot("linear acceleration limit, m/s²", 0, 50, above=True)
    decel_lim_x: float | None = _robot("linear deceleration limit (negative), m/s²", -50, 0)
    acc_lim_theta: float | None = _robot("angular acceleration limit, rad/s²", 0, 100)
    decel_lim_theta: float | None = _robot("angular deceleration limit (negative), rad/s²", -100, 0)
    vx_samples: int = param(20, "forward-speed samples in the dynamic window", 1, 500)
    vtheta_samples: int = param(20, "yaw-rate samples in the dynamic window", 1, 500)
    sim_time: float = param(
        1.7, "rollout horizon (and the window's acceleration time), s", 0.05, 10
    )
    discretize_by_time: bool = param(False, "rollout steps of time_granularity instead")
    time_granularity: float = param(0.5, "rollout step when discretize_by_time, s", 0.001, 10)
    linear_granularity: float = param(0.05, "longest rollout step along the path, m", 0.001, 5)
    angular_granularity: float = param(0.025, "longest rollout step in heading, rad", 0.001, 5)
    include_last_point: bool = param(True, "repeat the last pose at the end of each rollout")
    limit_vel_cmd_in_traj: bool = param(
        False, "command the first ramped velocity instead of the sampled one"
    )
    xy_goal_tolerance: float = param(0.25, "RotateToGoal's goal window, m", 0, 10)
    trans_stopped_velocity: float = param(
        0.25, "RotateToGoal counts the robot stopped below this speed, m/s", 0, 10
    )
    short_circuit_trajectory_evaluation: bool = param(
        True, "stop scoring a twist once it is worse than the best (same choice, less work)"
    )
    prune_plan: bool = param(True, "drop the plan behind the robot")
    prune_distance: float = param(
        2.0, "plan arc searched for the robot and kept behind it, m", 0, 100
    )
    forward_prune_distance: float = param(2.0, "plan kept ahead of the robot, m", 0, 100)
    shorten_transformed_plan: bool = param(True, "cut the plan at forward_prune_distance")
    critics: list[str] = param(list(NAV2_CRITICS), "critics in scoring order", choices=CRITICS)
    RotateToGoal: RotateToGoalParams = dc_field(default_factory=RotateToGoalParams)
    Oscillation: OscillationParams = dc_field(default_factory=OscillationParams)
    BaseObstacle: BaseObstacleParams = dc_field(default_factory=BaseObstacleParams)
    ObstacleFootprint: ObstacleFootprintParams = dc_field(default_factory=ObstacleFootprintParams)
    GoalAlign: GoalAlignParams = dc_field(default_factory=GoalAlignParams)
    PathAlign: PathAlignParams = dc_field(default_factory=PathAlignParams)
    PathDist: PathDistParams = dc_field(default_factory=PathDistParams)
    GoalDist: GoalDistParams = dc_field(default_factory=GoalDistParams)
    PreferForward: PreferForwardParams = dc_field(default_factory=PreferForwardParams)


@dataclass(frozen=True)
class DepthSourceParams:
    """The voxel layer's observation source fed by the depth camera (Nav2's per-source keys)."""

    min_obstacle_height: float = param(
        0.0, "points lower than this above the wheels' plane are ground, m", -1, 5
    )
    max_obstacle_height: float = param(2.0, "points higher than this are ignored, m", 0, 10)
    obstacle_max_range: float = param(2.5, "points farther from the camera do not mark, m", 0, 50)
    obstacle_min_range: float = param(0.0, "points nearer the camera do not mark, m", 0, 50)
    raytrace_max_range: float = param(3.0, "clearing rays stop after this, m", 0, 50)
    raytrace_min_range: float = param(0.0, "clearing rays start after this, m", 0, 50)
    marking: bool = param(True, "the source marks obstacles")
    clearing: bool = param(True, "the source clears voxels along its rays")


@dataclass(frozen=True)
class VoxelLayerParams:
    enabled: bool = param(True, "use the depth camera at all")
    origin_z: float = param(
        0.0, "height of the voxel grid's floor above the wheels' plane, m", -5, 5
    )
    z_resolution: float = param(0.05, "voxel height, m", 0.005, 1)
    z_voxels: int = param(16, "voxels per column (at most 16, as Nav2's bit columns)", 1, 16)
    max_obstacle_height: float = param(2.0, "the layer ignores points above this, m", 0, 10)
    mark_threshold: int = param(0, "a column is lethal with more marked voxels than this", 0, 16)
    footprint_clearing_enabled: bool = param(True, "cells under the robot's footprint are free")
    depth_camera: DepthSourceParams = dc_field(default_factory=DepthSourceParams)


@dataclass(frozen=True)
class InflationLayerParams:
    enabled: bool = param(True, "inflate obstacles")
    cost_scaling_factor: float = param(3.0, "exponential decay of cost with distance, 1/m", 0, 100)
    inflation_radius: float = param(0.55, "obstacles add cost up to this distance, m", 0, 10)


@dataclass(frozen=True)
class LocalCostmapParams:
    """A rolling-window costmap in the odometry frame (global_frame: odom)."""

    update_frequency: float = param(5.0, "costmap updates per second", 0.1, 1000)
    width: int = param(3, "window size along x, whole metres (Nav2 declares it an int)", 1, 50)
    height: int = param(3, "window size along y, whole metres", 1, 50)
    resolution: float = param(0.05, "cell size, m", 0.005, 1)
    footprint: list[list[float]] | None = param(
        None, "footprint polygon [[x, y], ...] in base_link, m (null: the robot's rectangle)"
    )
    footprint_padding: float = param(
        0.01, "added to the footprint on every side (negative shrinks it), m", -0.3, 1
    )
    voxel_layer: VoxelLayerParams = dc_field(default_factory=VoxelLayerParams)
    inflation_layer: InflationLayerParams = dc_field(default_factory=InflationLayerParams)


@dataclass(frozen=True)
class RotationShimParams:
    """nav2_rotation_shim_controller's RotationShimController in front of DWB (Humble's
    defaults; the robot's limits where the config says null): on a new plan whose point
    ``forward_sampling_distance`` along it lies more than ``angular_dist_threshold`` off the
    robot's heading it turns in place toward it, then hands the plan to DWB."""

    enabled: bool = param(False, "put the rotation shim in front of DWB")
    angular_dist_threshold: float = param(
        0.785, "turn in place while the sampled plan point is further off the heading, rad", 0, 3.15
    )
    forward_sampling_distance: float = param(
        0.5, "the plan point this far from the plan's start sets the heading, m", 0.01, 10
    )
    rotate_to_heading_angular_vel: float | None = _robot(
        "yaw rate of the in-place turn, rad/s", 0, 20
    )
    max_angular_accel: float | None = _robot("angular acceleration of the turn, rad/s²", 0, 100)
    simulate_ahead_time: float = param(
        1.0, "the turn's footprint is checked for collision this far ahead, s", 0, 10
    )
    plan_frequency: float = param(
        5.0,
        "new global plans per second (the exported behaviour tree's replanning rate, and a new "
        "waypoint goal): each one re-arms the shim",
        0.01,
        1000,
    )


@dataclass(frozen=True)
class DWBParams:
    """Everything the DWB controller reads (config/dwb_nav2.yaml is the reference)."""

    FollowPath: FollowPathParams = dc_field(default_factory=FollowPathParams)
    local_costmap: LocalCostmapParams = dc_field(default_factory=LocalCostmapParams)
    rotation_shim: RotationShimParams = dc_field(default_factory=RotationShimParams)
    clear_costmap_on_failure: bool = param(
        True,
        "when no trajectory is legal: stop and clear the local costmap, as Nav2's default "
        "behaviour tree does before retrying FollowPath",
    )
    two_d_mode: bool = param(
        True,
        "robot_localization's two_d_mode: odometry without roll and pitch, so the depth cloud "
        "is in the plane of the wheels; false levels it with the IMU's roll and pitch",
    )
    yaw_rate_source: str = param(
        "imu",
        "yaw rate of the odometry the costmap is kept in and the window starts from "
        "(imu: gyro, as a robot_localization odom EKF fuses it; wheels: wheel odometry)",
        choices=("imu", "wheels"),
    )

    @classmethod
    def load(cls, spec: str | Path | dict[str, Any] | None = None) -> DWBParams:
        """``nav2``, ``furrow`` (the default), ``tuned``, a YAML file of changes to
        ``dwb_nav2.yaml`` (or to the shipped config its ``base`` names), or such changes as a
        mapping (what ``agrinav tune`` tries)."""
        reference = _shipped("nav2")
        if isinstance(spec, dict):
            changes = spec
        elif spec is None or str(spec) == "furrow":
            changes = _shipped("furrow")
        elif str(spec) == "nav2":
            changes = {}
        elif str(spec) in SHIPPED:
            changes = _shipped(str(spec))
        elif not Path(spec).is_file():
            raise InputError(
                "dwb params", str(spec), f"allowed: {', '.join(SHIPPED)} or an existing YAML file"
            )
        else:
            changes = load_yaml(spec, "dwb params")
        changes = _over_base(changes)
        params: DWBParams = from_mapping(cls, merge(reference, changes), "dwb.")
        params.check()
        return params

    def check(self) -> None:
        """Cross-field rules that a single field's range cannot say."""
        fp = self.FollowPath
        if len(set(fp.critics)) != len(fp.critics):
            raise InputError("dwb.FollowPath.critics", fp.critics, "allowed: each critic once")
        if not fp.critics:
            raise InputError("dwb.FollowPath.critics", fp.critics, "allowed: at least one critic")
        if fp.max_vel_x is not None and fp.min_vel_x > fp.max_vel_x:
            raise InputError(
                "dwb.FollowPath.min_vel_x",
                fp.min_vel_x,
                f"allowed: at most max_vel_x ({fp.max_vel_x:g} m/s)",
            )
        cm = self.local_costmap
        fpn = cm.footprint
        if fpn is not None and (len(fpn) < 3 or any(len(p) != 2 for p in fpn)):
            raise InputError(
                "dwb.local_costmap.footprint", fpn, "allowed: at least 3 [x, y] points"
            )
        src = cm.voxel_layer.depth_camera
        if src.min_obstacle_height >= src.max_obstacle_height:
            raise InputError(
                "dwb.local_costmap.voxel_layer.depth_camera.min_obstacle_height",
                src.min_obstacle_height,
                "allowed: below max_obstacle_height",
            )


def _over_base(changes: dict[str, Any]) -> dict[str, Any]:
    """Changes that name a shipped config as ``base`` (``base: tuned``) apply over it, so a
    file that adds one thing to ``dwb:tuned`` lists only that thing."""
    if BASE_KEY not in changes:
        return changes
    rest = {k: v for k, v in changes.items() if k != BASE_KEY}
    base = changes[BASE_KEY]
    if not isinstance(base, str) or base not in SHIPPED:
        raise InputError(f"dwb.{BASE_KEY}", base, f"allowed: {', '.join(SHIPPED)}")
    return merge(_shipped(base) if base != "nav2" else {}, rest)


def _shipped(name: str) -> dict[str, Any]:
    if name not in SHIPPED:
        raise InputError("dwb config", name, f"allowed: {', '.join(SHIPPED)} or a YAML file")
    text = resources.files("policies.config").joinpath(f"dwb_{name}.yaml").read_text()
    data = parse_yaml(text, f"dwb_{name}.yaml")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputError(f"dwb_{name}.yaml", type(data).__name__, "allowed: a mapping")
    return data
