"""The Nav2 bundle's ROS 2 Humble configuration: ros_gz_bridge, sensor covariances,
robot_localization (two EKFs and navsat_transform), Nav2 (controller, planner, behaviour-tree
navigator, costmaps, lifecycle) and the behaviour tree.

Topics and frames::

    Gazebo (ros_robot.GZ_*)      bridge               ROS
    /clock                       GZ_TO_ROS            /clock
    imu, navsat, drive odometry  GZ_TO_ROS            /sim/imu, /sim/gps/fix, /sim/wheel/odometry
                                 sensor_covariances -> /imu/data, /gps/fix, /wheel/odometry
    depth camera cloud           GZ_TO_ROS            /depth_camera/points (voxel layer)
    depth image, camera_info     GZ_TO_ROS (lazy)     /depth_camera/image, /depth_camera/camera_info
    joint states                 GZ_TO_ROS            /joint_states (robot_state_publisher)
    drive command                ROS_TO_GZ            /cmd_vel (controller_server)

    ekf_local:  /wheel/odometry + /imu/data -> odom -> base_footprint, /odometry/local
    navsat_transform: /gps/fix + /imu/data + /odometry/global -> /odometry/gps
    ekf_global: the same + /odometry/gps -> map -> odom, /odometry/global

The drive plugin's own odom -> base_footprint transform stays in Gazebo: ekf_local publishes
that transform, and two publishers of one transform make tf jump between them.

Every key written here is one the Humble packages declare
(tests/data/ros_humble/, checked by tests/scenario_gen/export/test_nav2_bundle.py).
"""

from __future__ import annotations

import math
from typing import Any

import yaml

from ..errors import InputError
from ..model import Scenario
from .ros_robot import (
    BASE,
    GZ_CMD_VEL,
    GZ_DEPTH,
    GZ_IMU,
    GZ_JOINTS,
    GZ_NAVSAT,
    GZ_ODOM,
    MAP,
    ODOM,
    Nav2Robot,
)

CLOCK = "/clock"
IMU_RAW, IMU = "/sim/imu", "/imu/data"
GPS_RAW, GPS = "/sim/gps/fix", "/gps/fix"
ODOM_RAW, WHEEL_ODOM = "/sim/wheel/odometry", "/wheel/odometry"
POINTS = "/depth_camera/points"
DEPTH_IMAGE, CAMERA_INFO = "/depth_camera/image", "/depth_camera/camera_info"
JOINT_STATES = "/joint_states"
CMD_VEL = "/cmd_vel"
ODOM_LOCAL, ODOM_GLOBAL, ODOM_GPS = "/odometry/local", "/odometry/global", "/odometry/gps"
GPS_FILTERED = "/gps/filtered"

#: Nav2 node names, the order the lifecycle manager brings them up in
NAV2_NODES = ("controller_server", "planner_server", "bt_navigator")
LIFECYCLE = "lifecycle_manager_navigation"
CONTROLLER, PLANNER, GOAL_CHECKER, PROGRESS_CHECKER = (
    "FollowPath",
    "GridBased",
    "general_goal_checker",
    "progress_checker",
)
#: the behaviour tree replans through the follower's goals at this rate (the local costmap's)
REPLAN_HZ = 5.0
#: FollowPath failures (no legal trajectory) the tree clears the local costmap for, then gives up
FOLLOW_RETRIES = 20


class _Dumper(yaml.SafeDumper):
    """Block mappings; lists of scalars on one line."""


_Dumper.add_representer(
    list,
    lambda d, v: d.represent_sequence(
        "tag:yaml.org,2002:seq", v, flow_style=not any(isinstance(x, (dict, list)) for x in v)
    ),
)


def _float(v: float) -> str:
    """A float literal every YAML reader takes as one (PyYAML reads 1e-06 as a string)."""
    text = repr(float(v))
    mantissa, e, exponent = text.partition("e")
    return mantissa + ("" if "." in mantissa else ".0") + (e + exponent if e else "")


