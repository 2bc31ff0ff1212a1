"""The runnable part of the Nav2 bundle: the robot for Gazebo Sim, the ROS 2 configuration,
the behaviour tree, the bundle's ROS programs and the launch file (docs/exports.md).

    robot/summit_xl_gazebo.urdf      the Summit-XL with base_footprint, sensors, drive (Gazebo Sim)
    config/bridge.yaml               ros_gz_bridge
    config/sensor_covariances.yaml   what scripts/sensor_covariances.py stamps on the sensors
    config/ekf.yaml                  robot_localization ekf_local and ekf_global
    config/navsat_transform.yaml     robot_localization navsat_transform (datum = the export's)
    config/nav2_params.yaml          Nav2 with DWB as benchmarked (e.g. dwb:furrow)
    config/nav2_params_nav2_defaults.yaml   the same with DWB as Nav2 Humble ships it (dwb:nav2)
    behavior_trees/follow_route.xml  bt_navigator's tree (and navigate_to_pose.xml for one goal)
    scripts/follow_route.py          the route follower (GPS check, NavigateThroughPoses goals)
    scripts/sensor_covariances.py    covariances for the bridged sensors
    launch/agrinav_field.launch.py   everything above, started in order
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from importlib import resources
from pathlib import Path
from typing import Any

from ..model import Scenario
from . import ros_config as rc
from .options import ExportOptions
from .ros_robot import Nav2Robot, camera_image, gazebo_urdf, urdf_geometry

SCRIPTS = ("follow_route.py", "sensor_covariances.py")


def _template(name: str) -> str:
    return resources.files("scenario_gen.export.ros").joinpath(name).read_text()


def _set(text: str, prefix: str, line: str) -> str:
    """Replace the one line of ``text`` starting with ``prefix`` by ``line``."""
    pattern = re.compile(rf"^{re.escape(prefix)}.*$", re.M)
    out, n = pattern.subn(line.replace("\\", "\\\\"), text)
    if n != 1:
        raise RuntimeError(f"launch template: {n} lines start with {prefix!r}")
    return out


def launch_py(
    spawn: tuple[float, float, float, float], base_height: float, robot: Nav2Robot
) -> str:
    x, y, z, yaw = spawn
    text = _template("launch_template.py")
    text = _set(
        text,
        "SPAWN_X, SPAWN_Y, SPAWN_Z, SPAWN_YAW = ",
        f"SPAWN_X, SPAWN_Y, SPAWN_Z, SPAWN_YAW = {x:.4f}, {y:.4f}, {z:.4f}, {yaw:.6f}"
        "  # base_link at the route start",
    )
    text = _set(
        text,
        "BASE_HEIGHT = ",
        f"BASE_HEIGHT = {base_height:.4f}  # base_link above base_footprint (the ground), m",
    )
    return _set(
        text,
        "ROUTE_POINTS, ROUTE_SPACING = ",
        f"ROUTE_POINTS, ROUTE_SPACING = {robot.route_points}, {robot.route_spacing:.4f}"
        "  # follower goals, m apart",
    )


def write_ros_bundle(
    scn: Scenario,
    out: Path,
    urdf_text: str,
    spawn: tuple[float, float, float, float],
    opts: ExportOptions,
) -> dict[str, Any]:
    """Write the runnable bundle into ``out`` (the Gazebo export and the waypoints are there
    already); returns what the README reports."""
    assert opts.nav2_robot is not None  # checked before the output folder was made
    robot = Nav2Robot.from_dict(opts.nav2_robot)
    north = scn.geo.enu_to_geodetic(0.0, 1.0, 0.0)[0] - scn.geo.enu_to_geodetic(0.0, 0.0, 0.0)[0]
    gz_urdf = gazebo_urdf(urdf_text, robot, 1.0 / float(north))
    (out / "robot" / "summit_xl_gazebo.urdf").write_text(gz_urdf)
    config = out / "config"
    (config / "bridge.yaml").write_text(rc.bridge_yaml())
    (config / "sensor_covariances.yaml").write_text(rc.covariances_yaml(robot))
    (config / "ekf.yaml").write_text(rc.ekf_yaml(robot))
    (config / "navsat_transform.yaml").write_text(rc.navsat_yaml(scn, robot))
    (config / "nav2_params.yaml").write_text(rc.nav2_yaml(robot, reference=False))
    (config / "nav2_params_nav2_defaults.yaml").write_text(rc.nav2_yaml(robot, reference=True))
    (out / "behavior_trees").mkdir()
    clear = bool(robot.dwb.get("clear_costmap_on_failure", True))
    for navigator, (name, *_) in rc.TREES.items():
        (out / "behavior_trees" / name).write_text(rc.behavior_tree(clear, navigator))
    (out / "scripts").mkdir()
    for name in SCRIPTS:
        (out / "scripts" / name).write_text(_template(name))
        (out / "scripts" / name).chmod(0o755)
    base_height = urdf_geometry(ET.fromstring(urdf_text)).wheel_radius
    (out / "launch" / "agrinav_field.launch.py").write_text(launch_py(spawn, base_height, robot))
    width, height, _ = camera_image(robot.camera)
    return {
        "controller": robot.controller,
        "depth_image": (width, height),
        "base_height": base_height,
        "robot": robot,
    }
