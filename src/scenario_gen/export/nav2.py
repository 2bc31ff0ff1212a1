"""ROS 2 / Nav2: the Gazebo world, GPS waypoints and the reference path, and the runnable
bundle around them (ros_bundle.py: the robot for Gazebo Sim, ros_gz_bridge, robot_localization,
Nav2, the behaviour tree, the route follower and the launch file).

Waypoints are sparse — every lane entry and exit, the apex of every headland turn (and the
cusps of a three-point turn) and the end of the lead-out — since a waypoint follower plans
between them; the 0.1 m reference path is for measuring cross-track error afterwards, not for
driving. Yaw is the way the robot faces: against the direction of travel where the route is
driven backwards. A route planned through the user's GPS waypoints exports those waypoints,
with the yaws the file gave, so that ``agrinav scenario --waypoints`` reads the export back.
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
from .ros_bundle import write_ros_bundle

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
    """(route index, label) of the waypoints: lane ends, headland-turn apexes, the end; for a
    route planned through the user's GPS waypoints (``route.waypoints``), those waypoints."""
    r = scn.route
    goals = scn.info.get("route_goals")
    if goals is not None:
        return [(int(i), f"waypoint {k}") for k, i in enumerate(goals)]
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


def waypoint_yaw(scn: Scenario, idx: np.ndarray, yaw: FloatArray) -> FloatArray:
    """The yaw written with each waypoint: the user's where the route was planned through a
    waypoint file that gave one, else the heading of the leg leaving it (arriving, at the
    last) — not the route's yaw there, which averages the two legs at a corner."""
    out = yaw[idx].copy()
    if scn.info.get("route_goals") is None:
        return out
    given = scn.info.get("route_goal_yaw")
    xy = scn.route.xy
    for k, i in enumerate(idx):
        a, b = (i, i + 1) if i + 1 < len(xy) else (i - 1, i)
        out[k] = np.arctan2(*(xy[b] - xy[a])[::-1])
        if given is not None and given[k] is not None:
            out[k] = given[k]
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
    wp_yaw = waypoint_yaw(scn, idx, yaw)
    lat, lon, _ = scn.geo.enu_to_geodetic(r.xyz[idx, 0], r.xyz[idx, 1], r.xyz[idx, 2])
    gps = {
        "waypoints": [
            {"latitude": float(la), "longitude": float(lo), "yaw": float(y)}
            for la, lo, y in zip(lat, lon, wp_yaw, strict=True)
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
                "yaw": round(float(y), 6),
            }
            for i, y in zip(idx, wp_yaw, strict=True)
        ],
    }
    (config / "waypoints_enu.yaml").write_text(
        "# The same waypoints in the ENU frame at the datum (map frame of navsat_transform.yaml)\n"
        + yaml.safe_dump(enu, sort_keys=False)
    )
    _reference_path(scn, out / "reference_path.csv", yaw)
    x0, y0, z0 = r.xyz[0] if len(r) else (0.0, 0.0, 0.0)
    spawn = (float(x0), float(y0), float(z0) + SPAWN_CLEARANCE, float(yaw[0]) if len(r) else 0.0)
    bundle = write_ros_bundle(scn, out, Path(opts.robot_urdf).read_text(), spawn, opts)
    info = {"spawn": spawn, "waypoints": len(wps), "controller": bundle["controller"]}
    (out / "README.md").write_text(nav2_readme(scn, g, {**info, **bundle}))
    render_export_preview(
        scn, out / "preview.png", gazebo=g, waypoints=(idx, wp_yaw), spawn=spawn, opts=opts
    )
    return {**g.__dict__, **info}