def _dump(header: str, data: Any) -> str:
    """YAML with lists of scalars on one line and robot_localization's 15 × 15 matrices as
    rows of the state (its order in the comment of each row)."""
    matrices: dict[str, list[float]] = {}

    def strip(node: Any) -> Any:
        if isinstance(node, dict):
            out = {}
            for k, v in node.items():
                if k in MATRICES:
                    token = f"@MATRIX{len(matrices)}@"
                    matrices[token] = v
                    out[k] = token
                else:
                    out[k] = strip(v)
            return out
        return node

    text = yaml.dump(strip(data), Dumper=_Dumper, sort_keys=False, width=120)
    for token, values in matrices.items():
        line = next(li for li in text.splitlines() if token in li)
        indent = " " * (len(line) - len(line.lstrip()) + 2)
        n = len(STATE)
        # every element a float literal: ROS's YAML reader refuses arrays mixing 0 and 0.1
        rows = [
            indent
            + ", ".join(_float(v) for v in values[i * n : (i + 1) * n])
            + ("," if i < n - 1 else "")
            + f"  # {STATE[i]}"
            for i in range(n)
        ]
        text = text.replace(f"'{token}'", "[\n" + "\n".join(rows) + "\n" + indent[:-2] + "]")
    return header + text


# ----------------------------------------------------------------------------- bridge


def bridge_entries() -> list[dict[str, Any]]:
    """ros_gz_bridge's YAML: one entry per topic (Humble's ros_gz reads gz.msgs names for
    Fortress and Harmonic alike)."""

    def entry(
        ros: str, gz: str, ros_type: str, gz_type: str, direction: str, lazy: bool = False
    ) -> dict[str, Any]:
        e: dict[str, Any] = {
            "ros_topic_name": ros,
            "gz_topic_name": gz,
            "ros_type_name": ros_type,
            "gz_type_name": f"gz.msgs.{gz_type}",
            "direction": direction,
        }
        if lazy:
            e["lazy"] = True
        return e

    g2r, r2g = "GZ_TO_ROS", "ROS_TO_GZ"
    return [
        entry(CLOCK, "/clock", "rosgraph_msgs/msg/Clock", "Clock", g2r),
        entry(IMU_RAW, GZ_IMU, "sensor_msgs/msg/Imu", "IMU", g2r),
        entry(GPS_RAW, GZ_NAVSAT, "sensor_msgs/msg/NavSatFix", "NavSat", g2r),
        entry(ODOM_RAW, GZ_ODOM, "nav_msgs/msg/Odometry", "Odometry", g2r),
        entry(POINTS, GZ_DEPTH + "/points", "sensor_msgs/msg/PointCloud2", "PointCloudPacked", g2r),
        entry(DEPTH_IMAGE, GZ_DEPTH, "sensor_msgs/msg/Image", "Image", g2r, lazy=True),
        entry(
            CAMERA_INFO,
            GZ_DEPTH.rsplit("/", 1)[0] + "/camera_info",
            "sensor_msgs/msg/CameraInfo",
            "CameraInfo",
            g2r,
            lazy=True,
        ),
        entry(JOINT_STATES, GZ_JOINTS, "sensor_msgs/msg/JointState", "Model", g2r),
        entry(CMD_VEL, GZ_CMD_VEL, "geometry_msgs/msg/Twist", "Twist", r2g),
    ]


def bridge_yaml() -> str:
    return _dump(
        "# ros_gz_bridge (parameter_bridge, config_file): Gazebo Sim <-> ROS 2 Humble topics.\n"
        "# The drive's own odom transform is not bridged: robot_localization publishes it.\n",
        bridge_entries(),
    )


# ----------------------------------------------------------------------------- covariances


