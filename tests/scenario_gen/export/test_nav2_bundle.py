"""The Nav2 bundle's runnable part, checked without ROS (none is installed here).

- the Summit-XL for Gazebo Sim through libsdformat (tools/sdf_check --robot): sensors at their
  mounts with the env's rates, noise and camera, the drive from the URDF's wheels;
- every parameter name and type in the Nav2, robot_localization and bridge files, and in the
  launch file's parameter dictionaries, against what the Humble packages declare
  (tests/data/ros_humble/, read from their sources; README there);
- the bridge's message pairs against ros_gz_bridge's table and the Gazebo side's messages, and
  its topics against the sensors, the drive and the ROS consumers;
- the behaviour tree's nodes and ports against Nav2 Humble's and BehaviorTree.CPP 3.8's;
- the launch file parsed, then run against stand-in launch/launch_ros modules;
- the route follower's goals against the env's route observation.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib.util
import math
import re
import subprocess
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from scenario_gen import Scenario
from scenario_gen.errors import InputError
from scenario_gen.export import ExportOptions, export
from scenario_gen.export import ros_config as rc
from scenario_gen.export.ros import follow_route, sensor_covariances
from scenario_gen.export.ros_robot import Nav2Robot, camera_image, depth_sigma, imu_sigmas
from scenario_gen.schema import to_mapping

DATA = Path(__file__).resolve().parents[2] / "data" / "ros_humble"
URDF = Path(__file__).resolve().parents[3] / "src" / "agrinav_gym" / "assets" / "summit_xl.urdf"
NAV2 = yaml.safe_load((DATA / "nav2_parameters.yaml").read_text())
RL = yaml.safe_load((DATA / "robot_localization_parameters.yaml").read_text())
BT = yaml.safe_load((DATA / "nav2_bt_nodes.yaml").read_text())
GZ = yaml.safe_load((DATA / "ros_gz.yaml").read_text())
BUILTIN = {"use_sim_time": "bool"}  # every ROS 2 node's own
#: names newer than Humble's first release (1.1.0) the bundle writes, and why an older release
#: still behaves as intended
NEWER_OK = {
    "forward_prune_distance": "before 1.1.7 DWB cut the plan's far end at prune_distance, "
    "which the bundle sets to the same value (checked below)",
}


@pytest.fixture(scope="module")
def bundle(nav2_bundle) -> tuple[Scenario, Path]:
    return nav2_bundle


@pytest.fixture(scope="module")
def robot(bundle) -> Nav2Robot:
    from baselines.nav2_robot import nav2_robot

    return Nav2Robot.from_dict(nav2_robot())


def _yaml(out: Path, rel: str) -> Any:
    return yaml.safe_load((out / rel).read_text())


# ----------------------------------------------------------------------------- names and types


def _type_ok(value: Any, kind: str) -> bool:
    """Would rclcpp accept ``value`` (as YAML gives it) for a parameter declared ``kind``?"""
    scalar = {
        "double": lambda v: isinstance(v, float),
        "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
        "bool": lambda v: isinstance(v, bool),
        "string": lambda v: isinstance(v, str),
    }
    if kind.endswith("_array"):
        each = scalar[kind.removesuffix("_array")]
        return isinstance(value, list) and bool(value) and all(each(v) for v in value)
    return scalar[kind](value)


class Checker:
    """Walks a parameter mapping as Nav2 composes names (plugins, critics, layers, sources)."""

    def __init__(self) -> None:
        self.errors: list[str] = []
        self.used: dict[str, str] = {}  # name -> the release that added it (newer than 1.1.0)

    def _check(self, where: str, key: str, value: Any, entry: dict[str, Any], tkey: str) -> None:
        kind = {**BUILTIN, **entry.get(tkey, {})}.get(key)
        if kind is not None and not _type_ok(value, kind):
            self.errors.append(f"{where}.{key}: {value!r} is not a {kind}")
        if tkey == "types" and key in entry.get("since", {}):  # `since` is of `params`
            self.used[key] = entry["since"][key]

    def params(self, where: str, params: dict[str, Any], entry: dict[str, Any]) -> None:
        allowed = set(entry["params"]) | set(BUILTIN)
        owned: set[str] = set()
        for slot in entry.get("plugin_slots", []):
            names = params.get(slot, [])
            for name in [names] if isinstance(names, str) else names:
                owned.add(name)
                sub = params.get(name)
                if not isinstance(sub, dict) or sub.get("plugin") not in NAV2["plugins"]:
                    self.errors.append(f"{where}.{name}: no plugin of a known type")
                    continue
                self.plugin(f"{where}.{name}", sub, sub["plugin"])
        for key, value in params.items():
            if key in owned:
                continue
            if key not in allowed or isinstance(value, dict):
                self.errors.append(f"{where}.{key}: not declared")
            else:
                self._check(where, key, value, entry, "types")

    def plugin(self, where: str, sub: dict[str, Any], kind: str) -> None:
        entry = NAV2["plugins"][kind]
        allowed = set(entry["params"])
        owned: set[str] = {"plugin"}
        if "critic_slot" in entry:
            for critic in sub.get(entry["critic_slot"], []):
                ce = NAV2["plugins"].get(f"dwb_critics::{critic}Critic")
                if ce is None:
                    self.errors.append(f"{where}: unknown critic {critic}")
                    continue
                allowed |= set(ce.get("controller_params", []))
                for key, value in sub.get(critic, {}).items():
                    if key not in ce["params"]:
                        self.errors.append(f"{where}.{critic}.{key}: not declared")
                    else:
                        self._check(f"{where}.{critic}", key, value, ce, "types")
                owned.add(critic)
                for key in ce.get("controller_params", []):
                    if key in sub:
                        owned.add(key)
                        self._check(where, key, sub[key], ce, "controller_types")
        if "source_slot" in entry:
            for source in str(sub.get(entry["source_slot"], "")).split():
                owned.add(source)
                for key, value in sub.get(source, {}).items():
                    if key not in entry["source_params"]:
                        self.errors.append(f"{where}.{source}.{key}: not declared")
                    else:
                        self._check(f"{where}.{source}", key, value, entry, "source_types")
        for key, value in sub.items():
            if key in owned:
                continue
            if key not in allowed or isinstance(value, dict):
                self.errors.append(f"{where}.{key}: not declared by {kind}")
            else:
                self._check(where, key, value, entry, "types")


NAV2_SECTIONS = {
    "controller_server": "controller_server",
    "planner_server": "planner_server",
    "bt_navigator": "bt_navigator",
    rc.LIFECYCLE: "lifecycle_manager",
}


def check_nav2(doc: dict[str, Any]) -> Checker:
    c = Checker()
    for section, body in doc.items():
        if section == "/**":
            extra = set(body["ros__parameters"]) - set(BUILTIN)
            c.errors += [f"/**.{k}: not a parameter of every node" for k in sorted(extra)]
        elif section in ("local_costmap", "global_costmap"):
            c.params(section, body[section]["ros__parameters"], NAV2["nodes"]["costmap"])
        elif section in NAV2_SECTIONS:
            entry = NAV2["nodes"][NAV2_SECTIONS[section]]
            c.params(section, body["ros__parameters"], entry)
        else:
            c.errors.append(f"{section}: no such node in the bundle")
    return c


SENSOR = re.compile(r"^(odom|pose|twist|imu)(\d+)(_.*)?$")


def check_robot_localization(section: str, params: dict[str, Any], node: str) -> list[str]:
    entry = RL["nodes"][node]
    errors = []
    seen: dict[str, list[int]] = {}
    for key, value in params.items():
        m = SENSOR.match(key)
        if m:
            kind, index, rest = m.group(1), int(m.group(2)), m.group(3) or ""
            name = "{sensor}_config" if rest == "_config" else f"{{{kind}}}{rest}"
            if not rest:
                seen.setdefault(kind, []).append(index)
        else:
            name = key
        kind_of = {**BUILTIN, **entry["types"]}.get(name)
        if name not in entry["params"] and name not in BUILTIN:
            errors.append(f"{section}.{key}: not declared")
        elif kind_of is not None and not _type_ok(value, kind_of):
            errors.append(f"{section}.{key}: {value!r} is not a {kind_of}")
    for kind, indices in seen.items():  # robot_localization stops at the first missing index
        if sorted(indices) != list(range(len(indices))):
            errors.append(f"{section}: {kind} indices {sorted(indices)} do not count from 0")
    return errors


def test_parameter_files_use_names_humble_declares(bundle) -> None:
    _, out = bundle
    used: dict[str, str] = {}
    for rel in ("config/nav2_params.yaml", "config/nav2_params_nav2_defaults.yaml"):
        c = check_nav2(_yaml(out, rel))
        assert c.errors == [], rel
        used.update(c.used)
    assert set(used) <= set(NEWER_OK), used
    for rel in ("config/nav2_params.yaml", "config/nav2_params_nav2_defaults.yaml"):
        fp = _yaml(out, rel)["controller_server"]["ros__parameters"][rc.CONTROLLER]
        assert fp["forward_prune_distance"] == fp["prune_distance"]  # see NEWER_OK
    ekf = _yaml(out, "config/ekf.yaml")
    assert set(ekf) == {"ekf_local", "ekf_global"}
    for name, body in ekf.items():
        assert check_robot_localization(name, body["ros__parameters"], "ekf_node") == []
    nav = _yaml(out, "config/navsat_transform.yaml")
    params = nav["navsat_transform"]["ros__parameters"]
    assert check_robot_localization("navsat", params, "navsat_transform_node") == []


def test_the_checker_catches_misspelt_and_mistyped_keys(robot) -> None:
    good = rc.nav2_params(robot, robot.dwb)
    assert check_nav2(good).errors == []
    bad = yaml.safe_load(yaml.safe_dump(good))
    fp = bad["controller_server"]["ros__parameters"]["FollowPath"]
    fp["PathDist"]["scael"] = 1.0  # misspelt critic parameter
    fp["max_vel_x"] = 1  # an integer where Nav2 declares a double
    fp["stateful"] = True  # Humble's nav2_params.yaml has it; DWB never declares it
    bad["local_costmap"]["local_costmap"]["ros__parameters"]["voxel_layer"]["depth_camera"][
        "min_height"
    ] = 0.1
    errors = check_nav2(bad).errors
    assert len(errors) == 4, errors
    ekf = rc.ekf_params(robot, "map")
    assert check_robot_localization("ekf", {**ekf, "odom3": "/x"}, "ekf_node") != []
    assert check_robot_localization("ekf", {**ekf, "two_d_mode": 1}, "ekf_node") != []


# ----------------------------------------------------------------------------- values


def test_nav2_params_are_the_benchmarked_dwb(bundle, robot) -> None:
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.robot import RobotGeometry, robot_interface
    from policies.dwb.params import DWBParams
    from policies.dwb.policy import resolved_config

    _, out = bundle
    ri = robot_interface(EnvConfig(), RobotGeometry.from_urdf())
    for rel, spec in (("nav2_params.yaml", "furrow"), ("nav2_params_nav2_defaults.yaml", "nav2")):
        doc = _yaml(out, "config/" + rel)
        want = resolved_config(DWBParams.load(spec), ri)
        fp = doc["controller_server"]["ros__parameters"][rc.CONTROLLER]
        for key, value in want["FollowPath"].items():
            if isinstance(value, dict):
                if key in want["FollowPath"]["critics"]:
                    assert fp[key] == value, key
                else:
                    assert key not in fp, key  # a critic not scored declares nothing
            elif key == "limit_vel_cmd_in_traj":
                assert key not in fp  # the code default, unknown before 1.1.17
            else:
                assert fp[key] == value, key
        assert (fp["max_vel_x"], fp["max_vel_theta"], fp["acc_lim_x"]) == (1.0, 1.5, 0.6)
        cm = doc["local_costmap"]["local_costmap"]["ros__parameters"]
        wcm = want["local_costmap"]
        for key in ("update_frequency", "width", "height", "resolution", "footprint_padding"):
            assert cm[key] == wcm[key], key
        assert np.array(yaml.safe_load(cm["footprint"])) == pytest.approx(
            np.array(wcm["footprint"])
        )
        voxel = cm["voxel_layer"]
        for key, value in wcm["voxel_layer"].items():
            if key == "depth_camera":
                src = voxel["depth_camera"]
                assert {k: src[k] for k in value} == value
                assert (src["topic"], src["data_type"]) == (rc.POINTS, "PointCloud2")
            else:
                assert voxel[key] == value, key
        assert voxel["observation_sources"] == "depth_camera"
        assert {k: cm["inflation_layer"][k] for k in wcm["inflation_layer"]} == wcm[
            "inflation_layer"
        ]
        assert (cm["global_frame"], cm["robot_base_frame"]) == ("odom", "base_footprint")
    furrow = _yaml(out, "config/nav2_params.yaml")["local_costmap"]["local_costmap"]
    assert furrow["ros__parameters"]["footprint_padding"] == -0.07
    # the follower's goals fit the rolling global costmap on either side of the robot
    g = _yaml(out, "config/nav2_params.yaml")["global_costmap"]["global_costmap"]
    g = g["ros__parameters"]
    assert min(g["width"], g["height"]) / 2 > robot.route_points * robot.route_spacing
    assert (g["global_frame"], g["rolling_window"], g["plugins"]) == (
        "map",
        True,
        ["inflation_layer"],
    )


def test_localisation_matches_the_simulator(bundle, robot) -> None:
    scn, out = bundle
    ekf = _yaml(out, "config/ekf.yaml")
    loc = robot.localisation
    for name, world in (("ekf_local", "odom"), ("ekf_global", "map")):
        p = ekf[name]["ros__parameters"]
        assert p["frequency"] == robot.drive.control_hz
        assert (p["world_frame"], p["base_link_frame"], p["two_d_mode"]) == (
            world,
            "base_footprint",
            True,
        )
        fused = dict(zip(rc.STATE, p["odom0_config"], strict=True))
        assert [s for s, f in fused.items() if f] == ["vx", "vy"]  # yaw rate from the gyro
        fused = dict(zip(rc.STATE, p["imu0_config"], strict=True))
        assert [s for s, f in fused.items() if f] == ["yaw", "vyaw", "ax", "ay"]
        assert (p["odom0"], p["imu0"]) == (rc.WHEEL_ODOM, rc.IMU)
        q = np.array(p["process_noise_covariance"]).reshape(15, 15)
        assert np.count_nonzero(q - np.diag(np.diag(q))) == 0
        d = dict(zip(rc.STATE, np.diag(q), strict=True))
        # the simulator's robot_localization filter's, which its rows were measured with
        from agrinav_gym.config import EnvConfig

        sim = EnvConfig().localisation.robot_localization.process_noise
        assert tuple(d[s] for s in ("x", "y", "yaw", "vx", "vy", "vyaw", "ax", "ay")) == sim
        assert loc.process_noise == sim
        assert p["history_length"] == loc.history_s
    g = ekf["ekf_global"]["ros__parameters"]
    assert g["odom1"] == rc.ODOM_GPS and "odom1" not in ekf["ekf_local"]["ros__parameters"]
    p0 = np.diag(np.array(g["initial_estimate_covariance"]).reshape(15, 15))
    assert p0[0] == pytest.approx(loc.init_position_sigma**2)
    nav = _yaml(out, "config/navsat_transform.yaml")["navsat_transform"]["ros__parameters"]
    assert nav["frequency"] == robot.gnss.rate_hz
    assert nav["datum"] == pytest.approx([scn.geo.lat, scn.geo.lon, 0.0], abs=1e-10)
    assert (nav["use_local_cartesian"], nav["wait_for_datum"], nav["yaw_offset"]) == (
        True,
        True,
        0.0,
    )


def test_sensor_covariances_are_the_simulators(bundle, robot) -> None:
    _, out = bundle
    cfg = _yaml(out, "config/sensor_covariances.yaml")
    loc = robot.localisation
    orient, rate, accel = sensor_covariances.imu_covariances(cfg["imu"])
    sd = np.sqrt(np.diag(np.array(orient).reshape(3, 3)))
    assert np.degrees(sd) == pytest.approx([0.2, 0.2, 1.0])
    assert np.degrees(np.sqrt(rate[0])) == pytest.approx(loc.gyro_sigma_deg_s)
    assert math.sqrt(accel[8]) == pytest.approx(loc.accel_sigma)
    fix = np.array(sensor_covariances.gps_covariance(cfg["gps"])).reshape(3, 3)
    assert np.sqrt(np.diag(fix)) == pytest.approx([robot.gnss.sigma_h] * 2 + [robot.gnss.sigma_v])
    assert robot.gnss.sigma_h == pytest.approx((0.01 + 0.001) / 1.1774, rel=1e-4)  # RTK 1 ppm
    tw = np.array(sensor_covariances.odom_twist_covariance(cfg["odom"], 1.0, 0.0)).reshape(6, 6)
    assert math.sqrt(tw[0, 0]) == pytest.approx(math.hypot(0.03, 0.1))
    assert math.sqrt(tw[1, 1]) == pytest.approx(loc.lateral_sigma)
    tw = np.array(sensor_covariances.odom_twist_covariance(cfg["odom"], 0.0, 0.0)).reshape(6, 6)
    assert math.sqrt(tw[0, 0]) == pytest.approx(loc.odom_floor)
    # the relay sits between the bridge and robot_localization
    bridged = {e["ros_topic_name"] for e in _yaml(out, "config/bridge.yaml")}
    for raw, cooked in sensor_covariances.TOPICS.values():
        assert raw in bridged
        assert cooked in (rc.IMU, rc.GPS, rc.WHEEL_ODOM)


def test_nav2_robot_defaults_are_the_envs() -> None:
    from baselines.nav2_robot import nav2_robot

    built = nav2_robot()
    defaults = to_mapping(Nav2Robot())
    for section in ("drive", "camera", "imu", "gnss", "localisation"):
        for key, value in defaults[section].items():
            if value == "":  # named in agrinav_gym only (tests/test_vocabulary.py)
                continue
            want = value if isinstance(value, (str, bool)) else pytest.approx(value, rel=2e-3)
            assert built[section][key] == want, f"{section}.{key}"
    assert built["controller"] == "dwb:furrow"
    assert nav2_robot(dwb="nav2")["controller"] == "dwb:nav2"


def test_nav2_export_needs_the_robot(dem, tmp_path) -> None:
    _, src = dem
    out = tmp_path / "out"
    with pytest.raises(InputError, match="nav2_robot"):
        export(src, "nav2", out, ExportOptions(robot_urdf=str(URDF)))
    bad = {"robot_urdf": str(URDF), "nav2_robot": {"dwb": {"FollowPath": {}}}}
    with pytest.raises(InputError, match="nav2_robot.dwb"):
        export(src, "nav2", out, ExportOptions.from_dict(bad))
    assert not out.exists()


# ----------------------------------------------------------------------------- robot


def _robot_check(exe: Path, urdf: Path) -> dict[str, list[list[str]]]:
    r = subprocess.run([str(exe), "--robot", str(urdf)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.rstrip().endswith("Valid.")
    lines: dict[str, list[list[str]]] = {}
    for line in r.stdout.splitlines():
        kind, *rest = line.split()
        lines.setdefault(kind, []).append(rest)
    return lines


def _quat(rpy_pitch: float) -> list[float]:
    return [math.cos(rpy_pitch / 2), 0.0, math.sin(rpy_pitch / 2), 0.0]


def test_robot_loads_in_libsdformat_with_sensors_and_drive(bundle, robot, sdf_check) -> None:
    _, out = bundle
    got = _robot_check(sdf_check, out / "robot" / "summit_xl_gazebo.urdf")
    assert got["robot"] == [["summit_xl", "base_footprint"]]
    sensors = {s[0]: s for s in got["sensor"]}
    assert set(sensors) == {"imu", "navsat", "depth_camera"}
    base = 0.11  # base_link above base_footprint: the wheel radius
    c, g = robot.camera, robot.gnss
    want = {  # name: type, x, z, pitch, rate, topic, frame
        "depth_camera": ("depth_camera", c.x, c.z + base, math.radians(c.pitch_deg), c.rate_hz),
        "navsat": ("navsat", g.antenna_x, g.antenna_z + base, 0.0, g.rate_hz),
        "imu": ("imu", 0.0, 0.05 + base, 0.0, robot.imu.rate_hz),
    }
    frames = {"depth_camera": "camera_link", "navsat": "gps_link", "imu": "imu_link"}
    bridge = {e["gz_topic_name"]: e for e in _yaml(out, "config/bridge.yaml")}
    for name, (kind, x, z, pitch, rate) in want.items():
        s = sensors[name]
        assert s[1] == kind and s[2] == "base_footprint"
        pose = np.array(s[3:10], float)
        assert pose[:3] == pytest.approx([x, 0.0, z], abs=1e-9), name
        assert pose[3:] == pytest.approx(_quat(pitch), abs=1e-6), name
        assert float(s[10]) == rate and s[12] == frames[name]
        assert s[11] in bridge, name  # every sensor's topic is bridged
    # the depth camera: the env's width and both fields of view, square pixels
    (cam,) = got["camera"]
    hfov, width, height = float(cam[1]), int(cam[2]), int(cam[3])
    assert (width, height) == camera_image(c)[:2] == (64, 37)
    assert math.degrees(hfov) == pytest.approx(c.hfov_deg)
    vfov = 2 * math.atan(math.tan(hfov / 2) * height / width)
    assert math.degrees(vfov) == pytest.approx(c.vfov_deg, abs=1.0)
    assert cam[4] == "R_FLOAT32"
    assert [float(v) for v in cam[5:9]] == [c.min_range, c.max_range] * 2
    assert float(cam[9]) == pytest.approx(depth_sigma(c, 2.5))
    assert 0.005 < float(cam[9]) < 0.01  # D455 at 2.5 m: z²·s/(f·B)
    (imu,) = got["imu"]
    gyro, accel = imu_sigmas(robot.imu)
    assert imu[1] == "ENU"
    assert [float(v) for v in imu[2:]] == pytest.approx([gyro] * 3 + [accel] * 3)
    assert gyro == pytest.approx(math.radians(0.01) * math.sqrt(20))
    (nav,) = got["navsat"]
    scn, _ = bundle
    north = scn.geo.enu_to_geodetic(0.0, 1.0, 0.0)[0] - scn.geo.enu_to_geodetic(0.0, 0.0, 0.0)[0]
    assert float(nav[1]) / north == pytest.approx(g.sigma_h, rel=1e-6)  # degrees -> metres
    assert float(nav[2]) == pytest.approx(g.sigma_v)
    # tyres: the soil's traction coefficient on the four wheels
    friction = {f[0]: f[2:] for f in got["friction"] if f[0].endswith("wheel")}
    assert len(friction) == 4
    assert all(float(m) == robot.drive.friction for mu in friction.values() for m in mu)
    # the drive: the URDF's wheels, track and radius, the bundle's topics and frames
    joints = {j[0]: j for j in got["joint"]}
    assert {j[1] for j in joints.values()} == {"revolute"} and len(joints) == 4
    assert all(j[4:] == ["0", "1", "0"] for j in joints.values())
    params: dict[str, list[str]] = {}
    for name, key, value in got["plugin_param"]:
        params.setdefault(f"{name.rsplit(':', 1)[-1]}.{key}", []).append(value)
    assert params["DiffDrive.left_joint"] == ["front_left_wheel_joint", "back_left_wheel_joint"]
    assert params["DiffDrive.right_joint"] == ["front_right_wheel_joint", "back_right_wheel_joint"]
    assert float(params["DiffDrive.wheel_separation"][0]) == pytest.approx(0.47)
    assert float(params["DiffDrive.wheel_radius"][0]) == pytest.approx(0.11)
    assert params["DiffDrive.child_frame_id"] == ["base_footprint"]
    assert float(params["DiffDrive.max_linear_acceleration"][0]) == robot.drive.a_max
    assert float(params["DiffDrive.odom_publish_frequency"][0]) == robot.drive.control_hz
    for key in ("DiffDrive.topic", "DiffDrive.odom_topic", "JointStatePublisher.topic"):
        assert params[key][0] in bridge, key
    assert params["DiffDrive.tf_topic"][0] not in bridge  # robot_localization owns odom -> base


def test_gazebo_urdf_is_the_simulators_plus_gazebo(bundle) -> None:
    _, out = bundle
    plain = ET.parse(out / "robot" / "summit_xl.urdf").getroot()
    gz = ET.parse(out / "robot" / "summit_xl_gazebo.urdf").getroot()

    def joints(root: ET.Element) -> dict[str, tuple[str, ...]]:
        return {
            str(j.get("name")): (
                str(j.get("type")),
                str(j.find("parent").get("link")),  # type: ignore[union-attr]
                str(j.find("child").get("link")),  # type: ignore[union-attr]
            )
            for j in root.iter("joint")
        }

    links = {str(x.get("name")) for x in gz.iter("link")}
    assert {str(x.get("name")) for x in plain.iter("link")} | {"base_footprint"} == links
    assert joints(gz) == {
        **joints(plain),
        "base_footprint_joint": ("fixed", "base_footprint", "base_link"),
    }
    origin = gz.find("joint[@name='base_footprint_joint']/origin")
    assert origin is not None and origin.get("xyz") == "0 0 0.11"
    # the same geometry everywhere else (the camera and antenna mounts are the env's defaults)
    for link in plain.iter("link"):
        other = gz.find(f"link[@name='{link.get('name')}']")
        assert other is not None
        same = [ET.canonicalize(ET.tostring(x), strip_text=True) for x in (link, other)]
        assert same[0] == same[1], link.get("name")


def test_world_has_the_systems_the_sensors_need(bundle, sdf_check) -> None:
    from .tools import run_check

    _, out = bundle
    world = out / "worlds" / "field.sdf"
    check = run_check(sdf_check, world, out / "models")
    assert check.valid, check.stderr
    names = {p.get("name") for p in ET.parse(world).getroot().iter("plugin")}
    for system in ("Sensors", "Imu", "NavSat", "Physics", "SceneBroadcaster", "UserCommands"):
        assert f"ignition::gazebo::systems::{system}" in names


# ----------------------------------------------------------------------------- bridge


def test_bridge_is_valid_for_humble_and_wired(bundle, sdf_check) -> None:
    _, out = bundle
    entries = _yaml(out, "config/bridge.yaml")
    got = _robot_check(sdf_check, out / "robot" / "summit_xl_gazebo.urdf")
    gz_msg = {"/clock": GZ["gazebo"]["world"]["/clock"]}  # gz topic -> message on it
    for s in got["sensor"]:
        kind, topic = s[1], s[11]
        for elem, msg in GZ["gazebo"]["sensors"][kind].items():
            if elem == "topic":
                gz_msg[topic] = msg
            elif elem == "topic/points":
                gz_msg[topic + "/points"] = msg
            elif elem == "camera_info":
                gz_msg[topic.rsplit("/", 1)[0] + "/camera_info"] = msg
    systems = {p[1]: p[0] for p in got["plugin"]}
    for name, key, value in got["plugin_param"]:
        msg = GZ["gazebo"]["systems"].get(name, {}).get(key)
        if msg is not None:
            gz_msg[value] = msg
    assert len(systems) == 2
    for e in entries:
        assert set(e) <= set(GZ["config_keys"]) and e["direction"] in GZ["directions"]
        prefix, _, name = e["gz_type_name"].rpartition(".")
        assert prefix in ("gz.msgs", "ignition.msgs")
        assert name in GZ["mappings"][e["ros_type_name"]], e  # a pair the bridge converts
        assert gz_msg.get(e["gz_topic_name"]) == name, e  # what Gazebo sends or takes there
    by_ros = {e["ros_topic_name"]: e for e in entries}
    assert by_ros["/clock"]["direction"] == "GZ_TO_ROS"
    assert by_ros[rc.CMD_VEL]["direction"] == "ROS_TO_GZ"  # controller_server's cmd_vel
    # the cloud the voxel layer marks with
    nav = _yaml(out, "config/nav2_params.yaml")["local_costmap"]["local_costmap"]
    src = nav["ros__parameters"]["voxel_layer"]["depth_camera"]
    assert by_ros[src["topic"]]["ros_type_name"] == "sensor_msgs/msg/PointCloud2"
    assert not any(e["gz_topic_name"].endswith("/tf") for e in entries)


# ----------------------------------------------------------------------------- behaviour tree


@pytest.mark.parametrize("navigator", sorted(rc.TREES))
def test_behavior_tree_uses_humble_nodes_and_ports(bundle, navigator) -> None:
    _, out = bundle
    name, _, compute, _ = rc.TREES[navigator]
    root = ET.parse(out / "behavior_trees" / name).getroot()
    trees = root.findall("BehaviorTree")
    assert root.tag == "root" and [t.get("ID") for t in trees] == [root.get("main_tree_to_execute")]
    nav2, builtin = BT["nav2_behavior_tree"], BT["behaviortree_cpp_v3"]
    params = _yaml(out, "config/nav2_params.yaml")
    ids = {
        "planner_id": params["planner_server"]["ros__parameters"]["planner_plugins"],
        "controller_id": params["controller_server"]["ros__parameters"]["controller_plugins"],
        "goal_checker_id": params["controller_server"]["ros__parameters"]["goal_checker_plugins"],
    }
    used = set()
    for node in trees[0].iter():
        if node is trees[0]:
            continue
        spec = nav2.get(node.tag) or builtin.get(node.tag)
        assert spec is not None, node.tag
        assert "since" not in spec, node.tag  # registered by every Humble release
        ports = set(spec["ports"]) - set(spec.get("ports_since_1_1_0", []))
        assert set(node.attrib) - {"name"} <= ports, node.tag
        for key, value in node.attrib.items():
            if key in ids:
                assert value in ids[key], (key, value)
            if key == "service_name":  # <costmap>/clear_entirely_<costmap>
                costmap = value.split("/")[0]
                assert value == f"{costmap}/clear_entirely_{costmap}" and costmap in params
        used.add(node.tag)
    assert {compute, "FollowPath", "ClearEntireCostmap"} <= used
    # nothing that needs an action server the bundle does not start (bt_navigator waits for
    # every server of both trees when it loads them)
    servers = {"ComputePathThroughPoses", "ComputePathToPose", "FollowPath"}
    assert {t for t in used if "server_name" in nav2.get(t, {}).get("ports", [])} <= servers


# ----------------------------------------------------------------------------- launch


class Stub:
    """Stands in for a launch or launch_ros action: keeps what it was given."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


