"""ROS 2 / Nav2: the Gazebo world plus a launch file, GPS waypoints and the reference path.

Waypoints are sparse — every lane entry and exit, the apex of every headland turn (and the
cusps of a three-point turn) and the end of the lead-out — since a waypoint follower plans
between them; the 0.1 m reference path is for measuring cross-track error afterwards, not for
driving. Yaw is the way the robot faces: against the direction of travel where the route is
driven backwards.
"""

from __future__ import annotations

import csv
import itertools
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..arrays import FloatArray
from ..model import Scenario
from .gazebo import export_gazebo
from .options import ExportOptions

#: base_link sits 0.11 m above the footprint (wheel radius); spawn 2 cm above the ground.
SPAWN_CLEARANCE = 0.13


def route_yaw(xy: FloatArray, direction: np.ndarray | None = None) -> FloatArray:
    """Heading (rad, ENU: 0 east, counter-clockwise) of the path at each point; with the
    route's ``direction``, the way the robot faces (turned round where it reverses)."""
    if len(xy) < 2:
        return np.zeros(len(xy))
    d = np.gradient(xy, axis=0)
    if direction is not None and (np.asarray(direction) < 0).any():
        fwd = np.diff(xy, axis=0) * np.asarray(direction[:-1], np.float64)[:, None]
        d = np.vstack([fwd, fwd[-1:]])  # the facing along the segment leaving each point
    return np.arctan2(d[:, 1], d[:, 0])


def sparse_waypoints(scn: Scenario) -> list[tuple[int, str]]:
    """(route index, label) of the waypoints: lane ends, headland-turn apexes, the end."""
    r = scn.route
    seg = r.segment
    cuts = np.flatnonzero(seg[1:] != seg[:-1]) + 1
    bounds = [0, *cuts.tolist(), len(seg)]
    out: list[tuple[int, str]] = []
    runs = list(itertools.pairwise(bounds))
    for k, (a, b) in enumerate(runs):
        if seg[a] == "furrow":
            lane = int(r.lane[a])
            out += [(a, f"lane {lane} entry"), (b - 1, f"lane {lane} exit")]
        elif 0 < k < len(runs) - 1:  # a turn between two lanes: its apex (and cusps)
            flips = a + np.flatnonzero(np.diff(r.direction[a:b]) != 0) + 1
            if len(flips):
                out += [
                    (int(i), "cusp: reverse" if r.direction[i] < 0 else "cusp: forward")
                    for i in flips
                ]
                continue
            xy = r.xy[a:b]
            chord = xy[-1] - xy[0]
            length = float(np.hypot(*chord))
            if length > 1e-9:
                rel = xy - xy[0]
                dist = np.abs(chord[0] * rel[:, 1] - chord[1] * rel[:, 0]) / length
            else:  # a turn returning to its start: farthest point from it
                dist = np.hypot(*(xy - xy[0]).T)
            out.append((a + int(np.argmax(dist)), "headland turn"))
    if len(seg):
        out.append((len(seg) - 1, "route end"))
    return out


def _reference_path(scn: Scenario, path: Path, yaw: FloatArray) -> None:
    r = scn.route
    lat, lon, alt = scn.geo.enu_to_geodetic(r.xyz[:, 0], r.xyz[:, 1], r.xyz[:, 2])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(r.xy, axis=0).T))])
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            [
                "index",
                "x",
                "y",
                "z",
                "lat",
                "lon",
                "alt",
                "yaw",
                "segment",
                "lane",
                "s",
                "turn",
                "direction",
            ]
        )
        for i in range(len(r)):
            w.writerow(
                [
                    i,
                    f"{r.xyz[i, 0]:.6f}",
                    f"{r.xyz[i, 1]:.6f}",
                    f"{r.xyz[i, 2]:.6f}",
                    f"{lat[i]:.10f}",
                    f"{lon[i]:.10f}",
                    f"{alt[i]:.4f}",
                    f"{yaw[i]:.6f}",
                    r.segment[i],
                    int(r.lane[i]),
                    f"{s[i]:.4f}",
                    r.turn[i],
                    int(r.direction[i]),
                ]
            )