def covariances_yaml(robot: Nav2Robot) -> str:
    loc, g = robot.localisation, robot.gnss
    data = {
        "imu": {
            "roll_pitch_sigma_deg": loc.roll_pitch_sigma_deg,
            "heading_sigma_deg": loc.heading_sigma_deg,
            "gyro_sigma_deg_s": loc.gyro_sigma_deg_s,
            "accel_sigma": loc.accel_sigma,
        },
        "gps": {"sigma_h": g.sigma_h, "sigma_v": g.sigma_v},
        "odom": {
            "odom_speed_rel": loc.odom_speed_rel,
            "odom_scale_sigma": loc.odom_scale_sigma,
            "odom_yaw_rel": loc.odom_yaw_rel,
            "odom_floor": loc.odom_floor,
            "lateral_sigma": loc.lateral_sigma,
        },
    }
    return _dump(
        "# Standard deviations scripts/sensor_covariances.py stamps on the bridged sensors:\n"
        f"# the simulator's EKF model (imu, odom) and the receiver's best fix mode ({g.mode},\n"
        "# gps: per axis, m). Degrees where the name says so, else SI units.\n",
        data,
    )


# ----------------------------------------------------------------------------- localisation

MATRICES = ("process_noise_covariance", "initial_estimate_covariance")
#: robot_localization's state order (its 15-element config vectors and matrices)
STATE: tuple[str, ...] = ("x", "y", "z", "roll", "pitch", "yaw", "vx", "vy", "vz", "vroll")
STATE += ("vpitch", "vyaw", "ax", "ay", "az")


#: the states of LocalisationSetup.process_noise, in its order (robot_localization's two_d_mode
#: leaves the others at the floor)
PROCESS_NOISE_STATES = ("x", "y", "yaw", "vx", "vy", "vyaw", "ax", "ay")


def fuse(*names: str) -> list[bool]:
    unknown = set(names) - set(STATE)
    if unknown:
        raise ValueError(f"not robot_localization states: {sorted(unknown)}")
    return [s in names for s in STATE]


def _diag(values: dict[str, float], rest: float) -> list[float]:
    n = len(STATE)
    out = [0.0] * (n * n)
    for i, s in enumerate(STATE):
        out[i * n + i] = float(values.get(s, rest))
    return out


def ekf_params(robot: Nav2Robot, world: str) -> dict[str, Any]:
    """One robot_localization EKF: ``world`` odom (ekf_local: wheel odometry and IMU) or map
    (ekf_global: the same plus navsat_transform's GNSS odometry)."""
    loc, d = robot.localisation, robot.drive
    dwb = robot.dwb
    imu_states = ["yaw", "vyaw"] + (["ax", "ay"] if loc.use_accel else [])
    odom_states = ["vx", "vy"] + (["vyaw"] if dwb.get("yaw_rate_source") == "wheels" else [])
    q = dict(zip(PROCESS_NOISE_STATES, loc.process_noise, strict=True))
    pos0 = loc.init_position_sigma**2 if world == MAP else 1e-6
    p0 = {"x": pos0, "y": pos0, "yaw": math.radians(loc.init_yaw_sigma_deg) ** 2}
    p0.update({s: 1e-4 for s in ("vx", "vy", "vyaw", "ax", "ay")})
    p: dict[str, Any] = {
        "frequency": float(d.control_hz),
        "sensor_timeout": 2.0 / d.control_hz,
        "two_d_mode": bool(dwb.get("two_d_mode", True)),
        "publish_tf": True,
        "map_frame": MAP,
        "odom_frame": ODOM,
        "base_link_frame": BASE,
        "world_frame": world,
        "smooth_lagged_data": True,
        "history_length": loc.history_s,
        "odom0": WHEEL_ODOM,
        "odom0_config": fuse(*odom_states),
        "odom0_queue_size": 10,
        "odom0_differential": False,
        "odom0_relative": False,
        "imu0": IMU,
        "imu0_config": fuse(*imu_states),
        "imu0_queue_size": 10,
        "imu0_differential": False,
        "imu0_relative": False,
        "imu0_remove_gravitational_acceleration": True,
    }
    if world == MAP:
        p.update(
            {
                "odom1": ODOM_GPS,
                "odom1_config": fuse("x", "y"),
                "odom1_queue_size": 10,
                "odom1_differential": False,
                "odom1_relative": False,
            }
        )
    p["process_noise_covariance"] = _diag(q, 1e-6)
    p["initial_estimate_covariance"] = _diag(p0, 1e-9)
    return p