class Config(Stub):
    def perform(self, context: dict[str, str]) -> str:
        return context[self.args[0]]


def _load_launch(path: Path, monkeypatch: pytest.MonkeyPatch) -> Any:
    modules = {
        "launch": {"LaunchDescription": Stub},
        "launch.actions": {
            n: type(n, (Stub,), {})
            for n in (
                "DeclareLaunchArgument",
                "ExecuteProcess",
                "IncludeLaunchDescription",
                "OpaqueFunction",
                "SetEnvironmentVariable",
            )
        },
        "launch.launch_description_sources": {"PythonLaunchDescriptionSource": Stub},
        "launch.substitutions": {"LaunchConfiguration": Config},
        "launch_ros": {},
        "launch_ros.actions": {"Node": type("Node", (Stub,), {})},
        "ament_index_python": {},
        "ament_index_python.packages": {
            "get_package_share_directory": lambda pkg: f"/opt/ros/humble/share/{pkg}"
        },
    }
    for name, attrs in modules.items():
        mod = types.ModuleType(name)
        for k, v in attrs.items():
            setattr(mod, k, v)
        monkeypatch.setitem(sys.modules, name, mod)
    spec = importlib.util.spec_from_file_location("agrinav_field_launch", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _actions(module: Any, **given: str) -> tuple[list[Any], dict[str, str]]:
    ld = module.generate_launch_description()
    (items,) = ld.args
    args = {
        a.args[0]: a.kwargs["default_value"]
        for a in items
        if type(a).__name__.startswith("Declare")
    }
    context = {**args, **given}
    (opaque,) = [a for a in items if type(a).__name__ == "OpaqueFunction"]
    return opaque.kwargs["function"](context), context


def test_launch_file_starts_the_whole_stack(bundle, monkeypatch) -> None:
    scn, out = bundle
    path = out / "launch" / "agrinav_field.launch.py"
    ast.parse(path.read_text())
    module = _load_launch(path, monkeypatch)
    actions, context = _actions(module)
    assert context == {
        "sim": "gz",
        "controller": "benchmarked",
        "headless": "false",
        "follow": "true",
        "record": "",
    }
    nodes = [a for a in actions if type(a).__name__ == "Node"]
    started = {(n.kwargs["package"], n.kwargs["executable"], n.kwargs.get("name")) for n in nodes}
    assert started == {
        ("ros_gz_sim", "create", None),
        ("ros_gz_bridge", "parameter_bridge", None),
        ("robot_state_publisher", "robot_state_publisher", None),
        ("robot_localization", "ekf_node", "ekf_local"),
        ("robot_localization", "ekf_node", "ekf_global"),
        ("robot_localization", "navsat_transform_node", "navsat_transform"),
        ("nav2_controller", "controller_server", "controller_server"),
        ("nav2_planner", "planner_server", "planner_server"),
        ("nav2_bt_navigator", "bt_navigator", "bt_navigator"),
        ("nav2_lifecycle_manager", "lifecycle_manager", rc.LIFECYCLE),
    }
    nav2_file = out / "config" / "nav2_params.yaml"
    nav2 = _yaml(out, "config/nav2_params.yaml")
    for n in nodes:
        name, pkg = n.kwargs.get("name"), n.kwargs["package"]
        for p in n.kwargs.get("parameters", []):
            if isinstance(p, str):  # a parameter file: it exists and has this node's section
                assert Path(p).is_file(), p
                if pkg.startswith("nav2") or pkg == "robot_localization":
                    assert name in yaml.safe_load(Path(p).read_text()), (name, p)
                continue
            assert p.get("use_sim_time", True) is True
            extra = {k: v for k, v in p.items() if k != "use_sim_time"}
            if not extra:
                continue
            if pkg == "nav2_bt_navigator":
                c = Checker()
                c.params("bt_navigator", extra, NAV2["nodes"]["bt_navigator"])
                assert c.errors == []
                trees = {
                    "default_nav_through_poses_bt_xml": "follow_route.xml",
                    "default_nav_to_pose_bt_xml": "navigate_to_pose.xml",
                }
                for key, tree in trees.items():
                    assert Path(extra[key]) == out / "behavior_trees" / tree
            elif pkg == "ros_gz_bridge":
                assert set(extra) <= set(GZ["parameter_bridge"]["params"])
                assert Path(extra["config_file"]) == out / "config" / "bridge.yaml"
            elif pkg == "robot_state_publisher":
                assert (
                    extra["robot_description"]
                    == (out / "robot" / "summit_xl_gazebo.urdf").read_text()
                )
            else:
                raise AssertionError(f"{pkg} takes no parameter dictionary here")
        if pkg.startswith("nav2"):
            assert n.kwargs["parameters"][0] == str(nav2_file)
    lifecycle = nav2[rc.LIFECYCLE]["ros__parameters"]["node_names"]
    assert sorted(lifecycle) == sorted(
        n.kwargs["name"]
        for n in nodes
        if n.kwargs["package"] in ("nav2_controller", "nav2_planner", "nav2_bt_navigator")
    )
    # the spawn: base_footprint (the model's root) 2 cm above the ground at the route start
    (create,) = [n for n in nodes if n.kwargs["executable"] == "create"]
    argv = create.kwargs["arguments"]
    flags = {argv[i].lstrip("-"): argv[i + 1] for i in range(0, len(argv), 2)}
    assert set(flags) <= set(GZ["create_flags"])
    assert Path(flags["file"]) == out / "robot" / "summit_xl_gazebo.urdf"
    r = scn.route
    assert float(flags["z"]) == pytest.approx(r.xyz[0, 2] + 0.02, abs=1e-4)
    assert (float(flags["x"]), float(flags["y"])) == pytest.approx(tuple(r.xyz[0, :2]), abs=1e-4)
    # remappings line up with the EKFs and navsat_transform
    remaps = {n.kwargs.get("name"): dict(n.kwargs.get("remappings", [])) for n in nodes}
    assert remaps["ekf_local"]["odometry/filtered"] == rc.ODOM_LOCAL
    assert remaps["ekf_global"]["odometry/filtered"] == rc.ODOM_GLOBAL
    assert remaps["navsat_transform"] == {
        "imu": rc.IMU,
        "gps/fix": rc.GPS,
        "odometry/filtered": rc.ODOM_GLOBAL,
        "odometry/gps": rc.ODOM_GPS,
        "gps/filtered": rc.GPS_FILTERED,
    }
    assert nav2["controller_server"]["ros__parameters"]["odom_topic"] == rc.ODOM_LOCAL
    # the bundle's own programs and Gazebo
    procs = [a.kwargs["cmd"] for a in actions if type(a).__name__ == "ExecuteProcess"]
    scripts = sorted(Path(c[1]).name for c in procs)
    assert scripts == ["follow_route.py", "sensor_covariances.py"]
    for cmd in procs:
        assert Path(cmd[1]).is_file() and cmd[-2:] == ["-p", "use_sim_time:=true"]
        ast.parse(Path(cmd[1]).read_text())
    (follow,) = [c for c in procs if c[1].endswith("follow_route.py")]
    args = follow_route.parse_args(follow[2 : follow.index("--ros-args")])
    assert (args.points, args.spacing) == (10, 0.4)
    (gz,) = [a for a in actions if type(a).__name__ == "IncludeLaunchDescription"]
    assert dict(gz.kwargs["launch_arguments"])["gz_args"] == f"-r {out / 'worlds' / 'field.sdf'}"
    # the alternatives
    actions, _ = _actions(module, controller="nav2_defaults", headless="true", follow="false")
    nav = [
        a for a in actions if type(a).__name__ == "Node" and a.kwargs["package"].startswith("nav2")
    ]
    assert {n.kwargs["parameters"][0] for n in nav} == {
        str(out / "config" / "nav2_params_nav2_defaults.yaml")
    }
    assert all("follow_route.py" not in str(a.kwargs.get("cmd")) for a in actions)
    actions, _ = _actions(module, sim="classic")
    assert {type(a).__name__ for a in actions} == {"IncludeLaunchDescription", "Node"}
    assert any(a.kwargs.get("executable") == "spawn_entity.py" for a in actions)


# ----------------------------------------------------------------------------- follower


def test_follower_goals_are_the_route_observation(bundle) -> None:
    from agrinav_gym.routes import Tracker, scenario_route

    scn, out = bundle
    route = follow_route.load_route(out / "reference_path.csv")
    ref = scenario_route(scn)
    assert route.length == pytest.approx(ref.length, abs=1e-3)
    k, spacing = 10, 0.4
    offsets = spacing * np.arange(1, k + 1)
    for s0 in np.linspace(0.0, route.length - 0.05, 40):
        goals = follow_route.goals_ahead(route, float(s0), k, spacing)
        inside = offsets[s0 + offsets < route.length - 1e-9]
        pts, _ = ref.lookup(s0 + inside)
        assert np.array(goals)[: len(inside), :2] == pytest.approx(pts, abs=5e-3)
        if len(inside) < k:  # the window reaches past the end: it ends there
            assert goals[-1] == route.pose_at(route.length)
            assert len(goals) == len(inside) + 1
    # the tracker: the same arc length and cross-track error as the benchmark's
    rng = np.random.default_rng(0)
    theirs, mine = Tracker(ref), follow_route.Tracker(route)
    theirs.reset(*ref.xy[0])
    for s in np.linspace(0.0, ref.length, 400):
        x, y = ref.sample(np.array([s]))[0] + rng.normal(0, 0.05, 2)
        cte, arc, _ = theirs.update(x, y)
        assert mine.update(x, y) == pytest.approx((cte, arc), abs=1e-6)
    # the GPS check compares each waypoint with its ENU position
    wps = follow_route.load_waypoints(
        out / "config" / "gps_waypoints.yaml", out / "config" / "waypoints_enu.yaml"
    )
    x, y = np.array([w[2:] for w in wps]).T
    lat, lon, _ = scn.geo.enu_to_geodetic(x, y, np.zeros_like(x))
    assert np.array([w[:2] for w in wps]) == pytest.approx(np.column_stack([lat, lon]), abs=1e-8)
    assert follow_route.yaw_quaternion(math.pi / 2) == pytest.approx(
        (0, 0, math.sqrt(0.5), math.sqrt(0.5))
    )


def test_bundle_readme_says_what_was_verified(bundle, robot) -> None:
    _, out = bundle
    text = (out / "README.md").read_text()
    for phrase in (
        "never been run with ROS",
        "launch/agrinav_field.launch.py",
        "libsdformat",
        "tests/data/ros_humble",
        "Gazebo Classic",
        "1.1.7",
        robot.controller,
    ):
        assert phrase in text, phrase


def test_nav2_robot_round_trips_as_options() -> None:
    from baselines.nav2_robot import nav2_options

    opts = ExportOptions.from_dict(nav2_options())
    assert opts.robot_urdf is not None and Path(opts.robot_urdf).is_file()
    robot = Nav2Robot.from_dict(opts.nav2_robot or {})
    assert dataclasses.asdict(robot)["dwb"]["FollowPath"]["prune_distance"] == 0.8