def export_nav2(scn: Scenario, out: Path, opts: ExportOptions) -> dict[str, Any]:
    """Gazebo world + robot + launch + waypoints + reference path into ``out``."""
    from .preview import render_export_preview
    from .readme import nav2_readme

    assert opts.robot_urdf is not None  # checked before the output folder was made
    g = export_gazebo(scn, out, opts)
    config = out / "config"
    config.mkdir()
    (out / "robot").mkdir()
    (out / "launch").mkdir()
    shutil.copyfile(opts.robot_urdf, out / "robot" / "summit_xl.urdf")
    r = scn.route
    yaw = route_yaw(r.xy, r.direction)
    wps = sparse_waypoints(scn)
    idx = np.array([i for i, _ in wps], np.int64)
    lat, lon, _ = scn.geo.enu_to_geodetic(r.xyz[idx, 0], r.xyz[idx, 1], r.xyz[idx, 2])
    gps = {
        "waypoints": [
            {"latitude": float(la), "longitude": float(lo), "yaw": float(yaw[i])}
            for la, lo, i in zip(lat, lon, idx, strict=True)
        ]
    }
    header = (
        f"# {scn.spec.name} seed {scn.seed}: {len(wps)} GPS waypoints for Nav2's GPS waypoint\n"
        "# follower (yaw in radians, ENU: 0 = east, counter-clockwise). In order:\n"
        + "".join(f"#   {k}: {label}\n" for k, (_, label) in enumerate(wps))
    )
    (config / "gps_waypoints.yaml").write_text(header + yaml.safe_dump(gps, sort_keys=False))
    enu = {
        "frame_id": "map",
        "waypoints": [
            {
                "x": round(float(r.xyz[i, 0]), 4),
                "y": round(float(r.xyz[i, 1]), 4),
                "yaw": round(float(yaw[i]), 6),
            }
            for i in idx
        ],
    }
    (config / "waypoints_enu.yaml").write_text(
        "# The same waypoints in the ENU frame at the datum (map frame of navsat_transform.yaml)\n"
        + yaml.safe_dump(enu, sort_keys=False)
    )
    (config / "navsat_transform.yaml").write_text(navsat_yaml(scn))
    _reference_path(scn, out / "reference_path.csv", yaw)
    x0, y0, z0 = r.xyz[0] if len(r) else (0.0, 0.0, 0.0)
    spawn = (float(x0), float(y0), float(z0) + SPAWN_CLEARANCE, float(yaw[0]) if len(r) else 0.0)
    (out / "launch" / "agrinav_field.launch.py").write_text(launch_py(spawn))
    info = {"spawn": spawn, "waypoints": len(wps)}
    (out / "README.md").write_text(nav2_readme(scn, g, info))
    render_export_preview(
        scn, out / "preview.png", gazebo=g, waypoints=(idx, yaw[idx]), spawn=spawn, opts=opts
    )
    return {**g.__dict__, **info}


def navsat_yaml(scn: Scenario) -> str:
    g = scn.geo
    return f"""# robot_localization navsat_transform_node: its map frame = the export's ENU frame
navsat_transform:
  ros__parameters:
    frequency: 10.0
    use_local_cartesian: true   # ENU tangent plane at the datum, not UTM grid axes
    wait_for_datum: true
    datum: [{g.lat:.10f}, {g.lon:.10f}, 0.0]   # lat, lon (deg), heading (rad)
    zero_altitude: true
    yaw_offset: 0.0             # the IMU reads 0 facing east (ENU)
    magnetic_declination_radians: 0.0
    publish_filtered_gps: true
    broadcast_cartesian_transform: false
"""


def launch_py(spawn: tuple[float, float, float, float]) -> str:
    x, y, z, yaw = spawn
    return LAUNCH.replace("@SPAWN@", f"{x:.4f}, {y:.4f}, {z:.4f}, {yaw:.6f}")


LAUNCH = '''"""Gazebo with the AgriNav field and a Summit-XL at the route start (ROS 2 Humble).

    ros2 launch launch/agrinav_field.launch.py               # Gazebo Sim (ros_gz_sim)
    ros2 launch launch/agrinav_field.launch.py sim:=classic  # Gazebo Classic 11 (gazebo_ros)
"""

import os

from ament_index_python.packages import get_package_share_directory as share
from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    IncludeLaunchDescription,
    OpaqueFunction,
    SetEnvironmentVariable,
)
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
MODELS = os.path.join(ROOT, "models")
URDF = os.path.join(ROOT, "robot", "summit_xl.urdf")
SPAWN_X, SPAWN_Y, SPAWN_Z, SPAWN_YAW = @SPAWN@  # route start, ENU metres and radians


def _path(var):
    old = os.environ.get(var, "")
    return MODELS + (os.pathsep + old if old else "")


def _simulator(context, *args, **kwargs):
    sim = LaunchConfiguration("sim").perform(context)
    pose = ["-x", str(SPAWN_X), "-y", str(SPAWN_Y), "-z", str(SPAWN_Z), "-Y", str(SPAWN_YAW)]
    if sim == "classic":
        world = os.path.join(ROOT, "worlds", "field_classic.world")
        gazebo = IncludeLaunchDescription(
            PythonLaunchDescriptionSource(
                os.path.join(share("gazebo_ros"), "launch", "gazebo.launch.py")
            ),
            launch_arguments={"world": world}.items(),
        )
        spawn = Node(
            package="gazebo_ros",
            executable="spawn_entity.py",
            arguments=["-entity", "summit_xl", "-file", URDF, *pose],
            output="screen",
        )
    else:
        world = os.path.join(ROOT, "worlds", "field.sdf")
        gazebo = IncludeLaunchDescription(
            PythonLaunchDescriptionSource(
                os.path.join(share("ros_gz_sim"), "launch", "gz_sim.launch.py")
            ),
            launch_arguments={"gz_args": "-r " + world}.items(),
        )
        spawn = Node(
            package="ros_gz_sim",
            executable="create",
            arguments=["-name", "summit_xl", "-file", URDF, *pose],
            output="screen",
        )
    return [gazebo, spawn]


def generate_launch_description():
    with open(URDF) as f:
        description = f.read()
    return LaunchDescription(
        [
            DeclareLaunchArgument("sim", default_value="gz", description="gz or classic"),
            SetEnvironmentVariable("GAZEBO_MODEL_PATH", _path("GAZEBO_MODEL_PATH")),
            SetEnvironmentVariable("IGN_GAZEBO_RESOURCE_PATH", _path("IGN_GAZEBO_RESOURCE_PATH")),
            SetEnvironmentVariable("GZ_SIM_RESOURCE_PATH", _path("GZ_SIM_RESOURCE_PATH")),
            Node(
                package="robot_state_publisher",
                executable="robot_state_publisher",
                parameters=[{"robot_description": description, "use_sim_time": True}],
                output="screen",
            ),
            OpaqueFunction(function=_simulator),
        ]
    )
'''