def ekf_yaml(robot: Nav2Robot) -> str:
    loc = robot.localisation
    accel = " and horizontal specific force (gravity removed)" if loc.use_accel else ""
    source = "wheels" if robot.dwb.get("yaw_rate_source") == "wheels" else "gyro"
    header = f"""# robot_localization (Humble): two EKFs, set up as in Nav2's GPS navigation guide.
#   ekf_local  (world_frame odom): wheel odometry + IMU -> odom -> {BASE}, {ODOM_LOCAL}
#   ekf_global (world_frame map):  the same + navsat_transform's {ODOM_GPS} -> map -> odom
# Sensors as agrinav_gym simulates them: wheel odometry vx (and the skid-steer's vy = 0),
# the IMU's yaw, yaw rate{accel}; the yaw rate comes from the
# {source} (the benchmarked DWB's yaw_rate_source).
# two_d_mode keeps {BASE} on the odometry plane: the depth cloud's heights are then heights
# above the wheels, as the benchmark's costmap measures them. It also removes the GNSS antenna's
# offset through yaw alone, so on ridged or side-sloped ground the mast's lean (its height times
# sin(roll)) stays in ekf_global's position: two_d_mode false with the IMU's roll and pitch fused
# removes it (agrinav_gym docs/localisation.md, "Roll, pitch and the mast"). The process
# noise is the one the simulator's robot_localization filter runs with (per second; the node
# scales it by the time step); covariances of the measurements come with the messages
# (scripts/sensor_covariances.py). State order:
# {", ".join(STATE)}.
"""
    return _dump(
        header,
        {
            "ekf_local": {"ros__parameters": ekf_params(robot, ODOM)},
            "ekf_global": {"ros__parameters": ekf_params(robot, MAP)},
        },
    )


def navsat_yaml(scn: Scenario, robot: Nav2Robot) -> str:
    g = scn.geo
    params = {
        "frequency": float(robot.gnss.rate_hz),
        "delay": 0.0,
        "magnetic_declination_radians": 0.0,
        "yaw_offset": 0.0,
        "zero_altitude": True,
        "broadcast_cartesian_transform": False,
        "publish_filtered_gps": True,
        "use_odometry_yaw": False,
        "wait_for_datum": True,
        "use_local_cartesian": True,
        "datum": [round(g.lat, 10), round(g.lon, 10), 0.0],
    }
    return _dump(
        f"""# robot_localization navsat_transform_node: its map frame = the export's ENU frame.
# use_local_cartesian: the ENU tangent plane at the datum, not UTM grid axes; datum: lat, lon
# (degrees) and the heading (rad, ENU) of the robot when its map yaw is 0, so 0: the map's
# x axis points east. Gazebo's IMU reads yaw 0 facing east (ENU orientation reference) and
# true north, so yaw_offset and magnetic declination are 0. Inputs: {GPS}, {IMU},
# {ODOM_GLOBAL}; output: {ODOM_GPS}. The datum's altitude ({g.alt:.3f} m) is not used
# (zero_altitude; two_d_mode).
""",
        {"navsat_transform": {"ros__parameters": params}},
    )


# ----------------------------------------------------------------------------- Nav2


def _copy(src: dict[str, Any], keys: tuple[str, ...], where: str) -> dict[str, Any]:
    missing = [k for k in keys if k not in src]
    if missing:
        raise InputError(where, missing, "allowed: a complete DWB configuration")
    return {k: src[k] for k in keys}


