"""The simulated robot as the Nav2 bundle needs it, and its description for Gazebo Sim.

``Nav2Robot`` is plain data: the Summit-XL's drive limits, its sensors (rates, noise, mounts)
and the EKF's measurement model as agrinav_gym simulates them, and the DWB configuration as
benchmarked. ``scenario_gen`` cannot read agrinav_gym's config or the policies' YAML (imports
point the other way), so the caller builds it — the CLI through ``baselines.nav2_robot`` — and
passes it in ``ExportOptions.nav2_robot``. The defaults here are the env's defaults
(``tests/scenario_gen/export/test_nav2_bundle.py`` checks that they agree).

``gazebo_urdf`` adds to the packaged URDF what Gazebo Sim needs to drive and sense it: a
``base_footprint`` root on the ground under the wheels (REP 120; robot_localization's
``two_d_mode`` keeps it on the odometry plane, so the depth cloud's heights are heights above
the wheels' plane as the benchmark's costmap measures them), the camera and antenna mounts from
the env's config, a NavSat, an IMU and the D455 depth camera, tyre friction, the skid-steer
drive and a joint-state publisher.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Any

from ..errors import InputError
from ..schema import from_mapping
from ..schema import param as _f

#: Gazebo topics of the robot (the bridge maps them to ROS topics: ros_bridge.py)
GZ_IMU = "/agrinav/imu"
GZ_NAVSAT = "/agrinav/navsat"
GZ_DEPTH = "/agrinav/depth_camera"  # image; the cloud is GZ_DEPTH + "/points"
GZ_CMD_VEL = "/agrinav/cmd_vel"
GZ_ODOM = "/agrinav/wheel_odometry"
GZ_DRIVE_TF = "/agrinav/wheel_odometry/tf"  # the drive's own odom transform: not bridged
GZ_JOINTS = "/agrinav/joint_states"
MODEL_NAME = "summit_xl"
#: ROS frames
BASE = "base_footprint"
ODOM = "odom"
MAP = "map"
IMU_FRAME = "imu_link"
GPS_FRAME = "gps_link"
CAMERA_FRAME = "camera_link"
WHEELS = ("front_left_wheel", "back_left_wheel", "front_right_wheel", "back_right_wheel")


@dataclass(frozen=True)
class DriveSetup:
    control_hz: int = _f(
        20, "control rate: Nav2's controller, the EKFs, wheel odometry, Hz", 1, 200
    )
    v_max: float = _f(1.0, "forward speed limit the controller samples, m/s", 0.05, 1.5)
    w_max: float = _f(1.5, "yaw-rate limit, rad/s", 0.05, 3.0)
    a_max: float = _f(0.6, "linear acceleration limit, m/s²", 0.01, 10)
    alpha_max: float = _f(1.5, "angular acceleration limit, rad/s²", 0.01, 50)
    skid_factor: float = _f(
        2.107, "the sim's track multiplier χ (commanded yaw rates met on its soil)", 1.0, 10
    )
    friction: float = _f(0.6, "tyre–soil traction coefficient μ of the sim's soil", 0.05, 3)


@dataclass(frozen=True)
class CameraSetup:
    width: int = _f(64, "the env's depth image width, pixels", 8, 1280)
    height: int = _f(48, "the env's depth image height, pixels", 6, 800)
    hfov_deg: float = _f(87.0, "horizontal field of view", 10, 170)
    vfov_deg: float = _f(58.0, "vertical field of view", 10, 170)
    min_range: float = _f(0.4, "closest valid depth, m", 0.0, 10)
    max_range: float = _f(6.0, "farthest valid depth, m", 0.5, 50)
    rate_hz: int = _f(20, "frame rate, Hz", 1, 200)
    x: float = _f(0.25, "mount ahead of base_link, m", -1, 1)
    z: float = _f(0.55, "mount above base_link, m", 0.1, 3)
    pitch_deg: float = _f(25.0, "pitch below the horizon", -30, 90)
    subpixel: float = _f(0.08, "stereo subpixel accuracy s in σ = z²·s/(f·B)", 0.0, 1)
    baseline: float = _f(0.095, "stereo baseline B, m", 0.01, 1)
    native_width: int = _f(1280, "sensor width whose focal length sets the noise, pixels", 64, 4096)


@dataclass(frozen=True)
class ImuSetup:
    rate_hz: int = _f(20, "sample rate (the sim reads it every control step), Hz", 1, 2000)
    gyro_noise_deg_s_rthz: float = _f(0.01, "gyro noise density, °/s/√Hz", 0, 10)
    accel_noise_ug_rthz: float = _f(60.0, "accelerometer noise density, µg/√Hz", 0, 1e5)


@dataclass(frozen=True)
class GnssSetup:
    rate_hz: int = _f(10, "fix rate, Hz", 1, 20)
    sigma_h: float = _f(0.00934, "horizontal error std per axis of the best fix mode, m", 0, 100)
    sigma_v: float = _f(0.00934, "vertical error std of the best fix mode, m", 0, 100)
    mode: str = _f("", "the receiver's best fix mode, agrinav_gym's name (for the README)")
    antenna_x: float = _f(-0.25, "antenna ahead of base_link (negative: behind), m", -1, 1)
    antenna_z: float = _f(0.60, "antenna above base_link, m", 0, 3)


@dataclass(frozen=True)
class LocalisationSetup:
    """The filter the simulator runs as ``robot_localization``: its process noise, and the
    sensor noise models that set the measurement covariances (agrinav_gym LocalisationConfig)."""

    init_position_sigma: float = _f(0.5, "start position std without a fix, m", 0.0, 100)
    init_yaw_sigma_deg: float = _f(3.0, "start heading std, degrees", 0.0, 180)
    process_noise: tuple[float, float, float, float, float, float, float, float] = _f(
        (0.05, 0.05, 0.06, 0.025, 0.025, 0.02, 0.01, 0.01),
        "process_noise_covariance diagonal for x, y, yaw, vx, vy, vyaw, ax, ay, per second: the "
        "simulator's robot_localization filter's (default: the node's Humble default)",
        0.0,
        100.0,
    )
    odom_speed_rel: float = _f(0.03, "odometry speed std relative to speed", 0.0, 1.0)
    odom_scale_sigma: float = _f(0.1, "odometry speed scale error std", 0.0, 1.0)
    odom_yaw_rel: float = _f(0.15, "odometry yaw-rate std relative to it", 0.0, 1.0)
    odom_floor: float = _f(0.01, "odometry speed and yaw-rate std floor, m/s, rad/s", 1e-4, 1)
    lateral_sigma: float = _f(0.05, "std of the skid-steer's zero lateral velocity, m/s", 1e-3, 10)
    gyro_sigma_deg_s: float = _f(0.05, "gyro yaw-rate std at the control rate, °/s", 1e-4, 10)
    use_accel: bool = _f(True, "fuse the accelerometer's horizontal specific force")
    accel_sigma: float = _f(0.05, "accelerometer std after removing gravity, m/s²", 1e-3, 10)
    roll_pitch_sigma_deg: float = _f(0.2, "IMU roll and pitch error std, degrees", 0.0, 10)
    heading_sigma_deg: float = _f(1.0, "IMU heading error std, degrees", 0.0, 45)
    history_s: float = _f(1.0, "oldest measurement the filter re-applies, s", 0.05, 10)


@dataclass(frozen=True)
class Nav2Robot:
    """What the Nav2 bundle takes from the simulator and the benchmarked controller."""

    drive: DriveSetup = dc_field(default_factory=DriveSetup)
    camera: CameraSetup = dc_field(default_factory=CameraSetup)
    imu: ImuSetup = dc_field(default_factory=ImuSetup)
    gnss: GnssSetup = dc_field(default_factory=GnssSetup)
    localisation: LocalisationSetup = dc_field(default_factory=LocalisationSetup)
    route_points: int = _f(
        10, "route poses ahead the follower sends (the route observation)", 1, 100
    )
    route_spacing: float = _f(0.4, "arc length between them, m", 0.05, 10)
    controller: str = _f("dwb:furrow", "the benchmarked DWB configuration's name")
    dwb: dict[str, Any] = _f(
        {}, "that configuration (policies' DWB layout, the robot's values filled in)"
    )
    dwb_reference: dict[str, Any] = _f(
        {}, "Nav2 Humble's defaults in the same layout (dwb:nav2), for the alternative file"
    )

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Nav2Robot:
        robot: Nav2Robot = from_mapping(cls, data, "nav2_robot.")
        for name in ("dwb", "dwb_reference"):
            value = getattr(robot, name)
            if not isinstance(value.get("FollowPath"), dict) or not isinstance(
                value.get("local_costmap"), dict
            ):
                raise InputError(
                    f"nav2_robot.{name}",
                    sorted(value),
                    "allowed: a DWB configuration with FollowPath and local_costmap sections "
                    "(baselines.nav2_robot builds it)",
                )
        return robot


# ----------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class UrdfGeometry:
    """The wheel geometry of a skid-steer URDF: what the drive plugin needs."""

    wheel_radius: float
    track: float
    wheelbase: float
    left: tuple[str, ...]  # wheel joints, front to back
    right: tuple[str, ...]


def _origin(joint: ET.Element) -> tuple[float, ...]:
    o = joint.find("origin")
    xyz = (o.get("xyz") if o is not None else None) or "0 0 0"
    return tuple(float(v) for v in xyz.split())


def urdf_geometry(root: ET.Element) -> UrdfGeometry:
    joints = {str(j.get("name")): j for j in root.iter("joint")}
    wheels = {}
    for name in WHEELS:
        joint = joints.get(f"{name}_joint")
        cyl = root.find(f".//link[@name='{name}']/visual/geometry/cylinder")
        if joint is None or cyl is None:
            raise InputError("robot_urdf", name, "allowed: a URDF with the Summit-XL's wheels")
        wheels[name] = (_origin(joint), float(str(cyl.get("radius"))))
    (fl, r), (bl, _), (fr, _), _ = (wheels[n] for n in WHEELS)
    return UrdfGeometry(
        r,
        fl[1] - fr[1],
        fl[0] - bl[0],
        ("front_left_wheel_joint", "back_left_wheel_joint"),
        ("front_right_wheel_joint", "back_right_wheel_joint"),
    )


def camera_image(c: CameraSetup) -> tuple[int, int, float]:
    """(width, height, horizontal FOV in rad) of Gazebo's depth camera.

    Gazebo's depth camera has square pixels (Fortress ignores lens intrinsics for depth
    cameras), while the env's 64 × 48 image spans 87° × 58° with fx ≠ fy. The bundle keeps the
    width and both fields of view: the height is the width × tan(vfov/2)/tan(hfov/2)."""
    hfov = math.radians(c.hfov_deg)
    ratio = math.tan(math.radians(c.vfov_deg) / 2) / math.tan(hfov / 2)
    return c.width, max(1, round(c.width * ratio)), hfov


def depth_sigma(c: CameraSetup, z: float) -> float:
    """The D455 model's z-depth noise std at depth ``z``: z²·s/(f·B) (the env's camera)."""
    f = 0.5 * c.native_width / math.tan(math.radians(c.hfov_deg) / 2)
    return z * z * c.subpixel / (f * c.baseline)


def marking_range(robot: Nav2Robot) -> float:
    """The voxel layer's marking range (obstacle_max_range), m: Gazebo's depth noise is one
    constant std, taken from the D455 model at this depth, where the costmap reads obstacles."""
    source = robot.dwb.get("local_costmap", {}).get("voxel_layer", {}).get("depth_camera", {})
    return float(source.get("obstacle_max_range", 2.5))


def imu_sigmas(imu: ImuSetup) -> tuple[float, float]:
    """Per-sample gyro (rad/s) and accelerometer (m/s²) white-noise std at the sample rate
    (σ = density·√rate, as agrinav_gym's Imu)."""
    root = math.sqrt(imu.rate_hz)
    return (
        math.radians(imu.gyro_noise_deg_s_rthz) * root,
        imu.accel_noise_ug_rthz * 1e-6 * 9.81 * root,
    )


# ----------------------------------------------------------------------------- URDF


def _sub(parent: ET.Element, tag: str, text: Any = None, **attrib: str) -> ET.Element:
    el = ET.SubElement(parent, tag, attrib)
    if text is not None:
        el.text = text if isinstance(text, str) else _num(text)
    return el


def _num(v: float) -> str:
    return f"{v:.10g}"


def _noise(parent: ET.Element, stddev: float) -> None:
    n = _sub(parent, "noise", type="gaussian")
    _sub(n, "mean", 0.0)
    _sub(n, "stddev", stddev)


def _sensor(parent: ET.Element, name: str, kind: str, rate: float, topic: str, frame: str) -> Any:
    s = _sub(parent, "sensor", name=name, type=kind)
    _sub(s, "always_on", "true")
    _sub(s, "update_rate", rate)
    _sub(s, "topic", topic)
    # Fortress reads ignition_frame_id, Garden and later gz_frame_id; without them the header
    # frame would be the sensor's scoped name, which no ROS tf knows
    _sub(s, "ignition_frame_id", frame)
    _sub(s, "gz_frame_id", frame)
    return s


def gazebo_urdf(urdf_text: str, robot: Nav2Robot, metres_per_deg_lat: float) -> str:
    """The packaged URDF with the base_footprint root, the env's sensor mounts and Gazebo Sim's
    sensors, friction, drive and joint states (Fortress plugin names)."""
    tree = ET.fromstring(urdf_text, ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    geo = urdf_geometry(tree)
    joints = {str(j.get("name")): j for j in tree.iter("joint")}
    c, g, d = robot.camera, robot.gnss, robot.drive
    for name, xyz, rpy in (
        ("camera_link_joint", (c.x, 0.0, c.z), (0.0, math.radians(c.pitch_deg), 0.0)),
        ("gps_link_joint", (g.antenna_x, 0.0, g.antenna_z), (0.0, 0.0, 0.0)),
    ):
        joint = joints.get(name)
        if joint is None:
            raise InputError("robot_urdf", name, "allowed: a URDF with the Summit-XL's masts")
        origin = joint.find("origin")
        if origin is None:
            origin = _sub(joint, "origin")
        origin.set("xyz", " ".join(_num(v) for v in xyz))
        origin.set("rpy", " ".join(_num(v) for v in rpy))
    if tree.find("link[@name='base_footprint']") is not None:
        raise InputError("robot_urdf", BASE, "allowed: a URDF whose root is base_link")
    tree.insert(0, ET.Comment(" the ground under the wheels (REP 120), added for ROS "))
    _sub(tree, "link", name=BASE)
    j = _sub(tree, "joint", name="base_footprint_joint", type="fixed")
    _sub(j, "parent", link=BASE)
    _sub(j, "child", link="base_link")
    _sub(j, "origin", xyz=f"0 0 {_num(geo.wheel_radius)}", rpy="0 0 0")
    # Gazebo Sim: sensors, friction, drive (the <gazebo> extensions libsdformat converts)
    tree.append(ET.Comment(" Gazebo Sim: written by agrinav export for the Nav2 bundle "))
    gyro, accel = imu_sigmas(robot.imu)
    ext = _sub(tree, "gazebo", reference=IMU_FRAME)
    s = _sensor(ext, "imu", "imu", robot.imu.rate_hz, GZ_IMU, IMU_FRAME)
    imu = _sub(s, "imu")
    _sub(_sub(imu, "orientation_reference_frame"), "localization", "ENU")
    for block, sigma in (("angular_velocity", gyro), ("linear_acceleration", accel)):
        b = _sub(imu, block)
        for axis in "xyz":
            _noise(_sub(b, axis), sigma)
    ext = _sub(tree, "gazebo", reference=GPS_FRAME)
    s = _sensor(ext, "navsat", "navsat", g.rate_hz, GZ_NAVSAT, GPS_FRAME)
    ps = _sub(_sub(s, "navsat"), "position_sensing")
    # Gazebo applies the horizontal noise to latitude and longitude in degrees
    _noise(_sub(ps, "horizontal"), g.sigma_h / metres_per_deg_lat)
    _noise(_sub(ps, "vertical"), g.sigma_v)
    width, height, hfov = camera_image(c)
    ext = _sub(tree, "gazebo", reference=CAMERA_FRAME)
    s = _sensor(ext, "depth_camera", "depth_camera", c.rate_hz, GZ_DEPTH, CAMERA_FRAME)
    cam = _sub(s, "camera")
    _sub(cam, "horizontal_fov", hfov)
    img = _sub(cam, "image")
    _sub(img, "width", width)
    _sub(img, "height", height)
    _sub(img, "format", "R_FLOAT32")
    clip = _sub(cam, "clip")
    _sub(clip, "near", c.min_range)
    _sub(clip, "far", c.max_range)
    dclip = _sub(_sub(cam, "depth_camera"), "clip")
    _sub(dclip, "near", c.min_range)
    _sub(dclip, "far", c.max_range)
    n = _sub(cam, "noise")
    _sub(n, "type", "gaussian")
    _sub(n, "mean", 0.0)
    _sub(n, "stddev", depth_sigma(c, marking_range(robot)))
    for wheel in WHEELS:
        ext = _sub(tree, "gazebo", reference=wheel)
        _sub(ext, "mu1", d.friction)
        _sub(ext, "mu2", d.friction)
    ext = _sub(tree, "gazebo")
    p = _sub(
        ext,
        "plugin",
        filename="ignition-gazebo-diff-drive-system",
        name="ignition::gazebo::systems::DiffDrive",
    )
    for joint_name in geo.left:
        _sub(p, "left_joint", joint_name)
    for joint_name in geo.right:
        _sub(p, "right_joint", joint_name)
    _sub(p, "wheel_separation", geo.track)
    _sub(p, "wheel_radius", geo.wheel_radius)
    _sub(p, "odom_publish_frequency", d.control_hz)
    _sub(p, "topic", GZ_CMD_VEL)
    _sub(p, "odom_topic", GZ_ODOM)
    _sub(p, "tf_topic", GZ_DRIVE_TF)
    _sub(p, "frame_id", ODOM)
    _sub(p, "child_frame_id", BASE)
    for key, value in (
        ("max_linear_velocity", d.v_max),
        ("min_linear_velocity", -d.v_max),
        ("max_angular_velocity", d.w_max),
        ("min_angular_velocity", -d.w_max),
        ("max_linear_acceleration", d.a_max),
        ("min_linear_acceleration", -d.a_max),
        ("max_angular_acceleration", d.alpha_max),
        ("min_angular_acceleration", -d.alpha_max),
    ):
        _sub(p, key, value)
    p = _sub(
        ext,
        "plugin",
        filename="ignition-gazebo-joint-state-publisher-system",
        name="ignition::gazebo::systems::JointStatePublisher",
    )
    _sub(p, "topic", GZ_JOINTS)
    ET.indent(tree, "  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(tree, encoding="unicode") + "\n"