FOLLOW_PATH_KEYS = (
    "min_vel_x",
    "max_vel_x",
    "max_vel_theta",
    "min_speed_xy",
    "max_speed_xy",
    "min_speed_theta",
    "acc_lim_x",
    "decel_lim_x",
    "acc_lim_theta",
    "decel_lim_theta",
    "vx_samples",
    "vtheta_samples",
    "sim_time",
    "discretize_by_time",
    "time_granularity",
    "linear_granularity",
    "angular_granularity",
    "include_last_point",
    "xy_goal_tolerance",
    "trans_stopped_velocity",
    "short_circuit_trajectory_evaluation",
    "prune_plan",
    "prune_distance",
    "forward_prune_distance",
    "shorten_transformed_plan",
    "critics",
)
DWB_PLUGIN = "dwb_core::DWBLocalPlanner"
SHIM_PLUGIN = "nav2_rotation_shim_controller::RotationShimController"
#: the rotation shim's Nav2 parameters (the policies' ``plan_frequency`` is the tree's replanning)
SHIM_KEYS = (
    "angular_dist_threshold",
    "forward_sampling_distance",
    "rotate_to_heading_angular_vel",
    "max_angular_accel",
    "simulate_ahead_time",
)
#: keys of the policies' DWB layout written only when they differ from the code default,
#: because Humble releases before the one that added them do not declare them
ONLY_IF_SET = {"limit_vel_cmd_in_traj": False}


def follow_path(dwb: dict[str, Any]) -> dict[str, Any]:
    """The DWB controller plugin's parameters under Nav2's names, from the policies' layout."""
    fp = dwb["FollowPath"]
    known = set(FOLLOW_PATH_KEYS) | set(ONLY_IF_SET)
    sections = {k for k, v in fp.items() if isinstance(v, dict)}
    unknown = sorted(set(fp) - known - sections)
    if unknown:
        raise InputError("nav2_robot.dwb.FollowPath", unknown, "no Nav2 key is known for these")
    out: dict[str, Any] = {"plugin": DWB_PLUGIN}
    shim = dwb.get("rotation_shim") or {}
    if shim.get("enabled"):
        # the shim and its primary controller read their parameters from the same namespace
        if float(shim.get("plan_frequency", REPLAN_HZ)) != REPLAN_HZ:
            raise InputError(
                "nav2_robot.dwb.rotation_shim.plan_frequency",
                shim["plan_frequency"],
                f"allowed: {REPLAN_HZ:g} (the exported behaviour tree replans at that rate)",
            )
        out = {"plugin": SHIM_PLUGIN, "primary_controller": DWB_PLUGIN}
        out.update({k: float(shim[k]) for k in SHIM_KEYS})
    # Humble's nav2_params.yaml: no y velocities for a differential or skid-steer base
    out.update({"debug_trajectory_details": True, "transform_tolerance": 0.2})
    out.update(_copy(fp, FOLLOW_PATH_KEYS, "nav2_robot.dwb.FollowPath"))
    out.update({"min_vel_y": 0.0, "max_vel_y": 0.0, "acc_lim_y": 0.0, "decel_lim_y": 0.0})
    out["vy_samples"] = 5
    for key, default in ONLY_IF_SET.items():
        if key in fp and fp[key] != default:
            out[key] = fp[key]
    for critic in fp["critics"]:
        out[critic] = dict(fp[critic])
    return out


def local_costmap(dwb: dict[str, Any]) -> dict[str, Any]:
    cm = dwb["local_costmap"]
    vl, il = cm["voxel_layer"], cm["inflation_layer"]
    src = dict(vl["depth_camera"])
    src.update({"topic": POINTS, "data_type": "PointCloud2"})
    voxel = {"plugin": "nav2_costmap_2d::VoxelLayer", "publish_voxel_map": True}
    voxel.update({k: v for k, v in vl.items() if k != "depth_camera"})
    voxel.update({"observation_sources": "depth_camera", "depth_camera": src})
    fp = cm["footprint"]
    return {
        "update_frequency": cm["update_frequency"],
        "publish_frequency": 2.0,
        "global_frame": ODOM,
        "robot_base_frame": BASE,
        "rolling_window": True,
        "width": cm["width"],
        "height": cm["height"],
        "resolution": cm["resolution"],
        # Nav2 reads the footprint as a string
        "footprint": "[" + ", ".join(f"[{x:.4f}, {y:.4f}]" for x, y in fp) + "]",
        "footprint_padding": cm["footprint_padding"],
        "always_send_full_costmap": True,
        "plugins": ["voxel_layer", "inflation_layer"],
        "voxel_layer": voxel,
        "inflation_layer": {"plugin": "nav2_costmap_2d::InflationLayer", **il},
    }


def global_costmap(robot: Nav2Robot, resolution: float) -> dict[str, Any]:
    """A rolling window, obstacle-free: the planner only joins the follower's route poses
    (``route_points`` × ``route_spacing`` ahead) with straight lines, as the benchmark's DWB
    takes the route as its plan. Wide enough for the goals ahead and behind of either side."""
    reach = robot.route_points * robot.route_spacing
    size = 2 * math.ceil(reach + 1.0)
    return {
        "update_frequency": 1.0,
        "publish_frequency": 1.0,
        "global_frame": MAP,
        "robot_base_frame": BASE,
        "rolling_window": True,
        "width": size,
        "height": size,
        "resolution": resolution,
        "track_unknown_space": False,
        "always_send_full_costmap": True,
        "plugins": ["inflation_layer"],
        "inflation_layer": {
            "plugin": "nav2_costmap_2d::InflationLayer",
            "cost_scaling_factor": 3.0,
            "inflation_radius": 0.55,
        },
    }


def nav2_params(robot: Nav2Robot, dwb: dict[str, Any]) -> dict[str, Any]:
    d = robot.drive
    return {
        # every node of the process, the behaviour tree's client nodes included
        "/**": {"ros__parameters": {"use_sim_time": True}},
        "controller_server": {
            "ros__parameters": {
                "controller_frequency": float(d.control_hz),
                "odom_topic": ODOM_LOCAL,
                "min_x_velocity_threshold": 0.001,
                "min_y_velocity_threshold": 0.5,
                "min_theta_velocity_threshold": 0.001,
                "failure_tolerance": 0.3,
                "progress_checker_plugin": PROGRESS_CHECKER,
                "goal_checker_plugins": [GOAL_CHECKER],
                "controller_plugins": [CONTROLLER],
                PROGRESS_CHECKER: {
                    "plugin": "nav2_controller::SimpleProgressChecker",
                    "required_movement_radius": 0.5,
                    "movement_time_allowance": 10.0,
                },
                GOAL_CHECKER: {
                    "plugin": "nav2_controller::SimpleGoalChecker",
                    "stateful": True,
                    "xy_goal_tolerance": 0.25,
                    "yaw_goal_tolerance": 0.25,
                },
                CONTROLLER: follow_path(dwb),
            }
        },
        "local_costmap": {"local_costmap": {"ros__parameters": local_costmap(dwb)}},
        "global_costmap": {
            "global_costmap": {
                "ros__parameters": global_costmap(robot, dwb["local_costmap"]["resolution"])
            }
        },
        "planner_server": {
            "ros__parameters": {
                "expected_planner_frequency": 20.0,
                "planner_plugins": [PLANNER],
                PLANNER: {
                    "plugin": "nav2_navfn_planner/NavfnPlanner",
                    "tolerance": 0.5,
                    "use_astar": False,
                    "allow_unknown": True,
                },
            }
        },
        "bt_navigator": {
            "ros__parameters": {
                "global_frame": MAP,
                "robot_base_frame": BASE,
                "odom_topic": ODOM_LOCAL,
                "bt_loop_duration": 10,
                "default_server_timeout": 20,
                # default_nav_through_poses_bt_xml, default_nav_to_pose_bt_xml: the launch
                # file passes the bundle's trees (their paths depend on where it lies)
            }
        },
        LIFECYCLE: {
            "ros__parameters": {
                "autostart": True,
                "node_names": list(NAV2_NODES),
                "bond_timeout": 4.0,
            }
        },
    }


def nav2_yaml(robot: Nav2Robot, reference: bool) -> str:
    name = "dwb:nav2 (Nav2 Humble's defaults)" if reference else robot.controller
    dwb = robot.dwb_reference if reference else robot.dwb
    header = f"""# Nav2 (ROS 2 Humble) for the AgriNav route: DWB as benchmarked, {name}.
# controller_server: DWB under Nav2's names from the policies' configuration (docs/dwb.md),
# with the robot's limits and footprint rectangle; y velocities 0 (skid-steer), and
# debug_trajectory_details, transform_tolerance and vy_samples as Humble's nav2_params.yaml.
# local_costmap: rolling 3 x 3 m, the voxel layer fed by the depth camera's cloud ({POINTS})
# in the plane of the wheels ({BASE}, two_d_mode), inflation.
# planner_server + global_costmap: the route is the plan. The follower sends the route poses
# ahead ({robot.route_points} x {robot.route_spacing} m) as NavigateThroughPoses goals; NavFn
# joins them on an obstacle-free rolling costmap, so the path is the route to a cell.
# bt_navigator: behavior_trees/*.xml (the launch file passes them).
"""
    return _dump(header, nav2_params(robot, dwb))


#: the two navigators of Humble's bt_navigator: the file, the tree's ID, the planning node
TREES = {
    "through_poses": ("follow_route.xml", "FollowRoute", "ComputePathThroughPoses", "goals"),
    "to_pose": ("navigate_to_pose.xml", "NavigateToPose", "ComputePathToPose", "goal"),
}


def behavior_tree(clear_on_failure: bool, navigator: str = "through_poses") -> str:
    """Plan at REPLAN_HZ and follow the path; a FollowPath failure (no legal trajectory) clears
    the local costmap and retries, as the benchmark's DWB does within its step and Nav2's
    default tree does first. No spin, back-up or wait: the route is fixed, and Nav2's default
    trees would need the behavior server (a tree's action servers must exist when
    bt_navigator loads it, and both navigators load theirs when it starts).

    ``through_poses`` is the route follower's (NavigateThroughPoses: the route poses ahead);
    ``to_pose`` serves a single goal (NavigateToPose, e.g. from RViz) the same way."""
    _, tree_id, compute, goals = TREES[navigator]
    follow = (
        f'<FollowPath path="{{path}}" controller_id="{CONTROLLER}" '
        f'goal_checker_id="{GOAL_CHECKER}"/>'
    )
    if clear_on_failure:
        follow = f"""<RecoveryNode number_of_retries="{FOLLOW_RETRIES}" name="FollowPathRecovery">
        {follow}
        <ClearEntireCostmap name="ClearLocalCostmap"
                            service_name="local_costmap/clear_entirely_local_costmap"/>
      </RecoveryNode>"""
    what = (
        "route following (NavigateThroughPoses). The goals are the route poses ahead of the\n"
        "     robot (scripts/follow_route.py moves them on); the planner joins them, DWB follows."
        if navigator == "through_poses"
        else "a single goal (NavigateToPose): the planner's path to it, DWB follows."
    )
    return f"""<?xml version="1.0"?>
<!-- AgriNav, Nav2 Humble's bt_navigator, written by agrinav export: {what} -->
<root main_tree_to_execute="{tree_id}">
  <BehaviorTree ID="{tree_id}">
    <PipelineSequence name="PlanAndFollow">
      <RateController hz="{REPLAN_HZ}">
        <RecoveryNode number_of_retries="1" name="ComputePathRecovery">
          <{compute} {goals}="{{{goals}}}" path="{{path}}" planner_id="{PLANNER}"/>
          <ClearEntireCostmap name="ClearGlobalCostmap"
                              service_name="global_costmap/clear_entirely_global_costmap"/>
        </RecoveryNode>
      </RateController>
      {follow}
    </PipelineSequence>
  </BehaviorTree>
</root>
"""
